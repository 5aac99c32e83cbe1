//! Runs an experiment's grid in parallel, deterministically: results are collected in
//! run-index order, and every run draws from its own per-purpose, per-replicate streams,
//! so any `--jobs` and any sharding give the same numbers.

use std::collections::HashMap;
use std::io::IsTerminal;
use std::path::Path;
use std::str::FromStr;

use indicatif::{ProgressBar, ProgressState, ProgressStyle};
use rayon::prelude::*;
use robokey::Config;
use robokey::Metrics;
use robokey::interrupt::Interrupt;
use robokey::protocol::SessionPlan;
use robokey::sim::{
    RunOutput, TraceRow, replay, simulate_plan, simulate_plan_streaming, simulate_transcript,
};

use crate::error::{LabError, io_at};
use crate::results::trace_path;
use crate::sessions::physical_key;
use crate::sweep::Experiment;
use crate::trace::TraceCsv;

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
    /// Read back from a sweep folder when the sweep kept traces (replicate 0): the paths a
    /// trajectory figure draws of it ([`crate::trace::DrawnRows`]). A sweep streams the
    /// trace to disk as it runs and never holds it.
    pub trace: Option<Vec<Vec<TraceRow>>>,
}

/// A progress bar on a terminal, hidden otherwise: `label [=====>   ] done/len units, rate,
/// eta`.
#[must_use]
pub fn progress_bar(len: usize, label: &str, unit: &'static str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len as u64).with_message(label.to_owned());
    bar.set_style(
        ProgressStyle::with_template(&format!(
            "{{msg:>12}} [{{bar:40}}] {{pos}}/{{len}} {unit}s, {{rate}}, eta {{eta}}"
        ))
        .expect("a valid template")
        .with_key(
            "rate",
            move |state: &ProgressState, out: &mut dyn std::fmt::Write| {
                let _ = out.write_str(&rate_text(state.per_sec(), unit));
            },
        )
        .progress_chars("=> "),
    );
    bar
}

/// A rate for people: three significant figures at most, e.g. "46,700 runs/s", "12.3 runs/s";
/// below one per second, the seconds each takes ("4.2 s/run").
#[must_use]
pub fn rate_text(per_second: f64, unit: &str) -> String {
    if !(per_second.is_finite() && per_second > 0.0) {
        return format!("– {unit}s/s");
    }
    if per_second < 1.0 {
        return format!("{} s/{unit}", significant(1.0 / per_second));
    }
    format!("{} {unit}s/s", significant(per_second))
}

/// Three significant figures; thousands separated by commas.
fn significant(x: f64) -> String {
    if x < 100.0 {
        let decimals = if x < 10.0 { 2 } else { 1 };
        return format!("{x:.decimals$}");
    }
    let magnitude = 10f64.powi(x.log10().floor() as i32 - 2);
    let rounded = ((x / magnitude).round() * magnitude) as u64;
    thousands(rounded)
}

