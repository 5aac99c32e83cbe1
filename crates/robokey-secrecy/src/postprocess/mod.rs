//! Post-processing as a protocol without I/O: two endpoints that turn pooled raw session bits
//! into final keys — pool sync, error-rate estimate, Cascade, block confirmation, privacy
//! amplification, two-phase commit — driven only by messages in and messages out, so the
//! same code sizes the key in simulation and makes it on the network (docs/secrecy.md).
//!
//! The robot ([`RobotPost`]) holds the reference bits and only answers; the controller
//! ([`ControllerPost`]) corrects its bits, drives every exchange and retransmits on
//! a [`ControllerInput::Timeout`]. One block at a time:
//!
//! 1. `Propose` (controller): the sessions of the block, in order, and a fresh nonce.
//! 2. `Agree` (robot): the proposed sessions it holds, in that order, its nonce, and its bits
//!    at the disclosed sample positions (public randomness from both nonces, [`public`]).
//! 3. `Ask` / `Answer`: Cascade questions and parities, one round per pair.
//! 4. `Confirm` (controller): ℓ from the stated [`Assumption`], and its directional tag.
//! 5. `Confirmed` (robot): its tag; the robot has *prepared* the key (persisted, not used).
//! 6. `Commit` (controller, after persisting the key) → `CommitAck` (robot, after persisting).
//!
//! Outputs polled after one input form a batch: a [`Output::KeyCommitted`] belongs to the
//! durable state of that batch's [`Output::Persist`], so the shell stores the snapshot and the
//! keys committed in the batch before transmitting anything from it.
//!
//! `Abort` ends a block without a key (ℓ = 0, tags differ, a restart); every session that
//! entered a block is spent whatever the outcome, since its sample and parities are public.
//! The controller commits only after the robot's tag proves it prepared the key, and the robot
//! commits only on `Commit`, so after any crash and recovery — the controller aborts an
//! uncommitted block and repeats `Commit` for a committed one — neither side ends up with a
//! key the other lacks once both are quiet. Until then the key is *pending* on the side whose
//! peer has not acknowledged it (the controller's until `CommitAck`, the robot's prepared key
//! until `Commit`): the shell withholds it, so that a key either side delivers is always held
//! by the other. Endpoints signal [`Output::Persist`] when their durable state changed:
//! the shell must store [`ControllerPost::snapshot`] / [`RobotPost::snapshot`] before sending
//! what follows.

mod assumption;
mod controller;
mod encoding;
mod estimate;
mod fragment;
mod ledger;
mod message;
pub mod public;
mod robot;
mod slices;
mod soft_values;
mod syndromes;
#[cfg(test)]
mod tests;

use serde::{Deserialize, Serialize};

use crate::bitstring::BitString;
use crate::cascade::CascadeSchedule;
use crate::ldpc::LdpcSettings;

pub use assumption::{Assumption, AssumptionError};
pub use controller::{ControllerInput, ControllerPost, ControllerSnapshot, InFlight};
pub use encoding::{decode, encode};
pub use estimate::{
    EstimateOutcome, EstimateRefusal, EstimateRequest, KeptDoublet, KeptLate, LlrAnswer,
    LlrRequest, MAX_SEPARATION_STEPS, RecomputedLlrs, SEPARATION_QUANTUM, SessionSamples,
};
pub use fragment::{
    FRAGMENT_BYTES, MAX_FRAGMENTS, MAX_MESSAGE_BYTES, Reassembler, fits, fragments,
};
pub use message::{AbortReason, Message, RejectReason};
pub use robokey_codec::DecodeError;
pub use robot::{Prepared, RobotInput, RobotPost, RobotSnapshot};
pub use slices::{
    MAX_KEY_BITS, MAX_SLICES, ReconciledSlices, SliceInput, SlicesEstimateRequest, Slicing,
    StagedSession, slice_id,
};
pub use soft_values::{LLR_QUANTUM, dequantise_llr, quantise_llr};

/// Largest number of sessions one block may pool (bounds a `Propose`).
pub const MAX_BLOCK_SESSIONS: usize = 1 << 16;

/// Largest number of raw bits one session may contribute.
pub const MAX_SESSION_BITS: usize = 1 << 20;

/// Largest number of Cascade questions in one `Ask` (and parities in one `Answer`).
pub const MAX_QUESTIONS: usize = 1 << 20;

