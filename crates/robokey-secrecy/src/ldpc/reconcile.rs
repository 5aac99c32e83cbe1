//! One block reconciled in memory: the robot's syndrome, the controller's decoding, the leak.

use serde::{Deserialize, Serialize};

use super::{
    BlockCode, CODE_VERSION, LdpcError, MAX_ITERATIONS, SyndromeDecoder, bhattacharyya,
    syndrome_length,
};
use crate::bitstring::BitString;

/// What both sides agree on for LDPC reconciliation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LdpcSettings {
    /// Design efficiency f ∈ [1, 10] of long blocks: the first round's syndrome has
    /// m = ⌈f · H + c · √H⌉ bits for the soft limit H = H(X|L) ([`syndrome_length`]).
    pub efficiency: f64,
    /// The finite-length term c ∈ [0, 100] of m = ⌈f · H + c · √H⌉: belief propagation's
    /// gap to its threshold shrinks as 1/√H (a code of fewer checks needs a larger share).
    /// Settings written before it existed read as 0 (m = ⌈f · H⌉, as they ran).
    #[serde(default)]
    pub finite_length: f64,
    /// Belief-propagation iterations at most (1..=1000) in the last round's decoding.
    pub max_iterations: u32,
    /// Belief-propagation iterations at most (1..=`max_iterations`) in a round after which
    /// a feedback round is still allowed: a decoding that has not met the syndrome by then
    /// rarely does, and the next round's checks help it more than more iterations. Settings
    /// written before it existed read as 200, what every round ran then.
    #[serde(default = "LdpcSettings::earlier_round_iterations")]
    pub round_iterations: u32,
    /// Feedback rounds at most (0..=[`MAX_FEEDBACK_ROUNDS`]): after a failed decoding the
    /// controller asks for [`Self::round_bits`] more syndrome bits and decodes again.
    pub feedback_rounds: u32,
    /// Each feedback round's syndrome bits as a share of the first round's m, in (0, 1]:
    /// a round sends ⌈max(increment · m, increment_root · √m)⌉ ([`Self::round_bits`]).
    pub increment: f64,
    /// The least feedback round in units of √m, in [0, 100]: the spread of the syndrome a
    /// block needs shrinks as 1/√m in share of m, so short codes take larger steps. Settings
    /// written before it existed read as 0 (rounds of ⌈increment · m⌉, as they ran).
    #[serde(default)]
    pub increment_root: f64,
}

/// Largest number of feedback rounds.
pub const MAX_FEEDBACK_ROUNDS: u32 = 8;

impl LdpcSettings {
    /// m = ⌈1.09 · H + 2 · √H⌉ (f = 1.2 at H ≈ 330 bits, a 10⁴-bit block at the default
    /// world; 1.11 at H ≈ 10⁴), 200 iterations, up to 8 feedback rounds of 0.04·m bits.
    /// f and c were read off the first code's block failure rate against f at H from 310 to
    /// 35,000 bits (seed 1 of the `reconciliation_table` example; docs/postprocessing.md):
    /// about half the blocks decode at the first round, the rounds' split checks catch the
    /// rest in small steps.
    pub const DEFAULT: Self = Self {
        efficiency: 1.09,
        finite_length: 2.0,
        max_iterations: 200,
        round_iterations: 50,
        feedback_rounds: 8,
        increment: 0.04,
        increment_root: 2.0,
    };

    /// The syndrome bits of each feedback round after a first round of m:
    /// ⌈max(increment · m, increment_root · √m)⌉, at least 1.
    #[must_use]
    pub fn round_bits(&self, syndrome: usize) -> usize {
        let m = syndrome as f64;
        ((self.increment * m)
            .max(self.increment_root * m.sqrt())
            .ceil() as usize)
            .max(1)
    }

    /// What every round's decoding ran before [`Self::round_iterations`] existed.
    fn earlier_round_iterations() -> u32 {
        200
    }

    /// The iteration cap of round `round` (1 for the first): [`Self::round_iterations`]
    /// while a feedback round is left, [`Self::max_iterations`] in the last.
    #[must_use]
    pub fn iterations_in_round(&self, round: u32) -> u32 {
        if round <= self.feedback_rounds {
            self.round_iterations
        } else {
            self.max_iterations
        }
    }

    /// The settings as the agreement term `ldpc.code` names them: the construction's
    /// version ([`CODE_VERSION`]) and every parameter either side uses, so two binaries that
    /// would build or size codes differently refuse each other at the handshake.
    #[must_use]
    pub fn agreement_term(&self) -> String {
        format!(
            "v{CODE_VERSION}, syndrome {}·H + {}·√H, {} iterations ({} before a \
             feedback round), {} rounds of max({}·m, {}·√m)",
            self.efficiency,
            self.finite_length,
            self.max_iterations,
            self.round_iterations,
            self.feedback_rounds,
            self.increment,
            self.increment_root
        )
    }

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

