//! Runs an experiment's grid in parallel, deterministically: results are collected in
//! run-index order, and every run draws from its own per-purpose, per-replicate streams,
//! so any `--jobs` and any sharding give the same numbers.

use std::collections::HashMap;
use std::path::Path;

use rayon::prelude::*;
use robokey::Config;
use robokey::interrupt::Interrupt;
use robokey::private::Eavesdroppers;
use robokey::protocol::SessionPlan;
use robokey::sim::{
    RunOutput, replay, simulate_plan, simulate_plan_streaming, simulate_transcript,
};

use super::row::RunRow;
use super::sessions::{KeptSessions, physical_key};
use crate::error::{LabError, io_at};
use crate::experiment::Experiment;
use crate::progress::progress_bar;
use crate::trace::{TraceCsv, point_trace_path};

/// Runs the given runs of the experiment (run indices, see [`RunRow::run`]) on the
/// current rayon pool, starting none once `stop` is requested; `finished` is called after
/// each run. When the experiment keeps traces, replicate 0 of each point streams its trace
/// into `dir`'s `traces/point-<i>.csv` as it runs (complete files only: a run stopped
/// half-way leaves none). A run simulated alone (not traced, not shared between points)
/// is filed in `kept`, if given, for a later consumer of the same session. Returns the runs
/// that finished, in run order: all of them unless stopped.
///
/// # Errors
/// The first run whose session aborted, or a trace that cannot be written.
pub fn run_experiment(
    experiment: &Experiment,
    dir: &Path,
    runs: &[usize],
    stop: &Interrupt,
    finished: &(dyn Fn() + Sync),
    kept: Option<&KeptSessions>,
) -> Result<Vec<RunRow>, LabError> {
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
    // session: simulated once, each point's Eve hears its transcript (run/sessions.rs).
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
            let record = |run: usize, output: &RunOutput| {
                bar.inc(1);
                finished();
                RunRow {
                    run,
                    point: run / replicates,
                    replicate: (run % replicates) as u32,
                    metrics: output.metrics.clone(),
                }
            };
            let (point, replicate) = (session[0] / replicates, (session[0] % replicates) as u32);
            let config = &experiment.points[point].config;
            let mut plan = plans[point].clone();
            plan.agreed.session = replicate;
            if let [run] = session[..] {
                if experiment.traces && replicate == 0 {
                    let output = streamed(config, plan, &point_trace_path(dir, point))?;
                    return Ok(vec![record(run, &output)]);
                }
                // A row holds her metrics alone: only her evidence is judged.
                let judged = Eavesdroppers::reading(config.eve_strategy());
                let output = simulate_plan(config, plan, replicate, false, judged)?;
                let row = record(run, &output);
                if let Some(kept) = kept {
                    kept.keep(config, replicate, judged, output);
                }
                return Ok(vec![row]);
            }
            let mut silent = config.clone();
            silent.eve.enabled = false;
            let (output, transcript) = simulate_transcript(&silent, replicate)?;
            Ok(session
                .iter()
                .map(|&run| {
                    let config = &experiment.points[run / replicates].config;
                    record(run, &replay(config, replicate, &output, &transcript))
                })
                .collect())
        })
        .collect::<Result<Vec<Vec<RunRow>>, LabError>>();
    bar.finish_and_clear();
    let mut rows: Vec<RunRow> = records?.into_iter().flatten().collect();
    rows.sort_by_key(|r| r.run);
    Ok(rows)
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
        .map_err(|e| LabError::Threads {
            jobs,
            message: e.to_string(),
        })?;
    Ok(pool.install(f))
}
