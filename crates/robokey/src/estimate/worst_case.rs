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
//! `Q ⊗ W(ρ)`, `W(ρ) = Λ(ρ)⁻¹` with `Λ(ρ) = ((1 + ρ²)·I − ρ·J)/(1 − ρ²)` the AR(1) precision's
//! interior block (`J` the 3×3 matrix with ones beside the diagonal). Every `Λ(ρ)` is a
//! combination of `I` and `J`, so all `W(ρ)` share `J`'s eigenvectors
//! `u₊ = (1, √2, 1)/2, u₀ = (1, 0, −1)/√2, u₋ = (1, −√2, 1)/2` (eigenvalues `λ = √2, 0, −√2`):
//! `W(ρ) = Σ_λ w_λ(ρ)·u_λu_λᵀ`, `w_λ(ρ) = (1 − ρ²)/(1 + ρ² − λρ)`. Each `w_λ` is unimodal on
//! (−1, 1) (its derivative has the sign of `λρ² − 4ρ + λ`, one root there: `√2 − 1`, 0,
//! `1 − √2`), so over a cell `[a, b]` its least is at an end and its greatest at an end or
//! that root. With `W_low = Σ min w_λ·u_λu_λᵀ` and `W_high = Σ max w_λ·u_λu_λᵀ`,
//! `W(ρ) − W_low = Σ (w_λ(ρ) − min w_λ)·u_λu_λᵀ ⪰ 0` and `W_high − W(ρ) ⪰ 0` for every ρ of
//! the cell, and both equal `W(ρ)` at a point cell (the identity at ρ = 0: the white view).
//! With `Q_cell = P₊ − P₋` (its positive and negative parts) and `Q_cell ⪯ Q`,
//! `Q ⊗ W(ρ) − (P₊ ⊗ W_low − P₋ ⊗ W_high) = (Q − Q_cell) ⊗ W(ρ) + P₊ ⊗ (W(ρ) − W_low) +
//! P₋ ⊗ (W_high − W(ρ)) ⪰ 0` (Kronecker products of positive semidefinite matrices are), so
//! `K = P₊ ⊗ W_low − P₋ ⊗ W_high` lies below every member of the cell, and Eve's covariance
//! of the observed poses `F·P₀·Fᵀ + G·K·Gᵀ + R` (`F`, `G` the steps' Jacobians) with it: her
//! sharpest view over the cell, never sharper than the truth's.
//!
//! **The lag over its interval.** The lag is not monotone in what it gives her (it smooths
//! the bit after the first step and sharpens it after the second, and a lag other than the
//! prior leaves the bit at the doublet's end, where the commands reveal it): each bit's
//! separation `d(τ)` is bounded over the lag's whole interval `[τ_lo, τ_hi]`, Eve's means
//! following the doublet's offsets through τ (`largest_over_lags`). The interval is cut
//! into cells, and on each cell `d` is bounded at every τ from its value at the cell's
//! centre (estimate/lag_cell.rs: the steps' speeds are polynomials in `e^(−T/τ)` and
//! `(τ/T)(1 − e^(−T/τ))`, whose monomials all increase with τ; the means move by their
//! first-order map plus a bounded remainder, her covariance — which moves with τ through
//! the Jacobians along each pattern's mean path — within an entrywise radius): no
//! assumption on how `d` bends. A cell whose bound exceeds by more than [`LAG_SLACK`] what
//! the interval's ends and the cells' centres show is halved (at most [`MAX_LAG_CELLS`]);
//! the bound is the cells' largest. The bound is second order in a cell's width, so near
//! the prior, where `d` falls with τ, it is the lower end's value plus at most 2.5·10⁻⁴. Under
//! per-wheel slip ([`three_step_slip_pairs`]) each bit's exponent is still bounded between
//! the grid's lags by a convexity slack, a stated curvature assumption
//! (estimate/pairs_over_lags.rs).

use nalgebra::allocator::Allocator;
use nalgebra::{
    Cholesky, DMatrix, DVector, DefaultAllocator, DimDiff, DimMin, DimSub, Matrix3, Matrix6,
    OMatrix, OVector, SMatrix, SymmetricEigen, U1, Vector3, Vector6,
};

use super::lag_cell::{
    CentredView, LagPolynomial, covariance_radius, entry_speeds, monomial_moves, monomial_spans,
    observed_radius, path_radius, separation_bound, three_step_speeds,
};
use super::motion_noise::{Corner, MotionNoiseEstimate, loewner_below_both};
use super::pairs_over_lags::PairsOverLags;
use robokey_secrecy::covariance_pair::{Coordinate, CovariancePair, PairedBit};

use super::residual::{rotation, step_slip_covariance};
use crate::model::{Pose, Unicycle};
use crate::private::doublet::MAX_BITS;
use crate::private::likelihood::{
    DoubletModel, DoubletView, PoseObservation, separations_by, state_jacobian,
};
use crate::private::{DoubletInputs, Perturbation};
use crate::world::lagged;

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

/// One corner below every corner of `corners` (the cells of one correlation interval): `Q`
/// below each cell's (`loewner_below_both` folded), and the step weights whose eigenvalues
/// `λ± = α ± β` (eigenvectors `(1, ±1)`, shared by every cell) are the least, and the
/// greatest, over the cells. With `Q = P₊ − P₋`, `P₊ ⊗ C_least − P₋ ⊗ C_greatest` lies below
/// every cell's own, hence below the steps' conditional covariance at every ρ of the
/// interval: one view, sharper than every cell's, for a sizing that is costly per corner
/// (per-wheel slip).
#[must_use]
pub fn whole_interval_corner(corners: &[Corner]) -> Corner {
    let eigenvalues = |[alpha, beta]: [f64; 2]| [alpha + beta, alpha - beta];
    let weights = |[plus, minus]: [f64; 2]| [0.5 * (plus + minus), 0.5 * (plus - minus)];
    let first = corners[0];
    corners.iter().skip(1).fold(first, |low, c| {
        let [least, other_least] = [low.step_weights[0], c.step_weights[0]].map(eigenvalues);
        let [greatest, other_greatest] = [low.step_weights[1], c.step_weights[1]].map(eigenvalues);
        Corner {
            correlation: [
                low.correlation[0].min(c.correlation[0]),
                low.correlation[1].max(c.correlation[1]),
            ],
            motion: loewner_below_both(&low.motion, &c.motion),
            step_weights: [
                weights([least[0].min(other_least[0]), least[1].min(other_least[1])]),
                weights([
                    greatest[0].max(other_greatest[0]),
                    greatest[1].max(other_greatest[1]),
                ]),
            ],
        }
    })
}

/// Points of the grid over the lag's interval the commands check's prediction and, under
/// slip, Eve's view are first sized at.
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

/// How far a bit's bound over the lag's interval may lie above what its cells' centres and
/// the interval's ends show before a cell is halved (`largest_over_lags`): a sixteenth of
/// the published quantum (a quarter cost 13 bits more on one of the grid's lag blocks at a
/// third less CPU: docs/estimation.md, "The lag" item 5).
pub const LAG_SLACK: f64 = SEPARATION_QUANTUM / 16.0;

/// The most lags the commands check's grid over the lag's interval is refined to (its
/// spacing halved from [`LAG_GRID`] points four times).
const MAX_LAG_POINTS: usize = 65;

/// The three steps' noise covariance, 9×9 over their (x, y, θ) noises: block `(i, k)` is
/// step `i`'s noise with step `k`'s (m², m·rad, rad²).
pub type StepCovariance = SMatrix<f64, 9, 9>;

/// The eigenvalues `λ` of `J` (ones beside the diagonal of a 3×3 matrix) and their unit
/// eigenvectors: `√2, (1, √2, 1)/2`; `0, (1, 0, −1)/√2`; `−√2, (1, −√2, 1)/2`.
fn step_modes() -> [(f64, Vector3<f64>); 3] {
    let r = std::f64::consts::SQRT_2;
    [
        (r, Vector3::new(0.5, 0.5 * r, 0.5)),
        (0.0, Vector3::new(1.0 / r, 0.0, -1.0 / r)),
        (-r, Vector3::new(0.5, -0.5 * r, 0.5)),
    ]
}

/// `W(ρ)`'s eigenvalue along `J`'s mode `λ`: `(1 − ρ²)/(1 + ρ² − λρ)`.
fn mode_weight(rho: f64, lambda: f64) -> f64 {
    (1.0 - rho * rho) / (1.0 + rho * rho - lambda * rho)
}

/// `[W_low, W_high]`: Loewner bounds on three AR(1) steps' conditional covariance `W(ρ)`
/// given their neighbours, in units of `Q`, over every ρ in the cell `[a, b]` (the module's
/// doc): along each of `J`'s modes the least and the greatest of its eigenvalue over the
/// cell. `W(ρ)` itself for a point cell.
fn three_step_weights([a, b]: [f64; 2]) -> [Matrix3<f64>; 2] {
    let top = super::correlation::HIGHEST_CORRELATION;
    let (a, b) = (a.clamp(-top, top), b.clamp(-top, top));
    let peak_of = |lambda: f64| {
        // The root of λρ² − 4ρ + λ in (−1, 1): the eigenvalue's one maximum there.
        if lambda == 0.0 {
            0.0
        } else {
            (2.0 - (4.0 - lambda * lambda).sqrt()) / lambda
        }
    };
    let mut bounds = [Matrix3::zeros(); 2];
    for (lambda, v) in step_modes() {
        let ends = [mode_weight(a, lambda), mode_weight(b, lambda)];
        let low = ends[0].min(ends[1]);
        let peak = peak_of(lambda);
        let mut high = ends[0].max(ends[1]);
        if (a..=b).contains(&peak) {
            high = high.max(mode_weight(peak, lambda));
        }
        let projector = v * v.transpose();
        bounds[0] += low * projector;
        bounds[1] += high * projector;
    }
    bounds
}

