//! `robokey.run`: one simulated session, its metrics and its trace, no files.

use pyo3::prelude::*;
use pyo3::types::PyDict;
use robokey::protocol::SessionPlan;
use robokey::sim::simulate_plan_streaming;
use robokey_lab::LabError;
use robokey_lab::trace::metrics_table;

use robokey_lab::trace_table::TraceColumns;

use crate::columns::{metrics_dict, to_py};
use crate::errors::lab_error;

/// One run as `robokey run` makes it, without writing files: a dict with `metrics` (the
/// columns of `metrics.json`, undefined ones None), `trace_columns` (every row of
/// `trace.csv`, column by column), `table` (the metrics as `robokey run` prints them),
/// `config` (the resolved configuration as TOML), `seed` and `replicate`. The simulation runs
/// with the GIL released.
#[pyfunction]
#[pyo3(signature = (config=None, *, seed=None, replicate=0))]
pub fn run<'py>(
    py: Python<'py>,
    config: Option<&Bound<'py, PyAny>>,
    seed: Option<i64>,
    replicate: u32,
) -> PyResult<Bound<'py, PyDict>> {
    let config = crate::config::load(py, config, seed)?;
    let plan = SessionPlan::from_config(&config, replicate);
    let mut trace = TraceColumns::default();
    let output = py
        .detach(|| simulate_plan_streaming(&config, plan, replicate, &mut |row| trace.push(&row)))
        .map_err(|e| lab_error(py, LabError::Sim(e)))?;
    let result = PyDict::new(py);
    result.set_item("metrics", metrics_dict(py, &output.metrics)?)?;
    result.set_item("trace_columns", to_py(py, trace.into_columns())?)?;
    result.set_item(
        "table",
        metrics_table(&output.metrics, output.private.as_ref()),
    )?;
    result.set_item("config", config.to_toml())?;
    result.set_item("seed", config.run.seed)?;
    result.set_item("replicate", replicate)?;
    Ok(result)
}
