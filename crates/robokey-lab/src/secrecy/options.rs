//! What an analysis is asked: the adversaries, ε, the block size, which sessions are pooled,
//! the assumption that sizes the key, how many blocks and sessions.

use robokey::config::{EveStrategy, SensingMode};
use robokey::post_settings::ODOMETRY_ZERO;
use robokey_secrecy::postprocess::Assumption;

use super::pipeline::Pooling;

pub use robokey::config::{LlrModel, Reconciliation, Sizing};

/// The adversaries `robokey secrecy` evaluates by default in `mode`.
#[must_use]
pub fn default_adversaries(mode: SensingMode) -> Vec<EveStrategy> {
    match mode {
        SensingMode::Odometry => vec![
            EveStrategy::Oracle,
            EveStrategy::Identify,
            EveStrategy::Mismatch,
        ],
        SensingMode::Private => EveStrategy::of_mode(SensingMode::Private),
    }
}

/// Settings of the analysis.
#[derive(Clone, Debug)]
pub struct SecrecyOptions {
    /// Adversaries to evaluate.
    pub adversaries: Vec<EveStrategy>,
    /// ε of each term: smoothing ε_s, privacy amplification ε_PA and parameter
    /// estimation ε_PE; the key is then 4ε-secret (2ε_s + ε_PA + ε_PE).
    pub epsilon: f64,
    /// Least pooled raw bits per privacy-amplification block (whole sessions are pooled).
    pub block_bits: usize,
    /// Which sessions are pooled, and what was published over their keys.
    pub pooling: Pooling,
    /// Largest sample disclosed to estimate the error rate (`complete` pooling).
    pub sample_bits: usize,
    /// The operator's statement about Eve that sizes the key: her least independent error
    /// rate, or `None` (the odometry mode's structural zero).
    pub assumed_eve_error: Option<f64>,
    /// Blocks to fill per point (sessions are added until they are full).
    pub blocks: usize,
    /// Most sessions simulated per point and adversary.
    pub max_sessions: u32,
    /// Bootstrap resamples for the information intervals.
    pub bootstrap: usize,
    /// What sizes private sensing's key.
    pub sizing: Sizing,
    /// How `complete` pooling reconciles (LDPC: private sensing only).
    pub reconciliation: Reconciliation,
    /// LDPC: which model the controller's LLRs are computed with (none: each point's
    /// `postprocess.llrs`, else `LlrModel::following` this analysis's sizing and
    /// reconciliation — measured under the measured and world sizings, else the prior).
    pub llrs: Option<LlrModel>,
}

impl Default for SecrecyOptions {
    fn default() -> Self {
        Self {
            adversaries: default_adversaries(SensingMode::Odometry),
            epsilon: 1e-6,
            block_bits: 10_000,
            pooling: Pooling::Confirmed,
            sample_bits: 1_000,
            assumed_eve_error: None,
            blocks: 1,
            max_sessions: default_max_sessions(10_000, 1),
            bootstrap: 1_000,
            sizing: Sizing::Configured,
            reconciliation: Reconciliation::Cascade,
            llrs: None,
        }
    }
}

impl SecrecyOptions {
    /// The assumption that sizes the key.
    #[must_use]
    pub fn assumption(&self) -> Assumption {
        match self.assumed_eve_error {
            Some(error_rate) => Assumption::IndependentErrors { error_rate },
            None => Assumption::NoSecrecy {
                reason: ODOMETRY_ZERO.to_owned(),
            },
        }
    }
}

/// Most sessions simulated per point and adversary, by default, for `blocks` blocks of
/// `block_bits` raw bits: 2,000 per 10,000 bits the blocks need (about 60 times what a
/// session of the paper's settings pools), at most [`MAX_SESSIONS`].
#[must_use]
pub fn default_max_sessions(block_bits: usize, blocks: usize) -> u32 {
    let needed = (block_bits as u64).saturating_mul(blocks as u64);
    let sessions = needed.div_ceil(10_000).max(1).saturating_mul(2_000);
    sessions.min(u64::from(MAX_SESSIONS)) as u32
}

/// The largest session count `robokey secrecy` simulates per point and adversary.
pub const MAX_SESSIONS: u32 = 1_000_000;