/// `P₊ ⊗ W_low − P₋ ⊗ W_high` of one corner (robot frame): block `(i, k)` is
/// `W_low,ik·P₊ − W_high,ik·P₋`, `P₊ − P₋ = Q_cell` its positive and negative parts.
fn three_step_covariance(corner: &Corner) -> StepCovariance {
    let eigen = SymmetricEigen::new(corner.motion);
    let part = |sign: f64| {
        let kept = eigen.eigenvalues.map(|x| (sign * x).max(0.0));
        eigen.eigenvectors * Matrix3::from_diagonal(&kept) * eigen.eigenvectors.transpose()
    };
    let (positive, negative) = (part(1.0), part(-1.0));
    let [low, high] = three_step_weights(corner.correlation);
    let mut k = StepCovariance::zeros();
    for i in 0..3 {
        for j in 0..3 {
            k.fixed_view_mut::<3, 3>(3 * i, 3 * j)
                .copy_from(&(low[(i, j)] * positive - high[(i, j)] * negative));
        }
    }
    k
}

/// The three steps' noise covariances (robot frame) that bound `estimate`'s cells from
/// below (`P₊ ⊗ W_low − P₋ ⊗ W_high` of each corner, the module's doc), those that another
/// lies below in the Loewner order left out (a lower one gives Eve the sharper view of
/// every bit at once), each with whether it is positive semidefinite (then her covariance
/// is positive definite without a check).
#[must_use]
pub fn three_step_steps(estimate: &MotionNoiseEstimate) -> Vec<(StepCovariance, bool)> {
    let steps: Vec<StepCovariance> = estimate.corners.iter().map(three_step_covariance).collect();
    let least = |m: &StepCovariance| SymmetricEigen::new(*m).eigenvalues.min();
    let below = |a: &StepCovariance, b: &StepCovariance| least(&(b - a)) >= 0.0;
    let mut kept: Vec<(StepCovariance, bool)> = Vec::new();
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
/// `steps` ([`three_step_steps`]) and the lag's `interval` `[τ_lo, τ_hi]` (s): the largest
/// of its bounds over cells of it (`largest_over_lags`, the module's doc); `None` when a
/// bound does not exist at some corner.
///
/// With `next` (the following doublet's public inputs and Eve's view of it) her view takes
/// what a lag other than the prior leaves of the bits in the next doublet's entry speed too
/// (the module's doc, "The next doublet's entry"): per bit `√(d_end² + d_next²)`, `d_end`
/// her view with the doublet's end pose given to her exactly and `d_next` what the next
/// doublet's observed poses say from that end pose (`entry_separations`).
#[must_use]
pub fn three_step_worst_case(
    model: &DoubletModel,
    steps: &[(StepCovariance, bool)],
    interval: [f64; 2],
    inputs: &DoubletInputs,
    view: &DoubletView,
    next: Option<(&DoubletInputs, &DoubletView)>,
) -> Option<[f64; MAX_BITS]> {
    let world = |theta: f64| -> Vec<(StepCovariance, bool)> {
        steps
            .iter()
            .map(|(k, positive)| (in_world_frame(k, theta), *positive))
            .collect()
    };
    let here = world(view.start.value.z);
    let following = next.map(|(next_inputs, next_view)| {
        (
            with_exact_end(view, next_view),
            next_inputs,
            next_view,
            world(next_view.start.value.z),
        )
    });
    let over = |cell: [f64; 2]| {
        here.iter().enumerate().try_fold(
            OverCell::default(),
            |worst, (c, (k, positive))| -> Option<OverCell> {
                let d = match &following {
                    None => three_step_separations(model, k, *positive, inputs, view, cell)?,
                    Some((exact_end, next_inputs, next_view, next_world)) => {
                        let own =
                            three_step_separations(model, k, *positive, inputs, exact_end, cell)?;
                        let (next_k, next_positive) = &next_world[c];
                        let entry = entry_separations(
                            model,
                            next_k,
                            *next_positive,
                            inputs,
                            next_inputs,
                            next_view,
                            cell,
                        )?;
                        OverCell {
                            centre: std::array::from_fn(|i| own.centre[i].hypot(entry.centre[i])),
                            bound: std::array::from_fn(|i| own.bound[i].hypot(entry.bound[i])),
                        }
                    }
                };
                Some(worst.max(&d))
            },
        )
    };
    largest_over_lags(interval, over)
}

/// The three steps' noise covariance `k` (robot frame at the doublet's start) in the world's
/// frame at its start heading `theta` (rad): each step's block rotated by `H(θ)`.
fn in_world_frame(k: &StepCovariance, theta: f64) -> StepCovariance {
    let h = rotation(theta);
    let mut frame = StepCovariance::zeros();
    for i in 0..3 {
        frame.fixed_view_mut::<3, 3>(3 * i, 3 * i).copy_from(&h);
    }
    frame * k * frame.transpose()
}

/// `view` with the doublet's end pose given to Eve exactly (the next doublet's entry is then
/// bounded apart: the module's doc of [`three_step_worst_case`]); where `view` observes no
/// end, `next_view`'s start stands for it.
fn with_exact_end(view: &DoubletView, next_view: &DoubletView) -> DoubletView {
    DoubletView {
        end: Some(PoseObservation {
            covariance: Matrix3::zeros(),
            ..view.end.unwrap_or(next_view.start)
        }),
        ..*view
    }
}

/// Each key bit's separation of what the next doublet's observed poses (`next_view`'s, the
/// next doublet's public `next_inputs`) say of this doublet's bits given its end pose
/// exactly: the wheels leave this doublet (`inputs`) at the speed its bit's offsets reach
/// through the lag, 0 at the prior, decaying by `e^(−T/τ)` per step of the next
/// doublet; its means follow that speed's mean over each step from `next_view`'s start
/// pose, its covariance is `G·K·Gᵀ + R` with the next doublet's steps' `k` (world frame)
/// and no start uncertainty. At the centre of the lag's `cell` (s), with its bound over the
/// cell ([`path_separations`]); `None` when a covariance is not positive definite (checked
/// only when `k` is not known to be `positive`).
fn entry_separations(
    model: &DoubletModel,
    k: &StepCovariance,
    positive: bool,
    inputs: &DoubletInputs,
    next_inputs: &DoubletInputs,
    next_view: &DoubletView,
    cell: [f64; 2],
) -> Option<OverCell> {
    let centre = DoubletModel {
        lag: 0.5 * (cell[0] + cell[1]),
        ..*model
    };
    path_separations(
        &model.perturbation,
        (k, positive),
        &Matrix3::zeros(),
        &next_view.three_step_observed(),
        |pattern| {
            entry_path(
                &centre,
                inputs,
                next_inputs,
                &next_view.start.value,
                pattern,
            )
        },
        |pattern| entry_speeds(model, inputs, next_inputs, pattern),
        (cell, model.sample_time, next_view.start.value.z),
    )
}

/// The next doublet's mean path (`next_inputs`, from its start pose `start` exactly) under
/// this doublet's (`inputs`) `pattern`: the wheels leave this doublet at the speed its bit's
/// offsets reach through `model`'s lag, which decays by `e^(−T/τ)` per step of the next
/// doublet; its poses after each step, the steps' Jacobians and applied mean speeds
/// ([`DoubletModel::three_step_path`]'s).
fn entry_path(
    model: &DoubletModel,
    inputs: &DoubletInputs,
    next_inputs: &DoubletInputs,
    start: &Pose,
    pattern: usize,
) -> StepPath {
    let t = model.sample_time;
    let mut speed = model
        .step_offsets(inputs, Some(pattern))
        .iter()
        .fold(Unicycle::zeros(), |speed, &c| {
            lagged(c, speed, t, model.lag).1
        });
    let offsets: [Unicycle; 3] = std::array::from_fn(|_| {
        let (mean, end) = lagged(Unicycle::zeros(), speed, t, model.lag);
        speed = end;
        mean
    });
    let applied = next_inputs.applied_steps(offsets);
    let means = next_inputs.propagate_steps(start, offsets, 3, t);
    let before = [*start, means[0], means[1]];
    (
        means,
        std::array::from_fn(|i| state_jacobian(before[i].z, applied[i].x, t)),
        applied,
    )
}

/// Each bit's separation at a cell's centre and its bound over the whole cell
/// (estimate/lag_cell.rs).
#[derive(Clone, Copy, Debug, Default)]
struct OverCell {
    centre: [f64; MAX_BITS],
    bound: [f64; MAX_BITS],
}

impl OverCell {
    /// Each bit's larger centre and larger bound of `self` and `other`.
    fn max(&self, other: &Self) -> Self {
        Self {
            centre: std::array::from_fn(|i| self.centre[i].max(other.centre[i])),
            bound: std::array::from_fn(|i| self.bound[i].max(other.bound[i])),
        }
    }
}

/// The most cells the lag's interval is cut into for Eve's view (by halving).
const MAX_LAG_CELLS: usize = 64;

/// Each bit's largest separation over every τ in `interval` `[τ_lo, τ_hi]` (s), from
/// `over(cell)`'s bound on each cell (estimate/lag_cell.rs: a bound at every τ of the
/// cell, no assumption on how `d` bends): the largest of the cells' bounds. The interval is
/// one cell at first, and each cell whose bound exceeds by more than [`LAG_SLACK`] what the
/// separation is known to reach — its largest at the interval's ends and the cells'
/// centres — is halved, while there are at most [`MAX_LAG_CELLS`]. `None` when `over` has
/// no answer on some cell; `over([τ_lo, τ_lo])`'s value for a point.
fn largest_over_lags(
    [low, high]: [f64; 2],
    over: impl Fn([f64; 2]) -> Option<OverCell>,
) -> Option<[f64; MAX_BITS]> {
    if high <= low {
        return over([low, low]).map(|point| point.centre);
    }
    let mut reached = over([low, low])?.max(&over([high, high])?).centre;
    let mut cells = vec![([low, high], over([low, high])?)];
    loop {
        for (_, d) in &cells {
            reached = std::array::from_fn(|i| reached[i].max(d.centre[i]));
        }
        let loose = |d: &OverCell| (0..MAX_BITS).any(|i| d.bound[i] > reached[i] + LAG_SLACK);
        let split = cells.iter().filter(|(_, d)| loose(d)).count();
        if split == 0 || cells.len() + split > MAX_LAG_CELLS {
            break;
        }
        let mut finer = Vec::with_capacity(cells.len() + split);
        for (cell, d) in cells {
            if loose(&d) {
                let middle = 0.5 * (cell[0] + cell[1]);
                for half in [[cell[0], middle], [middle, cell[1]]] {
                    finer.push((half, over(half)?));
                }
            } else {
                finer.push((cell, d));
            }
        }
        cells = finer;
    }
    Some(cells.iter().fold(reached, |m, (_, d)| {
        std::array::from_fn(|i| m[i].max(d.bound[i]))
    }))
}

/// Each component's largest of `at(τ)` (one value per entry of `slack_limit`) over
/// `interval` `[τ_lo, τ_hi]` (s) as the commands check predicts it: the largest over
/// [`LAG_GRID`] evenly spaced lags plus each component's concavity slack — a quarter of its
/// most negative second difference along the grid, 0 where none is negative — the spacing
/// halved while a component's slack exceeds its `slack_limit` (at most [`MAX_LAG_POINTS`]
/// lags). A function whose second derivative stays above twice its most negative second
/// difference over the spacing² lies below this everywhere in the interval; one that bends
/// faster is under-predicted, which only makes the check refuse more (a refusal test, not a
/// key size: Eve's view takes the cells' bound, `largest_over_lags`). `None` when `at` has
/// no answer at some lag; `at(τ_lo)` itself for a point.
pub(crate) fn largest_of_each_over_lags(
    [low, high]: [f64; 2],
    slack_limit: &[f64],
    at: impl Fn(f64) -> Option<Vec<f64>>,
) -> Option<Vec<f64>> {
    if high <= low {
        return at(low);
    }
    let components = slack_limit.len();
    let mut values = lag_grid([low, high])
        .iter()
        .map(|&lag| at(lag))
        .collect::<Option<Vec<_>>>()?;
    loop {
        let slack: Vec<f64> = (0..components)
            .map(|b| {
                values
                    .windows(3)
                    .map(|w| (2.0 * w[1][b] - w[0][b] - w[2][b]).max(0.0) / 4.0)
                    .fold(0.0, f64::max)
            })
            .collect();
        if slack.iter().zip(slack_limit).all(|(x, limit)| x <= limit)
            || values.len() >= MAX_LAG_POINTS
        {
            let largest = values.iter().fold(vec![0.0_f64; components], |m, d| {
                m.iter().zip(d).map(|(a, b)| a.max(*b)).collect()
            });
            return Some(largest.iter().zip(&slack).map(|(l, s)| l + s).collect());
        }
        // Halve the spacing: a new lag between every two neighbours.
        let spacing = (high - low) / (values.len() - 1) as f64;
        let mut finer = Vec::with_capacity(2 * values.len() - 1);
        for (i, d) in values.iter().enumerate() {
            if i > 0 {
                finer.push(at(low + spacing * (i as f64 - 0.5))?);
            }
            finer.push(d.clone());
        }
        values = finer;
    }
}

/// Each key bit's separation of Eve's `view` of a three-step doublet under `model` (its
/// alphabet) at the centre of the lag's `cell` (s), and its bound over the cell
/// ([`path_separations`]), with the steps' noise covariance `k` (world frame, possibly correlated
/// between the steps): the observed poses' covariance `F·P₀·Fᵀ + G·K·Gᵀ + R` along each
/// pattern's mean path, `F` stacking `A₀, A₁A₀, A₂A₁A₀` and `G` the block lower-triangular
/// map of the steps' noises (`Gᵢₖ = Aᵢ ⋯ Aₖ₊₁`, `Gᵢᵢ = I`); `None` when a covariance is not
/// positive definite (checked only when `k` is not known to be `positive`) or the view
/// observes no pose.
fn three_step_separations(
    model: &DoubletModel,
    k: &StepCovariance,
    positive: bool,
    inputs: &DoubletInputs,
    view: &DoubletView,
    cell: [f64; 2],
) -> Option<OverCell> {
    let centre = DoubletModel {
        lag: 0.5 * (cell[0] + cell[1]),
        ..*model
    };
    let entry = view.entry;
    path_separations(
        &model.perturbation,
        (k, positive),
        &view.start.covariance,
        &view.three_step_observed(),
        |pattern| centre.three_step_path(inputs, view, pattern),
        |pattern| three_step_speeds(model, inputs, entry, pattern),
        (cell, model.sample_time, view.start.value.z),
    )
}

/// A three-step mean path under one pattern: the poses after each step, the steps'
/// Jacobians along it and their applied mean speeds (m/s, rad/s).
type StepPath = ([Pose; 3], [Matrix3<f64>; 3], [Unicycle; 3]);

/// Per-wheel slip in Eve's view of three steps: its variance σ², the wheels `axle` D (m)
/// apart, over steps of `sample_time` T (s) from a path starting at heading `start_heading`
/// (rad). Each step's noise gains `σ²·R(θₖ)·Wₖ·R(θₖ)ᵀ` ([`step_slip_covariance`] at the
/// step's applied mean speeds under the pattern, `θₖ` the heading at its start).
#[derive(Clone, Copy, Debug)]
struct StepSlip {
    variance: f64,
    axle: f64,
    sample_time: f64,
    start_heading: f64,
}

/// Each key bit of `perturbation`: the separation of three steps' `observed` poses (each
/// with its index among the three) whose mean path and Jacobians under each pattern are
/// `path(pattern)` at the centre of `cell` (s), from a start pose of covariance
/// `start_covariance` (its heading `start_heading`, rad) through steps of covariance `k`
/// ([`three_step_separations`]), and each one's bound over the cell, the steps' applied
/// speeds under each pattern `speeds(pattern)` as polynomials of the lag (steps of
/// `sample_time` T, s; estimate/lag_cell.rs). `None` when a covariance at the centre is
/// not positive definite (checked only when `k` is not known to be `positive`) or nothing
/// is observed.
fn path_separations(
    perturbation: &Perturbation,
    (k, positive): (&StepCovariance, bool),
    start_covariance: &Matrix3<f64>,
    observed: &[(usize, &PoseObservation)],
    path: impl Fn(usize) -> StepPath,
    speeds: impl Fn(usize) -> [LagPolynomial; 3],
    (cell, sample_time, start_heading): ([f64; 2], f64, f64),
) -> Option<OverCell> {
    if observed.is_empty() {
        return None;
    }
    let indices: Vec<usize> = observed.iter().map(|(i, _)| *i).collect();
    let spans = monomial_spans(cell, sample_time);
    let predictions = path_predictions(perturbation, k, start_covariance, observed, &path, None);
    let views: Vec<Option<CentredView>> = predictions
        .iter()
        .enumerate()
        .map(|(pattern, (_, s))| {
            if cell[0] == cell[1] {
                return CentredView::point(s);
            }
            let (means, jacobians, applied) = path(pattern);
            let speeds = speeds(pattern);
            let radius = path_radius(&applied, &speeds, cell, sample_time);
            let headings = [start_heading, means[0].z, means[1].z];
            let moves = monomial_moves(headings, &applied, &speeds, sample_time);
            let covariance = covariance_radius(&jacobians, &radius.jacobians, start_covariance, k);
            let (moves, remainder, s_radius) =
                observed_radius(&moves, &radius, &covariance, &indices);
            CentredView::new(s, &s_radius, moves, remainder)
        })
        .collect();
    if !positive && views.iter().any(Option::is_none) {
        return None;
    }
    // Each pair the bits compare, once: its separation at the centre and its bound.
    let patterns = perturbation.patterns();
    let mut pairs = vec![[0.0; 2]; patterns * patterns];
    for i in 0..perturbation.key_bits() {
        for a in (0..patterns).filter(|h| h >> i & 1 == 0) {
            let b = a | 1 << i;
            let d = &predictions[b].0 - &predictions[a].0;
            pairs[a * patterns + b] = match (&views[a], &views[b]) {
                (Some(view_a), Some(view_b)) => separation_bound(view_a, view_b, &d, &spans),
                _ => [0.0, f64::INFINITY],
            };
        }
    }
    Some(OverCell {
        centre: separations_by(perturbation, |a, b| pairs[a * patterns + b][0]),
        bound: separations_by(perturbation, |a, b| pairs[a * patterns + b][1]),
    })
}

/// Each pattern's mean of three steps' `observed` poses and their covariance
/// `F·P₀·Fᵀ + G·K·Gᵀ + R` ([`three_step_separations`]), the path under each pattern
/// `path(pattern)`, from a start pose of covariance `start_covariance` through steps of
/// covariance `k` (world frame); with `slip`, each step's own slip at the pattern's applied
/// speeds added to `K`'s diagonal blocks (then the pattern moves the covariance too).
fn path_predictions(
    perturbation: &Perturbation,
    k: &StepCovariance,
    start_covariance: &Matrix3<f64>,
    observed: &[(usize, &PoseObservation)],
    path: impl Fn(usize) -> StepPath,
    slip: Option<StepSlip>,
) -> Vec<(DVector<f64>, DMatrix<f64>)> {
    let n = 3 * observed.len();
    let predict = |pattern: usize| {
        let (means, a, applied) = path(pattern);
        let mut f = SMatrix::<f64, 9, 3>::zeros();
        let mut g = StepCovariance::identity();
        let mut through = Matrix3::identity();
        for i in 0..3 {
            through = a[i] * through;
            f.fixed_view_mut::<3, 3>(3 * i, 0).copy_from(&through);
            let mut carried = Matrix3::identity();
            for j in (0..i).rev() {
                carried *= a[j + 1];
                g.fixed_view_mut::<3, 3>(3 * i, 3 * j).copy_from(&carried);
            }
        }
        let c = match slip {
            None => f * start_covariance * f.transpose() + g * k * g.transpose(),
            Some(slip) => {
                let mut slipped = *k;
                let headings = [slip.start_heading, means[0].z, means[1].z];
                for i in 0..3 {
                    let r = rotation(headings[i]);
                    let own = step_slip_covariance(&applied[i], slip.sample_time, slip.axle);
                    let block: Matrix3<f64> = slipped.fixed_view::<3, 3>(3 * i, 3 * i).into_owned()
                        + slip.variance * r * own * r.transpose();
                    slipped
                        .fixed_view_mut::<3, 3>(3 * i, 3 * i)
                        .copy_from(&block);
                }
                f * start_covariance * f.transpose() + g * slipped * g.transpose()
            }
        };
        let mut mean = DVector::zeros(n);
        let mut s = DMatrix::zeros(n, n);
        for (row, &(i, y)) in observed.iter().enumerate() {
            mean.fixed_rows_mut::<3>(3 * row).copy_from(&means[i]);
            for (col, &(j, _)) in observed.iter().enumerate() {
                let mut block: Matrix3<f64> = c.fixed_view::<3, 3>(3 * i, 3 * j).into();
                if i == j {
                    block += y.covariance;
                }
                s.fixed_view_mut::<3, 3>(3 * row, 3 * col).copy_from(&block);
            }
        }
        (mean, s)
    };
    (0..perturbation.patterns()).map(predict).collect()
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
    // Every pattern's prediction once (a multilevel doublet's up to 64 patterns meet in
    // many pairs); the pairs as the configured sizing takes them ([`separations_by`]: each
    // bit with the rest of its doublet's bits known, the larger over their values).
    let predictions: Vec<_> = corner_predictions(model, corner, None, inputs, view)?
        .into_iter()
        .map(|(mean, s)| (mean, Cholesky::new(s)))
        .collect();
    if predictions.iter().any(|(_, s)| s.is_none()) {
        return None;
    }
    Some(separations_by(&model.perturbation, |a, b| {
        let (mean_a, s) = &predictions[a];
        let d = predictions[b].0 - mean_a;
        s.as_ref().map_or(0.0, |c| c.solve(&d).dot(&d).sqrt())
    }))
}

/// Eve's predicted observation of the doublet's middle and end, and its covariance `S`, under
/// each pattern, at `corner` (the module doc); with `slip = Some((σ², D))` each step's
/// per-wheel slip as well, `σ²·R(θ)·Wₖ·R(θ)ᵀ` (`Wₖ` [`step_slip_covariance`] at the step's
/// applied speeds under the pattern, wheels `D` apart, at the step's start heading θ): the
/// bit then moves the covariance too. `None` without a middle and an end in her view.
fn corner_predictions(
    model: &DoubletModel,
    corner: &Corner,
    slip: Option<(f64, f64)>,
    inputs: &DoubletInputs,
    view: &DoubletView,
) -> Option<Vec<(Vector6<f64>, Matrix6<f64>)>> {
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
        let [slip_first, slip_second] = match slip {
            None => [Matrix3::zeros(); 2],
            Some((variance, axle)) => [(a, start.value.z), (b, m1.z)].map(|(u, heading)| {
                let r = rotation(heading);
                variance * r * step_slip_covariance(&u, t, axle) * r.transpose()
            }),
        };
        let c11 = a0 * start.covariance * a0.transpose() + own;
        let c11 = if slip.is_some() {
            c11 + slip_first
        } else {
            c11
        };
        let c12 = c11 * a1.transpose() + across;
        let c22 =
            a1 * c11 * a1.transpose() + a1 * across + across.transpose() * a1.transpose() + own;
        let c22 = if slip.is_some() {
            c22 + slip_second
        } else {
            c22
        };
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
        (mean, s)
    };
    Some((0..model.perturbation.patterns()).map(predict).collect())
}

