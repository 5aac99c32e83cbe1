//! The motion noise's AR(1) correlation ρ between steps, its (1 − ε) interval, and the
//! whiteness test of the AR(1) model's innovations (docs/estimation.md, "Correlated motion
//! noise").
//!
//! **Moments.** With the sensor's part subtracted, a doublet's residual `z_j` holds the motion
//! noise of its two steps. Under AR(1) motion noise of stationary covariance `Q` and lag-one
//! correlation ρ (`w_{k+1} = ρw_k + √(1−ρ²)e_k`), per axis and with the maps at the identity
//! (they differ from it by `T·v` and `T·ω`):
//!
//! - `b = E[z_j²] − N_j = 2(1 + ρ)Q` (the motion part of the variance),
//! - `a = E[z_j z_{j+1}] − E_s = ρ(1 + ρ)²Q` (the motion part of the lag-one product; `E_s`
//!   the shared boundary sample's `−C₀,j R C₁,j+1ᵀ`),
//! - `E[z_j z_{j+2}] = ρ²·a` (two doublets apart the sensor shares nothing).
//!
//! So `a / b = g(ρ) = ρ(1 + ρ)/2`, increasing on `ρ ∈ [−½, 1)` from −⅛ to 1. Below −½ the
//! doublet's two steps cancel and `g` turns back: the two-step residual cannot tell such
//! correlation from weaker one, so the class this estimator covers is `ρ ∈ [−½, 1)`.
//!
//! **Estimate.** Per axis `r_k = Σa / Σb` over the pairs of consecutive doublets; the axes
//! pooled with weights `(b_k / (b_k + N_k))²` (an axis whose motion noise is buried under
//! the sensor's says little), `ρ̂ = g⁻¹(r̂) = (√(1 + 8r̂) − 1)/2`.
//!
//! **Interval.** The pairs cut into contiguous batches (the AR(1) memory decays by ρ² per
//! doublet, far within a batch); the pooled ratio's linearised batch terms
//! `u = Σ_k w_k (ā_k − r_k b̄_k)/b_k` give its standard error `s/√B`. With `s²` bounded
//! above by its χ²_{B−1} lower quantile at ε/2 (Wilson–Hilferty) and the normal quantile at ε/4
//! each side, `r ∈ r̂ ± z·σ_up` except with probability ε (asymptotically: the central limit
//! over batches); `g` is monotone on the class, so `ρ ∈ [g⁻¹(r_lo), g⁻¹(r_hi)]`.
//!
//! **Whiteness of the innovations.** Once ρ is fitted from the lag-one products, the lag-two
//! products test the model: per axis `T_k = Σ(z_j z_{j+2} − ρ̂²ā_k) / √(F·Σ(z_j z_{j+2})²)`
//! is ≈ N(0, 1) under AR(1), `F` the overlap's variance inflation below; refused beyond
//! `z(ε/6)` on any axis.
//!
//! **Three steps** (`private.prior_lag`): with `L` steps per doublet the same moments are
//! `b = b_L(ρ)·Q`, `b_L = L + 2Σ_{k<L}(L − k)ρ^k`, and `a = ρ·S_L(ρ)²·Q`, `S_L = Σ_{m<L} ρ^m`,
//! so `g_L(ρ) = ρS_L²/b_L` (`g_2` is the `g` above; `g_3` rises from −0.1875 at ρ = −½ to
//! 1, inverted by bisection on the same class), and two doublets apart `ρ^L·a`.
//!
//! **One step** (a two-step doublet split at its middle sample, or a three-step one at its
//! samples): `L = 1`, `g_1(ρ) = ρ`, each residual one step's motion `Q` against two samples'
//! noise, neighbours sharing a sample (`E_s`, −R per position axis). A two-step block takes ρ
//! from its one-step residuals twice ([`estimate_correlation_split`]): their lag-one ratio,
//! and the steps joined in pairs at every step (`g_2` over overlapping pairs), each at ε/2,
//! the interval the two intervals' intersection.
//!
//! **Under slip.** Per-wheel slip is independent between steps: it adds `σ²·Mᵢ` to each
//! residual's variance and nothing to the lag-one products, so with the slip in `b` the
//! ratios lean towards 0. Where the block measures slip ([`SlipShare`]) each pair's `b` is
//! taken with `σ²·M̄` moved to the noise beside it (`N`, in the weights too): `ρ̂` and the
//! whiteness test at σ̂², the interval a bound on the intervals at every σ² of σ²'s interval
//! (and every j² of the jitter's, jointly: `b` and `N` are affine in both, `b + N` moves with
//! neither; [`ratio_interval_over`]). `motion_noise` takes the two intervals jointly.
//!
//! **Dependence.** Residuals `d` doublets apart correlate by at most
//! `r_d = |ρ|^(2d−1)(1 + |ρ|)/2` (`d ≥ 1`) per axis from the motion, plus the sensor's MA(1)
//! `≤ ½` at `d = 1`. A sum of squares (or products) of such a series has its variance inflated
//! by at most `F = 1 + 2Σ_d r_d²` over independent terms; `F` (at least 1.5, the sensor's
//! MA(1) term) sizes the Wishart region's effective count and the other tests' variances.

use super::normal_tail::normal_upper_quantile;
use super::residual::DoubletResidual;
use nalgebra::Matrix3;

/// The lowest ρ the two-step residual identifies (where `g(ρ) = ρ(1 + ρ)/2` turns back).
pub const LOWEST_CORRELATION: f64 = -0.5;

/// The highest ρ the region may reach: at ρ → 1 the noise no longer varies within a doublet
/// and Eve's modelled view has no bound.
pub const HIGHEST_CORRELATION: f64 = 0.999;

/// Least pairs of consecutive doublets per batch of the interval's standard error.
pub const MIN_PAIRS_PER_BATCH: usize = 25;

/// Batches the interval's standard error is computed from, at most.
pub const MAX_BATCHES: usize = 400;

/// What the controller measured of the motion noise's correlation between steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Correlation {
    /// `ρ̂`: the point estimate.
    pub point: f64,
    /// `[ρ_lo, ρ_hi]`: the (1 − ε) interval, within `[LOWEST_CORRELATION, HIGHEST_CORRELATION]`.
    pub interval: [f64; 2],
}

/// Why the correlation could not be estimated or its model does not fit, named.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CorrelationDeparture {
    /// The pooled ratio `r̂ = a/b` below `g(−½) = −⅛`: correlation the class does not cover.
    OutsideClass {
        /// The pooled ratio `r̂`.
        ratio: f64,
    },
    /// No axis keeps motion variance once the slip's and the timing jitter's shares are taken
    /// out (at some σ² or j² of their intervals): the ratio has nothing to weigh.
    NoMotionVariance {
        /// The motion variance `b_k` left per axis at the point examined where its largest is
        /// least (m², m², rad²).
        motion_variance: [f64; 3],
    },
    /// Too few pairs of consecutive doublets for the interval's batches.
    TooFewPairs {
        /// Pairs found.
        have: usize,
    },
    /// The two statistics of the one-step residuals (the lag-one ratio and the joined
    /// pairs' ratio) give disjoint intervals: one of them fails, which the model gives
    /// probability at most ε.
    Disjoint {
        /// The lag-one ratio's interval `[ρ_lo, ρ_hi]` at ε/2.
        lag_one: [f64; 2],
        /// The joined pairs' interval at ε/2.
        joined: [f64; 2],
    },
    /// The lag-two products depart from the AR(1) prediction on an axis.
    NotAr1 {
        /// Axis index (along-track, lateral, heading).
        axis: usize,
        /// The standardised statistic.
        statistic: f64,
        /// Its allowed magnitude.
        limit: f64,
    },
}

/// `g(ρ) = ρ(1 + ρ)/2`: the ratio of the lag-one motion product to the motion variance.
#[must_use]
pub fn ratio_of(rho: f64) -> f64 {
    0.5 * rho * (1.0 + rho)
}

