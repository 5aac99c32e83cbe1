//! Products of binary polynomials (`GF(2)[z]`, carry-less) packed in u64 words.
//!
//! A polynomial is a word slice: coefficient of z^i is bit i mod 64 of word i / 64. Word
//! products use a portable 6-bit-window table (no CLMUL, safe Rust); slices below
//! [`KARATSUBA_THRESHOLD`] words are multiplied schoolbook, longer ones by Karatsuba, so an
//! m × m-word product costs O(m^log2(3)) = O(m^1.585) word operations.
//!
//! Side channels: table indices and branches depend only on the lengths and on the words of
//! the first factor `a`, never on the words of `b`; pass the secret factor as `b`.

use zeroize::Zeroize;

/// Shorter factor length (words) below which products are schoolbook; at and above it,
/// Karatsuba. Tuned on the Toeplitz benchmark (10⁵ and 10⁶-bit keys): 6 to 24 lie within
/// 40 % of each other, 8 was fastest.
pub(crate) const KARATSUBA_THRESHOLD: usize = 8;

/// Window of the word product, in bits: 11 table lookups per word product, 64-entry tables.
const WINDOW: u32 = 6;

/// Table index mask.
const DIGIT: u64 = (1 << WINDOW) - 1;

/// `REPAIR[i − 1]`: the bit positions p with p mod [`WINDOW`] ≥ i, for i = 1 .. WINDOW − 1.
const REPAIR: [u64; WINDOW as usize - 1] = {
    let mut masks = [0; WINDOW as usize - 1];
    let mut i = 1;
    while i < WINDOW {
        let mut p = 0;
        while p < 64 {
            if p % WINDOW >= i {
                masks[i as usize - 1] |= 1 << p;
            }
            p += 1;
        }
        i += 1;
    }
    masks
};

/// The multiples b·k mod z^64 of one word b for all k of [`WINDOW`] bits, to multiply many
/// words by b.
struct WordMultiples {
    low: [u64; 1 << WINDOW],
    b: u64,
}

impl WordMultiples {
    fn new(b: u64) -> Self {
        let mut low = [0_u64; 1 << WINDOW];
        low[1] = b;
        for k in 1..(1 << (WINDOW - 1)) {
            low[2 * k] = low[k] << 1;
            low[2 * k + 1] = low[2 * k] ^ b;
        }
        Self { low, b }
    }

    /// The 128-bit carry-less product a·b as (low word, high word).
    #[inline]
    fn mul(&self, a: u64) -> (u64, u64) {
        // ⊕_t z^{Wt}·low[digit t of a], the bits pushed past 64 by the shift going to the
        // high word.
        let mut lo = self.low[(a & DIGIT) as usize];
        let mut hi = 0;
        let mut shift = WINDOW;
        while shift < 64 {
            let g = self.low[((a >> shift) & DIGIT) as usize];
            lo ^= g << shift;
            hi ^= g >> (64 - shift);
            shift += WINDOW;
        }
        // Add back what the truncated table lost: bit 64 − i of b times bit p of a with
        // p mod W ≥ i lands at bit p − i of the high word. Masks, not branches, on b.
        for (i, mask) in (1..).zip(REPAIR) {
            let take = 0_u64.wrapping_sub((self.b >> (64 - i)) & 1);
            hi ^= ((a & mask) >> i) & take;
        }
        (lo, hi)
    }
}

/// Schoolbook product: `out[..a.len() + b.len()]` = a·b (overwritten), O(|a|·|b|) word
/// products. Panics if `out` is shorter.
pub(crate) fn mul_schoolbook(a: &[u64], b: &[u64], out: &mut [u64]) {
    let out = &mut out[..a.len() + b.len()];
    out.fill(0);
    for (j, &bj) in b.iter().enumerate() {
        let table = WordMultiples::new(bj);
        let mut carry = 0;
        for (o, &ai) in out[j..j + a.len()].iter_mut().zip(a) {
            let (lo, hi) = table.mul(ai);
            *o ^= lo ^ carry;
            carry = hi;
        }
        out[j + a.len()] ^= carry;
    }
}