/// An integer with its thousands separated by commas: `10,000`.
pub(crate) fn thousands(n: impl ToString) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// Runs the given runs of the experiment (run indices, see [`RunRecord::run`]) on the
/// current rayon pool, starting none once `stop` is requested; `finished` is called after
/// each run. When the experiment keeps traces, replicate 0 of each point streams its trace
/// into `dir`'s `traces/point-<i>.csv` as it runs (complete files only: a run stopped
/// half-way leaves none). Returns the runs that finished, in run order: all of them unless
/// stopped.
///
/// # Errors
/// The first run whose session aborted, or a trace that cannot be written.
pub fn run_experiment(
    experiment: &Experiment,
    dir: &Path,
    runs: &[usize],
    stop: &Interrupt,
    finished: &(dyn Fn() + Sync),
) -> Result<Vec<RunRecord>, LabError> {
    let replicates = experiment.replicates() as usize;
    let plans: Vec<SessionPlan> = experiment
        .points
        .iter()
        .map(|p| SessionPlan::from_config(&p.config, 0))
        .collect();
    let label = if experiment.name.is_empty() {
        "sweep"
    } else {
        &experiment.name
    };
    let bar = progress_bar(runs.len(), label, "run");
    // Runs of points that differ only in Eve's settings (e.g. an α sweep) are one physical
    // session: simulated once, each point's Eve hears its transcript (sessions.rs).
    // The first point of each point's physical configuration.
    let mut first_of: HashMap<String, usize> = HashMap::new();
    let physical: Vec<usize> = (0..experiment.points.len())
        .map(|p| {
            *first_of
                .entry(physical_key(&experiment.points[p].config))
                .or_insert(p)
        })
        .collect();
    let mut sessions: Vec<Vec<usize>> = Vec::with_capacity(runs.len());
    let mut session_of: HashMap<(usize, usize), usize> = HashMap::new();
    for &run in runs {
        let (point, replicate) = (run / replicates, run % replicates);
        if experiment.traces && replicate == 0 || first_of.len() == physical.len() {
            sessions.push(vec![run]);
            continue;
        }
        let index = *session_of
            .entry((physical[point], replicate))
            .or_insert_with(|| {
                sessions.push(Vec::new());
                sessions.len() - 1
            });
        sessions[index].push(run);
    }
    let records = sessions
        .par_iter()
        .map(|session| {
            if stop.is_requested() {
                return Ok(Vec::new());
            }
            let record = |run: usize, output: RunOutput| {
                bar.inc(1);
                finished();
                RunRecord {
                    run,
                    point: run / replicates,
                    replicate: (run % replicates) as u32,
                    metrics: output.metrics,
                    trace: None,
                }
            };
            let (point, replicate) = (session[0] / replicates, (session[0] % replicates) as u32);
            let config = &experiment.points[point].config;
            let mut plan = plans[point].clone();
            plan.agreed.session = replicate;
            if let [run] = session[..] {
                let output = if experiment.traces && replicate == 0 {
                    streamed(config, plan, &trace_path(dir, point))?
                } else {
                    simulate_plan(config, plan, replicate, false)?
                };
                return Ok(vec![record(run, output)]);
            }
            let mut silent = config.clone();
            silent.eve.enabled = false;
            let (output, transcript) = simulate_transcript(&silent, replicate)?;
            Ok(session
                .iter()
                .map(|&run| {
                    let config = &experiment.points[run / replicates].config;
                    record(run, replay(config, replicate, &output, &transcript))
                })
                .collect())
        })
        .collect::<Result<Vec<Vec<RunRecord>>, LabError>>();
    bar.finish_and_clear();
    let mut records: Vec<RunRecord> = records?.into_iter().flatten().collect();
    records.sort_by_key(|r| r.run);
    Ok(records)
}

/// Replicate 0 of `config`, its trace written row by row to `path` (through a `.partial`
/// file renamed once complete).
fn streamed(config: &Config, plan: SessionPlan, path: &Path) -> Result<RunOutput, LabError> {
    let partial = path.with_extension("csv.partial");
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).map_err(io_at(parent))?;
    }
    let file = std::fs::File::create(&partial).map_err(io_at(&partial))?;
    let mut csv = TraceCsv::new(std::io::BufWriter::new(file)).map_err(io_at(&partial))?;
    let mut written = Ok(());
    let output = simulate_plan_streaming(config, plan, 0, &mut |row| {
        if written.is_ok() {
            written = csv.write(&row);
        }
    })?;
    written
        .and_then(|()| csv.finish().map(drop))
        .map_err(io_at(&partial))?;
    std::fs::rename(&partial, path).map_err(io_at(path))?;
    Ok(output)
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

    #[test]
    fn rates_read_as_people_write_them() {
        assert_eq!(rate_text(46_698.136_3, "run"), "46,700 runs/s");
        assert_eq!(rate_text(1_234_567.0, "run"), "1,230,000 runs/s");
        assert_eq!(rate_text(123.4, "session"), "123 sessions/s");
        assert_eq!(rate_text(12.345, "run"), "12.3 runs/s");
        assert_eq!(rate_text(1.5, "run"), "1.50 runs/s");
        assert_eq!(rate_text(0.25, "run"), "4.00 s/run");
        assert_eq!(rate_text(0.0, "run"), "– runs/s");
    }
}
