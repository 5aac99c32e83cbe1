//! Rounding quotients `w/q` half away from zero without a call or a division, as the
//! command-quantum check (`quantum_check`) rounds every wheel command at every candidate
//! quantum: [`f64::round`] is a library call the compiler cannot vectorise, and a division
//! costs several products. `round_product` rounds the product `w·fl(1/q)` to its nearest
//! integer with additions alone and says whether that integer is provably `(w/q).round()`,
//! bit for bit; where it is not (at ties and their nearest neighbours), the caller divides.

/// `1.5·2⁵²`: adding it to `|y| < 2⁵¹` leaves a number in `[2⁵², 2⁵³)`, whose spacing is 1,
/// so the addition rounds `y` to an integer (ties to even, the hardware's rounding).
const SHIFT: f64 = 6_755_399_441_055_744.0;

/// A double's sign bit.
const SIGN: u64 = 1 << 63;

/// `2⁻⁴⁹`: the margin `round_product` keeps from every half-integer, per unit of the largest
/// product `fl(M·fl(1/q))`: twice the bound `2⁻⁵⁰·fl(M·fl(1/q))` on `|w·fl(1/q) − fl(w/q)|`
/// (`product_bound`), for the bound's own rounding.
const TIE_MARGIN: f64 = 1.0 / 562_949_953_421_312.0;

/// The bound that `round_product` holds a product's distance to its nearest integer under,
/// for products `p = fl(w·r)` of wheels `|w| ≤ fastest` (rad/s) and `r = fl(1/q)`:
/// `B = fl(½ − fl(M·r)·2⁻⁴⁹)`, `M = fastest`. Where `|p − e| < B` (`e` the integer nearest
/// `p`), `e` is `fl(w/q).round()`. With `u = 2⁻⁵³` and `m = fl(M·r)`:
///
/// - `|p| ≤ m` (rounding is monotone). For `|p| ≥ 2⁻⁹⁰⁰` every operation is normal:
///   `r = (1/q)(1 + ε₁)`, `p = (w/q)(1 + ε₁)(1 + ε₂)`, `y = fl(w/q) = (w/q)(1 + ε₃)`,
///   `|εᵢ| ≤ u`, so `|p − y| ≤ |w/q|·(3u + u²) < 3.01·u·|p| < 2⁻⁵¹·m`.
/// - `m ≥ 2⁴⁸`: `B ≤ 0`, nothing is accepted. So an accepted `|p| < 2⁴⁸ < 2⁵¹`, where the
///   shift gives `e` exactly, and `d = p − e` is exact (`|d| ≤ ½`, `e` within a factor 2 of
///   `p` or 0).
/// - `2⁻⁵ ≤ m < 2⁴⁸`: `t = m·2⁻⁴⁹` is exact and `B ≤ ½ − t + 2⁻⁵⁵` (half a unit in the last
///   place of `½ − t`), so an accepted `p` lies farther than `½ − B ≥ t − 2⁻⁵⁵ ≥ 2⁻⁵⁰·m
///   > |p − y|` from every half-integer: none lies between `p` and `y` or on either, and
///   both round to the same integer ([`f64::round`] is constant between half-integers).
/// - `m < 2⁻⁵`, or `|p| < 2⁻⁹⁰⁰`: `|p|` and `|y|` are below ½ and both round to zero.
///
/// Zeros keep `w`'s sign (`p`'s and `y`'s: `r > 0`), as [`f64::round`] keeps it. A NaN
/// `fastest` or one of `+∞` accepts nothing.
#[inline]
pub(super) fn product_bound(fastest: f64, reciprocal: f64) -> f64 {
    0.5 - fastest * reciprocal * TIE_MARGIN
}

