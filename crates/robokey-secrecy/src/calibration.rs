//! Calibration check of predicted error probabilities (the gate a posterior must pass before
//! it may feed [`crate::min_entropy::posterior_smooth_min_entropy`]).
//!
//! Input: pairs (q_i, e_i), q_i the predicted probability that the decision on bit i is wrong
//! and e_i whether it was. H₀ (calibration): given the predictions, the e_i are independent
//! Bernoulli(q_i). The pairs are split into equal-count bins by predicted q, and in each bin
//! the error count X = Σ e_i, a Poisson-binomial variable under H₀, is compared with its mean
//! μ = Σ q_i by an exact (or conservative) two-sided test; Bonferroni over the bins. The
//! tolerance comes from the distribution of X alone (the bin's size and q's): it is never a
//! free parameter.

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Largest m·(k + 1) (bin size m, k = min(x, m − x) for x observed errors) for which a bin's
/// p-value comes from the exact Poisson-binomial tails; larger bins use the Chernoff bound.
pub const EXACT_WORK_LIMIT: usize = 1 << 25;

/// Errors of [`check_calibration`] (bad input only: a failed check is a report, not an error).
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CalibrationError {
    /// No (prediction, outcome) pairs were given.
    #[error("no predictions to check")]
    EmptyInput,
    /// A predicted error probability outside [0, 1], or NaN.
    #[error("predicted error probability {value} at index {index} is outside [0, 1]")]
    InvalidProbability {
        /// Position of the offending pair in the input.
        index: usize,
        /// The value given.
        value: f64,
    },
    /// Zero bins were requested.
    #[error("the number of bins must be at least 1")]
    ZeroBins,
    /// A significance level outside the open interval (0, 1), or NaN.
    #[error("significance level {0} must lie strictly between 0 and 1")]
    InvalidAlpha(f64),
}

/// One bin of predictions with similar q.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationBin {
    /// Smallest (folded) predicted q in the bin.
    pub q_low: f64,
    /// Largest (folded) predicted q in the bin.
    pub q_high: f64,
    /// Number of predictions m in the bin.
    pub count: u64,
    /// μ = Σ q_i: errors expected under calibration.
    pub predicted_errors: f64,
    /// x = Σ e_i: errors that occurred.
    pub observed_errors: u64,
    /// Two-sided p-value min(1, 2·min(P[X ≤ x], P[X ≥ x])) under H₀ (before Bonferroni).
    pub p_value: f64,
    /// Whether `p_value` is from the exact Poisson-binomial tails (true) or the Chernoff
    /// bound on them (false, bins above [`EXACT_WORK_LIMIT`]).
    pub exact: bool,
}

/// Result of [`check_calibration`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationReport {
    /// Equal-count bins in increasing order of predicted q.
    pub bins: Vec<CalibrationBin>,
    /// Family-wise significance level α.
    pub alpha: f64,
    /// Every bin has `p_value` > α / `bins.len()` (Bonferroni). Under H₀,
    /// P[not passed] ≤ α.
    pub passed: bool,
}

