//! What the controller decided about a carrying doublet.

use super::doublet::{DoubletInputs, MAX_BITS};
use super::likelihood::BitEvidence;
use crate::model::Pose;

/// What the controller made of one carrying doublet.
#[derive(Clone, Debug, PartialEq)]
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
    /// Multilevel doublets: `ln p(view | h)` of every bit pattern `h` (up to a common
    /// constant), from which, with the reconciled bits of the lower slices, each higher
    /// slice's LLR follows ([`super::likelihood::staged_llrs`]); empty for binary doublets,
    /// whose LLRs are the marginal ones.
    pub log_likelihoods: Vec<f64>,
    /// Each bit's separation under the camera Eve's model as the controller can compute it
    /// — her stated camera noise around its own samples — which sizes the key.
    pub assumed_separation: [f64; MAX_BITS],
    /// The controller's samples `y(Lj), y(Lj+1), y(Lj+L)` at the doublet's start, after its
    /// first step and at its end (key material: they stay with the controller), from which
    /// the block's estimate recomputes the residual and Eve's modelled view
    /// (docs/estimation.md) and the commands
    /// check what the next commands revealed ([`crate::estimate::commands_check`]).
    pub samples: [Pose; 3],
    /// A three-step doublet's sample after its second step and its entry speed under the
    /// prior lag (`None` with two steps).
    pub late: Option<super::LateSample>,
}
