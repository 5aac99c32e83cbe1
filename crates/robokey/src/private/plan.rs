//! What private sensing adds to the agreed session parameters.

use super::doublet::{DoubletInputs, Perturbation};

/// The private-sensing parameters both endpoints agree on (the rest is in
/// [`crate::protocol::Agreed`]). Doublet `j` occupies the `L` steps `Lj … Lj + L − 1`
/// (`L` = [`Self::steps_per_doublet`]); steps after the last whole doublet are lone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrivatePlan {
    /// The bits a doublet carries and their Δ.
    pub perturbation: Perturbation,
    /// Doublets whose public nominal turn rate exceeds this carry no bit (rad/s).
    pub max_turn_rate: f64,
}

impl PrivatePlan {
    /// `L`: 2, or 3 with a prior lag (`private.prior_lag`).
    #[must_use]
    pub fn steps_per_doublet(&self) -> u32 {
        self.perturbation.steps()
    }

    /// Whether step `step` of a session of `steps` is a doublet's second or third step,
    /// whose input came with the doublet's first; every other step before `steps` is
    /// commanded on its own (a doublet's first, or a lone step after the last doublet).
    #[must_use]
    pub fn is_later_step(&self, step: u32, steps: u32) -> bool {
        let length = self.steps_per_doublet();
        !step.is_multiple_of(length) && step < steps / length * length
    }

    /// Whether a doublet with these public inputs carries bits: the protocol is on
    /// (`enabled`) and its nominal turn rate passes the gate.
    #[must_use]
    pub fn carries(&self, enabled: bool, inputs: &DoubletInputs) -> bool {
        enabled && inputs.turn_rate() <= self.max_turn_rate
    }
}
