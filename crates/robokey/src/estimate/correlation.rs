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
//! whiteness test at σ̂², the interval the hull of the intervals at [`SLIP_POINTS`] points of
//! σ²'s interval (`motion_noise` takes the two intervals jointly).
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
        /// `ρ̂` if `g` were continued (or the ratio's value).
        ratio: f64,
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
/// interval, over which `ρ`'s interval is taken (the hull of the intervals at
/// [`SLIP_POINTS`] evenly spaced points, its ends included).
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

    /// The points of the interval the correlation's interval is taken over (one where the
    /// interval is a point, as without slip).
    fn grid(&self) -> impl Iterator<Item = f64> + '_ {
        let [low, high] = self.interval;
        let points = if low == high { 1 } else { SLIP_POINTS };
        (0..points).map(move |i| low + (high - low) * i as f64 / (SLIP_POINTS - 1) as f64)
    }
}

/// Points of σ²'s interval the correlation's interval is taken at ([`SlipShare`]): between
/// them its ends are not proved to lie within the hull.
pub const SLIP_POINTS: usize = 9;

/// `ρ̂` and its (1 − `epsilon`) interval from `residuals` (each formed with the reconciled
/// bits) and the sensor's stated covariance `sensor`, the slip's share `slip` of their
/// variance taken out, and the whiteness test of the AR(1) model's innovations at level
/// `epsilon`. Where the residuals' sensor part holds a timing jitter j²
/// ([`DoubletResidual::jitter_variance`], the upper end of its interval: a three-step
/// block's one-step residuals), the interval bounds the statistic's at every j² from 0 to
/// that ([`ratio_interval_between`], [`over_the_jitter`]), as [`estimate_correlation_split`]'s
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
/// already bounds every j² of the range, [`ratio_interval_between`]) and at 0 (`untimed`,
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
        return Err(CorrelationDeparture::OutsideClass { ratio: f64::NAN });
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

/// Pieces the timing jitter's `[0, j²_hi]` is cut into for [`ratio_interval_between`].
const JITTER_PIECES: usize = 8;

/// `[min, max]` bounds of a quadratic over a piece from its values at the piece's start,
/// middle and end: the range of its Bernstein coefficients `p(s₀)`, `2p(s_m) − (p(s₀) +
/// p(s₁))/2`, `p(s₁)`, which the quadratic, their convex combination, never leaves.
fn quadratic_range([start, middle, end]: [f64; 3]) -> [f64; 2] {
    let inner = 2.0 * middle - 0.5 * (start + end);
    [start.min(inner).min(end), start.max(inner).max(end)]
}

