//! Finite-key privacy amplification (SECRECY §5): lower bounds on Eve's smooth min-entropy
//! H_min^ε(X|E) and the output length ℓ of the Toeplitz hash.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::special::ln_add_exp;

/// Errors of the min-entropy bounds and the output length.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, Error)]
pub enum MinEntropyError {
    /// An error probability outside [0, ½] (binomial bound) or [0, 1] (posteriors), or NaN.
    #[error("error probability {0} is out of range")]
    InvalidProbability(f64),
    /// A smoothing or amplification ε outside the open interval (0, 1).
    #[error("epsilon {0} must lie strictly between 0 and 1")]
    InvalidEpsilon(f64),
    /// A min-entropy that is negative or not finite.
    #[error("min-entropy {0} must be finite and non-negative")]
    InvalidEntropy(f64),
}

fn check_epsilon(epsilon: f64) -> Result<(), MinEntropyError> {
    if epsilon > 0.0 && epsilon < 1.0 {
        Ok(())
    } else {
        Err(MinEntropyError::InvalidEpsilon(epsilon))
    }
}

/// `x·log₂(1/p)` with 0·∞ = 0.
fn times_surprise(x: f64, p: f64) -> f64 {
    if x == 0.0 { 0.0 } else { -x * p.log2() }
}

/// The binomial smooth min-entropy bound for a binary-symmetric view of Eve.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BinomialMinEntropy {
    /// Key length n.
    pub n: u64,
    /// Eve's worst-case per-bit error probability p.
    pub p: f64,
    /// Smoothing parameter ε_s.
    pub epsilon: f64,
    /// w* = min{w : P[Bin(n, p) ≤ w] > ε}.
    pub w_star: u64,
    /// H_min^ε ≥ w*·log₂(1/p) + (n − w*)·log₂(1/(1 − p)), in bits.
    pub h_min: f64,
}

/// Binomial bound (SECRECY §5): with Eve's errors i.i.d. with probability p ≤ ½,
/// H_min^ε(X|E) ≥ w*·log₂(1/p) + (n − w*)·log₂(1/(1 − p)),
/// w* = min{w : P[Bin(n, p) ≤ w] > ε} (removing the error patterns of weight < w*, mass ≤ ε,
/// leaves none likelier than p^{w*}(1 − p)^{n−w*}).
///
/// The CDF is accumulated in log space with the pmf ratio recurrence, so it is stable for n
/// up to 10^6 and beyond; the cost is O(w*).
pub fn binomial_smooth_min_entropy(
    n: u64,
    p: f64,
    epsilon: f64,
) -> Result<BinomialMinEntropy, MinEntropyError> {
    if !(0.0..=0.5).contains(&p) {
        return Err(MinEntropyError::InvalidProbability(p));
    }
    check_epsilon(epsilon)?;
    let w_star = if p == 0.0 {
        0
    } else {
        binomial_quantile_above(n, p, epsilon)
    };
    let h_min = times_surprise(w_star as f64, p) + times_surprise((n - w_star) as f64, 1.0 - p);
    Ok(BinomialMinEntropy {
        n,
        p,
        epsilon,
        w_star,
        h_min,
    })
}

/// min{w : P[Bin(n, p) ≤ w] > ε} for 0 < p ≤ ½, 0 < ε < 1.
fn binomial_quantile_above(n: u64, p: f64, epsilon: f64) -> u64 {
    let ln_epsilon = epsilon.ln();
    let ln_odds = p.ln() - (-p).ln_1p();
    let mut ln_pmf = n as f64 * (-p).ln_1p();
    let mut ln_cdf = ln_pmf;
    let mut w = 0;
    while ln_cdf <= ln_epsilon && w < n {
        ln_pmf += ((n - w) as f64).ln() - ((w + 1) as f64).ln() + ln_odds;
        w += 1;
        ln_cdf = ln_add_exp(ln_cdf, ln_pmf);
    }
    w
}

/// The smooth min-entropy bound from Eve's per-position posterior error probabilities.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PosteriorMinEntropy {
    /// Number of positions n.
    pub positions: usize,
    /// Smoothing parameter ε_s.
    pub epsilon: f64,
    /// Plain (unsmoothed) min-entropy H₀ = Σ −log₂(1 − q_i).
    pub plain: f64,
    /// E(L) = Σ q_i λ_i with λ_i = log₂((1 − q_i)/q_i): mean extra surprise of Eve's errors.
    pub mean_surprise: f64,
    /// Deviation s with P[L ≤ E(L) − s] ≤ ε (the smaller of the Hoeffding and Maurer terms).
    pub deviation: f64,
    /// H_min^ε ≥ H₀ + max(0, E(L) − s), in bits.
    pub h_min: f64,
}

