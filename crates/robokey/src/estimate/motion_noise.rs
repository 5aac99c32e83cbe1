//! The motion noise `Q` from the doublets' residuals, and its (1 − ε_est) lower bound
//! (docs/estimation.md, "The region").
//!
//! **Point estimate** (method of moments, the sensor term subtracted): with `S` the mean of
//! `zzᵀ` over the residuals, `N̄` the mean sensor part and `𝓛̄(Q)` the mean motion part,
//! `𝓛̄(Q̂) = S − N̄` — a 6×6 linear system in the six entries of the symmetric `Q̂`.
//!
//! **Region.** Residuals of doublets of one parity are independent (the MA(1) structure
//! links neighbours only). For each parity half of `m` residuals, treated as `N(0, Σ̄)` with
//! `Σ̄` the mean covariance, `Σ̄^(−½)·S_half·Σ̄^(−½)` is a Wishart matrix `W₃(I, m)/m`; its
//! largest eigenvalue is below `c₊ = (1 + √(3/m) + √(2 ln(2/ε_est)/m))²` and its smallest
//! above `c₋ = (1 − √(3/m) − √(2 ln(2/ε_est)/m))²`, each except with probability ε_est/2
//! (Davidson–Szarek: the extreme singular values of a Gaussian m×3 matrix lie within
//! `√m ± (√3 + t)` except with probability `e^(−t²/2)`). So, except with probability ε_est,
//! `Σ̄ ⪰ S_half/c₊` for both halves, in the Loewner order — every direction at once. Their
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
//! doublets' speed or turn classes (`homogeneity`: slip); tails that are not Gaussian.

use nalgebra::{Matrix3, Matrix6, SymmetricEigen, Vector6};
use thiserror::Error;

use super::homogeneity::{ClassDeparture, speed_class_departure};
use super::residual::DoubletResidual;

/// Least residuals of each parity the bounds are computed from.
pub const MIN_DOUBLETS_PER_PARITY: usize = 100;

/// What the controller measured of the motion noise, and its bound.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionNoiseEstimate {
    /// Residuals used.
    pub doublets: usize,
    /// `Q̂` in the robot's frame (m², m², rad²; along-track, lateral, heading): for the
    /// controller's own likelihood and error estimate.
    pub point: Matrix3<f64>,
    /// `Q_low`: the region's Loewner vertex, which sizes Eve's modelled view.
    pub lower: Matrix3<f64>,
    /// `Q_high`: the region's upper vertex (for people and the class check).
    pub upper: Matrix3<f64>,
    /// The region's failure probability ε_est.
    pub epsilon: f64,
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
    /// Neighbouring doublets' residuals correlated beyond what the sensor's MA(1) term
    /// explains: the motion noise is not white (e.g. AR(1)).
    #[error(
        "motion-noise estimate: neighbouring doublets' residuals along the {axis} axis are \
         correlated beyond the sensor's MA(1) term: standardised statistic {statistic:.1} \
         (allowed: within ±{limit:.1} at level ε_est); the motion noise is not white, which \
         the model class does not cover"
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
    /// what one `Q` explains: slip, speed- or turn-dependent noise, or a turn-dependent residual
    /// the model leaves (the homogeneity test).
    #[error(
        "motion-noise estimate: the motion noise differs between the doublets' classes (by \
         {partition}, class {lo:.3}–{hi:.3} {unit}: measured/pooled variance along the {axis} axis \
         per class {ratios}, statistic {statistic:.1}, allowed: within ±{limit:.1} at level \
         ε_est): slip, noise that depends on the speed or the turn, or a turn-dependent \
         residual the model leaves — outside the white-noise class this estimator covers",
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

/// The entries `(i, j)` of a symmetric 3×3 matrix, in the order of its six coordinates.
const ENTRIES: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];

fn coordinates(m: &Matrix3<f64>) -> Vector6<f64> {
    Vector6::from_iterator(ENTRIES.iter().map(|&(i, j)| 0.5 * (m[(i, j)] + m[(j, i)])))
}

fn symmetric(q: &Vector6<f64>) -> Matrix3<f64> {
    let mut m = Matrix3::zeros();
    for (&(i, j), &v) in ENTRIES.iter().zip(q.iter()) {
        m[(i, j)] = v;
        m[(j, i)] = v;
    }
    m
}

/// `𝓛̄` as a 6×6 matrix on the coordinates: column k is `𝓛̄(E_k)`.
fn mean_motion_operator(residuals: &[DoubletResidual]) -> Matrix6<f64> {
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
            .map(|r| r.motion_part(&q))
            .sum::<Matrix3<f64>>()
            / n;
        operator.set_column(k, &coordinates(&mean));
    }
    operator
}

/// `(1 ± √(3/m) ± √(2 ln(2/ε)/m))²`: the Wishart eigenvalue bounds for m residuals.
fn wishart_factor(m: usize, epsilon: f64, sign: f64) -> f64 {
    let m = m as f64;
    (1.0 + sign * ((3.0 / m).sqrt() + (2.0 * (2.0 / epsilon).ln() / m).sqrt())).powi(2)
}

