//! One-way reconciliation by LDPC syndromes, decoded by belief propagation on the controller's
//! calibrated log-likelihood ratios, with an exactly counted leak.
//!
//! The robot (the bits' owner) holds x ∈ {0,1}ⁿ; the controller holds, per bit, the LLR
//! Lᵢ = ln P(xᵢ = 0 | yᵢ) / P(xᵢ = 1 | yᵢ). For a block the controller picks the syndrome
//! length m = ⌈f · H + c · √H⌉ for its soft limit H = H(X|L) = Σᵢ h₂(1/(1 + e^{|Lᵢ|})), a
//! design efficiency f and a finite-length term c ([`syndrome_length`]), and the channel's
//! Bhattacharyya parameter B ([`bhattacharyya`]); both sides build the same sparse
//! parity-check matrix H (m × n) from m, B and a public seed ([`ParityCheck::build`]), so
//! the code is fitted to the block's rate and channel; the robot sends s = H·x; the
//! controller finds x̂ with H·x̂ = s by log-domain sum-product belief propagation
//! ([`SyndromeDecoder`], capped iterations). The block tags then verify x̂ = x.
//!
//! If decoding fails (the syndrome is not met within the iteration cap), the controller may ask
//! for ⌈max(increment · m, increment_root · √m)⌉ more syndrome bits, up to [`LdpcSettings::feedback_rounds`] times: both
//! sides split that many checks of largest degree in two ([`ParityCheck::split`]), the robot
//! sends the new halves' parities, and the controller decodes the split code again.
//!
//! **Leak.** The transcript is the public seed, m and B (functions of the controller's LLR
//! magnitudes, not of x), every syndrome bit sent, and the number of rounds used, so
//! H_min^ε(X | E, transcript) ≥ H_min^ε(X | E) − (syndrome bits + ⌈log₂(R + 1)⌉) for at most R
//! feedback rounds; nothing is revealed. A block still undecoded after the last round, or
//! whose tags differ, is discarded like a failed Cascade block.
//!
//! Sizes are bounded before any work: n ≤ [`MAX_BLOCK_BITS`], m ≤ n, iterations ≤
//! [`MAX_ITERATIONS`].

mod code;
mod decoder;
mod degrees;
mod reconcile;
mod rounds;
mod soft_limit;
#[cfg(test)]
mod test_block;

use thiserror::Error;

pub use code::ParityCheck;
pub use decoder::{Decoded, SyndromeDecoder};
pub use degrees::DegreeProfile;
pub use reconcile::{LdpcReconciliation, LdpcSettings, MAX_FEEDBACK_ROUNDS, reconcile};
pub use rounds::BlockCode;
pub use soft_limit::{bhattacharyya, bit_error_probability, soft_limit_bits, syndrome_length};

/// Largest block one LDPC code may cover (bits): 2²².
pub const MAX_BLOCK_BITS: usize = 1 << 22;

/// The version of the code construction ([`ParityCheck::build`], [`ParityCheck::split`],
/// [`DegreeProfile`]): both sides must build the same matrix from the same public data, so
/// it is named in the agreement term ([`LdpcSettings::agreement_term`]); any change to what
/// they build raises it.
pub const CODE_VERSION: u32 = 1;

/// Largest number of belief-propagation iterations a decoder may run.
pub const MAX_ITERATIONS: u32 = 1_000;

/// Errors of LDPC code construction, encoding and decoding.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, Error)]
pub enum LdpcError {
    /// The block is empty or longer than [`MAX_BLOCK_BITS`].
    #[error("LDPC block length {0} bits is outside 1..={MAX_BLOCK_BITS}")]
    BlockLength(usize),
    /// The syndrome length is outside 1..=n.
    #[error("LDPC syndrome length {syndrome} is outside 1..={block} (the block length)")]
    SyndromeLength {
        /// Requested syndrome bits m.
        syndrome: usize,
        /// Block length n.
        block: usize,
    },
    /// The iteration cap is outside 1..=[`MAX_ITERATIONS`].
    #[error("LDPC iterations {0} outside 1..={MAX_ITERATIONS}")]
    Iterations(u32),
    /// The iteration cap of rounds before the last is outside 1..= the last round's.
    #[error(
        "LDPC iterations before a feedback round {round} outside 1..={last} (the last round's)"
    )]
    RoundIterations {
        /// Cap of the rounds before the last.
        round: u32,
        /// Cap of the last round.
        last: u32,
    },
    /// The design efficiency f is not a finite number ≥ 1.
    #[error("LDPC design efficiency {0} must be a finite number in [1, 10]")]
    Efficiency(f64),
    /// A vector's length does not match the code (bits, LLRs or syndrome).
    #[error("LDPC {what} has {got} entries, the code needs {expected}")]
    Length {
        /// Which vector.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The code's.
        expected: usize,
    },
    /// The feedback rounds exceed [`MAX_FEEDBACK_ROUNDS`], the increment is outside (0, 1] or
    /// the least increment outside [0, 100]·√m.
    #[error(
        "LDPC feedback: {rounds} rounds of {increment}·m bits; allowed at most {MAX_FEEDBACK_ROUNDS} rounds, increment in (0, 1], at least [0, 100]·√m"
    )]
    Feedback {
        /// Requested rounds.
        rounds: u32,
        /// Requested increment.
        increment: f64,
    },
    /// The finite-length term c is outside [0, 100].
    #[error("LDPC finite-length term {0} must be a number in [0, 100]")]
    FiniteLength(f64),
    /// An LLR is NaN.
    #[error("LLR at position {0} is NaN")]
    NanLlr(usize),
}
