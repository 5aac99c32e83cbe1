//! Eve's modelled view at the region's worst case (docs/estimation.md, "The corner").
//!
//! A bit's separation under the camera statement is `d² = δᵀS⁻¹δ`, with `δ` the difference
//! of her predicted observations of the doublet's middle and end under the bit's two values
//! (the doublet's other bits known, the larger over their values: with `protocol.levels >
//! 2` the rest of its symbols, as the configured sizing takes them) and `S` their
//! covariance: the start pose's `P₀` (her camera and the boundary sample fused) through the
//! Jacobians `A₀, A₁`, the two steps' motion noise, and her observation noises `R_e,1, R_e,2`.
//!
//! **Correlated steps: her genie view.** Under AR(1) motion noise the doublet's steps
//! correlate with their neighbours'. Eve is given the noise of the step just before and just
//! after the doublet (more than the neighbours' bits give her); by the Markov property the
//! doublet's two steps then have covariance `Q ⊗ [[α, β], [β, α]]` (`correlation`'s cells,
//! `[1, 0]` for white noise), and nothing else she holds says more about them. With
//! `K₀ = K₁ = αQ` and `K₀₁ = βQ`: `C₁₁ = A₀P₀A₀ᵀ + K₀`, `C₁₂ = C₁₁A₁ᵀ + K₀₁`,
//! `C₂₂ = A₁C₁₁A₁ᵀ + A₁K₀₁ + K₀₁ᵀA₁ᵀ + K₁`, and `S = [[C₁₁ + R_e,1, C₁₂], [C₁₂ᵀ, C₂₂ + R_e,2]]`.
//! What her observations beyond the doublet's boundaries say about its end pose is left out,
//! as the white model leaves it out (the boundary sample dominates).
//!
//! **The corner.** `S` grows in the Loewner order with the steps' covariance, so `d` shrinks:
//! over each cell of the correlation's interval, whose corner lies below every member of the
//! joint region there (`Q_cell ⪯ Q_low(ρ)`, the weights below `C(ρ)`), the cell's corner gives
//! the largest separation — the sharpest view Eve may have — for every bit at once; the block
//! takes the largest over the cells. Not one-sided in ρ: a larger ρ lowers `Q_low` and the
//! steps' difference `λ₋`, but not their sum `λ₊` (which peaks near ρ ≈ 0.27). The corner is
//! not the per-entry minimum: `Q_cell` is a full 3×3 matrix, rotated into the world's frame
//! at each doublet's heading. If `S` is not positive definite at a corner (a vertex so far
//! below zero that even her camera's noise does not cover it), no finite bound exists: `None`.
//!
//! **Three steps under a measured lag** (`private.prior_lag`, [`three_step_worst_case`]).
//! Given the steps just before and after the doublet, its three steps' noise has covariance
//! `Q ⊗ W(ρ)`, `W(ρ)` the inverse of the AR(1) precision's interior block (tridiagonal,
//! `(1 + ρ²)/(1 − ρ²)` on the diagonal, `−ρ/(1 − ρ²)` beside it), whose eigenvalues are
//! `(1 − ρ²)/(1 + ρ² ± √2|ρ| )` and `(1 − ρ²)/(1 + ρ²)`. Over a cell, `μ_low·I ⪯ W(ρ) ⪯ μ_high·I`
//! with `μ_low` the least eigenvalue at the cell's largest `|ρ|` and `μ_high` the greatest
//! (it peaks at `|ρ| = √2 − 1`), so `μ_low·P₊ − μ_high·P₋` as independent steps lies below
//! every member of the cell — coarser than the two-step weights (isotropic in the steps),
//! never sharper for Eve than the truth. The lag is not monotone in what it gives her (it
//! smooths the bit after the first step and sharpens it after the second, and a lag other
//! than the prior leaves the bit at the doublet's end, where the commands reveal it): each
//! bit's separation is the largest over the corners and a grid of `τ` over its interval
//! `[τ_lo, τ_hi]`, Eve's means following the doublet's offsets through that `τ` — so ℓ is at
//! most the least over the grid. A grid, not a proof between its points.

use nalgebra::{Cholesky, Matrix3, Matrix6, SymmetricEigen, Vector6};