/// The shares λ of the region's corner at which each slip doublet's view is tried
/// ([`below_the_region`]; docs/estimation.md, "Per-wheel slip").
pub const VERTEX_SHARES: [f64; 6] = [0.0, 0.125, 0.25, 0.5, 0.75, 1.0];

/// Matrices below every member of the region `{Q ⪰ 0, Q ⪰ Q_c, Q ⪯ U}` in the Loewner order
/// (robot frame; m², m², rad²), `Q_c` its `corner`, `U` its `upper` bound where one is
/// known: Eve's view at any of them is at least as sharp as at every member. `Q_c` alone
/// where it lies above 0 (then above each of the others); otherwise one per share λ of
/// [`VERTEX_SHARES`],
///
/// `L(λ) = θ(λ)·P₊ − λ·P₋`,  `θ(λ) = λ(1 + μ)/(μ + λ)`,
///
/// `P₊ − P₋ = Q_c` its positive and negative parts, `μ ≥ 0` the least with
/// `VᵀUV ⪯ (1 + μ)·A₊` (`A₊` the corner's positive eigenvalues on their eigenvectors `V`):
/// how far the upper bound lies above the corner's positive part, relatively. θ(λ) ≥ λ, so
/// each `L(λ)` lies above the share `λ·Q_c` and gives her the blunter view. Without an upper
/// bound (or where `Q_c` has other than two positive eigenvalues and one negative) μ is
/// infinite and `L(λ) = λ·Q_c`, the shares: `Q − λQ_c = λ(Q − Q_c) + (1 − λ)Q ⪰ 0`.
///
/// Proof (`−c` the negative eigenvalue, `n` its eigenvector, `z = λc`; in `Q_c`'s eigenbasis
/// a member is `Q = [[Q_uu, q], [qᵀ, y]]`, `X = Q_uu − A₊`): `Q − L ⪰ 0` iff
/// `X + (1 − θ)A₊ ⪰ qqᵀ/(y + z)`. The region gives `X ⪰ qqᵀ/(y + c)` (`Q ⪰ Q_c`),
/// `X + A₊ ⪰ qqᵀ/y` (`Q ⪰ 0`) and `μA₊ − X ⪰ 0` (`Q_uu ⪯ VᵀUV`). Where `y ≥ μc`,
/// `X + (1 − θ)A₊ = αX + ((1 − θ)/μ)(μA₊ − X) ⪰ α·qqᵀ/(y + c)` with `α = (1 + μ − θ)/μ`, and
/// `α(y + z) ≥ y + c` there; where `y ≤ μc`, `X + (1 − θ)A₊ = θX + (1 − θ)(X + A₊) ⪰
/// (θ/(y + c) + (1 − θ)/y)·qqᵀ`, at least `qqᵀ/(y + z)` iff `y(θc − z) ≤ (1 − θ)cz`, i.e.
/// `y ≤ μc` (μ = 0: `X = 0`, so `q = 0`). The cases meet at `y = μc`, where a member on both
/// boundaries makes the bound tight. With the step weights, `L₊ ⊗ C_least − L₋ ⊗ C_greatest`
/// lies below `Q ⊗ C(ρ)` as the corner's own does.
#[must_use]
pub fn below_the_region(corner: &Matrix3<f64>, upper: Option<&Matrix3<f64>>) -> Vec<Matrix3<f64>> {
    let eigen = SymmetricEigen::new(*corner);
    if eigen.eigenvalues.min() >= 0.0 {
        return vec![*corner];
    }
    let part = |sign: f64| {
        let kept = eigen.eigenvalues.map(|x| (sign * x).max(0.0));
        eigen.eigenvectors * Matrix3::from_diagonal(&kept) * eigen.eigenvectors.transpose()
    };
    let (positive, negative) = (part(1.0), part(-1.0));
    let excess = upper.and_then(|u| upper_excess(&eigen, u));
    VERTEX_SHARES
        .iter()
        .map(|&share| raised_share(share, excess) * positive - share * negative)
        .collect()
}

