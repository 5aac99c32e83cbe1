//! The motion noise `Q` from the doublets' residuals, and its (1 − ε_est) lower bound
//! (docs/estimation.md, "The region"). A block's residuals are its doublets' one-step
//! residuals, split at the controller's samples within each doublet (two-step doublets at
//! the middle sample, [`estimate_motion_noise_split`]; three-step ones where the pool kept
//! the sample after the second step), or each doublet's start-to-end residual (a three-step
//! block holding a session pooled without that sample).
//!
//! **Point estimate** (method of moments, the sensor term subtracted): with `S` the mean of
//! `zzᵀ` over the residuals, `N̄` the mean sensor part and `𝓛̄(Q)` the mean motion part,
//! `𝓛̄(Q̂) = S − N̄` — a 6×6 linear system in the six entries of the symmetric `Q̂`.
//!
//! **Region.** Residuals of one parity (of the doublet's index, or of the step's for
//! one-step residuals) are independent (the MA(1) structure links neighbours only). For each parity half of `m` residuals, treated as `N(0, Σ̄)` with
//! `Σ̄` the mean covariance, `Σ̄^(−½)·S_half·Σ̄^(−½)` is a Wishart matrix `W₃(I, m)/m`; its
//! largest eigenvalue is below `c₊` and its smallest above `c₋` (`wishart`: each direction's
//! exact χ²_m tail over two nets of directions, the lower side's net tightening `c₊` too,
//! never looser than Davidson–Szarek's `(1 ± √(3/m) ± √(2 ln(2/ε_half)/m))²`), both except
//! with probability ε_half (with fewer than about 1,000 residuals the upper side alone at
//! ε_half is tighter, and `c₋` holds with ε_half more); with ε_half = ε_est/4 per half, except
//! with probability ε_est/2, `Σ̄ ⪰ S_half/c₊` for both halves, in the Loewner order — every
//! direction at once (`Q_high`, from `c₋`, on the same event or with its own share). Their
//! weighted mean `Σ_low` is again a lower bound, and with `R` at its stated value
//! `𝓛̄(Q) ⪰ Σ_low − N̄`. The region is `{Q ⪰ 0 : 𝓛̄(Q) ⪰ Σ_low − N̄}`; its Loewner vertex
//! `Q_low = 𝓛̄⁻¹(Σ_low − N̄)` lies below every member (𝓛̄ is `2·id` up to the heading's
//! lateral coupling `T·v` and the turn `T·ω` within a doublet), and is where Eve's view is
//! sharpest (`worst_case`).
//!
//! **Refusals** (outside the class, named): too few doublets to bound anything; residuals
//! that vary less than the stated sensor noise alone explains (`Q_high = 𝓛̄⁻¹(S_half/c₋ − N̄)`
//! has a negative eigenvalue: no `Q ⪰ 0` fits, so the calibration `R` is wrong); neighbours
//! correlated beyond the sensor's MA(1) term (not white); a variance that differs between the
//! doublets' speed or turn classes beyond what the fitted model explains (`homogeneity`);
//! tails that are not Gaussian; per-wheel slip beyond the class's range.
//!
//! **Per-wheel slip, sized.** Where the block measures slip (`slip`, its interval above 0 at
//! level ε_est), the estimate is made again with ε_est split in three: the correlation's
//! interval and the Wishart bound at ε_est/3 each (the bound's two sides, `c₊` and `c₋`, at
//! ε_est/12 per half each), the slip's interval `[σ²_lo, σ²_hi]` at ε_est/3. The residuals'
//! covariance is then `𝓛ᵢ(Q) + Nᵢ + σ²Mᵢ`, so the region is
//! `Σ_high − N̄ − σ²M̄ ⪰ 𝓛̄(Q) ⪰ Σ_low − N̄ − σ²M̄` (`M̄` the mean slip map; the upper side
//! bounds Eve's view too), jointly with σ² in its interval: the vertex `Q_low(σ²)` falls as σ² rises, while the slip's own part of Eve's view rises —
//! not one-sided, so the corners are computed at [`SLIP_GRID`] points of σ²'s interval
//! ([`SlipCorners`]) and Eve's view is sized at each (`worst_case`). The residuals' spread
//! now differs between doublets (the slip's part follows the wheel speeds): along each
//! direction the whitened second moment is a weighted χ², bounded over every weight vector
//! the data and σ²'s upper end allow (`slip_wishart_bounds`, a fixed point), and the kurtosis
//! is taken of each residual whitened by its own fitted covariance. ρ's interval takes the
//! slip's share out over σ²'s interval, which holds at every ρ (its fit free of ρ), so the
//! two are taken jointly (`joint_region`) with no circular claim.

use nalgebra::{Matrix3, Matrix6, SymmetricEigen, Vector6};
use rayon::iter::{IntoParallelIterator, ParallelIterator};
use thiserror::Error;

use super::correlation::{
    Correlation, CorrelationDeparture, HIGHEST_CORRELATION, LOWEST_CORRELATION, SlipShare,
    correlation_untested, estimate_correlation, estimate_correlation_split, parity_inflation_for,
    variance_inflation_for,
};
use super::homogeneity::{ClassDeparture, speed_class_departure};
use super::normal_tail::normal_upper_quantile;
use super::residual::{AXES, DoubletResidual};
use super::slip::{SlipEstimate, estimate_slip, estimate_slip_over_jitter};
use super::symmetric_coordinates::{coordinates, symmetric};
use super::weighted_chi_square::{Cap, DirectionalChiSquare};
use super::wishart::{net_bounds, wishart_upper_bounds};
use crate::world::MAX_SLIP_STD;

/// Least residuals of each parity the bounds are computed from.
pub const MIN_DOUBLETS_PER_PARITY: usize = 100;

/// Cells the correlation's interval is cut into for the worst case (`Corner`).
pub const CORRELATION_CELLS: usize = 8;

/// One cell `[ρ_a, ρ_b]` of the correlation's interval and what bounds the region over it
/// from below: `Q_cell ⪯ Q_low(ρ)` and, for the doublet's two steps given their neighbours'
/// noise (Eve's genie view), the least and the greatest step weights `[α, β]` over the cell:
/// with `Q_cell = P₊ − P₋` (its positive and negative parts),
/// `P₊ ⊗ [[α, β], [β, α]]_least − P₋ ⊗ [[α, β], [β, α]]_greatest` lies below the two steps'
/// conditional covariance for every member of the cell (docs/estimation.md, "The corner").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Corner {
    /// `[ρ_a, ρ_b]`.
    pub correlation: [f64; 2],
    /// `Q_cell` in the robot's frame (m², m², rad²).
    pub motion: Matrix3<f64>,
    /// `[least, greatest]` of `[α, β]`: the two steps' conditional variance and covariance,
    /// in units of `Q`.
    pub step_weights: [[f64; 2]; 2],
}

/// What the controller measured of the motion noise, and its bound.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionNoiseEstimate {
    /// Residuals used (a three-step block reports its doublets: three one-step residuals each).
    pub doublets: usize,
    /// `Q̂` in the robot's frame (m², m², rad²; along-track, lateral, heading): the
    /// stationary covariance per step, for the controller's own likelihood and error estimate.
    pub point: Matrix3<f64>,
    /// The AR(1) correlation between steps: `ρ̂` and its interval.
    pub correlation: Correlation,
    /// `Q_low(ρ_hi)`: the region's lowest vertex (for people; Eve's view is sized over
    /// `corners`).
    pub lower: Matrix3<f64>,
    /// `Q_high(ρ_lo)`: the region's upper vertex (for people and the class check).
    pub upper: Matrix3<f64>,
    /// The joint region's lower bounds over the cells of the correlation's interval.
    pub corners: [Corner; CORRELATION_CELLS],
    /// The region's failure probability ε_est.
    pub epsilon: f64,
    /// Per-wheel slip fitted beside `Q` (`slip`): where the block measures it, the interval
    /// at ε_est/3 that `slip_corners` cover; otherwise the fit at level ε_est, whose interval
    /// reaches 0 (the slip that may go unseen). None where the block's speeds do not identify
    /// it; for a known world, its slip.
    pub slip: Option<SlipEstimate>,
    /// The region's lower bounds at points of the slip's interval, where the block measures
    /// slip (Eve's view is then sized at each; a known world's are one point repeated); none
    /// otherwise, and `corners` size it.
    pub slip_corners: Option<[SlipCorners; SLIP_GRID]>,
}

/// Points of the slip variance's interval the region's corners are computed at: its ends and
/// midpoint (a bound at those points; between them not proved: the corner falls in the
/// Loewner order as σ² rises, but the slip's own, bit-dependent part of Eve's view rises with
/// it. On the grid's slip blocks 9 and 17 points gave the same least H_min^ε, which fell
/// strictly in σ²: docs/estimation.md, "What is not done yet").
pub const SLIP_GRID: usize = 3;

/// The joint region's lower bounds at one value of the slip variance σ².
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlipCorners {
    /// σ² (a fraction of each wheel's travel, squared).
    pub variance: f64,
    /// The corners with `σ²M̄` subtracted: `Q_low(ρ, σ²) = 𝓛̄_ρ⁻¹(Σ_low − N̄ − σ²M̄)` over each
    /// cell of the correlation's interval.
    pub corners: [Corner; CORRELATION_CELLS],
    /// A matrix above `Q_high(ρ, σ²) = 𝓛̄_ρ⁻¹(Σ_high − N̄ − σ²M̄)` at every ρ of the
    /// correlation's interval (robot frame; m², m², rad²): every member of the region at σ²
    /// lies below it. None where the Wishart count is too small for an upper side.
    pub upper: Option<Matrix3<f64>>,
}

