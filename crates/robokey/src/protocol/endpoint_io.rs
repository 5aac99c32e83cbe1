//! What the endpoints take and give (docs/protocol.md): each side's input, output and, for
//! the controller, the events it reports. The shells (simulator, UDP agents) feed the inputs
//! and carry out the outputs; both sensing modes share them.

use super::Outcome;
use super::decoder::StepDecision;
use super::message::Message;
use crate::model::{Pose, Unicycle, WheelSpeeds};
use crate::private::{DoubletDecision, DoubletInputs};

/// Input to the controller endpoints (odometry and private sensing).
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
    /// The shell's retransmission timer fired (Finish or Confirm not answered yet).
    Timeout,
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
        /// Its first step `2j`.
        step: u32,
        /// `u(2j)` and `u'(2j+1)`.
        inputs: DoubletInputs,
        /// Whether it carries bits.
        carries: bool,
    },
    /// Private sensing: a carrying doublet was decided and is kept.
    DoubletDecided(DoubletDecision),
    /// Private sensing: a carrying doublet could not be decided (a sample or a measurement
    /// is missing, or the robot did not apply it): it is dropped on both sides.
    DoubletErased {
        /// Doublet index j.
        doublet: u32,
    },
    /// The session ended.
    Finished(Outcome),
}

/// Output of the controller endpoints.
#[derive(Clone, Debug, PartialEq)]
pub enum ControllerOutput {
    /// Send this message to the robot.
    Transmit(Message),
    /// Something happened.
    Event(ControllerEvent),
}

/// Input to the robot endpoint.
#[derive(Clone, Debug, PartialEq)]
pub enum RobotInput {
    /// The odometry pose `y(k)` was sampled at `t_k = k·T`.
    Sample {
        /// Step k.
        step: u32,
        /// `y(k)` (m, m, rad).
        y: Pose,
    },
    /// A message from the controller.
    Frame(Message),
    /// Command `step` has not arrived by its deadline.
    Deadline {
        /// Step k.
        step: u32,
    },
}

/// What the robot applies on `[t_k, t_{k+1})`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Actuation {
    /// Step k.
    pub step: u32,
    /// Wheel speeds (rad/s, right first).
    pub wheels: WheelSpeeds,
    /// The key bit `b(k)` applied, or `None` (protocol off, erased, or stopped).
    pub bit: Option<u8>,
    /// Whether the command was missing and the fallback was applied.
    pub erased: bool,
}

/// Output of the robot endpoint.
#[derive(Clone, Debug, PartialEq)]
pub enum RobotOutput {
    /// Send this message to the controller.
    Transmit(Message),
    /// Drive the wheels.
    Apply(Actuation),
    /// The session ended.
    Finished(Outcome),
}