/// Largest sample one `Agree` discloses (bits); bounds [`Settings::sample_bits`].
pub const MAX_SAMPLE_BITS: usize = 1 << 20;

/// Largest syndrome one `Syndrome` carries (bits): an LDPC code's block bound.
pub const MAX_SYNDROME_BITS: usize = crate::ldpc::MAX_BLOCK_BITS;

/// How the controller's bits are made the robot's (docs/postprocessing.md).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub enum ReconciliationMethod {
    /// Interactive Cascade on the controller's decisions: both sides' parities are leaked.
    #[default]
    Cascade,
    /// One-way LDPC syndromes decoded on the controller's calibrated LLRs
    /// ([`crate::ldpc`]): every syndrome bit and ⌈log₂(R + 1)⌉ for the rounds are leaked.
    /// Needs every pooled session's LLRs.
    Ldpc(LdpcSettings),
}

impl ReconciliationMethod {
    /// The name configurations and reports use: `cascade` or `ldpc`.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Self::Cascade => "cascade",
            Self::Ldpc(_) => "ldpc",
        }
    }
}

/// What both endpoints must agree on (exchanged out of band, like the session terms).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Settings {
    /// The controller proposes a block once its pool holds at least this many raw bits.
    pub block_bits: usize,
    /// Largest sample disclosed to estimate the error rate (at most a tenth of the block, and
    /// at most [`MAX_SAMPLE_BITS`]).
    pub sample_bits: usize,
    /// ε of each term (smoothing, amplification, parameter estimation).
    pub epsilon: f64,
    /// The Cascade schedule (its block sizes follow the sampled error rate).
    pub schedule: CascadeSchedule,
    /// What is assumed about Eve: it sets ℓ.
    pub assumption: Assumption,
    /// How the bits are reconciled (Cascade unless stated).
    #[serde(default)]
    pub reconciliation: ReconciliationMethod,
}

/// What happened to one block, for reports (both endpoints produce one). Its `Default` is
/// block 0 with nothing done yet.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct BlockReport {
    /// Block number.
    pub block: u64,
    /// Sessions pooled.
    pub sessions: Vec<u32>,
    /// Raw bits pooled.
    pub bits: usize,
    /// Positions disclosed to estimate the error rate.
    pub sample_bits: usize,
    /// Which positions of the pooled bits they are, in order (public).
    pub sampled: Vec<u32>,
    /// Disagreements in the sample (controller only; 0 on the robot).
    pub sample_errors: usize,
    /// The error-rate estimate that sized Cascade.
    pub q_estimate: f64,
    /// Bits reconciled and amplified.
    pub reconciled_bits: usize,
    /// Cascade questions answered (with LDPC: syndrome bits sent).
    pub questions: u64,
    /// Reconciliation leak: with Cascade both sides' parities, 2 per question; with LDPC
    /// every syndrome bit sent plus ⌈log₂(R + 1)⌉ for the number of rounds (R feedback
    /// rounds allowed).
    pub leak_ec: u64,
    /// With LDPC reconciliation: the syndrome rounds used (absent with Cascade).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ldpc_rounds: Option<u32>,
    /// With LDPC reconciliation, on the controller: the LLRs it decoded on. Absent with
    /// Cascade, which reads no LLRs, and on the robot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub llrs: Option<Box<LlrProvenance>>,
    /// Confirmation tags published over the block (two 64-bit tags).
    pub leak_confirmation: u64,
    /// Eve's smooth min-entropy bound under the assumption.
    pub h_min: f64,
    /// The final key length ℓ.
    pub length: u64,
    /// With the plant measured: the published outcome of the block's estimate, its
    /// worst-case separation in steps of [`SEPARATION_QUANTUM`] (a refused block has none,
    /// and its reason says why).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub separation_steps: Option<u32>,
    /// The assumption the block was sized under: the configured one at the block's
    /// separation. Not serialized (a report's reader has the configured assumption and the
    /// separation fields).
    #[serde(skip)]
    pub assumption: Option<Box<Assumption>>,
    /// Why the block ended without a key, if it did.
    pub reason: Option<String>,
    /// Messages sent by this endpoint for the block (retransmissions included).
    pub messages_sent: u32,
    /// Their payload bits (fields, before framing).
    pub bits_sent: u64,
}