/// Calibration test of predicted error probabilities at family-wise level `alpha`.
///
/// - Folding: a pair with q > ½ is read as (1 − q, ¬e), the flipped decision and whether
///   *it* was wrong (as [`crate::min_entropy::posterior_smooth_min_entropy`] reads q > ½);
///   under H₀ ¬e ~ Bernoulli(1 − q), so the test is unchanged.
/// - Bins: the pairs are stably sorted by folded q alone (never by outcome, so the binning
///   is fixed under H₀) and cut into min(`bins`, n) contiguous bins of ⌊n/B⌋ or ⌈n/B⌉ pairs.
///   Equal counts give every bin the same sample size: equal-width bins would put nearly all
///   pairs in the lowest bin when errors are rare and leave others empty.
/// - Per bin, with m pairs, x errors, μ = Σ q_i: p = min(1, 2·min(P[X ≤ x], P[X ≥ x])),
///   X ~ PoissonBinomial(q_1..q_m). Each tail bound T satisfies P[T(X) ≤ a] ≤ a, so
///   P[p ≤ a] ≤ a/2 + a/2. The tails are exact, by the DP over the count capped at
///   k = min(x, m − x) (an overflow cell collects mass above k, so neither tail is formed
///   by subtraction), when m·(k + 1) ≤ [`EXACT_WORK_LIMIT`]. Otherwise both are replaced by
///   the Chernoff bound exp(−m·D(x/m ‖ μ/m)) (D the binary relative entropy), valid for
///   the tail on x's side of μ because E e^{tX} = Π(1 − q_i + q_i e^t) ≤ (1 − q̄ + q̄ e^t)^m
///   (AM–GM, q̄ = μ/m); this p-value is never below the exact one, hence also valid.
///   No normal approximation is used: it is anti-conservative for rare errors.
/// - Decision: passed ⇔ every bin's p > α/B (Bonferroni, no independence between bins
///   needed), so a calibrated predictor fails with probability ≤ α.
///
/// A pass is not proof of calibration: miscalibration that cancels inside a bin, or too few
/// pairs, goes unseen. Errors that are dependent given the predictions widen the spread of X
/// and tend to fail the test.
pub fn check_calibration(
    predictions: &[(f64, bool)],
    bins: usize,
    alpha: f64,
) -> Result<CalibrationReport, CalibrationError> {
    if predictions.is_empty() {
        return Err(CalibrationError::EmptyInput);
    }
    if bins == 0 {
        return Err(CalibrationError::ZeroBins);
    }
    if !(alpha > 0.0 && alpha < 1.0) {
        return Err(CalibrationError::InvalidAlpha(alpha));
    }
    let mut folded = predictions
        .iter()
        .enumerate()
        .map(|(index, &(q, wrong))| {
            if !(0.0..=1.0).contains(&q) {
                Err(CalibrationError::InvalidProbability { index, value: q })
            } else if q > 0.5 {
                Ok((1.0 - q, !wrong))
            } else {
                Ok((q, wrong))
            }
        })
        .collect::<Result<Vec<_>, _>>()?;
    folded.sort_by(|a, b| a.0.total_cmp(&b.0));
    let n = folded.len();
    let b = bins.min(n);
    let threshold = alpha / b as f64;
    let bounds = |k: usize| (k as u128 * n as u128 / b as u128) as usize;
    let bins: Vec<CalibrationBin> = (0..b)
        .map(|k| {
            let chunk = &folded[bounds(k)..bounds(k + 1)];
            let q: Vec<f64> = chunk.iter().map(|&(q, _)| q).collect();
            let observed = chunk.iter().filter(|&&(_, wrong)| wrong).count();
            let (p_value, exact) = bin_p_value(&q, observed);
            CalibrationBin {
                q_low: q[0],
                q_high: q[q.len() - 1],
                count: q.len() as u64,
                predicted_errors: q.iter().sum(),
                observed_errors: observed as u64,
                p_value,
                exact,
            }
        })
        .collect();
    let passed = bins.iter().all(|bin| bin.p_value > threshold);
    Ok(CalibrationReport {
        bins,
        alpha,
        passed,
    })
}

/// Two-sided p-value of `observed` errors among independent Bernoulli(q_i), and whether it
/// is exact (else the Chernoff bound).
fn bin_p_value(q: &[f64], observed: usize) -> (f64, bool) {
    let m = q.len();
    let k = observed.min(m - observed);
    if m.saturating_mul(k + 1) <= EXACT_WORK_LIMIT {
        (exact_p_value(q, observed), true)
    } else {
        (chernoff_p_value(q, observed), false)
    }
}

/// min(1, 2·min(P[X ≤ x], P[X ≥ x])) from the exact Poisson-binomial tails. Counting the
/// correct decisions instead (Y = m − X, probabilities 1 − q_i) swaps the tails and leaves
/// the two-sided value unchanged, so the DP runs on the side with the fewer counts.
fn exact_p_value(q: &[f64], observed: usize) -> f64 {
    let m = q.len();
    let (at_most, at_least) = if observed <= m - observed {
        poisson_binomial_tails(q.iter().copied(), observed)
    } else {
        poisson_binomial_tails(q.iter().map(|&q| 1.0 - q), m - observed)
    };
    (2.0 * at_most.min(at_least)).min(1.0)
}

/// (P[X ≤ k], P[X ≥ k]) for X the number of successes of independent Bernoulli(p_i), by
/// f_j ← f_j(1 − p) + f_{j−1}·p over j ≤ k, with the mass leaving state k kept in `above`.
/// All terms are non-negative sums, no cancellation: relative error O(m·2⁻⁵³) (tails below
/// ~10⁻³⁰⁰ may underflow towards 0, which only makes a failing bin fail).
fn poisson_binomial_tails(probabilities: impl Iterator<Item = f64>, k: usize) -> (f64, f64) {
    let mut f = vec![0.0; k + 1];
    f[0] = 1.0;
    let mut above = 0.0;
    for (i, p) in probabilities.enumerate() {
        above += f[k] * p;
        for j in (1..=k.min(i + 1)).rev() {
            f[j] = f[j] * (1.0 - p) + f[j - 1] * p;
        }
        f[0] *= 1.0 - p;
    }
    let at_most: f64 = f.iter().sum();
    (at_most.min(1.0), (f[k] + above).min(1.0))
}

