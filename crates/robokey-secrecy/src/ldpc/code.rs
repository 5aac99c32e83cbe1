//! A sparse parity-check matrix built deterministically from a public seed.
//!
//! Construction: the variables' degrees from the [`DegreeProfile`] for the code's rate are
//! shuffled by ChaCha8 from the seed. The degree-2 variables form a chain (the j-th joins
//! checks ⌊j·m/(k+1)⌋ and ⌊(j+1)·m/(k+1)⌋ for k of them, k < m), so no cycle runs through
//! degree-2 variables alone (a weight-2 codeword would need one). Every other variable v gets
//! deg(v) sockets (the configuration model); the S sockets are shuffled and dealt in order to
//! the m checks, check c taking ⌊S/m⌋ or ⌈S/m⌉ of them. A variable
//! dealt twice to one check is swapped with a random socket of a later check (up to
//! [`SWAP_ATTEMPTS`] times); a pair still repeated cancels (it adds xᵥ ⊕ xᵥ = 0), so each
//! check is a set. Same seed, n and m: same matrix, on both sides.

use rand::rngs::ChaCha8Rng;
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};

use super::degrees::DegreeProfile;
use super::{LdpcError, MAX_BLOCK_BITS};
use crate::bitstring::BitString;

/// Attempts to move a repeated variable out of a check.
const SWAP_ATTEMPTS: usize = 16;

/// An m × n parity-check matrix H over GF(2), stored by checks (rows).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParityCheck {
    block: usize,
    /// Check c's variables are `variables[starts[c]..starts[c + 1]]`, increasing.
    starts: Vec<usize>,
    variables: Vec<u32>,
}

impl ParityCheck {
    /// The code for `block` bits and `syndrome` checks on a channel with Bhattacharyya
    /// parameter `bhattacharyya` (see [`super::bhattacharyya`]) from the public `seed`.
    pub fn build(
        block: usize,
        syndrome: usize,
        bhattacharyya: f64,
        seed: [u8; 32],
    ) -> Result<Self, LdpcError> {
        if block == 0 || block > MAX_BLOCK_BITS {
            return Err(LdpcError::BlockLength(block));
        }
        if syndrome == 0 || syndrome > block {
            return Err(LdpcError::SyndromeLength { syndrome, block });
        }
        let mut rng = ChaCha8Rng::from_seed(seed);
        let mut degrees =
            DegreeProfile::for_channel(block, syndrome, bhattacharyya).variable_degrees(block);
        degrees.shuffle(&mut rng);
        // Degree-2 variables form a chain through evenly spaced checks (no cycle among
        // them); any beyond m − 1 get degree 3.
        let mut chain = Vec::new();
        for (v, d) in degrees.iter_mut().enumerate() {
            if *d == 2 {
                if chain.len() + 1 < syndrome {
                    chain.push(v as u32);
                } else {
                    *d = 3;
                }
            }
        }
        let link = |j: usize| j * syndrome / (chain.len() + 1);
        let mut chained: Vec<(usize, u32)> = chain
            .iter()
            .enumerate()
            .flat_map(|(j, &v)| [(link(j), v), (link(j + 1), v)])
            .collect();
        chained.sort_unstable();
        let mut sockets: Vec<u32> = degrees
            .iter()
            .enumerate()
            .filter(|&(_, &d)| d != 2)
            .flat_map(|(v, &d)| std::iter::repeat_n(v as u32, d as usize))
            .collect();
        sockets.shuffle(&mut rng);
        let spread = sockets.len();
        let bounds: Vec<usize> = (0..=syndrome).map(|c| c * spread / syndrome).collect();
        let mut starts = Vec::with_capacity(syndrome + 1);
        let mut variables = Vec::with_capacity(spread + chained.len());
        let mut links = chained.iter().peekable();
        let mut check = Vec::new();
        starts.push(0);
        for c in 0..syndrome {
            let (start, end) = (bounds[c], bounds[c + 1]);
            separate_repeats(&mut sockets, start, end, &mut rng);
            check.clear();
            check.extend_from_slice(&sockets[start..end]);
            while let Some(&(_, v)) = links.next_if(|&&(k, _)| k == c) {
                check.push(v);
            }
            check.sort_unstable();
            let mut k = 0;
            while k < check.len() {
                if k + 1 < check.len() && check[k] == check[k + 1] {
                    k += 2;
                } else {
                    variables.push(check[k]);
                    k += 1;
                }
            }
            starts.push(variables.len());
        }
        Ok(Self {
            block,
            starts,
            variables,
        })
    }

