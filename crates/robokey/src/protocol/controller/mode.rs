//! What a sensing mode adds to the controller endpoint: how it tracks and commands the robot
//! and how it decides the units' fates.

use super::lifecycle::ControllerLifecycle;
use crate::model::Pose;
use crate::protocol::SessionMessage;
use crate::protocol::plan::Agreed;

/// The part of a controller endpoint that depends on the sensing mode (odometry: command
/// pairs decoded from the robot's measurements; private sensing: doublets decided from the
/// controller's own sensor). The shared [`ControllerLifecycle`] holds the rest; a mode calls
/// [`ControllerLifecycle::close`] once every fate is known. Its `Debug` prints no key
/// material.
pub(crate) trait ControllerMode: std::fmt::Debug + Send {
    /// A session message from the robot (its reports); one that does not fit the session's
    /// state is ignored.
    fn on_message(
        &mut self,
        agreed: &Agreed,
        life: &mut ControllerLifecycle,
        message: SessionMessage,
    );

    /// The controller's own sensor sampled `y_c(k)` (private sensing; the odometry mode
    /// ignores it).
    fn on_sensor(&mut self, agreed: &Agreed, life: &mut ControllerLifecycle, step: u32, pose: Pose);

    /// Whether the mode decides from the controller's own sensor, which must keep up.
    fn uses_sensor(&self) -> bool;
}
