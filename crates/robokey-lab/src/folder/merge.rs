//! `robokey merge`: the shard folders of a sweep, or of a suite, into one folder
//! byte-identical to a single machine's sweep.

use std::path::{Path, PathBuf};

use super::layout::{experiment_dirs, folder_name, read_experiment, read_rows, write_folder};
use super::manifest::{planned, read_manifest};
use super::rows::Rows;
use crate::error::{LabError, io_at};
use crate::experiment::Experiment;
use crate::output::read;
use crate::parquet_table::TableFormat;

/// Merges the folders of a sharded sweep, or of a sharded suite (each experiment's
/// subfolders), into `out`, its runs table and traces in `format`. Returns each experiment
/// with its number of runs.
///
/// # Errors
/// As [`merge_sweep`]; suite folders with different experiments.
pub fn merge(
    dirs: &[PathBuf],
    out: &Path,
    format: TableFormat,
) -> Result<Vec<Experiment>, LabError> {
    let first = dirs
        .first()
        .ok_or_else(|| LabError::Merge("no shard folders given".into()))?;
    let Some(subs) = experiment_dirs(first)? else {
        return Ok(vec![merge_sweep(dirs, out, format)?]);
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
            merge_sweep(&shards, &out.join(name), format)
        })
        .collect()
}

/// Merges shard folders of one sweep into `out`: checks they share the resolved config,
/// are complete and together hold every run exactly once; copies traces, and writes
/// `runs.csv` and `summary.json` byte-identical to a single-machine sweep (in `format`
/// Parquet, `runs.parquet` and the traces as a single-machine sweep with `--format parquet`).
///
/// # Errors
/// Shards of different sweeps, an interrupted shard, a missing or duplicated run,
/// unreadable files.
pub fn merge_sweep(
    dirs: &[PathBuf],
    out: &Path,
    format: TableFormat,
) -> Result<Experiment, LabError> {
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
        for (run, row) in read_rows(&experiment, dir, &manifest.shards)? {
            if rows.insert(run, row).is_some() {
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
    write_folder(out, &experiment, &rows, &shards, format)?;
    Ok(experiment)
}