/// min(1, 2·exp(−m·D(x/m ‖ q̄))): the Chernoff bound on the tail of X on x's side of
/// μ = m·q̄, doubled (the other tail's bound is 1).
fn chernoff_p_value(q: &[f64], observed: usize) -> f64 {
    let m = q.len() as f64;
    let mean = q.iter().sum::<f64>() / m;
    let rate = observed as f64 / m;
    (2.0 * (-m * relative_entropy(rate, mean)).exp()).min(1.0)
}

/// D(a ‖ p) = a·ln(a/p) + (1 − a)·ln((1 − a)/(1 − p)) in nats, with 0·ln 0 = 0 and
/// D = ∞ when a > 0 = p or a < 1 = p.
fn relative_entropy(a: f64, p: f64) -> f64 {
    let term = |x: f64, y: f64| {
        if x == 0.0 {
            0.0
        } else if y == 0.0 {
            f64::INFINITY
        } else {
            x * (x / y).ln()
        }
    };
    (term(a, p) + term(1.0 - a, 1.0 - p)).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::ChaCha8Rng;
    use rand::{RngExt, SeedableRng};
    use rand_distr::{Distribution, StandardNormal};

    const ALPHA: f64 = 1e-3;
    const BINS: usize = 10;

    /// Pairs whose outcomes are drawn from the predictions themselves.
    fn calibrated(n: usize, seed: u64) -> Vec<(f64, bool)> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                // Mostly small q (where λ = log₂((1 − q)/q) is large), some up to ½.
                let q = 0.5 * rng.random::<f64>().powi(3);
                (q, rng.random::<f64>() < q)
            })
            .collect()
    }

    /// Gaussian LLR setting: bit b = ±1, observation y = b + σ_true·z, decision sign(y).
    /// The posterior error probability of the decision under a noise model σ_design is
    /// q = 1/(1 + exp(2|y|/σ_design²)); it is the true-noise posterior iff σ_design = σ_true.
    fn gaussian_posteriors(n: usize, sigma_true: f64, sigma_design: f64) -> Vec<(f64, bool)> {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        (0..n)
            .map(|_| {
                let b = if rng.random::<bool>() { 1.0 } else { -1.0 };
                let z: f64 = StandardNormal.sample(&mut rng);
                let y = b + sigma_true * z;
                let q = 1.0 / (1.0 + (2.0 * y.abs() / (sigma_design * sigma_design)).exp());
                (q, y.signum() != b)
            })
            .collect()
    }

    #[test]
    fn calibrated_predictions_pass() {
        // Under H₀ each check fails with probability ≤ α = 10⁻³, so these five seeded data
        // sets all pass with probability ≥ 1 − 5·10⁻³ (the seeds make the outcome fixed).
        for seed in 1..=5 {
            let r = check_calibration(&calibrated(20_000, seed), BINS, ALPHA).unwrap();
            assert!(r.passed, "seed {seed}: {r:?}");
            assert_eq!(r.bins.len(), BINS);
            assert!(r.bins.iter().all(|b| b.count == 2000 && b.exact));
            assert!(r.bins.windows(2).all(|w| w[0].q_high <= w[1].q_low));
        }
    }

    #[test]
    fn true_noise_gaussian_posterior_passes() {
        // False-fail probability ≤ α = 10⁻³.
        let r = check_calibration(&gaussian_posteriors(20_000, 0.4, 0.4), BINS, ALPHA).unwrap();
        assert!(r.passed, "{r:?}");
    }

    #[test]
    fn posterior_25_times_too_wide_fails() {
        // σ_design = 25·σ_true: q ≈ ½ everywhere while the true error rate is Φ(−2.5) ≈ 0.6 %.
        let r = check_calibration(&gaussian_posteriors(20_000, 0.4, 10.0), BINS, ALPHA).unwrap();
        assert!(!r.passed, "{r:?}");
        assert!(r.bins.iter().all(|b| b.q_low > 0.48 && b.p_value < 1e-100));
        let observed: u64 = r.bins.iter().map(|b| b.observed_errors).sum();
        assert!(observed < 200, "{observed}");
    }

    #[test]
    fn overconfident_predictions_fail() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let pairs: Vec<(f64, bool)> = (0..5000)
            .map(|_| (0.001, rng.random::<f64>() < 0.05))
            .collect();
        let r = check_calibration(&pairs, BINS, ALPHA).unwrap();
        assert!(!r.passed, "{r:?}");
        assert!(r.bins.iter().all(|b| b.p_value < ALPHA / BINS as f64));
    }

    #[test]
    fn invalid_input_is_an_error() {
        let ok = [(0.1, false), (0.2, true)];
        assert_eq!(
            check_calibration(&[], BINS, ALPHA),
            Err(CalibrationError::EmptyInput)
        );
        assert_eq!(
            check_calibration(&ok, 0, ALPHA),
            Err(CalibrationError::ZeroBins)
        );
        for alpha in [0.0, 1.0, -0.1, f64::NAN] {
            assert!(matches!(
                check_calibration(&ok, BINS, alpha),
                Err(CalibrationError::InvalidAlpha(_))
            ));
        }
        for value in [-0.1, 1.5, f64::NAN, f64::INFINITY] {
            let err = check_calibration(&[(0.1, false), (value, true)], BINS, ALPHA).unwrap_err();
            assert!(matches!(
                err,
                CalibrationError::InvalidProbability { index: 1, value: v } if v.is_nan() || v == value
            ));
        }
    }

    #[test]
    fn folding_flips_the_outcome_and_bins_are_equal_count() {
        let pairs = calibrated(1003, 3);
        let flipped: Vec<(f64, bool)> = pairs.iter().map(|&(q, e)| (1.0 - q, !e)).collect();
        let a = check_calibration(&pairs, 4, ALPHA).unwrap();
        let b = check_calibration(&flipped, 4, ALPHA).unwrap();
        for (x, y) in a.bins.iter().zip(&b.bins) {
            assert_eq!((x.count, x.observed_errors), (y.count, y.observed_errors));
            assert!((x.p_value - y.p_value).abs() < 1e-9);
        }
        let counts: Vec<u64> = a.bins.iter().map(|b| b.count).collect();
        assert_eq!(counts, [250, 251, 251, 251]);
        // More bins than pairs: one pair per bin.
        assert_eq!(
            check_calibration(&pairs[..3], BINS, ALPHA)
                .unwrap()
                .bins
                .len(),
            3
        );
        // An error where q = 0 is impossible under H₀.
        let r = check_calibration(&[(0.0, true), (0.0, false)], 1, ALPHA).unwrap();
        assert!(!r.passed && r.bins[0].p_value == 0.0);
    }

    /// P[X = x] for all x by enumerating all 2^m outcome patterns.
    fn enumerated_pmf(q: &[f64]) -> Vec<f64> {
        let m = q.len();
        let mut pmf = vec![0.0; m + 1];
        for pattern in 0..1_u32 << m {
            let p: f64 = (0..m)
                .map(|i| {
                    if pattern >> i & 1 == 1 {
                        q[i]
                    } else {
                        1.0 - q[i]
                    }
                })
                .product();
            pmf[pattern.count_ones() as usize] += p;
        }
        pmf
    }

    const SMALL_BIN: [f64; 12] = [
        0.001, 0.01, 0.02, 0.05, 0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.45, 0.5,
    ];

    #[test]
    fn tails_match_enumeration() {
        let pmf = enumerated_pmf(&SMALL_BIN);
        for k in 0..=SMALL_BIN.len() {
            let (at_most, at_least) = poisson_binomial_tails(SMALL_BIN.iter().copied(), k);
            let below: f64 = pmf[..=k].iter().sum();
            let above: f64 = pmf[k..].iter().sum();
            assert!((at_most - below).abs() < 1e-14, "k={k}");
            assert!(
                (at_least - above).abs() <= 1e-12 * above,
                "k={k}: {at_least} vs {above}"
            );
        }
    }

    #[test]
    fn p_values_have_their_level() {
        // P[p(X) ≤ a] ≤ a under H₀, computed exactly from the pmf, for both p-values; the
        // Chernoff one is never below the exact one.
        let pmf = enumerated_pmf(&SMALL_BIN);
        for a in [1e-4, 1e-3, 0.01, 0.05, 0.1, 0.3, 0.5] {
            for p_value in [exact_p_value, chernoff_p_value] {
                let size: f64 = (0..pmf.len())
                    .filter(|&x| p_value(&SMALL_BIN, x) <= a)
                    .map(|x| pmf[x])
                    .sum();
                assert!(size <= a, "a={a}: size {size}");
            }
        }
        for x in 0..=SMALL_BIN.len() {
            assert!(chernoff_p_value(&SMALL_BIN, x) >= exact_p_value(&SMALL_BIN, x) - 1e-15);
        }
    }

    #[test]
    fn large_balanced_bins_use_the_chernoff_bound() {
        // m = 10⁵ with x ≈ m/2: m·(k + 1) ≈ 5·10⁹ > EXACT_WORK_LIMIT. False-fail ≤ α.
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let pairs: Vec<(f64, bool)> = (0..100_000)
            .map(|_| {
                let q = 0.45 + 0.05 * rng.random::<f64>();
                (q, rng.random::<f64>() < q)
            })
            .collect();
        let r = check_calibration(&pairs, 1, ALPHA).unwrap();
        assert!(r.passed && !r.bins[0].exact, "{r:?}");
        let skewed: Vec<(f64, bool)> = pairs.iter().map(|&(_, e)| (0.4, e)).collect();
        assert!(!check_calibration(&skewed, 1, ALPHA).unwrap().passed);
    }
}
