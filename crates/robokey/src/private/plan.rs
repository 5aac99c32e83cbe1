//! What private sensing adds to the agreed session parameters.

use super::doublet::{DoubletInputs, Perturbation};

/// The private-sensing parameters both endpoints agree on (the rest is in
/// [`crate::protocol::Agreed`]). Doublet `j` occupies steps `2j` and `2j + 1`; with `N` odd the
/// last step is lone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrivatePlan {
    /// The bits a doublet carries and their Δ.
    pub perturbation: Perturbation,
    /// Doublets whose public nominal turn rate exceeds this carry no bit (rad/s).
    pub max_turn_rate: f64,
}

impl PrivatePlan {
    /// Whether a doublet with these public inputs carries bits: the protocol is on
    /// (`enabled`) and its nominal turn rate passes the gate.
    #[must_use]
    pub fn carries(&self, enabled: bool, inputs: &DoubletInputs) -> bool {
        enabled && inputs.turn_rate() <= self.max_turn_rate
    }
}