/// Smooth min-entropy bound from Eve's per-position posterior error probabilities q_i (the
/// probability that her best guess of bit i is wrong given everything she saw), assuming the
/// key bits are independent given Eve's view (q > ½ is read as 1 − q: she would flip).
///
/// Given her view, the probability of a key is 2^{−(H₀ + L)} with H₀ = Σ −log₂(1 − q_i) and
/// L = Σ e_i λ_i, e_i ~ Bernoulli(q_i) her independent errors, λ_i = log₂((1 − q_i)/q_i) ≥ 0.
/// Removing the keys with L < E(L) − s (mass ≤ ε) leaves none likelier than
/// 2^{−(H₀ + E(L) − s)}, so H_min^ε ≥ H₀ + max(0, E(L) − s), where s is the smaller of
/// Hoeffding's √(ln(1/ε)/2 · Σλ_i²) and Maurer's lower-tail bound for non-negative summands
/// √(2 ln(1/ε) · Σ q_i λ_i²) (A. Maurer, JIPAM 4(1) 2003). With s = ∞ it is the plain
/// min-entropy H₀. For constant q it is below the exact [`binomial_smooth_min_entropy`].
pub fn posterior_smooth_min_entropy(
    error_probabilities: &[f64],
    epsilon: f64,
) -> Result<PosteriorMinEntropy, MinEntropyError> {
    check_epsilon(epsilon)?;
    let (mut plain, mut mean, mut sum_sq, mut sum_q_sq) = (0.0, 0.0, 0.0, 0.0);
    for &q in error_probabilities {
        if !(0.0..=1.0).contains(&q) {
            return Err(MinEntropyError::InvalidProbability(q));
        }
        let q = q.min(1.0 - q);
        if q == 0.0 {
            continue; // Eve knows this bit: no entropy, no randomness in L.
        }
        let lambda = ((1.0 - q) / q).log2();
        plain -= (1.0 - q).log2();
        mean += q * lambda;
        sum_sq += lambda * lambda;
        sum_q_sq += q * lambda * lambda;
    }
    let ln_inv_eps = -epsilon.ln();
    let hoeffding = (0.5 * ln_inv_eps * sum_sq).sqrt();
    let maurer = (2.0 * ln_inv_eps * sum_q_sq).sqrt();
    let deviation = hoeffding.min(maurer);
    Ok(PosteriorMinEntropy {
        positions: error_probabilities.len(),
        epsilon,
        plain,
        mean_surprise: mean,
        deviation,
        h_min: plain + (mean - deviation).max(0.0),
    })
}

/// The privacy-amplification output length and how it was reached.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OutputLength {
    /// ℓ = max(0, ⌊raw⌋): secret bits to extract.
    pub bits: u64,
    /// raw = H_min^ε − leak_EC − t_ver − 2·log₂(1/ε_PA) + 2 before flooring and clamping.
    pub raw: f64,
    /// Why ℓ = 0, for people (None when ℓ > 0).
    pub reason: Option<String>,
}