/// Why a block's motion noise could not be bounded: the class does not cover its data.
#[non_exhaustive]
#[derive(Clone, Debug, PartialEq, Error)]
pub enum EstimationRefusal {
    /// Too few residuals of one parity.
    #[error(
        "motion-noise estimate: {have} doublets of one parity (allowed: at least \
         {MIN_DOUBLETS_PER_PARITY} of each)"
    )]
    TooFewDoublets {
        /// The fewer of the two parities.
        have: usize,
    },
    /// A residual that is not finite.
    #[error("motion-noise estimate: doublet {doublet}'s residual is not finite")]
    NotFinite {
        /// Doublet index.
        doublet: u32,
    },
    /// The residuals vary less than the stated sensor noise explains.
    #[error(
        "motion-noise estimate: the residuals vary less than the stated sensor noise \
         (sensing.controller_std) explains, even at the (1 − ε_est) upper bound: Q_high has \
         eigenvalue {eigenvalue:.3e} along {direction} (allowed: ≥ 0); the sensor's \
         calibration R is outside the model class"
    )]
    BelowSensorNoise {
        /// The negative eigenvalue (m² or rad²).
        eigenvalue: f64,
        /// Its direction in the robot's frame, for people.
        direction: String,
    },
    /// Tails that are not Gaussian: Mardia's multivariate kurtosis of the residuals is
    /// outside the Gaussian range at level ε_est.
    #[error(
        "motion-noise estimate: the residuals' multivariate kurtosis {kurtosis:.2} is not \
         Gaussian (allowed: 15 ± {tolerance:.2} at level ε_est): their tails are outside the \
         model class, and the region's Wishart bound does not hold"
    )]
    NotGaussian {
        /// Mardia's b₂ of the residuals.
        kurtosis: f64,
        /// The allowed distance from 15.
        tolerance: f64,
    },
    /// The residuals of doublets two apart correlate otherwise than the AR(1) model fitted to
    /// neighbours predicts: its innovations are not white.
    #[error(
        "motion-noise estimate: residuals of doublets two apart along the {axis} axis depart \
         from the AR(1) model fitted to neighbouring doublets: standardised statistic \
         {statistic:.1} (allowed: within ±{limit:.1} at level ε_est); the model's innovations \
         are not white, which the model class does not cover"
    )]
    NotWhite {
        /// "along-track", "lateral" or "heading".
        axis: &'static str,
        /// The standardised lag-1 statistic.
        statistic: f64,
        /// Its allowed magnitude.
        limit: f64,
    },
    /// The residuals' variance differs between the doublets' speed or turn-rate classes beyond
    /// what the fitted model (one `Q`, and per-wheel slip where the block measures it)
    /// explains: speed- or turn-dependent noise, or a turn-dependent residual the model
    /// leaves (the homogeneity test).
    #[error(
        "motion-noise estimate: the motion noise differs between the doublets' classes (by \
         {partition}, class {lo:.3}–{hi:.3} {unit}: measured/pooled variance along the {axis} axis \
         per class {ratios}, statistic {statistic:.1}, allowed: within ±{limit:.1} at level \
         ε_est): noise that depends on the speed or the turn beyond per-wheel slip, or a \
         turn-dependent residual the model leaves — outside the class this estimator covers \
         (one Q and per-wheel slip)",
        partition = .0.partition,
        lo = .0.range[0],
        hi = .0.range[1],
        unit = .0.unit,
        axis = .0.axis,
        ratios = format_ratios(&.0.ratios),
        statistic = .0.statistic,
        limit = .0.limit
    )]
    NotHomogeneous(ClassDeparture),
    /// Per-wheel slip measured beyond the class's range: σ²'s upper end above
    /// [`MAX_SLIP_STD`]².
    #[error(
        "motion-noise estimate: per-wheel slip measured: σ̂ = {point:.2} % of each wheel's \
         travel, interval [{lo:.2} %, {hi:.2} %] at level ε_est/3 (allowed: up to {max:.0} %, \
         the class's range)",
        point = 100.0 * .0.stds()[0],
        lo = 100.0 * .0.stds()[1],
        hi = 100.0 * .0.stds()[2],
        max = 100.0 * MAX_SLIP_STD
    )]
    SlipBeyondClass(SlipEstimate),
    /// The residuals identify the slip's presence but not its interval at ε_est/3.
    #[error(
        "motion-noise estimate: per-wheel slip measured at level ε_est, but the doublets' \
         speeds leave it unidentified at ε_est/3 (allowed: an identified interval)"
    )]
    SlipUnidentified,
    /// Neighbouring doublets' residuals anti-correlated beyond what AR(1) motion noise of
    /// ρ ≥ −½ explains (below −½ the two-step residual cannot identify ρ).
    #[error(
        "motion-noise estimate: neighbouring doublets' residuals are anti-correlated: motion \
         lag-one ratio {ratio:.3} (allowed: ≥ −0.125, AR(1) correlation ρ ≥ −0.5 between \
         steps); outside the model class"
    )]
    CorrelationOutsideClass {
        /// The pooled ratio of the lag-one motion product to the motion variance.
        ratio: f64,
    },
    /// The slip's or the timing jitter's share, somewhere in its interval, leaves no axis any
    /// motion variance for ρ's ratio to weigh.
    #[error(
        "motion-noise estimate: no axis may keep motion variance for the correlation between \
         steps once the slip's and the timing jitter's shares are taken out at some point of \
         their intervals (left per axis where least: {:.3e} m², {:.3e} m², {:.3e} rad²; \
         allowed: an axis above 0 at every point); outside the model class",
        motion_variance[0], motion_variance[1], motion_variance[2]
    )]
    CorrelationWithoutMotion {
        /// The motion variance left per axis where its largest is least (m², m², rad²).
        motion_variance: [f64; 3],
    },
    /// ρ's two intervals from the one-step residuals split at the middle samples (their
    /// lag-one ratio, and the ratio of the steps joined in pairs) do not meet: one of them
    /// misses, which the AR(1) model gives probability at most ε_est/2.
    #[error(
        "motion-noise estimate: the motion noise's correlation between steps measured from the \
         one-step residuals' lag-one ratio, [{:.3}, {:.3}], and from the steps joined in pairs, \
         [{:.3}, {:.3}], do not meet (allowed: intervals that meet, each at half the level of ρ's \
         interval); outside the model class",
        lag_one[0], lag_one[1], joined[0], joined[1]
    )]
    CorrelationDisjoint {
        /// The lag-one ratio's interval `[ρ_lo, ρ_hi]`.
        lag_one: [f64; 2],
        /// The joined pairs' interval.
        joined: [f64; 2],
    },
    /// Under measured slip, ρ's interval over σ²'s interval (each round of their joint
    /// region) misses the region of the round before: a statistic fails, which the model
    /// gives probability at most the two intervals' levels.
    #[error(
        "motion-noise estimate: under the measured per-wheel slip the motion noise's correlation \
         between steps measured over the slip's interval, [{:.3}, {:.3}], misses its interval of \
         the round before, [{:.3}, {:.3}] (allowed: intervals that meet); outside the model \
         class",
        now[0], now[1], before[0], before[1]
    )]
    CorrelationUnderSlip {
        /// The region of the round before.
        before: [f64; 2],
        /// This round's interval.
        now: [f64; 2],
    },
    /// The doublets' paths leave `Q` undetermined (the mean motion operator 𝓛̄ is singular;
    /// it is 2·id up to T·v and T·ω, so this takes degenerate input).
    #[error(
        "motion-noise estimate: the doublets' paths leave the motion noise undetermined (the \
         mean motion operator is singular)"
    )]
    Singular,
    /// ε_est outside (0, 1).
    #[error("motion-noise estimate: ε_est {0} (allowed: (0, 1))")]
    Epsilon(f64),
}

/// `𝓛̄_ρ` as a 6×6 matrix on the coordinates: column k is `𝓛̄_ρ(E_k)`, the mean motion
/// part of the residuals' covariance under AR(1) correlation `rho`.
fn mean_motion_operator(residuals: &[DoubletResidual], rho: f64) -> Matrix6<f64> {
    let n = residuals.len() as f64;
    let mut operator = Matrix6::zeros();
    for (k, q) in (0..6).map(|k| {
        (
            k,
            symmetric(&Vector6::from_fn(|i, _| f64::from(u8::from(i == k)))),
        )
    }) {
        let mean: Matrix3<f64> = residuals
            .iter()
            .map(|r| r.motion_part(&q, rho))
            .sum::<Matrix3<f64>>()
            / n;
        operator.set_column(k, &coordinates(&mean));
    }
    operator
}

fn second_moment<'a>(residuals: impl Iterator<Item = &'a DoubletResidual>) -> Moment {
    let mut count = 0;
    let mut sum = Matrix3::zeros();
    for r in residuals {
        count += 1;
        sum += r.value * r.value.transpose();
    }
    (count, sum / count.max(1) as f64)
}

/// The per-class ratios, slowest class first, for people: "[0.91, 1.02, …]".
fn format_ratios(ratios: &[f64]) -> String {
    let parts: Vec<String> = ratios.iter().map(|r| format!("{r:.2}")).collect();
    format!("[{}]", parts.join(", "))
}

/// Mardia's multivariate kurtosis of 3-dimensional Gaussian data, `p(p + 2)` at p = 3.
const GAUSSIAN_KURTOSIS: f64 = 15.0;

/// Mardia's kurtosis `b₂ = mean((zᵀS⁻¹z)²)` of the residuals, `S` their second moment
/// (0 when `S` is singular).
fn mardia_kurtosis(residuals: &[DoubletResidual], second_moment: &Matrix3<f64>) -> f64 {
    let Some(inverse) = second_moment.try_inverse() else {
        return 0.0;
    };
    kurtosis_whitened(residuals, |_| Some(inverse))
}

/// `mean((zᵢᵀWᵢzᵢ)²)` with `Wᵢ = inverse(rᵢ)`, each residual's inverse covariance (0 when one
/// has none).
fn kurtosis_whitened(
    residuals: &[DoubletResidual],
    inverse: impl Fn(&DoubletResidual) -> Option<Matrix3<f64>>,
) -> f64 {
    let mut sum = 0.0;
    for r in residuals {
        let Some(w) = inverse(r) else {
            return 0.0;
        };
        sum += r.value.dot(&(w * r.value)).powi(2);
    }
    sum / residuals.len().max(1) as f64
}

/// The two-sided (1 − ε) range of Mardia's b₂ around 15 for n residuals: b₂ is
/// asymptotically `N(15, 8p(p+2)/n) = N(15, 120/n)` for independent Gaussian data; the
/// neighbours' MA(1) correlation (at most ½ in every direction) at most doubles the
/// variance, and AR(1) motion noise inflates it by at most `inflation` (the correlation's
/// `F`), so `z·√(120·max(2, F)/n)` with `z` the normal quantile of ε/2.
fn kurtosis_tolerance(n: usize, epsilon: f64, inflation: f64) -> f64 {
    normal_upper_quantile(epsilon / 2.0) * (120.0 * inflation.max(2.0) / n.max(1) as f64).sqrt()
}

/// The covariance of independent components of standard deviations `std`: a stated
/// sensor calibration `R` (m², m², rad²).
#[must_use]
pub fn diagonal_covariance(std: [f64; 3]) -> Matrix3<f64> {
    Matrix3::from_diagonal(&nalgebra::Vector3::from(std.map(|s| s * s)))
}

/// Names a robot-frame direction for people.
fn describe_direction(v: &nalgebra::Vector3<f64>) -> String {
    format!(
        "({:.2} along-track, {:.2} lateral, {:.2} heading)",
        v[0], v[1], v[2]
    )
}

/// A set of residuals' count and second moment `(1/m) Σ r rᵀ`.
type Moment = (usize, Matrix3<f64>);

/// Each parity half's residual count and second moment, and the sensor's mean part of the
/// residuals' covariance, `(1/n) Σ S_R` (world frame `sensor` = `R`): what every fit of `Q`
/// starts from.
///
/// # Errors
/// A residual not finite, or fewer than [`MIN_DOUBLETS_PER_PARITY`] of a parity.
fn fit_inputs(
    residuals: &[DoubletResidual],
    sensor: &Matrix3<f64>,
) -> Result<([Moment; 2], Matrix3<f64>), EstimationRefusal> {
    if let Some(r) = residuals
        .iter()
        .find(|r| !r.value.iter().all(|v| v.is_finite()))
    {
        return Err(EstimationRefusal::NotFinite { doublet: r.doublet });
    }
    let halves = [0, 1]
        .map(|parity| second_moment(residuals.iter().filter(move |r| r.doublet % 2 == parity)));
    let fewest = halves.iter().map(|h| h.0).min().unwrap_or(0);
    if fewest < MIN_DOUBLETS_PER_PARITY {
        return Err(EstimationRefusal::TooFewDoublets { have: fewest });
    }
    let n = residuals.len() as f64;
    let sensor_mean: Matrix3<f64> = residuals
        .iter()
        .map(|r| r.sensor_part(sensor))
        .sum::<Matrix3<f64>>()
        / n;
    Ok((halves, sensor_mean))
}

/// `Q` (robot frame) whose mean motion operator at correlation `rho` explains the second
/// moment `m` beyond `sensor_mean`: `vech Q = A(ρ)⁻¹ vech(m − (1/n) Σ S_R)`.
fn solve_motion(
    residuals: &[DoubletResidual],
    sensor_mean: &Matrix3<f64>,
    m: Matrix3<f64>,
    rho: f64,
) -> Result<Matrix3<f64>, EstimationRefusal> {
    mean_motion_operator(residuals, rho)
        .lu()
        .solve(&coordinates(&(m - sensor_mean)))
        .map(|q| symmetric(&q))
        .ok_or(EstimationRefusal::Singular)
}

/// Estimates `Q` and its (1 − `epsilon`) region from `residuals` (each formed with the
/// reconciled bits) and the sensor's stated covariance `sensor` (`R`, world frame).
///
/// # Errors
/// [`EstimationRefusal`] naming the test and the value when the data fall outside the class.
pub fn estimate_motion_noise(
    residuals: &[DoubletResidual],
    sensor: &Matrix3<f64>,
    epsilon: f64,
) -> Result<MotionNoiseEstimate, EstimationRefusal> {
    region_estimate(
        residuals,
        None,
        sensor,
        epsilon,
        None,
        JitterVariances::default(),
    )
}

