//! The codes of one block's rounds, as both sides build them from public data alone: the
//! first code from (n, m, B, seed); after each failed decoding, [`LdpcSettings::round_bits`] of the
//! current code's checks of largest degree split in two ([`ParityCheck::split`]). The robot
//! sends the parity of each new half; with the parity already sent for the whole check, the
//! controller knows both parts' parities. Rounds add syndrome bits and lower the check
//! degree, as a code designed for the longer syndrome would have it, instead of stacking
//! unrelated checks over a code that failed.

use super::{LdpcError, LdpcSettings, ParityCheck};
use crate::bitstring::BitString;

/// The code of a block after the rounds so far.
#[derive(Debug)]
pub struct BlockCode {
    code: ParityCheck,
    increment: usize,
    /// The checks split by the last round, in the order of its new halves (empty in round 1).
    split: Vec<u32>,
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
            increment: settings.round_bits(syndrome),
            split: Vec::new(),
            rounds: 1,
            feedback_rounds: settings.feedback_rounds,
            code,
        })
    }

    /// The code after the rounds so far (the one to decode).
    #[must_use]
    pub fn code(&self) -> &ParityCheck {
        &self.code
    }

    /// Rounds so far (1 before any feedback).
    #[must_use]
    pub fn rounds(&self) -> u32 {
        self.rounds
    }

    /// Checks new in this round: all of round 1's, the halves of a feedback round.
    #[must_use]
    pub fn round_checks(&self) -> usize {
        if self.rounds == 1 {
            self.code.syndrome_bits()
        } else {
            self.split.len()
        }
    }

    /// The robot's side: the parities of this round's new checks on its `bits`.
    ///
    /// # Errors
    /// [`LdpcError::Length`] if `bits` is not a block of the code's length.
    pub fn round_syndrome(&self, bits: &BitString) -> Result<Vec<bool>, LdpcError> {
        let syndrome = self.code.syndrome(bits)?;
        let checks = self.code.syndrome_bits();
        Ok((checks - self.round_checks()..checks)
            .map(|c| syndrome.get(c) == Some(true))
            .collect())
    }

    /// The controller's side: appends this round's `received` parities to `syndrome` (the
    /// code's syndrome as of the last round) and turns each split check's parity into its
    /// remainder's, s_rest = s_check ⊕ s_half, so `syndrome` is the current code's.
    ///
    /// # Errors
    /// [`LdpcError::Length`] if `syndrome` or `received` does not fit the round.
    pub fn receive(&self, syndrome: &mut Vec<bool>, received: &[bool]) -> Result<(), LdpcError> {
        let before = self.code.syndrome_bits() - self.round_checks();
        if syndrome.len() != before || received.len() != self.round_checks() {
            return Err(LdpcError::Length {
                what: "round's syndrome",
                got: syndrome.len() + received.len(),
                expected: self.code.syndrome_bits(),
            });
        }
        syndrome.extend_from_slice(received);
        for (k, &check) in self.split.iter().enumerate() {
            syndrome[check as usize] ^= received[k];
        }
        Ok(())
    }

    /// Splits the next feedback round's checks; `false` (nothing changes) when the rounds
    /// are used up or no check has two variables left to split.
    pub fn extend(&mut self) -> bool {
        if self.rounds > self.feedback_rounds {
            return false;
        }
        let (code, split) = self.code.split(self.increment);
        if split.is_empty() {
            return false;
        }
        self.code = code;
        self.split = split;
        self.rounds += 1;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand::rngs::ChaCha8Rng;

    #[test]
    fn the_controller_s_syndrome_follows_the_split_code() {
        let settings = LdpcSettings {
            feedback_rounds: 3,
            increment: 0.3,
            ..LdpcSettings::DEFAULT
        };
        let x = BitString::random(3_000, &mut ChaCha8Rng::seed_from_u64(2));
        let mut codes = BlockCode::first(3_000, 200, 0.2, [3; 32], &settings).unwrap();
        let mut syndrome = Vec::new();
        let mut sent = 0;
        loop {
            let round = codes.round_syndrome(&x).unwrap();
            sent += round.len();
            codes.receive(&mut syndrome, &round).unwrap();
            assert_eq!(
                BitString::from_bools(&syndrome),
                codes.code().syndrome(&x).unwrap()
            );
            assert!(codes.receive(&mut syndrome.clone(), &round).is_err());
            if !codes.extend() {
                break;
            }
        }
        assert_eq!(codes.rounds(), 4);
        assert_eq!(sent, 200 + 3 * 60);
        assert_eq!(codes.code().syndrome_bits(), sent);
    }
}
