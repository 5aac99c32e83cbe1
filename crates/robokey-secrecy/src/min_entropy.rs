//! Finite-key privacy amplification (docs/secrecy.md): lower bounds on Eve's smooth min-entropy
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
    /// A Gaussian view's separation that is negative or not finite.
    #[error("separation {0} must be finite and non-negative")]
    InvalidSeparation(f64),
    /// A view's noise standard deviation that is not positive and finite.
    #[error("noise standard deviation {0} must be finite and positive")]
    InvalidNoise(f64),
}

pub(crate) fn check_epsilon(epsilon: f64) -> Result<(), MinEntropyError> {
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

/// Binomial bound (docs/secrecy.md): with Eve's errors i.i.d. with probability p ≤ ½,
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
/// min-entropy H₀. The exact lower-tail Chernoff bound on the total surprisal
/// S = Σ S_i, with E[e^{−μ·ln2·S_i}] = (1 − q_i)^{1+μ} + q_i^{1+μ}, is another valid cut
/// (`chernoff_lower_quantile`); the larger of the two is returned. For constant q it is
/// below the exact [`binomial_smooth_min_entropy`].
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
    // ln(1 − q) and ln q of each bit, which do not depend on λ: computed once for the
    // search's ~150 evaluations.
    let logs: Vec<(f64, f64)> = error_probabilities
        .iter()
        .map(|&q| q.min(1.0 - q))
        .filter(|&q| q > 0.0)
        .map(|q| ((1.0 - q).ln(), q.ln()))
        .collect();
    let chernoff = chernoff_lower_quantile(
        |lambda| {
            let mu = lambda / std::f64::consts::LN_2;
            logs.iter()
                // In log space: the powers underflow to 0 for large μ.
                .map(|&(ln_p, ln_q)| ln_add_exp((1.0 + mu) * ln_p, (1.0 + mu) * ln_q))
                .sum()
        },
        epsilon,
    );
    Ok(PosteriorMinEntropy {
        positions: error_probabilities.len(),
        epsilon,
        plain,
        mean_surprise: mean,
        deviation,
        h_min: (plain + (mean - deviation).max(0.0)).max(chernoff.0.min(plain + mean)),
    })
}