/// Which LLRs a block's LDPC decoding used (docs/estimation.md, "Causality").
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct LlrProvenance {
    /// `prior` (each doublet's, computed online with the prior and pooled with its session)
    /// or the model the shell recomputed them with at block time (`measured`, `world`).
    pub model: String,
    /// Why the prior's LLRs stayed where the shell was asked to recompute them (naming the
    /// value), if they did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fallback: Option<String>,
}

/// A final key, committed on both sides.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FinalKey {
    /// The key's ID, the same on both sides: 16 hex digits of
    /// SHA-256("robokey/key-id/v1" ‖ block ‖ sessions ‖ nonces ‖ ℓ) — public, and unique
    /// even when a store is reset and block numbers start again.
    pub id: String,
    /// Block number.
    pub block: u64,
    /// The key bits.
    pub key: BitString,
    /// Sessions it came from.
    pub sessions: Vec<u32>,
    /// Secret against the stated assumption except with this probability: the sum of its ε
    /// terms ([`Assumption::total_epsilon`]: 4ε, or 4ε + ε_est with the plant measured).
    pub epsilon: f64,
    /// The assumption it is secret under.
    pub assumption: String,
    /// How its block was reconciled and what that leaked (absent in keys recorded before
    /// it was stated).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reconciliation: Option<KeyReconciliation>,
}

/// How a key's block was reconciled, as both sides charged it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct KeyReconciliation {
    /// `cascade` or `ldpc` ([`ReconciliationMethod::name`]).
    pub method: String,
    /// leak_EC (bits): what ℓ was charged for reconciliation, the tags' 128 bits apart.
    pub leak_ec: u64,
}

impl KeyReconciliation {
    /// The record of a block reconciled by `method` with leak_EC `leak_ec` bits.
    #[must_use]
    pub fn new(method: &ReconciliationMethod, leak_ec: u64) -> Self {
        Self {
            method: method.name().to_owned(),
            leak_ec,
        }
    }
}

/// What an endpoint asks its shell to do.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    /// Send this to the peer.
    Transmit(Message),
    /// Durable state changed: store the snapshot before transmitting what follows.
    Persist,
    /// A key was committed: hand it to the key store.
    KeyCommitted(FinalKey),
    /// A block ended (with or without key).
    BlockEnded(BlockReport),
    /// A message was ignored (stale, duplicate, malformed, or from the wrong state).
    Ignored(&'static str),
    /// The controller needs the block's estimate of the plant (measured sizing) or its
    /// commands check (configured sizing, sessions pooled with samples): answer with
    /// [`ControllerInput::Estimate`].
    EstimateNeeded(EstimateRequest),
    /// A block of multilevel slices was reconciled (the robot's bits are known): the shell
    /// computes the next slice's LLRs of its sessions given them and answers with
    /// [`ControllerInput::NextSlices`] before anything else is proposed.
    SliceReconciled(Box<ReconciledSlices>),
    /// A multilevel block's last slice was reconciled, its lower slices held reconciled:
    /// the shell estimates the plant on whole symbols (measured sizing) or runs the commands
    /// check on them (configured), for every slice, and answers with
    /// [`ControllerInput::SliceEstimates`]. No slice's key is proposed before.
    SlicesEstimateNeeded(Box<SlicesEstimateRequest>),
    /// LDPC with LLRs recomputed at block time ([`ControllerPost::recompute_llrs`]): the
    /// disclosed sample is known, reconciliation has not started; the shell recomputes the
    /// block's LLRs from the kept samples and answers with [`ControllerInput::Llrs`].
    LlrsNeeded(Box<LlrRequest>),
}

/// Errors of endpoint construction and input.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PostError {
    /// A session with this ID is already pooled or was spent.
    #[error("session {0} is already pooled or spent")]
    DuplicateSession(u32),
    /// A session with no bits, or more than [`MAX_SESSION_BITS`].
    #[error("session {id} has {bits} bits (allowed: 1 to {MAX_SESSION_BITS})")]
    SessionSize {
        /// Session ID.
        id: u32,
        /// Its bits.
        bits: usize,
    },
    /// Settings out of range.
    #[error("invalid post-processing settings: {0}")]
    Settings(String),
    /// A session's LLRs do not match its bits (one per bit, none NaN), or LDPC
    /// reconciliation needs them and the session has none.
    #[error("session {id}: {problem}")]
    Llrs {
        /// Session ID.
        id: u32,
        /// What is wrong.
        problem: String,
    },
    /// A multilevel session's staged material does not fit its slice.
    #[error("session {id}: staged slices: {problem}")]
    Staged {
        /// Pool ID.
        id: u32,
        /// What is wrong.
        problem: String,
    },
    /// A session's Eve separation outside [0, 10⁶].
    #[error("session {id} has Eve separation {separation} (allowed: 0 to 10^6)")]
    Separation {
        /// Session ID.
        id: u32,
        /// Its separation.
        separation: f64,
    },
}

