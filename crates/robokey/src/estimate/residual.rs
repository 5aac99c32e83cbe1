//! One doublet's two-step residual, boundary to boundary, with its deterministic part
//! removed (docs/estimation.md, "What is estimated").
//!
//! With the reconciled bit pattern `h`, the controller predicts the doublet's end from its
//! start sample through the Euler map, bit included: `m₂(h) = f(f(y(2j), u + sΔ), u' − sΔ)`.
//! The prediction carries every modelled deterministic residual of the doublet (the bit, the
//! turn residual `sTΔv(e(θ) − e(θ + Tω))`, the lateral `sT²vΔω`), so what remains is noise:
//!
//! `r = y(2j+2) − m₂(h) ≈ A₁w₀ + w₁ + η₂ − A₁A₀η₀`,
//!
//! with `Aᵢ = ∂f/∂x` along the path, `wₖ` the motion noise of step k and `ηₖ` the sensor's.
//! In the robot's frame at the doublet's start heading θ₀ (`H(θ)` the rotation about the
//! vertical axis, `z = H(θ₀)ᵀ r`), for motion noise of covariance `Q` in the frame of each
//! step's heading and sensor noise `R` in the world's:
//!
//! `Cov(z) = B₀QB₀ᵀ + B₁QB₁ᵀ + C₀RC₀ᵀ + C₁RC₁ᵀ`,
//! `B₀ = H(θ₀)ᵀA₁H(θ₀)`, `B₁ = H(θ₀)ᵀH(θ₁)`, `C₀ = H(θ₀)ᵀ`, `C₁ = H(θ₀)ᵀA₁A₀`.
//!
//! Consecutive doublets share a boundary sample, so their residuals are correlated (MA(1)
//! through `η`, lag-1 correlation `−R/(2Q + 2R)` per axis); doublets two apart share
//! nothing under white motion noise. Under AR(1) motion noise of lag-one correlation ρ
//! between steps (`w_{k+1} = ρw_k + √(1−ρ²)e_k`, stationary covariance `Q`) the two steps of
//! a doublet correlate too, `Cov(z) = B₀QB₀ᵀ + B₁QB₁ᵀ + ρ(B₀QB₁ᵀ + B₁QB₀ᵀ) + …`
//! (`correlation` estimates ρ).

use nalgebra::Matrix3;

use crate::model::Pose;
use crate::private::DoubletInputs;
use crate::private::likelihood::{DoubletModel, state_jacobian};

/// The robot-frame axes, for people.
pub(super) const AXES: [&str; 3] = ["along-track", "lateral", "heading"];

/// A doublet's residual and the maps that give its covariance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DoubletResidual {
    /// Doublet index j (residuals of doublets of the same parity are independent).
    pub doublet: u32,
    /// `z`: the residual in the robot's frame at the doublet's start (m, m, rad).
    pub value: Pose,
    /// `[B₀, B₁]`: how each step's motion noise enters `z`.
    pub motion_maps: [Matrix3<f64>; 2],
    /// `[C₀, C₁]`: how the end and the start sample's sensor noise enter `z`.
    pub sensor_maps: [Matrix3<f64>; 2],
    /// The doublet's public nominal inputs (what the homogeneity test classes it by).
    pub inputs: DoubletInputs,
}

/// The rotation `H(θ)` about the vertical axis: a robot-frame vector to the world's.
#[must_use]
pub fn rotation(theta: f64) -> Matrix3<f64> {
    let (sin, cos) = theta.sin_cos();
    Matrix3::new(cos, -sin, 0.0, sin, cos, 0.0, 0.0, 0.0, 1.0)
}