/// [`estimate_motion_noise`] for a two-step block from `steps`, its doublets' one-step
/// residuals split at their middle samples ([`DoubletResidual::two_step_split`]; indexed by
/// step, so each parity half is independent under white noise, as a three-step block's
/// one-step residuals are): `Q`, its Wishart bound, per-wheel slip and the class tests from
/// them, each residual one step's motion noise (and slip at that step's wheel speeds), and ρ,
/// its interval and the AR(1) model's whiteness tests from their two statistics
/// (`estimate_correlation_split`; docs/estimation.md, "Correlated motion noise" and
/// "The region").
///
/// # Errors
/// [`EstimationRefusal`] naming the test and the value when the data fall outside the class.
pub fn estimate_motion_noise_split(
    steps: &[DoubletResidual],
    sensor: &Matrix3<f64>,
    epsilon: f64,
) -> Result<MotionNoiseEstimate, EstimationRefusal> {
    region_estimate(
        steps,
        Some(steps),
        sensor,
        epsilon,
        None,
        JitterVariances::default(),
    )
}

/// [`estimate_motion_noise_split`] for `steps` whose sensor's part is taken at the timing
/// jitter's upper end ([`DoubletResidual::jitter_variance`]; `Q`'s bound and ρ's MA(1)
/// share), with the class tests — the speed and turn classes' homogeneity and the tails'
/// kurtosis, each residual whitened by its own modelled covariance — judged against the
/// model at the jitter's point `jitter.point` j² (s², at least 0), and slip's σ² fitted at
/// both the upper end `steps` carry and the lower end `jitter.lower`, its interval the hull
/// (docs/estimation.md, "Sample-timing jitter").
///
/// # Errors
/// [`EstimationRefusal`] naming the test and the value when the data fall outside the class.
pub fn estimate_motion_noise_timed(
    steps: &[DoubletResidual],
    sensor: &Matrix3<f64>,
    epsilon: f64,
    jitter: JitterVariances,
) -> Result<MotionNoiseEstimate, EstimationRefusal> {
    region_estimate(steps, Some(steps), sensor, epsilon, None, jitter)
}

/// [`estimate_motion_noise_timed`] for a three-step block's one-step residuals `steps`
/// ([`DoubletResidual::three_step_split`], the lagged means subtracted), ρ from their
/// lag-one ratio alone as [`estimate_motion_noise`] takes it, its interval the hull over
/// the jitter's `[0, j²_hi]` ([`estimate_correlation`]).
///
/// # Errors
/// [`EstimationRefusal`] naming the test and the value when the data fall outside the class.
pub fn estimate_three_step_motion_noise_timed(
    steps: &[DoubletResidual],
    sensor: &Matrix3<f64>,
    epsilon: f64,
    jitter: JitterVariances,
) -> Result<MotionNoiseEstimate, EstimationRefusal> {
    region_estimate(steps, None, sensor, epsilon, None, jitter)
}

/// The timing jitter's variances (s², each at least 0) a block's estimate takes
/// beside the upper end its residuals carry ([`DoubletResidual::jitter_variance`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct JitterVariances {
    /// The point j²: the class tests judge the residuals at it.
    pub point: f64,
    /// The interval's lower end: slip's σ² is fitted there too (less of the residuals'
    /// variance the sensor's, more left to slip), its interval the hull over both ends.
    pub lower: f64,
}

/// [`estimate_motion_noise`] with its region at `epsilon` (the Wishart bound and the
/// correlation's interval at half of it each), `Q` from `residuals`, ρ from them or, where
/// given, from one-step residuals `split` ([`estimate_motion_noise_split`]); `slip_epsilon`:
/// none to detect slip
/// at level `epsilon` (a block that measures it is estimated again, ε_est split in three:
/// the module doc), or the level its interval is sized at; `jitter`: the timing jitter's
/// point and lower end ([`estimate_motion_noise_timed`]; zeros where it is not modelled).
fn region_estimate(
    residuals: &[DoubletResidual],
    split: Option<&[DoubletResidual]>,
    sensor: &Matrix3<f64>,
    epsilon: f64,
    slip_epsilon: Option<f64>,
    jitter: JitterVariances,
) -> Result<MotionNoiseEstimate, EstimationRefusal> {
    if !(epsilon > 0.0 && epsilon < 1.0) {
        return Err(EstimationRefusal::Epsilon(epsilon));
    }
    let (halves, sensor_mean) = fit_inputs(residuals, sensor)?;
    let n = residuals.len() as f64;
    let solve = |m: Matrix3<f64>, rho: f64| solve_motion(residuals, &sensor_mean, m, rho);
    // The Wishart bound at ε_est/2 (the other half of ε_est is the correlation's interval),
    // its count divided by `deflation`: each parity half's `c₊` at a quarter of `epsilon`
    // (`wishart_upper_bounds`: the joint nets, `c₋` on the same event, or with few residuals
    // the upper side alone, `c₋` at its own quarter more); where slip is sized, both sides
    // bound Eve's view and hold on one event at that level (`slip_wishart_bounds`).
    let wishart_level = epsilon / 4.0;
    let bounds_at = |deflation: f64| -> [[f64; 2]; 2] {
        halves.map(|(m, _)| wishart_upper_bounds(m as f64 / deflation, wishart_level))
    };
    // `Σ_low` (over `c₊`, side 1) and `Σ_high` (over `c₋`, side 0): the halves' weighted
    // means; `Σ_high` none where a half's lower side has no room (`c₋ ≤ 0`).
    let weighted = |bounds: &[[f64; 2]; 2], side: usize| -> Matrix3<f64> {
        halves
            .iter()
            .zip(bounds)
            .map(|((m, s), c)| s * (*m as f64 / n) / c[side])
            .sum()
    };
    let high = |bounds: &[[f64; 2]; 2]| {
        bounds
            .iter()
            .all(|c| c[0] > 0.0)
            .then(|| weighted(bounds, 0))
    };
    // Residuals quieter than the sensor explains at every (Q ⪰ 0, ρ) of the class: the
    // upper bound at the lowest ρ (where the doublet's steps cancel most) has a negative
    // eigenvalue. Checked before ρ, which such residuals do not identify; where the counts
    // leave no upper bound, nothing is refused and `Q_high` is unbounded (infinite entries).
    let plain = bounds_at(1.0);
    let highest =
        |rho: f64| high(&plain).map_or(Ok(Matrix3::repeat(f64::INFINITY)), |m| solve(m, rho));
    let eigen = SymmetricEigen::new(highest(LOWEST_CORRELATION)?);
    let (k, &smallest) = eigen
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .unwrap_or((0, &0.0));
    if smallest < 0.0 {
        return Err(EstimationRefusal::BelowSensorNoise {
            eigenvalue: smallest,
            direction: describe_direction(&eigen.eigenvectors.column(k).into_owned()),
        });
    }
    // Slip's share is fitted beside the sensor's, which the residuals carry at the jitter's
    // upper end: the fit leaves slip the least there and the most at the lower end, so slip
    // is detected where either end shows it and σ²'s interval is the hull over both, each
    // end fitted with the upper end's weights and at one ρ, so that the hull holds at every
    // j² between (`estimate_slip_over_jitter`; docs/estimation.md, "Sample-timing jitter").
    let carried = residuals.first().map_or(0.0, |r| r.jitter_variance);
    let lower = (jitter.lower < carried).then_some(jitter.lower);
    let (measured, slip_fit) = match slip_epsilon {
        // Slip detected at level ε_est with ρ at its point, the slip's share not taken out —
        // the untested statistic's where the tested one departs: slip's share of the variance
        // leans ρ̂ towards 0, and the AR(1) model's lag-two products then depart from it.
        None => {
            let measured = match split {
                Some(steps) => {
                    estimate_correlation_split(steps, sensor, epsilon / 2.0, SlipShare::NONE)
                }
                None => estimate_correlation(residuals, sensor, epsilon / 2.0, SlipShare::NONE),
            };
            let point = match &measured {
                Ok(c) => Some(c.point),
                Err(_) => {
                    correlation_point(residuals, split, sensor, epsilon / 2.0, SlipShare::NONE).ok()
                }
            };
            let ends = point.and_then(|rho| match lower {
                Some(j2) => estimate_slip_over_jitter(residuals, sensor, rho, epsilon, j2)
                    .map(|e| [e.upper, e.lower]),
                None => estimate_slip(residuals, sensor, rho, epsilon).map(|e| [e, e]),
            });
            if ends.is_some_and(|e| e.iter().any(SlipEstimate::measured)) {
                return region_estimate(
                    residuals,
                    split,
                    sensor,
                    2.0 * epsilon / 3.0,
                    Some(epsilon / 3.0),
                    jitter,
                );
            }
            (measured, ends.map(|[upper, _]| upper))
        }
        Some(level) => {
            let (correlation, slip_fit) =
                joint_region(residuals, split, sensor, epsilon / 2.0, level, lower)?;
            (Ok(correlation), Some(slip_fit))
        }
    };
    let correlation = measured.map_err(correlation_refusal)?;
    let [rho_lo, rho_hi] = correlation.interval;
    let steps = residuals.first().map_or(2, |r| r.steps);
    let inflation = variance_inflation_for(rho_lo.abs().max(rho_hi.abs()), steps);
    // Within a parity half the residuals' dependence deflates the Wishart count (none for
    // white noise, whose halves are independent).
    let deflation = parity_inflation_for(rho_lo.abs().max(rho_hi.abs()), steps);
    let all = second_moment(residuals.iter()).1;
    let point = solve(all, correlation.point)?;
    let upper = highest(rho_lo)?;
    let cells = correlation_cells(correlation.interval);
    // Slip: sized at its share where the block measures it (above), none otherwise. The
    // homogeneity test is against the joint fit where slip is measured (departures beyond
    // slip are refused as such), otherwise against the white fit, as without slip.
    let slip = match (slip_epsilon, slip_fit) {
        (None, _) => None,
        (Some(_), None) => return Err(EstimationRefusal::SlipUnidentified),
        (Some(_), Some(fit)) if fit.stds()[2] > MAX_SLIP_STD => {
            return Err(EstimationRefusal::SlipBeyondClass(fit));
        }
        (Some(_), Some(fit)) => Some(fit),
    };
    let fitted = |r: &DoubletResidual, s: &SlipEstimate| {
        r.motion_part(&s.motion, correlation.point) + r.sensor_part(sensor) + r.slip_part(s.point)
    };
    // Where slip is sized, each half's bound over the residuals' unequal covariances
    // (`slip_wishart_bounds`), at σ²'s upper end.
    let region_bounds = match slip {
        None => bounds_at(deflation),
        Some(s) => [0, 1].map(|parity| {
            let half = residuals.iter().filter(|r| r.doublet % 2 == parity);
            let slip_maps: Vec<Matrix3<f64>> = half.clone().map(|r| r.slip_map).collect();
            let sensor_mean =
                half.map(|r| r.sensor_part(sensor)).sum::<Matrix3<f64>>() / slip_maps.len() as f64;
            slip_wishart_bounds(
                &slip_maps,
                &sensor_mean,
                &halves[parity as usize].1,
                s.interval[1].max(0.0),
                deflation,
                wishart_level,
            )
        }),
    };
    let low_moment = weighted(&region_bounds, 1);
    let slip_mean = |variance: f64| -> Matrix3<f64> {
        residuals
            .iter()
            .map(|r| r.slip_part(variance))
            .sum::<Matrix3<f64>>()
            / n
    };
    let vertices_at = |variance: f64| {
        let moment = low_moment - slip_mean(variance);
        cells
            .iter()
            .map(|&[a, b]| Ok([solve(moment, a)?, solve(moment, b)?]))
            .collect::<Result<Vec<[Matrix3<f64>; 2]>, EstimationRefusal>>()
    };
    // `Q_high(ρ, σ²)` above every cell's ends (as `Q_low` below them); none where the
    // Wishart bound's lower side has no room (`c₋ ≤ 0`).
    let upper_at = |variance: f64| -> Result<Option<Matrix3<f64>>, EstimationRefusal> {
        let Some(moment) = high(&region_bounds) else {
            return Ok(None);
        };
        let moment = moment - slip_mean(variance);
        let mut ends = cells.iter().flat_map(|&[a, b]| [a, b]);
        let first = solve(moment, ends.next().unwrap_or(rho_lo))?;
        ends.try_fold(first, |above, rho| {
            Ok(loewner_above_both(&above, &solve(moment, rho)?))
        })
        .map(Some)
    };
    let corners_of = |vertices: &[[Matrix3<f64>; 2]]| -> [Corner; CORRELATION_CELLS] {
        std::array::from_fn(|i| Corner {
            correlation: cells[i],
            motion: loewner_below_both(&vertices[i][0], &vertices[i][1]),
            step_weights: step_weights(cells[i]),
        })
    };
    let (corners, lower, slip_corners) = match slip {
        None => {
            let vertices = cells
                .iter()
                .map(|&[a, b]| Ok([solve(low_moment, a)?, solve(low_moment, b)?]))
                .collect::<Result<Vec<[Matrix3<f64>; 2]>, EstimationRefusal>>()?;
            (
                corners_of(&vertices),
                vertices[CORRELATION_CELLS - 1][1],
                None,
            )
        }
        Some(s) => {
            let [low, high] = s.interval.map(|v| v.max(0.0));
            // The grid's points on rayon's pool, the first refusal in the grid's order.
            let grid = (0..SLIP_GRID)
                .into_par_iter()
                .map(|i| {
                    let variance = low + (high - low) * i as f64 / (SLIP_GRID - 1) as f64;
                    Ok(SlipCorners {
                        variance,
                        corners: corners_of(&vertices_at(variance)?),
                        upper: upper_at(variance)?,
                    })
                })
                .collect::<Vec<Result<SlipCorners, EstimationRefusal>>>()
                .into_iter()
                .collect::<Result<Vec<SlipCorners>, EstimationRefusal>>()?;
            let highest_slip = vertices_at(high)?;
            (
                grid[SLIP_GRID - 1].corners,
                highest_slip[CORRELATION_CELLS - 1][1],
                Some(std::array::from_fn(|i| grid[i])),
            )
        }
    };
    // Where the block measures jitter, the class tests judge the residuals at its point
    // (without slip, `Q̂` solved again with the sensor's part there); the slip's joint fit
    // keeps the upper end's.
    let timed: Option<(Vec<DoubletResidual>, Matrix3<f64>)> = match slip {
        None if jitter.point > 0.0 => {
            let at_point: Vec<DoubletResidual> = residuals
                .iter()
                .map(|r| r.with_jitter(jitter.point))
                .collect();
            let (_, mean) = fit_inputs(&at_point, sensor)?;
            let q = solve_motion(&at_point, &mean, all, correlation.point)?;
            Some((at_point, q))
        }
        _ => None,
    };
    let tested_residuals = timed.as_ref().map_or(residuals, |(r, _)| r.as_slice());
    let (tested, slip_variance) = match (&timed, slip) {
        (Some((_, q)), _) => (*q, 0.0),
        (None, None) => (point, 0.0),
        (None, Some(s)) => (s.motion, s.point),
    };
    if let Some(departure) = speed_class_departure(
        tested_residuals,
        &tested,
        correlation.point,
        slip_variance,
        inflation,
        sensor,
        epsilon,
    ) {
        return Err(EstimationRefusal::NotHomogeneous(departure));
    }
    let kurtosis = match (&timed, slip) {
        (Some((at_point, q)), _) => kurtosis_whitened(at_point, |r| {
            (r.motion_part(q, correlation.point) + r.sensor_part(sensor)).try_inverse()
        }),
        (None, None) => mardia_kurtosis(residuals, &all),
        (None, Some(s)) => kurtosis_whitened(residuals, |r| fitted(r, &s).try_inverse()),
    };
    let tolerance = kurtosis_tolerance(residuals.len(), epsilon, inflation);
    if (kurtosis - GAUSSIAN_KURTOSIS).abs() > tolerance {
        return Err(EstimationRefusal::NotGaussian {
            kurtosis,
            tolerance,
        });
    }
    Ok(MotionNoiseEstimate {
        doublets: residuals.len(),
        point,
        correlation,
        lower,
        upper,
        corners,
        epsilon: epsilon + slip_epsilon.unwrap_or(0.0),
        slip: slip_fit,
        slip_corners,
    })
}

