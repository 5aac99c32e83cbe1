//! Toeplitz hashing over GF(2) for privacy amplification (SECRECY §5).

use rand::CryptoRng;
use thiserror::Error;

use crate::bitstring::BitString;

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

    /// T·x over GF(2). Output bit i = ⊕_j s[i + n − 1 − j]·x_j = parity(s[i..i + n] ∧ rev(x)):
    /// one AND and popcount per 64-bit word, O(ℓ·n/64).
    pub fn hash(&self, key: &BitString) -> Result<BitString, ToeplitzError> {
        if key.len() != self.n {
            return Err(ToeplitzError::KeyLength {
                expected: self.n,
                got: key.len(),
            });
        }
        let reversed = key.reversed();
        let mut out = BitString::zeros(self.l);
        for i in 0..self.l {
            let acc = reversed
                .words()
                .iter()
                .enumerate()
                .fold(0_u64, |acc, (w, &x)| {
                    acc ^ (self.seed.word_at(i + 64 * w) & x)
                });
            if acc.count_ones() % 2 == 1 {
                // i < ℓ = out.len(), so this cannot fail.
                let _ = out.flip(i);
            }
        }
        Ok(out)
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
