//! Physical sessions simulated once, heard by every eavesdropper (docs/speed.md).
//!
//! An eavesdropper only listens: the plant, the robot and the controller never depend on the
//! `[eve]` table. Configurations that differ only there (the α points of the paper's Eve
//! sweep, the adversaries of `robokey secrecy`, the strategies of `robokey eve`) therefore
//! share their sessions: each replicate is simulated once, without an eavesdropper, with its
//! transcript, and every eavesdropper hears that transcript ([`robokey::sim::replay`]),
//! which gives bit for bit the run she would have heard live.

use std::collections::{HashMap, HashSet};
use std::sync::{Mutex, PoisonError};

use rayon::prelude::*;
use robokey::Config;
use robokey::config::{EveConfig, SensingMode};
use robokey::private::Eavesdroppers;
use robokey::protocol::Message;
use robokey::sim::{RunOutput, simulate_transcript};

use crate::error::LabError;
use crate::progress::progress_bar;

/// What identifies a physical session: the configuration without `run.replicates` (which
/// says how many sessions, not what happens in one) and, in odometry mode, without its
/// `[eve]` table. In private sensing Eve films the robot from within the session (her camera
/// draws, her evidence in the output), so there her settings stay in the key: such sessions
/// are never shared.
#[must_use]
pub fn physical_key(config: &Config) -> String {
    let mut physical = config.clone();
    if config.sensing.mode == SensingMode::Odometry {
        physical.eve = EveConfig::default();
    }
    physical.run.replicates = Config::default().run.replicates;
    physical.to_toml()
}

/// The sessions `first, first + 1, …` of one physical configuration.
#[derive(Clone, Copy, Debug)]
pub struct Heard<'a> {
    /// The replicate (= session id) of the first.
    pub first: u32,
    /// Each session, simulated without an eavesdropper.
    pub runs: &'a [RunOutput],
    /// Each session's messages, in the order an eavesdropper hears them.
    pub transcripts: &'a [Vec<Message>],
}

impl<'a> Heard<'a> {
    /// Sessions `range` (indices into these).
    #[must_use]
    pub fn slice(&self, range: std::ops::Range<usize>) -> Heard<'a> {
        Heard {
            first: self.first + range.start as u32,
            runs: &self.runs[range.clone()],
            transcripts: &self.transcripts[range],
        }
    }

    /// Number of sessions.
    #[must_use]
    pub fn len(&self) -> usize {
        self.runs.len()
    }

    /// Whether there are none.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.runs.is_empty()
    }

    /// `(replicate, run, transcript)` of each session, in order.
    pub fn iter(&self) -> impl Iterator<Item = (u32, &'a RunOutput, &'a [Message])> + '_ {
        self.runs
            .iter()
            .zip(self.transcripts)
            .zip(self.first..)
            .map(|((run, transcript), replicate)| (replicate, run, transcript.as_slice()))
    }
}

/// Replicates `0, 1, …` of one physical configuration.
#[derive(Default)]
struct Group {
    runs: Vec<RunOutput>,
    transcripts: Vec<Vec<Message>>,
}

/// Sessions simulated by one consumer for a later one (a sweep's private-sensing replicates
/// for the secrecy analysis of the same points), each filed under what it is a pure
/// function of: its whole configuration as TOML (`[eve]` included, `run.replicates` left
/// out), its replicate (the session's id and streams) and whose judgement it computed. A
/// session taken from here is therefore the one the taker would have simulated, bit for bit.
#[derive(Default)]
pub struct KeptSessions {
    runs: Mutex<HashMap<(String, u32), RunOutput>>,
}

impl KeptSessions {
    /// What a session is a pure function of, besides its replicate.
    fn key(config: &Config, judged: Eavesdroppers) -> String {
        let mut config = config.clone();
        config.run.replicates = Config::default().run.replicates;
        format!("{judged:?}\n{}", config.to_toml())
    }

    /// Files `run`, replicate `replicate` of `config` simulated judging `judged`.
    pub fn keep(&self, config: &Config, replicate: u32, judged: Eavesdroppers, run: RunOutput) {
        self.runs
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .insert((Self::key(config, judged), replicate), run);
    }

