//! Where the robot agent's wheels and odometry live: a simulated plant, or a Khepera IV.

use robokey::model::{Pose, WheelSpeeds};

use crate::error::NetError;

/// The robot's motors and odometry, sampled once per period.
///
/// The agent calls [`Backend::sample`] at each sample time `t_k` and then
/// [`Backend::set_wheels`] with what it applies on `[t_k, t_{k+1})`. A backend with virtual
/// time advances one period `T` per sample after the first.
pub trait Backend {
    /// The odometry pose `y(k)` (m, m, rad; θ unwrapped) at the current sample time.
    ///
    /// # Errors
    /// The robot cannot be read.
    fn sample(&mut self) -> Result<Pose, NetError>;

    /// Drives the wheels (rad/s, right first) until the next call.
    ///
    /// # Errors
    /// The robot cannot be commanded.
    fn set_wheels(&mut self, wheels: WheelSpeeds) -> Result<(), NetError>;

    /// Stops the wheels (best effort; called on every exit path).
    fn stop(&mut self);
}