impl Settings {
    /// Checks the ranges.
    ///
    /// # Errors
    /// [`PostError::Settings`] naming the field.
    pub fn check(&self) -> Result<(), PostError> {
        if !(64..=1 << 30).contains(&self.block_bits) {
            return Err(PostError::Settings(format!(
                "block_bits {} (allowed: 64 to 2^30)",
                self.block_bits
            )));
        }
        if self.sample_bits > MAX_SAMPLE_BITS {
            return Err(PostError::Settings(format!(
                "sample_bits {} (allowed: 0 to 2^20)",
                self.sample_bits
            )));
        }
        crate::cascade::Cascade::new(self.schedule, 0.0)
            .map_err(|e| PostError::Settings(e.to_string()))?;
        if !(self.epsilon > 0.0 && self.epsilon < 1.0) {
            return Err(PostError::Settings(format!(
                "epsilon {} (allowed: (0, 1))",
                self.epsilon
            )));
        }
        if let ReconciliationMethod::Ldpc(ldpc) = &self.reconciliation {
            ldpc.check()
                .and_then(|()| crate::ldpc::SyndromeDecoder::new(ldpc.max_iterations).map(drop))
                .map_err(|e| PostError::Settings(format!("reconciliation: {e}")))?;
            if self.block_bits > MAX_SYNDROME_BITS {
                return Err(PostError::Settings(format!(
                    "block_bits {} with LDPC reconciliation (allowed: 64 to 2^22, one code's \
                     block)",
                    self.block_bits
                )));
            }
        }
        self.assumption
            .check()
            .map_err(|e| PostError::Settings(e.to_string()))
    }
}

/// Sessions held, by ID.
type Pool = std::collections::BTreeMap<u32, BitString>;

/// The concatenated bits of `sessions` from `pool`, in order.
fn concatenate(pool: &Pool, sessions: &[u32]) -> BitString {
    let bits: zeroize::Zeroizing<Vec<bool>> = zeroize::Zeroizing::new(
        sessions
            .iter()
            .filter_map(|id| pool.get(id))
            .flat_map(|s| (0..s.len()).map(move |i| s.get(i) == Some(true)))
            .collect(),
    );
    BitString::from_bools(&bits)
}

/// Splits `key` into (the bits at `sample` positions, in order; the rest).
fn split_sample(key: &BitString, sample: &[bool]) -> (Vec<bool>, BitString) {
    let mut disclosed = Vec::new();
    let mut kept = zeroize::Zeroizing::new(Vec::with_capacity(key.len()));
    for (i, &s) in sample.iter().enumerate() {
        let bit = key.get(i) == Some(true);
        if s {
            disclosed.push(bit);
        } else {
            kept.push(bit);
        }
    }
    (disclosed, BitString::from_bools(&kept))
}

/// The public data both block tags bind: block, sessions, nonces, ℓ.
fn tag_context(block: u64, sessions: &[u32], nonces: &[[u8; 32]; 2], length: u64) -> Vec<u8> {
    let mut context = Vec::with_capacity(8 + 4 * sessions.len() + 80);
    context.extend_from_slice(&block.to_be_bytes());
    context.extend_from_slice(&(sessions.len() as u64).to_be_bytes());
    for id in sessions {
        context.extend_from_slice(&id.to_be_bytes());
    }
    for nonce in nonces {
        context.extend_from_slice(nonce);
    }
    context.extend_from_slice(&length.to_be_bytes());
    context
}

/// The key ID both sides derive from a block's tag context.
fn key_id(context: &[u8]) -> String {
    use sha2::{Digest, Sha256};
    let digest = Sha256::new()
        .chain_update(b"robokey/key-id/v1")
        .chain_update(context)
        .finalize();
    digest[..8].iter().map(|b| format!("{b:02x}")).collect()
}

/// Direction labels of the block tags.
const CONTROLLER_TO_ROBOT: &[u8] = b"controller->robot";
const ROBOT_TO_CONTROLLER: &[u8] = b"robot->controller";
