//! The actuator's first-order lag τ measured from the bits' mid-doublet amplitude
//! (docs/estimation.md, "The lag").
//!
//! Through a lag τ a step offset `s·Δv` begun from wheels that carry no offset moves the
//! robot `s·Δv·T·g(τ)` along its heading (`s = ±1` binary, a multilevel symbol's amplitude
//! `(L − 1 − 2i)/√E` with `protocol.levels > 2`), `g(τ) = 1 − (τ/T)·(1 − e^(−T/τ))` (`g(0) = 1`,
//! decreasing toward 0). The controller's residual after a doublet's first step along its
//! start heading, `z = e(θ₀)·(y(Lj+1) − f(y(Lj), u))`, is that plus what does not depend on
//! the doublet's v-bit: the motion and sensor noise, the ω-bit (the Euler map moves the
//! position along the start heading), and the nominal input's own transient through the lag
//! (the wheels' speed at the doublet's start is not kept). With the reconciled amplitudes
//! `s`, which are uniform over the alphabet and independent of all of it,
//!
//! `ĝ = Σ sᵢzᵢ / (Δv·T·Σ sᵢ²)`
//!
//! (binary: `mean(s·z)/(Δv·T)`) is unbiased for `g(τ)`, and `ĝ ± z(ε_est/2)·σ̂/(Δv·T·√Σsᵢ²)`
//! (`σ̂` the deviation of what remains, `zᵢ − ĝ·sᵢ·Δv·T`; the products' covariances vanish
//! between doublets, `E[sᵢsⱼ] = 0`) covers it with
//! probability about 1 − ε_est — the normal approximation of the mean, the quantile taken
//! from the normal tail's bound, wider than the exact one, or from Student's `t` with
//! `n − 1` degrees of freedom where that is wider (σ̂ is estimated; below about 130
//! doublets). `g` is monotone, so the interval
//! maps to `[τ_lo, τ_hi]` through its inverse. A dead time `D` shortens the first step's
//! travel as a lag does (`g = 1 − D/T` for a pure delay): the estimate is the lag that
//! explains the amplitude, not the lag and the dead time apart.
//!
//! **Three-step doublets** carry the bit through τ in their second and third steps too: the
//! residuals after the second step (where the pool kept that sample) and at the doublet's
//! end, conditioned on the reconciled bits, share the first step's noise and move with τ,
//! so together they measure τ better than the first step alone. [`estimate_lag_jointly`]
//! inverts a weighted score of them (`Ŝ⁻¹v`, their covariance and slope in τ) into τ's
//! interval, with the doublets' turns beside them where the path turns (the heading's
//! transient through τ over the second and third steps, and over the first with its
//! weight's bias from the start sample removed through the controller's own gain,
//! estimate/block.rs; under AR(1) motion noise each turn's bias through the step before the
//! start sample corrected over ρ's interval, [`TurnCorrection`]); the first step's estimate
//! gives its starting point and the dead-time test's interval.

use nalgebra::{DMatrix, DVector};

use super::normal_tail::studentized_upper_quantile;
use crate::model::unicycle_step;
use crate::private::DoubletSamples;
use crate::private::doublet::Perturbation;

/// The largest lag the class covers (s): `private.prior_lag`'s range.
pub const MAX_LAG: f64 = 1.0;

/// The fewest doublets the estimate is made from.
pub const MIN_LAG_DOUBLETS: usize = 100;

/// What the controller measured of the lag for one block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LagEstimate {
    /// The point estimate τ̂ (s).
    pub point: f64,
    /// Its (1 − ε_est) interval `[τ_lo, τ_hi]` (s).
    pub interval: [f64; 2],
    /// The first step's share of the v-bit's travel, `ĝ` (1 without lag).
    pub share: f64,
    /// Its (1 − ε_est) interval.
    pub share_interval: [f64; 2],
    /// Doublets it was measured from.
    pub doublets: usize,
}

/// `g(τ) = 1 − (τ/T)·(1 − e^(−T/τ))`: the share of a step offset's travel a first-order
/// lag `lag` τ (s) leaves in a step of `sample_time` T (s) begun without offset.
#[must_use]
pub fn first_step_share(lag: f64, sample_time: f64) -> f64 {
    if lag <= 0.0 {
        return 1.0;
    }
    1.0 - lag / sample_time * (1.0 - (-sample_time / lag).exp())
}

/// `g′(τ) = e^(−T/τ)/τ − (1 − e^(−T/τ))/T`: the slope in `lag` τ (s) of
/// [`first_step_share`] at sample time `sample_time` T (1/s; below 0, 0 at τ = 0).
#[must_use]
pub fn first_step_share_slope(lag: f64, sample_time: f64) -> f64 {
    if lag <= 0.0 {
        return 0.0;
    }
    let decay = (-sample_time / lag).exp();
    decay / lag - (1.0 - decay) / sample_time
}

/// The lag in `[0, MAX_LAG]` whose [`first_step_share`] is `share`, by bisection (`g` is
/// decreasing): 0 for a share of 1 or more, [`MAX_LAG`] for one at or below `g(MAX_LAG)`.
fn lag_of_share(share: f64, sample_time: f64) -> f64 {
    if share >= 1.0 {
        return 0.0;
    }
    if share <= first_step_share(MAX_LAG, sample_time) {
        return MAX_LAG;
    }
    let (mut low, mut high) = (0.0, MAX_LAG);
    for _ in 0..64 {
        let middle = 0.5 * (low + high);
        if first_step_share(middle, sample_time) > share {
            low = middle;
        } else {
            high = middle;
        }
    }
    0.5 * (low + high)
}

/// The lag measured from `doublets` (the controller's samples and the reconciled bits) with
/// the v-symbol's offsets of `perturbation` (its Δv, m/s, and alphabet), sample time
/// `sample_time` (s), at ε_est = `epsilon`.
///
/// # Errors
/// Fewer than [`MIN_LAG_DOUBLETS`] doublets, a non-positive Δv, or an interval that leaves
/// the class (its upper end beyond [`MAX_LAG`]), naming the value.
pub fn estimate_lag<'a>(
    doublets: impl IntoIterator<Item = &'a DoubletSamples>,
    perturbation: &Perturbation,
    sample_time: f64,
    epsilon: f64,
) -> Result<LagEstimate, String> {
    let delta_v = perturbation.delta.x;
    let scale = delta_v * sample_time;
    if scale <= 0.0 {
        return Err(format!(
            "lag estimate: protocol.delta_v = {delta_v} m/s (allowed: above 0)"
        ));
    }
    // Each doublet's v-symbol amplitude `s` (its label: the pattern's low bits), `s·z/(Δv·T)`.
    let products: Vec<(f64, f64)> = doublets
        .into_iter()
        .map(|b| {
            let [start, middle, _] = b.samples;
            let predicted = unicycle_step(&start, &b.inputs.first, sample_time);
            let (sin, cos) = start.z.sin_cos();
            let along = (middle.x - predicted.x) * cos + (middle.y - predicted.y) * sin;
            let amplitude = perturbation.amplitude(b.pattern);
            (amplitude, amplitude * along / scale)
        })
        .collect();
    lag_of_products(&products, sample_time, epsilon)
}

