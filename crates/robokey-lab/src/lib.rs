//! robokey-lab: the experiment shell around the robokey core. It computes — sweeps of
//! parallel runs ([`run`]) into folders ([`folder`]), the secrecy analysis ([`secrecy`]), the
//! eavesdropping campaigns ([`adversary`]), the paper's stages ([`reproduce`]) — and writes
//! each result into its folder; then it renders reports from the folders alone ([`report`]).

pub mod adversary;
pub mod config_doc;
pub mod csv_field;
pub mod error;
pub mod experiment;
pub mod folder;
pub mod metric_table;
pub mod output;
pub mod parquet_table;
pub mod plot;
pub mod progress;
pub mod reals;
pub mod report;
pub mod reproduce;
pub mod run;
pub mod secrecy;
pub mod stats;
pub mod table;
pub mod trace;
pub mod trace_table;

pub use error::LabError;

/// The version `--version` prints: the crate's and the git commit it was built from
/// (`-dirty` when the tree had uncommitted changes).
pub const VERSION: &str = concat!(
    env!("CARGO_PKG_VERSION"),
    " (commit ",
    env!("ROBOKEY_GIT_COMMIT"),
    ")"
);