/// Bounds on [`ratio_interval`]'s interval `[r − zσ_up, r + zσ_up]` at every timing jitter
/// between the two ends whose terms `ends` holds (`[at 0, at j²_hi]`, pairs alike). Each
/// pair's `a_k`, `b_k` and `N_k` are affine in j² and `c_k = b_k + N_k` does not move, so
/// with the axis weights `(b_k/c_k)²/D`, `D = Σ_k b_k²/c_k²` (the axes with `b_k > 0`):
///
/// `r = P/D`, `P = Σ_k a_k b_k/c_k²`; each batch's term `u_i = E_i/D`,
/// `E_i = Σ_k (ā_ik b_k − a_k b̄_ik)/c_k²`; so `r ± zσ_up = (P ± zκ√W)/D`,
/// `W = Σ_i (E_i − Ē)²`, `κ² = 1/((B − 1)·q·B)` —
///
/// `P`, `D` and each `E_i − Ē` quadratics in j², a ratio of which is neither monotone nor
/// convex in general. On each of [`JITTER_PIECES`] pieces (cut where an axis's `b_k`
/// changes sign, as its weight's support does) each quadratic lies within its Bernstein
/// range ([`quadratic_range`]), so there `r + zσ_up ≤ (P_max + zκ√W_max)/D` at `D_min`
/// (the numerator at least 0) or `D_max`, `W_max = Σ_i max|E_i − Ē|²`, and the lower end
/// alike: a bound at every j² of the range, not only at its ends.
///
/// # Errors
/// [`CorrelationDeparture::OutsideClass`] where a piece has no axis with motion variance.
fn ratio_interval_between(
    ends: [&[[[f64; 3]; 3]]; 2],
    batches: usize,
    epsilon: f64,
) -> Result<[f64; 2], CorrelationDeparture> {
    // Means per axis of [a, b, N] over the pairs and over each batch, at each end.
    let mean = |terms: &[[[f64; 3]; 3]]| -> [[f64; 3]; 3] {
        let m = terms.len() as f64;
        std::array::from_fn(|k| {
            std::array::from_fn(|w| terms.iter().map(|t| t[k][w]).sum::<f64>() / m)
        })
    };
    let per_batch = ends[0].len() / batches;
    let totals = ends.map(mean);
    let batch_means = ends.map(|terms| {
        (0..batches)
            .map(|i| mean(&terms[i * per_batch..(i + 1) * per_batch]))
            .collect::<Vec<_>>()
    });
    let at = |x: [f64; 2], s: f64| (1.0 - s) * x[0] + s * x[1];
    let total = |k: usize, w: usize, s: f64| at([totals[0][k][w], totals[1][k][w]], s);
    let c = [0, 1, 2].map(|k| totals[1][k][1] + totals[1][k][2]);
    // The pieces' ends in s = j²/j²_hi: evenly spaced, and where a b_k changes sign.
    let mut cuts: Vec<f64> = (0..=JITTER_PIECES)
        .map(|i| i as f64 / JITTER_PIECES as f64)
        .collect();
    cuts.extend(
        totals[0]
            .iter()
            .zip(&totals[1])
            .map(|(start, end)| [start[1], end[1]])
            .filter(|[b0, b1]| b0 * b1 < 0.0)
            .map(|[b0, b1]| b0 / (b0 - b1)),
    );
    cuts.sort_by(f64::total_cmp);
    let [lower_quantile, z] = interval_quantiles(batches, epsilon);
    let kappa = (1.0 / ((batches - 1) as f64 * lower_quantile * batches as f64)).sqrt();
    let mut bounds = [f64::INFINITY, f64::NEG_INFINITY];
    for piece in cuts.windows(2) {
        let points = [piece[0], 0.5 * (piece[0] + piece[1]), piece[1]];
        let used: Vec<usize> = (0..3)
            .filter(|&k| total(k, 1, points[1]) > 0.0 && c[k] > 0.0)
            .collect();
        if used.is_empty() {
            return Err(CorrelationDeparture::OutsideClass { ratio: f64::NAN });
        }
        let sum = |f: &dyn Fn(usize, f64) -> f64, s: f64| -> f64 {
            used.iter().map(|&k| f(k, s) / (c[k] * c[k])).sum()
        };
        let p = quadratic_range(points.map(|s| sum(&|k, s| total(k, 0, s) * total(k, 1, s), s)));
        let d = quadratic_range(points.map(|s| sum(&|k, s| total(k, 1, s).powi(2), s)));
        let batch_term = |i: usize, s: f64| {
            let batch =
                |k: usize, w: usize| at([batch_means[0][i][k][w], batch_means[1][i][k][w]], s);
            sum(
                &|k, s| batch(k, 0) * total(k, 1, s) - total(k, 0, s) * batch(k, 1),
                s,
            )
        };
        let terms = points.map(|s| (0..batches).map(|i| batch_term(i, s)).collect::<Vec<f64>>());
        let centre = terms
            .clone()
            .map(|e| e.iter().sum::<f64>() / batches as f64);
        let w_max: f64 = (0..batches)
            .map(|i| {
                let [low, high] = quadratic_range([0, 1, 2].map(|j| terms[j][i] - centre[j]));
                low.abs().max(high.abs()).powi(2)
            })
            .sum();
        let spread = z * kappa * w_max.sqrt();
        let divide = |numerator: f64, upper: bool| {
            let denominator = if (numerator >= 0.0) == upper {
                d[0]
            } else {
                d[1]
            };
            numerator / denominator
        };
        bounds = [
            bounds[0].min(divide(p[0] - spread, false)),
            bounds[1].max(divide(p[1] + spread, true)),
        ];
    }
    Ok(bounds)
}

