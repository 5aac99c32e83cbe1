//! Toeplitz hashing over GF(2) for privacy amplification (docs/secrecy.md).

use rand::CryptoRng;
use thiserror::Error;

use crate::bitstring::BitString;
use crate::gf2_poly;

/// Errors of Toeplitz hashing.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ToeplitzError {
    /// Input length n or output length ℓ is zero.
    #[error("input and output lengths must be positive (n = {n}, l = {l})")]
    ZeroLength {
        /// Input length.
        n: usize,
        /// Output length.
        l: usize,
    },
    /// ℓ > n: hashing cannot lengthen a key.
    #[error("output length {l} exceeds input length {n}")]
    OutputLongerThanInput {
        /// Input length.
        n: usize,
        /// Output length.
        l: usize,
    },
    /// The seed does not have n + ℓ − 1 bits.
    #[error("seed has {got} bits, expected n + l - 1 = {expected}")]
    SeedLength {
        /// Required seed length.
        expected: usize,
        /// Given seed length.
        got: usize,
    },
    /// The key does not have n bits.
    #[error("key has {got} bits, expected {expected}")]
    KeyLength {
        /// Required key length.
        expected: usize,
        /// Given key length.
        got: usize,
    },
}

/// A random ℓ × n Toeplitz matrix T over GF(2), T_ij = s[i − j + n − 1], given by its public
/// seed s of n + ℓ − 1 bits. The family is two-universal, so the leftover hash lemma applies.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ToeplitzHash {
    seed: BitString,
    n: usize,
    l: usize,
}

fn check_lengths(n: usize, l: usize) -> Result<(), ToeplitzError> {
    if n == 0 || l == 0 {
        return Err(ToeplitzError::ZeroLength { n, l });
    }
    if l > n {
        return Err(ToeplitzError::OutputLongerThanInput { n, l });
    }
    Ok(())
}

impl ToeplitzHash {
    /// The hash for seed `seed` (n + ℓ − 1 bits) from n to ℓ ≤ n bits.
    pub fn new(seed: BitString, n: usize, l: usize) -> Result<Self, ToeplitzError> {
        check_lengths(n, l)?;
        let expected = n + l - 1;
        if seed.len() != expected {
            return Err(ToeplitzError::SeedLength {
                expected,
                got: seed.len(),
            });
        }
        Ok(Self { seed, n, l })
    }

    /// A hash with a fresh uniform seed from a cryptographic generator.
    pub fn random<R: CryptoRng + ?Sized>(
        n: usize,
        l: usize,
        rng: &mut R,
    ) -> Result<Self, ToeplitzError> {
        check_lengths(n, l)?;
        Self::new(BitString::random(n + l - 1, rng), n, l)
    }

    /// The public seed s.
    #[must_use]
    pub fn seed(&self) -> &BitString {
        &self.seed
    }

    /// Input length n.
    #[must_use]
    pub fn input_len(&self) -> usize {
        self.n
    }

    /// Output length ℓ.
    #[must_use]
    pub fn output_len(&self) -> usize {
        self.l
    }