fn second_moment<'a>(
    residuals: impl Iterator<Item = &'a DoubletResidual>,
) -> (usize, Matrix3<f64>) {
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

/// The robot-frame axes, for people.
pub(super) const AXES: [&str; 3] = ["along-track", "lateral", "heading"];

/// The whiteness test with the sensor's MA(1) structure: over the pairs of consecutive
/// doublets (j, j+1), white motion noise leaves only the shared boundary sample,
/// `E[z_j z_{j+1}ᵀ] = −C₀,j R C₁,j+1ᵀ`. Per axis k the statistic
/// `T_k = Σ (z_j,k z_{j+1},k − E[·]) / √(1.5·Σ z_j,k² z_{j+1},k²)` is ≈ N(0, 1) (the factor 1.5
/// covers the overlap of neighbouring pairs, whose products are correlated by at most
/// ρ₁² ≤ ¼); the first axis with `|T_k| > z(ε/6)` is returned with its statistic and limit.
fn lag_one_departure(
    residuals: &[DoubletResidual],
    sensor: &Matrix3<f64>,
    epsilon: f64,
) -> Option<(&'static str, f64, f64)> {
    let mut sum = [0.0; 3];
    let mut squares = [0.0; 3];
    for pair in residuals.windows(2) {
        let [a, b] = [&pair[0], &pair[1]];
        if b.doublet != a.doublet + 1 {
            continue;
        }
        let expected = -(a.sensor_maps[0] * sensor * b.sensor_maps[1].transpose());
        for k in 0..3 {
            let product = a.value[k] * b.value[k];
            sum[k] += product - expected[(k, k)];
            squares[k] += product * product;
        }
    }
    let limit = normal_upper_quantile(epsilon / 6.0);
    (0..3).find_map(|k| {
        let statistic = sum[k] / (1.5 * squares[k]).sqrt();
        (statistic.abs() > limit).then_some((AXES[k], statistic, limit))
    })
}

/// Mardia's multivariate kurtosis of 3-dimensional Gaussian data, `p(p + 2)` at p = 3.
const GAUSSIAN_KURTOSIS: f64 = 15.0;

/// Mardia's kurtosis `b₂ = mean((zᵀS⁻¹z)²)` of the residuals, `S` their second moment
/// (0 when `S` is singular).
fn mardia_kurtosis(residuals: &[DoubletResidual], second_moment: &Matrix3<f64>) -> f64 {
    let Some(inverse) = second_moment.try_inverse() else {
        return 0.0;
    };
    residuals
        .iter()
        .map(|r| r.value.dot(&(inverse * r.value)).powi(2))
        .sum::<f64>()
        / residuals.len().max(1) as f64
}

/// The two-sided (1 − ε) range of Mardia's b₂ around 15 for n residuals: b₂ is
/// asymptotically `N(15, 8p(p+2)/n) = N(15, 120/n)` for independent Gaussian data; the
/// neighbours' MA(1) correlation (at most ½ in every direction) at most doubles the
/// variance, so `z·√(240/n)` with `z` the normal quantile of ε/2.
fn kurtosis_tolerance(n: usize, epsilon: f64) -> f64 {
    normal_upper_quantile(epsilon / 2.0) * (240.0 / n.max(1) as f64).sqrt()
}

/// `z` with `P[N(0,1) > z] ≤ p` (p ≤ ½): from the tail bound `P[N > z] ≤ e^(−z²/2)/2`,
/// `z = √(2 ln(1/(2p)))` — a little wider than the exact quantile, never narrower.
pub(super) fn normal_upper_quantile(p: f64) -> f64 {
    (2.0 * (0.5 / p).ln()).max(0.0).sqrt()
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
    if !(epsilon > 0.0 && epsilon < 1.0) {
        return Err(EstimationRefusal::Epsilon(epsilon));
    }
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
    let operator = mean_motion_operator(residuals);
    let solve = |m: Matrix3<f64>| {
        operator
            .lu()
            .solve(&coordinates(&(m - sensor_mean)))
            .map(|q| symmetric(&q))
    };
    let weighted = |factor: f64| -> Matrix3<f64> {
        halves
            .iter()
            .map(|(m, s)| s * (*m as f64 / n) * wishart_factor(*m, epsilon, factor).recip())
            .sum()
    };
    let all = second_moment(residuals.iter()).1;
    let point = solve(all).ok_or(EstimationRefusal::Singular)?;
    let lower = solve(weighted(1.0)).ok_or(EstimationRefusal::Singular)?;
    let upper = solve(weighted(-1.0)).ok_or(EstimationRefusal::Singular)?;
    let eigen = SymmetricEigen::new(upper);
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
    if let Some((axis, statistic, limit)) = lag_one_departure(residuals, sensor, epsilon) {
        return Err(EstimationRefusal::NotWhite {
            axis,
            statistic,
            limit,
        });
    }
    if let Some(departure) = speed_class_departure(residuals, &point, sensor, epsilon) {
        return Err(EstimationRefusal::NotHomogeneous(departure));
    }
    let kurtosis = mardia_kurtosis(residuals, &all);
    let tolerance = kurtosis_tolerance(residuals.len(), epsilon);
    if (kurtosis - GAUSSIAN_KURTOSIS).abs() > tolerance {
        return Err(EstimationRefusal::NotGaussian {
            kurtosis,
            tolerance,
        });
    }
    Ok(MotionNoiseEstimate {
        doublets: residuals.len(),
        point,
        lower,
        upper,
        epsilon,
    })
}

impl MotionNoiseEstimate {
    /// Standard deviations `√Q_kk` of the point estimate and the lower vertex (m, m, rad;
    /// the vertex's negative diagonal entries read 0), for people.
    #[must_use]
    pub fn stds(&self) -> [[f64; 3]; 2] {
        [self.point, self.lower].map(|m| [0, 1, 2].map(|k| m[(k, k)].max(0.0).sqrt()))
    }
}

#[cfg(test)]
pub(super) mod tests {
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
            |j| {
                let turn = if j % 7 < 3 { 0.0 } else { 0.4 };
                DoubletInputs {
                    first: Unicycle::new(0.1, turn),
                    second: Unicycle::new(0.1, turn),
                }
            },
            |_, _, normal| {
                Pose::new(
                    q_std[0] * normal(),
                    q_std[1] * normal(),
                    q_std[2] * normal(),
                )
            },
        )
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
        let model = doublet_model(&Config::default());
        let mut rng = stream(seed, Purpose::Process, 0);
        let mut normal =
            || <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut rng);
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
        let mut out = Vec::new();
        for j in 0..doublets {
            let inputs = inputs(j);
            let pattern = (j as usize * 5 + 1) % 3 % 2;
            let [a, b] = inputs.applied(model.perturbation.offset(pattern));
            for u in [a, b] {
                let heading = x.z;
                x = crate::model::unicycle_step(&x, &u, t) + motion(&u, heading, &mut normal);
            }
            let y_end = sensed(&x, &mut normal);
            out.push(DoubletResidual::new(
                &model, j, &inputs, &y_start, &y_end, pattern,
            ));
            y_start = y_end;
        }
        out
    }

    use super::diagonal_covariance as covariance;

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
    /// doublets (2,000 per parity) `1/c₊ = 0.797`, so along position
    /// `Q_low/Q ≈ ((2Q + 2R)/c₊ − 2R)/(2Q) = 0.746` at Q = 1 mm², R = 0.25 mm², with a
    /// sampling standard error of `√(2/4000)·(Q + R)/Q ≈ 2.8 %`: asserted above 0.746 − 4·0.028.
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
            for k in 0..3 {
                assert!(
                    e.lower[(k, k)] > 0.63 * truth[(k, k)],
                    "seed {seed}: {}",
                    e.lower
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

    /// AR(1) motion noise of ρ = 0.5 correlates neighbouring residuals by ≈ 0.37 (against
    /// −0.06 from the sensor), a statistic of ≈ 30 against a limit of 5.6 at ε_est = 10⁻⁶ over
    /// 4,000 doublets: refused, naming the axis; white noise on 20 seeds is not.
    #[test]
    fn correlated_motion_noise_is_refused_as_not_white() {
        let r = [5e-4, 5e-4, 5e-4];
        for seed in 0..20 {
            let data = residuals(4_000, [1e-3; 3], r, 500 + seed);
            let sensor = covariance(r);
            assert!(
                lag_one_departure(&data, &sensor, 1e-6).is_none(),
                "seed {seed}"
            );
        }
        // Doublet residuals of AR(1) steps: z_j = w_2j + w_2j+1 (+ sensor), w_k = ρw_k−1 + √(1−ρ²)e_k.
        let mut rng = stream(4, Purpose::Process, 2);
        let mut normal =
            || <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut rng);
        let mut w = [0.0; 3];
        let mut eta_start = [0.0; 3].map(|_: f64| 5e-4 * normal());
        let correlated: Vec<DoubletResidual> = residuals(4_000, [0.0; 3], [0.0; 3], 4)
            .into_iter()
            .map(|mut d| {
                let eta_end = [0.0; 3].map(|_: f64| 5e-4 * normal());
                for k in 0..3 {
                    let mut two_steps = 0.0;
                    for _ in 0..2 {
                        w[k] = 0.5 * w[k] + (0.75_f64).sqrt() * 2e-3 * normal();
                        two_steps += w[k];
                    }
                    d.value[k] += two_steps + eta_end[k] - eta_start[k];
                }
                eta_start = eta_end;
                d
            })
            .collect();
        let error = estimate_motion_noise(&correlated, &covariance(r), 1e-6).unwrap_err();
        assert!(
            matches!(error, EstimationRefusal::NotWhite { .. }),
            "{error}"
        );
        assert!(error.to_string().contains("not white"), "{error}");
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
