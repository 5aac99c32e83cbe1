//! Test blocks: random bits and the LLRs of a binary symmetric channel's view of them.

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};

use crate::bitstring::BitString;

/// n random bits (seeded by `seed`), LLRs ±ln((1 − q)/q) of their copy through a BSC(q), and
/// the number of bits the copy has wrong.
pub(super) fn bsc_block(n: usize, q: f64, seed: u64) -> (BitString, Vec<f64>, usize) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let bits = BitString::random(n, &mut rng);
    let l = ((1.0 - q) / q).ln();
    let mut errors = 0;
    let llrs = (0..n)
        .map(|i| {
            let flipped = rng.random::<f64>() < q;
            errors += usize::from(flipped);
            if bits.get(i).unwrap_or(false) ^ flipped {
                -l
            } else {
                l
            }
        })
        .collect();
    (bits, llrs, errors)
}
