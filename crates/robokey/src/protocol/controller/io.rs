//! What goes into and comes out of the controller endpoint.

use crate::model::{Pose, Unicycle};
use crate::private::decision::DoubletDecision;
use crate::private::doublet::DoubletInputs;
use crate::protocol::decoder::StepDecision;
use crate::protocol::{Message, Outcome};

/// Input to the controller endpoint.
#[derive(Clone, Debug, PartialEq)]
pub enum ControllerInput {
    /// A message from the robot.
    Frame(Message),
    /// Private sensing: the controller's own sensor sampled `y_c(k)` at `t_k` (the odometry
    /// mode's controller ignores it).
    Sensor {
        /// Step k.
        step: u32,
        /// `y_c(k)` (m, m, rad).
        pose: Pose,
    },
    /// Private sensing: the controller's sensor stopped for good, with the reason.
    SensorStopped(String),
}

/// What the controller observed, for traces and metrics.
#[derive(Clone, Debug, PartialEq)]
pub enum ControllerEvent {
    /// Command pair k was computed from the nominal `uU(k)` (m/s, rad/s).
    Commanded {
        /// Step k.
        step: u32,
        /// Clipped nominal command.
        nominal: Unicycle,
    },
    /// Step `k − 1` was decoded from `y(k)`.
    Decoded(StepDecision),
    /// Steps whose measurement never arrived.
    Missing(std::ops::Range<u32>),
    /// A codeword was decided.
    CodewordDecided {
        /// Codeword index.
        index: u32,
        /// Accepted into the key.
        accepted: bool,
    },
    /// Private sensing: the doublet starting at `step` was commanded with these public
    /// inputs; it carries bits unless the protocol is off or the turn gate stopped it.
    DoubletCommanded {
        /// Its first step `Lj` (`L` steps per doublet).
        step: u32,
        /// `u(Lj)` and `u'(Lj+1)` (held through a third step).
        inputs: DoubletInputs,
        /// Whether it carries bits.
        carries: bool,
    },
    /// Private sensing: a carrying doublet was decided and is kept. Boxed: the decision is
    /// the largest event by far (240 bytes), and every output is moved through the
    /// endpoint's queue at the size of the largest.
    DoubletDecided(Box<DoubletDecision>),
    /// Private sensing: a carrying doublet could not be decided (a sample or a measurement
    /// is missing, or the robot did not apply it): it is dropped on both sides.
    DoubletErased {
        /// Doublet index j.
        doublet: u32,
    },
    /// The session ended.
    Finished(Outcome),
}

/// Output of the controller endpoint.
#[derive(Clone, Debug, PartialEq)]
pub enum ControllerOutput {
    /// Send this message to the robot.
    Transmit(Message),
    /// Something happened.
    Event(ControllerEvent),
}

#[cfg(test)]
mod tests {
    use super::ControllerOutput;

    /// Every output moves through the endpoint's queue and `Pair::drain` at the size of the
    /// largest: kept within 128 bytes (what a move copies inline, without a `memcpy` call),
    /// large payloads boxed (docs/speed.md).
    #[test]
    fn outputs_stay_small() {
        let size = std::mem::size_of::<ControllerOutput>();
        assert!(size <= 128, "a controller output takes {size} bytes");
    }
}