    /// Takes the filed replicates `0, 1, …` of `config` simulated judging `judged`, up to
    /// the first one not filed.
    #[must_use]
    pub fn take(&self, config: &Config, judged: Eavesdroppers) -> Vec<RunOutput> {
        let key = Self::key(config, judged);
        let mut runs = self.runs.lock().unwrap_or_else(PoisonError::into_inner);
        (0..)
            .map_while(|replicate| runs.remove(&(key.clone(), replicate)))
            .collect()
    }
}

/// The sessions simulated so far, per physical configuration. Sessions are pure functions
/// of the configuration and the replicate, so the bank changes how often they are
/// simulated, never what they are.
#[derive(Default)]
pub struct SessionBank {
    groups: HashMap<String, Group>,
    kept: HashSet<String>,
    sessions: KeptSessions,
}

impl SessionBank {
    /// An empty bank.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Keeps the sessions of `config`'s physical configuration through [`Self::release`]:
    /// a later consumer hears them too.
    pub fn keep(&mut self, config: &Config) {
        self.kept.insert(physical_key(config));
    }

    /// Replicates `0 … count − 1` of `config`'s physical configuration, simulating (in
    /// parallel) those not simulated yet.
    ///
    /// # Errors
    /// A session aborted.
    pub fn heard(&mut self, config: &Config, count: u32) -> Result<Heard<'_>, LabError> {
        let group = self.groups.entry(physical_key(config)).or_default();
        let have = group.runs.len() as u32;
        if have < count {
            let mut silent = config.clone();
            silent.eve.enabled = false;
            let bar = progress_bar((count - have) as usize, "sessions", "session");
            let more = (have..count)
                .into_par_iter()
                .map(|replicate| {
                    let session = simulate_transcript(&silent, replicate);
                    bar.inc(1);
                    session
                })
                .collect::<Result<Vec<_>, _>>()?;
            bar.finish_and_clear();
            for (run, transcript) in more {
                group.runs.push(run);
                group.transcripts.push(transcript);
            }
        }
        let count = count as usize;
        Ok(Heard {
            first: 0,
            runs: &group.runs[..count],
            transcripts: &group.transcripts[..count],
        })
    }

    /// The sessions filed for a later consumer: a sweep files its private-sensing runs
    /// here, the secrecy analysis of the same points takes them.
    #[must_use]
    pub fn kept_sessions(&self) -> &KeptSessions {
        &self.sessions
    }

    /// Forgets `config`'s sessions unless they are kept.
    pub fn release(&mut self, config: &Config) {
        let key = physical_key(config);
        if !self.kept.contains(&key) {
            self.groups.remove(&key);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robokey::config::EveStrategy;
    use robokey::sim::{replay, simulate};

    /// Every eavesdropper hearing the shared transcript decides exactly as she does live.
    #[test]
    fn a_replayed_run_is_the_live_run() {
        let mut bank = SessionBank::new();
        for strategy in [
            EveStrategy::Oracle,
            EveStrategy::Mismatch,
            EveStrategy::Soft,
            EveStrategy::Identify,
        ] {
            let mut config = Config::default();
            config.eve.strategy = Some(strategy);
            config.eve.alpha = 0.3;
            let heard = bank.heard(&config, 2).unwrap();
            for (replicate, run, transcript) in heard.iter() {
                let live = simulate(&config, replicate, false).unwrap();
                let replayed = replay(&config, replicate, run, transcript);
                assert_eq!(replayed.steps, live.steps, "{strategy:?}");
                assert_eq!(replayed.keys.eve, live.keys.eve, "{strategy:?}");
                assert_eq!(
                    format!("{:?}", replayed.metrics),
                    format!("{:?}", live.metrics),
                    "{strategy:?}"
                );
            }
        }
        // One physical configuration: the α and strategy changes share it.
        assert_eq!(bank.groups.len(), 1);
    }

    /// In private sensing Eve's camera is part of the session: no sharing across her settings.
    #[test]
    fn private_sessions_keep_eves_camera_in_their_key() {
        let private = |camera: f64| {
            let mut config = Config::default();
            config.sensing.mode = SensingMode::Private;
            config.eve.camera_std = [camera; 3];
            config
        };
        assert_ne!(physical_key(&private(0.004)), physical_key(&private(0.008)));
        let odometry = |alpha: f64| {
            let mut config = Config::default();
            config.eve.alpha = alpha;
            config
        };
        assert_eq!(physical_key(&odometry(0.0)), physical_key(&odometry(0.1)));
    }
}
