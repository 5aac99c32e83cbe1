//! Repetition-code advantage distillation (Maurer) for i.i.d. errors (docs/secrecy.md): the
//! paper's "repeat each bit N times, keep it only if all N estimates agree".
//!
//! These closed forms assume independent, stationary errors for the controller (p_c) and Eve
//! (p_e). The robot's real errors are correlated and position-dependent: use them as a
//! reference, and estimate from the joint table ([`crate::entropy::JointCounts`]).

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::entropy::{binary_convolution, binary_entropy};
use crate::special::ln_gamma;

/// Errors of the advantage-distillation formulas.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, Error)]
pub enum AdvantageError {
    /// An error probability outside [0, 1], or NaN.
    #[error("error probability {0} is out of range")]
    InvalidProbability(f64),
    /// Repetition length N = 0.
    #[error("repetition length must be at least 1")]
    ZeroRepetition,
}

fn check(p: f64) -> Result<(), AdvantageError> {
    if (0.0..=1.0).contains(&p) {
        Ok(())
    } else {
        Err(AdvantageError::InvalidProbability(p))
    }
}

fn check_n(n: u32) -> Result<i32, AdvantageError> {
    match i32::try_from(n) {
        Ok(0) => Err(AdvantageError::ZeroRepetition),
        Ok(v) => Ok(v),
        Err(_) => Err(AdvantageError::ZeroRepetition),
    }
}

/// Acceptance probability of one N-bit codeword: P_acc = p_c^N + (1 − p_c)^N.
pub fn acceptance_probability(p_c: f64, n: u32) -> Result<f64, AdvantageError> {
    check(p_c)?;
    let n = check_n(n)?;
    Ok(p_c.powi(n) + (1.0 - p_c).powi(n))
}

/// Controller's residual error given acceptance: p_B = p_c^N / P_acc.
pub fn residual_error(p_c: f64, n: u32) -> Result<f64, AdvantageError> {
    let accept = acceptance_probability(p_c, n)?;
    Ok(p_c.powi(check_n(n)?) / accept)
}

/// Eve's uncertainty about an accepted bit S when she keeps her whole N-bit pattern of
/// i.i.d. decisions with error p_e (independent of the controller's):
/// H(S | Eve) = Σ_j C(N, j)·P(j)·h(P(S = 1 | j)) over patterns with j ones, where
/// P(j) = ½[(1 − p)^j p^{N−j} + p^j (1 − p)^{N−j}] and the posterior log-odds are
/// (2j − N)·ln((1 − p)/p). For N = 3 this is P_u·h(p³/P_u) + (1 − P_u)·h(p),
/// P_u = p³ + (1 − p)³ (0.138 bit at p = 0.1).
pub fn eve_pattern_entropy(p_e: f64, n: u32) -> Result<f64, AdvantageError> {
    check(p_e)?;
    check_n(n)?;
    let p = p_e.min(1.0 - p_e); // an Eve wrong more than half the time flips her bits
    if p == 0.0 {
        return Ok(0.0);
    }
    let (ln_p, ln_q) = (p.ln(), (-p).ln_1p());
    let nf = f64::from(n);
    let ln_n_fact = ln_gamma(nf + 1.0).unwrap_or(0.0);
    let mut entropy = 0.0;
    for j in 0..=n {
        let jf = f64::from(j);
        let ln_choose =
            ln_n_fact - ln_gamma(jf + 1.0).unwrap_or(0.0) - ln_gamma(nf - jf + 1.0).unwrap_or(0.0);
        let a = jf * ln_q + (nf - jf) * ln_p; // ln P(pattern | S = 1)
        let b = jf * ln_p + (nf - jf) * ln_q; // ln P(pattern | S = 0)
        let weight = 0.5 * ((ln_choose + a).exp() + (ln_choose + b).exp());
        // Posterior of the less likely value: 1/(1 + e^{|a − b|}).
        let minority = 1.0 / (1.0 + (a - b).abs().exp());
        entropy += weight * binary_entropy(minority);
    }
    Ok(entropy)
}

/// Key rate per robot step after repetition AD + one-way reconciliation + amplification
/// (asymptotic): (P_acc/N)·[H(S | Eve) − h(p_B)]⁺.
pub fn rate_with_advantage_distillation(p_c: f64, p_e: f64, n: u32) -> Result<f64, AdvantageError> {
    let ad = RepetitionAdvantage::new(p_c, p_e, n)?;
    Ok(ad.rate_per_step)
}

/// Key rate per step without AD (one-way reconciliation + amplification, asymptotic):
/// [h(p_e) − h(p_c)]⁺ for p_c, p_e ≤ ½.
pub fn rate_one_way(p_c: f64, p_e: f64) -> Result<f64, AdvantageError> {
    check(p_c)?;
    check(p_e)?;
    Ok((binary_entropy(p_e) - binary_entropy(p_c)).max(0.0))
}

/// Upper bound on the key rate per step for independent errors:
/// I(B; B̂c | B̂a) = h(p_c ⋆ p_e) − h(p_c).
pub fn rate_upper_bound(p_c: f64, p_e: f64) -> Result<f64, AdvantageError> {
    check(p_c)?;
    check(p_e)?;
    Ok((binary_entropy(binary_convolution(p_c, p_e)) - binary_entropy(p_c)).max(0.0))
}

