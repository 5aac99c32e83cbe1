//! `robokey.eve`: the eavesdroppers on a recorded session — what `robokey eve --capture`
//! prints and writes as `capture.json` (robokey-net's `recorded_eve`), returned instead.

use std::path::PathBuf;

use pyo3::prelude::*;
use robokey::config::EveStrategy;
use robokey_net::NetError;
use robokey_net::recorded_eve::{
    Heard, Naming, RecordedSessions, check_strategies, explicit_errors, hear,
};

use crate::errors::net_error;
use crate::secrecy::strategy;

/// Runs the eavesdroppers on recorded sessions as `robokey eve --capture` does, with the GIL
/// released: odometry sensing, one capture; private sensing, one capture per session with her
/// camera's log, and with `block` (an agent report) her bound over the block. Returns
/// `(capture_json, shortfalls)`: the text of the `capture.json` robokey would write, and what
/// of the captures could not be read (`path: why`, as the command warns).
#[pyfunction]
#[pyo3(signature = (
    capture, config=None, *, camera_log=Vec::new(), robot_key=Vec::new(),
    controller_key=Vec::new(), block=None, strategy=Vec::new(), errors=None, seed=None
))]
#[allow(clippy::too_many_arguments)]
pub fn eve(
    py: Python<'_>,
    capture: Vec<PathBuf>,
    config: Option<&Bound<'_, PyAny>>,
    camera_log: Vec<PathBuf>,
    robot_key: Vec<PathBuf>,
    controller_key: Vec<PathBuf>,
    block: Option<PathBuf>,
    strategy: Vec<String>,
    errors: Option<Vec<f64>>,
    seed: Option<i64>,
) -> PyResult<(String, Vec<String>)> {
    let config = crate::config::load(py, config, seed)?;
    let strategies = strategy
        .iter()
        .map(|name| self::strategy(name))
        .collect::<PyResult<Vec<EveStrategy>>>()?;
    check_strategies(&strategies, config.sensing.mode, Naming::Keywords).map_err(net_error)?;
    let errors = errors
        .map(|values| {
            explicit_errors(&values)
                .map_err(|e| net_error(NetError::Usage(format!("errors={values:?}: {e}"))))
        })
        .transpose()?;
    let sessions = RecordedSessions {
        captures: &capture,
        camera_logs: &camera_log,
        robot_keys: &robot_key,
        controller_keys: &controller_key,
        block: block.as_deref(),
        strategies: &strategies,
        errors,
    };
    let heard = py
        .detach(|| hear(sessions, &config, Naming::Keywords))
        .map_err(net_error)?;
    let shortfalls = match &heard {
        Heard::Odometry(report) => vec![(&capture[0], &report.shortfalls)],
        Heard::Private(report) => capture
            .iter()
            .zip(&report.sessions)
            .map(|(path, session)| (path, &session.shortfalls))
            .collect(),
    };
    let warnings = shortfalls
        .into_iter()
        .flat_map(|(path, shortfalls)| {
            shortfalls
                .iter()
                .map(move |s| format!("{}: {s}", path.display()))
        })
        .collect();
    let json = serde_json::to_value(&heard)
        .and_then(|value| serde_json::to_string(&value))
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    Ok((json, warnings))
}
