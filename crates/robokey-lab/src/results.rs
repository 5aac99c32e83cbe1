//! The files of a sweep folder: `runs.csv`, `summary.json`, `manifest.json`,
//! `config.resolved.toml`, traces; and `merge` of shard folders.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use robokey::Metrics;
use serde_json::{Map, Value, json};

use crate::error::{LabError, io_at};
use crate::files::write;
use crate::runner::{RunRecord, Shard};
use crate::stats::Summary;
use crate::sweep::{Experiment, value_text};
use crate::trace::{csv_cell, trace_csv};

/// `runs.csv`: a column per swept field, `replicate`, then the metrics; rows in run order.
#[must_use]
pub fn runs_csv(experiment: &Experiment, records: &[RunRecord]) -> String {
    let mut out = csv_header(experiment);
    for record in records {
        out.push_str(&csv_row(experiment, record));
    }
    out
}

fn csv_header(experiment: &Experiment) -> String {
    let mut columns: Vec<String> = experiment.axes.iter().map(|a| a.field.clone()).collect();
    columns.push("replicate".into());
    columns.extend(Metrics::names());
    columns.join(",") + "\n"
}

fn csv_row(experiment: &Experiment, record: &RunRecord) -> String {
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

/// `manifest.json`: what produced the folder.
#[must_use]
pub fn manifest_json(experiment: &Experiment, shards: &[Shard]) -> String {
    let crates: Map<String, Value> = env!("ROBOKEY_NUMERIC_CRATES")
        .split(',')
        .filter_map(|kv| kv.split_once('='))
        .map(|(k, v)| (k.to_owned(), json!(v)))
        .collect();
    let manifest = json!({
        "tool": "robokey",
        "version": env!("CARGO_PKG_VERSION"),
        "git_commit": env!("ROBOKEY_GIT_COMMIT"),
        "seed": experiment.points[0].config.run.seed,
        "points": experiment.points.len(),
        "replicates": experiment.replicates(),
        "runs": experiment.runs(),
        "shards": shards.iter().map(ToString::to_string).collect::<Vec<_>>(),
        "numeric_crates": crates,
        "platform": format!("{}-{}", std::env::consts::ARCH, std::env::consts::OS),
        "rng": "ChaCha8, seed_p = SHA-256(\"robokey v1\" ‖ seed_le ‖ purpose), stream = replicate",
    });
    serde_json::to_string_pretty(&manifest).expect("JSON serializes") + "\n"
}

/// Writes a sweep folder for the given shard(s); returns the files written.
///
/// # Errors
/// A file cannot be written.
pub fn write_sweep(
    dir: &Path,
    experiment: &Experiment,
    records: &[RunRecord],
    shards: &[Shard],
) -> Result<Vec<PathBuf>, LabError> {
    std::fs::create_dir_all(dir).map_err(io_at(dir))?;
    let runs = runs_csv(experiment, records);
    let mut written = vec![
        write(
            &dir.join("config.resolved.toml"),
            experiment.resolved_toml(),
        )?,
        write(
            &dir.join("manifest.json"),
            manifest_json(experiment, shards),
        )?,
        write(&dir.join("summary.json"), summary_json(experiment, &runs)?)?,
        write(&dir.join("runs.csv"), runs)?,
    ];
    for record in records {
        if let Some(trace) = &record.trace {
            let traces = dir.join("traces");
            std::fs::create_dir_all(&traces).map_err(io_at(&traces))?;
            written.push(write(
                &traces.join(format!("point-{}.csv", record.point)),
                trace_csv(trace),
            )?);
        }
    }
    Ok(written)
}

/// Reads a file, naming it in the error.
pub(crate) fn read(path: &Path) -> Result<String, LabError> {
    std::fs::read_to_string(path).map_err(io_at(path))
}

/// Merges shard folders of one sweep into `out`: checks they share the resolved config
/// and together hold every run exactly once; writes `runs.csv` and `summary.json`
/// byte-identical to a single-machine sweep, and copies traces.
///
/// # Errors
/// Shards of different sweeps, a missing or duplicated run, unreadable files.
pub fn merge(dirs: &[PathBuf], out: &Path) -> Result<Experiment, LabError> {
    let first = dirs
        .first()
        .ok_or_else(|| LabError::Merge("no shard folders given".into()))?;
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
    let origin = first.join("config.resolved.toml").display().to_string();
    let table = robokey::config::parse_table(&resolved, &origin)?;
    let experiment = Experiment::from_table(&merged_name(first), table, &origin)?;
    let mut rows: Vec<Option<String>> = vec![None; experiment.runs()];
    let mut shards = Vec::new();
    for dir in dirs {
        let path = dir.join("runs.csv");
        for (run, line) in parse_runs(&experiment, &read(&path)?, &path)? {
            if rows[run].replace(line).is_some() {
                return Err(LabError::Merge(format!(
                    "run {run} appears twice ({})",
                    path.display()
                )));
            }
        }
        let manifest: Value =
            serde_json::from_str(&read(&dir.join("manifest.json"))?).map_err(|e| {
                LabError::Merge(format!("{}: {e}", dir.join("manifest.json").display()))
            })?;
        if let Some(list) = manifest["shards"].as_array() {
            shards.extend(
                list.iter()
                    .filter_map(|s| s.as_str()?.parse::<Shard>().ok()),
            );
        }
    }
    if let Some(missing) = rows.iter().position(Option::is_none) {
        return Err(LabError::Merge(format!(
            "run {missing} is in none of the shards ({} of {} runs present)",
            rows.iter().flatten().count(),
            rows.len()
        )));
    }
    shards.sort_by_key(|s| (s.count, s.index));
    std::fs::create_dir_all(out).map_err(io_at(out))?;
    let runs: String = csv_header(&experiment) + &rows.into_iter().flatten().collect::<String>();
    write(&out.join("config.resolved.toml"), &resolved)?;
    write(
        &out.join("manifest.json"),
        manifest_json(&experiment, &shards),
    )?;
    write(&out.join("summary.json"), summary_json(&experiment, &runs)?)?;
    write(&out.join("runs.csv"), runs)?;
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

fn merged_name(dir: &Path) -> String {
    let summary = read(&dir.join("summary.json")).ok();
    summary
        .and_then(|s| serde_json::from_str::<Value>(&s).ok())
        .and_then(|v| v["experiment"].as_str().map(str::to_owned))
        .unwrap_or_default()
}
