//! robokey-lab: the experiment shell around the robokey core — sweeps, parallel runs,
//! CSV/JSON outputs, statistics, figures and reports.

pub mod adversary;
pub mod config_doc;
pub mod error;
pub mod experiment;
pub mod folder;
pub mod metric_table;
pub mod output;
pub mod plot;
pub mod progress;
pub mod reals;
pub mod report;
pub mod reproduce;
pub mod run;
pub mod secrecy;
pub mod stats;
pub mod trace;

pub use error::LabError;

/// The version `--version` prints: the crate's and the git commit it was built from
/// (`-dirty` when the tree had uncommitted changes).
pub const VERSION: &str = concat!(
    env!("CARGO_PKG_VERSION"),
    " (commit ",
    env!("ROBOKEY_GIT_COMMIT"),
    ")"
);
