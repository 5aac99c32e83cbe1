//! Dynamic feedback linearization tracking controller (De Luca, Oriolo, Vendittelli 2001,
//! Eq. 5.18; docs/model.md).

use crate::model::{DiffDrive, Pose, Unicycle};
use crate::trajectory::ReferencePoint;

/// Gains and limits of the tracking controller.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackingGains {
    /// Proportional gain `kp` (1/s²).
    pub kp: f64,
    /// Derivative gain `kd` (1/s).
    pub kd: f64,
    /// Guard `ε` on the integrator in the ω division (m/s).
    pub xi_eps: f64,
    /// The controller's wheel-speed limit for the rhombus clip (rad/s).
    pub wheel_limit: f64,
}

impl TrackingGains {
    /// The gains of a configuration's `[controller]` table.
    #[must_use]
    pub fn of(c: &crate::config::ControllerConfig) -> Self {
        Self {
            kp: c.kp,
            kd: c.kd,
            xi_eps: c.xi_eps,
            wheel_limit: c.wheel_limit,
        }
    }

    /// `∂ω/∂θ̂`: how the turn rate ω (rad/s) [`TrackingController::command`] returns moves
    /// with the heading θ̂ (rad) of the pose it is given, the reference and ξ before the
    /// command held (rad/s per rad), read from the command `command` (m/s, rad/s) and the
    /// one before it, `previous`, whose speed is that ξ (m/s), on `drive` at sample time
    /// `sample_time` T (s). With the law's `u₁, u₂` (m/s²), `M = u₁·cos θ̂ + u₂·sin θ̂`,
    /// `N = u₂·cos θ̂ − u₁·sin θ̂`, `ξ′ = ξ + T·M` and `ω = N/ξ′`: `∂u₁/∂θ̂ = k_d·ξ·sin θ̂`,
    /// `∂u₂/∂θ̂ = −k_d·ξ·cos θ̂`, so `∂M/∂θ̂ = N`, `∂N/∂θ̂ = −(k_d·ξ + M)` and
    ///
    /// `∂ω/∂θ̂ = −(k_d·ξ + M)/ξ′ − T·ω²`, `M = (ξ′ − ξ)/T`, `ξ′` the command's speed.
    ///
    /// None where either command lies on the wheel rhombus's edge (clipped: its speed is not
    /// the integrator's) or the command's speed is within the guard (`|ξ′| ≤ ε`).
    #[must_use]
    pub fn heading_gain(
        &self,
        drive: &DiffDrive,
        previous: Unicycle,
        command: Unicycle,
        sample_time: f64,
    ) -> Option<f64> {
        let inside = |u: Unicycle| drive.clip_to_rhombus(u, self.wheel_limit * (1.0 - 1e-9)) == u;
        if !inside(previous) || !inside(command) || command.x.abs() <= self.xi_eps {
            return None;
        }
        let (xi, next, omega) = (previous.x, command.x, command.y);
        let along = (next - xi) / sample_time;
        Some(-(self.kd * xi + along) / next - sample_time * omega * omega)
    }
}

/// The controller with its integrator state `ξ` (= v, m/s).
#[derive(Clone, Debug)]
pub struct TrackingController {
    gains: TrackingGains,
    drive: DiffDrive,
    sample_time: f64,
    xi: f64,
}

impl TrackingController {
    /// A controller at rest (`ξ = 0`) for sample time `T` (s).
    #[must_use]
    pub fn new(gains: TrackingGains, drive: DiffDrive, sample_time: f64) -> Self {
        Self {
            gains,
            drive,
            sample_time,
            xi: 0.0,
        }
    }

    /// The integrator state `ξ` (m/s).
    #[must_use]
    pub fn xi(&self) -> f64 {
        self.xi
    }

    /// Computes the nominal command `uU(k)` for the pose `p` and reference at step k,
    /// clipped to the controller's wheel rhombus. Updates `ξ` first (unclipped, no
    /// anti-windup), then uses it.
    pub fn command(&mut self, pose: &Pose, reference: &ReferencePoint) -> Unicycle {
        let TrackingGains { kp, kd, xi_eps, .. } = self.gains;
        let (sin, cos) = pose.z.sin_cos();
        let u1 = reference.acceleration.x
            + kp * (reference.position.x - pose.x)
            + kd * (reference.velocity.x - self.xi * cos);
        let u2 = reference.acceleration.y
            + kp * (reference.position.y - pose.y)
            + kd * (reference.velocity.y - self.xi * sin);
        self.xi += self.sample_time * (u1 * cos + u2 * sin);
        // sgn(0) = +1: f64::signum(-0.0) is −1, so the guard is written out.
        let xi_guarded = if self.xi >= 0.0 {
            self.xi.max(xi_eps)
        } else {
            self.xi.min(-xi_eps)
        };
        let omega = (u2 * cos - u1 * sin) / xi_guarded;
        self.drive
            .clip_to_rhombus(Unicycle::new(self.xi, omega), self.gains.wheel_limit)
    }
}

