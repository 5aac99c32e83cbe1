//! The secrecy stage of a sweep folder: the analysis computed once and written beside the
//! runs — `secrecy.json` (the settings and every point's result against every adversary)
//! and, in private sensing, `private-map.json` — then read back by reports, which render
//! them without simulating anything.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::analyze::analyze_with;
use super::map::{PrivateMap, private_map};
use super::options::{Reconciliation, SecrecyOptions, Sizing};
use super::pipeline::Pooling;
use super::point::PointSecrecy;
use crate::error::{LabError, io_at};
use crate::experiment::Experiment;
use crate::output::{read_json, write};
use crate::run::sessions::SessionBank;

/// The file of the results.
pub const SECRECY_JSON: &str = "secrecy.json";
/// The file of a private-sensing map.
pub const PRIVATE_MAP_JSON: &str = "private-map.json";

/// The secrecy of an experiment's points: everything a report of it shows.
#[derive(Clone, Debug, PartialEq)]
pub struct Secrecy {
    /// ε per term; the key is 4ε-secret.
    pub epsilon: f64,
    /// Least pooled raw bits per block.
    pub block_bits: usize,
    /// Which sessions were pooled.
    pub pooling: Pooling,
    /// What sized private sensing's key.
    pub sizing: Sizing,
    /// How `complete` pooling reconciled.
    pub reconciliation: Reconciliation,
    /// Per point and adversary, strongest class first.
    pub results: Vec<PointSecrecy>,
    /// Private sensing: where it pays ([`private_map`]).
    pub map: Option<PrivateMap>,
}

/// `secrecy.json` as read back (`epsilon_total`, written for people, is 4ε).
#[derive(Deserialize)]
struct SecrecyFile {
    epsilon: f64,
    block_bits: usize,
    pooling: Pooling,
    #[serde(default)]
    sizing: Sizing,
    #[serde(default)]
    reconciliation: Reconciliation,
    results: Vec<PointSecrecy>,
}

impl Secrecy {
    /// Analyzes every point of `experiment` against every adversary of `options` (hearing
    /// the sessions of `bank`, see [`analyze_with`]) and, in private sensing, maps where it
    /// pays; on the current rayon pool. Deterministic.
    ///
    /// # Errors
    /// An option that does not fit the sensing mode, or a session that aborts.
    pub fn compute(
        experiment: &Experiment,
        options: &SecrecyOptions,
        bank: &mut SessionBank,
    ) -> Result<Self, LabError> {
        let results = analyze_with(experiment, options, bank)?;
        let map = private_map(experiment, &results)?;
        Ok(Self {
            epsilon: options.epsilon,
            block_bits: options.block_bits,
            pooling: options.pooling,
            sizing: options.sizing,
            reconciliation: options.reconciliation,
            results,
            map,
        })
    }

    /// Whether measured sizing applied: private sensing with `--sizing measured` (or `world`).
    fn measured(&self) -> bool {
        self.sizing != Sizing::Configured
            && self
                .results
                .iter()
                .any(|r| r.blocks.iter().any(|b| b.estimate.is_some()))
    }

