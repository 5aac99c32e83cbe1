//! Exact binomial inference (docs/secrecy.md): Clopper–Pearson intervals, one-sided confidence
//! bounds, and the two-sided exact binomial test.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::special::{inverse_regularized_incomplete_beta, ln_add_exp};

/// A closed interval [lower, upper].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Interval {
    /// Lower end.
    pub lower: f64,
    /// Upper end.
    pub upper: f64,
}

impl Interval {
    /// Whether `x` lies in [lower, upper].
    #[must_use]
    pub fn contains(&self, x: f64) -> bool {
        self.lower <= x && x <= self.upper
    }
}

/// Errors of the binomial inference functions.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, Error)]
pub enum IntervalError {
    /// More successes than trials.
    #[error("{successes} successes exceed {trials} trials")]
    SuccessesExceedTrials {
        /// Successes given.
        successes: u64,
        /// Trials given.
        trials: u64,
    },
    /// A confidence level or failure probability outside the open interval (0, 1).
    #[error("level {0} must lie strictly between 0 and 1")]
    InvalidLevel(f64),
    /// A null-hypothesis probability outside the open interval (0, 1).
    #[error("null probability {0} must lie strictly between 0 and 1")]
    InvalidProbability(f64),
    /// More trials than the exact test's O(n) evaluation accepts ([`MAX_TEST_TRIALS`]).
    #[error("{0} trials exceed the exact test's limit of {MAX_TEST_TRIALS}")]
    TooManyTrials(u64),
    /// The incomplete-beta evaluation did not converge (parameters far beyond 10^9).
    #[error("incomplete beta function did not converge")]
    NoConvergence,
}

fn check(successes: u64, trials: u64, level: f64) -> Result<(), IntervalError> {
    if successes > trials {
        return Err(IntervalError::SuccessesExceedTrials { successes, trials });
    }
    if !(level > 0.0 && level < 1.0) {
        return Err(IntervalError::InvalidLevel(level));
    }
    Ok(())
}

/// Beta(a, b) quantile at `q` as an f64 computation on integer parameters.
fn beta_quantile(q: f64, a: u64, b: u64) -> Result<f64, IntervalError> {
    inverse_regularized_incomplete_beta(q, a as f64, b as f64).ok_or(IntervalError::NoConvergence)
}

/// One-sided Clopper–Pearson lower bound on the success probability at level 1 − ε:
/// the ε-quantile of Beta(k, n − k + 1), and 0 when k = 0. P(p < bound) ≤ ε.
pub fn clopper_pearson_lower(
    successes: u64,
    trials: u64,
    epsilon: f64,
) -> Result<f64, IntervalError> {
    check(successes, trials, epsilon)?;
    if successes == 0 {
        return Ok(0.0);
    }
    beta_quantile(epsilon, successes, trials - successes + 1)
}

/// One-sided Clopper–Pearson upper bound on the success probability at level 1 − ε:
/// the (1 − ε)-quantile of Beta(k + 1, n − k), and 1 when k = n. P(p > bound) ≤ ε.
pub fn clopper_pearson_upper(
    successes: u64,
    trials: u64,
    epsilon: f64,
) -> Result<f64, IntervalError> {
    check(successes, trials, epsilon)?;
    if successes == trials {
        return Ok(1.0);
    }
    beta_quantile(1.0 - epsilon, successes + 1, trials - successes)
}

/// Two-sided Clopper–Pearson exact interval at `confidence` = 1 − α: the one-sided bounds at
/// ε = α/2 each. With no trials it is [0, 1].
pub fn clopper_pearson(
    successes: u64,
    trials: u64,
    confidence: f64,
) -> Result<Interval, IntervalError> {
    check(successes, trials, confidence)?;
    let half_alpha = 0.5 * (1.0 - confidence);
    Ok(Interval {
        lower: clopper_pearson_lower(successes, trials, half_alpha)?,
        upper: clopper_pearson_upper(successes, trials, half_alpha)?,
    })
}

/// Largest number of trials [`binomial_test`] accepts (it costs O(n) time and memory).
pub const MAX_TEST_TRIALS: u64 = 100_000_000;

/// Two-sided exact binomial test of H₀: p = p₀ given k successes in n trials: the total
/// probability under H₀ of all outcomes no more likely than k,
/// Σ_{i : P(i) ≤ P(k)(1 + 10⁻⁷)} P(i) (the rule of R's `binom.test`). With no trials it is 1.
///
/// Use it for "acceptance does not depend on the key bit": P(b = 1 | accepted) = ½.
/// Costs O(n) (the pmf is built by its ratio recurrence in log space).
pub fn binomial_test(successes: u64, trials: u64, p0: f64) -> Result<f64, IntervalError> {
    if successes > trials {
        return Err(IntervalError::SuccessesExceedTrials { successes, trials });
    }
    if !(p0 > 0.0 && p0 < 1.0) {
        return Err(IntervalError::InvalidProbability(p0));
    }
    if trials > MAX_TEST_TRIALS {
        return Err(IntervalError::TooManyTrials(trials));
    }
    let ln_pmf = binomial_ln_pmf(trials, p0);
    let Some(&ln_observed) = usize::try_from(successes).ok().and_then(|k| ln_pmf.get(k)) else {
        return Err(IntervalError::SuccessesExceedTrials { successes, trials });
    };
    let threshold = ln_observed + (1e-7_f64).ln_1p();
    let ln_p = ln_pmf
        .iter()
        .filter(|&&lp| lp <= threshold)
        .fold(f64::NEG_INFINITY, |acc, &lp| ln_add_exp(acc, lp));
    Ok(ln_p.exp().min(1.0))
}

