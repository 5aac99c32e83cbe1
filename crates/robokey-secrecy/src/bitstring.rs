//! Packed bit strings over GF(2), zeroized on drop (they hold key material).

use std::fmt;

use rand::Rng;
use serde::{Deserialize, Serialize};
use thiserror::Error;
use zeroize::{Zeroize, ZeroizeOnDrop};

/// Bits per storage word.
const WORD_BITS: usize = 64;

/// Errors of bit-string construction and combination.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum BitStringError {
    /// Two bit strings of different lengths were combined.
    #[error("length mismatch: {left} vs {right} bits")]
    LengthMismatch {
        /// Length of the left operand.
        left: usize,
        /// Length of the right operand.
        right: usize,
    },
    /// Too few words for the requested length.
    #[error("{words} words cannot hold {len} bits")]
    TooFewWords {
        /// Words given.
        words: usize,
        /// Bits requested.
        len: usize,
    },
}

/// A string of `len` bits packed little-endian into u64 words: bit i is bit i mod 64 of word
/// i / 64; bits past `len` in the last word are always zero. Zeroized on drop; `Debug` shows
/// only the length. Equality is not constant-time (compare keys through a confirmation tag).
/// Serialized as its length and words; deserializing checks that the words hold the length.
#[derive(Clone, PartialEq, Eq, Default, Zeroize, ZeroizeOnDrop, Serialize, Deserialize)]
#[serde(try_from = "PackedBits", into = "PackedBits")]
pub struct BitString {
    words: Vec<u64>,
    len: usize,
}

/// The serialized form of a [`BitString`].
#[derive(Serialize, Deserialize, Zeroize, ZeroizeOnDrop)]
struct PackedBits {
    len: usize,
    words: Vec<u64>,
}

impl From<BitString> for PackedBits {
    fn from(bits: BitString) -> Self {
        Self {
            len: bits.len,
            words: bits.words.clone(),
        }
    }
}

impl TryFrom<PackedBits> for BitString {
    type Error = BitStringError;

    fn try_from(packed: PackedBits) -> Result<Self, Self::Error> {
        Self::from_words(packed.words.clone(), packed.len)
    }
}

impl fmt::Debug for BitString {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("BitString")
            .field("len", &self.len)
            .finish_non_exhaustive()
    }
}

fn words_for(len: usize) -> usize {
    len.div_ceil(WORD_BITS)
}

/// Mask of the valid bits in the last word of a `len`-bit string.
fn tail_mask(len: usize) -> u64 {
    match len % WORD_BITS {
        0 => u64::MAX,
        r => (1_u64 << r) - 1,
    }
}

impl BitString {
    /// The all-zero string of `len` bits.
    #[must_use]
    pub fn zeros(len: usize) -> Self {
        Self {
            words: vec![0; words_for(len)],
            len,
        }
    }

    /// `len` uniformly random bits.
    pub fn random<R: Rng + ?Sized>(len: usize, rng: &mut R) -> Self {
        let mut s = Self {
            words: (0..words_for(len)).map(|_| rng.next_u64()).collect(),
            len,
        };
        s.clear_tail();
        s
    }

    /// From booleans, bit i = `bits[i]`.
    #[must_use]
    pub fn from_bools(bits: &[bool]) -> Self {
        let mut s = Self::zeros(bits.len());
        for (i, &b) in bits.iter().enumerate() {
            if b {
                s.words[i / WORD_BITS] |= 1 << (i % WORD_BITS);
            }
        }
        s
    }

    /// From packed words (little-endian bit order); bits past `len` are cleared and surplus
    /// words dropped.
    pub fn from_words(mut words: Vec<u64>, len: usize) -> Result<Self, BitStringError> {
        let needed = words_for(len);
        if words.len() < needed {
            let err = BitStringError::TooFewWords {
                words: words.len(),
                len,
            };
            words.zeroize();
            return Err(err);
        }
        words[needed..].zeroize();
        words.truncate(needed);
        let mut s = Self { words, len };
        s.clear_tail();
        Ok(s)
    }

    fn clear_tail(&mut self) {
        if let Some(last) = self.words.last_mut() {
            *last &= tail_mask(self.len);
        }
    }

    /// Number of bits.
    #[must_use]
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the string has no bits.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The packed words (little-endian bit order, zero tail).
    #[must_use]
    pub fn words(&self) -> &[u64] {
        &self.words
    }

