//! Eve's modelled view at the region's worst case (docs/estimation.md, "The corner").
//!
//! A bit's separation under the camera statement is `d² = δᵀS(Q)⁻¹δ`, with `δ` the
//! difference of her predicted observations under the bit's two values and
//! `S(Q) = [I; A₁]·(A₀P₀A₀ᵀ + Q)·[I, A₁ᵀ] + diag(0, Q) + diag(R_e,1, R_e,2)` (her camera
//! and the boundary samples fused). `S` grows with `Q` in the Loewner order, so `d` shrinks:
//! over the region `{Q : Q ⪰ Q_low}` the largest separation — the sharpest view Eve may
//! have — is at the vertex `Q_low` itself, for every bit at once. The corner is not the
//! per-entry minimum: `Q_low` is a full 3×3 matrix, rotated into the world's frame at each
//! doublet's heading. If `S(Q_low)` is not positive definite (a vertex so far below zero
//! that even her camera's noise does not cover it), no finite bound exists: `None`.

use nalgebra::Matrix3;

use super::residual::rotation;
use crate::private::DoubletInputs;
use crate::private::likelihood::{DoubletModel, DoubletView};

/// The grid a block's worst-case separation is published on: multiples of 2⁻⁸.
pub const SEPARATION_QUANTUM: f64 = 1.0 / 256.0;

/// The largest separation published; above it Eve is taken to see every bit (ℓ = 0).
pub const MAX_PUBLISHED_SEPARATION: f64 = 256.0;

/// log₂ of the values the published outcome of a block's estimate can take, rounded up: the
/// 2¹⁶ + 1 grid points 0, 2⁻⁸, …, 256 of the separation, or a refusal — `log₂(2¹⁶ + 2)` bits,
/// charged against Eve's min-entropy since the estimate depends on the bits.
pub const ESTIMATE_LEAK_BITS: f64 = 16.000_045;

/// `d` rounded up to the published grid, at most [`MAX_PUBLISHED_SEPARATION`]: rounding up
/// only sharpens Eve's modelled view, so the bound stays a bound.
#[must_use]
pub fn published_separation(d: f64) -> f64 {
    ((d / SEPARATION_QUANTUM).ceil() * SEPARATION_QUANTUM).min(MAX_PUBLISHED_SEPARATION)
}

/// Each bit's separation of Eve's modelled `view` of a doublet with public `inputs`, under
/// `model` with its motion noise replaced by the region's vertex `lower` (robot frame);
/// `None` when the bound does not exist.
#[must_use]
pub fn worst_case_separations(
    model: &DoubletModel,
    lower: &Matrix3<f64>,
    inputs: &DoubletInputs,
    view: &DoubletView,
) -> Option<[f64; 2]> {
    let h = rotation(view.start.value.z);
    let worst = DoubletModel {
        process_covariance: h * lower * h.transpose(),
        ..*model
    };
    let defined = worst
        .log_likelihoods(inputs, view)
        .iter()
        .take(worst.perturbation.patterns())
        .all(|l| l.is_finite());
    defined.then(|| worst.separations(inputs, view))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use crate::model::{Pose, Unicycle};
    use crate::private::doublet_model;
    use crate::private::likelihood::stated_camera_view;
    use crate::rng::{Purpose, stream};
    use nalgebra::Vector3;
    use rand::RngExt;

    #[test]
    fn the_published_grid_rounds_up_and_its_charge_counts_its_values() {
        assert_eq!(published_separation(1.0), 1.0);
        assert!(published_separation(1.0001) > 1.0001);
        assert!(published_separation(1.0001) - 1.0001 < SEPARATION_QUANTUM);
        assert_eq!(published_separation(1e6), MAX_PUBLISHED_SEPARATION);
        // The grid 0, 2⁻⁸, …, 256 and a refusal.
        let values = MAX_PUBLISHED_SEPARATION / SEPARATION_QUANTUM + 2.0;
        assert!(ESTIMATE_LEAK_BITS >= values.log2() && ESTIMATE_LEAK_BITS - values.log2() < 1e-5);
    }

    /// The vertex dominates the region: 500 random members `Q_low + GGᵀ` (full matrices,
    /// any orientation, off-diagonal entries of either sign) never give a larger separation
    /// than `Q_low` to either bit.
    #[test]
    fn no_member_of_the_region_gives_eve_a_sharper_view_than_the_vertex() {
        let mut config = Config::default();
        config.protocol.bits_per_doublet = 2;
        let model = doublet_model(&config);
        let inputs = DoubletInputs {
            first: Unicycle::new(0.1, 0.45),
            second: Unicycle::new(0.1, 0.4),
        };
        let samples = [
            Pose::new(0.0, 0.0, 0.8),
            Pose::new(0.02, 0.02, 0.9),
            Pose::new(0.03, 0.035, 0.97),
        ];
        let view = stated_camera_view(
            samples,
            config.sensing.controller_std,
            config.eve.camera_std,
        );
        let lower = Matrix3::new(1e-6, 2e-7, 0.0, 2e-7, 8e-7, 1e-8, 0.0, 1e-8, 1e-6);
        let vertex = worst_case_separations(&model, &lower, &inputs, &view).unwrap();
        let mut rng = stream(5, Purpose::Public, 0);
        for _ in 0..500 {
            let g = Matrix3::from_fn(|_, _| rng.random_range(-1.5e-3..1.5e-3));
            let member = lower + g * g.transpose();
            let d = worst_case_separations(&model, &member, &inputs, &view).unwrap();
            for k in 0..2 {
                assert!(d[k] <= vertex[k] + 1e-12, "{d:?} > {vertex:?}");
            }
        }
        // A vertex more than the camera's noise below zero has no bound.
        let impossible = -Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 1.0));
        assert!(worst_case_separations(&model, &impossible, &inputs, &view).is_none());
    }
}