/// `p`'s nearest integer (ties to even) with `p`'s sign, and whether `|p − e| < bound`: no
/// branch, no call, so that a loop over candidates vectorises. With `p = fl(w·fl(1/q))`
/// and `bound` from `product_bound` for a fastest wheel `≥ |w|`, an accepted integer is
/// `(w / q).round()`, bit for bit (`product_bound`: ties and their nearest neighbours are
/// never accepted, so ties to even and halves away from zero agree on every accepted one,
/// and a zero takes `p`'s sign as [`f64::round`] does). A NaN or infinite `p` is not
/// accepted.
#[inline]
pub(super) fn round_product(product: f64, bound: f64) -> (f64, bool) {
    let even = (product + SHIFT) - SHIFT;
    let multiple = f64::from_bits(even.to_bits() | (product.to_bits() & SIGN));
    (multiple, (product - even).abs() < bound)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{Purpose, stream};
    use rand::RngExt;

    /// `w/q` rounded from the product by `1/q` under the bound for wheels up to `fastest`:
    /// when accepted, `(w / q).round()` bit for bit. Returns whether it was accepted.
    fn assert_quotient(w: f64, q: f64, fastest: f64) -> bool {
        let reciprocal = 1.0 / q;
        let (multiple, accepted) =
            round_product(w * reciprocal, product_bound(fastest, reciprocal));
        if accepted {
            assert_eq!(
                multiple.to_bits(),
                (w / q).round().to_bits(),
                "{w:e}/{q:e}: {multiple} against {}",
                (w / q).round()
            );
        }
        accepted
    }

    /// Zeros of both signs, exact halves of either sign (away from zero, where ties to even
    /// would differ: never accepted), the numbers next to a half, the largest below ½, and
    /// numbers up to 2⁴⁰, taken as quotients by 1 with wheels up to 2⁴¹: every accepted one
    /// is [`f64::round`]'s, the halves are refused and the numbers a quarter from them
    /// accepted; beyond 2⁴⁸ nothing is accepted.
    #[test]
    fn the_edges_round_as_the_library_does() {
        let fastest = 2.0f64.powi(41);
        for y in [0.0, -0.0, 0.3, -0.3] {
            assert!(assert_quotient(y, 1.0, fastest), "{y:e} refused");
        }
        for y in [0.49999999999999994, -0.49999999999999994] {
            assert_quotient(y, 1.0, fastest);
        }
        for k in [0_i64, 1, 2, 3, 10, 11, 333, 1 << 20, (1 << 40) - 1] {
            let half = k as f64 + 0.5;
            for sign in [1.0, -1.0] {
                assert!(
                    !assert_quotient(sign * half, 1.0, fastest),
                    "{half:e} accepted"
                );
                for y in [k as f64, (k as f64).next_up(), k as f64 + 0.25] {
                    assert!(assert_quotient(sign * y, 1.0, fastest), "{y:e} refused");
                }
                for y in [half.next_up(), half.next_down()] {
                    assert_quotient(sign * y, 1.0, fastest);
                }
            }
        }
        assert!(!assert_quotient(f64::NAN, 1.0, fastest));
        assert!(!assert_quotient(1e15 + 0.25, 1.0, 1e15));
    }

    /// Quotients at and next to their ties: `w` the product of a half-integer and `q`, the
    /// floating-point numbers up to 8 units in the last place either side of it, and
    /// `w·(1 + j·2⁻⁴⁴)` for `|j| ≤ 16` (across the bound's margin), `q` seeded over the
    /// check's range and at numbers whose reciprocal rounds (0.03, 0.1, 0.3, …), both
    /// signs. Every accepted one rounds as the division does; an exact tie is never
    /// accepted, and among the neighbours some are and some are not.
    #[test]
    fn near_ties_round_as_the_division_does() {
        let mut rng = stream(12, Purpose::Process, 0);
        let mut quanta: Vec<f64> = vec![0.03, 0.1, 0.3, 0.7, 1.0 / 3.0, 0.0323, 1.0];
        quanta.extend((0..400).map(|_| rng.random_range(0.03..1.0)));
        let fastest = 12.0;
        let (mut accepted, mut total) = (0, 0);
        for &q in &quanta {
            for _ in 0..20 {
                let half = rng.random_range(-12..12) as f64 + 0.5;
                let tie = (half * q).clamp(-fastest, fastest);
                let mut near = vec![tie];
                let (mut down, mut up) = (tie, tie);
                for _ in 0..8 {
                    down = down.next_down();
                    up = up.next_up();
                    near.extend([down, up]);
                }
                near.extend((-16..=16).map(|j| tie * (1.0 + f64::from(j) * 2.0f64.powi(-44))));
                for w in near {
                    let taken = assert_quotient(w, q, fastest);
                    if w == tie && (w / q).fract().abs() == 0.5 {
                        assert!(!taken, "{w:e}/{q:e}: an exact tie accepted");
                    }
                    accepted += usize::from(taken);
                    total += 1;
                    assert_quotient(-w, q, fastest);
                }
            }
        }
        assert!(
            accepted > 0 && accepted < total,
            "{accepted} of {total} near ties accepted"
        );
    }

    /// Seeded quotients of every magnitude (the bound for the largest wheel of each draw's
    /// range), zeros of both signs, subnormal and huge numerators, infinities and NaNs:
    /// every accepted one is the division's rounding, and most are accepted.
    #[test]
    fn any_quotient_rounds_as_the_division_does() {
        let mut rng = stream(13, Purpose::Process, 0);
        let mut accepted = 0;
        for _ in 0..200_000 {
            let q = rng.random_range(0.03..1.0) * 2.0f64.powi(rng.random_range(-20..20));
            let fastest = 2.0f64.powi(rng.random_range(-60..40));
            let w = rng.random_range(-1.0..1.0) * fastest;
            accepted += usize::from(assert_quotient(w, q, fastest));
        }
        assert!(accepted > 100_000, "{accepted} of 200000 accepted");
        for w in [
            0.0,
            -0.0,
            f64::MIN_POSITIVE,
            5e-324,
            -5e-324,
            1e300,
            -1e300,
            f64::MAX,
            2.0f64.powi(49) + 0.5,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ] {
            for q in [0.03, 0.5, 1.0, 1e-300, 1e300] {
                for fastest in [w.abs(), 1.0, f64::INFINITY] {
                    assert_quotient(w, q, fastest.max(w.abs()));
                }
            }
        }
        assert!(!assert_quotient(f64::INFINITY, 0.1, f64::INFINITY));
    }
}
