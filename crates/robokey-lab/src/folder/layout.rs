//! A sweep folder as a whole: `config.resolved.toml`, `runs.csv` (or, complete and with
//! `--format parquet`, `runs.parquet`), `summary.json` and `manifest.json` written together,
//! the rows of its shards read back, and the folders of a suite.

use std::path::{Path, PathBuf};

use super::manifest::{Manifest, manifest, manifest_json};
use super::rows::{Rows, read_runs, run_columns, runs_csv};
use super::summary::summary_json;
use crate::error::{LabError, io_at};
use crate::experiment::Experiment;
use crate::output::{read, write};
use crate::parquet_table::{TableFormat, write_parquet};
use crate::run::Shard;
use crate::trace::point_trace_path;
use crate::trace_table::TraceColumns;

/// Writes the folder of an experiment holding `rows` of `shards`: `config.resolved.toml`,
/// `runs.csv`, `summary.json` when every run of the shards is done (none otherwise, so no
/// summary of part of a sweep is mistaken for the whole), and `manifest.json` last. Returns
/// the manifest written.
///
/// With [`TableFormat::Parquet`] a folder that holds every run of its shards gets
/// `runs.parquet` instead of `runs.csv`, and its traces `traces/point-<i>.parquet` instead of
/// `.csv` (the CSV files are removed); an incomplete one stays in CSV, so that `--resume`
/// can continue it.
///
/// # Errors
/// A file cannot be written.
pub fn write_folder(
    dir: &Path,
    experiment: &Experiment,
    rows: &Rows,
    shards: &[Shard],
    format: TableFormat,
) -> Result<Manifest, LabError> {
    std::fs::create_dir_all(dir).map_err(io_at(dir))?;
    let manifest = manifest(experiment, shards, rows.len());
    write(
        &dir.join("config.resolved.toml"),
        experiment.resolved_toml(),
    )?;
    let summary = dir.join("summary.json");
    if manifest.complete {
        write(&summary, summary_json(experiment, rows))?;
    } else if summary.exists() {
        std::fs::remove_file(&summary).map_err(io_at(&summary))?;
    }
    if manifest.complete && format == TableFormat::Parquet {
        let metadata = [("robokey.sweep", experiment.resolved_toml())];
        write_parquet(
            &dir.join("runs.parquet"),
            &run_columns(experiment, rows.values()),
            &metadata,
        )?;
        remove_if_present(&dir.join("runs.csv"))?;
        for point in 0..experiment.points.len() {
            trace_to_parquet(&point_trace_path(dir, point))?;
        }
    } else {
        write(&dir.join("runs.csv"), runs_csv(experiment, rows))?;
    }
    write(
        &dir.join("manifest.json"),
        manifest_json(experiment, &manifest),
    )?;
    Ok(manifest)
}

/// Removes `path` if it exists.
fn remove_if_present(path: &Path) -> Result<(), LabError> {
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(io_at(path)(e)),
        _ => Ok(()),
    }
}

/// Rewrites the trace `path` (a `.csv`, if the sweep kept it) as the `.parquet` beside it,
/// its columns' units and meanings in the metadata, and removes the CSV.
fn trace_to_parquet(path: &Path) -> Result<(), LabError> {
    if !path.exists() {
        return Ok(());
    }
    let mut trace = TraceColumns::default();
    let file = std::fs::File::open(path).map_err(io_at(path))?;
    crate::trace::read_trace(std::io::BufReader::new(file), path, |row| trace.push(&row))?;
    write_parquet(
        &path.with_extension(TableFormat::Parquet.extension()),
        &trace.into_columns(),
        &[],
    )?;
    remove_if_present(path)
}

/// Reads the rows of `dir/runs.csv` that belong to `shards` (none when there is no such
/// file: a sweep interrupted before its first run finished).
///
/// # Errors
/// The folder holds `runs.parquet` (a sweep written with `--format parquet`, which robokey
/// does not read back); a row is not on the grid, is outside the shards, or appears twice.
pub fn read_rows(experiment: &Experiment, dir: &Path, shards: &[Shard]) -> Result<Rows, LabError> {
    if dir.join("runs.parquet").exists() {
        return Err(LabError::ParquetRuns(dir.to_path_buf()));
    }
    let path = dir.join("runs.csv");
    if !path.exists() {
        return Ok(Rows::new());
    }
    let mut rows = Rows::new();
    for row in read_runs(experiment, &read(&path)?, &path)? {
        let run = row.run;
        let malformed = |message: String| LabError::Malformed {
            place: path.display().to_string(),
            message,
        };
        if !shards.iter().any(|s| s.contains(run)) {
            return Err(malformed(format!(
                "run {run} is outside the folder's shards"
            )));
        }
        if rows.insert(run, row).is_some() {
            return Err(malformed(format!("run {run} appears twice")));
        }
    }
    Ok(rows)
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
