//! `robokey reproduce`: the paper's suite swept ([`suite`]), then the stages computed into
//! its folder — the secrecy of the Δv and α sweeps, the eavesdropping campaigns, the coarse
//! private-sensing map ([`private_suite`]) and the coarse worlds ([`world_suite`]) — and
//! `reproduce.json` written last, vouching for them. `robokey report` then renders the
//! paper's report from the folder alone.

pub mod private_suite;
pub mod suite;
pub mod world_suite;

use std::path::Path;
use std::time::Instant;

use rayon::prelude::*;
use robokey::Config;
use robokey::config::EveStrategy;
use robokey::interrupt::Interrupt;
use serde::{Deserialize, Serialize};

use crate::adversary::run_campaigns_with;
use crate::error::{LabError, io_at};
use crate::experiment::Experiment;
use crate::folder::sweep::{SweepPlan, sweep_keeping};
use crate::output::{read_json, write};
use crate::parquet_table::TableFormat;
use crate::run::sessions::SessionBank;
use crate::secrecy::{Secrecy, SecrecyOptions};

/// The record of the stages, written once they are all computed.
pub const REPRODUCE_JSON: &str = "reproduce.json";
/// The folder of the eavesdropping campaigns.
pub const EVE_DIR: &str = "eve";
/// The sweeps whose secrecy the report shows, with its headings.
pub const SECRECY_EXPERIMENTS: [(&str, &str); 2] = [
    ("dv-sweep", "Against Δv (paper's Eve at α = 10 %)"),
    ("eve-sweep", "Against α (Δv = 0.035)"),
];

/// Independent eavesdropping campaigns (`--quick`: fewer).
const EVE_CAMPAIGNS: u32 = 20;
const QUICK_EVE_CAMPAIGNS: u32 = 5;

/// Least raw bits of a secrecy block with `--quick` (else the default, 10,000).
const QUICK_BLOCK_BITS: usize = 2_000;

/// How the stages of a reproduction were computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Reproduction {
    /// The small grids of `reproduce --quick`: 5 eavesdropping campaigns instead of 20,
    /// secrecy blocks of 2,000 raw bits instead of 10,000, a smaller private-sensing map
    /// (its sweep, 3 replicates per point instead of 10, is in the suite's folders).
    pub quick: bool,
}

impl Reproduction {
    /// Reads `reproduce.json` of `dir`: `None` when its stages were not computed.
    ///
    /// # Errors
    /// The file does not read back.
    pub fn read(dir: &Path) -> Result<Option<Self>, LabError> {
        let path = dir.join(REPRODUCE_JSON);
        if path.exists() {
            read_json(&path).map(Some)
        } else {
            Ok(None)
        }
    }
}