/// `g⁻¹(r) = (√(1 + 8r) − 1)/2` on the class's branch, clamped to the class's range.
#[must_use]
pub fn correlation_of(ratio: f64) -> f64 {
    (0.5 * ((1.0 + 8.0 * ratio).max(0.0).sqrt() - 1.0))
        .clamp(LOWEST_CORRELATION, HIGHEST_CORRELATION)
}

/// `g_L(ρ) = ρ·S_L(ρ)²/b_L(ρ)` for doublets of `steps` steps (the module's doc; [`ratio_of`]
/// with two).
#[must_use]
pub fn ratio_for(rho: f64, steps: u32) -> f64 {
    if steps == 2 {
        return ratio_of(rho);
    }
    let l = steps as i32;
    let sum: f64 = (0..l).map(|m| rho.powi(m)).sum();
    let variance = f64::from(l) + 2.0 * (1..l).map(|k| f64::from(l - k) * rho.powi(k)).sum::<f64>();
    rho * sum * sum / variance
}

/// `g_L⁻¹(r)` on the class `[LOWEST_CORRELATION, HIGHEST_CORRELATION]`, clamped to it
/// ([`correlation_of`] with two steps; by bisection otherwise, `g_L` rising on the class).
#[must_use]
pub fn correlation_for(ratio: f64, steps: u32) -> f64 {
    if steps == 2 {
        return correlation_of(ratio);
    }
    let (mut low, mut high) = (LOWEST_CORRELATION, HIGHEST_CORRELATION);
    if ratio <= ratio_for(low, steps) {
        return low;
    }
    if ratio >= ratio_for(high, steps) {
        return high;
    }
    for _ in 0..64 {
        let middle = 0.5 * (low + high);
        if ratio_for(middle, steps) < ratio {
            low = middle;
        } else {
            high = middle;
        }
    }
    0.5 * (low + high)
}

/// `|r_1|` at `|ρ| ≤ rho` for `steps` steps: the larger of `|g_L(±|ρ|)|`.
fn neighbour_correlation(rho: f64, steps: u32) -> f64 {
    ratio_for(rho, steps)
        .abs()
        .max(ratio_for(-rho, steps).abs())
}

/// [`variance_inflation`] for doublets of `steps` steps: `r_d = |ρ|^(L(d−1))·|r_1|`, so
/// `F = max(1.5, 1 + 2r_1²/(1 − ρ^(2L)))`.
#[must_use]
pub fn variance_inflation_for(rho: f64, steps: u32) -> f64 {
    if steps == 2 {
        return variance_inflation(rho);
    }
    let rho = rho.abs().min(HIGHEST_CORRELATION);
    let first = neighbour_correlation(rho, steps);
    (1.0 + 2.0 * first * first / (1.0 - rho.powi(2 * steps as i32))).max(1.5)
}

/// [`parity_inflation`] for doublets of `steps` steps: `1 + 2r_1²ρ^(2L)/(1 − ρ^(4L))`.
#[must_use]
pub fn parity_inflation_for(rho: f64, steps: u32) -> f64 {
    if steps == 2 {
        return parity_inflation(rho);
    }
    let rho = rho.abs().min(HIGHEST_CORRELATION);
    let first = neighbour_correlation(rho, steps);
    let l = steps as i32;
    1.0 + 2.0 * first * first * rho.powi(2 * l) / (1.0 - rho.powi(4 * l))
}

/// `F = max(1.5, 1 + 2Σ_{d≥1} r_d²)`, `r_d = |ρ|^(2d−1)(1 + |ρ|)/2`: the variance inflation a
/// sum of squares (or products) of the residuals suffers from their dependence at `|ρ| ≤ rho`.
#[must_use]
pub fn variance_inflation(rho: f64) -> f64 {
    let rho = rho.abs().min(HIGHEST_CORRELATION);
    let half = 0.5 * (1.0 + rho);
    // Σ_d ρ^(2(2d−1)) = ρ²/(1 − ρ⁴).
    let sum = half * half * rho * rho / (1.0 - rho.powi(4));
    (1.0 + 2.0 * sum).max(1.5)
}

/// `1 + 2Σ_{k≥1} r_{2k}²` at `|ρ| ≤ rho`: the variance inflation within one parity half
/// (residuals two apart), `1 + 2·((1 + ρ)/2)²·ρ⁶/(1 − ρ⁸)`; 1 for white noise, whose halves
/// are independent.
#[must_use]
pub fn parity_inflation(rho: f64) -> f64 {
    let rho = rho.abs().min(HIGHEST_CORRELATION);
    let half = 0.5 * (1.0 + rho);
    1.0 + 2.0 * half * half * rho.powi(6) / (1.0 - rho.powi(8))
}

/// One pair's motion products per axis: `[a_k, b_k, N_k, M_k]` — the lag-one product with
/// the shared sample's expectation removed, the mean motion variance of the two (with the
/// slip's, which `without_slip` takes out), their mean sensor variance, and their mean
/// slip map (the slip's variance per unit σ²).
type PairTerms = [[f64; 4]; 3];

/// [`PairTerms`] of a pair of residuals.
fn pair_terms(
    first: &DoubletResidual,
    second: &DoubletResidual,
    sensor: &Matrix3<f64>,
) -> PairTerms {
    let shared = first.shared_sensor_product(second, sensor);
    let [n1, n2] = [first, second].map(|r| r.sensor_part(sensor));
    std::array::from_fn(|k| {
        [
            first.value[k] * second.value[k] - shared[(k, k)],
            0.5 * (first.value[k].powi(2) - n1[(k, k)] + second.value[k].powi(2) - n2[(k, k)]),
            0.5 * (n1[(k, k)] + n2[(k, k)]),
            0.5 * (first.slip_map[(k, k)] + second.slip_map[(k, k)]),
        ]
    })
}

/// `[a_k, b_k − σ²·M_k, N_k + σ²·M_k]`: a pair's terms with the slip's share of the motion
/// variance at slip variance `slip_variance` moved to the noise beside it (slip is
/// independent between steps, so it adds to each residual's variance and nothing to the
/// lag-one product; like the sensor's noise it lowers the axis's weight).
fn without_slip(terms: &PairTerms, slip_variance: f64) -> [[f64; 3]; 3] {
    terms.map(|[a, b, n, m]| [a, b - slip_variance * m, n + slip_variance * m])
}

/// The pairs `(j, j+1)` and `(j, j+2)` of doublets within the residuals' sessions (the
/// indices run on where a session ends, so a pair must be consecutive in the list too).
fn pairs(
    residuals: &[DoubletResidual],
    gap: u32,
) -> impl Iterator<Item = (&DoubletResidual, &DoubletResidual)> {
    let gap_usize = gap as usize;
    residuals
        .iter()
        .zip(residuals.iter().skip(gap_usize))
        .enumerate()
        .filter(move |&(i, (a, b))| {
            b.doublet == a.doublet + gap
                && residuals[i..=i + gap_usize]
                    .windows(2)
                    .all(|w| w[1].doublet == w[0].doublet + 1)
        })
        .map(|(_, pair)| pair)
}

/// The per-wheel slip's variance σ² the correlation's statistics take out of the residuals'
/// motion variance: its point, at which `ρ̂` and the whiteness test are taken, and its
/// interval, at every σ² of which `ρ`'s interval bounds the statistic's
/// ([`ratio_interval_over`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlipShare {
    /// σ̂² (a fraction of each wheel's travel, squared).
    pub point: f64,
    /// `[σ²_lo, σ²_hi]`.
    pub interval: [f64; 2],
}

impl SlipShare {
    /// No slip: the statistics as without a slip model.
    pub const NONE: Self = Self {
        point: 0.0,
        interval: [0.0, 0.0],
    };

    /// σ² at `point` alone.
    #[must_use]
    pub fn at(point: f64) -> Self {
        Self {
            point,
            interval: [point, point],
        }
    }
}

