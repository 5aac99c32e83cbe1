//! `robokey.threat`: what a camera of Eve's leaves of the key at a configuration, as
//! `robokey threat` computes it (docs/threat-model.md), returned instead of printed.

use pyo3::prelude::*;
use robokey::world::Camera;
use robokey_lab::run::with_jobs;

use crate::errors::{InputError, lab_error};

/// The cameras of the keywords (mm; every combination of `fps` and `frame_std`), else the
/// configuration's own statement.
fn cameras(
    camera_std: Option<Vec<f64>>,
    fps: Option<Vec<f64>>,
    frame_std: Option<Vec<f64>>,
    own: Camera,
) -> PyResult<Vec<Camera>> {
    let mut out: Vec<Camera> = camera_std
        .unwrap_or_default()
        .into_iter()
        .map(|mm| Camera::Instants {
            std: [mm * 1e-3; 3],
        })
        .collect();
    match (fps, frame_std) {
        (None, None) => {}
        (Some(fps), Some(frame_std)) => {
            for f in fps {
                out.extend(frame_std.iter().map(|&mm| Camera::Frames {
                    fps: f,
                    frame_std: [mm * 1e-3; 3],
                }));
            }
        }
        _ => {
            return Err(InputError::new_err(
                "fps and frame_std are given together (her frames per second and the noise \
                 of each frame, mm)",
            ));
        }
    }
    if out.is_empty() {
        out.push(own);
    }
    Ok(out)
}

/// For each camera — `camera_std` (mm per sample instant), or every combination of `fps`
/// (frames/s) and `frame_std` (mm per frame) — at `config` (evaluated in private sensing):
/// its per-instant equivalent and the rate of a key sized against it; then the break-even
/// camera. Without cameras, the configuration's own. Returns the JSON `robokey threat --json`
/// prints; computed on `jobs` threads with the GIL released.
#[pyfunction]
#[pyo3(signature = (config=None, *, seed=None, camera_std=None, fps=None, frame_std=None, jobs=0))]
pub fn threat(
    py: Python<'_>,
    config: Option<&Bound<'_, PyAny>>,
    seed: Option<i64>,
    camera_std: Option<Vec<f64>>,
    fps: Option<Vec<f64>>,
    frame_std: Option<Vec<f64>>,
    jobs: usize,
) -> PyResult<String> {
    let config = crate::config::load(py, config, seed)?;
    let cameras = cameras(camera_std, fps, frame_std, config.camera_statement())?;
    let figures = py
        .detach(|| with_jobs(jobs, || robokey_lab::threat::threat(&config, &cameras)))
        .map_err(|e| lab_error(py, e))?
        .map_err(|e| lab_error(py, e))?;
    serde_json::to_string(&figures)
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))
}
