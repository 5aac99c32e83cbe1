//! A block's public randomness: the disclosed sample, Cascade's permutations and the Toeplitz
//! seed, all expanded from one 256-bit seed that both nonces enter, so neither side alone
//! chooses them and no datagram has to carry a 10⁶-bit Toeplitz seed.
//!
//! seed = SHA-256("robokey/post-processing/v1" ‖ block ‖ |sessions| ‖ sessions ‖ nonce_c ‖
//! nonce_r); each use reads its own stream of the ChaCha20 generator keyed by the seed
//! (stream 0: sample, 1: Cascade, 2: Toeplitz, 3: the LDPC code's seed). The Toeplitz matrix is thus drawn by a
//! cryptographic PRG from a uniform 256-bit seed rather than uniformly: the leftover hash
//! lemma holds for it as long as ChaCha20 is indistinguishable from random (docs/secrecy.md).

use rand::SeedableRng;
use rand::rngs::ChaCha20Rng;
use sha2::{Digest, Sha256};

use crate::toeplitz::{ToeplitzError, ToeplitzHash};

/// The public randomness of one block.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PublicRandomness {
    seed: [u8; 32],
}

impl PublicRandomness {
    /// The randomness of `block` over `sessions` with the controller's and the robot's nonces.
    #[must_use]
    pub fn new(block: u64, sessions: &[u32], nonces: &[[u8; 32]; 2]) -> Self {
        let mut hash = Sha256::new();
        hash.update(b"robokey/post-processing/v1");
        hash.update(block.to_be_bytes());
        hash.update((sessions.len() as u64).to_be_bytes());
        for id in sessions {
            hash.update(id.to_be_bytes());
        }
        for nonce in nonces {
            hash.update(nonce);
        }
        Self {
            seed: hash.finalize().into(),
        }
    }

    fn stream(&self, stream: u64) -> ChaCha20Rng {
        let mut rng = ChaCha20Rng::from_seed(self.seed);
        rng.set_stream(stream);
        rng
    }

    /// Which of `n` positions are disclosed: a uniform subset of [`sample_size`] of them.
    #[must_use]
    pub fn sample(&self, n: usize, most: usize) -> Vec<bool> {
        let size = sample_size(n, most);
        let mut disclosed = vec![false; n];
        for i in rand::seq::index::sample(&mut self.stream(0), n, size) {
            disclosed[i] = true;
        }
        disclosed
    }

    /// The generator of Cascade's permutations (both sides draw the same).
    #[must_use]
    pub fn cascade(&self) -> ChaCha20Rng {
        self.stream(1)
    }

    /// The 256-bit seed of the block's LDPC code (its feedback rounds split that code's checks).
    #[must_use]
    pub fn ldpc(&self) -> [u8; 32] {
        let mut seed = [0_u8; 32];
        rand::Rng::fill_bytes(&mut self.stream(3), &mut seed);
        seed
    }

    /// The Toeplitz hash from `n` to `length` bits.
    ///
    /// # Errors
    /// [`ToeplitzError`] for lengths the hash cannot have.
    pub fn toeplitz(&self, n: usize, length: usize) -> Result<ToeplitzHash, ToeplitzError> {
        ToeplitzHash::random(n, length, &mut self.stream(2))
    }
}

/// How many of `n` positions a block's sample discloses: min(`most`, ⌊n/10⌋).
#[must_use]
pub fn sample_size(n: usize, most: usize) -> usize {
    most.min(n / 10)
}