/// `ρ̂` and its (1 − `epsilon`) interval from `residuals` (each formed with the reconciled
/// bits) and the sensor's stated covariance `sensor`, the slip's share `slip` of their
/// variance taken out, and the whiteness test of the AR(1) model's innovations at level
/// `epsilon`. Where the residuals' sensor part holds a timing jitter j²
/// ([`DoubletResidual::jitter_variance`], the upper end of its interval: a three-step
/// block's one-step residuals), the interval bounds the statistic's at every j² from 0 to
/// that ([`ratio_interval_over`], [`over_the_jitter`]), as [`estimate_correlation_split`]'s
/// does.
///
/// # Errors
/// [`CorrelationDeparture`] naming what falls outside the class.
pub fn estimate_correlation(
    residuals: &[DoubletResidual],
    sensor: &Matrix3<f64>,
    epsilon: f64,
    slip: SlipShare,
) -> Result<Correlation, CorrelationDeparture> {
    let timed = correlation_over(residuals, sensor, epsilon, 1, slip)?;
    if !residuals.iter().any(|r| r.jitter_variance > 0.0) {
        return Ok(timed);
    }
    let untimed: Vec<DoubletResidual> = residuals.iter().map(|r| r.with_jitter(0.0)).collect();
    let other = correlation_over(&untimed, sensor, epsilon, 1, slip)?;
    Ok(over_the_jitter(timed, &other))
}

/// A statistic's interval over the timing jitter's `[0, j²_hi]`: the hull of its intervals
/// with the residuals carrying the upper end (`timed`, whose point it keeps; its interval
/// already bounds every j² of the range, [`ratio_interval_over`]) and at 0 (`untimed`,
/// whose whiteness test and class check are the block's too).
fn over_the_jitter(timed: Correlation, untimed: &Correlation) -> Correlation {
    Correlation {
        point: timed.point,
        interval: [
            timed.interval[0].min(untimed.interval[0]),
            timed.interval[1].max(untimed.interval[1]),
        ],
    }
}

/// The pooled ratio `r̂` of `terms` (slip taken out) over `batches` batches, and its
/// (1 − `epsilon`) interval `r̂ ± z(ε/4)·σ_up`, for doublets of `steps` steps.
fn ratio_interval(
    terms: &[[[f64; 3]; 3]],
    batches: usize,
    steps: u32,
    epsilon: f64,
) -> Result<[f64; 3], CorrelationDeparture> {
    let n = terms.len() as f64;
    let total = |k: usize, which: usize| terms.iter().map(|t| t[k][which]).sum::<f64>() / n;
    let [a, b, noise] = [0, 1, 2].map(|which| [0, 1, 2].map(|k| total(k, which)));
    // Weights (b/(b + N))², normalised (N the sensor's noise and the slip's taken out of b);
    // an axis without motion variance weighs nothing.
    let raw = [0, 1, 2].map(|k| {
        let signal = b[k].max(0.0);
        let fraction = signal / (signal + noise[k]);
        if fraction.is_finite() {
            fraction * fraction
        } else {
            0.0
        }
    });
    let weight_sum: f64 = raw.iter().sum();
    if weight_sum <= 0.0 {
        return Err(CorrelationDeparture::NoMotionVariance { motion_variance: b });
    }
    let weights = raw.map(|w| w / weight_sum);
    let axis_ratio = |k: usize| if weights[k] > 0.0 { a[k] / b[k] } else { 0.0 };
    let ratio: f64 = (0..3).map(|k| weights[k] * axis_ratio(k)).sum();
    if ratio < ratio_for(LOWEST_CORRELATION, steps) {
        return Err(CorrelationDeparture::OutsideClass { ratio });
    }
    // Batch terms u = Σ_k w_k (ā_k − r_k b̄_k)/b_k.
    let per_batch = terms.len() / batches;
    let u: Vec<f64> = (0..batches)
        .map(|i| {
            let chunk = &terms[i * per_batch..(i + 1) * per_batch];
            let m = chunk.len() as f64;
            (0..3)
                .filter(|&k| weights[k] > 0.0)
                .map(|k| {
                    let (sa, sb) = chunk
                        .iter()
                        .fold((0.0, 0.0), |(x, y), t| (x + t[k][0], y + t[k][1]));
                    weights[k] * (sa / m - axis_ratio(k) * sb / m) / b[k]
                })
                .sum()
        })
        .collect();
    let mean = u.iter().sum::<f64>() / batches as f64;
    let dof = (batches - 1) as f64;
    let variance = u.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / dof;
    let [lower_quantile, z] = interval_quantiles(batches, epsilon);
    let sigma_up = (variance / lower_quantile / batches as f64).sqrt();
    Ok([ratio, ratio - z * sigma_up, ratio + z * sigma_up])
}

/// `[q, z]` of [`ratio_interval`] over `batches` batches at level `epsilon`: `q` the
/// χ²_{B−1}/(B−1) lower quantile at ε/2 (Wilson–Hilferty) that bounds `s²` above by
/// `s²/q`, and `z` the normal quantile at ε/4.
fn interval_quantiles(batches: usize, epsilon: f64) -> [f64; 2] {
    let spread = 2.0 / (9.0 * (batches - 1) as f64);
    let lower_quantile = (1.0 - spread - normal_upper_quantile(epsilon / 2.0) * spread.sqrt())
        .max(1e-3)
        .powi(3);
    [lower_quantile, normal_upper_quantile(epsilon / 4.0)]
}

/// Pieces each side of the rectangle of slip and timing jitter `[σ²_lo, σ²_hi] × [0, j²_hi]`
/// is cut into for [`ratio_interval_over`] (one where a side is a point).
const PIECES: usize = 16;

/// Times a cell that an axis's zero line crosses is halved (each side that is not a point)
/// before [`ratio_interval_over`] bounds it with and without that axis.
const HALVINGS: u32 = 4;

/// The Bernstein coefficients `p(s₀)`, `2p(s_m) − (p(s₀) + p(s₁))/2`, `p(s₁)` of a quadratic
/// over a piece from its values at the piece's start, middle and end.
fn bernstein([start, middle, end]: [f64; 3]) -> [f64; 3] {
    [start, 2.0 * middle - 0.5 * (start + end), end]
}

/// `[min, max]` bounds over a cell of a polynomial of degree at most 2 in each of two
/// variables from its values `values[i][j]` on the cell's 3 × 3 grid (the first variable's
/// start, middle and end by the second's): the range of its tensor-product Bernstein
/// coefficients ([`bernstein`] along each variable), which the polynomial, their convex
/// combination (weights `B_i(x)·B_j(y) ≥ 0` summing to 1), never leaves.
fn biquadratic_range(values: [[f64; 3]; 3]) -> [f64; 2] {
    let rows = values.map(bernstein);
    [0, 1, 2]
        .map(|j| bernstein(rows.map(|row| row[j])))
        .as_flattened()
        .iter()
        .fold([f64::INFINITY, f64::NEG_INFINITY], |[low, high], &x| {
            [low.min(x), high.max(x)]
        })
}

/// A value at each point of a cell's 3 × 3 grid ([`biquadratic_range`]).
type OnCell<T> = [[T; 3]; 3];

/// Per axis `[a_k, b_k, N_k, M_k]` averaged over `terms`.
fn mean_terms(terms: &[PairTerms]) -> PairTerms {
    let m = terms.len() as f64;
    std::array::from_fn(|k| std::array::from_fn(|w| terms.iter().map(|t| t[k][w]).sum::<f64>() / m))
}