impl DoubletResidual {
    /// The residual of doublet `doublet` with public `inputs`, the controller's samples
    /// `start = y(2j)` and `end = y(2j+2)`, and the reconciled bit pattern `pattern`
    /// (v-bit `pattern & 1`, ω-bit `pattern >> 1`), under `model`'s sample time and Δ.
    #[must_use]
    pub fn new(
        model: &DoubletModel,
        doublet: u32,
        inputs: &DoubletInputs,
        start: &Pose,
        end: &Pose,
        pattern: usize,
    ) -> Self {
        let t = model.sample_time;
        let offset = model.perturbation.offset(pattern);
        let [a, b] = inputs.applied(offset);
        let [middle, predicted] = inputs.propagate(start, offset, t);
        let a0 = state_jacobian(start.z, a.x, t);
        let a1 = state_jacobian(middle.z, b.x, t);
        let h0 = rotation(start.z).transpose();
        Self {
            doublet,
            value: h0 * (end - predicted),
            motion_maps: [h0 * a1 * rotation(start.z), h0 * rotation(middle.z)],
            sensor_maps: [h0, h0 * a1 * a0],
            inputs: *inputs,
        }
    }

    /// `B₀QB₀ᵀ + B₁QB₁ᵀ + ρ·(B₀QB₁ᵀ + B₁QB₀ᵀ)`: the motion noise's part of `Cov(z)` for
    /// AR(1) motion noise of stationary covariance `Q` in the robot's frame and lag-one
    /// correlation `rho` between steps (`rho = 0`: white).
    #[must_use]
    pub fn motion_part(&self, q: &Matrix3<f64>, rho: f64) -> Matrix3<f64> {
        let [b0, b1] = &self.motion_maps;
        let cross = b0 * q * b1.transpose();
        b0 * q * b0.transpose() + b1 * q * b1.transpose() + rho * (cross + cross.transpose())
    }

    /// `C₀RC₀ᵀ + C₁RC₁ᵀ`: the sensor's part of `Cov(z)` for `R` in the world's frame.
    #[must_use]
    pub fn sensor_part(&self, r: &Matrix3<f64>) -> Matrix3<f64> {
        self.sensor_maps.iter().map(|c| c * r * c.transpose()).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use crate::model::Unicycle;
    use crate::private::doublet_model;

    /// A noise-free doublet leaves no residual whatever its bits and turn, when the
    /// residual is formed with the bits that rode on it.
    #[test]
    fn the_bits_and_the_turn_leave_no_residual() {
        let mut config = Config::default();
        config.protocol.bits_per_doublet = 2;
        let model = doublet_model(&config);
        let inputs = DoubletInputs {
            first: Unicycle::new(0.1, 0.4),
            second: Unicycle::new(0.09, 0.3),
        };
        let start = Pose::new(0.2, -0.4, 1.1);
        for pattern in 0..4 {
            let offset = model.perturbation.offset(pattern);
            let end = inputs.propagate(&start, offset, model.sample_time)[1];
            let r = DoubletResidual::new(&model, 3, &inputs, &start, &end, pattern);
            assert!(r.value.norm() < 1e-15, "{pattern}: {}", r.value);
            // With the wrong pattern the bit's 14 mm (or its turn residual) remains.
            let wrong = DoubletResidual::new(&model, 3, &inputs, &start, &end, pattern ^ 1);
            assert!(wrong.value.norm() > 1e-4, "{pattern}: {}", wrong.value);
        }
    }

    /// On a straight doublet the maps are the identity up to the heading's lateral
    /// coupling `T·v`: `Cov(z) = 2Q + 2R` to that order.
    #[test]
    fn on_a_straight_doublet_the_covariance_is_twice_q_plus_r() {
        let model = doublet_model(&Config::default());
        let inputs = DoubletInputs {
            first: Unicycle::new(0.1, 0.0),
            second: Unicycle::new(0.1, 0.0),
        };
        let start = Pose::new(0.0, 0.0, 0.7);
        let r = DoubletResidual::new(&model, 0, &inputs, &start, &start, 0);
        let q = Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, 2.0, 3.0));
        let two_q = r.motion_part(&q, 0.0);
        let coupling = model.sample_time * 0.135;
        assert!(
            (two_q - 2.0 * q).abs().max() < 3.0 * 3.0 * coupling,
            "{two_q}"
        );
        assert!((two_q[(0, 0)] - 2.0).abs() < 1e-12, "along-track: {two_q}");
    }
}