/// Whether repetition AD with long enough N gives a positive rate against i.i.d. Eve:
/// p_c/(1 − p_c) < 2√(p_e(1 − p_e)) (it can hold even when p_e < p_c).
pub fn advantage_distillation_possible(p_c: f64, p_e: f64) -> Result<bool, AdvantageError> {
    check(p_c)?;
    check(p_e)?;
    Ok(p_c / (1.0 - p_c) < 2.0 * (p_e * (1.0 - p_e)).sqrt())
}

/// Every figure of repetition advantage distillation for one (p_c, p_e, N).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RepetitionAdvantage {
    /// Repetition length N.
    pub n: u32,
    /// P_acc = p_c^N + (1 − p_c)^N.
    pub acceptance: f64,
    /// p_B = p_c^N / P_acc.
    pub residual_error: f64,
    /// H(S | Eve's N-bit pattern).
    pub eve_entropy: f64,
    /// (P_acc/N)·[H(S | Eve) − h(p_B)]⁺ bits per robot step.
    pub rate_per_step: f64,
    /// [h(p_e) − h(p_c)]⁺ bits per robot step without AD.
    pub rate_without: f64,
}

impl RepetitionAdvantage {
    /// Evaluates the closed forms for controller error `p_c`, Eve error `p_e`, length `n`.
    pub fn new(p_c: f64, p_e: f64, n: u32) -> Result<Self, AdvantageError> {
        let acceptance = acceptance_probability(p_c, n)?;
        let residual_error = residual_error(p_c, n)?;
        let eve_entropy = eve_pattern_entropy(p_e, n)?;
        let rate_per_step =
            acceptance / f64::from(n) * (eve_entropy - binary_entropy(residual_error)).max(0.0);
        Ok(Self {
            n,
            acceptance,
            residual_error,
            eve_entropy,
            rate_per_step,
            rate_without: rate_one_way(p_c, p_e)?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn n3_matches_secrecy_formula() {
        let p: f64 = 0.1;
        let pu = p.powi(3) + (1.0 - p).powi(3);
        let closed = pu * binary_entropy(p.powi(3) / pu) + (1.0 - pu) * binary_entropy(p);
        let got = eve_pattern_entropy(p, 3).unwrap();
        assert!(close(got, closed, 1e-14), "{got} vs {closed}");
        assert!(close(got, 0.138, 5e-4), "{got}");
        // Not the majority-vote figure h(p_E) = 0.184 (p_E = 3p²(1−p) + p³ = 0.028).
        assert!(close(binary_entropy(0.028), 0.184, 5e-4));
    }

    #[test]
    fn pattern_entropy_limits() {
        // N = 1: Eve's single bit leaves h(p).
        assert!(close(
            eve_pattern_entropy(0.2, 1).unwrap(),
            binary_entropy(0.2),
            1e-14
        ));
        assert_eq!(eve_pattern_entropy(0.0, 5).unwrap(), 0.0);
        assert!(close(eve_pattern_entropy(0.5, 7).unwrap(), 1.0, 1e-12));
        // More copies help Eve.
        let h: Vec<f64> = (1..8)
            .map(|n| eve_pattern_entropy(0.2, n).unwrap())
            .collect();
        assert!(h.windows(2).all(|w| w[1] < w[0]), "{h:?}");
        // Large N stays finite and small.
        let big = eve_pattern_entropy(0.3, 2000).unwrap();
        assert!((0.0..1e-10).contains(&big), "{big}");
    }

    #[test]
    fn acceptance_and_residual_error() {
        let p: f64 = 0.05;
        let acc = acceptance_probability(p, 3).unwrap();
        assert!(close(acc, p.powi(3) + 0.95_f64.powi(3), 1e-15));
        assert!(close(residual_error(p, 3).unwrap(), p.powi(3) / acc, 1e-15));
        assert_eq!(
            acceptance_probability(p, 0),
            Err(AdvantageError::ZeroRepetition)
        );
        assert!(matches!(
            residual_error(1.5, 3),
            Err(AdvantageError::InvalidProbability(_))
        ));
    }

    #[test]
    fn rates() {
        // Eve better than controller: no one-way rate, but AD can still work.
        let (pc, pe) = (0.2, 0.15);
        assert_eq!(rate_one_way(pc, pe).unwrap(), 0.0);
        assert!(advantage_distillation_possible(pc, pe).unwrap());
        let ad = RepetitionAdvantage::new(pc, pe, 5).unwrap();
        assert!(ad.rate_per_step > 0.0, "{ad:?}");
        assert!(close(
            rate_with_advantage_distillation(pc, pe, 5).unwrap(),
            ad.rate_per_step,
            0.0
        ));
        // Oracle Eve (same error statistics, p_e = 0): nothing.
        assert_eq!(
            RepetitionAdvantage::new(0.1, 0.0, 3).unwrap().rate_per_step,
            0.0
        );
        // Without AD and independent errors: h(pe) − h(pc) ≤ h(pc ⋆ pe) − h(pc).
        let (pc, pe) = (0.05, 0.2);
        let one_way = rate_one_way(pc, pe).unwrap();
        assert!(close(
            one_way,
            binary_entropy(0.2) - binary_entropy(0.05),
            1e-15
        ));
        assert!(one_way < rate_upper_bound(pc, pe).unwrap());
        // Condition fails when the controller is far worse than Eve.
        assert!(!advantage_distillation_possible(0.4, 0.01).unwrap());
    }
}