/// ln P[Bin(n, p) = i] for i = 0..=n by the recurrence
/// ln P(i + 1) = ln P(i) + ln((n − i)/(i + 1)) + ln(p/(1 − p)), normalised in log space.
pub(crate) fn binomial_ln_pmf(n: u64, p: f64) -> Vec<f64> {
    let mut out = Vec::with_capacity(usize::try_from(n).map_or(0, |n| n.saturating_add(1)));
    let ln_odds = p.ln() - (-p).ln_1p();
    let mut lp = n as f64 * (-p).ln_1p();
    for i in 0..=n {
        out.push(lp);
        lp += ((n - i) as f64).ln() - ((i + 1) as f64).ln() + ln_odds;
    }
    // Remove the drift of the recurrence: the pmf sums to one.
    let total = out
        .iter()
        .fold(f64::NEG_INFINITY, |acc, &v| ln_add_exp(acc, v));
    for v in &mut out {
        *v -= total;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn clopper_pearson_known_values() {
        let i = clopper_pearson(0, 10, 0.95).unwrap();
        assert_eq!(i.lower, 0.0);
        assert!(close(i.upper, 0.308_497_1, 5e-8), "{i:?}");
        let i = clopper_pearson(5, 10, 0.95).unwrap();
        assert!(close(i.lower, 0.187_086, 5e-7), "{i:?}");
        assert!(close(i.upper, 0.812_914, 5e-7), "{i:?}");
        let i = clopper_pearson(10, 10, 0.95).unwrap();
        assert!(
            close(i.lower, 1.0 - 0.308_497_1, 5e-8) && i.upper == 1.0,
            "{i:?}"
        );
        // R: binom.test(682, 925, p = 0.75)$conf.int = [0.7076683, 0.7654066].
        let i = clopper_pearson(682, 925, 0.95).unwrap();
        assert!(
            close(i.lower, 0.707_668_3, 5e-7) && close(i.upper, 0.765_406_6, 5e-7),
            "{i:?}"
        );
    }

    #[test]
    fn one_sided_bounds_have_their_level() {
        // 0 successes in n: upper bound is 1 − ε^{1/n}.
        let u = clopper_pearson_upper(0, 345, 1e-6).unwrap();
        assert!(close(u, 1.0 - 1e-6_f64.powf(1.0 / 345.0), 1e-12), "{u}");
        // n successes in n: lower bound is ε^{1/n}.
        let l = clopper_pearson_lower(345, 345, 1e-6).unwrap();
        assert!(close(l, 1e-6_f64.powf(1.0 / 345.0), 1e-12), "{l}");
        // A two-sided 95 % interval is the pair of one-sided 97.5 % bounds.
        let i = clopper_pearson(37, 200, 0.95).unwrap();
        assert_eq!(i.lower, clopper_pearson_lower(37, 200, 0.025).unwrap());
        assert_eq!(i.upper, clopper_pearson_upper(37, 200, 0.025).unwrap());
        assert!(i.contains(37.0 / 200.0));
    }

    #[test]
    fn invalid_input_is_an_error() {
        assert!(matches!(
            clopper_pearson(11, 10, 0.95),
            Err(IntervalError::SuccessesExceedTrials { .. })
        ));
        assert!(matches!(
            clopper_pearson(1, 10, 1.0),
            Err(IntervalError::InvalidLevel(_))
        ));
        assert!(matches!(
            clopper_pearson_upper(1, 10, f64::NAN),
            Err(IntervalError::InvalidLevel(_))
        ));
        assert!(matches!(
            binomial_test(1, 10, 0.0),
            Err(IntervalError::InvalidProbability(_))
        ));
        assert!(matches!(
            binomial_test(11, 10, 0.5),
            Err(IntervalError::SuccessesExceedTrials { .. })
        ));
    }

    #[test]
    fn binomial_test_known_values() {
        // R: binom.test(7, 10)$p.value = 0.34375; binom.test(0, 10) = 2/1024.
        assert!(close(binomial_test(7, 10, 0.5).unwrap(), 0.343_75, 1e-12));
        assert!(close(
            binomial_test(0, 10, 0.5).unwrap(),
            2.0 / 1024.0,
            1e-15
        ));
        assert!(close(binomial_test(5, 10, 0.5).unwrap(), 1.0, 1e-12));
        // R: binom.test(682, 925, p = 0.75)$p.value = 0.3824916.
        assert!(close(
            binomial_test(682, 925, 0.75).unwrap(),
            0.382_491_6,
            5e-7
        ));
        assert_eq!(binomial_test(0, 0, 0.5).unwrap(), 1.0);
    }

    #[test]
    fn binomial_test_scales_to_large_n() {
        // 500 600 of 10^6 under p0 = ½ (reference by direct summation in Python: 0.2305279).
        let p = binomial_test(500_600, 1_000_000, 0.5).unwrap();
        assert!(close(p, 0.230_527_9, 1e-6), "{p}");
    }

    #[test]
    fn pmf_sums_to_one() {
        let lp = binomial_ln_pmf(40, 0.3);
        let s: f64 = lp.iter().map(|v| v.exp()).sum();
        assert!(close(s, 1.0, 1e-12));
        // P[Bin(40, 0.3) = 12] = C(40,12) 0.3^12 0.7^28.
        let c =
            (29..=40).map(f64::from).product::<f64>() / (1..=12).map(f64::from).product::<f64>();
        assert!(close(
            lp[12].exp(),
            c * 0.3_f64.powi(12) * 0.7_f64.powi(28),
            1e-13
        ));
    }
}
