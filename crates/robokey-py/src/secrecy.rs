//! `robokey.secrecy`: how many of a sweep's agreed bits are secret, and against whom — the
//! analysis `robokey secrecy` computes (docs/secrecy.md), on a sweep definition or folder,
//! returned instead of written.

use std::path::PathBuf;

use pyo3::prelude::*;
use robokey::config::EveStrategy;
use robokey_lab::experiment::Experiment;
use robokey_lab::folder::layout::{folder_name, read_experiment};
use robokey_lab::run::sessions::SessionBank;
use robokey_lab::run::with_jobs;
use robokey_lab::secrecy::table::secrecy_columns;
use robokey_lab::secrecy::{Pooling, Secrecy, SecrecyRequest};

use crate::columns::{PyColumns, to_py};
use crate::errors::{InputError, lab_error, option_error};

/// The experiment of `sweep`: a sweep folder (a path-like object) as `robokey secrecy` reads
/// it, else a sweep definition as [`crate::sweep::sweep`] takes it.
///
/// # Errors
/// A folder that is not a sweep's, a definition that is not valid.
pub fn experiment_of(
    py: Python<'_>,
    sweep: &Bound<'_, PyAny>,
    seed: Option<i64>,
) -> PyResult<Experiment> {
    if sweep.hasattr("__fspath__")? {
        let folder: PathBuf = sweep.extract()?;
        return read_experiment(&folder, &folder_name(&folder)).map_err(|e| lab_error(py, e));
    }
    crate::sweep::experiment(py, sweep, seed)
}

/// A name of [`EveStrategy`], or the error naming the allowed ones.
pub(crate) fn strategy(name: &str) -> PyResult<EveStrategy> {
    EveStrategy::ALL
        .into_iter()
        .find(|s| s.name() == name)
        .ok_or_else(|| {
            let allowed: Vec<&str> = EveStrategy::ALL.iter().map(|s| s.name()).collect();
            InputError::new_err(format!(
                "adversary {name:?} is not allowed (allowed: {})",
                allowed.join(", ")
            ))
        })
}

/// Analyzes the secrecy of every point of `sweep` (a sweep definition, or a sweep folder as a
/// `pathlib.Path`) against each adversary, as `robokey secrecy` does, on `jobs` threads with
/// the GIL released. Returns `(secrecy_json, columns, map_json)`: the text of
/// `secrecy.json`, the columns of `secrecy.csv` (those of `secrecy.parquet`) and the text of
/// (private sensing) `private-map.json`, which robokey would write into the folder; nothing is
/// written.
#[pyfunction]
#[pyo3(signature = (
    sweep, *, seed=None, adversaries=None, epsilon=None, block_bits=None, blocks=1,
    pooling=None, sample_bits=1_000, max_sessions=None, assume_eve_error=None, jobs=0
))]
#[allow(clippy::too_many_arguments)]
pub fn secrecy<'py>(
    py: Python<'py>,
    sweep: &Bound<'py, PyAny>,
    seed: Option<i64>,
    adversaries: Option<Vec<String>>,
    epsilon: Option<f64>,
    block_bits: Option<u64>,
    blocks: usize,
    pooling: Option<String>,
    sample_bits: usize,
    max_sessions: Option<u32>,
    assume_eve_error: Option<f64>,
    jobs: usize,
) -> PyResult<(String, PyColumns<'py>, Option<String>)> {
    let pooling = pooling
        .map(|name| match name.as_str() {
            "confirmed" => Ok(Pooling::Confirmed),
            "complete" => Ok(Pooling::Complete),
            _ => Err(InputError::new_err(format!(
                "pooling {name:?} is not allowed (allowed: confirmed, complete)"
            ))),
        })
        .transpose()?;
    let request = SecrecyRequest {
        adversaries: adversaries
            .unwrap_or_default()
            .iter()
            .map(|a| strategy(a))
            .collect::<PyResult<_>>()?,
        epsilon,
        block_bits,
        blocks,
        pooling,
        sample_bits,
        max_sessions,
        assumed_eve_error: assume_eve_error,
        sizing: None,
        reconciliation: None,
        llrs: None,
    };
    request.validate().map_err(|e| option_error(py, &e))?;
    let experiment = experiment_of(py, sweep, seed)?;
    if !experiment.points[0].config.protocol.enabled {
        return Err(InputError::new_err(
            "the sweep runs with protocol.enabled = false: no key to analyze",
        ));
    }
    let options = request
        .options(&experiment)
        .map_err(|e| option_error(py, &e))?;
    let secrecy = py
        .detach(|| {
            with_jobs(jobs, || {
                Secrecy::compute(&experiment, &options, &mut SessionBank::new())
            })
        })
        .and_then(|computed| computed)
        .map_err(|e| lab_error(py, e))?;
    Ok((
        secrecy.json().to_string(),
        to_py(py, secrecy_columns(&secrecy.results))?,
        secrecy.map_json().map(|m| m.to_string()),
    ))
}
