//! Rounding a quotient `w/q` half away from zero without a call or a division: [`f64::round`]
//! is a library call the compiler cannot vectorise, and a division costs an order of
//! magnitude more than a product; the command-quantum check (`quantum_check`) rounds every
//! wheel command at every candidate quantum. `round_quotient` gives `(w/q).round()` bit for
//! bit from `w·(1/q)`, with the division kept where the product alone cannot tell.

/// `1.5·2⁵²`: adding it to `|y| < 2⁵¹` leaves a number in `[2⁵², 2⁵³)`, whose spacing is 1,
/// so the addition rounds `y` to an integer (ties to even, the hardware's rounding).
const SHIFT: f64 = 6_755_399_441_055_744.0;

/// The magnitude below which `round_half_away` equals [`f64::round`]: `2⁵¹`.
#[cfg(test)]
const EXACT_BELOW: f64 = 2_251_799_813_685_248.0;

/// `2⁻⁵⁰`: a product `p = w·fl(1/q)` farther than `2⁻⁵⁰·|p|` from every half-integer rounds
/// as the quotient `fl(w/q)` does (`round_quotient`: the two differ by less than `2⁻⁵¹·|p|`).
const TIE_MARGIN: f64 = 1.0 / 1_125_899_906_842_624.0;

/// `y.round()` and `y`'s distance to the nearest half-integer, for `|y| <` `EXACT_BELOW`.
/// With `a = |y|`, `e = (a + 1.5·2⁵²) − 1.5·2⁵²` is `a`'s nearest integer with ties to even,
/// both operations exact but the first's rounding; `d = a − e` is exact (at most ½, a
/// multiple of `a`'s unit in the last place), and is +½ only at a tie that went down, which
/// goes up instead; the sign is `y`'s. The distance is `½ − |d|` in floating point, within a
/// relative `2⁻⁵³` of the exact one. Beyond `2⁵¹` (and for a NaN) the rounding is not `y`'s
/// and the distance at most ½ (or a NaN).
#[inline]
fn round_and_distance(y: f64) -> (f64, f64) {
    let magnitude = y.abs();
    let even = (magnitude + SHIFT) - SHIFT;
    let offset = magnitude - even;
    let up = if offset == 0.5 { 1.0 } else { 0.0 };
    ((even + up).copysign(y), 0.5 - offset.abs())
}

/// `y.round()` — the nearest integer, halves away from zero, the sign of `y` kept (−0.3 →
/// −0) — for `|y| <` `EXACT_BELOW` (and a NaN for a NaN): see `round_and_distance`.
#[cfg(test)]
fn round_half_away(y: f64) -> f64 {
    round_and_distance(y).0
}

/// `(w / q).round()`, bit for bit, for `w` of any value and `q` positive with `1/q` normal
/// (`2⁻¹⁰²² ≤ q < 2¹⁰²²`), given `reciprocal = 1.0 / q`, and whether the product alone gave
/// it; where it did not (`w·(1/q)` within `2⁻⁵⁰` of its magnitude from a half-integer, or
/// beyond `2⁴⁹`, or not finite), `(w / q).round()` itself.
///
/// Why the product gives it elsewhere. With `u = 2⁻⁵³`, each operation rounds to nearest:
/// `r = fl(1/q) = (1/q)(1 + ε₁)`, `p = fl(w·r) = (w/q)(1 + ε₁)(1 + ε₂)`, `y = fl(w/q) =
/// (w/q)(1 + ε₃)`, `|εᵢ| ≤ u` (`r` normal by the premise; `p` and `y` normal when
/// `|p| ≥ 2⁻⁹⁰⁰`). So `|p − y| ≤ |w/q|·(3u + u²)`, and with `|w/q| ≤ |p|/(1 − u)²`,
/// `|p − y| < 3.01·u·|p| < 2⁻⁵¹·|p|`. `p` is accepted when its computed distance `D̃` to
/// the nearest half-integer exceeds `2⁻⁵⁰·|p|` (exact: a power of two), and `D̃ ≤ (1 + u)·D`
/// (`round_and_distance`), so the exact distance `D > 2⁻⁵⁰·|p|/(1 + u) > 2⁻⁵¹·|p| > |p − y|`:
/// no half-integer lies between `p` and `y` or on either, so both round to the same integer
/// ([`f64::round`] is constant between consecutive half-integers), with the same sign (`w`'s:
/// `r > 0`). Accepted, `D̃ ≤ ½` gives `|p| < 2⁴⁹`, where `round_and_distance` is
/// [`f64::round`]. For `|p| < 2⁻⁹⁰⁰`, `|w/q| < 2⁻⁸⁹⁹`: `p` and `y` both round to a zero of
/// `w`'s sign. A NaN or an infinity fails the comparison and takes the division.
#[inline]
pub(super) fn round_quotient(w: f64, q: f64, reciprocal: f64) -> (f64, bool) {
    let (multiple, clear) = round_product(w * reciprocal);
    if clear {
        (multiple, true)
    } else {
        ((w / q).round(), false)
    }
}

