//! Differential-drive and unicycle kinematics (docs/model.md).

use nalgebra::{Matrix2, Matrix3x2, Vector2, Vector3};

/// Robot pose `[px, py, θ]` (m, m, rad). θ is never wrapped.
pub type Pose = Vector3<f64>;
/// Wheel speeds `[ωr, ωl]` (rad/s, right wheel first).
pub type WheelSpeeds = Vector2<f64>;
/// Unicycle input `[v, ω]` (m/s, rad/s).
pub type Unicycle = Vector2<f64>;

/// Wheel geometry of a differential-drive robot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiffDrive {
    /// Wheel radius `r` (m).
    pub wheel_radius: f64,
    /// Distance between the wheels `D` (m).
    pub axle_length: f64,
}

impl DiffDrive {
    /// `H = [[r/2, r/2], [r/D, −r/D]]`, so that `uU = H·uD`.
    #[must_use]
    pub fn h(&self) -> Matrix2<f64> {
        let (r, d) = (self.wheel_radius, self.axle_length);
        Matrix2::new(r / 2.0, r / 2.0, r / d, -r / d)
    }

    /// `uU = H·uD`: wheel speeds (rad/s) to unicycle input (m/s, rad/s).
    #[must_use]
    pub fn to_unicycle(&self, wheels: WheelSpeeds) -> Unicycle {
        let r = self.wheel_radius;
        Unicycle::new(
            r * (wheels.x + wheels.y) / 2.0,
            r * (wheels.x - wheels.y) / self.axle_length,
        )
    }

    /// `uD = H⁻¹·uU`: unicycle input (m/s, rad/s) to wheel speeds (rad/s).
    #[must_use]
    pub fn to_wheels(&self, input: Unicycle) -> WheelSpeeds {
        let half_turn = input.y * self.axle_length / 2.0;
        WheelSpeeds::new(
            (input.x + half_turn) / self.wheel_radius,
            (input.x - half_turn) / self.wheel_radius,
        )
    }

    /// Clips a unicycle command to the wheel-speed rhombus `|ωr|, |ωl| ≤ limit` (rad/s)
    /// as the controller does (docs/model.md): first `|ω| ≤ 2·r·limit/D`, then
    /// `|v| ≤ r·limit − (D/2)|ω|`.
    #[must_use]
    pub fn clip_to_rhombus(&self, input: Unicycle, limit: f64) -> Unicycle {
        let (r, d) = (self.wheel_radius, self.axle_length);
        let omega_max = 2.0 * r * limit / d;
        let omega = input.y.clamp(-omega_max, omega_max);
        let v_max = (r * limit - d / 2.0 * omega.abs()).max(0.0);
        Unicycle::new(input.x.clamp(-v_max, v_max), omega)
    }
}

/// Clips each wheel to `|ω| ≤ limit` (rad/s), as the plant's motors do.
#[must_use]
pub fn clip_wheels(wheels: WheelSpeeds, limit: f64) -> WheelSpeeds {
    wheels.map(|w| w.clamp(-limit, limit))
}

/// `(sin θ, cos θ)` of a heading θ, computed once and shared by `f`, `A = ∂f/∂x` and
/// `B = ∂f/∂u` at the same pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Heading {
    /// `sin θ`.
    pub sin: f64,
    /// `cos θ`.
    pub cos: f64,
}

impl Heading {
    /// The heading of `pose`.
    #[must_use]
    pub fn of(pose: &Pose) -> Self {
        let (sin, cos) = pose.z.sin_cos();
        Self { sin, cos }
    }
}

/// `B(θ) = ∂f/∂u = [[T cos θ, 0], [T sin θ, 0], [0, T]]`.
#[must_use]
pub fn input_matrix(heading: Heading, sample_time: f64) -> Matrix3x2<f64> {
    Matrix3x2::new(
        sample_time * heading.cos,
        0.0,
        sample_time * heading.sin,
        0.0,
        0.0,
        sample_time,
    )
}

/// The noise-free forward-Euler unicycle map `f(x, u)` of docs/model.md over one period `T` (s).
#[must_use]
pub fn unicycle_step(pose: &Pose, input: &Unicycle, sample_time: f64) -> Pose {
    unicycle_step_at(pose, Heading::of(pose), input, sample_time)
}

/// [`unicycle_step`] with the heading's trigonometry already known.
#[must_use]
pub fn unicycle_step_at(pose: &Pose, heading: Heading, input: &Unicycle, sample_time: f64) -> Pose {
    Pose::new(
        pose.x + sample_time * input.x * heading.cos,
        pose.y + sample_time * input.x * heading.sin,
        pose.z + sample_time * input.y,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    const KHEPERA: DiffDrive = DiffDrive {
        wheel_radius: 0.021,
        axle_length: 0.1047,
    };

    #[test]
    fn h_times_h_inverse_is_identity() {
        let h_inv = KHEPERA.h().try_inverse().unwrap();
        assert!((KHEPERA.h() * h_inv - Matrix2::identity()).norm() < 1e-12);
        let u = Unicycle::new(0.07, -0.4);
        assert!((KHEPERA.to_unicycle(KHEPERA.to_wheels(u)) - u).norm() < 1e-15);
        assert!((KHEPERA.h() * KHEPERA.to_wheels(u) - u).norm() < 1e-15);
    }

    #[test]
    fn rhombus_keeps_both_wheels_within_limit() {
        for &(v, w) in &[
            (1.0, 0.0),
            (0.0, 50.0),
            (0.5, 2.0),
            (-0.3, -1.5),
            (0.05, 0.1),
        ] {
            let clipped = KHEPERA.clip_to_rhombus(Unicycle::new(v, w), 8.07);
            let wheels = KHEPERA.to_wheels(clipped);
            assert!(wheels.abs().max() <= 8.07 + 1e-9, "{v} {w} -> {wheels}");
        }
        let inside = Unicycle::new(0.05, 0.1);
        assert_eq!(KHEPERA.clip_to_rhombus(inside, 8.07), inside);
    }

    #[test]
    fn step_moves_along_heading() {
        let next = unicycle_step(
            &Pose::new(1.0, 2.0, std::f64::consts::FRAC_PI_2),
            &Unicycle::new(0.5, 1.0),
            0.2,
        );
        assert!((next - Pose::new(1.0, 2.1, std::f64::consts::FRAC_PI_2 + 0.2)).norm() < 1e-12);
    }
}