    /// Bit `i`, or `None` past the end.
    #[must_use]
    pub fn get(&self, i: usize) -> Option<bool> {
        (i < self.len).then(|| self.words[i / WORD_BITS] >> (i % WORD_BITS) & 1 == 1)
    }

    /// Sets bit `i` to `value`; `None` past the end.
    pub fn set(&mut self, i: usize, value: bool) -> Option<()> {
        if i >= self.len {
            return None;
        }
        let mask = 1_u64 << (i % WORD_BITS);
        let w = &mut self.words[i / WORD_BITS];
        *w = if value { *w | mask } else { *w & !mask };
        Some(())
    }

    /// Flips bit `i`; `None` past the end.
    pub fn flip(&mut self, i: usize) -> Option<()> {
        if i >= self.len {
            return None;
        }
        self.words[i / WORD_BITS] ^= 1 << (i % WORD_BITS);
        Some(())
    }

    /// Number of one bits (Hamming weight).
    #[must_use]
    pub fn count_ones(&self) -> usize {
        self.words.iter().map(|w| w.count_ones() as usize).sum()
    }

    /// Bitwise XOR a ⊕ b.
    pub fn xor(&self, other: &Self) -> Result<Self, BitStringError> {
        if self.len != other.len {
            return Err(BitStringError::LengthMismatch {
                left: self.len,
                right: other.len,
            });
        }
        let words = self
            .words
            .iter()
            .zip(&other.words)
            .map(|(a, b)| a ^ b)
            .collect();
        Ok(Self {
            words,
            len: self.len,
        })
    }

    /// Hamming distance: number of positions where the strings differ.
    pub fn hamming_distance(&self, other: &Self) -> Result<usize, BitStringError> {
        if self.len != other.len {
            return Err(BitStringError::LengthMismatch {
                left: self.len,
                right: other.len,
            });
        }
        Ok(self
            .words
            .iter()
            .zip(&other.words)
            .map(|(a, b)| (a ^ b).count_ones() as usize)
            .sum())
    }

    /// Parity (XOR) of bits in `start..end`, word at a time; `None` if the range is out of
    /// bounds or reversed.
    #[must_use]
    pub fn range_parity(&self, start: usize, end: usize) -> Option<bool> {
        if start > end || end > self.len {
            return None;
        }
        if start == end {
            return Some(false);
        }
        let (first, last) = (start / WORD_BITS, (end - 1) / WORD_BITS);
        let lo_mask = u64::MAX << (start % WORD_BITS);
        let hi_mask = tail_mask(end);
        let acc = if first == last {
            self.words[first] & lo_mask & hi_mask
        } else {
            let middle = self.words[first + 1..last].iter().fold(0, |a, w| a ^ w);
            (self.words[first] & lo_mask) ^ middle ^ (self.words[last] & hi_mask)
        };
        Some(acc.count_ones() % 2 == 1)
    }

    /// Parity of the bits at `positions` (bit by bit); `None` if any position is out of range.
    #[must_use]
    pub fn parity_of(&self, positions: &[usize]) -> Option<bool> {
        positions
            .iter()
            .try_fold(false, |acc, &i| Some(acc ^ self.get(i)?))
    }

    /// The bits as bytes, little-endian (bit i is bit i mod 8 of byte i / 8), ⌈len/8⌉ bytes.
    /// The caller owns the copy of key material: zeroize it after use.
    #[must_use]
    pub fn to_bytes(&self) -> Vec<u8> {
        // One allocation: no reallocated copies of key bytes left behind.
        let mut out = Vec::with_capacity(self.words.len() * 8);
        out.extend(self.words.iter().flat_map(|w| w.to_le_bytes()));
        let keep = self.len.div_ceil(8);
        for b in &mut out[keep..] {
            b.zeroize();
        }
        out.truncate(keep);
        out
    }

    /// The bits in reversed order (bit i becomes bit len − 1 − i).
    #[must_use]
    pub fn reversed(&self) -> Self {
        let mut out = Self::zeros(self.len);
        // Reverse whole words, then shift the result down by the unused tail width.
        let n = self.words.len();
        let shift = (n * WORD_BITS - self.len) % WORD_BITS;
        for (i, w) in self.words.iter().enumerate() {
            out.words[n - 1 - i] = w.reverse_bits();
        }
        if shift > 0 {
            for i in 0..n {
                let hi = out.words.get(i + 1).copied().unwrap_or(0);
                out.words[i] = (out.words[i] >> shift) | (hi << (WORD_BITS - shift));
            }
        }
        out.clear_tail();
        out
    }