use super::motion_noise::{Corner, MotionNoiseEstimate};
use super::residual::rotation;
use crate::private::DoubletInputs;
use crate::private::doublet::MAX_BITS;
use crate::private::likelihood::{DoubletModel, DoubletView, separations_by, state_jacobian};

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

/// Each key bit's separation of Eve's modelled `view` of a doublet with public `inputs`,
/// under `model` (its sample time and alphabet) with the motion noise at the worst case of
/// `estimate`'s joint region: the largest over its cells (entries beyond the doublet's key
/// bits 0); `None` when the bound does not exist.
#[must_use]
pub fn worst_case_separations(
    model: &DoubletModel,
    estimate: &MotionNoiseEstimate,
    inputs: &DoubletInputs,
    view: &DoubletView,
) -> Option<[f64; MAX_BITS]> {
    estimate
        .corners
        .iter()
        .try_fold([0.0_f64; MAX_BITS], |largest, corner| {
            let d = corner_separations(model, corner, inputs, view)?;
            Some(std::array::from_fn(|i| largest[i].max(d[i])))
        })
}

/// Points of the grid over the lag's interval Eve's view is sized at.
pub const LAG_GRID: usize = 5;

/// `LAG_GRID` lags evenly over `[low, high]` (s); one when the interval is a point.
#[must_use]
pub fn lag_grid([low, high]: [f64; 2]) -> Vec<f64> {
    if high <= low {
        return vec![low];
    }
    (0..LAG_GRID)
        .map(|i| low + (high - low) * i as f64 / (LAG_GRID - 1) as f64)
        .collect()
}

/// `[μ_low, μ_high]`: bounds on the eigenvalues of three AR(1) steps' conditional covariance
/// `W(ρ)` given their neighbours, in units of `Q`, over every ρ in the cell `[a, b]`.
fn three_step_weights([a, b]: [f64; 2]) -> [f64; 2] {
    let root_two = std::f64::consts::SQRT_2;
    let eigen = |r: f64, sign: f64| (1.0 - r * r) / (1.0 + r * r + sign * root_two * r);
    let largest = a
        .abs()
        .max(b.abs())
        .min(super::correlation::HIGHEST_CORRELATION);
    let smallest = if a <= 0.0 && b >= 0.0 {
        0.0
    } else {
        a.abs().min(b.abs())
    };
    let peak = root_two - 1.0;
    let mut high = eigen(smallest, -1.0).max(eigen(largest, -1.0));
    if (smallest..=largest).contains(&peak) {
        high = high.max(eigen(peak, -1.0));
    }
    [eigen(largest, 1.0), high]
}

/// The three steps' noise covariances (robot frame, m², m², rad²) that bound `estimate`'s
/// cells from below (`μ_low·P₊ − μ_high·P₋` of each corner, the module's doc), those that
/// another lies below in the Loewner order left out (a lower one gives Eve the sharper view
/// of every bit at once), each with whether it is positive semidefinite (then her
/// covariance is positive definite without a check).
#[must_use]
pub fn three_step_steps(estimate: &MotionNoiseEstimate) -> Vec<(Matrix3<f64>, bool)> {
    let steps: Vec<Matrix3<f64>> = estimate
        .corners
        .iter()
        .map(|corner| {
            let eigen = SymmetricEigen::new(corner.motion);
            let part = |sign: f64| {
                let kept = eigen.eigenvalues.map(|x| (sign * x).max(0.0));
                eigen.eigenvectors * Matrix3::from_diagonal(&kept) * eigen.eigenvectors.transpose()
            };
            let [low, high] = three_step_weights(corner.correlation);
            low * part(1.0) - high * part(-1.0)
        })
        .collect();
    let least = |m: &Matrix3<f64>| SymmetricEigen::new(*m).eigenvalues.min();
    let below = |a: &Matrix3<f64>, b: &Matrix3<f64>| least(&(b - a)) >= 0.0;
    let mut kept: Vec<(Matrix3<f64>, bool)> = Vec::new();
    for (i, m) in steps.iter().enumerate() {
        // Left out when another lies below it (the first of equal ones kept).
        let dominated = steps
            .iter()
            .enumerate()
            .any(|(j, other)| j != i && below(other, m) && (!below(m, other) || j < i));
        if !dominated {
            kept.push((*m, least(m) >= 0.0));
        }
    }
    kept
}

