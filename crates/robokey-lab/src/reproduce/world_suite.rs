//! The worlds of `reproduce` (docs/world.md, "Over-claims"): a coarse version of
//! `experiments/worlds.toml` — one world per physical effect the parties' configuration leaves
//! out — each analysed against the eavesdroppers who know it, so the report can say which
//! worlds the key over-claims.

use robokey::config::{EveStrategy, parse_table};

use crate::error::LabError;
use crate::experiment::{Experiment, experiments_from_table};
use crate::secrecy::SecrecyOptions;

/// The full map, embedded: `reproduce` computes a coarse version of it.
pub const WORLDS_TOML: &str = include_str!("../../../../experiments/worlds.toml");

/// The folder of the worlds, in the reproduction's folder.
pub const WORLDS_DIR: &str = "worlds";

/// Least raw bits of a block with `--quick` (else the file's).
const QUICK_BLOCK_BITS: u64 = 2_000;

/// Sessions simulated per world with `--quick`: about 450 raw bits each, so one block of
/// [`QUICK_BLOCK_BITS`] with room to spare (else sessions are added 32 at a time).
const QUICK_SESSIONS: u32 = 8;

/// The coarse grid: per experiment of `experiments/worlds.toml`, the one point kept.
const COARSE: [(&str, &str); 5] = [
    ("motion", "\"world.process_std\" = [[0.001, 0.001, 0.001]]"),
    ("correlation", "\"world.process_rho\" = [0.9]"),
    ("slip", "\"world.slip_std\" = [0.2]"),
    (
        "lag",
        "\"world.lag\" = [0.05]\n\"world.process_std\" = [[0.001, 0.001, 0.001]]",
    ),
    (
        "camera",
        "\"world.camera_fps\" = [30.0]\n\"world.camera_frame_std\" = [[0.008, 0.008, 0.008]]",
    ),
];

/// The embedded suite, each experiment cut to its coarse point (the delay's dropped), its
/// blocks of 2,000 raw bits with `--quick`.
///
/// # Errors
/// The embedded file does not read as a suite (a bug: it is tested).
pub fn coarse_suite(quick: bool) -> Result<Vec<Experiment>, LabError> {
    let origin = "experiments/worlds.toml";
    let mut table = parse_table(WORLDS_TOML, origin)?;
    let malformed = |message: String| LabError::Sweep {
        origin: origin.into(),
        message,
    };
    let suite = table
        .get_mut("experiment")
        .and_then(toml::Value::as_table_mut)
        .ok_or_else(|| malformed("no [experiment.*] tables".into()))?;
    suite.retain(|name: &str, _| COARSE.iter().any(|(kept, _)| *kept == name));
    for (name, axes) in COARSE {
        let sweep: toml::Table = axes
            .parse()
            .map_err(|e| malformed(format!("the coarse axes of {name}: {e}")))?;
        let experiment = suite
            .get_mut(name)
            .and_then(toml::Value::as_table_mut)
            .ok_or_else(|| malformed(format!("no [experiment.{name}]")))?;
        experiment.insert("sweep".into(), toml::Value::Table(sweep));
    }
    if quick {
        table
            .entry("secrecy")
            .or_insert_with(|| toml::Value::Table(toml::Table::new()))
            .as_table_mut()
            .ok_or_else(|| malformed("[secrecy] is not a table".into()))?
            .insert("block_bits".into(), (QUICK_BLOCK_BITS as i64).into());
    }
    experiments_from_table(table, origin)
}

/// The analysis of one world: the camera eavesdropper who knows it (the strongest; the
/// full map adds the commands one), complete pooling, the block size and ε its file states;
/// with `--quick` at most `QUICK_SESSIONS` sessions.
#[must_use]
pub fn options(experiment: &Experiment, quick: bool) -> SecrecyOptions {
    let stated = super::private_suite::as_stated(experiment);
    SecrecyOptions {
        adversaries: vec![EveStrategy::Camera],
        max_sessions: if quick {
            QUICK_SESSIONS
        } else {
            stated.max_sessions
        },
        ..stated
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_coarse_worlds_are_one_point_each_of_the_full_file() {
        let full =
            experiments_from_table(parse_table(WORLDS_TOML, "worlds").unwrap(), "worlds").unwrap();
        assert_eq!(full.len(), 6);
        for quick in [false, true] {
            let coarse = coarse_suite(quick).unwrap();
            assert_eq!(coarse.len(), COARSE.len());
            for e in &coarse {
                assert_eq!(e.points.len(), 1, "{}", e.name);
                let config = &e.points[0].config;
                assert!(
                    !config.world_model().differences(config).is_empty(),
                    "{}",
                    e.name
                );
                let blocks = options(e, quick).block_bits;
                assert_eq!(blocks, if quick { 2_000 } else { 10_000 });
            }
        }
    }
}