/// θ(λ) of [`below_the_region`] for `share` λ and the upper bound's `excess` μ (λ itself
/// without one).
fn raised_share(share: f64, excess: Option<f64>) -> f64 {
    match excess {
        Some(mu) if share > 0.0 => share * (1.0 + mu) / (mu + share),
        _ => share,
    }
}

/// μ of [`below_the_region`]: the largest eigenvalue of `A₊^(−½)·VᵀUV·A₊^(−½)` less
/// 1, at least 0; none unless the corner (its `eigen` decomposition) has two positive
/// eigenvalues and one negative.
fn upper_excess(eigen: &SymmetricEigen<f64, nalgebra::U3>, upper: &Matrix3<f64>) -> Option<f64> {
    let positive: Vec<usize> = (0..3).filter(|&k| eigen.eigenvalues[k] > 0.0).collect();
    if positive.len() != 2 {
        return None;
    }
    let scaled = nalgebra::Matrix3x2::from_fn(|r, c| {
        let k = positive[c];
        eigen.eigenvectors[(r, k)] / eigen.eigenvalues[k].sqrt()
    });
    let relative = scaled.transpose() * upper * scaled;
    let largest = SymmetricEigen::new(relative).eigenvalues.max();
    largest.is_finite().then(|| (largest - 1.0).max(0.0))
}

