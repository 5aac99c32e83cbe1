//! The files of a sweep folder: `runs.csv`, `summary.json`, `manifest.json`,
//! `config.resolved.toml`, traces; and `merge` of shard folders.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use robokey::Metrics;
use serde_json::{Map, Value, json};

use crate::error::{LabError, io_at};
use crate::files::write;
use crate::runner::{RunRecord, Shard};
use crate::stats::Summary;
use crate::sweep::{Experiment, value_text};
use crate::trace::csv_cell;

/// The rows of a `runs.csv` that are done: run index → its line (newline included).
pub type Rows = BTreeMap<usize, String>;

/// `runs.csv`: a column per swept field, `replicate`, then the metrics; rows in run order.
#[must_use]
pub fn runs_csv(experiment: &Experiment, rows: &Rows) -> String {
    csv_header(experiment) + &rows.values().map(String::as_str).collect::<String>()
}

fn csv_header(experiment: &Experiment) -> String {
    let mut columns: Vec<String> = experiment.axes.iter().map(|a| a.field.clone()).collect();
    columns.push("replicate".into());
    columns.extend(Metrics::names());
    columns.join(",") + "\n"
}

/// The `runs.csv` line of a finished run.
#[must_use]
pub fn csv_row(experiment: &Experiment, record: &RunRecord) -> String {
    let point = &experiment.points[record.point];
    let mut cells: Vec<String> = point
        .params
        .iter()
        .map(|(_, v)| param_cell(&value_text(v)))
        .collect();
    cells.push(record.replicate.to_string());
    cells.extend(record.metrics.values().into_iter().map(csv_cell));
    cells.join(",") + "\n"
}

/// A parameter's CSV cell: quoted (inner quotes doubled) when it holds a comma or a quote,
/// as an array value does.
fn param_cell(text: &str) -> String {
    if text.contains([',', '"']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_owned()
    }
}

/// The cells of one CSV line (quoted cells unquoted).
fn cells(line: &str) -> Vec<String> {
    csv::ReaderBuilder::new()
        .has_headers(false)
        .from_reader(line.as_bytes())
        .records()
        .next()
        .and_then(Result::ok)
        .map_or_else(Vec::new, |r| r.iter().map(str::to_owned).collect())
}

/// Parses a `runs.csv` back into `(run index, cells)`, checking that every row belongs to
/// the experiment's grid.
fn parse_runs(
    experiment: &Experiment,
    text: &str,
    origin: &Path,
) -> Result<Vec<(usize, String)>, LabError> {
    let bad =
        |line: usize, why: String| LabError::Merge(format!("{}:{line}: {why}", origin.display()));
    let mut lines = text.lines();
    if lines.next().map(|h| format!("{h}\n")) != Some(csv_header(experiment)) {
        return Err(bad(1, "header does not match the sweep".into()));
    }
    let axes = experiment.axes.len();
    let point_of: HashMap<Vec<String>, usize> = experiment
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| (p.params.iter().map(|(_, v)| value_text(v)).collect(), i))
        .collect();
    let replicates = experiment.replicates() as usize;
    lines
        .enumerate()
        .map(|(i, line)| {
            let cells = cells(line);
            let params: Vec<String> = cells.iter().take(axes).cloned().collect();
            let point = *point_of
                .get(&params)
                .ok_or_else(|| bad(i + 2, format!("parameters {params:?} are not on the grid")))?;
            let replicate: usize = cells
                .get(axes)
                .and_then(|r| r.parse().ok())
                .filter(|&r| r < replicates)
                .ok_or_else(|| bad(i + 2, "bad replicate".into()))?;
            Ok((point * replicates + replicate, format!("{line}\n")))
        })
        .collect()
}