/// Each bit's separation of Eve's modelled `view` of a three-step doublet with public
/// `inputs` (its `late` observation's value is not used: the separation depends on her
/// covariances and the means' differences), at the worst case over the steps' covariances
/// `steps` ([`three_step_steps`]) and the `lags` τ (s) of the lag's interval (the module's
/// doc); `None` when a bound does not exist at some corner.
#[must_use]
pub fn three_step_worst_case(
    model: &DoubletModel,
    steps: &[(Matrix3<f64>, bool)],
    lags: &[f64],
    inputs: &DoubletInputs,
    view: &DoubletView,
) -> Option<[f64; MAX_BITS]> {
    let h = rotation(view.start.value.z);
    let mut worst = [0.0_f64; MAX_BITS];
    for (robot_frame, positive) in steps {
        for &lag in lags {
            let at = DoubletModel {
                process_covariance: h * robot_frame * h.transpose(),
                lag,
                ..*model
            };
            if !positive && !at.covariances_positive(inputs, view) {
                return None;
            }
            let d = at.separations(inputs, view);
            worst = std::array::from_fn(|i| worst[i].max(d[i]));
        }
    }
    Some(worst)
}

/// Each key bit's separation at one `corner` (the genie view of the module's doc; entries
/// beyond the doublet's key bits 0); `None` when its covariance is not positive definite or
/// the view lacks the middle or the end.
fn corner_separations(
    model: &DoubletModel,
    corner: &Corner,
    inputs: &DoubletInputs,
    view: &DoubletView,
) -> Option<[f64; MAX_BITS]> {
    let (Some(middle), Some(end)) = (&view.middle, &view.end) else {
        return None;
    };
    let t = model.sample_time;
    let h = rotation(view.start.value.z);
    let eigen = SymmetricEigen::new(corner.motion);
    let part = |sign: f64| {
        let kept = eigen.eigenvalues.map(|x| (sign * x).max(0.0));
        h * eigen.eigenvectors
            * Matrix3::from_diagonal(&kept)
            * eigen.eigenvectors.transpose()
            * h.transpose()
    };
    let (positive, negative) = (part(1.0), part(-1.0));
    let [[alpha_low, beta_low], [alpha_high, beta_high]] = corner.step_weights;
    let own = alpha_low * positive - alpha_high * negative;
    let across = beta_low * positive - beta_high * negative;
    let predict = |pattern: usize| {
        let offsets = model.step_offsets(inputs, Some(pattern));
        let [a, b, _] = inputs.applied_steps(offsets);
        let start = &view.start;
        let [m1, m2, _] = inputs.propagate_steps(&start.value, offsets, 2, t);
        let a0 = state_jacobian(start.value.z, a.x, t);
        let a1 = state_jacobian(m1.z, b.x, t);
        let c11 = a0 * start.covariance * a0.transpose() + own;
        let c12 = c11 * a1.transpose() + across;
        let c22 =
            a1 * c11 * a1.transpose() + a1 * across + across.transpose() * a1.transpose() + own;
        let mut s = Matrix6::zeros();
        s.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(c11 + middle.covariance));
        s.fixed_view_mut::<3, 3>(0, 3).copy_from(&c12);
        s.fixed_view_mut::<3, 3>(3, 0).copy_from(&c12.transpose());
        s.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(c22 + end.covariance));
        let mut mean = Vector6::zeros();
        mean.fixed_rows_mut::<3>(0).copy_from(&m1);
        mean.fixed_rows_mut::<3>(3).copy_from(&m2);
        (mean, Cholesky::new(s))
    };
    // Every pattern's prediction once (a multilevel doublet's up to 64 patterns meet in
    // many pairs); the pairs as the configured sizing takes them ([`separations_by`]: each
    // bit with the rest of its doublet's bits known, the larger over their values).
    let predictions: Vec<_> = (0..model.perturbation.patterns()).map(predict).collect();
    if predictions.iter().any(|(_, s)| s.is_none()) {
        return None;
    }
    Some(separations_by(&model.perturbation, |a, b| {
        let (mean_a, s) = &predictions[a];
        let d = predictions[b].0 - mean_a;
        s.as_ref().map_or(0.0, |c| c.solve(&d).dot(&d).sqrt())
    }))
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

    /// The view of a doublet with a turn, both bits, the stated camera.
    fn turning_doublet() -> (DoubletModel, DoubletInputs, DoubletView) {
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
        (model, inputs, view)
    }

    fn white(motion: Matrix3<f64>) -> Corner {
        Corner {
            correlation: [0.0, 0.0],
            motion,
            step_weights: [[1.0, 0.0]; 2],
        }
    }

    /// At ρ = 0 the genie view is the white doublet model's view, to rounding.
    #[test]
    fn the_white_corner_is_the_doublet_models_view() {
        let (model, inputs, view) = turning_doublet();
        let q = Matrix3::new(1e-6, 2e-7, 0.0, 2e-7, 8e-7, 1e-8, 0.0, 1e-8, 1e-6);
        let h = rotation(view.start.value.z);
        let white_model = DoubletModel {
            process_covariance: h * q * h.transpose(),
            ..model
        };
        let expected = white_model.separations(&inputs, &view);
        let got = corner_separations(&model, &white(q), &inputs, &view).unwrap();
        for k in 0..2 {
            assert!(
                (got[k] - expected[k]).abs() <= 1e-6 * expected[k],
                "{got:?} {expected:?}"
            );
        }
    }

    /// Multilevel symbols: at ρ = 0 the corner's separations are the configured sizing's
    /// ([`DoubletModel::separations`]: each bit with the rest of its doublet's symbols known,
    /// the larger over their values) for every key bit of 4- and 8-level alphabets on two
    /// dimensions, natural and Gray, to rounding; and nonzero for exactly the key bits.
    #[test]
    fn the_white_corner_is_the_configured_view_of_multilevel_symbols() {
        let (binary, inputs, view) = turning_doublet();
        let q = Matrix3::new(1e-6, 2e-7, 0.0, 2e-7, 8e-7, 1e-8, 0.0, 1e-8, 1e-6);
        let h = rotation(view.start.value.z);
        for levels in [4_u8, 8] {
            for labeling in [
                crate::config::Labeling::Natural,
                crate::config::Labeling::Gray,
            ] {
                let model = DoubletModel {
                    perturbation: crate::private::Perturbation {
                        delta: Unicycle::new(binary.perturbation.delta.x, 0.035),
                        levels,
                        labeling,
                        ..binary.perturbation
                    },
                    ..binary
                };
                let configured = DoubletModel {
                    process_covariance: h * q * h.transpose(),
                    ..model
                }
                .separations(&inputs, &view);
                let got = corner_separations(&model, &white(q), &inputs, &view).unwrap();
                let bits = model.perturbation.key_bits();
                for k in 0..MAX_BITS {
                    assert!(
                        (got[k] - configured[k]).abs() <= 1e-6 * configured[k],
                        "{levels} {labeling:?} bit {k}: {got:?} {configured:?}"
                    );
                    assert_eq!(got[k] > 0.0, k < bits, "{levels} bit {k}: {got:?}");
                }
            }
        }
    }

    /// The corner dominates its cell of the joint region: 500 random members — `Q_cell + GGᵀ`
    /// (full matrices, any orientation, off-diagonal entries of either sign) with ρ anywhere in
    /// the cell and the steps' exact conditional weights at that ρ — never give a larger
    /// separation than the corner to either bit, on cells at negative, small and large ρ.
    #[test]
    fn no_member_of_a_cell_gives_eve_a_sharper_view_than_its_corner() {
        let (model, inputs, view) = turning_doublet();
        let lower = Matrix3::new(1e-6, 2e-7, 0.0, 2e-7, 8e-7, 1e-8, 0.0, 1e-8, 1e-6);
        let mut rng = stream(5, Purpose::Public, 0);
        for cell in [[-0.5, -0.3], [0.0, 0.0], [-0.05, 0.4], [0.8, 0.95]] {
            let corner = Corner {
                correlation: cell,
                motion: lower,
                step_weights: super::super::motion_noise::tests::weights_of(cell),
            };
            let vertex = corner_separations(&model, &corner, &inputs, &view).unwrap();
            for _ in 0..500 {
                let g = Matrix3::from_fn(|_, _| rng.random_range(-1.5e-3..1.5e-3));
                let rho = if cell[0] == cell[1] {
                    cell[0]
                } else {
                    rng.random_range(cell[0]..cell[1])
                };
                let exact = super::super::motion_noise::tests::weights_of([rho, rho]);
                let member = Corner {
                    correlation: [rho, rho],
                    motion: lower + g * g.transpose(),
                    step_weights: exact,
                };
                let d = corner_separations(&model, &member, &inputs, &view).unwrap();
                for k in 0..2 {
                    assert!(
                        d[k] <= vertex[k] + 1e-12,
                        "{cell:?} ρ {rho}: {d:?} > {vertex:?}"
                    );
                }
            }
        }
        // A vertex more than the camera's noise below zero has no bound.
        let impossible = -Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 1.0));
        assert!(corner_separations(&model, &white(impossible), &inputs, &view).is_none());
    }

    /// The three steps' weight bounds hold every member of a cell: the conditional
    /// covariance's eigenvalues at 200 ρ of each cell lie within `[μ_low, μ_high]`.
    #[test]
    fn the_three_step_weights_bound_every_member_of_the_cell() {
        use nalgebra::Matrix3 as M;
        for cell in [
            [-0.5, -0.3],
            [0.0, 0.0],
            [-0.05, 0.4],
            [0.3, 0.5],
            [0.8, 0.95],
        ] {
            let [low, high] = three_step_weights(cell);
            for i in 0..=200 {
                let rho = cell[0] + (cell[1] - cell[0]) * f64::from(i) / 200.0;
                let (d, o) = (
                    (1.0 + rho * rho) / (1.0 - rho * rho),
                    -rho / (1.0 - rho * rho),
                );
                let precision = M::new(d, o, 0.0, o, d, o, 0.0, o, d);
                let w = precision.try_inverse().unwrap();
                for &x in SymmetricEigen::new(w).eigenvalues.iter() {
                    assert!(low - 1e-12 <= x && x <= high + 1e-12, "{cell:?} {rho}: {x}");
                }
            }
        }
        assert_eq!(three_step_weights([0.0, 0.0]), [1.0, 1.0]);
    }

    /// The steps' covariances kept for the three-step worst case bound every corner's from
    /// below: for each corner's `μ_low·P₊ − μ_high·P₋` some kept one lies below it, and one
    /// lying below another is what is left out.
    #[test]
    fn the_three_step_corners_kept_lie_below_every_corner() {
        let q = Matrix3::new(1e-6, 2e-7, 0.0, 2e-7, 8e-7, 1e-8, 0.0, 1e-8, 1e-6);
        let mut estimate = MotionNoiseEstimate::known(q, 0.0, 1e-6);
        let cells = [-0.4, -0.3, -0.2, -0.1, 0.0, 0.1, 0.2, 0.3, 0.4];
        for (i, corner) in estimate.corners.iter_mut().enumerate() {
            corner.correlation = [cells[i], cells[i + 1]];
            corner.motion = q * (1.0 - 0.1 * i as f64);
        }
        let kept = three_step_steps(&estimate);
        assert!(
            !kept.is_empty() && kept.len() < estimate.corners.len(),
            "{kept:?}"
        );
        for corner in &estimate.corners {
            let [low, high] = three_step_weights(corner.correlation);
            let own = low * corner.motion - high * Matrix3::zeros();
            assert!(
                kept.iter()
                    .any(|(m, _)| SymmetricEigen::new(own - m).eigenvalues.min() >= -1e-18),
                "{corner:?}"
            );
        }
        assert!(kept.iter().all(|&(_, positive)| positive));
    }

    /// Which way ρ moves her: at a fixed `Q`, positive correlation sharpens Eve's view of the
    /// v-bit (the bit shows in the steps' difference, whose variance `λ₋` falls with ρ).
    #[test]
    fn positive_correlation_sharpens_her_view_at_a_fixed_q() {
        let (model, inputs, view) = turning_doublet();
        let q = Matrix3::from_diagonal(&Vector3::new(1e-6, 1e-6, 1e-6));
        let at = |rho: f64| {
            let corner = Corner {
                correlation: [rho, rho],
                motion: q,
                step_weights: super::super::motion_noise::tests::weights_of([rho, rho]),
            };
            corner_separations(&model, &corner, &inputs, &view).unwrap()[0]
        };
        assert!(
            at(0.5) > at(0.0) && at(0.9) > at(0.5),
            "{} {} {}",
            at(0.0),
            at(0.5),
            at(0.9)
        );
    }
}
