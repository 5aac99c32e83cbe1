//! Special functions behind the exact binomial statistics: ln Γ, the regularized incomplete
//! beta function I_x(a, b) and its inverse.
//!
//! I_x(a, b) links the binomial and beta distributions: for integers 0 ≤ k < n,
//! P[Bin(n, p) ≤ k] = I_{1−p}(n − k, k + 1) and P[Bin(n, p) ≥ k] = I_p(k, n − k + 1).

/// Lanczos approximation parameter g (with the nine coefficients below: ~1e-15 relative error).
pub(crate) const LANCZOS_G: f64 = 7.0;

/// Lanczos coefficients for g = 7, n = 9.
pub(crate) const LANCZOS_COEFFICIENTS: [f64; 9] = [
    0.999_999_999_999_809_9,
    676.520_368_121_885_1,
    -1_259.139_216_722_402_8,
    771.323_428_777_653_1,
    -176.615_029_162_140_6,
    12.507_343_278_686_905,
    -0.138_571_095_265_720_12,
    9.984_369_578_019_572e-6,
    1.505_632_735_149_311_6e-7,
];

/// Iteration cap of the continued fraction; it needs O(√max(a, b)) terms, so this covers
/// a, b far beyond 10^6.
const MAX_CONTINUED_FRACTION_TERMS: usize = 100_000;

/// Relative tolerance at which the continued fraction stops.
const CONTINUED_FRACTION_TOLERANCE: f64 = 1e-15;

/// Guard against division by zero in the modified Lentz method.
const TINY: f64 = 1e-300;

/// ln Γ(x) for x > 0 (Lanczos approximation, g = 7); `None` for x ≤ 0 or non-finite x.
#[must_use]
pub fn ln_gamma(x: f64) -> Option<f64> {
    if !(x > 0.0 && x.is_finite()) {
        return None;
    }
    Some(ln_gamma_positive(x))
}

/// ln Γ(x) for finite x > 0; uses Γ(x) = Γ(x + 1)/x below ½.
fn ln_gamma_positive(x: f64) -> f64 {
    if x < 0.5 {
        return ln_gamma_positive(x + 1.0) - x.ln();
    }
    let x = x - 1.0;
    let mut series = LANCZOS_COEFFICIENTS[0];
    for (i, c) in LANCZOS_COEFFICIENTS.iter().enumerate().skip(1) {
        series += c / (x + i as f64);
    }
    let t = x + LANCZOS_G + 0.5;
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + series.ln()
}

/// Regularized incomplete beta function I_x(a, b) = B(x; a, b)/B(a, b), by the continued
/// fraction of Numerical Recipes (§6.4) evaluated with the modified Lentz method.
///
/// Returns `None` for a ≤ 0, b ≤ 0, x outside [0, 1], non-finite input, or if the continued
/// fraction fails to converge.
#[must_use]
pub fn regularized_incomplete_beta(x: f64, a: f64, b: f64) -> Option<f64> {
    if !(a > 0.0 && b > 0.0 && a.is_finite() && b.is_finite() && (0.0..=1.0).contains(&x)) {
        return None;
    }
    if x == 0.0 {
        return Some(0.0);
    }
    if x == 1.0 {
        return Some(1.0);
    }
    let ln_front = ln_gamma_positive(a + b) - ln_gamma_positive(a) - ln_gamma_positive(b)
        + a * x.ln()
        + b * (-x).ln_1p();
    let front = ln_front.exp();
    // The continued fraction converges fast for x < (a + 1)/(a + b + 2); use the symmetry
    // I_x(a, b) = 1 − I_{1−x}(b, a) on the other side.
    if x < (a + 1.0) / (a + b + 2.0) {
        Some((front * beta_continued_fraction(x, a, b)? / a).clamp(0.0, 1.0))
    } else {
        Some((1.0 - front * beta_continued_fraction(1.0 - x, b, a)? / b).clamp(0.0, 1.0))
    }
}

/// The continued fraction for I_x(a, b) (Numerical Recipes `betacf`).
fn beta_continued_fraction(x: f64, a: f64, b: f64) -> Option<f64> {
    let qab = a + b;
    let qap = a + 1.0;
    let qam = a - 1.0;
    let guard = |v: f64| if v.abs() < TINY { TINY } else { v };
    let mut c = 1.0;
    let mut d = 1.0 / guard(1.0 - qab * x / qap);
    let mut h = d;
    for m in 1..=MAX_CONTINUED_FRACTION_TERMS {
        let m = m as f64;
        let m2 = 2.0 * m;
        // Even step.
        let aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        d = 1.0 / guard(1.0 + aa * d);
        c = guard(1.0 + aa / c);
        h *= d * c;
        // Odd step.
        let aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        d = 1.0 / guard(1.0 + aa * d);
        c = guard(1.0 + aa / c);
        let delta = d * c;
        h *= delta;
        if (delta - 1.0).abs() < CONTINUED_FRACTION_TOLERANCE {
            return Some(h);
        }
    }
    None
}