/// The refusal a correlation's departure from the class is reported as.
fn correlation_refusal(departure: CorrelationDeparture) -> EstimationRefusal {
    match departure {
        CorrelationDeparture::TooFewPairs { have } => {
            EstimationRefusal::TooFewDoublets { have: have / 2 }
        }
        CorrelationDeparture::Disjoint { lag_one, joined } => {
            EstimationRefusal::CorrelationDisjoint { lag_one, joined }
        }
        CorrelationDeparture::OutsideClass { ratio } => {
            EstimationRefusal::CorrelationOutsideClass { ratio }
        }
        CorrelationDeparture::NoMotionVariance { motion_variance } => {
            EstimationRefusal::CorrelationWithoutMotion { motion_variance }
        }
        CorrelationDeparture::NotAr1 {
            axis,
            statistic,
            limit,
        } => EstimationRefusal::NotWhite {
            axis: AXES[axis],
            statistic,
            limit,
        },
    }
}

/// ρ̂ at no level with the slip's share `slip` taken out: the untested statistics' point
/// (`correlation_untested`) or, where the middle samples' two intervals do not meet (as the
/// slip's share, before it is taken out, leans them apart), the lag-one ratio's of
/// `residuals` alone (a two-step block's one-step residuals: the first statistic).
///
/// # Errors
/// The statistics' departure from the class where neither gives a point.
fn correlation_point(
    residuals: &[DoubletResidual],
    split: Option<&[DoubletResidual]>,
    sensor: &Matrix3<f64>,
    epsilon: f64,
    slip: SlipShare,
) -> Result<f64, EstimationRefusal> {
    correlation_untested(residuals, split, sensor, epsilon, slip)
        .or_else(|_| correlation_untested(residuals, None, sensor, epsilon, slip))
        .map(|c| c.point)
        .map_err(correlation_refusal)
}

/// ρ's interval at `epsilon` and σ²'s at `slip_epsilon`, jointly, where the block measures
/// slip (docs/estimation.md, "Correlated motion noise", "Under slip"). Slip is independent
/// between steps: it adds `σ²·Mᵢ` to each residual's variance and nothing to the lag-one
/// product, so ρ's statistics take it out over σ²'s interval ([`SlipShare`]). σ²'s fit
/// (`estimate_slip`) is free of ρ: on one-step residuals (every sized block's: two-step
/// blocks' split at their middle samples, three-step blocks') `𝓛ᵢ,ρ(Q) = B₀QB₀ᵀ` holds no
/// ρ, and on residuals of two or three steps `Q` and each `ρᵈ·Q` are unknowns of their own,
/// which the truth satisfies at its ρ whatever it is; ρ (here the point with no slip share
/// taken out, a function of the data) sets only the weights. So σ²'s interval `S` — over
/// the timing jitter's `[lower, j²_hi]` where `lower` is given, the hull of its two ends at
/// one set of weights (`estimate_slip_over_jitter`) — is one interval, fitted once, that
/// holds σ² on its own event whatever ρ is. On that event and `ρ ∈ I_ρ(σ²)` at the truth's
/// own values (probability `1 − epsilon − slip_epsilon`) the truth lies in the region
/// `P = [−½, 0.999] ∩ I_ρ(S)`, met by ρ's statistics untested and then tested (the AR(1)
/// model's whiteness tests, [`estimate_correlation`], whose interval with jitter is also
/// hulled with the statistic at j² = 0: each holds ρ on that event, so both are kept). The
/// slip estimate returned is σ̂² and `Q̂` at that ρ (the jitter's upper end) with `S` as its
/// interval; ρ̂ and σ̂² are points, at no level.
///
/// # Errors
/// [`EstimationRefusal::SlipUnidentified`] where σ²'s fit is singular,
/// [`EstimationRefusal::CorrelationUnderSlip`] where ρ's tested interval misses its untested
/// one's region (a statistic fails, which the events give probability at most their sum),
/// and the correlation's departures from the class.
fn joint_region(
    residuals: &[DoubletResidual],
    split: Option<&[DoubletResidual]>,
    sensor: &Matrix3<f64>,
    epsilon: f64,
    slip_epsilon: f64,
    lower: Option<f64>,
) -> Result<(Correlation, SlipEstimate), EstimationRefusal> {
    let rho = correlation_point(residuals, split, sensor, epsilon, SlipShare::NONE)?;
    let slip = match lower {
        Some(j2) => estimate_slip_over_jitter(residuals, sensor, rho, slip_epsilon, j2)
            .map(|ends| ends.hull()),
        None => estimate_slip(residuals, sensor, rho, slip_epsilon),
    }
    .ok_or(EstimationRefusal::SlipUnidentified)?;
    let share = SlipShare {
        point: slip.point,
        interval: slip.interval,
    };
    let narrowed = |region: [f64; 2], c: &Correlation| {
        let next = [region[0].max(c.interval[0]), region[1].min(c.interval[1])];
        if next[0] > next[1] {
            return Err(EstimationRefusal::CorrelationUnderSlip {
                before: region,
                now: c.interval,
            });
        }
        Ok(next)
    };
    let untested = correlation_untested(residuals, split, sensor, epsilon, share)
        .map_err(correlation_refusal)?;
    let region = narrowed([LOWEST_CORRELATION, HIGHEST_CORRELATION], &untested)?;
    let c = match split {
        Some(steps) => estimate_correlation_split(steps, sensor, epsilon, share),
        None => estimate_correlation(residuals, sensor, epsilon, share),
    }
    .map_err(correlation_refusal)?;
    let region = narrowed(region, &c)?;
    Ok((
        Correlation {
            point: c.point.clamp(region[0], region[1]),
            interval: region,
        },
        slip,
    ))
}

/// Rounds of the slip path's fixed point at most (`slip_wishart_bounds`); it stops earlier
/// once `c₊` moves by less than `FIXED_POINT_TOLERANCE` of itself (every round's bound
/// holds, so where it stops sets only how tight the bound is).
const FIXED_POINT_ROUNDS: usize = 40;

/// The fixed point's relative step at which it stops.
const FIXED_POINT_TOLERANCE: f64 = 1e-6;

/// The slip path's caps of directions: the cube's face squares, this many per side
/// (`3k²` caps of `sin²θ = 2/k²`, `weighted_chi_square::Cap::of_faces`).
const SLIP_CAP_CUTS: u32 = 4;