/// The lag measured from each doublet's v-amplitude `s` and first-step product
/// `s·z/(Δv·T)` ([`estimate_lag`]).
fn lag_of_products(
    products: &[(f64, f64)],
    sample_time: f64,
    epsilon: f64,
) -> Result<LagEstimate, String> {
    let n = products.len();
    if n < MIN_LAG_DOUBLETS {
        return Err(format!(
            "lag estimate: {n} doublets (allowed: at least {MIN_LAG_DOUBLETS})"
        ));
    }
    let count = n as f64;
    // Σ s² (binary: n).
    let weight = products.iter().map(|(s, _)| s * s).sum::<f64>();
    let share = products.iter().map(|(_, p)| p).sum::<f64>() / weight;
    // What remains of each, `(z/(Δv·T) − ĝ·s)² = s²·(p/s² − ĝ)²` (binary: `(p − ĝ)²`).
    let variance = products
        .iter()
        .map(|(s, p)| s * s * (p / (s * s) - share).powi(2))
        .sum::<f64>()
        / (count - 1.0);
    let half_width = studentized_upper_quantile(epsilon / 2.0, n - 1) * (variance / weight).sqrt();
    let [low, high] = [share - half_width, share + half_width];
    let floor = first_step_share(MAX_LAG, sample_time);
    if low <= floor {
        return Err(format!(
            "lag estimate: the first step's share of the bit's travel is {share:.4} \
             [{low:.4}, {high:.4}] over {n} doublets, which allows a lag beyond the class \
             (allowed: the interval's lower end above {floor:.4}, the share at τ = {MAX_LAG} s)"
        ));
    }
    Ok(LagEstimate {
        point: lag_of_share(share, sample_time),
        interval: [
            lag_of_share(high, sample_time),
            lag_of_share(low, sample_time),
        ],
        share,
        share_interval: [low, high],
        doublets: n,
    })
}

/// A turn's product whose mean under AR(1) motion noise is not 0 at the true τ, and how it
/// is corrected ([`estimate_lag_jointly`]): its weight `a` is fixed at the doublet's start
/// sample `θ̂(3j)`, which the heading noise of the step before, `w(3j−1)`, moved, and the
/// steps its residual spans follow that step by ρ per step. With `m = E[a·w(3j−1)]` the
/// product's mean is `f(ρ)·E[s]`, `s = a·r_s` the same weight times the straddle residual
/// `r_s = θ̂(3j+1) − θ̂(3j−1)` less its lagged means' turn (steps `3j−1` and `3j`: mean
/// `(1 + ρ)·m`, its sensor noise at samples the controller did not read).
#[derive(Clone, Copy, Debug)]
pub struct TurnCorrection {
    /// The product's index among the doublet's components.
    pub component: usize,
    /// Its straddle product's index among the doublet's entries (after the components).
    pub straddle: usize,
    /// `f(ρ)`: the product's mean over the straddle's (`ρ/(1 + ρ)` for the first step's
    /// turn, whose residual spans step `3j`; `ρ²` for the turn over steps `3j+1` and `3j+2`).
    pub factor: fn(f64) -> f64,
}

/// The turns' corrections of a joint lag statistic and the AR(1) correlation's interval
/// `[ρ_lo, ρ_hi]` they are taken over (no corrections, or a point at 0: the plain statistic).
#[derive(Clone, Copy, Debug)]
pub struct TurnCorrections<'a> {
    /// The products corrected.
    pub corrections: &'a [TurnCorrection],
    /// ρ's interval.
    pub correlation: [f64; 2],
}

impl TurnCorrections<'_> {
    /// No correction: every product has mean 0 at the true τ.
    pub const NONE: TurnCorrections<'static> = TurnCorrections {
        corrections: &[],
        correlation: [0.0, 0.0],
    };

    /// The corners of the box of each correction's `f(ρ)` over ρ's interval: each factor's
    /// least and greatest over the interval (`ρ/(1 + ρ)` is monotone; `ρ²` least at 0 where
    /// the interval holds it), every combination (one corner where each is a point).
    fn corners(&self) -> Vec<Vec<f64>> {
        let [low, high] = self.correlation;
        self.corrections
            .iter()
            .fold(vec![Vec::new()], |corners, c| {
                let ends = [(c.factor)(low), (c.factor)(high)];
                let through_zero = low < 0.0 && high > 0.0;
                let least = if through_zero {
                    ends[0].min(ends[1]).min((c.factor)(0.0))
                } else {
                    ends[0].min(ends[1])
                };
                let greatest = ends[0].max(ends[1]);
                let values: &[f64] = if least == greatest {
                    &[least][..]
                } else {
                    &[least, greatest][..]
                };
                corners
                    .iter()
                    .flat_map(|corner| {
                        values.iter().map(move |&v| {
                            let mut next = corner.clone();
                            next.push(v);
                            next
                        })
                    })
                    .collect()
            })
    }
}

/// The first step's turn's `f(ρ) = ρ/(1 + ρ)` ([`TurnCorrection`]).
#[must_use]
pub fn first_turn_factor(rho: f64) -> f64 {
    rho / (1.0 + rho)
}

/// The turn over the second and third steps' `f(ρ) = ρ²`: its residual spans steps `3j+1`
/// and `3j+2`, `(ρ² + ρ³)·m = ρ²·(1 + ρ)·m` ([`TurnCorrection`]).
#[must_use]
pub fn later_turn_factor(rho: f64) -> f64 {
    rho * rho
}

/// Grid points over the bracket at which the joint statistic is evaluated before its
/// crossings are bisected.
const JOINT_GRID: usize = 17;

/// Bisection steps per crossing (its bracket's 2⁻²⁴).
const CROSSING_STEPS: usize = 24;

/// The lag step (s) of the residuals' numerical slope in τ.
const SLOPE_STEP: f64 = 1e-3;

