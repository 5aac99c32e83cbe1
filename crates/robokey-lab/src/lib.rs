//! robokey-lab: the experiment shell around the robokey core — configuration files,
//! sweeps, parallel runs, CSV/JSON outputs, statistics, figures and reports.

pub mod adversary;
pub mod config_doc;
pub mod error;
pub mod files;
pub mod folder;
pub mod generic_report;
pub mod plot;
pub mod private_report;
pub mod report;
pub mod results;
pub mod runner;
pub mod secrecy;
pub mod sessions;
pub mod stats;
pub mod sweep;
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
