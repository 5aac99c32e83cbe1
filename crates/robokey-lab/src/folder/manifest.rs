//! `manifest.json`: what wrote a sweep folder (robokey's version and commit, the resolved
//! configuration's digest, the seed), which shards it holds and whether it holds every run
//! of them.

use std::path::Path;

use serde_json::{Map, Value, json};

use crate::error::LabError;
use crate::experiment::Experiment;
use crate::output::read;
use crate::run::Shard;

/// What a folder's `manifest.json` says about its runs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Manifest {
    /// The experiment's name (empty for a single sweep).
    pub experiment: String,
    /// The shards whose runs the folder holds.
    pub shards: Vec<Shard>,
    /// Whether it holds every run of its shards.
    pub complete: bool,
    /// Runs done.
    pub runs_done: usize,
    /// SHA-256 of `config.resolved.toml`.
    pub config_sha256: String,
    /// The commit of the robokey that wrote it.
    pub git_commit: String,
}

/// The manifest of the robokey that is running, for a folder holding `runs_done` runs of
/// `shards`.
#[must_use]
pub fn manifest(experiment: &Experiment, shards: &[Shard], runs_done: usize) -> Manifest {
    Manifest {
        experiment: experiment.name.clone(),
        shards: shards.to_vec(),
        complete: runs_done == planned(experiment, shards).count(),
        runs_done,
        config_sha256: sha256_hex(&experiment.resolved_toml()),
        git_commit: env!("ROBOKEY_GIT_COMMIT").to_owned(),
    }
}

/// The runs of `shards`, in run order.
pub fn planned(experiment: &Experiment, shards: &[Shard]) -> impl Iterator<Item = usize> {
    let shards = shards.to_vec();
    (0..experiment.runs()).filter(move |&r| shards.iter().any(|s| s.contains(r)))
}

/// Lower-case hex SHA-256 of a text.
#[must_use]
pub fn sha256_hex(text: &str) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(text.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// `manifest.json`: what produced the folder and whether it holds every run of its shards.
/// Nothing in it depends on the time or the machine's load, so an interrupted sweep that
/// is resumed ends with the same bytes as one that never stopped.
#[must_use]
pub fn manifest_json(experiment: &Experiment, manifest: &Manifest) -> String {
    let crates: Map<String, Value> = env!("ROBOKEY_NUMERIC_CRATES")
        .split(',')
        .filter_map(|kv| kv.split_once('='))
        .map(|(k, v)| (k.to_owned(), json!(v)))
        .collect();
    let json = json!({
        "tool": "robokey",
        "version": env!("CARGO_PKG_VERSION"),
        "git_commit": manifest.git_commit,
        "experiment": manifest.experiment,
        "config_sha256": manifest.config_sha256,
        "seed": experiment.points[0].config.run.seed,
        "points": experiment.points.len(),
        "replicates": experiment.replicates(),
        "runs": experiment.runs(),
        "shards": manifest.shards.iter().map(ToString::to_string).collect::<Vec<_>>(),
        "runs_done": manifest.runs_done,
        "complete": manifest.complete,
        "numeric_crates": crates,
        "platform": format!("{}-{}", std::env::consts::ARCH, std::env::consts::OS),
        "rng": "ChaCha8, seed_p = SHA-256(\"robokey v1\" ‖ seed_le ‖ purpose), stream = replicate",
    });
    serde_json::to_string_pretty(&json).expect("JSON serializes") + "\n"
}

/// Reads a folder's `manifest.json`.
///
/// # Errors
/// It is missing or is not a manifest robokey wrote.
pub fn read_manifest(dir: &Path) -> Result<Manifest, LabError> {
    let path = dir.join("manifest.json");
    let bad = |why: &str| LabError::Malformed {
        place: path.display().to_string(),
        message: why.to_owned(),
    };
    let json: Value = serde_json::from_str(&read(&path)?).map_err(|e| bad(&e.to_string()))?;
    let text = |key: &str| json[key].as_str().map(str::to_owned);
    let shards = json["shards"]
        .as_array()
        .ok_or_else(|| bad("no `shards` list"))?
        .iter()
        .map(|s| s.as_str().and_then(|s| s.parse::<Shard>().ok()))
        .collect::<Option<Vec<_>>>()
        .ok_or_else(|| bad("a shard that is not m/n"))?;
    Ok(Manifest {
        experiment: text("experiment").unwrap_or_default(),
        shards,
        // Folders written before sweeps could be interrupted were always complete.
        complete: json["complete"].as_bool().unwrap_or(true),
        runs_done: json["runs_done"]
            .as_u64()
            .or_else(|| json["runs"].as_u64())
            .map_or(0, |n| n as usize),
        config_sha256: text("config_sha256").unwrap_or_default(),
        git_commit: text("git_commit").unwrap_or_default(),
    })
}
