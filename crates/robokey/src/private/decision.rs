//! What the controller decided about a carrying doublet.

use super::doublet::{DoubletInputs, MAX_BITS};
use super::likelihood::{BitEvidence, MAX_PATTERNS};
use crate::model::Pose;

/// What the controller made of one carrying doublet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DoubletDecision {
    /// Doublet index j.
    pub doublet: u32,
    /// Its first step `Lj` (`L` steps per doublet).
    pub step: u32,
    /// Its public inputs.
    pub inputs: DoubletInputs,
    /// The controller's LLR and separation of each bit; the bit is the LLR's sign
    /// (`ln P(view|0) − ln P(view|1)`, 1 when negative).
    pub evidence: BitEvidence,
    /// `ln p(view | h)` of every bit pattern `h` (up to a common constant; unused entries
    /// −∞): with the reconciled bits of the lower slices they give each higher slice's
    /// LLR ([`super::likelihood::staged_llrs`]).
    pub log_likelihoods: [f64; MAX_PATTERNS],
    /// Each bit's separation under the camera Eve's model as the controller can compute it
    /// — her stated camera noise around its own samples — which sizes the key.
    pub assumed_separation: [f64; MAX_BITS],
    /// The controller's samples `y(Lj), y(Lj+1), y(Lj+L)` at the doublet's start, after its
    /// first step and at its end (key material: they stay with the controller), from which
    /// the block's estimate recomputes the residual and Eve's modelled view
    /// (docs/estimation.md; the estimate models the two-step doublet only) and the commands
    /// check what the next commands revealed ([`crate::estimate::commands_check`]).
    pub samples: [Pose; 3],
}