/// Each key bit's view of the doublet under per-wheel slip of variance `slip_variance` (σ²)
/// at `corner`, on wheels `axle` D (m) apart: for each value of the doublet's other bits
/// (given to Eve, as `separations_by` takes them), the pair of her Gaussian views of the
/// bit's two values, each with its own covariance (`corner_predictions`), diagonalised
/// together ([`CovariancePair`]: whitened by the first value's `S`, rotated onto the
/// eigenvectors of the second's). `None` where a covariance is not positive definite (no
/// bound exists at the corner).
#[must_use]
pub fn slip_pairs(
    model: &DoubletModel,
    corner: &Corner,
    slip_variance: f64,
    axle: f64,
    inputs: &DoubletInputs,
    view: &DoubletView,
) -> Option<Vec<PairedBit>> {
    let predictions = corner_predictions(model, corner, Some((slip_variance, axle)), inputs, view)?;
    paired_bits(&model.perturbation, |a, b| {
        let [(mean_a, s_a), (mean_b, s_b)] = [&predictions[a], &predictions[b]];
        covariance_pair(mean_a, s_a, mean_b, s_b)
    })
}

/// Each key bit of `perturbation`: for each value of the doublet's other bits (given to
/// Eve, as `separations_by` takes them), `pair(p, q)` of the bit's two values' patterns
/// `p` (the bit 0) and `q` (the bit 1); `None` where a pair has none.
fn paired_bits(
    perturbation: &Perturbation,
    pair: impl Fn(usize, usize) -> Option<CovariancePair>,
) -> Option<Vec<PairedBit>> {
    let patterns = perturbation.patterns();
    (0..perturbation.key_bits())
        .map(|i| {
            (0..patterns)
                .filter(|p| p >> i & 1 == 0)
                .map(|p| pair(p, p | 1 << i))
                .collect::<Option<PairedBit>>()
        })
        .collect()
}

/// Her views `N(mean_a, s_a)` and `N(mean_b, s_b)` of a bit's two values diagonalised
/// together ([`CovariancePair`]): whitened by `s_a` (`L⁻¹`, `s_a = LLᵀ`), rotated onto the
/// eigenvectors `V` of `L⁻¹·s_b·L⁻ᵀ`: coordinate k has shift `(VᵀL⁻¹(mean_b − mean_a))ₖ` and
/// variance that eigenvalue. `None` where `s_a` is not positive definite or a coordinate's
/// variance is not.
fn covariance_pair<D>(
    mean_a: &OVector<f64, D>,
    s_a: &OMatrix<f64, D, D>,
    mean_b: &OVector<f64, D>,
    s_b: &OMatrix<f64, D, D>,
) -> Option<CovariancePair>
where
    D: DimSub<U1> + DimMin<D, Output = D>,
    DefaultAllocator: Allocator<D, D> + Allocator<D> + Allocator<DimDiff<D, U1>>,
{
    let root = Cholesky::new(s_a.clone())?.l().try_inverse()?;
    let eigen = SymmetricEigen::new(&root * s_b * root.transpose());
    let shift = eigen.eigenvectors.transpose() * root * (mean_b - mean_a);
    CovariancePair::new((0..shift.len()).map(|k| Coordinate {
        shift: shift[k],
        variance: eigen.eigenvalues[k],
    }))
    .ok()
}