/// Bounds on [`ratio_interval`]'s interval `[r − zσ_up, r + zσ_up]` at every slip variance
/// σ² of `slip` `[σ²_lo, σ²_hi]` and, where `untimed` holds the pairs' terms without the
/// timing jitter whose upper end j²_hi `timed` carries, every j² of `[0, j²_hi]` jointly.
/// Each pair's `a_k` and `N_k` are affine in j² and (slip moved to the noise,
/// [`without_slip`]) `b_k − σ²M_k` and `N_k + σ²M_k` affine in (σ², j²) jointly — `M_k` does
/// not depend on j² — while `c_k = b_k + N_k` moves with neither. With the axis weights
/// `(b_k/c_k)²/D`, `D = Σ_k b_k²/c_k²` (the axes with `b_k > 0`):
///
/// `r = P/D`, `P = Σ_k a_k b_k/c_k²`; each batch's term `u_i = E_i/D`,
/// `E_i = Σ_k (ā_ik b_k − a_k b̄_ik)/c_k²`; so `r ± zσ_up = (P ± zκ√W)/D`,
/// `W = Σ_i (E_i − Ē)²`, `κ² = 1/((B − 1)·q·B)` —
///
/// `P`, `D` and each `E_i − Ē` polynomials of total degree 2 in (σ², j²) (sums of products
/// of two affine terms; `a_k b_k` holds a σ²·j² term), so of degree at most 2 in each, a
/// ratio of which is neither monotone nor convex in general. On each cell of a
/// [`PIECES`] × [`PIECES`] grid each lies within its tensor-product Bernstein range
/// ([`biquadratic_range`]), so there `r + zσ_up ≤ (P_max + zκ√W_max)/D` at `D_min` (the
/// numerator at least 0; no bound where `D_min ≤ 0`) or `D_max`, `W_max = Σ_i max|E_i − Ē|²`,
/// and the lower end alike. An axis whose `b_k` (affine: its extremes at the cell's corners)
/// changes sign within a cell weighs there on one side of its zero line and not on the
/// other: such a cell is halved [`HALVINGS`] times, then its bound is the hull of the bounds
/// with and without the axis, each a bound over the whole cell of the ratio its axes give.
/// So the bound holds at every (σ², j²) of the rectangle, not only at its corners.
///
/// # Errors
/// [`CorrelationDeparture::NoMotionVariance`] where a cell may hold a point with no axis of
/// motion variance (named: the corner whose largest `b_k` is least), the statistic undefined.
fn ratio_interval_over(
    timed: &[PairTerms],
    untimed: Option<&[PairTerms]>,
    slip: [f64; 2],
    batches: usize,
    epsilon: f64,
) -> Result<[f64; 2], CorrelationDeparture> {
    // Means per axis of [a, b, N, M] over the pairs and over each batch, at j² = 0 and j²_hi.
    let ends = [untimed.unwrap_or(timed), timed];
    let per_batch = timed.len() / batches;
    let totals = ends.map(mean_terms);
    let batch_means: Vec<[PairTerms; 2]> = (0..batches)
        .map(|i| ends.map(|terms| mean_terms(&terms[i * per_batch..(i + 1) * per_batch])))
        .collect();
    // The terms at (u, s) of the unit square: σ² = σ²_lo + u·(σ²_hi − σ²_lo), j² = s·j²_hi.
    let at = |means: &[PairTerms; 2], [u, s]: [f64; 2]| -> [[f64; 3]; 3] {
        let mixed: PairTerms = std::array::from_fn(|k| {
            std::array::from_fn(|w| (1.0 - s) * means[0][k][w] + s * means[1][k][w])
        });
        without_slip(&mixed, (1.0 - u) * slip[0] + u * slip[1])
    };
    let c = [0, 1, 2].map(|k| totals[1][k][1] + totals[1][k][2]);
    let cuts =
        |pieces: usize| -> Vec<f64> { (0..=pieces).map(|i| i as f64 / pieces as f64).collect() };
    let slip_cuts = cuts(if slip[0] < slip[1] { PIECES } else { 1 });
    let jitter_cuts = cuts(if untimed.is_some() { PIECES } else { 1 });
    let [lower_quantile, z] = interval_quantiles(batches, epsilon);
    let scale = z * (1.0 / ((batches - 1) as f64 * lower_quantile * batches as f64)).sqrt();
    let mut cells: Vec<([f64; 2], [f64; 2], u32)> = slip_cuts
        .windows(2)
        .flat_map(|u| {
            jitter_cuts
                .windows(2)
                .map(move |s| ([u[0], u[1]], [s[0], s[1]], 0))
        })
        .collect();
    let mut bounds = [f64::INFINITY, f64::NEG_INFINITY];
    while let Some((u, s, halvings)) = cells.pop() {
        let three = |[start, end]: [f64; 2]| [start, 0.5 * (start + end), end];
        let points: OnCell<[f64; 2]> = three(u).map(|u| three(s).map(|s| [u, s]));
        let total = points.map(|row| row.map(|p| at(&totals, p)));
        let corners = [total[0][0], total[0][2], total[2][0], total[2][2]];
        let positive = |k: usize| corners.iter().filter(|t| t[k][1] > 0.0).count();
        let [sure, unsure] = [4..=4, 1..=3].map(|count| {
            (0..3)
                .filter(|&k| c[k] > 0.0 && count.contains(&positive(k)))
                .collect::<Vec<usize>>()
        });
        if !unsure.is_empty() && halvings < HALVINGS {
            // Halve the cell where an axis's zero line crosses it.
            let halves = |[start, end]: [f64; 2]| {
                let middle = 0.5 * (start + end);
                if start < end {
                    vec![[start, middle], [middle, end]]
                } else {
                    vec![[start, end]]
                }
            };
            for u in halves(u) {
                cells.extend(halves(s).into_iter().map(|s| (u, s, halvings + 1)));
            }
            continue;
        }
        let batch: Vec<OnCell<[[f64; 3]; 3]>> = batch_means
            .iter()
            .map(|means| points.map(|row| row.map(|p| at(means, p))))
            .collect();
        for choice in 0..1_usize << unsure.len() {
            let chosen = unsure
                .iter()
                .enumerate()
                .filter(|&(i, _)| choice >> i & 1 == 1)
                .map(|(_, &k)| k);
            let used: Vec<usize> = sure.iter().copied().chain(chosen).collect();
            if used.is_empty() {
                let least = corners
                    .iter()
                    .min_by(|x, y| {
                        let largest = |t: &[[f64; 3]; 3]| t[0][1].max(t[1][1]).max(t[2][1]);
                        largest(x).total_cmp(&largest(y))
                    })
                    .map_or([0.0; 3], |t| t.map(|axis| axis[1]));
                return Err(CorrelationDeparture::NoMotionVariance {
                    motion_variance: least,
                });
            }
            let [low, high] = cell_bound(&used, c, &total, &batch, scale);
            bounds = [bounds[0].min(low), bounds[1].max(high)];
        }
    }
    Ok(bounds)
}

/// [`ratio_interval_over`]'s bound on one cell whose grid holds the terms `[a_k, b_k, N_k]`
/// over all pairs (`total`) and over each batch (`batch`), the axes `used` weighing (`c_k`
/// their `b_k + N_k`), `scale` = `zκ`: `[(P_min − zκ√W_max)/D, (P_max + zκ√W_max)/D]`, each
/// at `D_min` or `D_max` as its numerator's sign asks (infinite where that is `D_min ≤ 0`).
fn cell_bound(
    used: &[usize],
    c: [f64; 3],
    total: &OnCell<[[f64; 3]; 3]>,
    batch: &[OnCell<[[f64; 3]; 3]>],
    scale: f64,
) -> [f64; 2] {
    let sum =
        |f: &dyn Fn(usize) -> f64| -> f64 { used.iter().map(|&k| f(k) / (c[k] * c[k])).sum() };
    let p = biquadratic_range(total.map(|row| row.map(|t| sum(&|k| t[k][0] * t[k][1]))));
    let d = biquadratic_range(total.map(|row| row.map(|t| sum(&|k| t[k][1] * t[k][1]))));
    let terms: Vec<OnCell<f64>> = batch
        .iter()
        .map(|m| {
            std::array::from_fn(|i| {
                std::array::from_fn(|j| {
                    let (t, m) = (total[i][j], m[i][j]);
                    sum(&|k| m[k][0] * t[k][1] - t[k][0] * m[k][1])
                })
            })
        })
        .collect();
    let count = terms.len() as f64;
    let centre: OnCell<f64> = std::array::from_fn(|i| {
        std::array::from_fn(|j| terms.iter().map(|e| e[i][j]).sum::<f64>() / count)
    });
    let w_max: f64 = terms
        .iter()
        .map(|e| {
            let deviation =
                std::array::from_fn(|i| std::array::from_fn(|j| e[i][j] - centre[i][j]));
            let [low, high] = biquadratic_range(deviation);
            low.abs().max(high.abs()).powi(2)
        })
        .sum();
    let spread = scale * w_max.sqrt();
    let divide = |numerator: f64, upper: bool| {
        let denominator = if (numerator >= 0.0) == upper {
            d[0]
        } else {
            d[1]
        };
        match (denominator > 0.0, upper) {
            (true, _) => numerator / denominator,
            (false, true) => f64::INFINITY,
            (false, false) => f64::NEG_INFINITY,
        }
    };
    [divide(p[0] - spread, false), divide(p[1] + spread, true)]
}