/// `[c₋, c₊]` for one parity half of residuals with slip maps `slip_maps` (`Mᵢ`), mean sensor
/// part `sensor_mean` (`N̄`) and second moment `moment` (`S_half`), where the block sizes
/// slip: `c₋ ≤ λ_min(W) ≤ λ_max(W) ≤ c₊` for `W = Σ̄^(−½)·S_half·Σ̄^(−½)`, both failing
/// with probability at most `level` (one event: the nets' of `wishart::net_bounds`), given σ² ≤
/// `slip_high` (σ²'s interval, its own share of ε_est) and the sensor's stated `R`;
/// `dependence` the parity halves' count deflation under AR(1) (1 when white).
///
/// Each residual's covariance is `Σᵢ = P + σ²Mᵢ` (`P` the motion and sensor part, taken
/// common to the half as without slip), so along a standardised direction `v`
/// (`a = Σ̄^(−½)v`) `m·vᵀWv = Σᵢ wᵢξᵢ²`, ξᵢ independent standard normals, with weights
/// `wᵢ = aᵀΣᵢa/aᵀΣ̄a = 1 + σ²·aᵀDᵢa/aᵀΣ̄a`, `Dᵢ = Mᵢ − M̄` (mean 1): a weighted χ² whose
/// weights all come from one direction. For a floor `L = CCᵀ` with `σ²·aᵀLa ≤ σ²_hi·aᵀΣ̄a`
/// and `b = Cᵀa/|Cᵀa|`,
///
/// ```text
/// wᵢ = 1 + t·bᵀEᵢb,   Eᵢ = σ²_hi·C⁻¹DᵢC⁻ᵀ,   t = σ²·aᵀLa/(σ²_hi·aᵀΣ̄a) ∈ [0, 1],
/// ```
///
/// one `b` and one `t` for every term (`ΣEᵢ = 0`): `DirectionalChiSquare` bounds the tails
/// over every `t` and every `b` in a cap (`weighted_chi_square`), and each net line's
/// quantile (`wishart::net_bounds`) is at most the most extreme over the `3k²` caps of the
/// cube's face squares (`SLIP_CAP_CUTS`), which hold every line. Two floors, each a bound of
/// its own (the least upper and the greatest lower quantile of the two taken): `L = N̄ +
/// σ²_hi·M̄` (`Σ̄ ⪰ N̄ + σ²M̄`, the motion's part being a covariance, and `σ²/(n + σ²μ̄)`
/// rises with σ²), and `L = S_half/c` for a `c` above the truth's `c₊` (where
/// `λ_max(W) ≤ c₊`, `Σ̄ ⪰ S_half/c₊`).
///
/// The circle — `c₊` from weights that need a floor under `Σ̄` — is broken by a fixed point
/// on one event: `E`, every line of the nets within its exact quantiles at the truth's own
/// weights (the nets χ²_m's choice, fixed by m and the level; no data in it), of probability
/// at least `1 − level`. For any valid floor `L` the truth's weights are among those the caps
/// and t allow, so the computed quantiles lie outside the exact ones and, on `E`,
/// `λ_min(W) ≥ c₋(L)` and `λ_max(W) ≤ c₊(L)` (`covered` rises with the upper quantile and
/// falls with the lower). The sensor's floor is valid without data; on `E` each round's
/// `c₊` makes `Σ̄ ⪰ S_half/c₊` valid for the next, so every round's `[c₋, c₊]` is a bound on
/// that one event — no further share of ε — and the last is kept.
fn slip_wishart_bounds(
    slip_maps: &[Matrix3<f64>],
    sensor_mean: &Matrix3<f64>,
    moment: &Matrix3<f64>,
    slip_high: f64,
    dependence: f64,
    level: f64,
) -> [f64; 2] {
    let m = slip_maps.len() as f64;
    let mean_slip = slip_maps.iter().sum::<Matrix3<f64>>() / m;
    let sensor_floor = sensor_mean + slip_high * mean_slip;
    let spreads: Vec<Matrix3<f64>> = slip_maps
        .iter()
        .map(|map| slip_high * (map - mean_slip))
        .collect();
    let caps = Cap::of_faces(SLIP_CAP_CUTS);
    let bounds_over = |floors: &[Matrix3<f64>]| -> [f64; 2] {
        let families: Vec<DirectionalChiSquare> = floors
            .iter()
            .filter_map(|l| l.cholesky().and_then(|c| c.l().try_inverse()))
            .map(|w| {
                let whitened = spreads.iter().map(|d| w * d * w.transpose()).collect();
                DirectionalChiSquare::new(whitened, dependence)
            })
            .collect();
        net_bounds(
            m,
            level,
            |ln_p| {
                families
                    .iter()
                    .map(|f| f.upper_quantile(&caps, ln_p))
                    .fold(f64::INFINITY, f64::min)
            },
            |ln_p| {
                families
                    .iter()
                    .map(|f| f.lower_quantile(&caps, ln_p))
                    .fold(f64::NEG_INFINITY, f64::max)
            },
        )
    };
    let mut bounds = bounds_over(&[sensor_floor]);
    for _ in 0..FIXED_POINT_ROUNDS {
        if !bounds[1].is_finite() {
            break;
        }
        let next = bounds_over(&[sensor_floor, moment / bounds[1]]);
        let settled = next[1] >= bounds[1] * (1.0 - FIXED_POINT_TOLERANCE);
        bounds = next;
        if settled {
            break;
        }
    }
    bounds
}

/// The correlation's interval cut into [`CORRELATION_CELLS`] equal cells.
fn correlation_cells([lo, hi]: [f64; 2]) -> [[f64; 2]; CORRELATION_CELLS] {
    let at = |i: usize| lo + (hi - lo) * i as f64 / CORRELATION_CELLS as f64;
    std::array::from_fn(|i| [at(i), at(i + 1)])
}

/// A matrix below both `a` and `b` in the Loewner order: `b − [a − b]₋`, with `[M]₋` the
/// negative part of `M` (so it equals `a − [a − b]₊` too). With `𝓛̄_ρ ≈ 2(1 + ρ)·id`,
/// `Q_low(ρ)` moves monotonically between a cell's ends along each eigenvector of
/// `Σ_low − N̄`, so this bounds it over the whole cell.
pub(crate) fn loewner_below_both(a: &Matrix3<f64>, b: &Matrix3<f64>) -> Matrix3<f64> {
    let eigen = SymmetricEigen::new(a - b);
    let negative = eigen.eigenvalues.map(|x| x.min(0.0));
    b + eigen.eigenvectors * Matrix3::from_diagonal(&negative) * eigen.eigenvectors.transpose()
}

/// A matrix above both `a` and `b` in the Loewner order: `b + [a − b]₊`, with `[M]₊` the
/// positive part of `M` — `Q_high(ρ)` over a cell, as [`loewner_below_both`] bounds `Q_low`.
fn loewner_above_both(a: &Matrix3<f64>, b: &Matrix3<f64>) -> Matrix3<f64> {
    -loewner_below_both(&-a, &-b)
}

/// `[α, β]` below (`[0]`) and above (`[1]`) the two steps' conditional covariance for every
/// ρ in `[ρ_a, ρ_b]`.
///
/// Given the noise of the steps just before and after a doublet (its Markov blanket under
/// AR(1); Eve's genie view gives her the neighbours' bits, and this gives her more), the
/// doublet's two steps have covariance `Q ⊗ C(ρ)`, `C(ρ) = (1 − ρ²)/((1 + ρ²)² − ρ²)·
/// [[1 + ρ², ρ], [ρ, 1 + ρ²]]`, whose eigenvectors `(1, ±1)` do not depend on ρ and whose
/// eigenvalues `λ± = (1 − ρ²)/(1 + ρ² ∓ ρ)` are unimodal in ρ, peaking at `ρ = ±(2 − √3)`
/// — their least over a cell is at one of its ends, their greatest there or at the peak.
/// `α = (λ₊ + λ₋)/2`, `β = (λ₊ − λ₋)/2`; `[1, 0]` at ρ = 0 (white).
fn step_weights([a, b]: [f64; 2]) -> [[f64; 2]; 2] {
    let lambda = |rho: f64, sign: f64| (1.0 - rho * rho) / (1.0 + rho * rho - sign * rho);
    let least = |sign: f64| lambda(a, sign).min(lambda(b, sign));
    let greatest = |sign: f64| {
        let peak = sign * (2.0 - 3f64.sqrt());
        let ends = lambda(a, sign).max(lambda(b, sign));
        if (a..=b).contains(&peak) {
            ends.max(lambda(peak, sign))
        } else {
            ends
        }
    };
    let weights = |plus: f64, minus: f64| [0.5 * (plus + minus), 0.5 * (plus - minus)];
    [
        weights(least(1.0), least(-1.0)),
        weights(greatest(1.0), greatest(-1.0)),
    ]
}

impl MotionNoiseEstimate {
    /// The degenerate region of a world whose stationary motion noise `q` (robot frame) and
    /// correlation `rho` are known: every corner at the truth. What a pair configured with
    /// the true world sizes from, for comparison in the simulator.
    #[must_use]
    pub fn known(q: Matrix3<f64>, rho: f64, epsilon: f64) -> Self {
        let cell = [rho, rho];
        Self {
            doublets: 0,
            point: q,
            correlation: Correlation {
                point: rho,
                interval: cell,
            },
            lower: q,
            upper: q,
            corners: [Corner {
                correlation: cell,
                motion: q,
                step_weights: step_weights(cell),
            }; CORRELATION_CELLS],
            epsilon,
            slip: None,
            slip_corners: None,
        }
    }

    /// [`Self::known`] with per-wheel slip of known variance `slip_variance` (σ²): the
    /// region's corners at the truth, sized with the slip at that one point.
    #[must_use]
    pub fn known_with_slip(q: Matrix3<f64>, rho: f64, slip_variance: f64, epsilon: f64) -> Self {
        let known = Self::known(q, rho, epsilon);
        Self {
            slip: Some(SlipEstimate {
                point: slip_variance,
                interval: [slip_variance; 2],
                motion: q,
            }),
            slip_corners: Some(
                [SlipCorners {
                    variance: slip_variance,
                    corners: known.corners,
                    upper: Some(q),
                }; SLIP_GRID],
            ),
            ..known
        }
    }

