//! One block reconciled in memory: the robot's syndrome, the controller's decoding, the leak.

use serde::{Deserialize, Serialize};

use super::{BlockCode, LdpcError, SyndromeDecoder, bhattacharyya, syndrome_length};
use crate::bitstring::BitString;

/// What both sides agree on for LDPC reconciliation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LdpcSettings {
    /// Design efficiency f ∈ [1, 10]: m = ⌈f · H(X|L)⌉ syndrome bits.
    pub efficiency: f64,
    /// Belief-propagation iterations at most (1..=1000), per decoding.
    pub max_iterations: u32,
    /// Feedback rounds at most (0..=[`MAX_FEEDBACK_ROUNDS`]): after a failed decoding the
    /// controller asks for ⌈increment · m⌉ more syndrome bits and decodes again.
    pub feedback_rounds: u32,
    /// Each feedback round's syndrome bits as a share of the first round's m, in (0, 1].
    pub increment: f64,
}

/// Largest number of feedback rounds.
pub const MAX_FEEDBACK_ROUNDS: u32 = 8;

impl LdpcSettings {
    /// f = 1.2, 200 iterations, up to 8 feedback rounds of 0.08·m bits. At 10⁴ bits the
    /// first code's f = 1.2 fails in about 40 % of blocks (finite length); rounds of smaller
    /// increments, split from the code's checks, bring the failure rate below 1 % for a mean
    /// f_soft ≈ 1.28 (docs/postprocessing.md), and cost 2 bits more for the round count.
    pub const DEFAULT: Self = Self {
        efficiency: 1.2,
        max_iterations: 200,
        feedback_rounds: 8,
        increment: 0.08,
    };

    /// The bits charged for the number of rounds used, which the feedback publishes:
    /// ⌈log₂(feedback_rounds + 1)⌉, whatever the number used.
    #[must_use]
    pub fn round_count_bits(&self) -> u64 {
        u64::from(
            (self.feedback_rounds + 1)
                .next_power_of_two()
                .trailing_zeros(),
        )
    }

    /// Checks the feedback's ranges.
    ///
    /// # Errors
    /// [`LdpcError::Feedback`].
    pub fn check(&self) -> Result<(), LdpcError> {
        if self.feedback_rounds > MAX_FEEDBACK_ROUNDS
            || !(self.increment > 0.0 && self.increment <= 1.0)
        {
            return Err(LdpcError::Feedback {
                rounds: self.feedback_rounds,
                increment: self.increment,
            });
        }
        Ok(())
    }
}

