//! The χ² distribution's tails and quantiles, computed in the log domain so that tails down
//! to 10⁻³⁰⁰ keep their relative accuracy (for the Wishart bound, `wishart`).
//!
//! `P[χ²_ν > x] = Q(ν/2, x/2)` and `P[χ²_ν < x] = P(ν/2, x/2)`, the regularized incomplete
//! gamma functions: `P(a, y)` by its power series `e^(−y) y^a/Γ(a) · Σₙ yⁿ/(a(a+1)…(a+n))`
//! below `y = a + 1`, `Q(a, y)` by its continued fraction above (Numerical Recipes §6.2,
//! modified Lentz), each the other's complement on the far side. ν need not be an integer.

use robokey_secrecy::special::ln_gamma;

/// Terms or iterations at most: both need `O(√a)` near `y ≈ a`, so this covers a far beyond
/// the 10⁶ degrees of freedom of any block.
const MAX_TERMS: usize = 1_000_000;

/// Relative size at which a series term or a continued-fraction step stops changing the sum.
const TOLERANCE: f64 = 1e-16;

/// Guard against division by zero in the modified Lentz method.
const TINY: f64 = 1e-300;

/// Relative width at which a quantile's bracket stops being halved.
const QUANTILE_WIDTH: f64 = 1e-13;

/// `ln(e^(−y) y^a / Γ(a))`: the incomplete gamma functions' common prefactor.
fn ln_prefactor(a: f64, y: f64) -> f64 {
    a * y.ln() - y - ln_gamma(a).unwrap_or(f64::NAN)
}

/// `ln P(a, y)` by the power series, for `0 < y < a + 1`.
fn ln_lower_series(a: f64, y: f64) -> f64 {
    let (mut term, mut sum) = (1.0 / a, 1.0 / a);
    for n in 1..MAX_TERMS {
        term *= y / (a + n as f64);
        sum += term;
        if term < sum * TOLERANCE {
            break;
        }
    }
    ln_prefactor(a, y) + sum.ln()
}

/// `ln Q(a, y)` by the continued fraction, for `y ≥ a + 1`.
fn ln_upper_fraction(a: f64, y: f64) -> f64 {
    let mut b = y + 1.0 - a;
    let mut c = 1.0 / TINY;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..MAX_TERMS {
        let an = -(i as f64) * (i as f64 - a);
        b += 2.0;
        d = an * d + b;
        if d.abs() < TINY {
            d = TINY;
        }
        c = b + an / c;
        if c.abs() < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        let step = d * c;
        h *= step;
        if (step - 1.0).abs() < TOLERANCE {
            break;
        }
    }
    ln_prefactor(a, y) + h.ln()
}

/// `ln(1 − e^x)` for `x ≤ 0`.
fn ln_complement(x: f64) -> f64 {
    if x > -std::f64::consts::LN_2 {
        (-x.exp_m1()).ln()
    } else {
        (-x.exp()).ln_1p()
    }
}

/// `ln P[χ²_ν > x]` (0 for x ≤ 0).
pub(super) fn ln_upper_tail(nu: f64, x: f64) -> f64 {
    let (a, y) = (0.5 * nu, 0.5 * x);
    if y <= 0.0 {
        0.0
    } else if y < a + 1.0 {
        ln_complement(ln_lower_series(a, y))
    } else {
        ln_upper_fraction(a, y)
    }
}

/// `ln P[χ²_ν < x]` (−∞ for x ≤ 0).
pub(super) fn ln_lower_tail(nu: f64, x: f64) -> f64 {
    let (a, y) = (0.5 * nu, 0.5 * x);
    if y <= 0.0 {
        f64::NEG_INFINITY
    } else if y < a + 1.0 {
        ln_lower_series(a, y)
    } else {
        ln_complement(ln_upper_fraction(a, y))
    }
}

/// Halves `[below, above]` around the `x` where `ln_tail(x)` crosses `ln_p` to a relative
/// width of 10⁻¹³: where the tail still exceeds `ln_p` at the midpoint, the crossing lies
/// above it for a `falling` tail (the upper one) and below it for a rising one.
fn bisect(
    mut below: f64,
    mut above: f64,
    ln_tail: impl Fn(f64) -> f64,
    ln_p: f64,
    falling: bool,
) -> [f64; 2] {
    while above - below > QUANTILE_WIDTH * above {
        let mid = 0.5 * (below + above);
        if (ln_tail(mid) > ln_p) == falling {
            below = mid;
        } else {
            above = mid;
        }
    }
    [below, above]
}