    /// T·x over GF(2). Output bit i = ⊕_j s[i + n − 1 − j]·x_j is coefficient i + n − 1 of
    /// the carry-less product S(z)·X(z), S = Σ s_k z^k, X = Σ x_j z^j: one packed
    /// polynomial product (Karatsuba over a portable 64-bit carry-less word product), then
    /// the ℓ coefficients n − 1 .. n + ℓ − 2. Cost O(((n + ℓ)/64)^1.585) word products:
    /// about 8 ms for n = 10⁵ and 0.3 s for n = 10⁶ (ℓ = n/2, one core), where the direct
    /// row-by-row product, O(ℓ·n/64), took 0.15 s and about 15 s. Table lookups and
    /// branches depend on the lengths and the public seed only, not on the key; the
    /// intermediate product is zeroized.
    pub fn hash(&self, key: &BitString) -> Result<BitString, ToeplitzError> {
        if key.len() != self.n {
            return Err(ToeplitzError::KeyLength {
                expected: self.n,
                got: key.len(),
            });
        }
        // The seed is the first (table-indexing) factor: the key's words are never indices.
        // Held as a BitString, the product is zeroized on drop.
        let product = gf2_poly::mul(self.seed.words(), key.words());
        let product_bits = 64 * product.len();
        let product = BitString::from_words(product, product_bits)
            .expect("a word vector holds 64 bits per word");
        let words = (0..self.l.div_ceil(64))
            .map(|k| product.word_at(self.n - 1 + 64 * k))
            .collect();
        Ok(BitString::from_words(words, self.l).expect("⌈ℓ/64⌉ words hold ℓ bits"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand::SeedableRng;
    use rand::rngs::ChaCha8Rng;

    /// The definition: T[i][j] = s[i − j + n − 1], y_i = ⊕_j T[i][j] x_j, bit by bit.
    fn naive(seed: &BitString, x: &BitString, l: usize) -> BitString {
        let n = x.len();
        let bits: Vec<bool> = (0..l)
            .map(|i| {
                (0..n).fold(false, |acc, j| {
                    acc ^ (seed.get(i + n - 1 - j).unwrap() & x.get(j).unwrap())
                })
            })
            .collect();
        BitString::from_bools(&bits)
    }

    /// The former implementation: bit i = parity(s[i..i + n] ∧ rev(x)), one AND and
    /// popcount per word, O(ℓ·n/64).
    fn direct(seed: &BitString, x: &BitString, l: usize) -> BitString {
        let reversed = x.reversed();
        let mut out = BitString::zeros(l);
        for i in 0..l {
            let acc = reversed
                .words()
                .iter()
                .enumerate()
                .fold(0_u64, |acc, (w, &x)| acc ^ (seed.word_at(i + 64 * w) & x));
            if acc.count_ones() % 2 == 1 {
                out.flip(i).unwrap();
            }
        }
        out
    }

    fn check_against_direct(n: usize, l: usize, rng: &mut ChaCha8Rng) {
        let t = ToeplitzHash::random(n, l, rng).unwrap();
        let x = BitString::random(n, rng);
        let y = t.hash(&x).unwrap();
        assert_eq!(y.len(), l);
        assert_eq!(y, direct(t.seed(), &x, l), "n = {n}, l = {l}");
    }

    proptest! {
        #[test]
        fn equals_naive_product_and_is_linear(
            n in 1usize..300,
            l_frac in 0.0f64..1.0,
            seed in any::<u64>(),
        ) {
            let l = ((n as f64 * l_frac) as usize).max(1);
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let t = ToeplitzHash::random(n, l, &mut rng).unwrap();
            let a = BitString::random(n, &mut rng);
            let b = BitString::random(n, &mut rng);
            let ha = t.hash(&a).unwrap();
            prop_assert_eq!(&ha, &naive(t.seed(), &a, l));
            let hb = t.hash(&b).unwrap();
            let hab = t.hash(&a.xor(&b).unwrap()).unwrap();
            prop_assert_eq!(hab, ha.xor(&hb).unwrap());
            prop_assert_eq!(ha.len(), l);
        }

        #[test]
        fn equals_direct_product(
            n in 1usize..4000,
            l_frac in 0.0f64..1.0,
            seed in any::<u64>(),
        ) {
            let l = ((n as f64 * l_frac) as usize).max(1);
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            for l in [1, l, n] {
                check_against_direct(n, l, &mut rng);
            }
        }
    }

    #[test]
    fn equals_direct_product_at_word_edges() {
        // n and ℓ around multiples of 64, around the Karatsuba threshold (in words), and one
        // size deep enough for several Karatsuba levels.
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let t = 64 * crate::gf2_poly::KARATSUBA_THRESHOLD;
        for n in [
            1,
            63,
            64,
            65,
            127,
            128,
            129,
            t - 1,
            t,
            t + 1,
            2 * t + 65,
            9000,
        ] {
            for l in [1, 2, 63, 64, 65, n / 2, n - 1, n] {
                if (1..=n).contains(&l) {
                    check_against_direct(n, l, &mut rng);
                }
            }
        }
    }

    #[test]
    fn rejects_bad_lengths() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        assert!(matches!(
            ToeplitzHash::random(0, 0, &mut rng),
            Err(ToeplitzError::ZeroLength { .. })
        ));
        assert!(matches!(
            ToeplitzHash::random(10, 11, &mut rng),
            Err(ToeplitzError::OutputLongerThanInput { .. })
        ));
        assert!(matches!(
            ToeplitzHash::new(BitString::zeros(10), 10, 2),
            Err(ToeplitzError::SeedLength {
                expected: 11,
                got: 10
            })
        ));
        let t = ToeplitzHash::random(10, 2, &mut rng).unwrap();
        assert!(matches!(
            t.hash(&BitString::zeros(9)),
            Err(ToeplitzError::KeyLength { .. })
        ));
    }

    #[test]
    fn unit_vectors_read_seed_columns() {
        // Column j of T is s[n−1−j .. n−1−j+ℓ]: hashing e_j must return it.
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (n, l) = (130, 70);
        let t = ToeplitzHash::random(n, l, &mut rng).unwrap();
        for j in [0, 1, 63, 64, 129] {
            let mut e = BitString::zeros(n);
            e.flip(j).unwrap();
            let col = t.hash(&e).unwrap();
            for i in 0..l {
                assert_eq!(col.get(i), t.seed().get(i + n - 1 - j), "i={i} j={j}");
            }
        }
    }
}
