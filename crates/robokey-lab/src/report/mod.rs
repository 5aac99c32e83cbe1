//! `robokey report`: the figures and `report.md` of a complete sweep folder or suite folder,
//! rendered from its files alone — nothing is simulated. A sweep of
//! `experiments/paper.toml` gets the paper's report ([`paper`]), which also renders the
//! stages `reproduce` computed into it; any other sweep a report of each experiment's
//! metrics against its axes ([`generic`]). The renderers of the stages ([`secrecy`],
//! [`private`], [`rate_map`], [`adversary`]) also serve `robokey secrecy` and `robokey eve`.

pub mod adversary;
pub mod figures;
pub mod generic;
pub mod paper;
pub mod paper_sections;
pub mod private;
pub mod rate_map;
pub mod secrecy;
pub mod trend;
pub mod world;

use std::path::{Path, PathBuf};

use crate::error::LabError;
use crate::folder::load::load;
use crate::reproduce::suite::PAPER_EXPERIMENTS;

pub use figures::trajectory_figure;

/// What `report` produced.
#[derive(Clone, Debug)]
pub struct Report {
    /// `report.md`.
    pub path: PathBuf,
    /// A few lines for the terminal.
    pub summary: String,
}

/// Makes the figures (`figures/`) and `report.md` of a complete sweep folder or suite
/// folder, from its files alone: the paper's report for a sweep of `experiments/paper.toml`
/// (a suite holding its four experiments, with the stages `reproduce` computes), else a
/// report of each experiment's metrics against its axes.
///
/// # Errors
/// The folder is not a complete sweep (an interrupted sweep, a lone shard), a paper suite
/// without its stages, a file that does not read back, a figure or file that cannot be
/// written.
pub fn report(dir: &Path) -> Result<Report, LabError> {
    let loaded = load(dir)?;
    let paper = PAPER_EXPERIMENTS
        .iter()
        .all(|name| loaded.iter().any(|l| l.experiment.name == *name));
    if paper {
        let stages = paper::PaperStages::read(dir, &loaded)?;
        paper::paper_report(dir, &loaded, &stages)
    } else {
        generic::report(dir, &loaded)
    }
}