/// The least `x` found with `P[χ²_ν > x] ≤ e^ln_p` (`ln_p < ln ½`): the bracket's upper end
/// after halving it, so never below the exact quantile.
pub(super) fn upper_quantile(nu: f64, ln_p: f64) -> f64 {
    let (mut below, mut above) = (nu, 2.0 * nu + 2.0);
    while ln_upper_tail(nu, above) > ln_p {
        (below, above) = (above, 2.0 * above);
    }
    bisect(below, above, |x| ln_upper_tail(nu, x), ln_p, true)[1]
}

/// The greatest `x` found with `P[χ²_ν < x] ≤ e^ln_p` (`ln_p < ln ½`): the bracket's lower
/// end, so never above the exact quantile.
pub(super) fn lower_quantile(nu: f64, ln_p: f64) -> f64 {
    bisect(0.0, nu, |x| ln_lower_tail(nu, x), ln_p, false)[0]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `ln P[χ²_ν > x]` (`upper`) or `ln P[χ²_ν < x]` for even ν from the Poisson identity
    /// `Q(n, y) = e^(−y) Σ_{k<n} y^k/k!` and `P(n, y) = e^(−y) Σ_{k≥n} y^k/k!` (summed until
    /// its terms fall below 10⁻⁴⁰ of the sum), in the log domain.
    fn ln_poisson_tail(nu: u32, x: f64, upper: bool) -> f64 {
        let y = 0.5 * x;
        let n = nu / 2;
        let mut k = if upper { 0 } else { n };
        let mut t = -y + f64::from(k) * y.ln() - ln_gamma(f64::from(k) + 1.0).unwrap_or(0.0);
        let mut ln_sum = f64::NEG_INFINITY;
        loop {
            let (hi, lo) = (ln_sum.max(t), ln_sum.min(t));
            ln_sum = hi + (lo - hi).exp().ln_1p();
            k += 1;
            if (upper && k == n) || (!upper && f64::from(k) > y && t < ln_sum - 92.0) {
                return ln_sum;
            }
            t += y.ln() - f64::from(k).ln();
        }
    }

    /// Both tails against the Poisson identity, from the bulk to tails of 10⁻²⁰⁰⁰, on both
    /// sides of `y = a + 1` where the method switches; relative error below 10⁻⁸ (the
    /// reference's own rounding over 10⁵ terms reaches 10⁻⁹).
    #[test]
    fn the_tails_match_the_poisson_identity() {
        for nu in [2, 4, 10, 60, 1_000, 30_000] {
            let n = f64::from(nu);
            for ratio in [0.3, 0.8, 0.97, 1.0, 1.03, 1.2, 2.0, 5.0] {
                let x = ratio * n;
                let exact = ln_poisson_tail(nu, x, true);
                let upper = ln_upper_tail(n, x);
                assert!(
                    (upper - exact).abs() < 1e-8 * exact.abs().max(1.0),
                    "ν {nu} x {x}: {upper} against {exact}"
                );
                let lower = ln_lower_tail(n, x);
                let complement = ln_poisson_tail(nu, x, false);
                assert!(
                    (lower - complement).abs() < 1e-8 * complement.abs().max(1.0),
                    "ν {nu} x {x}: lower {lower} against {complement}"
                );
            }
        }
    }

    /// Textbook quantiles (χ²₁ at 5 %: 3.841459; χ²₁₀ at 1 %: 23.209251 and at 99 %:
    /// 2.558212), and the quantiles invert the tails at 10⁻¹² on either side.
    #[test]
    fn quantiles_invert_the_tails() {
        assert!((upper_quantile(1.0, 0.05f64.ln()) - 3.841_459).abs() < 1e-5);
        assert!((upper_quantile(10.0, 0.01f64.ln()) - 23.209_251).abs() < 1e-5);
        assert!((lower_quantile(10.0, 0.01f64.ln()) - 2.558_212).abs() < 1e-5);
        for nu in [3.0, 150.5, 14_319.0] {
            let ln_p = 1e-12f64.ln();
            let x = upper_quantile(nu, ln_p);
            assert!(ln_upper_tail(nu, x) <= ln_p);
            assert!(ln_upper_tail(nu, x * (1.0 - 1e-9)) > ln_p);
            let x = lower_quantile(nu, ln_p);
            assert!(ln_lower_tail(nu, x) <= ln_p);
            assert!(ln_lower_tail(nu, x * (1.0 + 1e-9)) > ln_p);
        }
    }
}
