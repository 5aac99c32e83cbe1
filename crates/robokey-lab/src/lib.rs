//! robokey-lab: the experiment shell around the robokey core — configuration files,
//! sweeps, parallel runs, CSV/JSON outputs, statistics, figures and reports.

pub mod adversary;
pub mod error;
pub mod files;
pub mod plot;
pub mod private_report;
pub mod report;
pub mod results;
pub mod runner;
pub mod secrecy;
pub mod stats;
pub mod sweep;
pub mod trace;

pub use error::LabError;