    /// Standard deviations `√Q_kk` of the point estimate and the lower vertex (m, m, rad;
    /// the vertex's negative diagonal entries read 0), for people.
    #[must_use]
    pub fn stds(&self) -> [[f64; 3]; 2] {
        [self.point, self.lower].map(|m| [0, 1, 2].map(|k| m[(k, k)].max(0.0).sqrt()))
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::super::wishart::wishart_bounds;
    use super::*;
    use crate::config::Config;
    use crate::model::{Pose, Unicycle};
    use crate::private::{DoubletInputs, doublet_model};
    use crate::rng::{Purpose, stream};
    use rand::RngExt;
    use rand_distr::{Distribution, StandardNormal};

    /// Residuals of `doublets` consecutive straight and turning doublets whose controller
    /// samples carry white motion noise `q_std` and sensor noise `r_std` (world frame,
    /// isotropic in position), simulated through the Euler map with the bits that rode.
    fn residuals(
        doublets: u32,
        q_std: [f64; 3],
        r_std: [f64; 3],
        seed: u64,
    ) -> Vec<DoubletResidual> {
        simulated_residuals(
            doublets,
            r_std,
            seed,
            straight_and_turning,
            |_, _, normal| {
                Pose::new(
                    q_std[0] * normal(),
                    q_std[1] * normal(),
                    q_std[2] * normal(),
                )
            },
        )
    }

    /// Doublet `j`'s nominal inputs in the tests: 0.1 m/s, straight three doublets in seven,
    /// turning at 0.4 rad/s the other four.
    pub(in crate::estimate) fn straight_and_turning(j: u32) -> DoubletInputs {
        let turn = if j % 7 < 3 { 0.0 } else { 0.4 };
        DoubletInputs {
            first: Unicycle::new(0.1, turn),
            second: Unicycle::new(0.1, turn),
        }
    }

    /// Residuals of `doublets` consecutive doublets of nominal inputs `inputs(j)`, each step's
    /// world-frame motion noise `motion(applied input, heading, a standard normal source)`, and
    /// sensor noise `r_std` (world frame), simulated through the Euler map with the bits that
    /// rode.
    pub(in crate::estimate) fn simulated_residuals(
        doublets: u32,
        r_std: [f64; 3],
        seed: u64,
        inputs: impl Fn(u32) -> DoubletInputs,
        motion: impl Fn(&Unicycle, f64, &mut dyn FnMut() -> f64) -> Pose,
    ) -> Vec<DoubletResidual> {
        simulated_doublets(doublets, r_std, seed, inputs, motion).0
    }

    /// [`simulated_residuals`] and the same doublets' one-step residuals split at their
    /// middle samples ([`DoubletResidual::two_step_split`], two per doublet), the middle
    /// samples' sensor noise drawn from a stream of their own (the doublets' residuals are
    /// `simulated_residuals`' draw for draw).
    pub(in crate::estimate) fn simulated_doublets(
        doublets: u32,
        r_std: [f64; 3],
        seed: u64,
        inputs: impl Fn(u32) -> DoubletInputs,
        motion: impl Fn(&Unicycle, f64, &mut dyn FnMut() -> f64) -> Pose,
    ) -> (Vec<DoubletResidual>, Vec<DoubletResidual>) {
        let model = doublet_model(&Config::default());
        let axle = Config::default().robot.axle_length;
        let mut rng = stream(seed, Purpose::Process, 0);
        let mut normal =
            || <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut rng);
        let mut middle_rng = stream(seed, Purpose::Measurement, 0);
        let mut middle_normal =
            || <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut middle_rng);
        let t = model.sample_time;
        let mut x = Pose::new(0.0, 0.0, 0.3);
        let sensed = |x: &Pose, normal: &mut dyn FnMut() -> f64| {
            x + Pose::new(
                r_std[0] * normal(),
                r_std[1] * normal(),
                r_std[2] * normal(),
            )
        };
        let mut y_start = sensed(&x, &mut normal);
        let (mut whole, mut split) = (Vec::new(), Vec::new());
        for j in 0..doublets {
            let inputs = inputs(j);
            let pattern = (j as usize * 5 + 1) % 3 % 2;
            let [a, b] = inputs.applied(model.perturbation.offset(pattern));
            let mut y_middle = x;
            for (k, u) in [a, b].iter().enumerate() {
                let heading = x.z;
                x = crate::model::unicycle_step(&x, u, t) + motion(u, heading, &mut normal);
                if k == 0 {
                    y_middle = sensed(&x, &mut middle_normal);
                }
            }
            let y_end = sensed(&x, &mut normal);
            whole.push(DoubletResidual::new(
                &model, axle, j, &inputs, &y_start, &y_end, pattern,
            ));
            split.extend(DoubletResidual::two_step_split(
                &model,
                axle,
                j,
                &inputs,
                [&y_start, &y_middle, &y_end],
                pattern,
            ));
            y_start = y_end;
        }
        (whole, split)
    }

    use super::diagonal_covariance as covariance;

    /// The step weights of a correlation cell, for the worst case's tests.
    pub(in crate::estimate) fn weights_of(cell: [f64; 2]) -> [[f64; 2]; 2] {
        step_weights(cell)
    }

    /// The point estimate is unbiased with the sensor term removed: over 20,000 doublets
    /// each diagonal entry's relative standard error is √(2/n)·(Q + R)/Q ≈ 1 % at 1 mm
    /// against 0.5 mm; the tolerance is 5 of them.
    #[test]
    fn the_point_estimate_recovers_q_with_the_sensor_term_removed() {
        for (q, r) in [
            ([1e-3, 1e-3, 1e-3], [5e-4, 5e-4, 5e-4]),
            ([4e-3, 4e-3, 4e-3], [5e-4, 5e-4, 5e-4]),
        ] {
            let data = residuals(20_000, q, r, 11);
            let e = estimate_motion_noise(&data, &covariance(r), 1e-6).unwrap();
            for k in 0..3 {
                let (truth, noise) = (q[k] * q[k], r[k] * r[k]);
                let se = (2.0 / 20_000_f64).sqrt() * (truth + noise) / truth;
                let rel = e.point[(k, k)] / truth - 1.0;
                assert!(
                    rel.abs() < 5.0 * se,
                    "{q:?} axis {k}: {} vs {truth} ({rel})",
                    e.point[(k, k)]
                );
            }
            assert!(e.point[(0, 1)].abs() < 5.0 * (2.0 / 20_000_f64).sqrt() * 2.0 * q[0] * q[0]);
        }
    }

    /// The region holds: the true Q lies above the lower vertex in every direction (its
    /// smallest eigenvalue of Q − Q_low ≥ 0) and below the upper one, on 40 seeds at
    /// ε_est = 0.05 (a failure every 20 blocks at most; the Wishart bound is conservative,
    /// so none is expected), and the lower vertex is as tight as the bound says: at 4,000
    /// doublets (2,000 per parity) `1/c₊ = 0.873`, so along position
    /// `Q_low/Q ≈ ((2Q + 2R)/c₊ − 2R)/(2Q) = 0.841` at Q = 1 mm², R = 0.25 mm², with a
    /// sampling standard error of `√(2/4000)·(Q + R)/Q ≈ 2.8 %`: asserted above 0.841 − 4·0.028
    /// once the correlation's share is taken out (the lowest vertex sits at `ρ_hi`).
    #[test]
    fn the_region_contains_the_truth_and_is_tight() {
        let (q, r) = ([1e-3, 1e-3, 2e-3], [5e-4, 5e-4, 5e-4]);
        let truth = covariance(q);
        let mut misses = 0;
        for seed in 0..40 {
            let data = residuals(4_000, q, r, 100 + seed);
            let e = estimate_motion_noise(&data, &covariance(r), 0.05).unwrap();
            let below = SymmetricEigen::new(truth - e.lower).eigenvalues.min();
            let above = SymmetricEigen::new(e.upper - truth).eigenvalues.min();
            misses += usize::from(below < 0.0 || above < 0.0);
            // The lowest vertex sits at ρ_hi, where 𝓛̄_ρ ≈ 2(1 + ρ)·id: 1/(1 + ρ_hi) lower.
            let shrink = 1.0 + e.correlation.interval[1];
            for k in 0..3 {
                assert!(
                    e.lower[(k, k)] * shrink > 0.729 * truth[(k, k)],
                    "seed {seed}: {} {:?}",
                    e.lower,
                    e.correlation
                );
            }
        }
        assert!(misses <= 2, "{misses} of 40 regions miss the truth");
    }

    /// Laplace-tailed motion noise (kurtosis 6 per axis, against 3) is refused by the tail
    /// test at ε_est = 10⁻⁶ over 4,000 doublets (tolerance 4.9·√(240/4000) ≈ 1.3 around 15,
    /// where the measured b₂ is ≈ 20); Gaussian noise on 20 seeds passes it.
    #[test]
    fn heavy_tails_are_refused_and_gaussian_ones_are_not() {
        let r = [5e-4, 5e-4, 5e-4];
        for seed in 0..20 {
            let data = residuals(4_000, [2e-3; 3], r, 300 + seed);
            assert!(
                estimate_motion_noise(&data, &covariance(r), 1e-6).is_ok(),
                "seed {seed}"
            );
        }
        let mut rng = stream(9, Purpose::Process, 1);
        let heavy: Vec<DoubletResidual> = residuals(4_000, [0.0; 3], r, 3)
            .into_iter()
            .map(|mut d| {
                for k in 0..3 {
                    // A Laplace variate of standard deviation 2 mm: the difference of two
                    // exponentials.
                    let u: f64 = rng.random_range(1e-12..1.0);
                    let v: f64 = rng.random_range(1e-12..1.0);
                    d.value[k] += 2e-3 / 2f64.sqrt() * (u.ln() - v.ln());
                }
                d
            })
            .collect();
        let error = estimate_motion_noise(&heavy, &covariance(r), 1e-6).unwrap_err();
        assert!(
            matches!(error, EstimationRefusal::NotGaussian { .. }),
            "{error}"
        );
    }

    /// AR(1) motion noise is measured, not refused: at ρ = 0.5 and 0.9 over 10,000 doublets
    /// (1 mm per axis against the sensor's 0.5 mm) ρ's interval holds the truth, `Q̂` is
    /// within 10 % of it (the ratio's standard error ≈ √(2F/n)·(Q + R)/Q ≈ 2–4 %), and the
    /// joint region's corners lie below the truth in every direction — the truth's own
    /// cell's `Q_cell ⪯ Q` — on 5 seeds each at ε_est = 10⁻⁶.
    #[test]
    fn correlated_motion_noise_is_measured_and_bounded() {
        use crate::estimate::correlation::tests::ar1_residuals;
        let sensor = covariance([5e-4; 3]);
        let truth = covariance([1e-3; 3]);
        for rho in [0.5, 0.9] {
            for seed in 0..5 {
                let data = ar1_residuals(10_000, 1e-3, rho, 60 + seed);
                let e = estimate_motion_noise(&data, &sensor, 1e-6)
                    .unwrap_or_else(|error| panic!("ρ {rho} seed {seed}: {error}"));
                let [lo, hi] = e.correlation.interval;
                assert!(
                    lo <= rho && rho <= hi,
                    "ρ {rho} seed {seed}: {:?}",
                    e.correlation
                );
                for k in 0..3 {
                    let rel = e.point[(k, k)] / truth[(k, k)] - 1.0;
                    assert!(rel.abs() < 0.1, "ρ {rho} seed {seed} axis {k}: {rel}");
                }
                let cell = e
                    .corners
                    .iter()
                    .find(|c| c.correlation[0] <= rho && rho <= c.correlation[1])
                    .unwrap();
                let below = SymmetricEigen::new(truth - cell.motion).eigenvalues.min();
                assert!(below >= 0.0, "ρ {rho} seed {seed}: {}", cell.motion);
            }
        }
    }

    /// One-step residuals ([`DoubletResidual::three_step_split`]) of `doublets` consecutive
    /// three-step doublets (a 50 ms prior lag, [`straight_and_turning`] inputs) whose steps
    /// carry AR(1) motion noise of correlation `rho` and `q_std` per axis (robot frame at
    /// the step's heading, isotropic in position) and whose samples carry sensor noise
    /// `r_std`, simulated through the Euler map at the steps' lagged mean speeds.
    fn split_residuals(
        doublets: u32,
        q_std: [f64; 3],
        rho: f64,
        r_std: [f64; 3],
        seed: u64,
    ) -> Vec<DoubletResidual> {
        let mut config = Config::default();
        config.sensing.mode = crate::config::SensingMode::Private;
        config.private.prior_lag = 0.05;
        let model = doublet_model(&config);
        assert_eq!(model.perturbation.steps(), 3);
        let mut rng = stream(seed, Purpose::Process, 0);
        let mut normal =
            || <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut rng);
        let t = model.sample_time;
        let innovation = (1.0 - rho * rho).sqrt();
        let mut w = [0, 1, 2].map(|k| q_std[k] * normal());
        let mut x = Pose::new(0.0, 0.0, 0.3);
        let sensed = |x: &Pose, normal: &mut dyn FnMut() -> f64| {
            x + Pose::from_fn(|k, _| r_std[k] * normal())
        };
        let mut y = sensed(&x, &mut normal);
        let mut out = Vec::new();
        for j in 0..doublets {
            let inputs = straight_and_turning(j);
            let pattern = (j as usize * 5 + 1) % 3 % 2;
            let entry = inputs.first;
            let (applied, _) =
                DoubletResidual::three_step_means(&model, &inputs, &y, pattern, entry);
            let mut samples = [y; 4];
            for (k, u) in applied.iter().enumerate() {
                let (sin, cos) = x.z.sin_cos();
                let noise = Pose::new(cos * w[0] - sin * w[1], sin * w[0] + cos * w[1], w[2]);
                x = crate::model::unicycle_step(&x, u, t) + noise;
                w = [0, 1, 2].map(|a| rho * w[a] + innovation * q_std[a] * normal());
                samples[k + 1] = sensed(&x, &mut normal);
            }
            out.extend(DoubletResidual::three_step_split(
                &model,
                config.robot.axle_length,
                j,
                &inputs,
                [&samples[0], &samples[1], &samples[2], &samples[3]],
                pattern,
                entry,
            ));
            y = samples[3];
        }
        out
    }

    /// The region from a three-step doublet's one-step residuals holds: neighbouring steps
    /// share a sample (their residuals correlate by `−R/(Q + 2R)` per position axis, −⅓ at
    /// Q = R), and residuals two steps apart share none, so each parity half of the step
    /// index is independent under white noise and the Wishart bound is exact there. Over 200
    /// blocks of 1,000 doublets (3,000 residuals) at ε_est = 0.05, at 4 mm and at 0.5 mm of
    /// white motion noise against the sensor's 0.5 mm and at 4 mm with ρ = 0.5, `Q − Q_low`
    /// and `Q_high − Q` are positive semidefinite and ρ's interval holds the truth in all but
    /// at most 19 of those the class tests size (10 expected were the bound exact; 19 is 3
    /// binomial standard deviations above; at this ε the tests refuse some). The lower vertex
    /// is as tight as the bound says: at 1,500 residuals per parity `1/c₊ = 0.860`, so along
    /// position `Q_low/Q ≈ ((Q + 2R)/c₊ − 2R)/Q`, 0.856 at 4 mm and
    /// 0.581 at 0.5 mm, with the sample second moment's standard error
    /// `√(2/3000)·(Q + 2R)/Q` (2.6 % and 7.7 %; the shared samples inflate it by at most
    /// `√(1 + 2/9)`): the mean over the blocks within 4 of those errors divided by √200.
    #[test]
    fn one_step_residuals_of_three_step_doublets_bound_q() {
        let sensor = [5e-4; 3];
        for (q_std, rho) in [(4e-3, 0.0), (5e-4, 0.0), (4e-3, 0.5)] {
            let truth = covariance([q_std; 3]);
            let (q, r) = (q_std * q_std, sensor[0] * sensor[0]);
            let (mut misses, mut refused, mut shares) = (0, 0, Vec::new());
            for seed in 0..200 {
                let data = split_residuals(1_000, [q_std; 3], rho, sensor, 500 + seed);
                let Ok(e) = estimate_motion_noise(&data, &covariance(sensor), 0.05) else {
                    refused += 1;
                    continue;
                };
                let below = SymmetricEigen::new(truth - e.lower).eigenvalues.min();
                let above = SymmetricEigen::new(e.upper - truth).eigenvalues.min();
                let [lo, hi] = e.correlation.interval;
                misses += usize::from(below < 0.0 || above < 0.0 || rho < lo || rho > hi);
                shares.push(e.lower[(0, 0)] / q);
            }
            eprintln!(
                "Q {q_std} ρ {rho}: {misses} misses, {refused} refused, mean Q_low/Q {:.4}",
                shares.iter().sum::<f64>() / shares.len() as f64
            );
            assert!(
                misses <= 19,
                "Q {q_std} ρ {rho}: {misses} of 200 regions miss the truth"
            );
            assert!(refused <= 50, "Q {q_std} ρ {rho}: {refused} of 200 refused");
            if rho == 0.0 {
                let c = wishart_upper_bounds(1_500.0, 0.0125)[1];
                let predicted = ((q + 2.0 * r) / c - 2.0 * r) / q;
                let error =
                    (2.0 / 3_000_f64).sqrt() * (q + 2.0 * r) / q * (1.0 + 2.0 / 9.0_f64).sqrt();
                let mean = shares.iter().sum::<f64>() / shares.len() as f64;
                assert!(
                    (mean - predicted).abs() < 4.0 * error / (shares.len() as f64).sqrt(),
                    "Q {q_std}: Q_low/Q {mean} against {predicted} ± {error}"
                );
            }
        }
    }

    /// One draw of a parity half's whitened second moment `W = Σ̄^(−½)SΣ̄^(−½)` for residuals
    /// of covariances `covariances` (`Σ̄` their mean): its extreme eigenvalues.
    fn whitened_extremes(
        covariances: &[Matrix3<f64>],
        normal: &mut dyn FnMut() -> f64,
    ) -> [f64; 2] {
        let m = covariances.len() as f64;
        let mean = covariances.iter().sum::<Matrix3<f64>>() / m;
        let whiten = mean.cholesky().unwrap().l().try_inverse().unwrap();
        let mut s = Matrix3::zeros();
        for c in covariances {
            let z =
                c.cholesky().unwrap().l() * nalgebra::Vector3::new(normal(), normal(), normal());
            s += z * z.transpose();
        }
        let e = SymmetricEigen::new(whiten * (s / m) * whiten.transpose()).eigenvalues;
        [e.min(), e.max()]
    }

    /// Residuals whose slip parts are rank one along the four directions of a tetrahedron
    /// (`Mᵢ = uᵢuᵢᵀ`, 25 residuals each, over a sensor part of 10⁻³·I): every residual's
    /// covariance has the same diagonal, so the count's former deflation (`m·Σv²/(Σv)²` per
    /// axis) is 1 and the bound was the χ² net bound at m = 100, while along each `uₖ` the
    /// weights are 3 and ⅓ (an effective count of about 43). Over 20,000 seeded draws at
    /// level 0.02 (both sides on one event: 400 misses expected at most; 480 is 4 binomial
    /// standard deviations above, reached with probability below 10⁻⁴ by a bound that holds)
    /// that bound misses beyond it — and on each side beyond 256, 4 standard deviations above
    /// ε/2's 200: it under-covers — and the weighted bound's misses stay within it.
    #[test]
    fn unequal_covariances_defeat_the_deflated_count_and_not_the_weighted_bound() {
        let directions = crate::estimate::weighted_chi_square::tests::tetrahedron_directions();
        let (epsilon, draws) = (0.02, 20_000);
        let maps: Vec<Matrix3<f64>> = (0..100)
            .map(|i| directions[i % 4] * directions[i % 4].transpose())
            .collect();
        let sensor = Matrix3::identity() * 1e-3;
        let covariances: Vec<Matrix3<f64>> = maps.iter().map(|m| sensor + m).collect();
        let mean = covariances.iter().sum::<Matrix3<f64>>() / 100.0;
        let axis_deflation = (0..3)
            .map(|k| {
                let v: Vec<f64> = covariances.iter().map(|c| c[(k, k)]).collect();
                100.0 * v.iter().map(|x| x * x).sum::<f64>() / v.iter().sum::<f64>().powi(2)
            })
            .fold(1.0, f64::max);
        assert!((axis_deflation - 1.0).abs() < 1e-12, "{axis_deflation}");
        let deflated = wishart_bounds(100.0 / axis_deflation, epsilon);
        let weighted = slip_wishart_bounds(&maps, &sensor, &mean, 1.0, 1.0, epsilon);
        let mut rng = stream(77, Purpose::Process, 0);
        let mut normal =
            || <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut rng);
        let misses = |bounds: [f64; 2], [least, most]: [f64; 2]| {
            [most > bounds[1], most <= bounds[1] && least < bounds[0]].map(usize::from)
        };
        let (mut old, mut new) = ([0, 0], [0, 0]);
        for _ in 0..draws {
            let extremes = whitened_extremes(&covariances, &mut normal);
            for (count, bounds) in [(&mut old, deflated), (&mut new, weighted)] {
                let m = misses(bounds, extremes);
                count[0] += m[0];
                count[1] += m[1];
            }
        }
        eprintln!(
            "deflated {deflated:?}: {old:?} above, below; weighted {weighted:?}: {new:?} of {draws}"
        );
        let limit = |level: f64| {
            let expected = f64::from(draws) * level;
            expected + 4.0 * (expected * (1.0 - level)).sqrt()
        };
        assert!(
            (old[0] + old[1]) as f64 > limit(epsilon),
            "deflated: {old:?}"
        );
        assert!(
            old.iter().all(|&k| k as f64 > limit(epsilon / 2.0)),
            "deflated: {old:?}"
        );
        assert!(
            (new[0] + new[1]) as f64 <= limit(epsilon),
            "weighted: {new:?}"
        );
    }

    /// The bound holds with the fixed point on each draw's own data: 100 residuals whose slip
    /// parts turn with their heading and couple it with the heading's noise, as a turning
    /// doublet's do (`Mᵢ = 0.1s²·(uᵢuᵢᵀ + ½vᵢvᵢᵀ)`, `uᵢ = (cos θ, sin θ, 0.8·sin 3θ)`, `vᵢ ⊥` in
    /// the plane, θ spread by the golden angle, s from 0.4 to 1.6), over a sensor part of
    /// 0.05·I and a motion part of 0.3·I that the bound is not told (so that its floor
    /// `S_half/c`, the data's, sets it), σ² = σ²_hi = 1. Over 800 seeded draws, each bounded
    /// from its own `S_half`, `λ_max(W) > c₊` or `λ_min(W) < c₋` in at most level 0.1's 80
    /// plus 4 binomial standard deviations (`√(800·0.1·0.9) ≈ 8.5`): 113.
    #[test]
    fn the_directional_bound_covers_turning_slip_on_its_own_data() {
        let (m, epsilon, draws) = (100, 0.1, 800);
        let maps: Vec<Matrix3<f64>> = (0..m)
            .map(|i| {
                let theta = 2.399_963 * i as f64;
                let s = 0.4 + 1.2 * (i % 7) as f64 / 6.0;
                let (sin, cos) = theta.sin_cos();
                let u = nalgebra::Vector3::new(cos, sin, 0.8 * (3.0 * theta).sin());
                let v = nalgebra::Vector3::new(-sin, cos, 0.0);
                0.1 * s * s * (u * u.transpose() + 0.5 * v * v.transpose())
            })
            .collect();
        let sensor = Matrix3::identity() * 0.05;
        let motion = Matrix3::identity() * 0.3;
        let covariances: Vec<Matrix3<f64>> = maps.iter().map(|map| sensor + motion + map).collect();
        let mean = covariances.iter().sum::<Matrix3<f64>>() / m as f64;
        let whiten = mean.cholesky().unwrap().l().try_inverse().unwrap();
        let factors: Vec<Matrix3<f64>> = covariances
            .iter()
            .map(|c| c.cholesky().unwrap().l())
            .collect();
        let mut rng = stream(78, Purpose::Process, 0);
        let mut normal =
            || <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut rng);
        let (mut misses, mut widest) = (0, [f64::INFINITY, 0.0f64]);
        for _ in 0..draws {
            let mut s = Matrix3::zeros();
            for l in &factors {
                let z = l * nalgebra::Vector3::new(normal(), normal(), normal());
                s += z * z.transpose();
            }
            let s = s / m as f64;
            let e = SymmetricEigen::new(whiten * s * whiten.transpose()).eigenvalues;
            let [least, most] = slip_wishart_bounds(&maps, &sensor, &s, 1.0, 1.0, epsilon);
            misses += usize::from(e.max() > most || e.min() < least);
            widest = [widest[0].min(least), widest[1].max(most)];
        }
        let at_truth = slip_wishart_bounds(&maps, &sensor, &mean, 1.0, 1.0, epsilon);
        eprintln!(
            "{misses} misses of {draws}; [c₋, c₊] at the mean {at_truth:.4?}, over the draws \
             within {widest:.4?}"
        );
        let expected = f64::from(draws) * epsilon;
        assert!(misses as f64 <= expected + 4.0 * (expected * (1.0 - epsilon)).sqrt());
    }

    /// The weighted bound contains the χ² net bound at equal covariances (`Mᵢ` all alike: a
    /// box of width 0, where it is χ²_m's Chernoff bound sharpened by Berry–Esseen over the
    /// same net), and lies within that tail's slack of it: at m = 5,000 and ε = 10⁻⁷
    /// `c₊ − 1` and `1 − c₋` are 1.5 % and 1.4 % wider (asserted below 3 %; Chernoff's
    /// alone, 6.6 % and 6.2 %).
    #[test]
    fn equal_covariances_give_the_chi_square_net_bound_or_wider() {
        for (m, epsilon) in [(100, 0.02), (5_000, 1e-7)] {
            let maps = vec![Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, 0.5, 2.0)); m];
            let sensor = Matrix3::identity() * 1e-3;
            let mean = sensor + maps[0];
            let exact = wishart_bounds(m as f64, epsilon);
            let weighted = slip_wishart_bounds(&maps, &sensor, &mean, 1.0, 1.0, epsilon);
            eprintln!("m {m} ε {epsilon}: χ² {exact:?}, weighted {weighted:?}");
            assert!(weighted[0] <= exact[0] && exact[1] <= weighted[1]);
            if m == 5_000 {
                assert!(weighted[1] - 1.0 < 1.03 * (exact[1] - 1.0));
                assert!(1.0 - weighted[0] < 1.03 * (1.0 - exact[0]));
            }
        }
    }

    /// Whether the truth `q` (robot frame) with slip variance `slip` lies outside `e`'s region:
    /// ρ = 0 outside its interval, `Q_high − Q` not positive semidefinite, or, where the slip
    /// is sized, σ² outside its interval or `Q − Q_low(σ²)` not positive semidefinite (from
    /// one-step residuals `Q_low(σ²) = Σ_low − N̄ − σ²M̄` is linear in σ², so its grid's ends
    /// give it exactly), otherwise `Q − Q_low` not positive semidefinite.
    fn misses(e: &MotionNoiseEstimate, q: &Matrix3<f64>, slip: f64) -> bool {
        let not_psd = |m: Matrix3<f64>| SymmetricEigen::new(m).eigenvalues.min() < 0.0;
        let [lo, hi] = e.correlation.interval;
        let lower = match &e.slip_corners {
            None => e.lower,
            Some(grid) => {
                let [first, last] = [grid[0], grid[SLIP_GRID - 1]];
                if slip < first.variance || slip > last.variance {
                    return true;
                }
                let share = (slip - first.variance) / (last.variance - first.variance);
                let [a, b] = [first, last].map(|g| g.corners[0].motion);
                a + (b - a) * share
            }
        };
        lo > 0.0 || hi < 0.0 || not_psd(e.upper - q) || not_psd(q - lower)
    }

    /// A two-step block's region from its one-step residuals split at the middle samples
    /// ([`estimate_motion_noise_split`]) holds at its level and is tighter than the one from
    /// the doublets' two-step residuals (ρ from the same one-step statistics), on the same
    /// blocks: 200 blocks of 1,000 doublets at ε_est = 0.05 of white noise (4 mm and 1 mm
    /// against the sensor's 0.5 mm; straight and turning doublets), and 40 blocks of 1,000
    /// doublets of 2 mm with 5 % per-wheel slip (speeds 0.01–0.16 m/s, turn rates ±0.4 rad/s,
    /// the slip sized: σ² and `Q` jointly). The region misses the truth in at most 19 of the
    /// 200 white blocks and 6 of the 40 slip ones (10 and 2 expected were it exact; 3 binomial
    /// standard deviations above, and the Wishart bound's union over its net is conservative).
    /// Tighter: each block's lowest vertex `Q_low` (at ρ's upper end, and σ²'s) per diagonal
    /// entry, the blocks' mean of the new less the old (in units of the truth's entry) above 0
    /// by more than 4 of its standard errors on every axis but the slip world's heading
    /// (there `Q_low`'s entry is the slip's uncertainty, not the Wishart factor's: asserted
    /// not below 0 by 4 of them), and the new above the old in the Loewner order in a
    /// majority of the white blocks. The predicted gain at 4 mm: `Q_low/Q ≈ ((Q + 2R)/c₊(m)
    /// − 2R)/Q` over m = 1,000 residuals per parity against `((2Q + 2R)/c₊(m/2) − 2R)/2Q` over
    /// 500.
    #[test]
    fn two_step_blocks_bound_q_from_their_one_step_residuals() {
        use crate::estimate::homogeneity::tests::slipping_doublets;
        type Block = (Vec<DoubletResidual>, Vec<DoubletResidual>);
        let epsilon = 0.05;
        let sensor = [5e-4; 3];
        let white = |q_std: f64, seed: u64| -> Block {
            simulated_doublets(1_000, sensor, seed, straight_and_turning, |_, _, normal| {
                Pose::new(q_std * normal(), q_std * normal(), q_std * normal())
            })
        };
        let four = |seed| white(4e-3, seed);
        let one = |seed| white(1e-3, seed);
        let slipping = |seed| slipping_doublets(1_000, 2e-3, 0.05, seed);
        // Name, `√Q` per axis (m), slip, blocks, misses allowed, the block's residuals.
        type World<'a> = (&'a str, f64, f64, usize, usize, &'a dyn Fn(u64) -> Block);
        let worlds: [World; 3] = [
            ("4 mm", 4e-3, 0.0, 200, 19, &four),
            ("1 mm", 1e-3, 0.0, 200, 19, &one),
            ("5 % slip", 2e-3, 0.05, 40, 6, &slipping),
        ];
        let sensed = covariance(sensor);
        for (name, q_std, slip, blocks, allowed, block) in worlds {
            let q = covariance([q_std; 3]);
            let (mut missed, mut refused, mut unlike, mut above) = ([0, 0], 0, 0, 0);
            let mut gains: Vec<[f64; 3]> = Vec::new();
            for seed in 0..blocks {
                let (whole, split) = block(2_000 + seed as u64);
                let new = estimate_motion_noise_split(&split, &sensed, epsilon);
                let old = region_estimate(
                    &whole,
                    Some(&split),
                    &sensed,
                    epsilon,
                    None,
                    JitterVariances::default(),
                );
                let (Ok(new), Ok(old)) = (new, old) else {
                    refused += 1;
                    continue;
                };
                assert!(slip == 0.0 || new.slip_corners.is_some(), "{name} {seed}");
                missed[0] += usize::from(misses(&new, &q, slip * slip));
                missed[1] += usize::from(misses(&old, &q, slip * slip));
                // A white block may show slip at this level: its region then misses σ² = 0
                // (counted above), and where one estimate sizes slip and the other does not,
                // their vertices are not comparable.
                if new.slip_corners.is_some() != old.slip_corners.is_some() {
                    unlike += 1;
                    continue;
                }
                let difference = new.lower - old.lower;
                above += usize::from(SymmetricEigen::new(difference).eigenvalues.min() >= 0.0);
                gains.push(std::array::from_fn(|k| difference[(k, k)] / q[(k, k)]));
            }
            let n = gains.len() as f64;
            let mean: [f64; 3] =
                std::array::from_fn(|k| gains.iter().map(|g| g[k]).sum::<f64>() / n);
            let error: [f64; 3] = std::array::from_fn(|k| {
                let spread = gains.iter().map(|g| (g[k] - mean[k]).powi(2)).sum::<f64>();
                (spread / (n - 1.0) / n).sqrt()
            });
            eprintln!(
                "{name}: misses {missed:?} (new, old) of {blocks}, {refused} refused, {unlike} \
                 sized with slip by one alone; new ⪰ old in {above} of {n}; Q_low new − old \
                 per axis, of Q: {mean:.4?} ± {error:.4?}"
            );
            assert!(
                missed[0] <= allowed,
                "{name}: {missed:?} misses of {blocks}"
            );
            assert!(
                refused + unlike <= blocks / 10,
                "{name}: {refused} refused, {unlike} unlike, of {blocks}"
            );
            for k in 0..3 {
                let least = if slip > 0.0 && k == 2 { -4.0 } else { 4.0 };
                assert!(
                    mean[k] > least * error[k],
                    "{name} axis {k}: {mean:?} ± {error:?}"
                );
            }
            if slip == 0.0 {
                assert!(2 * above > gains.len(), "{name}: new ⪰ old in {above}");
            }
        }
    }

    /// ρ under slip: over 50 seeded blocks of 2,000 doublets each at ρ = 0.5 with 5 % and
    /// with 20 % per-wheel slip (1 mm of motion noise, the sensor's 0.5 mm, speeds and turns
    /// varied), the joint region of ρ and σ² (`joint_region`, ρ's interval and σ²'s at 0.05
    /// each) holds ρ in all but at most 11 blocks (both events hold except with probability
    /// 0.1: 5 misses expected were the intervals exact, 11 is 3 binomial standard deviations
    /// `√(50·0.1·0.9)` above), and σ² in as many, from the one-step residuals and from the
    /// whole doublets (ρ from their lag-one ratio, σ²'s interval free of ρ:
    /// `slip::estimate_slip`); ρ's interval without the slip taken out (the one-step
    /// statistics as before slip was modelled, untested) misses ρ, or its two statistics do
    /// not meet, in more than 11 of them — the slip's share leans them towards 0.
    #[test]
    fn rho_under_slip_is_covered_by_the_joint_region() {
        use crate::estimate::correlation::tests::slipping_ar1_doublets;
        let sensor = covariance([5e-4; 3]);
        let (blocks, level, rho) = (50_u64, 0.05, 0.5);
        let expected = blocks as f64 * 2.0 * level;
        let allowed = (expected + 3.0 * (expected * (1.0 - 2.0 * level)).sqrt()).floor() as usize;
        for slip in [0.05, 0.2] {
            // ρ's and σ²'s misses from the one-step residuals, then from the whole doublets.
            let (mut missed, mut missed_slip, mut plain_missed) = ([0; 2], [0; 2], 0);
            let holds = |[lo, hi]: [f64; 2], x: f64| lo <= x && x <= hi;
            for seed in 0..blocks {
                let (whole, split) = slipping_ar1_doublets(2_000, 1e-3, rho, slip, 300 + seed);
                let regions = [
                    joint_region(&split, Some(&split), &sensor, level, level, None),
                    joint_region(&whole, None, &sensor, level, level, None),
                ];
                for (k, region) in regions.into_iter().enumerate() {
                    let (c, s) = region.unwrap();
                    missed[k] += usize::from(!holds(c.interval, rho));
                    missed_slip[k] += usize::from(!holds(s.interval, slip * slip));
                }
                let plain =
                    correlation_untested(&split, Some(&split), &sensor, level, SlipShare::NONE);
                plain_missed += usize::from(!plain.is_ok_and(|c| holds(c.interval, rho)));
            }
            eprintln!(
                "slip {slip}: ρ missed {missed:?}, σ² missed {missed_slip:?} (one-step, whole), \
                 without the slip taken out {plain_missed} of {blocks}"
            );
            for k in 0..2 {
                assert!(
                    missed[k] <= allowed && missed_slip[k] <= allowed,
                    "slip {slip}: ρ missed {missed:?}, σ² {missed_slip:?} of {blocks}"
                );
            }
            assert!(
                plain_missed > allowed,
                "slip {slip}: {plain_missed} of {blocks}"
            );
        }
    }

    /// The region is the same number for number on one thread and on two (the slip's
    /// Wishart nets' two sides, ρ's two statistics and the slip grid's points are computed on
    /// rayon's pool): a seeded block of 1,000 doublets under 5 % per-wheel slip on 2 mm of
    /// white motion noise and one of 4 mm without slip, each estimated in a pool of one
    /// thread and in one of two: the same estimate (its `Debug` form prints every number's
    /// shortest round trip), the slip's block with its slip grid's corners.
    #[test]
    fn the_region_is_alike_on_one_thread_and_on_two() {
        use crate::estimate::homogeneity::tests::slipping_doublets;
        let sensed = covariance([5e-4; 3]);
        let white = simulated_doublets(1_000, [5e-4; 3], 7, straight_and_turning, |_, _, n| {
            Pose::new(4e-3 * n(), 4e-3 * n(), 4e-3 * n())
        });
        for (slip, (_, split)) in [
            (true, slipping_doublets(1_000, 2e-3, 0.05, 2_000)),
            (false, white),
        ] {
            let on = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                format!(
                    "{:?}",
                    pool.install(|| estimate_motion_noise_split(&split, &sensed, 1e-6))
                )
            };
            let one = on(1);
            assert!(one.starts_with("Ok("), "{one}");
            assert_eq!(one.contains("slip_corners: Some("), slip, "{one}");
            assert_eq!(one, on(2));
        }
    }

    /// Without slip ρ is what it was: on white and on ρ = 0.5 blocks the two-step estimate's
    /// correlation is `estimate_correlation_split`'s with no slip share, bit for bit (the
    /// slip is not measured there, so the joint region is not entered), and a share of σ² = 0
    /// gives the statistics' intervals bit for bit.
    #[test]
    fn without_slip_the_correlation_is_unchanged() {
        use crate::estimate::correlation::tests::ar1_doublets;
        let sensor = covariance([5e-4; 3]);
        for (rho, seed) in [(0.0, 61), (0.5, 62)] {
            let (_, split) = ar1_doublets(4_000, 1e-3, rho, seed);
            let estimate = estimate_motion_noise_split(&split, &sensor, 1e-6).unwrap();
            let alone = estimate_correlation_split(&split, &sensor, 0.5e-6, SlipShare::NONE);
            assert_eq!(Ok(estimate.correlation), alone, "ρ {rho}");
            assert!(estimate.slip_corners.is_none(), "ρ {rho}");
            assert_eq!(
                estimate_correlation_split(&split, &sensor, 0.01, SlipShare::at(0.0)),
                estimate_correlation_split(&split, &sensor, 0.01, SlipShare::NONE)
            );
        }
    }

    #[test]
    fn data_outside_the_class_are_refused_by_name() {
        let r = [5e-4, 5e-4, 5e-4];
        let short = residuals(150, [1e-3; 3], r, 1);
        let error = estimate_motion_noise(&short, &covariance(r), 1e-6).unwrap_err();
        assert_eq!(error, EstimationRefusal::TooFewDoublets { have: 75 });
        // A sensor stated 4× noisier than it is: no Q ⪰ 0 explains residuals this quiet.
        let quiet = residuals(4_000, [1e-4; 3], r, 2);
        let error = estimate_motion_noise(&quiet, &covariance([2e-3; 3]), 1e-6).unwrap_err();
        assert!(
            matches!(error, EstimationRefusal::BelowSensorNoise { .. }),
            "{error}"
        );
        assert!(error.to_string().contains("sensing.controller_std"));
        assert!(matches!(
            estimate_motion_noise(&quiet, &covariance(r), 1.5),
            Err(EstimationRefusal::Epsilon(_))
        ));
    }
}
