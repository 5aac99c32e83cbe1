//! Rounding half away from zero without a call: [`f64::round`] is a library call the
//! compiler cannot vectorise, and the command-quantum check (`quantum_check`) rounds every
//! wheel command at every candidate quantum. `round_half_away` is the same function, bit
//! for bit, on `|y| <` `EXACT_BELOW`, from additions alone.

/// `1.5·2⁵²`: adding it to `|y| < 2⁵¹` leaves a number in `[2⁵², 2⁵³)`, whose spacing is 1,
/// so the addition rounds `y` to an integer (ties to even, the hardware's rounding).
const SHIFT: f64 = 6_755_399_441_055_744.0;

/// The magnitude below which `round_half_away` equals [`f64::round`]: `2⁵¹`.
pub(super) const EXACT_BELOW: f64 = 2_251_799_813_685_248.0;

/// `y.round()` — the nearest integer, halves away from zero, the sign of `y` kept (−0.3 →
/// −0) — for `|y| <` `EXACT_BELOW` (and a NaN for a NaN). With `a = |y|`,
/// `(a + 1.5·2⁵²) − 1.5·2⁵²` is `a`'s nearest integer with ties to even, both operations
/// exact but the first's rounding; `a` less it is exact (at most ½, a multiple of `a`'s unit
/// in the last place), and is +½ only at a tie that went down, which goes up instead; the
/// sign is `y`'s.
#[inline]
pub(super) fn round_half_away(y: f64) -> f64 {
    let magnitude = y.abs();
    let even = (magnitude + SHIFT) - SHIFT;
    let up = if magnitude - even == 0.5 { 1.0 } else { 0.0 };
    (even + up).copysign(y)
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
}
