//! The private-sensing map of `reproduce` (docs/private-sensing.md): a coarse version of
//! `experiments/private-sensing.toml` — the secret rate against Eve's camera noise with its
//! break-even, and the rate against tracking cost over Δv, which the report also draws
//! beside each point's limit (the binary corner of `experiments/private-rates.toml`) — and
//! the analysis each of its experiments gets.

use robokey::config::{EveStrategy, parse_table};

use crate::error::LabError;
use crate::experiment::{Experiment, experiments_from_table};
use crate::secrecy::map::CAMERA_FIELD;
use crate::secrecy::{Pooling, SecrecyOptions};

/// The full map, embedded: `reproduce` computes a coarse version of it.
pub const PRIVATE_SENSING_TOML: &str = include_str!("../../../../experiments/private-sensing.toml");

/// The folder of the map, in the reproduction's folder.
pub const PRIVATE_SENSING_DIR: &str = "private-sensing";
/// The experiment of the rate against Eve's camera noise.
pub const CAMERA_EXPERIMENT: &str = "camera";
/// The experiment of the rate against tracking cost over Δv.
pub const FRONT_EXPERIMENT: &str = "pareto-v";

/// What the section costs on the 2-core reference machine (s), stated in the report.
pub const BUDGET_SECONDS: u32 = 30;

/// Eve's camera noise (mm) and motion noise (mm) of the coarse map; fewer with `--quick`.
fn coarse_grid(quick: bool) -> (&'static [f64], &'static [f64]) {
    if quick {
        (&[2.0, 4.0, 8.0], &[4.0])
    } else {
        (&[1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 16.0], &[2.0, 4.0])
    }
}

fn millimetres(values: &[f64]) -> toml::Value {
    toml::Value::Array(
        values
            .iter()
            .map(|&mm| toml::Value::Array(vec![(mm / 1e3).into(); 3]))
            .collect(),
    )
}

/// The embedded suite with its axes made coarse: the camera map, and the Δv front with one
/// bit per doublet at three values.
pub fn coarse_suite(quick: bool) -> Result<Vec<Experiment>, LabError> {
    let origin = "experiments/private-sensing.toml";
    let mut table = parse_table(PRIVATE_SENSING_TOML, origin)?;
    let (camera, motion) = coarse_grid(quick);
    let suite = table
        .get_mut("experiment")
        .and_then(toml::Value::as_table_mut)
        .ok_or_else(|| LabError::Sweep {
            origin: origin.into(),
            message: "no [experiment.*] tables".into(),
        })?;
    suite.remove("pareto-v-omega");
    let mut axis = |experiment: &str, field: &str, value: toml::Value| {
        suite
            .get_mut(experiment)
            .and_then(|e| e.get_mut("sweep"))
            .and_then(toml::Value::as_table_mut)
            .map(|sweep| sweep.insert(field.into(), value))
            .ok_or_else(|| LabError::Sweep {
                origin: origin.into(),
                message: format!("no [experiment.{experiment}.sweep]"),
            })
    };
    axis(CAMERA_EXPERIMENT, CAMERA_FIELD, millimetres(camera))?;
    axis(CAMERA_EXPERIMENT, "noise.process_std", millimetres(motion))?;
    axis(
        FRONT_EXPERIMENT,
        "protocol.delta_v",
        toml::Value::Array(vec![0.02.into(), 0.035.into(), 0.05.into()]),
    )?;
    experiments_from_table(table, origin)
}

/// The analysis of one experiment of the map: the camera adversary (and, except on the
/// camera map, the commands one), complete pooling, the block size and ε its file states.
#[must_use]
pub fn options(experiment: &Experiment) -> SecrecyOptions {
    let mut adversaries = vec![EveStrategy::Camera];
    if experiment.name != CAMERA_EXPERIMENT {
        adversaries.push(EveStrategy::Commands);
    }
    SecrecyOptions {
        adversaries,
        ..as_stated(experiment)
    }
}

/// The defaults with complete pooling and the block size and ε `experiment`'s file states.
pub(super) fn as_stated(experiment: &Experiment) -> SecrecyOptions {
    let defaults = SecrecyOptions::default();
    SecrecyOptions {
        pooling: Pooling::Complete,
        block_bits: experiment
            .secrecy
            .block_bits
            .map_or(defaults.block_bits, |b| b as usize),
        epsilon: experiment.secrecy.epsilon.unwrap_or(defaults.epsilon),
        ..defaults
    }
}
