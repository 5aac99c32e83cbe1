//! The controller's LLRs as its pool keeps them: quantised to multiples of [`LLR_QUANTUM`]
//! nat in an `i16`, magnitude rounded toward zero and clamped to |L| ≤ 32767 · 2⁻⁸ ≈ 128 nats,
//! so a stored LLR is never more confident than the calibrated one, and a restored pool
//! decodes exactly as the live one did.
//!
//! The LLRs never size the key: they choose the syndrome length m and steer the decoder,
//! while ℓ is charged every syndrome bit actually sent and the tags verify the result. A
//! coarser LLR can only lengthen the syndrome (h₂(1/(1 + e^{|L|})) grows as |L| shrinks) or
//! make decoding fail (no key), never shorten what is charged.

/// The step of a stored LLR: 2⁻⁸ nat.
pub const LLR_QUANTUM: f64 = 1.0 / 256.0;

/// `llr` in steps of [`LLR_QUANTUM`], toward zero, clamped to ±[`i16::MAX`] steps (NaN: 0).
#[must_use]
pub fn quantise_llr(llr: f64) -> i16 {
    let steps = (llr / LLR_QUANTUM).trunc();
    if steps.is_nan() {
        return 0;
    }
    steps.clamp(-f64::from(i16::MAX), f64::from(i16::MAX)) as i16
}

/// The LLR (nats) a stored value stands for.
#[must_use]
pub fn dequantise_llr(stored: i16) -> f64 {
    f64::from(stored) * LLR_QUANTUM
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stored_llrs_are_never_more_confident_and_keep_their_sign() {
        for llr in [
            0.0,
            1e-4,
            0.003,
            0.5,
            1.0 / 3.0,
            7.9,
            127.0,
            1e6,
            f64::INFINITY,
        ] {
            for l in [llr, -llr] {
                let back = dequantise_llr(quantise_llr(l));
                assert!(back.abs() <= l.abs(), "{l} → {back}");
                assert!(l.abs() - back.abs() < LLR_QUANTUM || l.abs() > 127.0, "{l}");
                assert!(back == 0.0 || back.signum() == l.signum(), "{l}");
            }
        }
        assert_eq!(quantise_llr(f64::NAN), 0);
        assert_eq!(quantise_llr(f64::NEG_INFINITY), -i16::MAX);
    }
}