/// The lag measured jointly from each three-step doublet's first step, its sample after
/// the second step where kept, and its end (docs/estimation.md, "The lag"), starting from
/// the first step's estimate `first`, at ε_est = `epsilon`.
///
/// `residuals(τ)` gives, per doublet, its residuals along its start heading with the lagged
/// means through τ subtracted, times its v-amplitude: `uᵢ(τ) = sᵢ·(z₁ᵢ(τ), z₃ᵢ(τ))` (m)
/// after the first step and at the end, or `sᵢ·(z₁ᵢ(τ), z₂ᵢ(τ), z₃ᵢ(τ))` with the sample
/// after the second step, and possibly up to two more of mean 0 at the true τ that move
/// with it (the turns' products of a three-step block; every doublet the same components, 2
/// to 5). Each has mean 0 at the true τ (the amplitudes are independent of everything but
/// their own travel). The later ones add
/// what the second and third steps carry of the bit through τ: after the second step the
/// bit's travel through τ is largest (the shape's `−(1 + a)` step, lagged, has not undone
/// the first's), at the end the shape cancels it near the prior; both share the first
/// step's noise. With `Ŝ` the products' sample covariance and `v = ∂ū/∂τ` at `first`'s
/// point (a central difference), the weights `c = Ŝ⁻¹v` make
///
/// `t(τ) = mean(qᵢ) / √((γ₀ + 2γ₁)/n)`, `qᵢ = c·uᵢ(τ)`,
///
/// standard normal at the true τ (the normal approximation of a mean, as for the first
/// step), `γ₀` the `qᵢ`'s sample variance and `γ₁` their sample covariance with the next
/// in the order given: the v-amplitudes' products are uncorrelated between doublets
/// (`E[sᵢsⱼ] = 0`), but a doublet's first-step turn shares its start sample with the end
/// of the turn its predecessor measured, so consecutive products may correlate, and none
/// further apart do (a 1-dependent sequence; `γ₁` estimates 0 where nothing is shared). So
/// `{τ : |t(τ)| ≤ z(ε_est/2)}` covers it with probability about 1 − ε_est (`z` the
/// studentized quantile with `n − 1` degrees of freedom). `t` rises with
/// τ (`cᵀv = vᵀŜ⁻¹v > 0`): the interval is that set's hull within a bracket — `first`'s
/// interval, widened until `t` lies below `−z` at its lower end (or τ = 0) and above `z`
/// at its upper — located on a 17-point grid and bisected at the crossings, each end
/// taken at the side outside the set; τ̂ is `t`'s zero. A set the grid does not resolve
/// (parts of it between two grid points outside it) is not covered: that is the stated
/// assumption.
///
/// **The turns under AR(1) noise** (`corrections`, [`TurnCorrection`]): a turn's product
/// has mean `f(ρ)·E[s]` at the true τ, `s` its straddle product (each doublet's entries
/// after its components, in `corrections`' order), so `u_k − f(ρ)·s` has mean 0 at the true
/// τ and ρ. Over ρ's interval each `f` takes values in `[f_lo, f_hi]`; at every corner of
/// that box the weighted mean is linear in the `f`'s and its variance convex, so where the
/// true ρ's `|t| ≤ z` the least weighted mean over the corners is at most `z` times the
/// largest standard error among them, and the greatest at least `−z` times it: the set
/// `{τ : t_lo(τ) ≤ z, t_hi(τ) ≥ −z}` (`t_lo`, `t_hi` those extremes over that error)
/// holds the true τ whenever ρ's interval holds ρ and the statistic lies within `z`, and
/// is found as above with `t_hi` at the lower end and `t_lo` at the upper. The weights and
/// τ̂ are taken at the box's middle. With no corrections (or a point at ρ = 0) it is the
/// plain statistic, number for number.
///
/// # Errors
/// Fewer than [`MIN_LAG_DOUBLETS`] doublets, doublets with other than 2 to 5 components,
/// residuals without slope in τ, a statistic whose variance estimate is not positive, a set beyond the class (τ above [`MAX_LAG`]) or an empty
/// one (the doublets carry more of the bit than no lag does), naming the values.
pub fn estimate_lag_jointly(
    first: &LagEstimate,
    residuals: &dyn Fn(f64) -> Vec<Vec<f64>>,
    corrections: &TurnCorrections,
    sample_time: f64,
    epsilon: f64,
) -> Result<LagEstimate, String> {
    let at_first = residuals(first.point);
    let n = at_first.len();
    if n < MIN_LAG_DOUBLETS {
        return Err(format!(
            "lag estimate: {n} three-step doublets with a kept predecessor (allowed: at \
             least {MIN_LAG_DOUBLETS})"
        ));
    }
    let entries = at_first[0].len();
    let components = entries.saturating_sub(corrections.corrections.len());
    if !(2..=5).contains(&components) || at_first.iter().any(|u| u.len() != entries) {
        return Err(format!(
            "lag estimate: doublets with {components} residuals, or differing counts \
             (allowed: 2 to 5 each, the same for every doublet)"
        ));
    }
    let corners = corrections.corners();
    // The products at the middle of each correction's range (the weights' and τ̂'s).
    let middle: Vec<f64> = (0..corrections.corrections.len())
        .map(|k| {
            let values = corners.iter().map(|c| c[k]);
            let [least, greatest] = [
                values.clone().fold(f64::INFINITY, f64::min),
                values.fold(f64::NEG_INFINITY, f64::max),
            ];
            0.5 * (least + greatest)
        })
        .collect();
    let corrected = |products: &[Vec<f64>], factors: &[f64]| -> Vec<Vec<f64>> {
        products
            .iter()
            .map(|u| {
                let mut v = u[..components].to_vec();
                for (c, f) in corrections.corrections.iter().zip(factors) {
                    v[c.component] -= f * u[c.straddle];
                }
                v
            })
            .collect()
    };
    let covariance = product_covariance(&corrected(&at_first, &middle));
    let [below, above] = [
        (first.point - SLOPE_STEP).max(0.0),
        first.point + SLOPE_STEP,
    ];
    let [low_mean, high_mean] =
        [below, above].map(|tau| product_mean(&corrected(&residuals(tau), &middle)));
    let slope = (high_mean - low_mean) / (above - below);
    let determinant = covariance.determinant();
    let weights = covariance
        .clone()
        .cholesky()
        .map(|c| c.solve(&slope))
        .filter(|w| w.iter().all(|x| x.is_finite()));
    let information = weights.as_ref().map_or(f64::NAN, |w| w.dot(&slope));
    let weights = match weights {
        Some(w) if information > 0.0 && information.is_finite() => w,
        _ => {
            return Err(format!(
                "lag estimate: the doublets' residuals carry no slope in the lag \
                 ({components} components, covariance determinant {determinant:.3e}, \
                 information {information:.3e}; allowed: both above 0)"
            ));
        }
    };
    // `(mean(qᵢ), (γ₀ + 2γ₁)/n)` of the weighted products.
    let moments = |products: &[Vec<f64>]| {
        let q: Vec<f64> = products
            .iter()
            .map(|u| u.iter().zip(weights.iter()).map(|(x, c)| x * c).sum())
            .collect();
        let count = q.len() as f64;
        let mean = q.iter().sum::<f64>() / count;
        let variance = q.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (count - 1.0);
        let next = q
            .windows(2)
            .map(|pair| (pair[0] - mean) * (pair[1] - mean))
            .sum::<f64>()
            / (count - 1.0);
        (mean, (variance + 2.0 * next) / count)
    };
    let spread = corners
        .iter()
        .map(|corner| moments(&corrected(&at_first, corner)).1)
        .fold(f64::INFINITY, f64::min);
    if spread.is_nan() || spread <= 0.0 {
        return Err(format!(
            "lag estimate: the weighted residuals' variance with their neighbours' covariance \
             is {spread:.3e} (allowed: above 0)"
        ));
    }
    // `[t_lo(τ), t_hi(τ)]`: the least and greatest weighted mean over the corners, each over
    // the largest standard error among them. Where some corner's `|t| ≤ z`, `t_lo ≤ z` and
    // `t_hi ≥ −z`; with one corner both are `t(τ)`.
    let statistics = |tau: f64| -> [f64; 2] {
        let products = residuals(tau);
        let (least, greatest, spread) = corners.iter().fold(
            (f64::INFINITY, f64::NEG_INFINITY, 0.0_f64),
            |(least, greatest, spread), corner| {
                let (mean, s) = moments(&corrected(&products, corner));
                (least.min(mean), greatest.max(mean), spread.max(s))
            },
        );
        let error = spread.max(0.0).sqrt();
        [least / error, greatest / error]
    };
    let lowest = |tau: f64| statistics(tau)[0];
    let highest = |tau: f64| statistics(tau)[1];
    let centre = |tau: f64| {
        let (mean, spread) = moments(&corrected(&residuals(tau), &middle));
        mean / spread.max(0.0).sqrt()
    };
    let limit = studentized_upper_quantile(epsilon / 2.0, n - 1);
    let [mut low, mut high] = first.interval;
    let mut widen = (high - low).max(SLOPE_STEP);
    while low > 0.0 && highest(low) > -limit {
        low = (low - widen).max(0.0);
        widen *= 2.0;
    }
    let mut widen = (high - low).max(SLOPE_STEP);
    while lowest(high) < limit {
        if high >= MAX_LAG {
            return Err(format!(
                "lag estimate: the doublets' residuals along the heading allow a lag beyond \
                 the class (allowed: the interval's upper end below τ = {MAX_LAG} s; the first \
                 step alone measured {:.4} s [{:.4}, {:.4}])",
                first.point, first.interval[0], first.interval[1]
            ));
        }
        high = (high + widen).min(MAX_LAG);
        widen *= 2.0;
    }
    let grid: Vec<(f64, [f64; 2])> = (0..JOINT_GRID)
        .map(|k| {
            let tau = low + (high - low) * k as f64 / (JOINT_GRID - 1) as f64;
            (tau, statistics(tau))
        })
        .collect();
    let Some(last_inside) = grid.iter().rposition(|&(_, [t, _])| t < limit) else {
        return Err(format!(
            "lag estimate: the doublets' residuals along the heading carry more of the bit's \
             travel than a lag leaves (t = {:.1} at τ = 0; allowed: within {limit:.1})",
            grid[0].1[0]
        ));
    };
    let lower = match grid.iter().position(|&(_, [_, t])| t > -limit) {
        Some(k) if k > 0 => crossing(&highest, [grid[k - 1].0, grid[k].0], -limit)[0],
        _ => low,
    };
    let upper = crossing(
        &lowest,
        [grid[last_inside].0, grid[last_inside + 1].0],
        limit,
    )[1];
    let point = if centre(lower) >= 0.0 {
        lower
    } else {
        let [left, right] = crossing(&centre, [lower, upper], 0.0);
        0.5 * (left + right)
    };
    Ok(LagEstimate {
        point,
        interval: [lower, upper],
        share: first_step_share(point, sample_time),
        share_interval: [
            first_step_share(upper, sample_time),
            first_step_share(lower, sample_time),
        ],
        doublets: n,
    })
}

