//! One block reconciled in memory: the robot's syndrome, the controller's decoding, the leak.

use serde::{Deserialize, Serialize};

use super::{LdpcError, ParityCheck, SyndromeDecoder, bhattacharyya, syndrome_length};
use crate::bitstring::BitString;

/// What both sides agree on for LDPC reconciliation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LdpcSettings {
    /// Design efficiency f ∈ [1, 10]: m = ⌈f · H(X|L)⌉ syndrome bits.
    pub efficiency: f64,
    /// Belief-propagation iterations at most (1..=1000).
    pub max_iterations: u32,
}

impl LdpcSettings {
    /// f = 1.2, 200 iterations.
    pub const DEFAULT: Self = Self {
        efficiency: 1.2,
        max_iterations: 200,
    };
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
    /// leak_EC: the syndrome bits m (one round, nothing revealed).
    pub leak: u64,
    /// Whether the decoder met the syndrome.
    pub converged: bool,
    /// Belief-propagation iterations run.
    pub iterations: u32,
}

/// Reconciles the controller's view (`llrs`, Lᵢ = ln P(xᵢ = 0)/P(xᵢ = 1)) with the robot's
/// `bits` through the code from the public `seed`, in memory.
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
    let decoder = SyndromeDecoder::new(settings.max_iterations)?;
    let m = syndrome_length(llrs, settings.efficiency)?;
    let code = ParityCheck::build(bits.len(), m, bhattacharyya(llrs), seed)?;
    let syndrome = code.syndrome(bits)?;
    let decoded = decoder.decode(&code, llrs, &syndrome)?;
    Ok(LdpcReconciliation {
        corrected: decoded.bits,
        leak: m as u64,
        converged: decoded.converged,
        iterations: decoded.iterations,
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
            max_iterations: 200,
        };
        let out = reconcile(&x, &llrs, settings, [9; 32]).unwrap();
        assert!(out.converged);
        assert_eq!(out.corrected, x);
        let m = syndrome_length(&llrs, 1.4).unwrap() as u64;
        assert_eq!(out.leak, m);
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