/// [`estimate_correlation`] over residuals that overlap by `stride − 1` of every `stride`
/// (one per step, each spanning `stride` steps: [`DoubletResidual::joined`]): the lag-one
/// pairs are `stride` apart, the lag-two ones `2·stride`, the batches at least `stride` times
/// as long, and the whiteness test's variance inflated `stride` times more (a sum over
/// `stride` interleaved phases has at most `stride²` times one phase's variance, by
/// Cauchy–Schwarz, and `stride` times its sum of squares). The slip's share `slip` is taken
/// out of each pair's motion variance: `ρ̂` at its point, `ρ`'s interval a bound on the
/// intervals at every σ² of its interval ([`ratio_interval_over`]; the lag-one and lag-two
/// products carry no slip, which is independent between steps).
fn correlation_over(
    residuals: &[DoubletResidual],
    sensor: &Matrix3<f64>,
    epsilon: f64,
    stride: u32,
    slip: SlipShare,
) -> Result<Correlation, CorrelationDeparture> {
    let (correlation, lag_one) = ratio_statistic(residuals, sensor, epsilon, stride, slip)?;
    innovations(residuals, epsilon, stride, &correlation, lag_one)?;
    Ok(correlation)
}

/// [`correlation_over`]'s ratio without the whiteness test: `ρ̂`, its interval, and the mean
/// lag-one products `ā` per axis. The interval bounds the ratio's at every σ² of the slip's
/// interval and, where the residuals carry a timing jitter j²
/// ([`DoubletResidual::jitter_variance`]), every j² from 0 to that jointly
/// ([`ratio_interval_over`]), its intervals at σ²'s ends (at that j²) included.
fn ratio_statistic(
    residuals: &[DoubletResidual],
    sensor: &Matrix3<f64>,
    epsilon: f64,
    stride: u32,
    slip: SlipShare,
) -> Result<(Correlation, [f64; 3]), CorrelationDeparture> {
    let steps = residuals.first().map_or(2, |r| r.steps);
    let terms: Vec<PairTerms> = pairs(residuals, stride)
        .map(|(a, b)| pair_terms(a, b, sensor))
        .collect();
    let batches = (terms.len() / (MIN_PAIRS_PER_BATCH * stride as usize)).min(MAX_BATCHES);
    if batches < 2 {
        return Err(CorrelationDeparture::TooFewPairs { have: terms.len() });
    }
    // Where the residuals carry a timing jitter j²_hi, the same pairs' terms at 0.
    let untimed: Option<Vec<PairTerms>> = residuals
        .first()
        .is_some_and(|r| r.jitter_variance > 0.0)
        .then(|| {
            let plain: Vec<DoubletResidual> =
                residuals.iter().map(|r| r.with_jitter(0.0)).collect();
            pairs(&plain, stride)
                .map(|(a, b)| pair_terms(a, b, sensor))
                .collect()
        });
    let at = |variance: f64| {
        let corrected: Vec<[[f64; 3]; 3]> =
            terms.iter().map(|t| without_slip(t, variance)).collect();
        ratio_interval(&corrected, batches, steps, epsilon)
    };
    let [ratio, _, _] = at(slip.point)?;
    // The intervals at σ²'s ends (j²_hi), and where σ² or j² has a range the bound over it.
    let [low_end, high_end] = slip.interval.map(at);
    let [_, mut ratio_lo, mut ratio_hi] = low_end?;
    let [_, low, high] = high_end?;
    (ratio_lo, ratio_hi) = (ratio_lo.min(low), ratio_hi.max(high));
    if slip.interval[0] < slip.interval[1] || untimed.is_some() {
        let [below, above] =
            ratio_interval_over(&terms, untimed.as_deref(), slip.interval, batches, epsilon)?;
        (ratio_lo, ratio_hi) = (ratio_lo.min(below), ratio_hi.max(above));
    }
    let n = terms.len() as f64;
    let lag_one = [0, 1, 2].map(|k| terms.iter().map(|t| t[k][0]).sum::<f64>() / n);
    let correlation = Correlation {
        point: correlation_for(ratio, steps),
        interval: [
            correlation_for(ratio_lo, steps),
            correlation_for(ratio_hi, steps),
        ],
    };
    Ok((correlation, lag_one))
}

/// The whiteness test of the AR(1) model's innovations at level `epsilon`: the lag-two
/// products (`2·stride` apart) against `ρ̂^L·ā`, `lag_one` the mean lag-one products `ā`.
fn innovations(
    residuals: &[DoubletResidual],
    epsilon: f64,
    stride: u32,
    correlation: &Correlation,
    lag_one: [f64; 3],
) -> Result<(), CorrelationDeparture> {
    let steps = residuals.first().map_or(2, |r| r.steps);
    let (point, interval) = (correlation.point, correlation.interval);
    let inflation =
        f64::from(stride) * variance_inflation_for(interval[0].abs().max(interval[1].abs()), steps);
    let decay = if steps == 2 {
        point * point
    } else {
        point.powi(steps as i32)
    };
    let limit = normal_upper_quantile(epsilon / 6.0);
    let mut sum = [0.0; 3];
    let mut squares = [0.0; 3];
    for (x, y) in pairs(residuals, 2 * stride) {
        for k in 0..3 {
            let product = x.value[k] * y.value[k];
            sum[k] += product - decay * lag_one[k];
            squares[k] += product * product;
        }
    }
    match (0..3)
        .map(|k| (k, sum[k] / (inflation * squares[k]).sqrt()))
        .find(|(_, s)| s.abs() > limit)
    {
        Some((axis, statistic)) => Err(CorrelationDeparture::NotAr1 {
            axis,
            statistic,
            limit,
        }),
        None => Ok(()),
    }
}

/// The correlation's point and interval as [`estimate_correlation`] (`split` none) or
/// [`estimate_correlation_split`] (`split` the one-step residuals) take them, without their
/// whiteness tests: what the joint region of ρ and the slip's σ² iterates on
/// (`motion_noise`), the tests made once on its last round.
///
/// # Errors
/// [`CorrelationDeparture`] naming what falls outside the class (never `NotAr1`).
pub fn correlation_untested(
    residuals: &[DoubletResidual],
    split: Option<&[DoubletResidual]>,
    sensor: &Matrix3<f64>,
    epsilon: f64,
    slip: SlipShare,
) -> Result<Correlation, CorrelationDeparture> {
    let statistic = |r: &[DoubletResidual], level: f64, stride: u32| {
        ratio_statistic(r, sensor, level, stride, slip).map(|(c, _)| c)
    };
    match split {
        Some(steps) => both_statistics(steps, |r, stride| statistic(r, epsilon / 2.0, stride)),
        None => statistic(residuals, epsilon, 1),
    }
}