/// How long each stage took (s), for the terminal; the odometry stages (secrecy, then the
/// eavesdroppers) and the private-sensing map run side by side.
pub type StageTimes = Vec<(&'static str, f64)>;

/// Computes the stages of the paper's report into `dir`, the folder of a complete sweep of
/// [`suite::paper_suite`]`(quick)`, on the current rayon pool: the odometry stages and the
/// private-sensing map side by side. Between stages, a requested stop ends it.
/// `reproduce.json` is removed first and written last, so it vouches only for stages that
/// all finished.
///
/// # Errors
/// A session aborts, a file cannot be written, or the stop was requested.
pub fn compute_stages(dir: &Path, quick: bool, stop: &Interrupt) -> Result<StageTimes, LabError> {
    let record = dir.join(REPRODUCE_JSON);
    if record.exists() {
        std::fs::remove_file(&record).map_err(io_at(&record))?;
    }
    let suite = suite::paper_suite(quick)?;
    // The odometry stages share their sessions; the private-sensing map and the worlds share
    // nothing with them, so the three run side by side on the pool. The worlds, the longest,
    // start first, so that what they do one at a time overlaps the other stages.
    let (worlds, (odometry, private)) = rayon::join(
        || worlds_stage(dir, quick, stop),
        || {
            rayon::join(
                || odometry_stages(dir, &suite, quick, stop),
                || private_stage(dir, quick, stop),
            )
        },
    );
    let mut times = odometry?;
    times.push(("private sensing", private?));
    times.push(("worlds", worlds?));
    let json = serde_json::to_string_pretty(&Reproduction { quick }).expect("JSON serializes");
    write(&record, json + "\n")?;
    Ok(times)
}

/// Runs `stage` unless a stop was requested; returns how long it took (s).
fn timed(stop: &Interrupt, stage: impl FnOnce() -> Result<(), LabError>) -> Result<f64, LabError> {
    stopped(stop)?;
    let started = Instant::now();
    stage()?;
    Ok(started.elapsed().as_secs_f64())
}

/// The secrecy of the Δv and α sweeps, then the eavesdropping campaigns, into `dir`.
fn odometry_stages(
    dir: &Path,
    suite: &[Experiment],
    quick: bool,
    stop: &Interrupt,
) -> Result<StageTimes, LabError> {
    // Every physical session is simulated once: the α points share the Δv = 0.035
    // sessions, and so do the campaigns (the default configuration), so the bank keeps them
    // from the Δv sweep's secrecy to the campaigns.
    let mut bank = SessionBank::new();
    for experiment in suite.iter().filter(|e| e.name == SECRECY_EXPERIMENTS[1].0) {
        for point in &experiment.points {
            bank.keep(&point.config);
        }
    }
    bank.keep(&Config::default());
    let secrecy = timed(stop, || {
        let options = SecrecyOptions {
            block_bits: if quick {
                QUICK_BLOCK_BITS
            } else {
                SecrecyOptions::default().block_bits
            },
            ..SecrecyOptions::default()
        };
        for (name, _) in SECRECY_EXPERIMENTS {
            stopped(stop)?;
            let experiment = find(suite, name)?;
            Secrecy::compute(experiment, &options, &mut bank)?.write(&dir.join(name))?;
        }
        Ok(())
    })?;
    let eavesdroppers = timed(stop, || {
        let config = Config::default();
        let strategies = EveStrategy::of_mode(config.sensing.mode);
        let campaigns = if quick {
            QUICK_EVE_CAMPAIGNS
        } else {
            EVE_CAMPAIGNS
        };
        run_campaigns_with(&config, &strategies, campaigns, &mut bank)?
            .write(&dir.join(EVE_DIR))?;
        Ok(())
    })?;
    Ok(vec![("secrecy", secrecy), ("eavesdroppers", eavesdroppers)])
}

/// The coarse private-sensing map: each experiment swept into `dir/private-sensing`, then
/// its secrecy. Returns how long it took (s).
fn private_stage(dir: &Path, quick: bool, stop: &Interrupt) -> Result<f64, LabError> {
    timed(stop, || {
        sweep_each_then_secrecy(
            &dir.join(private_suite::PRIVATE_SENSING_DIR),
            private_suite::coarse_suite(quick)?,
            private_suite::options,
            stop,
        )
    })
}

/// The coarse worlds: each swept into `dir/worlds`, then its secrecy against the
/// eavesdroppers who know it. Returns how long it took (s).
fn worlds_stage(dir: &Path, quick: bool, stop: &Interrupt) -> Result<f64, LabError> {
    timed(stop, || {
        sweep_each_then_secrecy(
            &dir.join(world_suite::WORLDS_DIR),
            world_suite::coarse_suite(quick)?,
            |experiment| world_suite::options(experiment, quick),
            stop,
        )
    })
}

/// Sweeps each experiment into its folder of `out`, then computes and writes its secrecy
/// with `options(experiment)` there; the experiments side by side on the pool (each has its
/// own folder and sessions). The sweep's runs are filed for the secrecy, which takes those
/// simulated with its own settings (the same configuration, replicate and judged
/// eavesdroppers) as its first sessions instead of simulating them again.
fn sweep_each_then_secrecy(
    out: &Path,
    experiments: Vec<Experiment>,
    options: impl Fn(&Experiment) -> SecrecyOptions + Sync,
    stop: &Interrupt,
) -> Result<(), LabError> {
    experiments.par_iter().try_for_each(|experiment| {
        let plan = SweepPlan {
            shard: None,
            resume: false,
            format: TableFormat::Csv,
        };
        let mut bank = SessionBank::new();
        let swept = sweep_keeping(
            out,
            std::slice::from_ref(experiment),
            plan,
            stop,
            &mut |_| {},
            &|| {},
            Some(bank.kept_sessions()),
        )?;
        if let Some(signal) = swept.interrupted {
            return Err(LabError::Interrupted(signal));
        }
        Secrecy::compute(experiment, &options(experiment), &mut bank)?
            .write(&out.join(&experiment.name))?;
        Ok(())
    })
}

/// The experiment `name` of the suite.
fn find<'a>(suite: &'a [Experiment], name: &str) -> Result<&'a Experiment, LabError> {
    suite
        .iter()
        .find(|e| e.name == name)
        .ok_or_else(|| LabError::Sweep {
            origin: "experiments/paper.toml".into(),
            message: format!("no [experiment.{name}]"),
        })
}

/// Ends the stages once a stop is requested.
fn stopped(stop: &Interrupt) -> Result<(), LabError> {
    stop.signal()
        .map_or(Ok(()), |signal| Err(LabError::Interrupted(signal)))
}