/// The product a·b of two packed binary polynomials, |a| + |b| words (the top word may be
/// zero), by Karatsuba above [`KARATSUBA_THRESHOLD`]. Any lengths, equal or not; the
/// scratch space (about 4·max(|a|, |b|) words) is allocated once and zeroized.
pub(crate) fn mul(a: &[u64], b: &[u64]) -> Vec<u64> {
    let mut out = vec![0; a.len() + b.len()];
    // A node with longer factor m keeps 4·⌈m/2⌉ ≤ 2m + 2 words (an unbalanced split less)
    // and hands at most ⌈m/2⌉ to its children: 4m + 4·depth in all, depth < 64.
    let mut scratch = vec![0; 4 * a.len().max(b.len()) + 256];
    mul_rec(a, b, &mut out, &mut scratch);
    scratch.zeroize();
    out
}

fn xor_into(dst: &mut [u64], src: &[u64]) {
    for (d, s) in dst.iter_mut().zip(src) {
        *d ^= s;
    }
}

/// `out` (|a| + |b| words) = a·b, using `scratch`.
fn mul_rec(a: &[u64], b: &[u64], out: &mut [u64], scratch: &mut [u64]) {
    let (la, lb) = (a.len(), b.len());
    let (short, long) = (la.min(lb), la.max(lb));
    if short < KARATSUBA_THRESHOLD {
        mul_schoolbook(a, b, out);
        return;
    }
    let h = long.div_ceil(2);
    if short <= h {
        mul_unbalanced(a, b, out, scratch);
        return;
    }
    // a = a0 + z^h·a1, b = b0 + z^h·b1 with |a0| = |b0| = h ≥ |a1|, |b1| ≥ 1:
    // a·b = p0 + z^h·(pm − p0 − p2) + z^2h·p2, p0 = a0·b0, p2 = a1·b1,
    // pm = (a0 + a1)·(b0 + b1).
    let (a0, a1) = a.split_at(h);
    let (b0, b1) = b.split_at(h);
    let (sa, rest) = scratch.split_at_mut(h);
    let (sb, rest) = rest.split_at_mut(h);
    let (pm, rest) = rest.split_at_mut(2 * h);
    sa.copy_from_slice(a0);
    xor_into(sa, a1);
    sb.copy_from_slice(b0);
    xor_into(sb, b1);
    mul_rec(sa, sb, pm, rest);
    let (p0, p2) = out.split_at_mut(2 * h);
    mul_rec(a0, b0, p0, rest);
    mul_rec(a1, b1, p2, rest);
    xor_into(pm, p0);
    xor_into(pm, p2);
    // |a| + |b| ≥ (2h − 1) + (h + 1) = 3h: the middle term fits.
    xor_into(&mut out[h..3 * h], pm);
}