/// `summary.json` computed from the text of `runs.csv`, so that a single sweep and a merge
/// of shards produce the same bytes: per point, for each metric, count of defined values,
/// median, quartiles, min, max, mean.
///
/// # Errors
/// The CSV does not belong to the experiment.
pub fn summary_json(experiment: &Experiment, runs_csv: &str) -> Result<String, LabError> {
    let rows = parse_runs(experiment, runs_csv, Path::new("runs.csv"))?;
    let names = Metrics::names();
    let offset = experiment.axes.len() + 1;
    let replicates = experiment.replicates() as usize;
    let mut values = vec![vec![Vec::new(); names.len()]; experiment.points.len()];
    for (run, line) in &rows {
        for (m, cell) in cells(line.trim_end()).iter().skip(offset).enumerate() {
            let value = match cell.as_str() {
                "" => None,
                "true" => Some(1.0),
                "false" => Some(0.0),
                number => number.parse::<f64>().ok(),
            };
            if let Some(v) = value {
                values[run / replicates][m].push(v);
            }
        }
    }
    let points: Vec<Value> = experiment
        .points
        .iter()
        .zip(values)
        .enumerate()
        .map(|(i, (point, columns))| {
            let params: Map<String, Value> = point
                .params
                .iter()
                .map(|(f, v)| (f.clone(), toml_to_json(v)))
                .collect();
            let metrics: Map<String, Value> = names
                .iter()
                .zip(columns)
                .map(|(name, column)| {
                    let summary =
                        Summary::of(&column).map_or_else(|| json!({ "count": 0 }), |s| json!(s));
                    (name.clone(), summary)
                })
                .collect();
            json!({ "point": i, "params": params, "metrics": metrics })
        })
        .collect();
    let summary = json!({
        "experiment": experiment.name,
        "replicates": experiment.replicates(),
        "runs": rows.len(),
        "statistics": "per metric over the runs where it is defined: count, median, quartiles (linear interpolation between order statistics), min, max, mean",
        "points": points,
    });
    Ok(serde_json::to_string_pretty(&summary).expect("JSON serializes") + "\n")
}

/// A TOML value as JSON.
#[must_use]
pub fn toml_to_json(value: &toml::Value) -> Value {
    match value {
        toml::Value::Float(x) => json!(x),
        toml::Value::Integer(i) => json!(i),
        toml::Value::Boolean(b) => json!(b),
        other => json!(value_text(other)),
    }
}

/// What a folder's `manifest.json` says about its runs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Manifest {
    /// The experiment's name (empty for a single sweep).
    pub experiment: String,
    /// The shards whose runs the folder holds.
    pub shards: Vec<Shard>,
    /// Whether it holds every run of its shards.
    pub complete: bool,
    /// Runs done.
    pub runs_done: usize,
    /// SHA-256 of `config.resolved.toml`.
    pub config_sha256: String,
    /// The commit of the robokey that wrote it.
    pub git_commit: String,
}

/// The manifest of the robokey that is running, for a folder holding `runs_done` runs of
/// `shards`.
#[must_use]
pub fn manifest(experiment: &Experiment, shards: &[Shard], runs_done: usize) -> Manifest {
    Manifest {
        experiment: experiment.name.clone(),
        shards: shards.to_vec(),
        complete: runs_done == planned(experiment, shards).count(),
        runs_done,
        config_sha256: sha256_hex(&experiment.resolved_toml()),
        git_commit: env!("ROBOKEY_GIT_COMMIT").to_owned(),
    }
}

/// The runs of `shards`, in run order.
pub fn planned(experiment: &Experiment, shards: &[Shard]) -> impl Iterator<Item = usize> {
    let shards = shards.to_vec();
    (0..experiment.runs()).filter(move |&r| shards.iter().any(|s| s.contains(r)))
}