/// Every two consecutive one-step residuals (indices one apart) joined into a two-step
/// residual (`DoubletResidual::joined`): the joined steps' statistic reads these.
fn joined_steps(steps: &[DoubletResidual]) -> Vec<DoubletResidual> {
    steps
        .windows(2)
        .filter(|w| w[1].doublet == w[0].doublet + 1)
        .map(|w| w[0].joined(&w[1]))
        .collect()
}

/// The two statistics of one-step residuals `steps` (`statistic(residuals, stride)`: their
/// lag-one ratio at stride 1, the joined steps' at stride 2) and their intersection
/// ([`estimate_correlation_split`]). The two are independent: `rayon::join` computes them
/// on the current pool, the lag-one ratio's departure reported first as before.
fn both_statistics(
    steps: &[DoubletResidual],
    statistic: impl Fn(&[DoubletResidual], u32) -> Result<Correlation, CorrelationDeparture> + Sync,
) -> Result<Correlation, CorrelationDeparture> {
    // Pairs of steps, two for each pair of doublets: reported as the doublets' pairs.
    let per_doublet = |departure| match departure {
        CorrelationDeparture::TooFewPairs { have } => {
            CorrelationDeparture::TooFewPairs { have: have / 2 }
        }
        other => other,
    };
    let (lag_one, two_step) = rayon::join(
        || statistic(steps, 1),
        || statistic(&joined_steps(steps), 2),
    );
    let lag_one = lag_one.map_err(per_doublet)?;
    let two_step = two_step.map_err(per_doublet)?;
    let interval = [
        lag_one.interval[0].max(two_step.interval[0]),
        lag_one.interval[1].min(two_step.interval[1]),
    ];
    if interval[0] > interval[1] {
        return Err(CorrelationDeparture::Disjoint {
            lag_one: lag_one.interval,
            joined: two_step.interval,
        });
    }
    let width = |c: &Correlation| c.interval[1] - c.interval[0];
    let narrower = if width(&lag_one) <= width(&two_step) {
        lag_one
    } else {
        two_step
    };
    Ok(Correlation {
        point: narrower.point.clamp(interval[0], interval[1]),
        interval,
    })
}