    /// Splits the `count` checks of largest degree (ties: the lower index; degree ≥ 2 only)
    /// in two: the variables at odd positions of each check's increasing list leave it and
    /// form a new check. Returns the code with the remainders in place and the halves
    /// appended, and the split checks' indices in the halves' order. A syndrome bit of each
    /// half, with the split check's, gives both parts' parities (s_rest = s_check ⊕ s_half):
    /// the increment of a feedback round, a code of lower check degree instead of extra
    /// checks stacked over the old ones.
    #[must_use]
    pub fn split(&self, count: usize) -> (Self, Vec<u32>) {
        let mut order: Vec<usize> = (0..self.syndrome_bits())
            .filter(|&c| self.check(c).len() >= 2)
            .collect();
        order.sort_by_key(|&c| (std::cmp::Reverse(self.check(c).len()), c));
        order.truncate(count);
        let mut split = vec![false; self.syndrome_bits()];
        for &c in &order {
            split[c] = true;
        }
        let mut starts = Vec::with_capacity(self.starts.len() + order.len());
        let mut variables = Vec::with_capacity(self.variables.len());
        starts.push(0);
        for (c, &halved) in split.iter().enumerate() {
            let check = self.check(c);
            if halved {
                variables.extend(check.iter().step_by(2));
            } else {
                variables.extend_from_slice(check);
            }
            starts.push(variables.len());
        }
        for &c in &order {
            variables.extend(self.check(c).iter().skip(1).step_by(2));
            starts.push(variables.len());
        }
        let code = Self {
            block: self.block,
            starts,
            variables,
        };
        (code, order.iter().map(|&c| c as u32).collect())
    }

    /// Block length n.
    #[must_use]
    pub fn block(&self) -> usize {
        self.block
    }

    /// Syndrome length m.
    #[must_use]
    pub fn syndrome_bits(&self) -> usize {
        self.starts.len() - 1
    }

    /// Edges (ones of H).
    #[must_use]
    pub fn edges(&self) -> usize {
        self.variables.len()
    }

    /// Check c's variables.
    pub(super) fn check(&self, c: usize) -> &[u32] {
        &self.variables[self.starts[c]..self.starts[c + 1]]
    }

    /// s = H·x over GF(2).
    pub fn syndrome(&self, bits: &BitString) -> Result<BitString, LdpcError> {
        if bits.len() != self.block {
            return Err(LdpcError::Length {
                what: "key",
                got: bits.len(),
                expected: self.block,
            });
        }
        let words = bits.words();
        let parities: Vec<bool> = (0..self.syndrome_bits())
            .map(|c| {
                self.check(c)
                    .iter()
                    .fold(false, |p, &v| p ^ bit(words, v as usize))
            })
            .collect();
        Ok(BitString::from_bools(&parities))
    }
}

/// Bit i of packed words.
pub(super) fn bit(words: &[u64], i: usize) -> bool {
    (words[i / 64] >> (i % 64)) & 1 == 1
}