/// Lower-case hex SHA-256 of a text.
#[must_use]
pub fn sha256_hex(text: &str) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(text.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// `manifest.json`: what produced the folder and whether it holds every run of its shards.
/// Nothing in it depends on the time or the machine's load, so an interrupted sweep that
/// is resumed ends with the same bytes as one that never stopped.
#[must_use]
pub fn manifest_json(experiment: &Experiment, manifest: &Manifest) -> String {
    let crates: Map<String, Value> = env!("ROBOKEY_NUMERIC_CRATES")
        .split(',')
        .filter_map(|kv| kv.split_once('='))
        .map(|(k, v)| (k.to_owned(), json!(v)))
        .collect();
    let json = json!({
        "tool": "robokey",
        "version": env!("CARGO_PKG_VERSION"),
        "git_commit": manifest.git_commit,
        "experiment": manifest.experiment,
        "config_sha256": manifest.config_sha256,
        "seed": experiment.points[0].config.run.seed,
        "points": experiment.points.len(),
        "replicates": experiment.replicates(),
        "runs": experiment.runs(),
        "shards": manifest.shards.iter().map(ToString::to_string).collect::<Vec<_>>(),
        "runs_done": manifest.runs_done,
        "complete": manifest.complete,
        "numeric_crates": crates,
        "platform": format!("{}-{}", std::env::consts::ARCH, std::env::consts::OS),
        "rng": "ChaCha8, seed_p = SHA-256(\"robokey v1\" ‖ seed_le ‖ purpose), stream = replicate",
    });
    serde_json::to_string_pretty(&json).expect("JSON serializes") + "\n"
}

/// Reads a folder's `manifest.json`.
///
/// # Errors
/// It is missing or is not a manifest robokey wrote.
pub fn read_manifest(dir: &Path) -> Result<Manifest, LabError> {
    let path = dir.join("manifest.json");
    let bad = |why: &str| LabError::Merge(format!("{}: {why}", path.display()));
    let json: Value = serde_json::from_str(&read(&path)?).map_err(|e| bad(&e.to_string()))?;
    let text = |key: &str| json[key].as_str().map(str::to_owned);
    let shards = json["shards"]
        .as_array()
        .ok_or_else(|| bad("no `shards` list"))?
        .iter()
        .map(|s| s.as_str().and_then(|s| s.parse::<Shard>().ok()))
        .collect::<Option<Vec<_>>>()
        .ok_or_else(|| bad("a shard that is not m/n"))?;
    Ok(Manifest {
        experiment: text("experiment").unwrap_or_default(),
        shards,
        // Folders written before sweeps could be interrupted were always complete.
        complete: json["complete"].as_bool().unwrap_or(true),
        runs_done: json["runs_done"]
            .as_u64()
            .or_else(|| json["runs"].as_u64())
            .map_or(0, |n| n as usize),
        config_sha256: text("config_sha256").unwrap_or_default(),
        git_commit: text("git_commit").unwrap_or_default(),
    })
}

/// Reads the rows of `dir/runs.csv` that belong to `shards` (none when there is no such
/// file: a sweep interrupted before its first run finished).
///
/// # Errors
/// A row is not on the grid, is outside the shards, or appears twice.
pub fn read_rows(experiment: &Experiment, dir: &Path, shards: &[Shard]) -> Result<Rows, LabError> {
    let path = dir.join("runs.csv");
    if !path.exists() {
        return Ok(Rows::new());
    }
    let mut rows = Rows::new();
    for (run, line) in parse_runs(experiment, &read(&path)?, &path)? {
        if !shards.iter().any(|s| s.contains(run)) {
            return Err(LabError::Merge(format!(
                "{}: run {run} is outside the folder's shards",
                path.display()
            )));
        }
        if rows.insert(run, line).is_some() {
            return Err(LabError::Merge(format!(
                "{}: run {run} appears twice",
                path.display()
            )));
        }
    }
    Ok(rows)
}

/// The metrics of a `runs.csv` line: the inverse of [`csv_row`] (reals are written in their
/// shortest round-trip form, so they read back exactly).
///
/// # Errors
/// A cell does not parse as its metric.
pub fn metrics_of_line(experiment: &Experiment, line: &str) -> Result<Metrics, String> {
    let cells = cells(line.trim_end());
    let names = Metrics::names();
    let values = cells.get(experiment.axes.len() + 1..).unwrap_or_default();
    if values.len() != names.len() {
        return Err(format!(
            "{} metric cells, expected {}",
            values.len(),
            names.len()
        ));
    }
    let mut cells = MetricCells(names.iter().zip(values));
    Ok(Metrics {
        codewords_sent: cells.next()?,
        accepted: cells.next()?,
        accepted_pct: cells.next()?,
        correct_pct: cells.next()?,
        ber_controller: cells.next()?,
        ber_eve: cells.next()?,
        jx: cells.next()?.ok_or("`jx` is empty")?,
        eve_disagreement_pct: cells.next()?,
        key_match: cells.next()?,
        n_bce: cells.counts()?,
        n_acc: cells.counts()?,
    })
}

/// The metric cells of a `runs.csv` line with their column names, read in column order.
struct MetricCells<'a>(std::iter::Zip<std::slice::Iter<'a, String>, std::slice::Iter<'a, String>>);

impl MetricCells<'_> {
    fn next<T: std::str::FromStr>(&mut self) -> Result<Option<T>, String> {
        let (name, cell) = self.0.next().ok_or("too few cells")?;
        if cell.is_empty() {
            return Ok(None);
        }
        cell.parse()
            .map(Some)
            .map_err(|_| format!("`{name}` = `{cell}` does not parse"))
    }

    /// Eight joint counts, all defined or all undefined.
    fn counts(&mut self) -> Result<Option<[u64; 8]>, String> {
        let cells: Vec<Option<u64>> = (0..8).map(|_| self.next()).collect::<Result<_, _>>()?;
        if cells.iter().all(Option::is_none) {
            return Ok(None);
        }
        let mut table = [0; 8];
        for (slot, cell) in table.iter_mut().zip(&cells) {
            *slot = cell.ok_or("joint counts partly empty")?;
        }
        Ok(Some(table))
    }
}