/// Each key bit's view of a three-step doublet (public `inputs`, Eve's `view`) under per-wheel
/// slip `slip = (σ², D)` (its variance, the wheels D m apart), at `corner` (a matrix below
/// every member of the region and the correlation interval's step weights: its steps'
/// `P₊ ⊗ W_low − P₋ ⊗ W_high`, the module's doc) over the lag's `interval` `[τ_lo, τ_hi]`
/// (s): at each lag of its grid ([`lag_grid`]) the pair of her Gaussian views of the bit's
/// two values, each step's noise with its own slip at that value's applied mean speeds
/// through τ (`σ²·R(θₖ)·Wₖ·R(θₖ)ᵀ`), and with `next` (the following doublet's public
/// inputs and her view of it) what its observed poses say from the doublet's end given to
/// her exactly (`entry_path`), its steps with their own slip likewise: given the end pose
/// the two views are independent (the Markov property), so their coordinates join in one
/// pair. Each bit keeps every lag's pairs ([`PairsOverLags`]): its exponent at every λ is
/// the least over the grid less a convexity slack, a bound at every τ of the interval under
/// the stated curvature assumption (that module's doc). `None` where a covariance is not
/// positive definite (no bound at the corner).
#[must_use]
pub fn three_step_slip_pairs(
    model: &DoubletModel,
    corner: &Corner,
    (slip_variance, axle): (f64, f64),
    interval: [f64; 2],
    inputs: &DoubletInputs,
    view: &DoubletView,
    next: Option<(&DoubletInputs, &DoubletView)>,
) -> Option<Vec<PairsOverLags>> {
    let k = three_step_covariance(corner);
    let here = in_world_frame(&k, view.start.value.z);
    let following = next.map(|(next_inputs, next_view)| {
        (
            with_exact_end(view, next_view),
            next_inputs,
            next_view,
            in_world_frame(&k, next_view.start.value.z),
        )
    });
    let own_view = following.as_ref().map_or(view, |(exact, ..)| exact);
    let observed = own_view.three_step_observed();
    if observed.is_empty() {
        return None;
    }
    let perturbation = &model.perturbation;
    let mut bits: Vec<Vec<PairedBit>> = vec![Vec::new(); perturbation.key_bits()];
    for lag in lag_grid(interval) {
        let model = DoubletModel { lag, ..*model };
        let slip = |start_heading: f64| StepSlip {
            variance: slip_variance,
            axle,
            sample_time: model.sample_time,
            start_heading,
        };
        let own = path_predictions(
            perturbation,
            &here,
            &own_view.start.covariance,
            &observed,
            |pattern| model.three_step_path(inputs, own_view, pattern),
            Some(slip(view.start.value.z)),
        );
        let entry = following
            .as_ref()
            .filter(|(_, _, next_view, _)| !next_view.three_step_observed().is_empty())
            .map(|(_, next_inputs, next_view, next_k)| {
                let start = next_view.start.value;
                path_predictions(
                    perturbation,
                    next_k,
                    &Matrix3::zeros(),
                    &next_view.three_step_observed(),
                    |pattern| entry_path(&model, inputs, next_inputs, &start, pattern),
                    Some(slip(start.z)),
                )
            });
        let at_lag = paired_bits(perturbation, |a, b| {
            let [(mean_a, s_a), (mean_b, s_b)] = [&own[a], &own[b]];
            let pair = covariance_pair(mean_a, s_a, mean_b, s_b)?;
            match &entry {
                None => Some(pair),
                Some(entry) => {
                    let [(mean_a, s_a), (mean_b, s_b)] = [&entry[a], &entry[b]];
                    let after = covariance_pair(mean_a, s_a, mean_b, s_b)?;
                    CovariancePair::new(
                        pair.coordinates()
                            .iter()
                            .chain(after.coordinates())
                            .copied(),
                    )
                    .ok()
                }
            }
        })?;
        for (lags, pairs) in bits.iter_mut().zip(at_lag) {
            lags.push(pairs);
        }
    }
    bits.into_iter().map(PairsOverLags::over_grid).collect()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::config::Config;
    use crate::model::{Pose, Unicycle};
    use crate::private::doublet_model;
    use crate::private::likelihood::stated_camera_view;
    use crate::rng::{Purpose, stream};
    use nalgebra::Vector3;
    use rand::RngExt;

    /// Each bit's separation at `model`'s own lag (a point cell).
    fn separations_at(
        model: &DoubletModel,
        k: &StepCovariance,
        positive: bool,
        inputs: &DoubletInputs,
        view: &DoubletView,
    ) -> Option<[f64; MAX_BITS]> {
        three_step_separations(model, k, positive, inputs, view, [model.lag; 2]).map(|d| d.centre)
    }

    /// A turning doublet of two bits in private sensing at the default configuration, seen
    /// by the stated camera: the slip tests' doublet (parties' config, model, inputs, view).
    pub(crate) fn turning_two_bit_doublet() -> (
        Config,
        crate::private::DoubletModel,
        DoubletInputs,
        DoubletView,
    ) {
        let mut config = Config::default();
        config.protocol.bits_per_doublet = 2;
        config.sensing.mode = crate::config::SensingMode::Private;
        let model = doublet_model(&config);
        let inputs = DoubletInputs {
            first: Unicycle::new(0.08, 0.3),
            second: Unicycle::new(0.08, 0.25),
        };
        let view = stated_camera_view(
            vec![
                Pose::new(0.0, 0.0, 0.8),
                Pose::new(0.011, 0.012, 0.86),
                Pose::new(0.021, 0.025, 0.91),
            ],
            config.sensing.controller_std,
            config.eve.camera_std,
        );
        (config, model, inputs, view)
    }

    /// Each bit's least exponent `−ln E[e^(−λS)]` over its pairs.
    pub(crate) fn exponents(bits: &[PairedBit], lambda: f64) -> Vec<f64> {
        bits.iter()
            .map(|bit| {
                bit.iter()
                    .map(|pair| -pair.ln_moment(lambda))
                    .fold(f64::INFINITY, f64::min)
            })
            .collect()
    }

    /// A member of a correlation cell: motion noise `motion` at correlation ρ between steps.
    pub(crate) fn member(motion: Matrix3<f64>, rho: f64) -> Corner {
        Corner {
            correlation: [rho, rho],
            motion,
            step_weights: crate::estimate::motion_noise::tests::weights_of([rho, rho]),
        }
    }

    /// Asserts that `bound`'s view tells her no more than the member's exponents `truth`
    /// at λ on any bit (each bound exponent at most the member's, to 10⁻⁹ of it); `case`
    /// names the draw in the message.
    pub(crate) fn assert_blunter(bound: &[PairedBit], truth: &[f64], lambda: f64, case: &str) {
        for (b, t) in exponents(bound, lambda).iter().zip(truth) {
            assert!(
                *b <= t + 1e-9 * t.abs(),
                "{case} λ {lambda}: bound {b} above the member's {t}"
            );
        }
    }

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
        turning_doublet_under(0.0)
    }

    /// [`turning_doublet`] in private sensing with doublets shaped for `prior_lag` (s; above 0:
    /// three steps, private sensing, her view of the four instants, the late one at the
    /// middle's value).
    fn turning_doublet_under(prior_lag: f64) -> (DoubletModel, DoubletInputs, DoubletView) {
        let mut config = Config::default();
        config.protocol.bits_per_doublet = 2;
        config.sensing.mode = crate::config::SensingMode::Private;
        config.private.prior_lag = prior_lag;
        let model = doublet_model(&config);
        assert_eq!(model.perturbation.settle.is_some(), prior_lag > 0.0);
        let inputs = DoubletInputs {
            first: Unicycle::new(0.1, 0.45),
            second: Unicycle::new(0.1, 0.4),
        };
        let mut samples = vec![
            Pose::new(0.0, 0.0, 0.8),
            Pose::new(0.02, 0.02, 0.9),
            Pose::new(0.03, 0.035, 0.97),
        ];
        if prior_lag > 0.0 {
            samples.insert(2, samples[1]);
        }
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

    /// `W(ρ)`: three AR(1) steps' conditional covariance given their neighbours (units of
    /// `Q`), the inverse of the precision's interior block.
    fn exact_weights(rho: f64) -> Matrix3<f64> {
        let (d, o) = (
            (1.0 + rho * rho) / (1.0 - rho * rho),
            -rho / (1.0 - rho * rho),
        );
        Matrix3::new(d, o, 0.0, o, d, o, 0.0, o, d)
            .try_inverse()
            .unwrap()
    }

    /// The three steps' weight bounds hold every member of a cell in the Loewner order:
    /// `W_low ⪯ W(ρ) ⪯ W_high` at 200 ρ of each cell; a point cell's bounds are `W(ρ)` itself
    /// (white: the identity).
    #[test]
    fn the_three_step_weights_bound_every_member_of_the_cell() {
        let least = |m: Matrix3<f64>| SymmetricEigen::new(m).eigenvalues.min();
        for cell in [
            [-0.5, -0.3],
            [0.0, 0.0],
            [-0.05, 0.4],
            [0.3, 0.5],
            [0.8, 0.95],
            [0.06, 0.1],
        ] {
            let [low, high] = three_step_weights(cell);
            for i in 0..=200 {
                let rho = cell[0] + (cell[1] - cell[0]) * f64::from(i) / 200.0;
                let w = exact_weights(rho);
                assert!(least(w - low) >= -1e-12, "{cell:?} {rho}: {low} ⋠ {w}");
                assert!(least(high - w) >= -1e-12, "{cell:?} {rho}: {w} ⋠ {high}");
            }
        }
        for rho in [0.0, -0.3, 0.5] {
            let [low, high] = three_step_weights([rho, rho]);
            assert!(
                (low - exact_weights(rho)).abs().max() < 1e-12,
                "{rho}: {low}"
            );
            assert!(
                (high - exact_weights(rho)).abs().max() < 1e-12,
                "{rho}: {high}"
            );
        }
        assert!(
            (three_step_weights([0.0, 0.0])[0] - Matrix3::identity())
                .abs()
                .max()
                < 1e-15
        );
    }

    /// The steps' covariances kept for the three-step worst case bound every corner's from
    /// below: for each corner's `P₊ ⊗ W_low − P₋ ⊗ W_high` some kept one lies below it, and one
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
            "{}",
            kept.len()
        );
        for corner in &estimate.corners {
            let own = three_step_covariance(corner);
            assert!(
                kept.iter()
                    .any(|(m, _)| SymmetricEigen::new(own - m).eigenvalues.min() >= -1e-18),
                "{corner:?}"
            );
        }
        assert!(kept.iter().all(|&(_, positive)| positive));
    }

    /// `Q ⊗ W` in the world frame at the doublet's heading.
    fn kron(q: &Matrix3<f64>, w: &Matrix3<f64>, theta: f64) -> StepCovariance {
        let h = rotation(theta);
        let mut k = StepCovariance::zeros();
        for i in 0..3 {
            for j in 0..3 {
                k.fixed_view_mut::<3, 3>(3 * i, 3 * j)
                    .copy_from(&(w[(i, j)] * h * q * h.transpose()));
            }
        }
        k
    }

    /// The next doublet's entry (1 mm of white motion noise, the shape for 50 ms): at the
    /// prior the bits' offsets leave the wheels at rest and the next doublet's poses say
    /// nothing of them; under a 100 ms lag they leave a speed whose travel through the next
    /// doublet her view takes (0.34 for each bit). With it the bound costs little at the
    /// prior (her view with the end pose given exactly: 0.012 of the v-bit's 1.52) and lies
    /// above her view of the doublet alone by more under the wrong lag (0.055 of 1.30).
    #[test]
    fn the_next_doublets_entry_enters_her_view_where_the_lag_is_not_the_prior() {
        let (model, inputs, view) = turning_doublet_under(0.05);
        let q = Matrix3::from_diagonal_element(1e-6);
        let k = kron(&q, &Matrix3::identity(), view.start.value.z);
        let next_view = DoubletView {
            start: view.end.unwrap(),
            ..view
        };
        let entry = |lag: f64| {
            let at = DoubletModel { lag, ..model };
            entry_separations(&at, &k, true, &inputs, &inputs, &next_view, [lag; 2])
                .unwrap()
                .centre
        };
        let [at_prior, wrong] = [entry(0.05), entry(0.1)];
        eprintln!("entry separations: at the prior {at_prior:?}, at 100 ms {wrong:?}");
        assert!(at_prior[..2].iter().all(|&d| d < 1e-6), "{at_prior:?}");
        assert!(wrong[0] > 0.1, "{wrong:?}");
        let steps = three_step_steps(&MotionNoiseEstimate::known(q, 0.0, 1e-6));
        let [cost_at_prior, cost_wrong] = [0.05, 0.1].map(|lag| {
            let interval = [lag, lag];
            let alone = three_step_worst_case(&model, &steps, interval, &inputs, &view, None);
            let next = Some((&inputs, &next_view));
            let with = three_step_worst_case(&model, &steps, interval, &inputs, &view, next);
            let [alone, with] = [alone.unwrap(), with.unwrap()];
            eprintln!("τ {lag}: alone {alone:?}, with the next doublet's entry {with:?}");
            assert!(with[0] >= alone[0] && with[1] >= alone[1]);
            with[0] - alone[0]
        });
        assert!(
            cost_at_prior < 0.015 && cost_wrong > 0.04,
            "{cost_at_prior} {cost_wrong}"
        );
    }

    /// White steps (`W = I`): the three-step separation with the steps' covariance stacked
    /// is the doublet model's own, at lags within and beyond the prior.
    #[test]
    fn white_three_steps_are_the_doublet_models_view() {
        let (model, inputs, view) = turning_doublet_under(0.05);
        let q = Matrix3::new(1e-6, 2e-7, 0.0, 2e-7, 8e-7, 1e-8, 0.0, 1e-8, 1e-6);
        let h = rotation(view.start.value.z);
        for lag in [0.0, 0.03, 0.05, 0.1] {
            let at = DoubletModel {
                process_covariance: h * q * h.transpose(),
                lag,
                ..model
            };
            let expected = at.separations(&inputs, &view);
            let k = kron(&q, &Matrix3::identity(), view.start.value.z);
            let got = separations_at(&at, &k, true, &inputs, &view).unwrap();
            for b in 0..2 {
                assert!(
                    expected[b] > 0.0 && (got[b] - expected[b]).abs() <= 1e-9 * expected[b],
                    "{lag}: {got:?} {expected:?}"
                );
            }
        }
    }

    /// The three-step corner dominates its cell: 300 random members of each cell — `Q_cell +
    /// GGᵀ` (full matrices, any orientation) with ρ anywhere in the cell and the steps'
    /// exact conditional covariance `Q ⊗ W(ρ)` — never give either bit a larger separation
    /// than the corner's `P₊ ⊗ W_low − P₋ ⊗ W_high`, at a vertex with a negative eigenvalue
    /// too; and a point cell at ρ = 0 is the white view.
    #[test]
    fn no_member_of_a_cell_gives_eve_a_sharper_three_step_view() {
        let (model, inputs, view) = turning_doublet_under(0.05);
        let theta = view.start.value.z;
        let mut rng = stream(7, Purpose::Public, 0);
        for lower in [
            Matrix3::new(1e-6, 2e-7, 0.0, 2e-7, 8e-7, 1e-8, 0.0, 1e-8, 1e-6),
            Matrix3::new(1e-6, 0.0, 0.0, 0.0, -2e-8, 0.0, 0.0, 0.0, 1e-6),
        ] {
            for cell in [
                [-0.5, -0.3],
                [0.0, 0.0],
                [-0.05, 0.1],
                [0.06, 0.1],
                [0.8, 0.95],
            ] {
                let corner = Corner {
                    correlation: cell,
                    motion: lower,
                    step_weights: super::super::motion_noise::tests::weights_of(cell),
                };
                let bound = three_step_covariance(&corner);
                let h = rotation(theta);
                let mut frame = StepCovariance::zeros();
                for i in 0..3 {
                    frame.fixed_view_mut::<3, 3>(3 * i, 3 * i).copy_from(&h);
                }
                let vertex = separations_at(
                    &model,
                    &(frame * bound * frame.transpose()),
                    false,
                    &inputs,
                    &view,
                )
                .unwrap();
                for _ in 0..300 {
                    let g = Matrix3::from_fn(|_, _| rng.random_range(-1.5e-3..1.5e-3));
                    let rho = if cell[0] == cell[1] {
                        cell[0]
                    } else {
                        rng.random_range(cell[0]..cell[1])
                    };
                    let member = kron(&(lower + g * g.transpose()), &exact_weights(rho), theta);
                    let d = separations_at(&model, &member, false, &inputs, &view).unwrap();
                    for k in 0..2 {
                        assert!(
                            d[k] <= vertex[k] * (1.0 + 1e-12),
                            "{cell:?} ρ {rho}: {d:?} > {vertex:?}"
                        );
                    }
                }
            }
        }
    }

    /// The bound holds between the lag's grid points: on intervals around the prior, below
    /// and above it, and on wide ones, the worst case is at least the separation at each of
    /// 401 lags sampled evenly over the interval, for each bit, two noise levels, the wheels'
    /// entry speed known or not and the next doublet's entry in her view or not, and lies
    /// within a quantum of the 5-point grid's largest (no slack of its own was needed there).
    #[test]
    fn the_lag_bound_holds_for_every_lag_in_the_interval() {
        let (model, inputs, plain) = turning_doublet_under(0.05);
        let entered = DoubletView {
            entry: Some(Unicycle::new(0.085, 0.52)),
            ..plain
        };
        let next_inputs = DoubletInputs {
            first: Unicycle::new(0.11, 0.35),
            second: Unicycle::new(0.1, 0.3),
        };
        for q_std in [1e-3, 4e-3] {
            let q = Matrix3::from_diagonal_element(q_std * q_std);
            let steps = three_step_steps(&MotionNoiseEstimate::known(q, 0.0, 1e-6));
            for view in [plain, entered] {
                let next_view = DoubletView {
                    start: view.end.unwrap(),
                    ..view
                };
                for next in [None, Some((&next_inputs, &next_view))] {
                    for interval in [
                        [0.0435, 0.0573],
                        [0.0, 0.03],
                        [0.08, 0.12],
                        [0.0, 0.3],
                        [0.02, 0.5],
                    ] {
                        let worst = |interval: [f64; 2]| {
                            three_step_worst_case(&model, &steps, interval, &inputs, &view, next)
                                .unwrap()
                        };
                        let bound = worst(interval);
                        let grid = lag_grid(interval)
                            .into_iter()
                            .map(|lag| worst([lag; 2]))
                            .fold([0.0_f64; MAX_BITS], |m, d| {
                                std::array::from_fn(|i| m[i].max(d[i]))
                            });
                        for i in 0..=400 {
                            let lag =
                                interval[0] + (interval[1] - interval[0]) * f64::from(i) / 400.0;
                            let d = worst([lag; 2]);
                            for b in 0..2 {
                                assert!(
                                    d[b] <= bound[b] * (1.0 + 1e-12)
                                        && (interval[1] - interval[0] > 0.05
                                            || bound[b] - grid[b] <= SEPARATION_QUANTUM),
                                    "{q_std} {interval:?} τ {lag} entry {:?} next {}: bit {b} \
                                     {} > {} (grid {})",
                                    view.entry,
                                    next.is_some(),
                                    d[b],
                                    bound[b],
                                    grid[b]
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    /// The speeds' polynomials in the lag are the paths' own applied speeds: at lags from 0
    /// to 0.3 s, every pattern, the wheels' entry speed known or not, the doublet's and the
    /// next doublet's steps (a point's range is the value, to 10⁻¹⁵ m/s).
    #[test]
    fn the_lag_polynomials_are_the_paths_speeds() {
        let (model, inputs, plain) = turning_doublet_under(0.05);
        let next_inputs = DoubletInputs {
            first: Unicycle::new(0.11, 0.35),
            second: Unicycle::new(0.1, 0.3),
        };
        for view in [
            plain,
            DoubletView {
                entry: Some(Unicycle::new(0.085, 0.52)),
                ..plain
            },
        ] {
            for lag in [0.0, 0.01, 0.05, 0.1, 0.3] {
                let at = DoubletModel { lag, ..model };
                for pattern in 0..model.perturbation.patterns() {
                    let cases = [
                        (
                            at.three_step_path(&inputs, &view, pattern).2,
                            three_step_speeds(&model, &inputs, view.entry, pattern),
                        ),
                        (
                            entry_path(&at, &inputs, &next_inputs, &view.start.value, pattern).2,
                            entry_speeds(&model, &inputs, &next_inputs, pattern),
                        ),
                    ];
                    for (applied, speeds) in cases {
                        for (u, speed) in applied.iter().zip(&speeds) {
                            for end in speed.range([lag; 2], model.sample_time) {
                                assert!(
                                    (end - u).abs().max() < 1e-15,
                                    "{lag} {pattern}: {u} {end}"
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    /// The cells' driver: for separations that peak inside a grid interval (one bit a bump
    /// of width 0.08 s, the other a sine), each cell bounded by its centre's value plus a
    /// true Lipschitz constant (2.2 and 1.3 per s) times its half-width, the grid's largest
    /// alone misses the peak, and the bound is at least every one of 2,000 samples and at
    /// most the peak plus the first cells' slack; a point interval is its value.
    #[test]
    fn the_cells_cover_a_peak_between_grid_points() {
        let interval = [0.0, 0.4];
        let lipschitz = [2.2, 1.3];
        let at = |t: f64| -> [f64; MAX_BITS] {
            let mut d = [0.0; MAX_BITS];
            d[0] = 1.0 + 0.2 * (-((t - 0.15) / 0.08).powi(2)).exp();
            d[1] = 1.3 + 0.1 * (t * 13.0).sin();
            d
        };
        let over = |[low, high]: [f64; 2]| {
            let centre = at(0.5 * (low + high));
            let mut bound = centre;
            for (b, l) in lipschitz.iter().enumerate() {
                bound[b] += l * 0.5 * (high - low);
            }
            Some(OverCell { centre, bound })
        };
        let bound = largest_over_lags(interval, over).unwrap();
        let grid = lag_grid(interval)
            .into_iter()
            .map(at)
            .fold([0.0_f64; MAX_BITS], |m, d| {
                std::array::from_fn(|i| m[i].max(d[i]))
            });
        let samples: Vec<[f64; MAX_BITS]> = (0..=2000)
            .map(|i| at(interval[0] + (interval[1] - interval[0]) * f64::from(i) / 2000.0))
            .collect();
        for b in 0..2 {
            let peak = samples.iter().map(|d| d[b]).fold(0.0, f64::max);
            assert!(
                grid[b] < peak && peak <= bound[b] && bound[b] <= peak + lipschitz[b] * 0.05,
                "bit {b}: {grid:?} {peak} {bound:?}"
            );
        }
        assert_eq!(largest_over_lags([0.1, 0.1], over).unwrap(), at(0.1));
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

    /// The raised shares lie below every member of the bounded region, tightly. Corners as
    /// slip leaves them at 4 mm (`Q_c` = diag(12, 12.5, −26)·10⁻⁶ and the same turned into a
    /// seeded random frame, so that along-track, lateral and heading mix), with an upper bound
    /// `U` whose positive block lies `(1 + μ)`, μ = 0.8, above the corner's: a loose `U` (its
    /// heading 5c) and a tight one, `U = Q* + diag(0, μb, 10⁻⁹)` with `Q*` the member on both
    /// of the proof's boundaries (`Q₁₁ = a(1 + μ)`, `Q₃₃ = μc`, its along-track and heading
    /// noise perfectly correlated). μ is recovered from `U`; each matrix lies above its share
    /// `λQ_c`; each of the seeded members `Q ⪰ 0`, `Q ⪰ Q_c`, `Q ⪯ U` (minimal ones
    /// `Q_c + xxᵀ` and ones `U − GGᵀ`, kept where they are members) lies above every matrix
    /// to 10⁻¹⁸ m², while some lie not above a matrix with θ taken from a μ of half the
    /// true one; and at `Q*` θ raised by 10⁻³ of itself fails on each share strictly between
    /// 0 and 1 (the bound cannot be raised). Without `U` the matrices are the shares; a
    /// corner above 0 is its own one matrix.
    #[test]
    fn every_raised_share_lies_below_the_members_of_the_bounded_region() {
        use nalgebra::Rotation3;
        let (a, b, c, mu) = (12e-6, 12.5e-6, 26e-6, 0.8_f64);
        let least = |m: Matrix3<f64>| SymmetricEigen::new(m).eigenvalues.min();
        let mut rng = stream(43, Purpose::Public, 0);
        let axis = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0));
        let s = (a * (1.0 + mu) * mu * c).sqrt();
        let tight_member = Matrix3::new(a * (1.0 + mu), 0.0, s, 0.0, b, 0.0, s, 0.0, mu * c);
        let mut over_claimed = 0;
        for frame in [
            Matrix3::identity(),
            *Rotation3::from_scaled_axis(axis).matrix(),
        ] {
            let turn = |m: Matrix3<f64>| frame * m * frame.transpose();
            let corner = turn(Matrix3::from_diagonal(&Vector3::new(a, b, -c)));
            let n = frame * Vector3::z();
            let positive = corner + c * n * n.transpose();
            let loose = turn(Matrix3::from_diagonal(&Vector3::new(
                a * (1.0 + mu),
                b * (1.0 + mu),
                5.0 * c,
            )));
            let tight =
                turn(tight_member + Matrix3::from_diagonal(&Vector3::new(0.0, mu * b, 1e-9)));
            let shares: Vec<Matrix3<f64>> = VERTEX_SHARES.iter().map(|&l| l * corner).collect();
            let plain = below_the_region(&corner, None);
            assert!(
                plain
                    .iter()
                    .zip(&shares)
                    .all(|(l, share)| (l - share).abs().max() < 1e-18),
                "{plain:?}"
            );
            let eigen = SymmetricEigen::new(corner);
            let recovered = upper_excess(&eigen, &loose).unwrap();
            assert!((recovered - mu).abs() < 1e-9, "μ {recovered}");
            // What a μ of half the true one would claim: no bound.
            let over: Vec<Matrix3<f64>> = VERTEX_SHARES
                .iter()
                .map(|&l| raised_share(l, Some(mu / 2.0)) * positive - l * c * n * n.transpose())
                .collect();
            for upper in [loose, tight] {
                let bounds = below_the_region(&corner, Some(&upper));
                for (l, share) in bounds.iter().zip(&shares) {
                    assert!(least(l - share) >= -1e-18, "{l} below its share {share}");
                }
                let mut members = Vec::new();
                for trial in 0..4000 {
                    let candidate = if trial % 2 == 0 {
                        let [t1, t2] =
                            [a, b].map(|x| (mu * x).sqrt() * rng.random_range(-1.2..1.2));
                        let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                        let t3 = sign * (c * (1.0 + t1 * t1 / a + t2 * t2 / b)).sqrt();
                        let x = frame * Vector3::new(t1, t2, t3);
                        corner + x * x.transpose()
                    } else {
                        let g = Matrix3::from_fn(|_, _| rng.random_range(-1.0..1.0))
                            * (10f64.powf(rng.random_range(-4.0..0.2)) * a).sqrt();
                        upper - g * g.transpose()
                    };
                    if least(candidate) >= -1e-18
                        && least(candidate - corner) >= -1e-18
                        && least(upper - candidate) >= -1e-18
                    {
                        members.push(candidate);
                    }
                }
                if upper == tight {
                    members.push(turn(tight_member));
                }
                // The tight region is thin (`U − Q*` is 0 along-track): `Q*` and a few.
                let wanted = if upper == tight { 1 } else { 200 };
                assert!(members.len() > wanted, "{} members", members.len());
                for member in &members {
                    for l in &bounds {
                        assert!(least(member - l) >= -1e-18, "{member} not above {l}");
                    }
                    over_claimed += over.iter().filter(|l| least(member - *l) < -1e-12).count();
                }
                if upper == tight {
                    for (l, &share) in bounds.iter().zip(&VERTEX_SHARES) {
                        let raised = (l + share * c * n * n.transpose()) * 1.001
                            - share * c * n * n.transpose();
                        let at_tight = least(turn(tight_member) - raised);
                        if share > 0.0 && share < 1.0 {
                            assert!(at_tight < -1e-12, "λ {share}: {at_tight}");
                        }
                    }
                }
            }
        }
        assert!(over_claimed > 0, "no member below the over-raised shares");
        let above = Matrix3::from_diagonal(&Vector3::new(a, b, c));
        assert_eq!(below_the_region(&above, Some(&above)), vec![above]);
    }

    /// What Eve sees at each raised share bounds what every member of the bounded region
    /// shows her, with the slip's bit-dependent covariance: on a turning doublet of two bits
    /// at σ² = 2.85·10⁻³, white and over a correlation cell [0.3, 0.5], 60 seeded members of
    /// `{Q ⪰ 0, Q ⪰ Q_c, Q ⪯ U}` (`Q_c` = diag(12, 12.5, −26)·10⁻⁶, `U` = diag(21.6, 22.5,
    /// 130)·10⁻⁶, ρ anywhere in the cell) give her on every bit no larger moment
    /// `E[e^(−λS)]` (λ = ¼, ½, 1; each bit's least exponent over its pairs) than each raised
    /// share's view, to 10⁻⁹ of it; and the raised shares' bluntest view tells her less than
    /// the plain shares' (a larger Bhattacharyya exponent summed over the bits).
    #[test]
    fn the_raised_shares_bound_what_the_members_show_her() {
        use super::super::motion_noise::tests::weights_of;
        let (config, model, inputs, view) = turning_two_bit_doublet();
        let (slip, axle) = (2.85e-3, config.robot.axle_length);
        let (a, b, c) = (12e-6, 12.5e-6, 26e-6);
        let corner_motion = Matrix3::from_diagonal(&Vector3::new(a, b, -c));
        let upper = Matrix3::from_diagonal(&Vector3::new(1.8 * a, 1.8 * b, 5.0 * c));
        let least = |m: Matrix3<f64>| SymmetricEigen::new(m).eigenvalues.min();
        let sum = |bits: &[PairedBit]| exponents(bits, 0.5).iter().sum::<f64>();
        let mut rng = stream(47, Purpose::Public, 0);
        for cell in [[0.0, 0.0], [0.3, 0.5]] {
            let corner = Corner {
                correlation: cell,
                motion: corner_motion,
                step_weights: weights_of(cell),
            };
            let pairs_at = |motion: Matrix3<f64>| {
                slip_pairs(
                    &model,
                    &Corner { motion, ..corner },
                    slip,
                    axle,
                    &inputs,
                    &view,
                )
            };
            let raised: Vec<Vec<PairedBit>> = below_the_region(&corner_motion, Some(&upper))
                .into_iter()
                .filter_map(pairs_at)
                .collect();
            let plain: Vec<Vec<PairedBit>> = below_the_region(&corner_motion, None)
                .into_iter()
                .filter_map(pairs_at)
                .collect();
            let bluntest =
                |views: &[Vec<PairedBit>]| views.iter().map(|v| sum(v)).fold(f64::MIN, f64::max);
            assert!(
                bluntest(&raised) > bluntest(&plain),
                "{} ≤ {}",
                bluntest(&raised),
                bluntest(&plain)
            );
            let mut members = 0;
            while members < 60 {
                let [t1, t2] = [a, b].map(|x| (0.8 * x).sqrt() * rng.random_range(-1.0..1.0));
                let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                let t3 = sign * (c * (1.0 + t1 * t1 / a + t2 * t2 / b)).sqrt();
                let x = Vector3::new(t1, t2, t3);
                let g = Matrix3::from_fn(|_, _| rng.random_range(-0.3..0.3)) * a.sqrt();
                let motion = corner_motion + x * x.transpose() + g * g.transpose();
                if least(upper - motion) < 0.0 {
                    continue;
                }
                members += 1;
                let rho = rng.random_range(cell[0]..=cell[1]);
                let seen =
                    slip_pairs(&model, &member(motion, rho), slip, axle, &inputs, &view).unwrap();
                for lambda in [0.25, 0.5, 1.0] {
                    let truth = exponents(&seen, lambda);
                    for bound in &raised {
                        assert_blunter(bound, &truth, lambda, &format!("cell {cell:?}"));
                    }
                }
            }
        }
    }
}