    /// The 64 bits starting at bit `start` as one word (bit j of the result = bit start + j),
    /// zero past the end.
    #[must_use]
    pub(crate) fn word_at(&self, start: usize) -> u64 {
        let (q, r) = (start / WORD_BITS, start % WORD_BITS);
        let lo = self.words.get(q).copied().unwrap_or(0);
        if r == 0 {
            lo
        } else {
            let hi = self.words.get(q + 1).copied().unwrap_or(0);
            (lo >> r) | (hi << (WORD_BITS - r))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn bools() -> impl Strategy<Value = Vec<bool>> {
        proptest::collection::vec(any::<bool>(), 0..300)
    }

    proptest! {
        #[test]
        fn round_trips_and_counts(bits in bools()) {
            let s = BitString::from_bools(&bits);
            prop_assert_eq!(s.len(), bits.len());
            for (i, &b) in bits.iter().enumerate() {
                prop_assert_eq!(s.get(i), Some(b));
            }
            prop_assert_eq!(s.get(bits.len()), None);
            prop_assert_eq!(s.count_ones(), bits.iter().filter(|&&b| b).count());
            let bytes = s.to_bytes();
            prop_assert_eq!(bytes.len(), bits.len().div_ceil(8));
            for (i, &b) in bits.iter().enumerate() {
                prop_assert_eq!(bytes[i / 8] >> (i % 8) & 1 == 1, b);
            }
            let rev = s.reversed();
            for (i, &b) in bits.iter().rev().enumerate() {
                prop_assert_eq!(rev.get(i), Some(b));
            }
            prop_assert_eq!(BitString::from_words(s.words().to_vec(), s.len()).unwrap(), s);
        }

        #[test]
        fn range_parity_matches_bitwise(bits in bools(), a in 0usize..300, b in 0usize..300) {
            let s = BitString::from_bools(&bits);
            let (start, end) = (a.min(b), a.max(b));
            let expected = (end <= bits.len())
                .then(|| bits[start..end].iter().fold(false, |acc, &x| acc ^ x));
            prop_assert_eq!(s.range_parity(start, end), expected);
            let positions: Vec<usize> = (start..end.min(bits.len())).collect();
            let direct = positions.iter().fold(false, |acc, &i| acc ^ bits[i]);
            prop_assert_eq!(s.parity_of(&positions), Some(direct));
        }

        #[test]
        fn xor_and_distance(x in bools(), seed in any::<u64>()) {
            use rand::SeedableRng;
            let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(seed);
            let a = BitString::from_bools(&x);
            let b = BitString::random(x.len(), &mut rng);
            let c = a.xor(&b).unwrap();
            prop_assert_eq!(c.count_ones(), a.hamming_distance(&b).unwrap());
            prop_assert_eq!(c.xor(&b).unwrap(), a);
            // Random strings keep the zero tail.
            prop_assert_eq!(b.words().last().map_or(0, |w| w & !tail_mask(b.len())), 0);
        }
    }

    #[test]
    fn errors_and_edits() {
        let mut s = BitString::zeros(70);
        assert_eq!(s.set(69, true), Some(()));
        assert_eq!(s.flip(0), Some(()));
        assert_eq!(s.flip(70), None);
        assert_eq!(s.count_ones(), 2);
        assert_eq!(s.word_at(6), 1 << 63);
        assert!(matches!(
            s.xor(&BitString::zeros(3)),
            Err(BitStringError::LengthMismatch { left: 70, right: 3 })
        ));
        assert!(matches!(
            BitString::from_words(vec![1], 65),
            Err(BitStringError::TooFewWords { .. })
        ));
        let t = BitString::from_words(vec![u64::MAX, u64::MAX, 7], 65).unwrap();
        assert_eq!((t.count_ones(), t.words().len()), (65, 2));
        assert_eq!(format!("{t:?}"), "BitString { len: 65, .. }");
        assert_eq!(s.range_parity(5, 4), None);
    }
}