/// Writes the folder of an experiment holding `rows` of `shards`: `config.resolved.toml`,
/// `runs.csv`, `summary.json` when every run of the shards is done (none otherwise, so no
/// summary of part of a sweep is mistaken for the whole), and `manifest.json` last. Returns
/// the manifest written.
///
/// # Errors
/// A file cannot be written.
pub fn write_folder(
    dir: &Path,
    experiment: &Experiment,
    rows: &Rows,
    shards: &[Shard],
) -> Result<Manifest, LabError> {
    std::fs::create_dir_all(dir).map_err(io_at(dir))?;
    let manifest = manifest(experiment, shards, rows.len());
    write(
        &dir.join("config.resolved.toml"),
        experiment.resolved_toml(),
    )?;
    let runs = runs_csv(experiment, rows);
    let summary = dir.join("summary.json");
    if manifest.complete {
        write(&summary, summary_json(experiment, &runs)?)?;
    } else if summary.exists() {
        std::fs::remove_file(&summary).map_err(io_at(&summary))?;
    }
    write(&dir.join("runs.csv"), runs)?;
    write(
        &dir.join("manifest.json"),
        manifest_json(experiment, &manifest),
    )?;
    Ok(manifest)
}

/// Where the trace of a point's replicate 0 is kept.
#[must_use]
pub fn trace_path(dir: &Path, point: usize) -> PathBuf {
    dir.join("traces").join(format!("point-{point}.csv"))
}

/// Reads a file, naming it in the error.
pub(crate) fn read(path: &Path) -> Result<String, LabError> {
    std::fs::read_to_string(path).map_err(io_at(path))
}

/// Reads the experiment a folder was swept from, from its `config.resolved.toml`.
///
/// # Errors
/// The file is missing or does not define a sweep.
pub fn read_experiment(dir: &Path, name: &str) -> Result<Experiment, LabError> {
    let path = dir.join("config.resolved.toml");
    let origin = path.display().to_string();
    let table = robokey::config::parse_table(&read(&path)?, &origin)?;
    Experiment::from_table(name, table, &origin)
}

/// The experiment folders of a suite folder (subfolders with a `config.resolved.toml`, by
/// name), or `None` when `dir` is itself a sweep folder.
///
/// # Errors
/// `dir` cannot be read, or holds neither.
pub fn experiment_dirs(dir: &Path) -> Result<Option<Vec<PathBuf>>, LabError> {
    if dir.join("config.resolved.toml").exists() {
        return Ok(None);
    }
    let mut subs: Vec<PathBuf> = dir
        .read_dir()
        .map_err(io_at(dir))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.join("config.resolved.toml").exists())
        .collect();
    if subs.is_empty() {
        return Err(LabError::NotSweep(dir.to_path_buf()));
    }
    subs.sort();
    Ok(Some(subs))
}