/// `p.round()` for a product `p = w·fl(1/q)` and whether it is `(w/q).round()` by
/// `round_quotient`'s argument (`p` farther than `2⁻⁵⁰·|p|` from every half-integer): no
/// branch, no call, so that a loop over candidates vectorises; the division is left to the
/// caller where it is not.
#[inline]
pub(super) fn round_product(product: f64) -> (f64, bool) {
    let (multiple, distance) = round_and_distance(product);
    (multiple, distance > product.abs() * TIE_MARGIN)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{Purpose, stream};
    use rand::RngExt;

    fn assert_same(y: f64) {
        assert_eq!(
            round_half_away(y).to_bits(),
            y.round().to_bits(),
            "{y:e}: {} against {}",
            round_half_away(y),
            y.round()
        );
    }

    /// `round_quotient(w, q, 1/q)` is `(w / q).round()`, bit for bit; returns whether the
    /// product alone gave it.
    fn assert_quotient(w: f64, q: f64) -> bool {
        let (multiple, clear) = round_quotient(w, q, 1.0 / q);
        assert_eq!(
            multiple.to_bits(),
            (w / q).round().to_bits(),
            "{w:e}/{q:e}: {multiple} against {}",
            (w / q).round()
        );
        clear
    }

    /// Zeros of both signs, exact halves of either sign (away from zero, where ties to even
    /// would differ), the numbers next to a half, the largest below ½, and the ends of the
    /// exact range: bit for bit [`f64::round`].
    #[test]
    fn the_edges_round_as_the_library_does() {
        for y in [
            0.0,
            -0.0,
            0.3,
            -0.3,
            0.49999999999999994,
            -0.49999999999999994,
        ] {
            assert_same(y);
        }
        for k in [0_i64, 1, 2, 3, 10, 11, 333, 1 << 20, (1 << 50) - 1] {
            let half = k as f64 + 0.5;
            for y in [
                half,
                half.next_up(),
                half.next_down(),
                k as f64,
                (k as f64).next_up(),
            ] {
                assert_same(y);
                assert_same(-y);
            }
        }
        for y in [EXACT_BELOW.next_down(), 2.0f64.powi(50) + 0.5, 1e15 + 0.5] {
            assert_same(y);
            assert_same(-y);
        }
        assert!(round_half_away(f64::NAN).is_nan());
    }

    /// Seeded random numbers of every magnitude in the exact range, and quotients `w/q` of
    /// wheel commands and quanta as the check forms them: bit for bit [`f64::round`].
    #[test]
    fn random_numbers_round_as_the_library_does() {
        let mut rng = stream(11, Purpose::Process, 0);
        for _ in 0..200_000 {
            let magnitude = 2.0f64.powi(rng.random_range(-30..51));
            assert_same(rng.random_range(-1.0..1.0) * magnitude);
            let (w, q) = (rng.random_range(-10.0..10.0), rng.random_range(0.03..1.0));
            assert_same(w / q);
        }
    }

    /// Quotients at and next to their ties: `w` the product of a half-integer and `q` and
    /// the floating-point numbers up to 8 units in the last place either side of it, `q`
    /// seeded over the check's range and at numbers whose reciprocal rounds (0.03, 0.1,
    /// 0.3, …), both signs. Every one rounds as the division does; an exact tie is never
    /// taken from the product, and both ways are taken among the neighbours.
    #[test]
    fn near_ties_round_as_the_division_does() {
        let mut rng = stream(12, Purpose::Process, 0);
        let mut quanta: Vec<f64> = vec![0.03, 0.1, 0.3, 0.7, 1.0 / 3.0, 0.0323, 1.0];
        quanta.extend((0..400).map(|_| rng.random_range(0.03..1.0)));
        let (mut from_product, mut total) = (0, 0);
        for &q in &quanta {
            for _ in 0..20 {
                let half = rng.random_range(-400..400) as f64 + 0.5;
                let tie = half * q;
                let mut w = tie;
                for _ in 0..8 {
                    w = w.next_down();
                }
                for step in -8..=8 {
                    let clear = assert_quotient(w, q);
                    if (tie / q).fract().abs() == 0.5 && step == 0 {
                        assert!(!clear, "{w:e}/{q:e}: an exact tie from the product");
                    }
                    from_product += usize::from(clear);
                    total += 1;
                    assert_quotient(-w, q);
                    w = w.next_up();
                }
            }
        }
        assert!(
            from_product > 0 && from_product < total,
            "{from_product} of {total} near ties from the product"
        );
    }

    /// Seeded quotients of every magnitude, zeros of both signs, subnormal and huge
    /// numerators, infinities and NaNs: bit for bit the division's rounding (a NaN for a
    /// NaN), and the quotients far from a half-integer taken from the product.
    #[test]
    fn any_quotient_rounds_as_the_division_does() {
        let mut rng = stream(13, Purpose::Process, 0);
        let mut from_product = 0;
        for _ in 0..200_000 {
            let q = rng.random_range(0.03..1.0) * 2.0f64.powi(rng.random_range(-20..20));
            let w = rng.random_range(-1.0..1.0) * 2.0f64.powi(rng.random_range(-60..40));
            from_product += usize::from(assert_quotient(w, q));
        }
        assert!(
            from_product > 100_000,
            "{from_product} of 200000 from the product"
        );
        for w in [
            0.0,
            -0.0,
            f64::MIN_POSITIVE,
            5e-324,
            -5e-324,
            1e300,
            -1e300,
            f64::MAX,
            EXACT_BELOW,
            2.0f64.powi(49) + 0.5,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ] {
            for q in [0.03, 0.5, 1.0, 1e-300, 1e300] {
                assert_quotient(w, q);
            }
        }
        let (nan, clear) = round_quotient(f64::NAN, 0.1, 10.0);
        assert!(nan.is_nan() && !clear);
    }
}
