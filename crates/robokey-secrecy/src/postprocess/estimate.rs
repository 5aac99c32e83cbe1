//! Keys sized from the measured plant between the agents (docs/estimation.md, "In the
//! agents"): what the controller's endpoint asks of its shell after reconciliation, and what
//! it carries of the answer. The shell estimates the plant from the samples the pool kept of
//! each session and the robot's bits (the reconciled key with the disclosed sample put
//! back); the endpoint publishes the outcome — the block's separation on a 2⁻⁸ grid in
//! `Confirm`, or a refusal as an `Abort` — and both sides size ℓ from what was carried.

use serde::{Deserialize, Serialize};

use crate::bitstring::BitString;

/// The grid a block's separation is published on: multiples of 2⁻⁸.
pub const SEPARATION_QUANTUM: f64 = 1.0 / 256.0;

/// The largest published separation in grid steps (separation 256): above it Eve is taken
/// to see every bit. With the refusal, the published outcome takes 2¹⁶ + 2 values.
pub const MAX_SEPARATION_STEPS: u32 = 1 << 16;

/// One carrying doublet as the controller keeps it for the block's estimate: key material
/// (its samples), never sent.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct KeptDoublet {
    /// Doublet index j in its session.
    pub doublet: u32,
    /// Its public inputs `u(2j)`, `u'(2j+1)` (m/s, rad/s).
    pub inputs: [[f64; 2]; 2],
    /// The controller's samples `y(Lj), y(Lj+1), y(Lj+L)` (m, m, rad): the start, after the
    /// first step, the end (`L` = 2, or 3 with a prior lag).
    pub samples: [[f64; 3]; 3],
    /// A three-step doublet's sample after its second step and entry speed. Absent with
    /// two steps, and in what the format before it kept: such records read unchanged and
    /// a block holding any of them is sized from the three samples alone.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub late: Option<KeptLate>,
}

/// What a three-step doublet keeps beyond its three samples (docs/estimation.md, "The
/// lag"): key material, never sent.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct KeptLate {
    /// The controller's sample `y(3j+2)` after the shape's second step (m, m, rad).
    pub sample: [f64; 3],
    /// The wheels' nominal speed at the doublet's start under the prior lag (m/s, rad/s),
    /// with which the online decision took the doublet.
    pub entry: [f64; 2],
}

/// What the pool keeps of one session for the estimate: its decided doublets, in the order
/// of the session's raw bits (one doublet per `bits_per_doublet` bits).
pub type SessionSamples = Vec<KeptDoublet>;

/// What the controller needs estimated, for one block.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimateRequest {
    /// Block number.
    pub block: u64,
    /// Each agreed session, in block order: its ID, what the pool kept of it (empty if
    /// nothing was kept) and the robot's bits of it — the reconciled key with the disclosed
    /// sample put back (key material).
    pub sessions: Vec<(u32, SessionSamples, BitString)>,
    /// How many of the block's bits its sample disclosed: the block is sized over the rest,
    /// whichever they were (the per-bit bound takes the worst choice).
    pub disclosed: u64,
}

/// Why the shell's estimate refused a block, naming the test and the value.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EstimateRefusal(pub String);

/// The published outcome of a block's estimate: the equivalent separation of its bits'
/// worst-case separations in grid steps
/// ([`SEPARATION_QUANTUM`], at most [`MAX_SEPARATION_STEPS`]), or a refusal. Under
/// configured sizing the shell answers the commands check only: `Ok` (the value unused, the
/// block sized from the assumption as configured) or the refusal.
pub type EstimateOutcome = Result<u32, EstimateRefusal>;

/// What the controller asks of its shell before LDPC decodes a block whose LLRs are
/// recomputed at block time (docs/estimation.md, "Causality"): every agreed session's kept
/// samples and the disclosed sample — public bits — from which the shell estimates the
/// motion model and recomputes every bit's LLR; for a multilevel slice's block, each
/// session's staged material as well (the lower slices' bits the controller reconciled
/// before). Nothing in it depends on bits the controller does not hold yet.
#[derive(Debug, Clone, PartialEq)]
pub struct LlrRequest {
    /// Block number.
    pub block: u64,
    /// Each agreed session, in block order: its ID, its raw bits' count and what the pool
    /// kept of it (empty if nothing was kept).
    pub sessions: Vec<(u32, usize, SessionSamples)>,
    /// The disclosed sample: each sampled position in the block's raw bits (in order) with
    /// the robot's bit there, as the robot published it.
    pub disclosed: Vec<(u32, bool)>,
    /// A multilevel slice's block: each agreed session's staged material, in block order
    /// (its slice, the lower slices' reconciled bits and what the pool kept of its doublets);
    /// empty for binary sessions.
    pub staged: Vec<super::StagedSession>,
}

/// The LLRs the shell recomputed for an [`LlrRequest`].
#[derive(Debug, Clone, PartialEq)]
pub struct RecomputedLlrs {
    /// The model they were computed with, for the block's report (`measured`, `world`).
    pub model: String,
    /// One per raw bit of the block, in block order (nats, `ln P(view | 0) − ln P(view | 1)`).
    pub llrs: Vec<f64>,
}

/// The shell's answer to an [`LlrRequest`]: the recomputed LLRs, or why the prior's (those
/// pooled with the sessions) stay — recorded in the block's report.
pub type LlrAnswer = Result<RecomputedLlrs, String>;
