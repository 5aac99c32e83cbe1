//! Reading what robokey wrote: a sweep folder's runs and a trace file, as the library reads
//! them back for its reports (files checked against the sweep's definition, named errors).

use std::path::PathBuf;

use pyo3::prelude::*;
use robokey_lab::folder::load::load;
use robokey_lab::trace::read_trace as read_trace_rows;

use robokey_lab::folder::rows::run_columns;
use robokey_lab::trace_table::TraceColumns;

use crate::columns::{PyColumns, to_py};
use crate::errors::lab_error;

/// The runs of a complete sweep folder (or of each experiment folder of a suite folder):
/// `[(name, columns, resolved)]` — the experiment's name (empty for a single sweep), the
/// columns of its `runs.csv` as [`crate::sweep::sweep`] returns them, and its
/// `config.resolved.toml`.
#[pyfunction]
pub fn read_sweep(
    py: Python<'_>,
    folder: PathBuf,
) -> PyResult<Vec<(String, PyColumns<'_>, String)>> {
    let loaded = py.detach(|| load(&folder)).map_err(|e| lab_error(py, e))?;
    loaded
        .into_iter()
        .map(|l| {
            let columns = to_py(py, run_columns(&l.experiment, l.rows.iter()))?;
            Ok((
                l.experiment.name.clone(),
                columns,
                l.experiment.resolved_toml(),
            ))
        })
        .collect()
}

/// Every row of a `trace.csv` (a run's, or a sweep's `traces/point-<i>.csv`), column by
/// column as [`crate::run::run`] returns its trace.
#[pyfunction]
pub fn read_trace(py: Python<'_>, path: PathBuf) -> PyResult<PyColumns<'_>> {
    let mut trace = TraceColumns::default();
    py.detach(|| {
        let file = std::fs::File::open(&path).map_err(|error| robokey_lab::LabError::Io {
            path: path.clone(),
            error,
        })?;
        read_trace_rows(std::io::BufReader::new(file), &path, |row| trace.push(&row))
    })
    .map_err(|e| lab_error(py, e))?;
    to_py(py, trace.into_columns())
}