/// The controller's tracking of the reference: the trajectory and the tracking law, as both
/// controller modes use them.
#[derive(Clone, Debug)]
pub struct ReferenceTracker {
    trajectory: crate::trajectory::Trajectory,
    law: TrackingController,
    sample_time: f64,
}

impl ReferenceTracker {
    /// The tracking of a validated configuration's trajectory, with the agreed wheel geometry
    /// `drive` and sample time `T` (s).
    #[must_use]
    pub fn new(config: &crate::config::Config, drive: DiffDrive, sample_time: f64) -> Self {
        Self {
            trajectory: config.trajectory(),
            law: TrackingController::new(TrackingGains::of(&config.controller), drive, sample_time),
            sample_time,
        }
    }

    /// The nominal command `uU(k)` (m/s, rad/s) from `pose` towards the reference at `t_k`.
    pub fn command(&mut self, pose: &Pose, step: u32) -> Unicycle {
        let reference = self.trajectory.at(f64::from(step) * self.sample_time);
        self.law.command(pose, &reference)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::unicycle_step;
    use crate::trajectory::Trajectory;

    /// The Khepera's drive and the paper's tracking gains.
    fn khepera() -> (DiffDrive, TrackingGains) {
        let drive = DiffDrive {
            wheel_radius: 0.021,
            axle_length: 0.1047,
        };
        let gains = TrackingGains {
            kp: 1.1,
            kd: 0.8,
            xi_eps: 1e-3,
            wheel_limit: 8.07,
        };
        (drive, gains)
    }

    #[test]
    fn noise_free_tracking_error_is_below_two_millimetres() {
        let (drive, gains) = khepera();
        let traj = Trajectory::paper_square();
        let mut ctl = TrackingController::new(gains, drive, 0.2);
        let mut pose = Pose::zeros();
        let n = traj.steps(0.2);
        let mut jx = 0.0;
        for k in 0..n {
            let u = ctl.command(&pose, &traj.at(k as f64 * 0.2));
            let applied = drive.to_unicycle(crate::model::clip_wheels(drive.to_wheels(u), 38.0));
            pose = unicycle_step(&pose, &applied, 0.2);
            jx += (pose.xy() - traj.at((k + 1) as f64 * 0.2).position).norm();
        }
        let jx = jx / n as f64;
        assert!(jx < 2e-3, "J_x = {jx} m");
    }

    /// The gain read from the commands matches the law's own central difference in the
    /// heading (±1 µrad) at every step of the paper's square driven without noise, where
    /// neither command is clipped (relative error below 10⁻⁵ plus 10⁻⁵ rad/s per rad: the
    /// difference's truncation, `O(h²)` of ω's third derivative, and rounding, `O(10⁻¹⁶/h)`).
    #[test]
    fn the_heading_gain_is_the_laws_derivative() {
        let (drive, gains) = khepera();
        let traj = Trajectory::paper_square();
        let mut ctl = TrackingController::new(gains, drive, 0.1);
        let mut pose = Pose::new(0.01, -0.02, 0.05);
        let mut previous = Unicycle::zeros();
        let mut compared = 0;
        for k in 1..traj.steps(0.1) {
            let reference = traj.at(k as f64 * 0.1);
            let turned = |h: f64| {
                let mut law = ctl.clone();
                law.command(&Pose::new(pose.x, pose.y, pose.z + h), &reference)
                    .y
            };
            let difference = (turned(1e-6) - turned(-1e-6)) / 2e-6;
            let command = ctl.command(&pose, &reference);
            if let Some(gain) = gains.heading_gain(&drive, previous, command, 0.1) {
                assert!(
                    (gain - difference).abs() < 1e-5 * (1.0 + difference.abs()),
                    "step {k}: {gain} against {difference}"
                );
                compared += 1;
            }
            pose = unicycle_step(&pose, &command, 0.1);
            previous = command;
        }
        assert!(compared > 100, "{compared} steps compared");
    }

    #[test]
    fn guard_treats_zero_as_positive() {
        let drive = DiffDrive {
            wheel_radius: 0.021,
            axle_length: 0.1047,
        };
        let gains = TrackingGains {
            kp: 1.0,
            kd: 1.0,
            xi_eps: 1e-3,
            wheel_limit: 1e9,
        };
        let mut ctl = TrackingController::new(gains, drive, 0.2);
        let reference = ReferencePoint {
            position: nalgebra::Vector2::new(0.0, 1e-6),
            velocity: nalgebra::Vector2::zeros(),
            acceleration: nalgebra::Vector2::zeros(),
        };
        // u1 = 0 ⇒ ξ stays 0; ω = u2 / (+ε) must be positive.
        let u = ctl.command(&Pose::zeros(), &reference);
        assert_eq!(ctl.xi(), 0.0);
        assert!(u.y > 0.0, "{u}");
    }
}