/// An experiment's name within its suite: its folder's name.
#[must_use]
pub fn folder_name(dir: &Path) -> String {
    dir.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// Merges the folders of a sharded sweep, or of a sharded suite (each experiment's
/// subfolders), into `out`. Returns each experiment with its number of runs.
///
/// # Errors
/// As [`merge_sweep`]; suite folders with different experiments.
pub fn merge(dirs: &[PathBuf], out: &Path) -> Result<Vec<Experiment>, LabError> {
    let first = dirs
        .first()
        .ok_or_else(|| LabError::Merge("no shard folders given".into()))?;
    let Some(subs) = experiment_dirs(first)? else {
        return Ok(vec![merge_sweep(dirs, out)?]);
    };
    let names: Vec<String> = subs.iter().map(|d| folder_name(d)).collect();
    for dir in &dirs[1..] {
        let theirs: Vec<String> = experiment_dirs(dir)?
            .unwrap_or_default()
            .iter()
            .map(|d| folder_name(d))
            .collect();
        if theirs != names {
            return Err(LabError::Merge(format!(
                "{} holds the experiments [{}], {} holds [{}]: shards of different suites",
                first.display(),
                names.join(", "),
                dir.display(),
                theirs.join(", ")
            )));
        }
    }
    names
        .iter()
        .map(|name| {
            let shards: Vec<PathBuf> = dirs.iter().map(|d| d.join(name)).collect();
            merge_sweep(&shards, &out.join(name))
        })
        .collect()
}

/// Merges shard folders of one sweep into `out`: checks they share the resolved config,
/// are complete and together hold every run exactly once; writes `runs.csv` and
/// `summary.json` byte-identical to a single-machine sweep, and copies traces.
///
/// # Errors
/// Shards of different sweeps, an interrupted shard, a missing or duplicated run,
/// unreadable files.
pub fn merge_sweep(dirs: &[PathBuf], out: &Path) -> Result<Experiment, LabError> {
    let first = &dirs[0];
    let resolved = read(&first.join("config.resolved.toml"))?;
    for dir in &dirs[1..] {
        if read(&dir.join("config.resolved.toml"))? != resolved {
            return Err(LabError::Merge(format!(
                "{} and {} are shards of different sweeps (config.resolved.toml differs)",
                first.display(),
                dir.display()
            )));
        }
    }
    let experiment = read_experiment(first, &read_manifest(first)?.experiment)?;
    let mut rows = Rows::new();
    let mut shards = Vec::new();
    for dir in dirs {
        let manifest = read_manifest(dir)?;
        if !manifest.complete {
            return Err(LabError::Incomplete {
                dir: dir.clone(),
                done: manifest.runs_done,
                planned: planned(&experiment, &manifest.shards).count(),
            });
        }
        for (run, line) in read_rows(&experiment, dir, &manifest.shards)? {
            if rows.insert(run, line).is_some() {
                return Err(LabError::Merge(format!(
                    "run {run} appears twice ({})",
                    dir.join("runs.csv").display()
                )));
            }
        }
        shards.extend(manifest.shards);
    }
    if let Some(missing) = (0..experiment.runs()).find(|r| !rows.contains_key(r)) {
        return Err(LabError::Merge(format!(
            "run {missing} is in none of the shards ({} of {} runs present)",
            rows.len(),
            experiment.runs()
        )));
    }
    shards.sort_by_key(|s| (s.count, s.index));
    write_folder(out, &experiment, &rows, &shards)?;
    for dir in dirs {
        let traces = dir.join("traces");
        if let Ok(entries) = traces.read_dir() {
            let target = out.join("traces");
            std::fs::create_dir_all(&target).map_err(io_at(&target))?;
            for entry in entries.flatten() {
                std::fs::copy(entry.path(), target.join(entry.file_name()))
                    .map_err(io_at(entry.path()))?;
            }
        }
    }
    Ok(experiment)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metrics_read_back_from_runs_csv_exactly() {
        let experiment = Experiment::from_table(
            "t",
            "[run]\nreplicates = 2\n[sweep]\n\"protocol.enabled\" = [true, false]\n"
                .parse()
                .unwrap(),
            "t.toml",
        )
        .unwrap();
        for point in 0..2 {
            let output =
                robokey::sim::simulate(&experiment.points[point].config, 1, false).unwrap();
            let record = RunRecord {
                run: point * 2 + 1,
                point,
                replicate: 1,
                metrics: output.metrics,
                trace: None,
            };
            let line = csv_row(&experiment, &record);
            assert_eq!(metrics_of_line(&experiment, &line).unwrap(), record.metrics);
        }
        // `accepted`, the second metric, after the axis and the replicate.
        let mut bad: Vec<&str> = "true,0".split(',').collect();
        bad.extend(std::iter::repeat_n("1", 25));
        bad[3] = "x";
        let err = metrics_of_line(&experiment, &bad.join(",")).unwrap_err();
        assert_eq!(err, "`accepted` = `x` does not parse");
        let err = metrics_of_line(&experiment, "true,0,1\n").unwrap_err();
        assert!(err.contains("1 metric cells, expected 25"), "{err}");
    }
}
