//! Linear block codes for the key bits (SPEC §6). A codeword of `n` bits is held in a
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

    #[test]
    fn repetition_corrects_every_minority_pattern() {
        for n in 1..=9 {
            let code = Repetition::new(n).unwrap();
            decodes_every_correctable_pattern(&code, ((n - 1) / 2) as u32);
        }
    }
}
