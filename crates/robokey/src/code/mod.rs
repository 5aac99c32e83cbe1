//! Linear block codes for the key bits (docs/protocol.md). A codeword of `n` bits is held in a
//! `u64`, bit `j` = the bit sent at the codeword's `j`-th step; messages likewise.

mod generator;
mod repetition;

pub use generator::GeneratorCode;
pub use repetition::Repetition;

/// Nearest-codeword decoding result.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Decoded {
    /// The decoded message (its lowest `k` bits).
    pub message: u64,
    /// Hamming distance from the received word to the nearest codeword.
    pub distance: u32,
}

/// Maximum-likelihood decoding result from per-bit log-likelihood ratios.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoftDecoded {
    /// The most likely message.
    pub message: u64,
    /// The second most likely message (equal to `message` when `k = 0`).
    pub runner_up: u64,
    /// Log-likelihood margin of `message` over `runner_up` (≥ 0; nats).
    pub margin: f64,
}

/// Largest message length for which [`BlockCode::decode_soft`] enumerates all messages.
pub const MAX_SOFT_MESSAGE_BITS: usize = 16;

/// A binary block code `(n, k)` with nearest-codeword decoding.
pub trait BlockCode: std::fmt::Debug + Send + Sync {
    /// Codeword length `n_c` (bits, ≤ 64).
    fn n(&self) -> usize;
    /// Message length `k_c` (bits, ≤ 64).
    fn k(&self) -> usize;
    /// Encodes the lowest `k` bits of `message`.
    fn encode(&self, message: u64) -> u64;
    /// Finds the nearest codeword to the lowest `n` bits of `word`; ties go to the lowest
    /// message index.
    fn decode(&self, word: u64) -> Decoded;
    /// Short name, e.g. `repetition(3)`.
    fn name(&self) -> String;

    /// Maximum-likelihood decoding from `llr[j] = ln p(obs_j | bit 1) − ln p(obs_j | bit 0)`
    /// (0 for an erased bit), by enumerating the `2^k` codewords (`k ≤`
    /// [`MAX_SOFT_MESSAGE_BITS`]): the score of codeword `c` is `Σ_j c_j·llr[j]`. Ties go to
    /// the lowest message index.
    fn decode_soft(&self, llr: &[f64]) -> SoftDecoded {
        let k = self.k().min(MAX_SOFT_MESSAGE_BITS);
        let score = |message: u64| {
            let word = self.encode(message);
            llr.iter()
                .take(self.n())
                .enumerate()
                .filter(|(j, _)| word >> j & 1 == 1)
                .map(|(_, l)| l)
                .sum::<f64>()
        };
        let (mut best, mut second) = ((0, score(0)), None::<(u64, f64)>);
        for message in 1..(1u64 << k) {
            let candidate = (message, score(message));
            if candidate.1 > best.1 {
                second = Some(best);
                best = candidate;
            } else if second.is_none_or(|s| candidate.1 > s.1) {
                second = Some(candidate);
            }
        }
        let (runner_up, runner_score) = second.unwrap_or(best);
        SoftDecoded {
            message: best.0,
            runner_up,
            margin: best.1 - runner_score,
        }
    }
}

/// Mask of the lowest `bits` bits.
#[must_use]
pub(crate) fn low_mask(bits: usize) -> u64 {
    if bits >= 64 {
        u64::MAX
    } else {
        (1u64 << bits) - 1
    }
}

/// Hamming(7,4) with generator rows `1000110, 0100101, 0010011, 0001111` (message bits
/// first).
#[must_use]
pub fn hamming74() -> GeneratorCode {
    GeneratorCode::from_rows("hamming74", &["1000110", "0100101", "0010011", "0001111"])
        .expect("the Hamming(7,4) generator is valid")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every error pattern of weight ≤ t decodes to the sent message with distance = weight.
    fn decodes_every_correctable_pattern(code: &dyn BlockCode, t: u32) {
        let n = code.n();
        for message in 0..(1u64 << code.k()) {
            let word = code.encode(message);
            for error in 0..(1u64 << n) {
                if error.count_ones() <= t {
                    let decoded = code.decode(word ^ error);
                    assert_eq!(
                        decoded.message,
                        message,
                        "{} m={message} e={error:b}",
                        code.name()
                    );
                    assert_eq!(decoded.distance, error.count_ones());
                }
            }
        }
    }

    #[test]
    fn hamming74_corrects_every_single_error_and_has_distance_three() {
        let code = hamming74();
        decodes_every_correctable_pattern(&code, 1);
        let min_weight = (1..16u64).map(|m| code.encode(m).count_ones()).min();
        assert_eq!(min_weight, Some(3));
        assert_eq!(code.encode(0b1000), 0b111_1000);
        assert_eq!(code.encode(0b0001), 0b011_0001);
    }

    /// With LLRs of ±1 (a hard word), ML decoding is nearest-codeword decoding wherever
    /// the nearest codeword is unique.
    fn soft_decoding_of_hard_words_is_nearest_codeword(code: &dyn BlockCode) {
        let n = code.n();
        for word in 0..(1u64 << n) {
            let llr: Vec<f64> = (0..n)
                .map(|j| if word >> j & 1 == 1 { 1.0 } else { -1.0 })
                .collect();
            let soft = code.decode_soft(&llr);
            let hard = code.decode(word);
            let ties = (0..(1u64 << code.k()))
                .filter(|&m| (code.encode(m) ^ word).count_ones() == hard.distance)
                .count();
            if ties == 1 {
                assert_eq!(soft.message, hard.message, "{} word {word:b}", code.name());
                assert!(soft.margin > 0.0);
            } else {
                assert_eq!(soft.margin, 0.0);
            }
        }
    }

    #[test]
    fn soft_decoding_agrees_with_hard_decoding_on_hard_words() {
        soft_decoding_of_hard_words_is_nearest_codeword(&hamming74());
        for n in 1..=7 {
            soft_decoding_of_hard_words_is_nearest_codeword(&Repetition::new(n).unwrap());
        }
    }

    #[test]
    fn soft_decoding_weighs_reliable_bits() {
        // Two weak ones against one strong zero: majority says 1, likelihood says 0.
        let decoded = Repetition::new(3).unwrap().decode_soft(&[0.2, 0.3, -2.0]);
        assert_eq!(decoded.message, 0);
        assert_eq!(decoded.runner_up, 1);
        assert!((decoded.margin - 1.5).abs() < 1e-12);
    }

    #[test]
    fn repetition_corrects_every_minority_pattern() {
        for n in 1..=9 {
            let code = Repetition::new(n).unwrap();
            decodes_every_correctable_pattern(&code, ((n - 1) / 2) as u32);
        }
    }
}
