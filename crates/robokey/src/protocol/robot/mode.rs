//! What a sensing mode adds to the robot endpoint: how it reports a sample, applies a
//! command, falls back when one is missing, and which units its key keeps.

use super::lifecycle::RobotLifecycle;
use crate::model::Pose;
use crate::protocol::plan::Agreed;
use crate::protocol::{FateLedger, KeyBits, Outcome, SessionMessage};

/// The part of a robot endpoint that depends on the sensing mode (odometry: codewords of
/// command pairs; private sensing: doublets). The shared [`RobotLifecycle`] holds the rest.
pub(crate) trait RobotMode: Send {
    /// Sample instant `t_k`: reports to the controller what the robot applied, and does
    /// whatever the mode does at a sample (private sensing applies a doublet's second input,
    /// or stops at `k = N`).
    fn on_sample(&mut self, agreed: &Agreed, life: &mut RobotLifecycle, step: u32, y: &Pose);

    /// A session message from the controller (its commands); one that does not fit the
    /// robot's state is ignored.
    fn on_message(&mut self, agreed: &Agreed, life: &mut RobotLifecycle, message: SessionMessage);

    /// Step `step`'s command is missing at its deadline: the fallback.
    fn on_missing(&mut self, agreed: &Agreed, life: &mut RobotLifecycle, step: u32);

    /// Whether unit `index` may be kept: one the robot saw erased, or did not carry, never is.
    fn keepable(&self, index: u32) -> bool;

    /// The robot's key from the final fates.
    fn key(&self, fates: &FateLedger) -> KeyBits;

    /// Whether the confirmation tags cover the key (odometry) or not (private sensing: its
    /// raw bits are confirmed per post-processing block).
    fn tags_cover_key(&self) -> bool;

    /// The outcome once the controller's tags verify.
    fn verified(&self) -> Outcome;

    /// The `Abort` reason for a `Finish` covering `codewords` units when the session has `len`.
    fn count_mismatch(&self, codewords: u32, len: u32) -> String;

    /// The bits `[v, ω]` doublet `doublet` carries, once the robot applied it with them
    /// (private sensing; `None` in odometry mode).
    fn carried_bits(&self, doublet: u32) -> Option<[u8; 2]>;
}