/// Inverse of x ↦ I_x(a, b): the x ∈ [0, 1] with I_x(a, b) = `target`, by bisection to the
/// resolution of f64 (I_x is increasing in x).
///
/// Returns `None` for target outside [0, 1], invalid a, b, or a non-converging evaluation.
#[must_use]
pub fn inverse_regularized_incomplete_beta(target: f64, a: f64, b: f64) -> Option<f64> {
    if !((0.0..=1.0).contains(&target) && a > 0.0 && b > 0.0) {
        return None;
    }
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    // 1100 halvings reach any representable x in [0, 1] (subnormals included); stops earlier
    // once the midpoint no longer moves.
    for _ in 0..1100 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if regularized_incomplete_beta(mid, a, b)? < target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(0.5 * (lo + hi))
}

/// ln(e^a + e^b), exact when one side is −∞.
#[must_use]
pub fn ln_add_exp(a: f64, b: f64) -> f64 {
    let (hi, lo) = if a >= b { (a, b) } else { (b, a) };
    if lo == f64::NEG_INFINITY {
        return hi;
    }
    hi + (lo - hi).exp().ln_1p()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ln_gamma_matches_factorials() {
        let mut factorial = 1.0_f64;
        for n in 1..=30_u32 {
            factorial *= f64::from(n);
            let got = ln_gamma(f64::from(n) + 1.0).unwrap();
            assert!(
                (got - factorial.ln()).abs() < 1e-12 * factorial.ln().max(1.0),
                "n = {n}"
            );
        }
        // Γ(½) = √π.
        let half = ln_gamma(0.5).unwrap();
        assert!((half - std::f64::consts::PI.sqrt().ln()).abs() < 1e-14);
        assert_eq!(ln_gamma(0.0), None);
        assert_eq!(ln_gamma(-1.0), None);
    }

    #[test]
    fn incomplete_beta_matches_binomial_tails() {
        // I_x(a, b) = P[Bin(a + b − 1, x) ≥ a] for integer a, b.
        // I_0.5(2, 3) = P[Bin(4, ½) ≥ 2] = 11/16.
        let v = regularized_incomplete_beta(0.5, 2.0, 3.0).unwrap();
        assert!((v - 0.6875).abs() < 1e-14);
        // I_0.3(1, 5) = 1 − 0.7^5.
        let v = regularized_incomplete_beta(0.3, 1.0, 5.0).unwrap();
        assert!((v - (1.0 - 0.7_f64.powi(5))).abs() < 1e-14);
        // I_x(a, 1) = x^a.
        let v = regularized_incomplete_beta(0.9, 7.0, 1.0).unwrap();
        assert!((v - 0.9_f64.powi(7)).abs() < 1e-14);
        assert_eq!(regularized_incomplete_beta(1.5, 1.0, 1.0), None);
        assert_eq!(regularized_incomplete_beta(0.5, 0.0, 1.0), None);
    }

    #[test]
    fn incomplete_beta_handles_large_parameters() {
        // Symmetric: I_½(a, a) = ½.
        let v = regularized_incomplete_beta(0.5, 5e5, 5e5).unwrap();
        assert!((v - 0.5).abs() < 1e-6, "{v}");
    }

    #[test]
    fn inverse_round_trips() {
        for &(a, b) in &[(1.0, 10.0), (5.0, 6.0), (6.0, 5.0), (300.0, 700.0)] {
            for &t in &[1e-6, 0.025, 0.5, 0.975] {
                let x = inverse_regularized_incomplete_beta(t, a, b).unwrap();
                let back = regularized_incomplete_beta(x, a, b).unwrap();
                assert!((back - t).abs() < 1e-10 * t.max(1e-3), "a={a} b={b} t={t}");
            }
        }
    }

    #[test]
    fn ln_add_exp_is_stable() {
        assert!((ln_add_exp(0.0, 0.0) - 2.0_f64.ln()).abs() < 1e-15);
        assert_eq!(ln_add_exp(f64::NEG_INFINITY, -3.0), -3.0);
        assert!((ln_add_exp(-1000.0, -1000.0) - (-1000.0 + 2.0_f64.ln())).abs() < 1e-12);
    }
}