/// Output length (SECRECY §5, leftover hash lemma):
/// ℓ = max(0, ⌊H_min^ε(X|E) − leak_EC − t_ver − 2·log₂(1/ε_PA) + 2⌋), secure with
/// ε_sec = 2ε_s + ε_PA + ε_PE. `h_min` must be a lower bound on Eve's smooth min-entropy;
/// `leak_ec` is the realised reconciliation leak and `t_ver` the confirmation tag length.
pub fn output_length(
    h_min: f64,
    leak_ec: u64,
    t_ver: u64,
    epsilon_pa: f64,
) -> Result<OutputLength, MinEntropyError> {
    if !(h_min >= 0.0 && h_min.is_finite()) {
        return Err(MinEntropyError::InvalidEntropy(h_min));
    }
    check_epsilon(epsilon_pa)?;
    let cost = leak_ec as f64 + t_ver as f64 + 2.0 * (1.0 / epsilon_pa).log2() - 2.0;
    let raw = h_min - cost;
    let floor = raw.floor();
    if floor >= 1.0 {
        return Ok(OutputLength {
            bits: floor as u64,
            raw,
            reason: None,
        });
    }
    let reason = if h_min == 0.0 {
        "no secret bits: Eve's min-entropy is zero (she does as well as the controller)".to_owned()
    } else {
        format!(
            "no secret bits: H_min^eps = {h_min:.2} bits does not cover leak_EC {leak_ec} + \
             t_ver {t_ver} + 2*log2(1/eps_PA) - 2 = {cost:.2} bits (raw length {raw:.2}); \
             pool more confirmed sessions before amplifying"
        )
    };
    Ok(OutputLength {
        bits: 0,
        raw,
        reason: Some(reason),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const EPS: f64 = 1e-6;

    fn reference(n: u64, p: f64, w_star: u64, h_min: f64, ell: u64, raw_floor: i64) {
        let b = binomial_smooth_min_entropy(n, p, EPS).unwrap();
        assert_eq!(b.w_star, w_star, "n={n} p={p}");
        assert!((b.h_min - h_min).abs() < 0.005, "n={n} p={p}: {}", b.h_min);
        let l = output_length(b.h_min, 0, 64, EPS).unwrap();
        assert_eq!(l.bits, ell, "n={n} p={p}: {l:?}");
        assert_eq!(l.raw.floor() as i64, raw_floor);
        assert_eq!(l.reason.is_some(), ell == 0);
    }

    #[test]
    fn secrecy_section_5_reference_values() {
        reference(1000, 0.10, 58, 335.86, 233, 233);
        reference(1000, 0.05, 21, 163.21, 61, 61);
        reference(345, 0.10, 11, 87.31, 0, -15);
    }

    #[test]
    fn w_star_is_the_defining_quantile() {
        // Check against direct summation of the pmf for a moderate n.
        let (n, p) = (200_u64, 0.2);
        let pmf = crate::interval::binomial_ln_pmf(n, p);
        let b = binomial_smooth_min_entropy(n, p, 1e-3).unwrap();
        let cdf = |w: u64| pmf[..=w as usize].iter().map(|v| v.exp()).sum::<f64>();
        assert!(cdf(b.w_star) > 1e-3);
        assert!(cdf(b.w_star - 1) <= 1e-3);
    }

    #[test]
    fn binomial_bound_is_stable_for_large_n() {
        let b = binomial_smooth_min_entropy(1_000_000, 0.1, 1e-10).unwrap();
        // Normal approximation: w* ≈ np − 6.36·√(np(1−p)) = 100000 − 1908.
        assert!((b.w_star as f64 - 98_092.0).abs() < 40.0, "{}", b.w_star);
        assert!(b.h_min > 0.0 && b.h_min < 1e6 * crate::entropy::binary_entropy(0.1));
    }

    #[test]
    fn binomial_edge_cases() {
        let b = binomial_smooth_min_entropy(345, 0.0, EPS).unwrap();
        assert_eq!((b.w_star, b.h_min), (0, 0.0));
        let b = binomial_smooth_min_entropy(345, 0.5, EPS).unwrap();
        assert!((b.h_min - 345.0).abs() < 1e-9);
        assert!(binomial_smooth_min_entropy(345, 0.6, EPS).is_err());
        assert!(binomial_smooth_min_entropy(345, 0.1, 0.0).is_err());
        assert!(output_length(f64::NAN, 0, 64, EPS).is_err());
        assert!(output_length(100.0, 0, 64, 1.0).is_err());
        let zero = output_length(0.0, 0, 64, EPS).unwrap();
        assert_eq!(zero.bits, 0);
        assert!(zero.reason.unwrap().contains("zero"));
    }

    #[test]
    fn output_length_subtracts_leak() {
        let l = output_length(1000.0, 300, 64, 1e-6).unwrap();
        let raw = 1000.0 - 300.0 - 64.0 - 2.0 * 1e6_f64.log2() + 2.0;
        assert!((l.raw - raw).abs() < 1e-9);
        assert_eq!(l.bits, raw.floor() as u64);
    }

    #[test]
    fn posterior_bound_matches_constant_case_from_below() {
        let q = vec![0.1; 1000];
        let post = posterior_smooth_min_entropy(&q, EPS).unwrap();
        let bin = binomial_smooth_min_entropy(1000, 0.1, EPS).unwrap();
        assert!((post.plain - 1000.0 * (1.0 / 0.9_f64).log2()).abs() < 1e-9);
        assert!(
            post.h_min <= bin.h_min + 1e-9,
            "{} > {}",
            post.h_min,
            bin.h_min
        );
        assert!(post.h_min >= post.plain);
        // Known bits add nothing; q > ½ counts as 1 − q.
        let mut mixed = q.clone();
        mixed.extend([0.0; 10]);
        assert!(
            (posterior_smooth_min_entropy(&mixed, EPS).unwrap().h_min - post.h_min).abs() < 1e-9
        );
        let flipped: Vec<f64> = q.iter().map(|v| 1.0 - v).collect();
        assert!(
            (posterior_smooth_min_entropy(&flipped, EPS).unwrap().h_min - post.h_min).abs() < 1e-9
        );
        assert!(posterior_smooth_min_entropy(&[0.2, 1.5], EPS).is_err());
        assert!(posterior_smooth_min_entropy(&[0.2, f64::NAN], EPS).is_err());
    }

    /// Exact best removal smoothing for few positions: drop the likeliest keys while their
    /// total mass stays ≤ ε; the bound is −log₂ of the likeliest key left.
    fn exact_smooth_min_entropy(q: &[f64], epsilon: f64) -> f64 {
        let n = q.len();
        let mut probs: Vec<f64> = (0..1_u32 << n)
            .map(|m| {
                (0..n)
                    .map(|i| if m >> i & 1 == 1 { q[i] } else { 1.0 - q[i] })
                    .product()
            })
            .collect();
        probs.sort_by(|a, b| b.total_cmp(a));
        let mut removed = 0.0;
        for &p in &probs {
            if removed + p > epsilon {
                return -p.log2();
            }
            removed += p;
        }
        f64::INFINITY
    }

    proptest! {
        #[test]
        fn posterior_bound_is_sound(
            q in proptest::collection::vec(0.01_f64..0.5, 1..12),
            log_eps in -6.0_f64..-0.5,
        ) {
            let eps = 10_f64.powf(log_eps);
            let bound = posterior_smooth_min_entropy(&q, eps).unwrap().h_min;
            let exact = exact_smooth_min_entropy(&q, eps);
            prop_assert!(bound <= exact + 1e-9, "bound {} > exact {}", bound, exact);
        }
    }
}
