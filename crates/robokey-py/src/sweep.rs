//! `robokey.sweep`: an experiment's grid run in parallel with the GIL released, its rows those
//! of `runs.csv`, its progress reported to a Python callable, Ctrl-C stopping it.

use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::Duration;

use pyo3::prelude::*;
use robokey::config::source;
use robokey::interrupt::Interrupt;
use robokey_lab::LabError;
use robokey_lab::experiment::{Experiment, experiments_from_table};
use robokey_lab::folder::rows::run_columns;
use robokey_lab::run::{RunRow, run_experiment, with_jobs};

use crate::columns::{PyColumns, to_py};
use crate::config::{ORIGIN, seed_override, table};
use crate::errors::{SweepError, lab_error};

/// How often the progress callable hears how many runs finished.
const PROGRESS_PERIOD: Duration = Duration::from_millis(200);

/// The experiment of a sweep definition (`config` with a `[sweep]` table) with `seed=`
/// applied.
///
/// # Errors
/// A configuration or sweep definition error; a suite of `[experiment.NAME]` tables.
pub fn experiment(
    py: Python<'_>,
    config: &Bound<'_, PyAny>,
    seed: Option<i64>,
) -> PyResult<Experiment> {
    let mut table = table(py, Some(config))?;
    let overrides = seed_override(seed);
    source::apply(&mut table, &overrides).map_err(|e| crate::errors::config_error(py, &e))?;
    let mut experiments = experiments_from_table(table, ORIGIN).map_err(|e| {
        lab_error(
            py,
            match e {
                LabError::Config(e) => LabError::Config(source::blame(e, &overrides)),
                other => other,
            },
        )
    })?;
    match experiments.pop() {
        Some(experiment) if experiments.is_empty() && experiment.name.is_empty() => Ok(experiment),
        _ => Err(SweepError::new_err(format!(
            "{ORIGIN}: a suite of [experiment.NAME] tables; sweep each experiment's table on \
             its own"
        ))),
    }
}

/// Runs every run of `experiment` on `jobs` threads (0: one per core) with the GIL released,
/// calling `progress(done, total)` from this thread every [`PROGRESS_PERIOD`] and at the end.
/// Ctrl-C (or an exception raised by `progress`) stops the sweep once the running runs end,
/// and is raised.
///
/// # Errors
/// A run that aborted, the worker threads, Ctrl-C, `progress`'s exception.
pub fn run_all(
    py: Python<'_>,
    experiment: &Experiment,
    jobs: usize,
    progress: Option<&Bound<'_, PyAny>>,
) -> PyResult<Vec<RunRow>> {
    let runs: Vec<usize> = (0..experiment.runs()).collect();
    let total = runs.len();
    let done = AtomicUsize::new(0);
    let stop = Interrupt::new();
    let (ended, ends) = mpsc::channel::<()>();
    // Waited on with the GIL released, from this thread only.
    let ends = Mutex::new(ends);
    let mut raised: Option<PyErr> = None;
    let rows = std::thread::scope(|scope| {
        // Traces are off (`experiment.traces` is cleared by the caller): no folder is written.
        let (done, stop, runs) = (&done, &stop, &runs);
        let worker = scope.spawn(move || {
            // `ended` is dropped when the sweep ends, however it ends.
            let _ended = ended;
            with_jobs(jobs, || {
                run_experiment(
                    experiment,
                    std::path::Path::new(""),
                    runs,
                    stop,
                    &|| {
                        done.fetch_add(1, Ordering::Relaxed);
                    },
                    None,
                )
            })
        });
        loop {
            let finished = py.detach(|| {
                ends.lock().map_or(true, |ends| {
                    ends.recv_timeout(PROGRESS_PERIOD) != Err(RecvTimeoutError::Timeout)
                })
            });
            let report = progress.map_or(Ok(()), |p| {
                p.call1((done.load(Ordering::Relaxed), total)).map(drop)
            });
            if let Err(e) = report.and_then(|()| py.check_signals())
                && raised.is_none()
            {
                stop.request(2);
                raised = Some(e);
            }
            if finished {
                break;
            }
        }
        py.detach(|| worker.join())
    });
    if let Some(e) = raised {
        return Err(e);
    }
    let rows =
        rows.map_err(|_| pyo3::exceptions::PyRuntimeError::new_err("a sweep thread panicked"))?;
    rows.and_then(|r| r).map_err(|e| lab_error(py, e))
}

/// Sweeps `config` (a configuration with a `[sweep]` table, as `robokey sweep` reads its
/// file) and returns `(columns, resolved)`: the columns of `runs.csv`, a row per run in run
/// order, and the resolved sweep definition (TOML) that reproduces them.
#[pyfunction]
#[pyo3(signature = (config, *, seed=None, jobs=0, progress=None))]
pub fn sweep<'py>(
    py: Python<'py>,
    config: &Bound<'py, PyAny>,
    seed: Option<i64>,
    jobs: usize,
    progress: Option<&Bound<'py, PyAny>>,
) -> PyResult<(PyColumns<'py>, String)> {
    let mut experiment = experiment(py, config, seed)?;
    experiment.traces = false;
    let rows = run_all(py, &experiment, jobs, progress.filter(|p| !p.is_none()))?;
    Ok((
        to_py(py, run_columns(&experiment, rows.iter()))?,
        experiment.resolved_toml(),
    ))
}
