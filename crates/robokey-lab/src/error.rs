//! Errors of the experiment shell.

use std::path::PathBuf;

/// What can go wrong while loading, running or writing an experiment.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LabError {
    /// A configuration problem (names the file, field, value and allowed range).
    #[error(transparent)]
    Config(#[from] robokey::config::ConfigError),
    /// A sweep definition problem.
    #[error("{origin}: [sweep] {message}")]
    Sweep {
        /// File of the sweep.
        origin: String,
        /// What is wrong.
        message: String,
    },
    /// A file could not be read or written.
    #[error("{path}: {error}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The underlying error (part of the message, so not repeated as a source).
        error: std::io::Error,
    },
    /// A simulation aborted.
    #[error(transparent)]
    Sim(#[from] robokey::sim::SimError),
    /// An output folder already holds results.
    #[error(
        "{0}: the folder is not empty (pass --force to remove robokey's files from it and \
         write anew; files robokey does not write are kept)"
    )]
    NotEmpty(PathBuf),
    /// `--force` on a folder that does not hold robokey's output.
    #[error(
        "{0}: --force clears only folders holding robokey's output (a manifest.json, \
         config.resolved.toml, report.md, metrics.json or secrecy.json); this one has none: \
         choose another --out"
    )]
    NotOutput(PathBuf),
    /// A folder that holds neither a sweep nor a suite of sweeps.
    #[error("{0}: no config.resolved.toml here or in its subfolders (is it a sweep folder?)")]
    NotSweep(PathBuf),
    /// A sweep folder that an interrupted sweep left incomplete.
    #[error(
        "{dir}: an interrupted sweep ({done} of {planned} runs done): finish it first with \
         `robokey sweep FILE --resume` on its sweep folder"
    )]
    Incomplete {
        /// The experiment's folder.
        dir: PathBuf,
        /// Runs done.
        done: usize,
        /// Runs of its shards.
        planned: usize,
    },
    /// A shard's folder where the whole sweep is needed.
    #[error(
        "{dir}: holds shard {shards} only ({held} of the sweep's {total} runs); merge the shards \
         first with `robokey merge`"
    )]
    NotWhole {
        /// The folder.
        dir: PathBuf,
        /// Its shards, e.g. `1/2`.
        shards: String,
        /// Runs it holds.
        held: usize,
        /// Runs of the sweep.
        total: usize,
    },
    /// A sweep folder whose runs are in `runs.parquet`, where robokey reads `runs.csv`.
    #[error(
        "{0}: its runs are in runs.parquet (swept with --format parquet); robokey's report, \
         merge and --resume read runs.csv only: sweep into a folder with --format csv \
         (the default) for those, and read runs.parquet with Arrow/pandas/polars"
    )]
    ParquetRuns(PathBuf),
    /// A folder that `--resume` cannot continue with this sweep.
    #[error("{dir}: cannot resume: {message}")]
    Resume {
        /// The folder.
        dir: PathBuf,
        /// Why not.
        message: String,
    },
    /// Stopped by signal `0` (SIGINT 2, SIGTERM 15) before the work was done.
    #[error("interrupted by signal {0}")]
    Interrupted(usize),
    /// An adversary or option that does not apply in the experiment's sensing mode.
    #[error("{0}")]
    SensingMode(String),
    /// Shards cannot be merged.
    #[error("merge: {0}")]
    Merge(String),
    /// A folder of the paper's suite without the stages `reproduce` computes.
    #[error(
        "{}: the paper's report renders the stages `robokey reproduce` computes (secrecy, \
         eavesdropping campaigns, private sensing), and no reproduce.json vouches for them \
         here: {how}",
        dir.display()
    )]
    Uncomputed {
        /// The folder.
        dir: PathBuf,
        /// How to compute them, or why they cannot be.
        how: String,
    },
    /// A file of an output folder does not read back as robokey wrote it.
    #[error("{place}: {message}")]
    Malformed {
        /// The file, with the line when known (`runs.csv:12`).
        place: String,
        /// What is wrong.
        message: String,
    },
    /// The worker threads could not be started.
    #[error("cannot start {jobs} worker threads: {message}")]
    Threads {
        /// Threads asked for.
        jobs: usize,
        /// Why not.
        message: String,
    },
    /// A figure could not be drawn.
    #[error("figure {path}: {message}")]
    Plot {
        /// The figure's file.
        path: PathBuf,
        /// What failed.
        message: String,
    },
}

impl LabError {
    /// Whether the error is the user's input: a configuration, a sweep definition, an
    /// output or input folder that does not fit the command, an option the sensing mode
    /// does not allow. Not: a file the system cannot read or write, a simulation that
    /// aborted, a figure, a merge of inconsistent shards, a stop by signal.
    #[must_use]
    pub fn is_usage(&self) -> bool {
        match self {
            Self::Config(e) => e.is_usage(),
            Self::Sweep { .. }
            | Self::NotEmpty(_)
            | Self::NotOutput(_)
            | Self::NotSweep(_)
            | Self::NotWhole { .. }
            | Self::Incomplete { .. }
            | Self::Resume { .. }
            | Self::ParquetRuns(_)
            | Self::Uncomputed { .. }
            | Self::SensingMode(_) => true,
            Self::Io { .. }
            | Self::Sim(_)
            | Self::Interrupted(_)
            | Self::Merge(_)
            | Self::Malformed { .. }
            | Self::Threads { .. }
            | Self::Plot { .. } => false,
        }
    }
}

/// Attaches a path to an I/O error.
pub(crate) fn io_at(path: impl Into<PathBuf>) -> impl FnOnce(std::io::Error) -> LabError {
    let path = path.into();
    move |source| LabError::Io {
        path,
        error: source,
    }
}