/// Swaps variables repeated within `sockets[start..end]` with random sockets of later checks
/// (sorted, so a repeat is a neighbour: O(d log d) per attempt for a check of degree d).
fn separate_repeats(sockets: &mut [u32], start: usize, end: usize, rng: &mut ChaCha8Rng) {
    let len = sockets.len();
    if end >= len {
        return;
    }
    let mut repeats = Vec::new();
    for _ in 0..SWAP_ATTEMPTS {
        let check = &mut sockets[start..end];
        check.sort_unstable();
        repeats.clear();
        repeats.extend((1..check.len()).filter(|&k| check[k] == check[k - 1]));
        if repeats.is_empty() {
            return;
        }
        for &k in &repeats {
            let other = rng.random_range(end..len);
            sockets.swap(start + k, other);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_seed_builds_the_same_code_and_another_seed_another() {
        let a = ParityCheck::build(5_000, 1_000, 0.3, [7; 32]).unwrap();
        let b = ParityCheck::build(5_000, 1_000, 0.3, [7; 32]).unwrap();
        let c = ParityCheck::build(5_000, 1_000, 0.3, [8; 32]).unwrap();
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert_eq!(a.syndrome_bits(), 1_000);
    }

    #[test]
    fn checks_are_sets_and_every_variable_is_checked() {
        let code = ParityCheck::build(4_000, 400, 0.3, [1; 32]).unwrap();
        let mut seen = vec![false; 4_000];
        for c in 0..code.syndrome_bits() {
            let check = code.check(c);
            assert!(check.windows(2).all(|w| w[0] < w[1]), "check {c}");
            for &v in check {
                seen[v as usize] = true;
            }
        }
        assert!(seen.iter().all(|&s| s));
    }

    #[test]
    fn the_syndrome_is_linear() {
        let code = ParityCheck::build(3_000, 900, 0.3, [3; 32]).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (x, y) = (
            BitString::random(3_000, &mut rng),
            BitString::random(3_000, &mut rng),
        );
        let sum = code.syndrome(&x.xor(&y).unwrap()).unwrap();
        let parts = code
            .syndrome(&x)
            .unwrap()
            .xor(&code.syndrome(&y).unwrap())
            .unwrap();
        assert_eq!(sum, parts);
    }

    #[test]
    fn a_split_check_keeps_its_variables_in_two_halves() {
        let base = ParityCheck::build(2_000, 300, 0.3, [4; 32]).unwrap();
        let (split, parents) = base.split(30);
        assert_eq!(split.syndrome_bits(), 330);
        assert_eq!(split.edges(), base.edges());
        let largest = (0..300).map(|c| base.check(c).len()).max().unwrap();
        assert_eq!(base.check(parents[0] as usize).len(), largest);
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        let x = BitString::random(2_000, &mut rng);
        let (whole, parts) = (base.syndrome(&x).unwrap(), split.syndrome(&x).unwrap());
        for (k, &p) in parents.iter().enumerate() {
            let p = p as usize;
            let (rest, half) = (split.check(p), split.check(300 + k));
            assert!(!rest.is_empty() && !half.is_empty());
            let mut joined = [rest, half].concat();
            joined.sort_unstable();
            assert_eq!(joined, base.check(p));
            assert_eq!(whole.get(p), Some(parts.get(p) != parts.get(300 + k)));
        }
        let unsplit = (0..300).find(|c| !parents.contains(&(*c as u32))).unwrap();
        assert_eq!(split.check(unsplit), base.check(unsplit));
    }

    #[test]
    fn bad_sizes_are_refused() {
        assert_eq!(
            ParityCheck::build(0, 1, 0.3, [0; 32]),
            Err(LdpcError::BlockLength(0))
        );
        assert_eq!(
            ParityCheck::build(10, 11, 0.3, [0; 32]),
            Err(LdpcError::SyndromeLength {
                syndrome: 11,
                block: 10
            })
        );
        let code = ParityCheck::build(10, 5, 0.3, [0; 32]).unwrap();
        assert!(matches!(
            code.syndrome(&BitString::zeros(9)),
            Err(LdpcError::Length { got: 9, .. })
        ));
    }
}