    /// The named ε terms, for people: "ε_s = ε_PA = ε_PE", and "= ε_est" when the plant
    /// was measured.
    #[must_use]
    pub fn epsilon_terms(&self) -> &'static str {
        if self.measured() {
            "ε_s = ε_PA = ε_PE = ε_est"
        } else {
            "ε_s = ε_PA = ε_PE"
        }
    }

    /// The key's total ε: 2ε_s + ε_PA + ε_PE, + ε_est when the plant was measured.
    #[must_use]
    pub fn epsilon_total(&self) -> f64 {
        if self.measured() {
            // Five terms, read back at 12 digits so that 5 × 10⁻⁶ prints as 5e-6.
            format!("{:.12e}", 5.0 * self.epsilon)
                .parse()
                .unwrap_or(5.0 * self.epsilon)
        } else {
            4.0 * self.epsilon
        }
    }

    /// The contents of `secrecy.json`: the settings (`epsilon_total`, for people, is 4ε) and
    /// every result.
    #[must_use]
    pub fn json(&self) -> serde_json::Value {
        let mut json = serde_json::json!({
            "epsilon": self.epsilon,
            "epsilon_total": self.epsilon_total(),
            "block_bits": self.block_bits,
            "pooling": self.pooling,
            "results": self.results,
        });
        if self.sizing != Sizing::Configured {
            json["sizing"] = serde_json::json!(self.sizing);
        }
        if !self.reconciliation.is_cascade() {
            json["reconciliation"] = serde_json::json!(self.reconciliation);
        }
        json
    }

    /// The contents of `private-map.json`, if the sweep has a map.
    #[must_use]
    pub fn map_json(&self) -> Option<serde_json::Value> {
        self.map.as_ref().map(|map| serde_json::json!(map))
    }

    /// Writes `secrecy.json` and, with a map, `private-map.json` into `dir` (removing a map
    /// an earlier analysis left); returns the files.
    ///
    /// # Errors
    /// A file cannot be written.
    pub fn write(&self, dir: &Path) -> Result<Vec<PathBuf>, LabError> {
        std::fs::create_dir_all(dir).map_err(io_at(dir))?;
        let mut files = vec![write(&dir.join(SECRECY_JSON), pretty(&self.json()))?];
        let map_file = dir.join(PRIVATE_MAP_JSON);
        match self.map_json() {
            Some(map) => files.push(write(&map_file, pretty(&map))?),
            None if map_file.exists() => {
                std::fs::remove_file(&map_file).map_err(io_at(&map_file))?;
            }
            None => {}
        }
        Ok(files)
    }

    /// Reads the results [`Secrecy::write`] wrote into `dir`, the folder of `experiment`.
    ///
    /// # Errors
    /// `secrecy.json` is missing, a file does not read back, or a result names a point the
    /// experiment does not have.
    pub fn read(dir: &Path, experiment: &Experiment) -> Result<Self, LabError> {
        let path = dir.join(SECRECY_JSON);
        let file: SecrecyFile = read_json(&path)?;
        let points = experiment.points.len();
        if let Some(r) = file.results.iter().find(|r| r.point_index >= points) {
            return Err(LabError::Malformed {
                place: path.display().to_string(),
                message: format!(
                    "a result of point {}, and the sweep has {points} points: not this \
                     folder's analysis",
                    r.point_index
                ),
            });
        }
        let map_file = dir.join(PRIVATE_MAP_JSON);
        let map = if map_file.exists() {
            Some(read_json(&map_file)?)
        } else {
            None
        };
        Ok(Self {
            epsilon: file.epsilon,
            block_bits: file.block_bits,
            pooling: file.pooling,
            sizing: file.sizing,
            reconciliation: file.reconciliation,
            results: file.results,
            map,
        })
    }
}

/// JSON for people: indented, keys in order, a final newline.
fn pretty(json: &serde_json::Value) -> String {
    serde_json::to_string_pretty(json).expect("JSON serializes") + "\n"
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::secrecy::default_adversaries;

    fn experiment(text: &str) -> Experiment {
        Experiment::from_table("t", text.parse().unwrap(), "test.toml").unwrap()
    }

    /// What a report reads back is what was computed, bit for bit, in both sensing modes.
    #[test]
    fn the_results_read_back_exactly() {
        let dir = std::env::temp_dir().join(format!("robokey-secrecy-{}", std::process::id()));
        let odometry = experiment("[run]\nreplicates = 1\n[sweep]\n\"eve.alpha\" = [0.0, 0.1]\n");
        let options = SecrecyOptions {
            block_bits: 1_000,
            bootstrap: 50,
            ..SecrecyOptions::default()
        };
        let computed = Secrecy::compute(&odometry, &options, &mut SessionBank::new()).unwrap();
        assert!(computed.map.is_none() && computed.results.len() == 6);
        computed.write(&dir).unwrap();
        assert_eq!(Secrecy::read(&dir, &odometry).unwrap(), computed);
        let single = experiment("[run]\nreplicates = 1\n");
        let err = Secrecy::read(&dir, &single).unwrap_err().to_string();
        assert!(
            err.contains("a result of point 1, and the sweep has 1 points"),
            "{err}"
        );
        let private = experiment(
            "[sensing]\nmode = \"private\"\n[run]\nreplicates = 1\n\
             [sweep]\n\"protocol.delta_v\" = [0.035, 0.05]\n",
        );
        let options = SecrecyOptions {
            adversaries: default_adversaries(robokey::config::SensingMode::Private),
            pooling: Pooling::Complete,
            block_bits: 2_000,
            bootstrap: 50,
            ..SecrecyOptions::default()
        };
        let computed = Secrecy::compute(&private, &options, &mut SessionBank::new()).unwrap();
        assert!(computed.map.as_ref().is_some_and(|m| m.pareto.len() == 2));
        let files = computed.write(&dir).unwrap();
        assert_eq!(files.len(), 2);
        assert_eq!(Secrecy::read(&dir, &private).unwrap(), computed);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