/// `out` = a·b when the shorter factor has at most half the longer one's length: the
/// longer is cut into pieces as long as the shorter, each product added in at its offset.
fn mul_unbalanced(a: &[u64], b: &[u64], out: &mut [u64], scratch: &mut [u64]) {
    let short = a.len().min(b.len());
    out.fill(0);
    let (piece_out, rest) = scratch.split_at_mut(2 * short);
    if a.len() >= b.len() {
        for (k, piece) in a.chunks(short).enumerate() {
            let len = piece.len() + short;
            mul_rec(piece, b, &mut piece_out[..len], rest);
            xor_into(&mut out[k * short..k * short + len], &piece_out[..len]);
        }
    } else {
        for (k, piece) in b.chunks(short).enumerate() {
            let len = piece.len() + short;
            mul_rec(a, piece, &mut piece_out[..len], rest);
            xor_into(&mut out[k * short..k * short + len], &piece_out[..len]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand::rngs::ChaCha8Rng;
    use rand::{Rng, SeedableRng};

    /// Bit-by-bit carry-less product of two words: (low, high).
    fn clmul_bits(a: u64, b: u64) -> (u64, u64) {
        let (a, b) = (u128::from(a), u128::from(b));
        let p = (0..64).fold(0_u128, |acc, i| {
            if (a >> i) & 1 == 1 {
                acc ^ (b << i)
            } else {
                acc
            }
        });
        (p as u64, (p >> 64) as u64)
    }

    /// Bit-by-bit polynomial product, |a| + |b| words.
    fn mul_bits(a: &[u64], b: &[u64]) -> Vec<u64> {
        let mut out = vec![0; a.len() + b.len()];
        for i in 0..64 * a.len() {
            if (a[i / 64] >> (i % 64)) & 1 == 1 {
                for j in 0..64 * b.len() {
                    if (b[j / 64] >> (j % 64)) & 1 == 1 {
                        out[(i + j) / 64] ^= 1 << ((i + j) % 64);
                    }
                }
            }
        }
        out
    }

    fn words(len: usize, rng: &mut ChaCha8Rng) -> Vec<u64> {
        (0..len).map(|_| rng.next_u64()).collect()
    }

    proptest! {
        #[test]
        fn word_product_matches_bitwise(a in any::<u64>(), b in any::<u64>()) {
            prop_assert_eq!(WordMultiples::new(b).mul(a), clmul_bits(a, b));
        }

        #[test]
        fn karatsuba_matches_schoolbook(
            la in 1usize..5 * KARATSUBA_THRESHOLD,
            lb in 1usize..5 * KARATSUBA_THRESHOLD,
            seed in any::<u64>(),
        ) {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let (a, b) = (words(la, &mut rng), words(lb, &mut rng));
            let mut expected = vec![0; la + lb];
            mul_schoolbook(&a, &b, &mut expected);
            prop_assert_eq!(mul(&a, &b), expected);
        }
    }

    #[test]
    fn word_product_edge_words() {
        let edges = [
            0,
            1,
            2,
            0xf,
            1 << 63,
            0xe000_0000_0000_0000,
            u64::MAX,
            0x8000_0001,
        ];
        for a in edges {
            for b in edges {
                assert_eq!(
                    WordMultiples::new(b).mul(a),
                    clmul_bits(a, b),
                    "{a:x}·{b:x}"
                );
            }
        }
    }

    #[test]
    fn schoolbook_matches_bitwise() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for (la, lb) in [(1, 1), (1, 3), (3, 1), (2, 5), (4, 4)] {
            let (a, b) = (words(la, &mut rng), words(lb, &mut rng));
            let mut out = vec![u64::MAX; la + lb + 1];
            mul_schoolbook(&a, &b, &mut out);
            assert_eq!(out[..la + lb], mul_bits(&a, &b), "{la}×{lb}");
            assert_eq!(out[la + lb], u64::MAX, "writes only |a| + |b| words");
        }
    }

    #[test]
    fn karatsuba_at_threshold_edges() {
        // Lengths 1, T − 1, T, T + 1, 2T ± 1 and far-unbalanced pairs, each way round.
        let t = KARATSUBA_THRESHOLD;
        let lens = [
            1,
            t - 1,
            t,
            t + 1,
            2 * t - 1,
            2 * t,
            2 * t + 1,
            4 * t + 3,
            9 * t,
        ];
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for &la in &lens {
            for &lb in &lens {
                let (a, b) = (words(la, &mut rng), words(lb, &mut rng));
                let mut expected = vec![0; la + lb];
                mul_schoolbook(&a, &b, &mut expected);
                assert_eq!(mul(&a, &b), expected, "{la}×{lb}");
            }
        }
        // Deep recursions, balanced, 3:2 (as in the Toeplitz hash) and 3:1.
        for (la, lb) in [(1000, 999), (1500, 1000), (999, 333)] {
            let (a, b) = (words(la, &mut rng), words(lb, &mut rng));
            let mut expected = vec![0; la + lb];
            mul_schoolbook(&a, &b, &mut expected);
            assert_eq!(mul(&a, &b), expected, "{la}×{lb}");
        }
        // All-ones factors: every partial product is nonzero.
        let ones = vec![u64::MAX; 3 * t + 1];
        let mut expected = vec![0; 2 * ones.len()];
        mul_schoolbook(&ones, &ones, &mut expected);
        assert_eq!(mul(&ones, &ones), expected);
        assert_eq!(mul(&[], &ones), vec![0; ones.len()]);
    }
}
