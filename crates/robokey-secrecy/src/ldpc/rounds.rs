//! The codes of one block's rounds, as both sides build them from public data alone: the
//! first code from (n, m, B, seed), and after each failed decoding ⌈increment · m⌉ further
//! checks of the first code's mean check degree, each from the next 256-bit seed of the
//! public `seed`'s ChaCha8 stream, stacked under it.

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};

use super::{LdpcError, LdpcSettings, ParityCheck};

/// The stacked code of a block after the rounds so far.
#[derive(Debug)]
pub struct BlockCode {
    code: ParityCheck,
    check_degree: usize,
    increment: usize,
    seeds: ChaCha8Rng,
    rounds: u32,
    feedback_rounds: u32,
}

impl BlockCode {
    /// Round 1: the code of `syndrome` checks on `block` bits for a channel with
    /// Bhattacharyya parameter `bhattacharyya`, from the public `seed`.
    ///
    /// # Errors
    /// Sizes out of bounds or `settings` out of range ([`LdpcError`]).
    pub fn first(
        block: usize,
        syndrome: usize,
        bhattacharyya: f64,
        seed: [u8; 32],
        settings: &LdpcSettings,
    ) -> Result<Self, LdpcError> {
        settings.check()?;
        let code = ParityCheck::build(block, syndrome, bhattacharyya, seed)?;
        Ok(Self {
            check_degree: code.edges().div_ceil(syndrome),
            increment: ((settings.increment * syndrome as f64).ceil() as usize).max(1),
            seeds: ChaCha8Rng::from_seed(seed),
            rounds: 1,
            feedback_rounds: settings.feedback_rounds,
            code,
        })
    }

    /// The code after the rounds so far.
    #[must_use]
    pub fn code(&self) -> &ParityCheck {
        &self.code
    }

    /// Rounds so far (1 before any feedback).
    #[must_use]
    pub fn rounds(&self) -> u32 {
        self.rounds
    }

    /// Stacks the next feedback round's checks; `false` (nothing changes) when the rounds
    /// are used up or every bit is already checked (m = n).
    ///
    /// # Errors
    /// [`LdpcError`] from the extension's construction.
    pub fn extend(&mut self) -> Result<bool, LdpcError> {
        if self.rounds > self.feedback_rounds {
            return Ok(false);
        }
        let n = self.code.block();
        let extra = self.increment.min(n - self.code.syndrome_bits());
        if extra == 0 {
            return Ok(false);
        }
        let extension = ParityCheck::extension(n, extra, self.check_degree, self.seeds.random())?;
        self.code = self.code.stacked(&extension)?;
        self.rounds += 1;
        Ok(true)
    }
}
