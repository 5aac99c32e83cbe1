//! The post-processing messages. Every message names its block, so a stale or duplicated one
//! is recognised and never changes state.

use serde::{Deserialize, Serialize};

use crate::cascade::BlockQuery;

/// Why the controller ends a block without a key.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum AbortReason {
    /// ℓ = 0 under the stated assumption.
    NoSecretBits,
    /// Reconciliation failed or left the keys different (the tags differ).
    Reconciliation,
    /// The controller restarted before committing.
    Restart,
    /// The robot refused the block.
    Refused,
    /// The block's estimate of the plant refused it (measured sizing: a test of the model
    /// class failed, or the worst case leaves no bound), or its commands check did (either
    /// sizing); nothing is committed.
    PlantRefused,
}

/// Why the robot refuses a message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum RejectReason {
    /// It knows nothing of this block (it restarted).
    UnknownBlock,
    /// The controller's tag does not match its key.
    TagMismatch,
    /// The proposed ℓ is not what the assumption gives.
    LengthMismatch,
    /// It is still prepared for another block.
    Busy,
    /// The questions are not ones an honest controller asks.
    BadQuestions,
}

/// A post-processing message.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum Message {
    /// Controller → robot: pool these sessions, in this order, as block `block`.
    Propose {
        /// Block number (increasing).
        block: u64,
        /// Session IDs.
        sessions: Vec<u32>,
        /// The controller's fresh nonce.
        nonce: [u8; 32],
        /// The largest separation of Eve's view over the proposed sessions' bits, in
        /// millionths, rounded up (0 unless the assumption is [`Assumption::GaussianViews`],
        /// whose statement the controller evaluates on its own samples).
        ///
        /// [`Assumption::GaussianViews`]: super::Assumption::GaussianViews
        separation_micros: u64,
    },
    /// Robot → controller: the proposed sessions it holds, in the proposed order.
    Agree {
        /// Block number.
        block: u64,
        /// Session IDs it holds.
        sessions: Vec<u32>,
        /// The robot's fresh nonce.
        nonce: [u8; 32],
        /// Its bits at the sample positions, in order.
        sample: Vec<bool>,
    },
    /// Controller → robot: Cascade questions.
    Ask {
        /// Block number.
        block: u64,
        /// Round number (1, 2, …).
        round: u32,
        /// The questions.
        queries: Vec<BlockQuery>,
    },
    /// Robot → controller: its parities, in the order asked.
    Answer {
        /// Block number.
        block: u64,
        /// Round answered.
        round: u32,
        /// The parities.
        parities: Vec<bool>,
    },
    /// Controller → robot: reconciliation is over; ℓ and the controller's tag.
    Confirm {
        /// Block number.
        block: u64,
        /// Final key length ℓ (> 0).
        length: u64,
        /// Tag over the controller's reconciled key.
        tag: [u8; 8],
        /// With the plant measured: the block's worst-case separation in steps of
        /// [`super::SEPARATION_QUANTUM`] (at most [`super::MAX_SEPARATION_STEPS`]), from
        /// which the robot recomputes ℓ; absent with the configured plant.
        estimate: Option<u32>,
    },
    /// Robot → controller: its tag; it has prepared the key.
    Confirmed {
        /// Block number.
        block: u64,
        /// Tag over the robot's key.
        tag: [u8; 8],
    },
    /// Controller → robot: the controller committed the key; commit it too.
    Commit {
        /// Block number.
        block: u64,
    },
    /// Robot → controller: committed.
    CommitAck {
        /// Block number.
        block: u64,
    },
    /// Controller → robot: the block ends without key; drop these sessions.
    Abort {
        /// Block number.
        block: u64,
        /// Sessions spent.
        sessions: Vec<u32>,
        /// Why.
        reason: AbortReason,
    },
    /// Robot → controller: aborted.
    AbortAck {
        /// Block number.
        block: u64,
    },
    /// Robot → controller: refused.
    Reject {
        /// Block number.
        block: u64,
        /// Why.
        reason: RejectReason,
    },
    /// Controller → robot (LDPC reconciliation): send the syndrome of round `round` of the
    /// code both sides build from the block's public randomness, m and B.
    SyndromeAsk {
        /// Block number.
        block: u64,
        /// Round (1, then one per feedback round, at most 1 + the feedback rounds agreed).
        round: u32,
        /// The first round's syndrome bits m (1..=n), repeated in every round.
        syndrome_bits: u32,
        /// The channel's Bhattacharyya parameter B in 1024ths (1..=1024), repeated in every
        /// round.
        bhattacharyya: u16,
    },
    /// Robot → controller (LDPC reconciliation): the syndrome bits of the round's new checks,
    /// in check order.
    Syndrome {
        /// Block number.
        block: u64,
        /// Round answered.
        round: u32,
        /// The syndrome bits.
        syndrome: Vec<bool>,
    },
}

impl Message {
    /// The block the message is about.
    #[must_use]
    pub fn block(&self) -> u64 {
        match self {
            Self::Propose { block, .. }
            | Self::Agree { block, .. }
            | Self::Ask { block, .. }
            | Self::Answer { block, .. }
            | Self::Confirm { block, .. }
            | Self::Confirmed { block, .. }
            | Self::Commit { block }
            | Self::CommitAck { block }
            | Self::Abort { block, .. }
            | Self::AbortAck { block }
            | Self::Reject { block, .. }
            | Self::SyndromeAsk { block, .. }
            | Self::Syndrome { block, .. } => *block,
        }
    }

    /// Payload bits: the fields as they would be encoded (u64 64, u32 32, bool 1, nonce 256,
    /// tag 64, a reason 8, a list's length 32, a present optional field its own, u16 16),
    /// before framing.
    #[must_use]
    pub fn payload_bits(&self) -> u64 {
        let list = |items: usize, each: u64| 32 + items as u64 * each;
        64 + match self {
            Self::Propose { sessions, .. } => list(sessions.len(), 32) + 256 + 64,
            Self::Agree {
                sessions, sample, ..
            } => list(sessions.len(), 32) + 256 + list(sample.len(), 1),
            Self::Ask { queries, .. } => 32 + list(queries.len(), 96),
            Self::Answer { parities, .. } => 32 + list(parities.len(), 1),
            Self::Confirm { estimate, .. } => 64 + 64 + 32 * u64::from(estimate.is_some()),
            Self::Confirmed { .. } => 64,
            Self::Commit { .. } | Self::CommitAck { .. } | Self::AbortAck { .. } => 0,
            Self::Abort { sessions, .. } => list(sessions.len(), 32) + 8,
            Self::Reject { .. } => 8,
            Self::SyndromeAsk { .. } => 32 + 32 + 16,
            Self::Syndrome { syndrome, .. } => 32 + list(syndrome.len(), 1),
        }
    }
}
