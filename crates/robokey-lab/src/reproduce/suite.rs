//! The paper's suite, `experiments/paper.toml`, embedded so that `reproduce` needs no file.

use robokey::config::{parse_table, set_path};

use crate::error::LabError;
use crate::experiment::{Experiment, experiments_from_table};

/// The paper's experiment suite.
pub const PAPER_TOML: &str = include_str!("../../../../experiments/paper.toml");

/// The experiments of the paper's suite whose sweep folders make the paper's report.
pub const PAPER_EXPERIMENTS: [&str; 4] = ["dv-sweep", "eve-sweep", "baseline", "trajectory"];

/// The paper's suite as `reproduce` sweeps it: `experiments/paper.toml`; `quick`: 3
/// replicates per point.
///
/// # Errors
/// The embedded file is inconsistent.
pub fn paper_suite(quick: bool) -> Result<Vec<Experiment>, LabError> {
    let mut table = parse_table(PAPER_TOML, "experiments/paper.toml")?;
    if quick {
        set_path(&mut table, "run.replicates", 3.into())?;
    }
    experiments_from_table(table, "experiments/paper.toml")
}
