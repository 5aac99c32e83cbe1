//! What goes into and comes out of the robot endpoint.

use crate::model::{Pose, WheelSpeeds};
use crate::protocol::{Message, Outcome};

/// Input to the robot endpoint.
#[derive(Clone, Debug, PartialEq)]
pub enum RobotInput {
    /// The pose `y(k)` sampled at `t_k`, as a [`RobotOutput::Sense`] asked (odometry in
    /// odometry mode; in private sensing the pose stays on the robot).
    Sample {
        /// Step k.
        step: u32,
        /// `y(k)` (m, m, rad).
        y: Pose,
    },
    /// A message from the controller.
    Frame(Message),
}

/// What the robot applies on `[t_k, t_{k+1})`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Actuation {
    /// Step k.
    pub step: u32,
    /// Wheel speeds (rad/s, right first).
    pub wheels: WheelSpeeds,
    /// The key bit `b(k)` applied, or `None` (protocol off, erased, gated, or stopped).
    pub bit: Option<u8>,
    /// Whether the command was missing and the fallback was applied.
    pub erased: bool,
}

/// Output of the robot endpoint.
#[derive(Clone, Debug, PartialEq)]
pub enum RobotOutput {
    /// Send this message to the controller.
    Transmit(Message),
    /// Sample instant `t_k`: read the pose now and feed it back as [`RobotInput::Sample`].
    Sense {
        /// Step k.
        step: u32,
    },
    /// Drive the wheels.
    Apply(Actuation),
    /// The session ended.
    Finished(Outcome),
}