/// `ρ̂` and its (1 − `epsilon`) interval from one-step residuals `steps`, one per step (a
/// two-step block's doublets split at their middle samples, [`DoubletResidual::two_step_split`]),
/// from two statistics at `epsilon/2` each, the interval their intersection (both hold except
/// with probability `epsilon`, and so does the intersection):
///
/// - the lag-one ratio of the one-step residuals, `g₁(ρ) = ρ`: each residual's motion
///   variance `Q` against the sensor's `2R`, their neighbours' MA(1) term `−R` subtracted at
///   the stated `R` — the sharper at small ρ;
/// - the lag-one ratio of the steps joined in pairs at every step ([`DoubletResidual::joined`],
///   the doublets' own two-step residuals and the ones straddling their boundaries), pairs two
///   steps apart, `g₂(ρ) = ρ(1 + ρ)/2`, whose slope `ρ + ½` makes it the sharper at large ρ.
///
/// Each statistic runs its own whiteness test at `epsilon/2`, and each takes the slip's
/// share `slip` out of its residuals' variance ([`estimate_correlation`]). `ρ̂` is the
/// narrower statistic's point, within the intersection. Where the steps' sensor part holds
/// a timing jitter j² ([`DoubletResidual::jitter_variance`], the upper end of its interval),
/// each statistic's interval bounds its intervals at every j² from 0 to that (the shared
/// sample's MA(1) term grows with j², and the ratios with it: [`ratio_interval_over`]),
/// and `ρ̂` is taken at the upper end.
///
/// # Errors
/// [`CorrelationDeparture`] naming what falls outside the class, from either statistic, or
/// [`CorrelationDeparture::Disjoint`] where their intervals do not meet.
pub fn estimate_correlation_split(
    steps: &[DoubletResidual],
    sensor: &Matrix3<f64>,
    epsilon: f64,
    slip: SlipShare,
) -> Result<Correlation, CorrelationDeparture> {
    let untimed: Option<Vec<DoubletResidual>> = steps
        .iter()
        .any(|r| r.jitter_variance > 0.0)
        .then(|| steps.iter().map(|r| r.with_jitter(0.0)).collect());
    both_statistics(steps, |residuals, stride| {
        let timed = correlation_over(residuals, sensor, epsilon / 2.0, stride, slip)?;
        let Some(untimed) = &untimed else {
            return Ok(timed);
        };
        // The same statistic without the jitter's share: the steps (stride 1) or the
        // steps joined in pairs (stride 2).
        let plain = if stride == 1 {
            untimed.clone()
        } else {
            joined_steps(untimed)
        };
        let other = correlation_over(&plain, sensor, epsilon / 2.0, stride, slip)?;
        Ok(over_the_jitter(timed, &other))
    })
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::estimate::diagonal_covariance;
    use crate::estimate::homogeneity::tests::{varied_inputs, wheel_slips};
    use crate::estimate::motion_noise::tests::{simulated_doublets, straight_and_turning};
    use crate::estimate::residual::rotation;
    use crate::model::Pose;
    use std::cell::RefCell;

    const SENSOR: [f64; 3] = [5e-4; 3];

    /// Residuals of `doublets` doublets of straight and turning inputs whose steps carry AR(1)
    /// motion noise of stationary standard deviation `std` per axis (robot frame) and lag-one
    /// correlation `rho`.
    pub(in crate::estimate) fn ar1_residuals(
        doublets: u32,
        std: f64,
        rho: f64,
        seed: u64,
    ) -> Vec<DoubletResidual> {
        ar1_doublets(doublets, std, rho, seed).0
    }

    /// The next step's AR(1) motion noise per axis (stationary standard deviation `std`,
    /// correlation `rho`) after the one `state` holds (none: a fresh stationary draw),
    /// stored back in `state`.
    fn ar1_next(
        state: &RefCell<Option<[f64; 3]>>,
        std: f64,
        rho: f64,
        normal: &mut dyn FnMut() -> f64,
    ) -> [f64; 3] {
        let mut state = state.borrow_mut();
        let fresh = [0; 3].map(|_| std * normal());
        let w = match *state {
            None => fresh,
            Some(last) => {
                std::array::from_fn(|k| rho * last[k] + (1.0 - rho * rho).sqrt() * fresh[k])
            }
        };
        *state = Some(w);
        w
    }

    /// [`ar1_residuals`] and the same doublets' one-step residuals split at their middle
    /// samples ([`DoubletResidual::two_step_split`]).
    pub(in crate::estimate) fn ar1_doublets(
        doublets: u32,
        std: f64,
        rho: f64,
        seed: u64,
    ) -> (Vec<DoubletResidual>, Vec<DoubletResidual>) {
        let state = RefCell::new(None::<[f64; 3]>);
        simulated_doublets(
            doublets,
            SENSOR,
            seed,
            straight_and_turning,
            |_, heading, normal| rotation(heading) * Pose::from(ar1_next(&state, std, rho, normal)),
        )
    }

    /// The doublets' residuals and their one-step residuals split at the middle samples
    /// ([`ar1_doublets`]) of `doublets` doublets over speeds 0.01–0.16 m/s and turn rates
    /// ±0.4 rad/s (`homogeneity`'s varied inputs), whose steps carry AR(1) motion noise of
    /// stationary standard deviation `std` per axis and correlation `rho` (robot frame) and,
    /// independent between steps, per-wheel slip of `slip` (a fraction of each wheel's
    /// travel `(v ± ωD/2)·T`).
    pub(in crate::estimate) fn slipping_ar1_doublets(
        doublets: u32,
        std: f64,
        rho: f64,
        slip: f64,
        seed: u64,
    ) -> (Vec<DoubletResidual>, Vec<DoubletResidual>) {
        let state = RefCell::new(None::<[f64; 3]>);
        simulated_doublets(
            doublets,
            SENSOR,
            seed,
            varied_inputs,
            |u, heading, normal| {
                let w = ar1_next(&state, std, rho, normal);
                let [slip_along, slip_turn] = wheel_slips(u, slip, normal);
                rotation(heading) * Pose::new(w[0] + slip_along, w[1], w[2] + slip_turn)
            },
        )
    }

    #[test]
    fn the_ratio_and_its_inverse_agree_on_the_class() {
        for rho in [-0.5, -0.3, 0.0, 0.2, 0.5, 0.9] {
            assert!((correlation_of(ratio_of(rho)) - rho).abs() < 1e-12, "{rho}");
        }
        assert_eq!(correlation_of(-1.0), LOWEST_CORRELATION);
        assert_eq!(correlation_of(5.0), HIGHEST_CORRELATION);
        assert_eq!(variance_inflation(0.0), 1.5);
        assert!(variance_inflation(0.9) > 4.0 && variance_inflation(0.9) < 6.0);
        assert_eq!(parity_inflation(0.0), 1.0);
        // Three steps: g_3 rises on the class and inverts; two steps are the closed form.
        let mut last = f64::NEG_INFINITY;
        for i in 0..=300 {
            let rho = LOWEST_CORRELATION
                + (HIGHEST_CORRELATION - LOWEST_CORRELATION) * f64::from(i) / 300.0;
            let ratio = ratio_for(rho, 3);
            assert!(ratio > last, "{rho}");
            last = ratio;
            assert!((correlation_for(ratio, 3) - rho).abs() < 1e-9, "{rho}");
            assert_eq!(ratio_for(rho, 2), ratio_of(rho));
        }
        assert!((ratio_for(-0.5, 3) + 0.1875).abs() < 1e-12);
        assert_eq!(variance_inflation_for(0.0, 3), 1.5);
        assert_eq!(parity_inflation_for(0.0, 3), 1.0);
        assert!(variance_inflation_for(0.9, 3) > variance_inflation_for(0.5, 3));
    }

    /// ρ̂ recovers ρ and its interval holds it: over 10,000 doublets the ratio's standard
    /// error is ≈ 0.01–0.02, ρ̂ within 0.08 of the truth (≈ 5 of them at ρ = 0.9, where
    /// `g` is steepest); every interval holds the truth on 10 seeds at ε = 0.01 (a miss
    /// every 100 blocks at most).
    #[test]
    fn the_correlation_is_recovered_and_its_interval_holds_it() {
        let sensor = diagonal_covariance(SENSOR);
        for rho in [0.0, 0.5, 0.9] {
            for seed in 0..10 {
                let data = ar1_residuals(10_000, 1e-3, rho, 40 + seed);
                let c = estimate_correlation(&data, &sensor, 0.01, SlipShare::NONE).unwrap();
                assert!((c.point - rho).abs() < 0.08, "ρ {rho} seed {seed}: {c:?}");
                assert!(
                    c.interval[0] <= rho && rho <= c.interval[1],
                    "ρ {rho} seed {seed}: {c:?}"
                );
                assert!(c.interval[1] - c.interval[0] < 0.3, "{c:?}");
                eprintln!("rho {rho} seed {seed}: {c:?}");
            }
        }
    }

    /// Motion noise that is MA(1) between doublets, not AR(1) between steps (each doublet's
    /// noise repeated, halved, in the next: lag-one products, none at lag two), departs from
    /// the AR(1) model's lag-two prediction: refused at ε = 10⁻⁶ over 10,000 doublets.
    #[test]
    fn noise_outside_the_ar1_model_is_refused() {
        let sensor = diagonal_covariance(SENSOR);
        let mut data = ar1_residuals(10_000, 1e-3, 0.0, 7);
        let original: Vec<Pose> = data.iter().map(|r| r.value).collect();
        for (j, r) in data.iter_mut().enumerate().skip(1) {
            r.value += 1.2 * original[j - 1];
        }
        let error = estimate_correlation(&data, &sensor, 1e-6, SlipShare::NONE).unwrap_err();
        assert!(
            matches!(error, CorrelationDeparture::NotAr1 { .. }),
            "{error:?}"
        );
    }

    /// ρ from the one-step residuals split at the middle samples too (two per doublet, the
    /// sensor's MA(1) term between neighbouring steps subtracted at the stated `R`): over
    /// 200 seeded blocks of 2,000 doublets at 1 mm of motion noise against the sensor's
    /// 0.5 mm (where that term, `−R/(Q + 2R) = −⅙` per position axis, is largest against
    /// the motion's), at ρ = 0, 0.5 and 0.9 and ε = 0.05, the one-step statistic's interval
    /// alone (at ε) and the block's ([`estimate_correlation_split`]) each miss the truth in
    /// at most 19 of the blocks they size (10 expected were they exact; 19 is 3 binomial
    /// standard deviations `√(200·0.05·0.95)` above), the whiteness tests refuse at most
    /// 12 (their level ε/2: 5 expected, 3 standard deviations above), and the block's
    /// interval is narrower than the doublets' residuals' alone at ε, on average over the
    /// blocks and in most of them (each of its two statistics at ε/2 costs it a few per cent
    /// where one alone is the sharper, ρ ≈ 0.5).
    #[test]
    fn the_middle_samples_interval_covers_the_truth_and_is_narrower() {
        let sensor = diagonal_covariance(SENSOR);
        let (blocks, level) = (200_u64, 0.05);
        let expected = blocks as f64 * level;
        let allowed = (expected + 3.0 * (expected * (1.0 - level)).sqrt()).floor() as usize;
        for rho in [0.0, 0.5, 0.9] {
            let (mut misses, mut refused, mut widths) = ([0; 2], [0; 2], [0.0; 3]);
            let (mut narrower, mut compared) = (0, 0);
            let width = |c: &Correlation| c.interval[1] - c.interval[0];
            let missed = |c: &Correlation| usize::from(rho < c.interval[0] || rho > c.interval[1]);
            for seed in 0..blocks {
                let (whole, split) = ar1_doublets(2_000, 1e-3, rho, 900 + seed);
                let alone = estimate_correlation(&split, &sensor, level, SlipShare::NONE);
                let block = estimate_correlation_split(&split, &sensor, level, SlipShare::NONE);
                for (k, c) in [alone, block].iter().enumerate() {
                    match c {
                        Ok(c) => misses[k] += missed(c),
                        Err(_) => refused[k] += 1,
                    }
                }
                if let (Ok(alone), Ok(block), Ok(old)) = (
                    alone,
                    block,
                    estimate_correlation(&whole, &sensor, level, SlipShare::NONE),
                ) {
                    widths[0] += width(&alone);
                    widths[1] += width(&block);
                    widths[2] += width(&old);
                    narrower += usize::from(width(&block) < width(&old));
                    compared += 1;
                }
            }
            eprintln!(
                "ρ {rho}: misses {misses:?}, refused {refused:?}, mean width against the \
                 doublets' alone: one-step {:.3}, the block's {:.3}, narrower in {narrower} \
                 of {compared}",
                widths[0] / widths[2],
                widths[1] / widths[2]
            );
            for k in 0..2 {
                assert!(misses[k] <= allowed, "ρ {rho}: {misses:?} of {blocks} miss");
                assert!(refused[k] <= 12, "ρ {rho}: {refused:?} of {blocks} refused");
            }
            assert!(
                widths[1] < widths[2],
                "ρ {rho}: mean width {} against the doublets' {}",
                widths[1] / compared as f64,
                widths[2] / compared as f64
            );
            assert!(
                2 * narrower > compared,
                "ρ {rho}: narrower in {narrower} of {compared}"
            );
        }
    }

    /// [`ratio_interval_over`] bounds the ratio's interval at every (σ², j²) of the slip's and
    /// the jitter's rectangle: over 8 seeded blocks of 1,000 two-step doublets per world (the
    /// one-step residuals, `jitter`'s simulation; six worlds with 5 % or 20 % of slip at 1 or
    /// 4 mm, two of them with 5 ms of jitter, and two with 5 ms of jitter alone), `j_hi` the
    /// jitter's upper end at ε = 0.05 where the world has jitter (else j² = 0), σ²'s interval
    /// `[(0.8σ)², (1.2σ)²]` about the world's slip σ (a wider band than a block's, so more
    /// curvature to bound), both statistics (the lag-one ratio, stride 1, and the joined
    /// steps', stride 2) at ε = 0.05, the interval at each point of a 17 × 17 grid (17 where
    /// one side is a point) lies within the bound (with the intervals at σ²'s ends, as
    /// `ratio_statistic` takes it). Printed: the closest approach (negative inside) and the
    /// bound's mean widening over the hull of the intervals at 9 evenly spaced σ² at j² = 0
    /// and `j²_hi` (what ρ's interval was before the bound), both in the ratio `r`.
    #[test]
    fn the_ratios_interval_over_the_slip_and_the_jitter_is_bounded() {
        use crate::estimate::jitter::tests::jittered_steps;
        use crate::estimate::jitter::{JitterRows, estimate_jitter};
        let sensor = diagonal_covariance(crate::estimate::homogeneity::tests::SENSOR);
        let (blocks, epsilon, points) = (8_u64, 0.05, 17);
        // Name, √Q per axis, ρ, slip, jitter (s).
        let worlds: [(&str, f64, f64, f64, f64); 8] = [
            ("5 ms, 1 mm", 1e-3, 0.0, 0.0, 5e-3),
            ("5 ms, ρ 0.5, 4 mm", 4e-3, 0.5, 0.0, 5e-3),
            ("5 % slip, ρ 0.5, 1 mm", 1e-3, 0.5, 0.05, 0.0),
            ("5 % slip, ρ 0.5, 4 mm", 4e-3, 0.5, 0.05, 0.0),
            ("20 % slip, ρ 0.5, 1 mm", 1e-3, 0.5, 0.2, 0.0),
            ("20 % slip, 4 mm", 4e-3, 0.0, 0.2, 0.0),
            ("5 ms, 5 % slip, ρ 0.5, 4 mm", 4e-3, 0.5, 0.05, 5e-3),
            ("5 ms, 20 % slip, ρ 0.5, 1 mm", 1e-3, 0.5, 0.2, 5e-3),
        ];
        for (name, q_std, rho, slip, jitter) in worlds {
            let (mut beyond, mut checked, mut widening, mut bounded) =
                (f64::NEG_INFINITY, 0, 0.0, 0);
            let variances = [0.8, 1.2].map(|f| (f * slip).powi(2));
            let grid = |[low, high]: [f64; 2], count: usize| -> Vec<f64> {
                let count = if low < high { count } else { 1 };
                (0..count)
                    .map(|i| low + (high - low) * i as f64 / (count - 1).max(1) as f64)
                    .collect()
            };
            for seed in 0..blocks {
                let steps = jittered_steps(1_000, q_std, rho, slip, jitter, 8_300 + seed);
                let high = if jitter > 0.0 {
                    let Some(fit) = estimate_jitter(&steps, &sensor, epsilon, JitterRows::Both)
                    else {
                        continue;
                    };
                    fit.interval[1].max(0.0)
                } else {
                    0.0
                };
                for stride in [1, 2] {
                    let terms_at = |variance: f64| {
                        let timed: Vec<DoubletResidual> =
                            steps.iter().map(|r| r.with_jitter(variance)).collect();
                        let residuals = if stride == 1 {
                            timed
                        } else {
                            joined_steps(&timed)
                        };
                        let terms: Vec<PairTerms> = pairs(&residuals, stride)
                            .map(|(a, b)| pair_terms(a, b, &sensor))
                            .collect();
                        (terms, residuals[0].steps)
                    };
                    let (low_end, steps_per) = terms_at(0.0);
                    let (high_end, _) = terms_at(high);
                    let batches =
                        (low_end.len() / (MIN_PAIRS_PER_BATCH * stride as usize)).min(MAX_BATCHES);
                    let interval = |terms: &[PairTerms], variance: f64| {
                        let corrected: Vec<[[f64; 3]; 3]> =
                            terms.iter().map(|t| without_slip(t, variance)).collect();
                        ratio_interval(&corrected, batches, steps_per, epsilon).ok()
                    };
                    let untimed = (high > 0.0).then_some(low_end.as_slice());
                    let Ok(mut bound) =
                        ratio_interval_over(&high_end, untimed, variances, batches, epsilon)
                    else {
                        continue;
                    };
                    let mut hull = [f64::INFINITY, f64::NEG_INFINITY];
                    for terms in [&low_end, &high_end] {
                        for variance in grid(variances, 9) {
                            if let Some([_, lo, hi]) = interval(terms, variance) {
                                hull = [hull[0].min(lo), hull[1].max(hi)];
                            }
                        }
                        // With the intervals at σ²'s ends, as `ratio_statistic` takes it.
                        for variance in variances {
                            if let Some([_, lo, hi]) = interval(terms, variance) {
                                bound = [bound[0].min(lo), bound[1].max(hi)];
                            }
                        }
                    }
                    widening += (bound[1] - bound[0]) - (hull[1] - hull[0]);
                    bounded += 1;
                    for j2 in grid([0.0, high], points) {
                        let terms = terms_at(j2).0;
                        for variance in grid(variances, points) {
                            let Some([_, lo, hi]) = interval(&terms, variance) else {
                                continue;
                            };
                            beyond = beyond.max(bound[0] - lo).max(hi - bound[1]);
                            checked += 1;
                        }
                    }
                }
            }
            eprintln!(
                "{name}: closest approach to the bound {beyond:.3e} over {checked} points; \
                 the bound wider than the 9-point hull by {:.3e} on average over {bounded}",
                widening / f64::from(bounded)
            );
            assert!(checked > 0, "{name}: no block evaluated");
            assert!(
                beyond <= 0.0,
                "{name}: a point reaches {beyond:.3e} beyond the bound"
            );
        }
    }

    /// Where the slip's share takes all the motion variance, the refusal names what each axis
    /// kept, finite (it named the ratio NaN before): 200 pairs whose axes each hold motion
    /// variance `b` ≈ 10⁻⁶ against a slip map of 10⁻⁴ per unit σ², so every axis's `b` falls
    /// to 0 at σ² ≈ 0.01 — the bound over `[0, 0.005]` is finite, over `[0, 0.02]` refused, as
    /// is the interval at 0.02 alone.
    #[test]
    fn no_motion_variance_left_is_refused_by_name() {
        let terms: Vec<PairTerms> = (0..200)
            .map(|i| {
                let wobble = 1e-7 * ((i % 7) as f64 - 3.0);
                [0, 1, 2].map(|_| [0.2e-6 + wobble, 1e-6 - wobble, 1e-7, 1e-4])
            })
            .collect();
        let batches = 4;
        let bound = ratio_interval_over(&terms, None, [0.0, 0.005], batches, 0.05).unwrap();
        assert!(bound.iter().all(|x| x.is_finite()), "{bound:?}");
        let refused = |result: Result<_, CorrelationDeparture>| match result {
            Err(CorrelationDeparture::NoMotionVariance { motion_variance }) => {
                assert!(
                    motion_variance.iter().all(|b| b.is_finite() && *b <= 0.0),
                    "{motion_variance:?}"
                );
            }
            other => panic!("{other:?}"),
        };
        refused(ratio_interval_over(&terms, None, [0.0, 0.02], batches, 0.05).map(|_| ()));
        let at_end: Vec<[[f64; 3]; 3]> = terms.iter().map(|t| without_slip(t, 0.02)).collect();
        refused(ratio_interval(&at_end, batches, 2, 0.05).map(|_| ()));
    }
}
