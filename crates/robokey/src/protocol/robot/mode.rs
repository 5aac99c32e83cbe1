//! What a sensing mode adds to the robot endpoint: how it reports a sample, applies a
//! command and falls back when one is missing.

use super::lifecycle::{ClosingRules, RobotLifecycle};
use crate::model::Pose;
use crate::protocol::SessionMessage;
use crate::protocol::plan::Agreed;

/// The part of a robot endpoint that depends on the sensing mode (odometry: codewords of
/// command pairs; private sensing: doublets). The shared [`RobotLifecycle`] holds the rest,
/// and closes the session by the mode's [`ClosingRules`].
pub(crate) trait RobotMode: ClosingRules + Send {
    /// Sample instant `t_k`: reports to the controller what the robot applied, and does
    /// whatever the mode does at a sample (private sensing applies a doublet's second input,
    /// or stops at `k = N`).
    fn on_sample(&mut self, agreed: &Agreed, life: &mut RobotLifecycle, step: u32, y: &Pose);

    /// A session message from the controller (its commands); one that does not fit the
    /// robot's state is ignored.
    fn on_message(&mut self, agreed: &Agreed, life: &mut RobotLifecycle, message: &SessionMessage);

    /// Step `step`'s command is missing at its deadline: the fallback.
    fn on_missing(&mut self, agreed: &Agreed, life: &mut RobotLifecycle, step: u32);

    /// The bit word (`v | ω << m`, `m` bits per symbol label) doublet `doublet` carries,
    /// once the robot applied it with them (private sensing; `None` in odometry mode).
    fn carried_word(&self, doublet: u32) -> Option<u64>;
}