/// The bracket `[left, right]` (s), `2⁻²⁴` of `bracket`, in which the rising `statistic`
/// crosses `level`: bisection keeping `statistic(left) < level ≤ statistic(right)`.
fn crossing(statistic: &dyn Fn(f64) -> f64, bracket: [f64; 2], level: f64) -> [f64; 2] {
    let [mut left, mut right] = bracket;
    for _ in 0..CROSSING_STEPS {
        let middle = 0.5 * (left + right);
        if statistic(middle) < level {
            left = middle;
        } else {
            right = middle;
        }
    }
    [left, right]
}

/// The mean of the doublets' products `uᵢ` (m; the turns' rad²/s), one entry per component.
fn product_mean(products: &[Vec<f64>]) -> DVector<f64> {
    let n = products.len() as f64;
    let components = products.first().map_or(0, Vec::len);
    DVector::from_fn(components, |k, _| {
        products.iter().map(|u| u[k]).sum::<f64>() / n
    })
}

/// The sample covariance of the doublets' products `uᵢ` (each component's unit squared).
fn product_covariance(products: &[Vec<f64>]) -> DMatrix<f64> {
    let mean = product_mean(products);
    let n = products.len() as f64;
    DMatrix::from_fn(mean.len(), mean.len(), |i, j| {
        products
            .iter()
            .map(|u| (u[i] - mean[i]) * (u[j] - mean[j]))
            .sum::<f64>()
            / (n - 1.0)
    })
}

#[cfg(test)]
pub(in crate::estimate) mod tests {
    use super::*;
    use crate::model::{Pose, Unicycle};
    use crate::private::DoubletInputs;
    use crate::rng::{Purpose, stream};
    use rand_distr::{Distribution, StandardNormal};

    const T: f64 = 0.2;
    const DELTA_V: f64 = 0.035;

    #[test]
    fn the_share_is_one_without_lag_and_inverts() {
        assert_eq!(first_step_share(0.0, T), 1.0);
        for tau in [0.01, 0.02, 0.05, 0.1, 0.3, 0.9] {
            let share = first_step_share(tau, T);
            assert!(share < 1.0 && share > first_step_share(MAX_LAG, T));
            assert!((lag_of_share(share, T) - tau).abs() < 1e-12, "{tau}");
        }
        assert_eq!(lag_of_share(1.2, T), 0.0);
    }

    /// The binary doublet of the tests, two bits.
    fn binary() -> Perturbation {
        Perturbation::binary(Unicycle::new(DELTA_V, 0.0), 2, None)
    }

    /// `n` doublets of a world with lag `tau`: the mid sample carries the v-bit's lagged
    /// travel, 1 mm of motion noise and 0.5 mm of sensor noise per sample, a bit-free
    /// nominal transient of up to 3 mm and the ω-bit's heading (two bits per doublet).
    pub(in crate::estimate) fn doublets(n: u32, tau: f64, seed: u64) -> Vec<DoubletSamples> {
        doublets_of(&binary(), n, tau, seed)
    }