impl Default for LdpcSettings {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Outcome of one LDPC reconciliation.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LdpcReconciliation {
    /// The controller's bits after decoding (the robot's unless decoding failed or found
    /// another word with the same syndrome: the tags tell).
    pub corrected: BitString,
    /// leak_EC: every syndrome bit sent, over all rounds, plus
    /// [`LdpcSettings::round_count_bits`] for the number of rounds (nothing is revealed).
    pub leak: u64,
    /// Syndrome bits sent, over all rounds.
    pub syndrome_bits: u64,
    /// Rounds used (1 without feedback).
    pub rounds: u32,
    /// Whether the decoder met the syndrome.
    pub converged: bool,
    /// Belief-propagation iterations run, over all rounds.
    pub iterations: u32,
}

/// Reconciles the controller's view (`llrs`, Lᵢ = ln P(xᵢ = 0)/P(xᵢ = 1)) with the robot's
/// `bits` through the code from the public `seed`, in memory. Round r > 1 (after a failed
/// decoding) splits ⌈increment · m⌉ checks of largest degree ([`BlockCode::extend`]), sends
/// the parities of their new halves, and decodes the split code afresh.
pub fn reconcile(
    bits: &BitString,
    llrs: &[f64],
    settings: LdpcSettings,
    seed: [u8; 32],
) -> Result<LdpcReconciliation, LdpcError> {
    if bits.len() != llrs.len() {
        return Err(LdpcError::Length {
            what: "LLRs",
            got: llrs.len(),
            expected: bits.len(),
        });
    }
    settings.check()?;
    let decoder = SyndromeDecoder::new(settings.max_iterations)?;
    let n = bits.len();
    let m = syndrome_length(llrs, settings.efficiency)?;
    let mut codes = BlockCode::first(n, m, bhattacharyya(llrs), seed, &settings)?;
    let mut syndrome = Vec::new();
    let mut iterations = 0;
    let decoded = loop {
        codes.receive(&mut syndrome, &codes.round_syndrome(bits)?)?;
        let decoded = decoder.decode(codes.code(), llrs, &BitString::from_bools(&syndrome))?;
        iterations += decoded.iterations;
        if decoded.converged || !codes.extend() {
            break decoded;
        }
    };
    let syndrome_bits = codes.code().syndrome_bits() as u64;
    Ok(LdpcReconciliation {
        corrected: decoded.bits,
        leak: syndrome_bits + settings.round_count_bits(),
        syndrome_bits,
        rounds: codes.rounds(),
        converged: decoded.converged,
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bsc_block_is_reconciled_and_the_leak_is_the_syndrome() {
        let (x, llrs, _) = super::super::test_block::bsc_block(10_000, 0.02, 3);
        let settings = LdpcSettings {
            efficiency: 1.4,
            ..LdpcSettings::DEFAULT
        };
        let out = reconcile(&x, &llrs, settings, [9; 32]).unwrap();
        assert!(out.converged);
        assert_eq!(out.corrected, x);
        assert_eq!(out.rounds, 1);
        let m = syndrome_length(&llrs, 1.4).unwrap() as u64;
        // 8 feedback rounds allowed: ⌈log₂ 9⌉ = 4 bits for the count of rounds.
        assert_eq!(out.leak, m + 4);
    }

    #[test]
    fn feedback_rounds_add_their_syndrome_bits_and_rescue_a_short_syndrome() {
        let (x, llrs, _) = super::super::test_block::bsc_block(10_000, 0.05, 4);
        // f = 1.0 is below what belief propagation reaches at this length: the first
        // decoding fails; rounds of 0.25·m more bits get through.
        let settings = LdpcSettings {
            efficiency: 1.0,
            feedback_rounds: 8,
            increment: 0.25,
            ..LdpcSettings::DEFAULT
        };
        let out = reconcile(&x, &llrs, settings, [1; 32]).unwrap();
        assert!(out.rounds > 1, "{}", out.rounds);
        assert!(out.converged);
        assert_eq!(out.corrected, x);
        let m = syndrome_length(&llrs, 1.0).unwrap() as u64;
        let increment = (0.25 * m as f64).ceil() as u64;
        assert_eq!(out.syndrome_bits, m + u64::from(out.rounds - 1) * increment);
        assert_eq!(out.leak, out.syndrome_bits + 4);
    }

    #[test]
    fn feedback_settings_out_of_range_are_refused() {
        let (x, llrs, _) = super::super::test_block::bsc_block(100, 0.05, 4);
        for (rounds, increment) in [(9, 0.1), (1, 0.0), (1, 1.5), (1, f64::NAN)] {
            let settings = LdpcSettings {
                feedback_rounds: rounds,
                increment,
                ..LdpcSettings::DEFAULT
            };
            assert!(matches!(
                reconcile(&x, &llrs, settings, [0; 32]),
                Err(LdpcError::Feedback { .. })
            ));
        }
        let none = LdpcSettings {
            feedback_rounds: 0,
            ..LdpcSettings::DEFAULT
        };
        assert_eq!(none.round_count_bits(), 0);
    }

    #[test]
    fn mismatched_lengths_are_refused() {
        assert!(matches!(
            reconcile(
                &BitString::zeros(5),
                &[1.0; 4],
                LdpcSettings::DEFAULT,
                [0; 32]
            ),
            Err(LdpcError::Length { .. })
        ));
    }
}
