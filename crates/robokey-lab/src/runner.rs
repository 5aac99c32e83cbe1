//! Runs an experiment's grid in parallel, deterministically: results are collected in
//! run-index order, and every run draws from its own per-purpose, per-replicate streams,
//! so any `--jobs` and any sharding give the same numbers.

use std::io::IsTerminal;
use std::str::FromStr;

use indicatif::{ParallelProgressIterator, ProgressBar, ProgressStyle};
use rayon::prelude::*;
use robokey::Metrics;
use robokey::protocol::SessionPlan;
use robokey::sim::{TraceRow, simulate_plan};

use crate::error::LabError;
use crate::sweep::Experiment;

/// Shard `index` of `count` (1-based): runs whose index ≡ index − 1 (mod count).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// 1-based shard number.
    pub index: usize,
    /// Number of shards.
    pub count: usize,
}

impl Shard {
    /// The whole sweep.
    pub const ALL: Self = Self { index: 1, count: 1 };

    /// Whether run `run` belongs to this shard.
    #[must_use]
    pub fn contains(self, run: usize) -> bool {
        run % self.count == self.index - 1
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl FromStr for Shard {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let bad = || format!("shard `{text}`: expected m/n with 1 ≤ m ≤ n, e.g. 2/8");
        let (m, n) = text.split_once('/').ok_or_else(bad)?;
        let (index, count): (usize, usize) = (
            m.trim().parse().map_err(|_| bad())?,
            n.trim().parse().map_err(|_| bad())?,
        );
        if index == 0 || index > count {
            return Err(bad());
        }
        Ok(Self { index, count })
    }
}

/// One finished run.
#[derive(Clone, Debug)]
pub struct RunRecord {
    /// Run index = point · replicates + replicate.
    pub run: usize,
    /// Grid point.
    pub point: usize,
    /// Replicate within the point.
    pub replicate: u32,
    /// The run's metrics.
    pub metrics: Metrics,
    /// The trace, for replicate 0 when the sweep asks for traces.
    pub trace: Option<Vec<TraceRow>>,
}

/// A progress bar on a terminal, hidden otherwise.
#[must_use]
pub fn progress_bar(len: usize, message: &str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len as u64).with_message(message.to_owned());
    bar.set_style(
        ProgressStyle::with_template("{msg:>12} [{bar:40}] {pos}/{len} runs, {per_sec}, eta {eta}")
            .expect("a valid template")
            .progress_chars("=> "),
    );
    bar
}

/// Runs this shard's part of the experiment on the current rayon pool.
///
/// # Errors
/// The first run whose session aborted.
pub fn run_experiment(experiment: &Experiment, shard: Shard) -> Result<Vec<RunRecord>, LabError> {
    let replicates = experiment.replicates() as usize;
    let plans: Vec<SessionPlan> = experiment
        .points
        .iter()
        .map(|p| SessionPlan::from_config(&p.config, 0))
        .collect();
    let runs: Vec<usize> = (0..experiment.runs())
        .filter(|&r| shard.contains(r))
        .collect();
    let label = if experiment.name.is_empty() {
        "sweep"
    } else {
        &experiment.name
    };
    let bar = progress_bar(runs.len(), label);
    let records = runs
        .par_iter()
        .progress_with(bar.clone())
        .map(|&run| {
            let (point, replicate) = (run / replicates, (run % replicates) as u32);
            let mut plan = plans[point].clone();
            plan.session = replicate;
            let with_trace = experiment.traces && replicate == 0;
            let output = simulate_plan(
                &experiment.points[point].config,
                plan,
                replicate,
                with_trace,
            )?;
            Ok(RunRecord {
                run,
                point,
                replicate,
                metrics: output.metrics,
                trace: with_trace.then_some(output.trace),
            })
        })
        .collect::<Result<Vec<_>, LabError>>();
    bar.finish_and_clear();
    records
}

/// Runs `f` on a rayon pool of `jobs` threads (0: one per core; never more than one per core).
///
/// # Errors
/// The pool cannot be built.
pub fn with_jobs<T: Send>(jobs: usize, f: impl FnOnce() -> T + Send) -> Result<T, LabError> {
    // More threads than cores only add overhead to this CPU-bound work.
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    let jobs = if jobs == 0 { cores } else { jobs.min(cores) };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .build()
        .map_err(|e| LabError::Merge(format!("cannot start {jobs} worker threads: {e}")))?;
    Ok(pool.install(f))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_parse_and_partition() {
        assert_eq!("2/3".parse::<Shard>(), Ok(Shard { index: 2, count: 3 }));
        assert!("0/3".parse::<Shard>().is_err());
        assert!("4/3".parse::<Shard>().is_err());
        assert!("x".parse::<Shard>().is_err());
        let shards: Vec<Shard> = (1..=3).map(|i| Shard { index: i, count: 3 }).collect();
        for run in 0..20 {
            assert_eq!(shards.iter().filter(|s| s.contains(run)).count(), 1);
        }
    }
}