    /// [`doublets`] carrying `perturbation`'s symbols (uniform labels on both dimensions).
    fn doublets_of(
        perturbation: &Perturbation,
        n: u32,
        tau: f64,
        seed: u64,
    ) -> Vec<DoubletSamples> {
        let mut rng = stream(seed, Purpose::Process, 0);
        let mut normal =
            || <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut rng);
        let share = first_step_share(tau, T);
        (0..n)
            .map(|j| {
                let start = Pose::new(0.3 * f64::from(j), 0.1, 0.1 * f64::from(j % 60));
                let inputs = DoubletInputs {
                    first: Unicycle::new(0.1, 0.3 * f64::from(j % 3) - 0.3),
                    second: Unicycle::new(0.1, 0.0),
                };
                let pattern = (0..perturbation.key_bits())
                    .fold(0, |pattern, i| pattern | usize::from(normal() > 0.0) << i);
                let transient = 3e-3 * (f64::from(j % 5) - 2.0) / 2.0;
                let along = perturbation.amplitude(pattern) * DELTA_V * T * share
                    + transient
                    + 1e-3 * normal();
                let sensor = |k: f64| 5e-4 * k;
                let predicted = unicycle_step(&start, &inputs.first, T);
                let middle = predicted
                    + Pose::new(
                        along * start.z.cos() + sensor(normal()),
                        along * start.z.sin() + sensor(normal()),
                        0.01 * normal(),
                    );
                let sensed_start = start + Pose::new(sensor(normal()), sensor(normal()), 0.0);
                DoubletSamples {
                    doublet: j,
                    inputs,
                    samples: [sensed_start, middle, middle],
                    pattern,
                    late: None,
                }
            })
            .collect()
    }

    /// Seeded recovery: over 200 blocks of 1,000 doublets per lag at ε_est = 0.05, the
    /// interval misses the truth at most 5 % of the time plus 3 binomial deviations
    /// (√(200·0.05·0.95) ≈ 3.1: at most 19 misses), and the point estimates' mean lies
    /// within 4 of its standard errors of the truth (the share's deviation ≈ 1.12 mm /
    /// (Δv·T·√1000) ≈ 0.005 per block, mapped through g's slope).
    #[test]
    fn the_lag_is_recovered_and_its_interval_covers_it() {
        for (i, tau) in [0.0, 0.02, 0.05, 0.1].into_iter().enumerate() {
            let mut misses = 0;
            let mut shares = Vec::new();
            for block in 0..200 {
                let seed = 1000 * i as u64 + block;
                let estimate = estimate_lag(&doublets(1000, tau, seed), &binary(), T, 0.05)
                    .expect("inside the class");
                let [low, high] = estimate.interval;
                if tau < low || tau > high {
                    misses += 1;
                }
                shares.push(estimate.share);
            }
            assert!(misses <= 19, "τ = {tau}: {misses} of 200 missed");
            let mean = shares.iter().sum::<f64>() / 200.0;
            let deviation = (shares.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / 199.0).sqrt()
                / 200_f64.sqrt();
            let truth = first_step_share(tau, T);
            assert!(
                (mean - truth).abs() < 4.0 * deviation,
                "τ = {tau}: share {mean} ± {deviation} against {truth}"
            );
        }
    }

    #[test]
    fn too_few_doublets_or_a_lag_beyond_the_class_is_refused() {
        let few = estimate_lag(&doublets(99, 0.05, 1), &binary(), T, 1e-6).unwrap_err();
        assert!(few.contains("99 doublets"), "{few}");
        let beyond = estimate_lag(&doublets(400, 3.0, 2), &binary(), T, 1e-6).unwrap_err();
        assert!(beyond.contains("beyond the class"), "{beyond}");
    }

    /// Multilevel symbols (4 and 8 levels, two dimensions, natural labeling): over 50 blocks
    /// of 1,000 doublets at ε_est = 0.05 the interval misses a 50 ms lag at most 5 % of the
    /// time plus 3 binomial deviations (√(50·0.05·0.95) ≈ 1.5: at most 7 misses), and the
    /// shares' mean lies within 4 of its standard errors of the truth — where regressing on
    /// the label's low bit alone (the binary sign) reads `E[sign·s] = 1/√5` of it at 4 levels.
    #[test]
    fn the_lag_is_recovered_from_multilevel_symbols() {
        for levels in [4_u8, 8] {
            let perturbation = Perturbation { levels, ..binary() };
            let tau = 0.05;
            let truth = first_step_share(tau, T);
            let mut misses = 0;
            let mut shares = Vec::new();
            for block in 0..50 {
                let doublets = doublets_of(&perturbation, 1000, tau, 7000 + block);
                let estimate = estimate_lag(&doublets, &perturbation, T, 0.05).expect("in class");
                let [low, high] = estimate.interval;
                misses += usize::from(tau < low || tau > high);
                shares.push(estimate.share);
            }
            let mean = shares.iter().sum::<f64>() / 50.0;
            let deviation = (shares.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / 49.0).sqrt()
                / 50_f64.sqrt();
            assert!(misses <= 7, "{levels} levels: {misses} of 50 missed");
            assert!(
                (mean - truth).abs() < 4.0 * deviation,
                "{levels} levels: share {mean} ± {deviation} against {truth}"
            );
        }
    }

    /// The three-step shape `(+1, −(1 + a), +a)` of a unit step offset (a from `prior`, s)
    /// through a lag `tau` (s): its travel along a straight heading after each step, in
    /// units of `Δv·T` (the first is `g(τ)`).
    fn shape_travel(tau: f64, prior: f64) -> [f64; 3] {
        let a = (-T / prior).exp();
        let decay = if tau > 0.0 { (-T / tau).exp() } else { 0.0 };
        let (mut speed, mut position) = (0.0, 0.0);
        [1.0, -(1.0 + a), a].map(|command: f64| {
            position += command + (speed - command) * tau / T * (1.0 - decay);
            speed = command + (speed - command) * decay;
            position
        })
    }

    /// `n` three-step doublets of a straight robot with lag `tau` (s), shaped for `prior`
    /// (s): each v-sign `s` and its residuals along the heading after each step,
    /// `z₁ = sΔvT·g(τ) + w₀ + η₁ − η₀`, `z₂ = sΔvT·m(τ) + w₀ + w₁ + η₂ − η₀` and
    /// `z₃ = sΔvT·h(τ) + w₀ + w₁ + w₂ + η₃ − η₀` (`motion` m of white motion noise per step,
    /// 0.5 mm of sensor noise per sample).
    fn shape_block(n: u32, tau: f64, prior: f64, motion: f64, seed: u64) -> Vec<(f64, [f64; 3])> {
        let mut rng = stream(seed, Purpose::Process, 0);
        let mut normal =
            || <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut rng);
        let [g, m, h] = shape_travel(tau, prior);
        (0..n)
            .map(|_| {
                let sign = if normal() > 0.0 { 1.0 } else { -1.0 };
                let [w0, w1, w2] = [0; 3].map(|_| motion * normal());
                let [e0, e1, e2, e3] = [0; 4].map(|_| 5e-4 * normal());
                let travel = sign * DELTA_V * T;
                (
                    sign,
                    [
                        travel * g + w0 + e1 - e0,
                        travel * m + w0 + w1 + e2 - e0,
                        travel * h + w0 + w1 + w2 + e3 - e0,
                    ],
                )
            })
            .collect()
    }

    /// The products `sᵢ·(z₁ᵢ(λ), z₂ᵢ(λ), z₃ᵢ(λ))` of `block` with the lagged travel through
    /// `lag` (s) subtracted; without `late`, the first step's and the end's alone.
    fn shape_products(
        block: &[(f64, [f64; 3])],
        prior: f64,
        lag: f64,
        late: bool,
    ) -> Vec<Vec<f64>> {
        let travel = shape_travel(lag, prior);
        block
            .iter()
            .map(|(s, z)| {
                (0..3)
                    .filter(|&k| late || k != 1)
                    .map(|k| s * (z[k] - s * DELTA_V * T * travel[k]))
                    .collect()
            })
            .collect()
    }

    /// Seeded coverage of the joint interval: over 200 blocks of 1,000 three-step doublets
    /// (4 mm of motion noise per step: the first step's own noise dominates) at 20, 50 and
    /// 100 ms with the prior at the lag, and 100 ms under a 50 ms prior, at ε_est = 0.05 the
    /// interval misses the truth at most 19 times (5 % plus 3 binomial deviations,
    /// √(200·0.05·0.95) ≈ 3.1), the point estimates' shares lie within 4 of their standard
    /// errors of `g(τ)`, and the interval is narrower than the first step's alone — from
    /// the first step and the end its mean width at most 0.9 of it (with white noise the end
    /// adds about half the first step's information, a width near 0.8) — and, with the
    /// sample after the second step, narrower still, by the ratio the three residuals'
    /// Fisher information predicts, `√(vᵀS⁻¹v)` of the pair over the triple (`S` their
    /// covariance under the block's noise, `v` their slope in τ): 0.504, 0.545, 0.726 and
    /// 0.787 of the pair's width, which the mean width ratio meets within 5 % (200 blocks'
    /// widths vary by a few per cent each).
    #[test]
    fn the_joint_lag_interval_covers_and_is_narrower_than_the_first_steps() {
        for (i, (tau, prior, predicted)) in [
            (0.02, 0.02, 0.504),
            (0.05, 0.05, 0.545),
            (0.1, 0.1, 0.726),
            (0.1, 0.05, 0.787),
        ]
        .into_iter()
        .enumerate()
        {
            let (mut misses, mut shares, mut widths) = ([0; 2], [Vec::new(), Vec::new()], [0.0; 3]);
            for block in 0..200 {
                let doublets = shape_block(1000, tau, prior, 4e-3, 5000 * i as u64 + block);
                let first = first_step_lag(&doublets);
                widths[0] += first.interval[1] - first.interval[0];
                for (k, late) in [false, true].into_iter().enumerate() {
                    let products = |lag: f64| shape_products(&doublets, prior, lag, late);
                    let joint =
                        estimate_lag_jointly(&first, &products, &TurnCorrections::NONE, T, 0.05)
                            .expect("class");
                    let [low, high] = joint.interval;
                    misses[k] += usize::from(tau < low || tau > high);
                    shares[k].push(joint.share);
                    widths[k + 1] += high - low;
                }
            }
            let truth = first_step_share(tau, T);
            for k in 0..2 {
                let mean = shares[k].iter().sum::<f64>() / 200.0;
                let deviation = (shares[k].iter().map(|s| (s - mean).powi(2)).sum::<f64>() / 199.0)
                    .sqrt()
                    / 200_f64.sqrt();
                eprintln!(
                    "τ {tau} prior {prior} ({} components): {} misses, share {mean:.5} ± \
                     {deviation:.5} against {truth:.5}, width {:.5} against the first step's \
                     {:.5}",
                    2 + k,
                    misses[k],
                    widths[k + 1] / 200.0,
                    widths[0] / 200.0
                );
                assert!(misses[k] <= 19, "τ = {tau}: {} of 200 missed", misses[k]);
                assert!(
                    (mean - truth).abs() < 4.0 * deviation,
                    "τ = {tau}: share {mean} ± {deviation} against {truth}"
                );
            }
            assert!(widths[1] <= 0.9 * widths[0], "τ = {tau}: widths {widths:?}");
            let ratio = widths[2] / widths[1];
            assert!(
                (ratio / predicted - 1.0).abs() < 0.05,
                "τ = {tau}: width ratio {ratio} against {predicted}"
            );
        }
    }

    /// Residuals without a slope in the lag (the end a copy of the middle, both free of it)
    /// are refused by name, not given an interval.
    #[test]
    fn residuals_without_slope_in_the_lag_are_refused() {
        let first = estimate_lag(&doublets(400, 0.05, 3), &binary(), T, 1e-6).unwrap();
        let flat = |_: f64| vec![vec![1e-3, 1e-3]; 400];
        let why = estimate_lag_jointly(&first, &flat, &TurnCorrections::NONE, T, 1e-6).unwrap_err();
        assert!(why.contains("no slope"), "{why}");
    }

    /// A first-order lag `tau` (s) over one step from wheel speed `speed` to `command`: the
    /// step's mean speed and its end speed.
    fn lag_step(command: f64, speed: f64, tau: f64) -> (f64, f64) {
        if tau <= 0.0 {
            return (command, command);
        }
        let decay = (-T / tau).exp();
        (
            command + (speed - command) * tau / T * (1.0 - decay),
            command + (speed - command) * decay,
        )
    }

    /// A block of doublets turned by a heading-feedback controller: per doublet its inputs
    /// `(ω₁, ω₂)`, the controller's gain `∂ω₁/∂θ̂` and its sensed headings at its start, after
    /// each of its steps (rad/s, rad/s per rad, rad).
    type Turning = Vec<([f64; 2], f64, [f64; 4])>;

    /// The lag from the first steps alone: `lag_of_products` of each doublet's `s·z₁/(Δv·T)`.
    fn first_step_lag(doublets: &[(f64, [f64; 3])]) -> LagEstimate {
        let first: Vec<(f64, f64)> = doublets
            .iter()
            .map(|(s, z)| (*s, s * z[0] / (DELTA_V * T)))
            .collect();
        lag_of_products(&first, T, 0.05).expect("inside the class")
    }

    /// Each doublet's shape products (`shape_products`, late ones included) followed by its
    /// turn products (`turn_products` with `kinds`).
    fn joined_products(
        doublets: &[(f64, [f64; 3])],
        turning: &Turning,
        prior: f64,
        lag: f64,
        sensor: f64,
        kinds: [bool; 3],
    ) -> Vec<Vec<f64>> {
        let turns = turn_products(turning, prior, lag, sensor, kinds);
        shape_products(doublets, prior, lag, true)
            .into_iter()
            .zip(turns)
            .map(|(mut u, turn)| {
                u.extend(turn);
                u
            })
            .collect()
    }

    /// `n` doublets' heading, turned by a controller that reads the sensed heading at each
    /// doublet's start: the first input `ω₁ = cⱼ − 0.2·sin θ̂(3j)/ξⱼ` (`cⱼ = 0.3·tanh ζ` rad/s
    /// a path's turn, ζ standard normal; `ξⱼ = 0.1 + 0.3·|tanh ζ′|` m/s a speed the gain
    /// divides by, as the tracking law's does), the second `ω₁ + 0.1·tanh ζ″`, each step
    /// through a lag `tau` (s) from the previous step's wheel speed, `motion` rad of motion
    /// noise per step, AR(1)-correlated by `rho` between steps (0: white), and `sensor` rad
    /// of sensor noise per sample.
    fn turning_block(
        n: usize,
        tau: f64,
        [motion, rho]: [f64; 2],
        sensor: f64,
        seed: u64,
    ) -> Turning {
        let mut rng = stream(seed, Purpose::Measurement, 0);
        let mut normal =
            || <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut rng);
        let (mut heading, mut speed, mut noise) = (0.0, 0.0, 0.0);
        (0..n)
            .map(|_| {
                let sensed = heading + sensor * normal();
                let turn = 0.3 * normal().tanh();
                let xi = 0.1 + 0.3 * normal().tanh().abs();
                let first = turn - 0.2 * sensed.sin() / xi;
                let gain = -0.2 * sensed.cos() / xi;
                let second = first + 0.1 * normal().tanh();
                let mut after = [sensed; 4];
                for (k, command) in [first, second, second].into_iter().enumerate() {
                    let (mean, end) = lag_step(command, speed, tau);
                    noise = rho * noise + (1.0 - rho * rho).sqrt() * motion * normal();
                    heading += T * mean + noise;
                    speed = end;
                    after[k + 1] = heading + sensor * normal();
                }
                ([first, second], gain, after)
            })
            .collect()
    }

    /// Each doublet of `block` through a lag `lag` (s), the wheels' speed carried from
    /// doublet to doublet: the wheels' turn rate at its start (rad/s) and its turn over each
    /// of its steps (rad).
    fn lagged_turns(block: &Turning, lag: f64) -> Vec<[f64; 4]> {
        let mut speed = 0.0;
        block
            .iter()
            .map(|([first, second], _, _)| {
                let mut turns = [speed, 0.0, 0.0, 0.0];
                for (k, command) in [*first, *second, *second].into_iter().enumerate() {
                    let (mean, end) = lag_step(command, speed, lag);
                    speed = end;
                    turns[k + 1] = T * mean;
                }
                turns
            })
            .collect()
    }

    /// The turns' products of `block` through a lag `lag` (s) at the prior `prior` (s): the
    /// turn over the second and third steps less its lagged mean, times its slope in τ at the
    /// prior; with `first`, also the first step's, times its weight `a = −T·g′(τ_p)·(ω_e −
    /// ω₁)` and plus `R_θ·∂a/∂θ̂` (`R_θ` the variance of `sensor` rad) where `corrected`; with
    /// `straddles`, then each product's weight times the straddle residual from the previous
    /// doublet's sample after its second step to this one's after its first (the first
    /// doublet, without a previous one, carries no turn products).
    fn turn_products(
        block: &Turning,
        prior: f64,
        lag: f64,
        sensor: f64,
        [first, corrected, straddles]: [bool; 3],
    ) -> Vec<Vec<f64>> {
        let slope_of = -T * first_step_share_slope(prior, T);
        let at = lagged_turns(block, lag);
        let [high, low] = [prior + 1e-3, prior - 1e-3].map(|l| lagged_turns(block, l));
        let entries = lagged_turns(block, prior);
        (0..block.len())
            .map(|j| {
                let (inputs, gain, [start, middle, _, end]) = &block[j];
                let [turns, entry, h, l] = [&at[j], &entries[j], &high[j], &low[j]];
                let slope = (h[2] + h[3] - l[2] - l[3]) / 2e-3;
                let weight = slope_of * (entry[0] - inputs[0]);
                let mut u = vec![slope * (end - middle - turns[2] - turns[3])];
                let mut after = vec![slope];
                if first {
                    let correction = -sensor * sensor * slope_of * gain;
                    let bias = if corrected { correction } else { 0.0 };
                    u.push(weight * (middle - start - turns[1]) + bias);
                    after.push(weight);
                }
                if straddles {
                    if j == 0 {
                        return vec![0.0; 2 * u.len()];
                    }
                    let before = &block[j - 1].2[2];
                    let straddle = middle - before - at[j - 1][3] - turns[1];
                    u.extend(after.iter().map(|a| a * straddle));
                }
                u
            })
            .collect()
    }

    /// Seeded coverage with the turns' products (the fourth component, as the three-step
    /// blocks add it): 200 blocks of 1,000 doublets at 4 mm and 4 mrad of white motion noise
    /// per step, 20 and 50 ms with the prior at the lag, the turns from a controller that reads
    /// its noisy heading at each doublet's start. The turn residual over the second and third
    /// steps, times its slope in τ at the prior, has mean 0 at the true τ whatever the
    /// controller did with the start sample (that residual's noise comes later). At ε_est =
    /// 0.05 the interval misses the truth at most 19 times (5 % plus 3 binomial deviations),
    /// the point estimates' shares lie within 4 of their standard errors of `g(τ)`, and the
    /// interval is narrower than from the v-bit's three residuals alone.
    #[test]
    fn the_turns_keep_the_joint_interval_covering_and_narrow_it() {
        for (i, tau) in [0.02, 0.05].into_iter().enumerate() {
            let (mut misses, mut shares, mut widths) = (0, Vec::new(), [0.0; 2]);
            for block in 0..200 {
                let seed = 9000 + 1000 * i as u64 + block;
                let doublets = shape_block(1000, tau, tau, 4e-3, seed);
                let turning = turning_block(1000, tau, [4e-3, 0.0], 5e-4, seed);
                let first = first_step_lag(&doublets);
                let along = |lag: f64| shape_products(&doublets, tau, lag, true);
                let with_turns =
                    |lag: f64| joined_products(&doublets, &turning, tau, lag, 5e-4, [false; 3]);
                let alone = estimate_lag_jointly(&first, &along, &TurnCorrections::NONE, T, 0.05)
                    .expect("class");
                let joint =
                    estimate_lag_jointly(&first, &with_turns, &TurnCorrections::NONE, T, 0.05)
                        .expect("class");
                let [low, high] = joint.interval;
                misses += usize::from(tau < low || tau > high);
                shares.push(joint.share);
                widths[0] += alone.interval[1] - alone.interval[0];
                widths[1] += high - low;
            }
            let truth = first_step_share(tau, T);
            let mean = shares.iter().sum::<f64>() / 200.0;
            let deviation = (shares.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / 199.0).sqrt()
                / 200_f64.sqrt();
            eprintln!(
                "τ {tau}: {misses} misses, share {mean:.5} ± {deviation:.5} against {truth:.5}, \
                 width {:.5} against the v-bit's {:.5}",
                widths[1] / 200.0,
                widths[0] / 200.0
            );
            assert!(misses <= 19, "τ = {tau}: {misses} of 200 missed");
            assert!(
                (mean - truth).abs() < 4.0 * deviation,
                "τ = {tau}: share {mean} ± {deviation} against {truth}"
            );
            assert!(widths[1] < widths[0], "τ = {tau}: widths {widths:?}");
        }
    }

    /// Seeded coverage with the first step's turn (the fifth component, as the three-step
    /// blocks add it): 200 blocks of 1,000 doublets at 4 mm and 4 mrad of white motion noise
    /// per step, 20 and 50 ms with the prior at the lag, turned by a heading-feedback
    /// controller whose gain divides by a speed, with 0.5 mrad of heading sensor noise (the
    /// grid's) and 2 mrad (its bias on the uncorrected product 16 times larger). Its weight
    /// `a` depends on the start sample the turn's residual carries as `−η₀`; with `R_θ·∂a/∂θ̂`
    /// added from the controller's gain the product has mean 0 at the true τ (Stein's
    /// identity), and consecutive doublets' products correlate through the sample they share.
    /// At ε_est = 0.05 the interval misses the truth at most 19 times of 200 (5 % plus 3
    /// binomial deviations), the point estimates' shares lie within 4 of their standard
    /// errors of `g(τ)`, and the mean interval is narrower than with the turns over the second
    /// and third steps alone.
    #[test]
    fn the_first_turn_with_the_controllers_gain_keeps_the_interval_covering() {
        for (i, (tau, sensor)) in [(0.02, 5e-4), (0.05, 5e-4), (0.05, 2e-3)]
            .into_iter()
            .enumerate()
        {
            let (mut misses, mut shares, mut widths) = ([0; 2], [Vec::new(), Vec::new()], [0.0; 2]);
            for block in 0..200 {
                let seed = 12_000 + 1000 * i as u64 + block;
                let doublets = shape_block(1000, tau, tau, 4e-3, seed);
                let turning = turning_block(1000, tau, [4e-3, 0.0], sensor, seed);
                let first = first_step_lag(&doublets);
                let products = |lag: f64, kinds: [bool; 3]| {
                    joined_products(&doublets, &turning, tau, lag, sensor, kinds)
                };
                let later = |lag: f64| products(lag, [false; 3]);
                let both = |lag: f64| products(lag, [true, true, false]);
                let uncorrected = |lag: f64| products(lag, [true, false, false]);
                let alone = estimate_lag_jointly(&first, &later, &TurnCorrections::NONE, T, 0.05)
                    .expect("class");
                widths[0] += alone.interval[1] - alone.interval[0];
                for (k, statistic) in [&both as &dyn Fn(f64) -> Vec<Vec<f64>>, &uncorrected]
                    .into_iter()
                    .enumerate()
                {
                    let joint =
                        estimate_lag_jointly(&first, statistic, &TurnCorrections::NONE, T, 0.05)
                            .expect("class");
                    let [low, high] = joint.interval;
                    misses[k] += usize::from(tau < low || tau > high);
                    shares[k].push(joint.share);
                    if k == 0 {
                        widths[1] += high - low;
                    }
                }
            }
            let truth = first_step_share(tau, T);
            let [mean, uncorrected] = [0, 1].map(|k| shares[k].iter().sum::<f64>() / 200.0);
            let deviation = (shares[0].iter().map(|s| (s - mean).powi(2)).sum::<f64>() / 199.0)
                .sqrt()
                / 200_f64.sqrt();
            eprintln!(
                "τ {tau} sensor {sensor}: {} misses, share {mean:.5} ± {deviation:.5} against \
                 {truth:.5} (uncorrected: {} misses, share {uncorrected:.5}), width {:.5} \
                 against the later turns' {:.5}",
                misses[0],
                misses[1],
                widths[1] / 200.0,
                widths[0] / 200.0
            );
            assert!(misses[0] <= 19, "τ = {tau}: {} of 200 missed", misses[0]);
            assert!(
                (mean - truth).abs() < 4.0 * deviation,
                "τ = {tau}: share {mean} ± {deviation} against {truth}"
            );
            assert!(widths[1] < widths[0], "τ = {tau}: widths {widths:?}");
        }
    }

    /// Seeded coverage under AR(1) motion noise (50 ms, 4 mm and 4 mrad per step, 0.5 mrad
    /// of heading sensor noise, ρ = 0.5 and 0.9; 200 blocks of 1,000 doublets at ε_est =
    /// 0.05). The turns' weights are fixed at the doublet's start sample, which the step
    /// before moved, and their residuals' steps follow that step by ρ: with the products of
    /// the v-bit's three residuals and both turns taken as of mean 0, the point estimates'
    /// mean share lies more than 4 of its standard errors from `g(τ)` at ρ = 0.9 (the bias,
    /// shown; at this block size it is about half the interval's half-width, so the misses
    /// stay few); corrected through the straddle residual over ρ's interval (the truth ±
    /// 0.02, standing for the region's) the interval misses the truth at most 19 times (5 %
    /// plus 3 binomial deviations) and the shares lie within 4 of their standard errors of
    /// `g(τ)`.
    #[test]
    fn the_turns_under_correlated_noise_are_corrected_over_rhos_interval() {
        let tau = 0.05;
        let corrections = [
            TurnCorrection {
                component: 3,
                straddle: 5,
                factor: later_turn_factor,
            },
            TurnCorrection {
                component: 4,
                straddle: 6,
                factor: first_turn_factor,
            },
        ];
        for (i, rho) in [0.5, 0.9].into_iter().enumerate() {
            let over = TurnCorrections {
                corrections: &corrections,
                correlation: [rho - 0.02, rho + 0.02],
            };
            let (mut misses, mut shares, mut widths) = ([0; 2], [Vec::new(), Vec::new()], [0.0; 2]);
            for block in 0..200 {
                let seed = 16_000 + 1000 * i as u64 + block;
                let doublets = shape_block(1000, tau, tau, 4e-3, seed);
                let turning = turning_block(1000, tau, [4e-3, rho], 5e-4, seed);
                let first = first_step_lag(&doublets);
                let products = |lag: f64, straddles: bool| {
                    let kinds = [true, true, straddles];
                    joined_products(&doublets, &turning, tau, lag, 5e-4, kinds)
                };
                let plain = |lag: f64| products(lag, false);
                let straddled = |lag: f64| products(lag, true);
                let estimates = [
                    estimate_lag_jointly(&first, &plain, &TurnCorrections::NONE, T, 0.05),
                    estimate_lag_jointly(&first, &straddled, &over, T, 0.05),
                ];
                for (k, estimate) in estimates.into_iter().enumerate() {
                    let [low, high] = estimate.expect("inside the class").interval;
                    misses[k] += usize::from(tau < low || tau > high);
                    widths[k] += high - low;
                    shares[k].push(first_step_share(0.5 * (low + high), T));
                }
            }
            let truth = first_step_share(tau, T);
            let [(plain, plain_deviation), (mean, deviation)] = [0, 1].map(|k| {
                let mean = shares[k].iter().sum::<f64>() / 200.0;
                let variance = shares[k].iter().map(|s| (s - mean).powi(2)).sum::<f64>() / 199.0;
                (mean, (variance / 200.0).sqrt())
            });
            eprintln!(
                "ρ {rho}: uncorrected {} misses (width {:.5}, share {plain:.5} ± \
                 {plain_deviation:.5}), corrected {} misses (width {:.5}, share {mean:.5} ± \
                 {deviation:.5}) against {truth:.5}",
                misses[0],
                widths[0] / 200.0,
                misses[1],
                widths[1] / 200.0
            );
            if rho == 0.9 {
                assert!(
                    (plain - truth).abs() > 4.0 * plain_deviation,
                    "ρ = {rho}: the bias not shown, share {plain} ± {plain_deviation}"
                );
            }
            assert!(misses[1] <= 19, "ρ = {rho}: {} of 200 missed", misses[1]);
            assert!(
                (mean - truth).abs() < 4.0 * deviation,
                "ρ = {rho}: share {mean} ± {deviation} against {truth}"
            );
        }
    }
}