/// The largest `t` that the lower-tail Chernoff bound `P[S ≤ t] ≤ min_λ e^{λt}·E[e^{−λS}]`
/// keeps at or below ε, for a total surprisal `S` (bits) whose `ln E[e^{−λS}]` is
/// `ln_mgf(λ)`: `t = max_λ (−ln_mgf(λ) − ln(1/ε)) / λ`, searched over λ ∈ [10⁻⁴, 10³] (a
/// log-spaced scan, then golden-section refinement). Returns `(t, λ)`; `t` may be negative
/// (no bound).
pub(crate) fn chernoff_lower_quantile(ln_mgf: impl Fn(f64) -> f64, epsilon: f64) -> (f64, f64) {
    let ln_inv_eps = -epsilon.ln();
    // The golden-section points often land on a λ already evaluated, bit for bit (about a
    // third of them): each λ's `t` is computed once and looked up after.
    let evaluated = std::cell::RefCell::new(Vec::<(u64, f64)>::with_capacity(160));
    // A λ whose moment underflowed proves nothing: −∞, never +∞.
    let t_of = |lambda: f64| {
        let key = lambda.to_bits();
        if let Some(&(_, t)) = evaluated.borrow().iter().find(|(k, _)| *k == key) {
            return t;
        }
        let t = (-ln_mgf(lambda) - ln_inv_eps) / lambda;
        let t = if t.is_finite() { t } else { f64::NEG_INFINITY };
        evaluated.borrow_mut().push((key, t));
        t
    };
    let grid: Vec<f64> = (0..=70)
        .map(|i| 10f64.powf(-4.0 + 7.0 * f64::from(i) / 70.0))
        .collect();
    let values: Vec<f64> = grid.iter().map(|&l| t_of(l)).collect();
    let best = (0..grid.len())
        .max_by(|&a, &b| values[a].total_cmp(&values[b]))
        .unwrap_or(0);
    let (mut lo, mut hi) = (
        grid[best.saturating_sub(1)].ln(),
        grid[(best + 1).min(grid.len() - 1)].ln(),
    );
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..40 {
        let (a, b) = (hi - ratio * (hi - lo), lo + ratio * (hi - lo));
        if t_of(a.exp()) > t_of(b.exp()) {
            hi = b;
        } else {
            lo = a;
        }
    }
    let lambda = (0.5 * (lo + hi)).exp();
    (t_of(lambda).max(values[best]), lambda)
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

/// Output length (docs/secrecy.md, leftover hash lemma):
/// ℓ = max(0, ⌊H_min^ε(X|E) − leak_EC − t_ver − 2·log₂(1/ε_PA) + 2⌋), secure with
/// ε_sec = 2ε_s + ε_PA + ε_PE. `h_min` must be a lower bound on Eve's smooth min-entropy;
/// `leak_ec` is the realised reconciliation leak and `t_ver` the confirmation tag length.
/// The caller must pass as `leak_ec` every public bit that depends on the key (reconciliation
/// parities and any other disclosed function of it) except the tag length passed as `t_ver`.
/// The shortfall `reason` states the deficit only; advice on what to do is the caller's.
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
             t_ver {t_ver} + 2*log2(1/eps_PA) - 2 = {cost:.2} bits (raw length {raw:.2})"
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

    #[test]
    fn shortfall_reason_states_the_deficit_only() {
        let l = output_length(80.0, 20, 64, EPS).unwrap();
        let reason = l.reason.unwrap();
        assert!(reason.contains("does not cover leak_EC 20"), "{reason}");
        assert!(
            reason.ends_with(&format!("(raw length {:.2})", l.raw)),
            "{reason}"
        );
    }

    /// Joint distribution of n independent bits with P[bit i = 1] = q_i, indexed by the
    /// pattern (bit i of the index is bit i of the pattern).
    fn product_distribution(q: &[f64]) -> Vec<f64> {
        let mut probs = Vec::with_capacity(1 << q.len());
        probs.push(1.0);
        for &qi in q {
            let len = probs.len();
            for j in 0..len {
                let p = probs[j];
                probs[j] = p * (1.0 - qi);
                probs.push(p * qi);
            }
        }
        probs
    }

    /// Exact best-removal smooth min-entropy of an arbitrary joint distribution over the 2ⁿ
    /// patterns (Eve's joint posterior of the key given her view): drop the likeliest patterns
    /// while their total mass stays ≤ ε; the value is −log₂ of the likeliest pattern left.
    /// (No other removal of mass ≤ ε leaves a smaller maximum: getting below p_k means
    /// removing p_1..p_k, whose mass exceeds ε.) Sorts once: O(2ⁿ·n).
    fn exact_smooth_min_entropy(mut probs: Vec<f64>, epsilon: f64) -> f64 {
        probs.sort_unstable_by(|a, b| b.total_cmp(a));
        let mut removed = 0.0;
        for &p in &probs {
            if removed + p > epsilon {
                return -p.log2();
            }
            removed += p;
        }
        f64::INFINITY
    }

    /// The soundness check every non-approximate bound must pass: bound ≤ exact (with a
    /// rounding margin of 10⁻⁹ bits).
    fn exceeds_exact(bound: f64, exact: f64) -> bool {
        bound > exact + 1e-9
    }

    #[test]
    fn exact_reference_on_hand_computed_joints() {
        // Non-product joint on 2 bits: {0.4, 0.3, 0.2, 0.1}.
        let joint = vec![0.1, 0.4, 0.2, 0.3];
        assert!((exact_smooth_min_entropy(joint.clone(), 0.35) + 0.4_f64.log2()).abs() < 1e-12);
        assert!((exact_smooth_min_entropy(joint.clone(), 0.45) + 0.3_f64.log2()).abs() < 1e-12);
        assert!((exact_smooth_min_entropy(joint, 0.75) + 0.2_f64.log2()).abs() < 1e-12);
        // The product builder matches the pattern-by-pattern product.
        let q = [0.1, 0.25, 0.4];
        let probs = product_distribution(&q);
        for (m, &p) in probs.iter().enumerate() {
            let direct: f64 = (0..3)
                .map(|i| if m >> i & 1 == 1 { q[i] } else { 1.0 - q[i] })
                .product();
            assert!((p - direct).abs() < 1e-15);
        }
    }

    /// The search evaluates each λ once: the golden-section points that land on one
    /// already evaluated are looked up, and the result is what evaluating them again gives.
    #[test]
    fn the_chernoff_search_evaluates_each_lambda_once() {
        let calls = std::cell::RefCell::new(Vec::new());
        let ln_mgf = |lambda: f64| -> f64 {
            calls.borrow_mut().push(lambda.to_bits());
            // A sum of 200 Bernoulli surprisals, q = 0.1, in log space.
            let mu = lambda / std::f64::consts::LN_2;
            200.0 * ln_add_exp((1.0 + mu) * 0.9_f64.ln(), (1.0 + mu) * 0.1_f64.ln())
        };
        let (t, lambda) = chernoff_lower_quantile(ln_mgf, 1e-6);
        let mut distinct = calls.borrow().clone();
        let evaluations = distinct.len();
        distinct.sort_unstable();
        distinct.dedup();
        assert_eq!(distinct.len(), evaluations, "a λ evaluated twice");
        // 71 grid points, 2 per golden-section round, the final λ: fewer when some repeat.
        assert!(evaluations < 71 + 2 * 40 + 1, "{evaluations} evaluations");
        let direct = (-ln_mgf(lambda) - 1e-6_f64.ln().abs()) / lambda;
        assert!(t >= direct, "{t} < {direct} at λ = {lambda}");
    }

    #[test]
    fn the_independence_assumption_is_load_bearing() {
        // 12 bits with marginals ½ but all equal (two patterns of mass ½): 1 bit of
        // min-entropy, while the posterior bound, which assumes independence, claims 12.
        let n = 12;
        let mut joint = vec![0.0; 1 << n];
        joint[0] = 0.5;
        joint[(1 << n) - 1] = 0.5;
        let exact = exact_smooth_min_entropy(joint, 0.1);
        assert!((exact - 1.0).abs() < 1e-12);
        let bound = posterior_smooth_min_entropy(&[0.5; 12], 0.1).unwrap().h_min;
        assert!(exceeds_exact(bound, exact), "{bound}");
    }

    #[test]
    fn the_soundness_check_catches_optimistic_bounds() {
        // Fixed example: n = 20, q = 0.1, ε = 0.05. Exact: P[Bin(20, 0.1) = 0] = 0.12 > ε, so
        // nothing is removed and H_min^ε = 20·log₂(1/0.9) ≈ 3.04 bits.
        let (q, eps) = ([0.1; 20], 0.05);
        let exact = exact_smooth_min_entropy(product_distribution(&q), eps);
        assert!(
            (exact - 20.0 * (1.0 / 0.9_f64).log2()).abs() < 1e-9,
            "{exact}"
        );
        let post = posterior_smooth_min_entropy(&q, eps).unwrap();
        assert!(!exceeds_exact(post.h_min, exact));
        // Without the deviation: H₀ + E(L) = Σ h(q_i), the Shannon entropy ≈ 9.38 bits.
        let no_deviation = post.plain + post.mean_surprise;
        let shannon: f64 = q.iter().map(|&v| crate::entropy::binary_entropy(v)).sum();
        assert!((no_deviation - shannon).abs() < 1e-9);
        assert!(
            exceeds_exact(no_deviation, exact),
            "{no_deviation} vs {exact}"
        );
        // A binomial bound with the mean n·p = 2 errors in place of the quantile w* = 0.
        let bin = binomial_smooth_min_entropy(20, 0.1, eps).unwrap();
        assert!(!exceeds_exact(bin.h_min, exact));
        let at_mean = 2.0 * (1.0 / 0.1_f64).log2() + 18.0 * (1.0 / 0.9_f64).log2();
        assert!(exceeds_exact(at_mean, exact), "{at_mean} vs {exact}");
    }

    /// A per-position error probability: uniform on (0.001, 0.999) or log-uniform near 0.
    fn posterior_q() -> impl Strategy<Value = f64> {
        prop_oneof![
            0.001_f64..0.999,
            (-4.0_f64..-1.0).prop_map(|e| 10_f64.powf(e))
        ]
    }

    /// ε log-uniform in [0.01, 0.3].
    fn smoothing_epsilon() -> impl Strategy<Value = f64> {
        (0.01_f64.ln()..=0.3_f64.ln()).prop_map(f64::exp)
    }

    fn check_posterior_bound(q: &[f64], eps: f64) -> Result<(), TestCaseError> {
        let bound = posterior_smooth_min_entropy(q, eps).unwrap().h_min;
        let exact = exact_smooth_min_entropy(product_distribution(q), eps);
        prop_assert!(
            !exceeds_exact(bound, exact),
            "bound {} > exact {}",
            bound,
            exact
        );
        Ok(())
    }

    fn check_binomial_bound(n: usize, p: f64, eps: f64) -> Result<(), TestCaseError> {
        let bound = binomial_smooth_min_entropy(n as u64, p, eps).unwrap().h_min;
        let exact = exact_smooth_min_entropy(product_distribution(&vec![p; n]), eps);
        prop_assert!(
            !exceeds_exact(bound, exact),
            "bound {} > exact {}",
            bound,
            exact
        );
        Ok(())
    }

    #[test]
    fn bounds_are_sound_at_20_bits() {
        // Fixed grid at the largest enumerated length (2²⁰ patterns per case).
        let q: Vec<f64> = (0..20).map(|i| 0.002 + 0.025 * f64::from(i)).collect();
        for eps in [0.01, 0.05, 0.1, 0.3] {
            check_posterior_bound(&q, eps).unwrap();
            for p in [0.02, 0.1, 0.3, 0.5] {
                check_binomial_bound(20, p, eps).unwrap();
            }
        }
    }

    proptest! {
        #[test]
        fn posterior_bound_is_sound_small_n(
            q in proptest::collection::vec(posterior_q(), 1..=12),
            eps in smoothing_epsilon(),
        ) {
            check_posterior_bound(&q, eps)?;
        }

        #[test]
        fn binomial_bound_is_sound_small_n(
            n in 1_usize..=12,
            p in 0.001_f64..=0.5,
            eps in smoothing_epsilon(),
        ) {
            check_binomial_bound(n, p, eps)?;
        }
    }

    proptest! {
        // 2¹³..2²⁰ patterns per case: few cases.
        #![proptest_config(ProptestConfig::with_cases(12))]

        #[test]
        fn posterior_bound_is_sound_up_to_20_bits(
            q in proptest::collection::vec(posterior_q(), 13..=20),
            eps in smoothing_epsilon(),
        ) {
            check_posterior_bound(&q, eps)?;
        }

        #[test]
        fn binomial_bound_is_sound_up_to_20_bits(
            n in 13_usize..=20,
            p in 0.001_f64..=0.5,
            eps in smoothing_epsilon(),
        ) {
            check_binomial_bound(n, p, eps)?;
        }
    }
}
