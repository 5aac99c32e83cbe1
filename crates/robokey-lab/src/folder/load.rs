//! A complete sweep folder read back for reports: its experiment, every run's row and the
//! traces the sweep kept.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use robokey::sim::TraceRow;

use super::layout::{experiment_dirs, folder_name, read_experiment, read_rows};
use super::manifest::{planned, read_manifest};
use crate::error::LabError;
use crate::experiment::Experiment;
use crate::run::RunRow;
use crate::trace::{drawn_trace, point_trace_path};

/// A complete sweep folder, read back.
#[derive(Clone, Debug)]
pub struct Loaded {
    /// Its folder.
    pub dir: PathBuf,
    /// The experiment, from its `config.resolved.toml`.
    pub experiment: Experiment,
    /// Every run, in run order.
    pub rows: Vec<RunRow>,
    /// When the sweep kept traces, by point: the paths a trajectory figure draws of its
    /// replicate 0 ([`crate::trace::DrawnRows`]). A sweep streams a trace to disk as it runs
    /// and never holds it.
    pub traces: BTreeMap<usize, Vec<Vec<TraceRow>>>,
}

/// Reads a sweep folder, or every experiment folder of a suite folder (by name).
///
/// # Errors
/// Not a sweep folder; a folder that an interrupted sweep left incomplete, or that holds
/// only some shards; files that do not read back.
pub fn load(dir: &Path) -> Result<Vec<Loaded>, LabError> {
    match experiment_dirs(dir)? {
        None => Ok(vec![load_experiment(dir, None)?]),
        Some(subs) => subs
            .iter()
            .map(|d| load_experiment(d, Some(folder_name(d))))
            .collect(),
    }
}

/// Reads one experiment's folder (`name`: its name in a suite; else the manifest's).
///
/// # Errors
/// As [`load`].
pub fn load_experiment(dir: &Path, name: Option<String>) -> Result<Loaded, LabError> {
    let manifest = read_manifest(dir)?;
    let experiment = read_experiment(dir, &name.unwrap_or(manifest.experiment))?;
    let planned = planned(&experiment, &manifest.shards).count();
    if !manifest.complete {
        return Err(LabError::Incomplete {
            dir: dir.to_path_buf(),
            done: manifest.runs_done,
            planned,
        });
    }
    let rows = read_rows(&experiment, dir, &manifest.shards)?;
    if rows.len() != experiment.runs() {
        return Err(LabError::NotWhole {
            dir: dir.to_path_buf(),
            shards: manifest
                .shards
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join(", "),
            held: rows.len(),
            total: experiment.runs(),
        });
    }
    let traces = if experiment.traces {
        (0..experiment.points.len())
            .map(|point| Ok((point, drawn_trace(&point_trace_path(dir, point))?)))
            .collect::<Result<_, LabError>>()?
    } else {
        BTreeMap::new()
    };
    Ok(Loaded {
        dir: dir.to_path_buf(),
        experiment,
        rows: rows.into_values().collect(),
        traces,
    })
}