/// [`estimate_correlation`] over residuals that overlap by `stride − 1` of every `stride`
/// (one per step, each spanning `stride` steps: [`DoubletResidual::joined`]): the lag-one
/// pairs are `stride` apart, the lag-two ones `2·stride`, the batches at least `stride` times
/// as long, and the whiteness test's variance inflated `stride` times more (a sum over
/// `stride` interleaved phases has at most `stride²` times one phase's variance, by
/// Cauchy–Schwarz, and `stride` times its sum of squares). The slip's share `slip` is taken
/// out of each pair's motion variance: `ρ̂` at its point, `ρ`'s interval the hull of the
/// intervals over its interval's [`SLIP_POINTS`] (the lag-one and lag-two products carry no
/// slip, which is independent between steps).
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
/// lag-one products `ā` per axis. Where the residuals carry a timing jitter j²
/// ([`DoubletResidual::jitter_variance`]), the interval bounds the ratio's at every j² from
/// 0 to that ([`ratio_interval_between`]) as well as at its end.
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
    let corrected = |terms: &[PairTerms], variance: f64| -> Vec<[[f64; 3]; 3]> {
        terms.iter().map(|t| without_slip(t, variance)).collect()
    };
    let at = |variance: f64| ratio_interval(&corrected(&terms, variance), batches, steps, epsilon);
    let [ratio, _, _] = at(slip.point)?;
    let [ratio_lo, ratio_hi] =
        slip.grid()
            .try_fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], variance| {
                let [_, mut low, mut high] = at(variance)?;
                if let Some(untimed) = &untimed {
                    let ends = [corrected(untimed, variance), corrected(&terms, variance)];
                    let [below, above] =
                        ratio_interval_between([&ends[0], &ends[1]], batches, epsilon)?;
                    (low, high) = (low.min(below), high.max(above));
                }
                Ok([lo.min(low), hi.max(high)])
            })?;
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
/// ([`estimate_correlation_split`]).
fn both_statistics(
    steps: &[DoubletResidual],
    statistic: impl Fn(&[DoubletResidual], u32) -> Result<Correlation, CorrelationDeparture>,
) -> Result<Correlation, CorrelationDeparture> {
    // Pairs of steps, two for each pair of doublets: reported as the doublets' pairs.
    let per_doublet = |departure| match departure {
        CorrelationDeparture::TooFewPairs { have } => {
            CorrelationDeparture::TooFewPairs { have: have / 2 }
        }
        other => other,
    };
    let lag_one = statistic(steps, 1).map_err(per_doublet)?;
    let two_step = statistic(&joined_steps(steps), 2).map_err(per_doublet)?;
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
/// sample's MA(1) term grows with j², and the ratios with it: [`ratio_interval_between`]),
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

    /// [`ratio_interval_between`] bounds the ratio's interval at every j² of `[0, j²_hi]`:
    /// over 8 seeded blocks of 1,000 two-step doublets per world (the one-step residuals,
    /// `jitter`'s simulation), `j_hi` the jitter's upper end at ε = 0.05, both statistics
    /// (the lag-one ratio, stride 1, and the joined steps', stride 2) at ε = 0.05, the
    /// interval at each of 17 evenly spaced j² lies within the bound. Printed: the closest
    /// approach (negative inside) and the bound's mean widening over the ends' hull, both in
    /// the ratio `r`.
    #[test]
    fn the_ratios_interval_between_the_jitters_ends_is_bounded() {
        use crate::estimate::jitter::tests::jittered_steps;
        use crate::estimate::jitter::{JitterRows, estimate_jitter};
        let sensor = diagonal_covariance(crate::estimate::homogeneity::tests::SENSOR);
        let (blocks, epsilon, points) = (8_u64, 0.05, 17);
        // Name, √Q per axis, ρ, slip, jitter (s).
        let worlds: [(&str, f64, f64, f64, f64); 4] = [
            ("none, 1 mm", 1e-3, 0.0, 0.0, 0.0),
            ("5 ms, 4 mm", 4e-3, 0.0, 0.0, 5e-3),
            ("5 ms, ρ 0.5, 4 mm", 4e-3, 0.5, 0.0, 5e-3),
            ("5 ms, 5 % slip, ρ 0.5, 4 mm", 4e-3, 0.5, 0.05, 5e-3),
        ];
        for (name, q_std, rho, slip, jitter) in worlds {
            let (mut beyond, mut checked, mut widening, mut bounded) =
                (f64::NEG_INFINITY, 0, 0.0, 0);
            for seed in 0..blocks {
                let steps = jittered_steps(1_000, q_std, rho, slip, jitter, 8_300 + seed);
                let Some(fit) = estimate_jitter(&steps, &sensor, epsilon, JitterRows::Both) else {
                    continue;
                };
                let high = fit.interval[1].max(0.0);
                for stride in [1, 2] {
                    let terms_at = |variance: f64| {
                        let timed: Vec<DoubletResidual> =
                            steps.iter().map(|r| r.with_jitter(variance)).collect();
                        let residuals = if stride == 1 {
                            timed
                        } else {
                            joined_steps(&timed)
                        };
                        let terms: Vec<[[f64; 3]; 3]> = pairs(&residuals, stride)
                            .map(|(a, b)| without_slip(&pair_terms(a, b, &sensor), 0.0))
                            .collect();
                        (terms, residuals[0].steps)
                    };
                    let (low_end, steps_per) = terms_at(0.0);
                    let (high_end, _) = terms_at(high);
                    let batches =
                        (low_end.len() / (MIN_PAIRS_PER_BATCH * stride as usize)).min(MAX_BATCHES);
                    let interval = |terms: &[[[f64; 3]; 3]]| {
                        ratio_interval(terms, batches, steps_per, epsilon).ok()
                    };
                    let (Some([_, lo0, hi0]), Some([_, lo1, hi1]), Ok(bound)) = (
                        interval(&low_end),
                        interval(&high_end),
                        ratio_interval_between([&low_end, &high_end], batches, epsilon),
                    ) else {
                        continue;
                    };
                    widening += (bound[1] - bound[0]) - (hi0.max(hi1) - lo0.min(lo1));
                    bounded += 1;
                    for i in 0..points {
                        let variance = high * i as f64 / (points - 1) as f64;
                        let Some([_, lo, hi]) = interval(&terms_at(variance).0) else {
                            continue;
                        };
                        beyond = beyond.max(bound[0] - lo).max(hi - bound[1]);
                        checked += 1;
                    }
                }
            }
            eprintln!(
                "{name}: closest approach to the bound {beyond:.3e} over {checked} points; \
                 the bound wider than the ends' hull by {:.3e} on average",
                widening / f64::from(bounded)
            );
            assert!(checked > 0, "{name}: no block evaluated");
            assert!(
                beyond <= 0.0,
                "{name}: a j² reaches {beyond:.3e} beyond the bound"
            );
        }
    }
}
