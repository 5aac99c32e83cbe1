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

/// Stops the wheels of the backend it borrows when dropped: on every way out of a session
/// that runs destructors (normal end, error, panic). A killed process runs none, and
/// kh4server has no watchdog (docs/threat-model.md).
pub struct WheelGuard<'a, B: Backend + ?Sized>(&'a mut B);

impl<'a, B: Backend + ?Sized> WheelGuard<'a, B> {
    /// Guards `backend`.
    pub fn new(backend: &'a mut B) -> Self {
        Self(backend)
    }
}

impl<B: Backend + ?Sized> std::ops::Deref for WheelGuard<'_, B> {
    type Target = B;
    fn deref(&self) -> &B {
        self.0
    }
}

impl<B: Backend + ?Sized> std::ops::DerefMut for WheelGuard<'_, B> {
    fn deref_mut(&mut self) -> &mut B {
        self.0
    }
}

impl<B: Backend + ?Sized> Drop for WheelGuard<'_, B> {
    fn drop(&mut self) {
        self.0.stop();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Wheels that remember whether they were stopped.
    #[derive(Default)]
    struct Wheels {
        stopped: bool,
    }

    impl Backend for Wheels {
        fn sample(&mut self) -> Result<Pose, NetError> {
            Err(NetError::Kh4("the encoder read failed".into()))
        }
        fn set_wheels(&mut self, _: WheelSpeeds) -> Result<(), NetError> {
            self.stopped = false;
            Ok(())
        }
        fn stop(&mut self) {
            self.stopped = true;
        }
    }

    fn drive_then_fail(backend: &mut Wheels, panic: bool) -> Result<(), NetError> {
        let mut guarded = WheelGuard::new(backend);
        guarded.set_wheels(WheelSpeeds::new(3.0, 3.0))?;
        assert!(!panic, "a bug in the session");
        guarded.sample()?;
        Ok(())
    }

    #[test]
    fn the_guard_stops_the_wheels_on_an_error_and_on_a_panic() {
        let mut wheels = Wheels::default();
        assert!(drive_then_fail(&mut wheels, false).is_err());
        assert!(wheels.stopped);
        let mut wheels = Wheels::default();
        let unwound = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let _ = drive_then_fail(&mut wheels, true);
        }));
        assert!(unwound.is_err());
        assert!(wheels.stopped);
    }
}