    /// Checks the syndrome length's, the iterations' and the feedback's ranges.
    ///
    /// # Errors
    /// [`LdpcError::Efficiency`], [`LdpcError::FiniteLength`], [`LdpcError::Iterations`],
    /// [`LdpcError::Feedback`].
    pub fn check(&self) -> Result<(), LdpcError> {
        if self.max_iterations == 0 || self.max_iterations > MAX_ITERATIONS {
            return Err(LdpcError::Iterations(self.max_iterations));
        }
        if self.round_iterations == 0 || self.round_iterations > self.max_iterations {
            return Err(LdpcError::RoundIterations {
                round: self.round_iterations,
                last: self.max_iterations,
            });
        }
        if !(1.0..=10.0).contains(&self.efficiency) {
            return Err(LdpcError::Efficiency(self.efficiency));
        }
        if !(0.0..=100.0).contains(&self.finite_length) {
            return Err(LdpcError::FiniteLength(self.finite_length));
        }
        if self.feedback_rounds > MAX_FEEDBACK_ROUNDS
            || !(self.increment > 0.0 && self.increment <= 1.0)
            || !(0.0..=100.0).contains(&self.increment_root)
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
/// decoding) splits [`LdpcSettings::round_bits`] checks of largest degree ([`BlockCode::extend`]), sends
/// the parities of their new halves, and decodes the split code afresh; each round's
/// decoding runs at most [`LdpcSettings::iterations_in_round`] iterations.
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
    let m = syndrome_length(llrs, settings.efficiency, settings.finite_length)?;
    let mut codes = BlockCode::first(n, m, bhattacharyya(llrs), seed, &settings)?;
    let mut syndrome = Vec::new();
    let mut iterations = 0;
    let decoded = loop {
        codes.receive(&mut syndrome, &codes.round_syndrome(bits)?)?;
        let decoded = decoder.decode_within(
            codes.code(),
            llrs,
            &BitString::from_bools(&syndrome),
            settings.iterations_in_round(codes.rounds()),
        )?;
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
        let m = syndrome_length(&llrs, 1.4, settings.finite_length).unwrap() as u64;
        // 8 feedback rounds allowed: ⌈log₂ 9⌉ = 4 bits for the count of rounds.
        assert_eq!(out.leak, m + 4);
    }

    /// The default settings' block failure rate on short blocks, seeded: 200 blocks of 2,000
    /// bits through a BSC(5 %) (the example measured 0 of 300 at these settings). The
    /// tolerance comes from the sample size: the test fails only if the failures show, at
    /// confidence 1 − 10⁻³ (one-sided Clopper–Pearson), a rate above 2 %.
    #[test]
    fn short_blocks_rarely_fail_at_the_default_settings() {
        let blocks = 200;
        let failures = (0..blocks)
            .filter(|&k| {
                let (x, llrs, _) = super::super::test_block::bsc_block(2_000, 0.05, 100 + k);
                let seed = [k as u8; 32];
                let out = reconcile(&x, &llrs, LdpcSettings::DEFAULT, seed).unwrap();
                out.corrected != x
            })
            .count() as u64;
        let lower = crate::interval::clopper_pearson_lower(failures, blocks, 1e-3).unwrap();
        assert!(lower <= 0.02, "{failures} of {blocks} blocks failed");
    }

    #[test]
    fn feedback_rounds_add_their_syndrome_bits_and_rescue_a_short_syndrome() {
        let (x, llrs, _) = super::super::test_block::bsc_block(10_000, 0.05, 4);
        // f = 1.0 is below what belief propagation reaches at this length: the first
        // decoding fails; rounds of 0.25·m more bits get through.
        let settings = LdpcSettings {
            efficiency: 1.0,
            finite_length: 0.0,
            feedback_rounds: 8,
            increment: 0.25,
            ..LdpcSettings::DEFAULT
        };
        let out = reconcile(&x, &llrs, settings, [1; 32]).unwrap();
        assert!(out.rounds > 1, "{}", out.rounds);
        assert!(out.converged);
        assert_eq!(out.corrected, x);
        let m = syndrome_length(&llrs, 1.0, 0.0).unwrap() as u64;
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
    fn short_codes_take_rounds_of_at_least_two_root_m() {
        let settings = LdpcSettings::DEFAULT;
        // m = 372 (10⁴ bits at the default world): 2·√372 = 38.6 > 0.04·372 = 14.9.
        assert_eq!(settings.round_bits(372), 39);
        // m = 3,500 (10⁵ bits): 0.04·m = 140 > 2·√3500 = 118.3.
        assert_eq!(settings.round_bits(3_500), 140);
        let bad = LdpcSettings {
            increment_root: -1.0,
            ..LdpcSettings::DEFAULT
        };
        assert!(matches!(bad.check(), Err(LdpcError::Feedback { .. })));
    }

    #[test]
    fn rounds_before_the_last_run_their_own_iteration_cap() {
        let settings = LdpcSettings::DEFAULT;
        assert_eq!(settings.iterations_in_round(1), 50);
        assert_eq!(settings.iterations_in_round(8), 50);
        assert_eq!(settings.iterations_in_round(9), 200);
        for (round_iterations, max_iterations) in [(0, 200), (201, 200), (5, 0), (5, 1_001)] {
            let settings = LdpcSettings {
                round_iterations,
                max_iterations,
                ..LdpcSettings::DEFAULT
            };
            assert!(
                matches!(
                    settings.check(),
                    Err(LdpcError::RoundIterations { .. } | LdpcError::Iterations(_))
                ),
                "{round_iterations} {max_iterations}"
            );
        }
        // Without feedback the only round is the last.
        let none = LdpcSettings {
            feedback_rounds: 0,
            ..LdpcSettings::DEFAULT
        };
        assert_eq!(none.iterations_in_round(1), 200);
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
