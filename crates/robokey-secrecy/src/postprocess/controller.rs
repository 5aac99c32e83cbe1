//! The controller's post-processing endpoint: it pools its (noisy) session bits, proposes
//! blocks, corrects its bits by Cascade or by decoding the robot's LDPC syndromes on its
//! LLRs, and coordinates the two-phase commit.

use std::collections::{BTreeMap, VecDeque};

use rand::rngs::ChaCha20Rng;
use serde::{Deserialize, Serialize};

use super::estimate::{
    EstimateOutcome, EstimateRefusal, EstimateRequest, LlrAnswer, LlrRequest, MAX_SEPARATION_STEPS,
    SessionSamples,
};
use super::ledger::Ledger;
use super::public::{PublicRandomness, sample_size};
use super::syndromes::{DecodingStep, Reconciled, SyndromeDecoding};
use super::{
    AbortReason, Assumption, BlockReport, CONTROLLER_TO_ROBOT, FinalKey, KeyReconciliation,
    LlrProvenance, MAX_BLOCK_SESSIONS, Message, Output, Pool, PostError, ROBOT_TO_CONTROLLER,
    ReconciledSlices, ReconciliationMethod, RejectReason, Settings, SliceInput,
    SlicesEstimateRequest, StagedSession, concatenate, dequantise_llr, key_id, quantise_llr,
    split_sample, tag_context,
};
use crate::bitstring::BitString;
use crate::cascade::{BlockQuery, Cascade, CascadeBob, CascadeStep};
use crate::confirm::ConfirmationTag;
use crate::view_profile::{equivalent_separation, separation_counts};

/// What the controller feeds its endpoint.
#[derive(Debug, Clone)]
pub enum ControllerInput {
    /// The raw bits of a session both sides completed.
    Session {
        /// Session ID.
        id: u32,
        /// The controller's bits (decisions) of the session.
        bits: BitString,
        /// The separation of Eve's view of each bit under a Gaussian-views assumption, as the
        /// controller computes it from public data or its own samples (empty: 0 for every
        /// bit). A list longer than the bits counts its largest `bits.len()` (a list of every
        /// decided doublet's bits errs safe); a shorter one gives the bits it lacks its
        /// largest.
        separations: Vec<f64>,
        /// What the pool keeps of the session for the block's estimate of the plant
        /// (measured sizing) or its commands check (configured; empty: not checked).
        samples: SessionSamples,
        /// The controller's calibrated LLR of each bit, Lᵢ = ln P(xᵢ = 0)/P(xᵢ = 1) (nats;
        /// the bit is 1 when negative), one per bit, or empty when it has none (odometry).
        /// LDPC reconciliation needs them; the pool keeps them quantised
        /// ([`quantise_llr`]).
        llrs: Vec<f64>,
    },
    /// Slice 0 of a multilevel session (docs/postprocessing.md, "Multilevel slices"), pooled
    /// under the session's ID with its staged material.
    StagedSession(SliceInput),
    /// The shell's answer to [`Output::SliceReconciled`] for `block`: its sessions' next
    /// slices, which form the next block (whatever their bits), in order.
    NextSlices {
        /// The block reconciled.
        block: u64,
        /// The next slices.
        slices: Vec<SliceInput>,
    },
    /// The shell's answer to [`Output::SlicesEstimateNeeded`] for `block` (the last slice's):
    /// each slice's published outcome, slice 0 first — its separation in grid steps (measured
    /// sizing; any value under configured sizing), or a refusal, which refuses the block.
    SliceEstimates {
        /// The last slice's block number.
        block: u64,
        /// One outcome per slice.
        outcomes: Vec<EstimateOutcome>,
    },
    /// The shell's answer to [`Output::LlrsNeeded`] for `block`: the LLR of each of the
    /// block's raw bits, in block order, with the model they were recomputed with; or why
    /// LDPC decodes on the LLRs pooled with the sessions (the prior's). Either goes into the
    /// block's report.
    Llrs {
        /// Block number.
        block: u64,
        /// The recomputed LLRs, or why the prior's stay.
        llrs: LlrAnswer,
    },
    /// The shell's answer to [`Output::EstimateNeeded`] for `block`.
    Estimate {
        /// Block number.
        block: u64,
        /// The published outcome: the block's separation in grid steps, or a refusal.
        outcome: EstimateOutcome,
    },
    /// A message from the robot.
    Frame(Message),
    /// The retransmission timer fired: repeat the last request.
    Timeout,
}

/// A block the durable state must remember across a crash.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum InFlight {
    /// Proposed, not committed: aborted on recovery.
    Started {
        /// Block number.
        block: u64,
        /// Sessions proposed.
        sessions: Vec<u32>,
    },
    /// Committed here; the robot's `CommitAck` is outstanding.
    Committed {
        /// Block number.
        block: u64,
        /// Sessions proposed.
        sessions: Vec<u32>,
    },
    /// Being aborted.
    Aborting {
        /// Block number.
        block: u64,
        /// Sessions proposed.
        sessions: Vec<u32>,
        /// Why.
        reason: AbortReason,
    },
}

/// The controller's durable state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ControllerSnapshot {
    /// The next block number.
    pub next_block: u64,
    /// Sessions pooled and not yet proposed.
    pub pool: Vec<(u32, BitString)>,
    /// Their largest Eve separations, in millionths (only those above 0).
    pub separations: Vec<(u32, u64)>,
    /// Their bits' Eve separations rounded up to the group grid (millionths), with how many
    /// bits have each (only sessions with a separation above 0; a session without falls
    /// back to its largest for every bit).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub separation_counts: Vec<(u32, Vec<(u64, u64)>)>,
    /// What the pool keeps of them for the block's estimate or commands check (only those
    /// with samples). The store writes them once, beside the sessions' bits.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub samples: Vec<(u32, SessionSamples)>,
    /// Their bits' LLRs in steps of [`super::LLR_QUANTUM`] nat ([`quantise_llr`]; only
    /// sessions that came with LLRs).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub llrs: Vec<(u32, Vec<i16>)>,
    /// Pooled multilevel slices with a slice after them: what their next slice needs.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub staged: Vec<(u32, StagedSession)>,
    /// Sessions proposed in a block (spent).
    pub spent: Vec<u32>,
    /// The block in flight, if any.
    pub in_flight: Option<InFlight>,
    /// Blocks whose keys were committed.
    pub committed: Vec<u64>,
}

/// A block after the robot agreed.
struct Agreed {
    sessions: Vec<u32>,
    nonces: [[u8; 32]; 2],
    public: PublicRandomness,
    /// Which positions of the pooled bits were disclosed, and the robot's bits there.
    mask: Vec<bool>,
    robot_sample: Vec<bool>,
}

/// A multilevel block's lower slice, reconciled and held until the last slice is: the block
/// is estimated on whole symbols, then each held slice sized, confirmed and committed in turn
/// (docs/postprocessing.md, "Multilevel slices").
struct HeldSlice {
    block: u64,
    /// Sessions proposed, and their bits.
    proposed: Vec<u32>,
    pool: Pool,
    agreed: Agreed,
    outcome: Reconciled,
    report: Option<BlockReport>,
    /// Its equivalent separation (configured sizing), millionths.
    separation: u64,
    /// The sessions its slices belong to (slice 0's IDs), in block order.
    sessions: Vec<u32>,
    /// The pool IDs of its sessions' later slices.
    later: Vec<u32>,
}

/// What the controller waits for.
enum State {
    Idle,
    ExpectAgree {
        nonce: [u8; 32],
    },
    ExpectAnswer {
        agreed: Agreed,
        bob: Box<CascadeBob<ChaCha20Rng>>,
        round: u32,
    },
    /// LDPC with LLRs recomputed at block time: the shell's LLRs of the block.
    ExpectLlrs {
        agreed: Agreed,
        settings: crate::ldpc::LdpcSettings,
    },
    /// LDPC: the robot's syndrome of the current round.
    ExpectSyndrome {
        agreed: Agreed,
        decoding: Box<SyndromeDecoding>,
    },
    /// Reconciled; the shell estimates the plant (measured sizing) or runs the commands
    /// check (configured sizing, sessions pooled with their samples).
    ExpectEstimate {
        agreed: Agreed,
        outcome: Reconciled,
    },
    ExpectConfirmed {
        agreed: Agreed,
        reconciled: BitString,
        key: BitString,
        length: u64,
        assumption: Assumption,
        leak_ec: u64,
    },
    ExpectCommitAck,
    ExpectAbortAck,
}

/// The controller's endpoint. See the [module](super) documentation for the protocol.
pub struct ControllerPost {
    ledger: Ledger,
    next_block: u64,
    /// The block in flight: its number, proposed sessions and their bits.
    block: Option<(u64, Vec<u32>, Pool)>,
    /// Pooled sessions' largest Eve separations (millionths).
    separations: BTreeMap<u32, u64>,
    /// Pooled sessions' per-bit Eve separations, grouped: millionths → bits.
    separation_counts: BTreeMap<u32, BTreeMap<u64, u64>>,
    /// The block in flight's equivalent separation (what sizes it, sent in `Propose`) and
    /// its largest, in millionths.
    block_separation: u64,
    block_largest: u64,
    /// Pooled sessions' kept samples, and the block in flight's.
    samples: BTreeMap<u32, SessionSamples>,
    block_samples: BTreeMap<u32, SessionSamples>,
    /// Pooled sessions' quantised LLRs, and the block in flight's.
    llrs: BTreeMap<u32, Vec<i16>>,
    block_llrs: BTreeMap<u32, Vec<i16>>,
    /// Pooled multilevel slices with a slice after them, and the block in flight's.
    staged: BTreeMap<u32, StagedSession>,
    block_staged: BTreeMap<u32, StagedSession>,
    /// The block in flight's sessions advanced to their next slice, once it is reconciled.
    next_slices: Option<ReconciledSlices>,
    /// The block whose next slices the shell computes: nothing is proposed until they come.
    awaiting_slices: Option<u64>,
    /// Pooled next slices that form the next block, in order.
    slice_group: Vec<u32>,
    /// A multilevel block's lower slices, reconciled and held until its last slice is
    /// (sessions pooled with samples: sized on whole symbols), slice 0 first.
    held: Vec<HeldSlice>,
    /// The block's slices estimated, confirmed and committed one after another, each with
    /// its published separation in grid steps (measured sizing).
    releasing: VecDeque<(HeldSlice, Option<u32>)>,
    in_flight: Option<InFlight>,
    state: State,
    report: Option<BlockReport>,
    last_request: Option<Message>,
    /// LDPC decodes on LLRs the shell recomputes at block time ([`Self::recompute_llrs`]).
    recompute_llrs: bool,
}

impl std::fmt::Debug for ControllerPost {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ControllerPost")
            .field("pooled", &self.ledger.pool.len())
            .field("next_block", &self.next_block)
            .field("in_flight", &self.in_flight)
            .field("committed", &self.ledger.committed.len())
            .finish_non_exhaustive()
    }
}

impl ControllerPost {
    /// A fresh endpoint; `rng_seed` seeds its nonces (from the OS CSPRNG in a deployment).
    ///
    /// # Errors
    /// [`PostError::Settings`].
    pub fn new(settings: Settings, rng_seed: [u8; 32]) -> Result<Self, PostError> {
        Ok(Self::with(Ledger::new(settings, rng_seed)?, 0))
    }

    fn with(ledger: Ledger, next_block: u64) -> Self {
        Self {
            ledger,
            next_block,
            block: None,
            separations: BTreeMap::new(),
            separation_counts: BTreeMap::new(),
            block_separation: 0,
            block_largest: 0,
            samples: BTreeMap::new(),
            block_samples: BTreeMap::new(),
            llrs: BTreeMap::new(),
            block_llrs: BTreeMap::new(),
            staged: BTreeMap::new(),
            block_staged: BTreeMap::new(),
            next_slices: None,
            awaiting_slices: None,
            slice_group: Vec::new(),
            held: Vec::new(),
            releasing: VecDeque::new(),
            in_flight: None,
            state: State::Idle,
            report: None,
            last_request: None,
            recompute_llrs: false,
        }
    }

    /// Whether LDPC decodes on LLRs the shell recomputes at block time from the kept samples
    /// and the disclosed sample ([`Output::LlrsNeeded`]; docs/estimation.md, "Causality")
    /// rather than on those pooled with the sessions (the default). Not durable: the shell
    /// sets it on every endpoint it makes or restores.
    pub fn recompute_llrs(&mut self, recompute: bool) {
        self.recompute_llrs = recompute;
    }

    /// The endpoint after a crash, from its last stored snapshot: an uncommitted block is
    /// aborted, a committed one's `Commit` repeated.
    ///
    /// # Errors
    /// [`PostError::Settings`].
    pub fn restore(
        snapshot: ControllerSnapshot,
        settings: Settings,
        rng_seed: [u8; 32],
    ) -> Result<Self, PostError> {
        let ledger = Ledger::restore(
            settings,
            rng_seed,
            snapshot.pool,
            snapshot.spent,
            snapshot.committed,
        )?;
        let mut endpoint = Self::with(ledger, snapshot.next_block);
        endpoint.separations = snapshot.separations.into_iter().collect();
        endpoint.separation_counts = snapshot
            .separation_counts
            .into_iter()
            .map(|(id, counts)| (id, counts.into_iter().collect()))
            .collect();
        endpoint.samples = snapshot.samples.into_iter().collect();
        endpoint.llrs = snapshot.llrs.into_iter().collect();
        endpoint.staged = snapshot.staged.into_iter().collect();
        match snapshot.in_flight {
            None => endpoint.maybe_propose(),
            Some(InFlight::Committed { block, sessions }) => {
                endpoint.block = Some((block, sessions.clone(), Pool::new()));
                endpoint.in_flight = Some(InFlight::Committed { block, sessions });
                endpoint.report = Some(empty_report(block));
                endpoint.state = State::ExpectCommitAck;
                endpoint.request(Message::Commit { block });
            }
            Some(
                InFlight::Started { block, sessions }
                | InFlight::Aborting {
                    block, sessions, ..
                },
            ) => {
                endpoint.block = Some((block, sessions, Pool::new()));
                endpoint.report = Some(empty_report(block));
                endpoint.abort(AbortReason::Restart, "the controller restarted".into());
            }
        }
        Ok(endpoint)
    }

    /// The durable state to store on [`Output::Persist`].
    #[must_use]
    pub fn snapshot(&self) -> ControllerSnapshot {
        ControllerSnapshot {
            next_block: self.next_block,
            pool: self.ledger.stored_pool(),
            separations: self.separations.iter().map(|(&id, &s)| (id, s)).collect(),
            separation_counts: self
                .separation_counts
                .iter()
                .map(|(&id, counts)| (id, counts.iter().map(|(&d, &n)| (d, n)).collect()))
                .collect(),
            samples: self
                .samples
                .iter()
                .map(|(&id, s)| (id, s.clone()))
                .collect(),
            llrs: self.llrs.iter().map(|(&id, l)| (id, l.clone())).collect(),
            staged: self.staged.iter().map(|(&id, s)| (id, s.clone())).collect(),
            spent: self.ledger.spent.iter().copied().collect(),
            in_flight: self.in_flight.clone(),
            committed: self.ledger.committed.iter().copied().collect(),
        }
    }

    /// Whether no block is in flight.
    #[must_use]
    pub fn is_idle(&self) -> bool {
        matches!(self.state, State::Idle)
    }

    /// The next thing to do.
    pub fn poll_output(&mut self) -> Option<Output> {
        self.ledger.outputs.pop_front()
    }

    /// Feeds one input.
    ///
    /// # Errors
    /// A session that is a duplicate, of a size outside the bounds, with a separation
    /// outside [0, 10⁶], or with LLRs that are not one per bit (or none where LDPC
    /// reconciliation needs them) (nothing changes).
    pub fn handle_input(&mut self, input: ControllerInput) -> Result<(), PostError> {
        match input {
            ControllerInput::Session {
                id,
                bits,
                separations,
                samples,
                llrs,
            } => {
                self.pool_session(id, bits, &separations, samples, llrs)?;
                self.maybe_propose();
            }
            ControllerInput::StagedSession(slice) => {
                self.pool_slice(slice)?;
                self.maybe_propose();
            }
            ControllerInput::NextSlices { block, slices } => {
                if self.awaiting_slices != Some(block) {
                    self.ledger
                        .outputs
                        .push_back(Output::Ignored("slices of a block not awaited"));
                    return Ok(());
                }
                self.awaiting_slices = None;
                let mut first_error = None;
                for slice in slices {
                    let id = super::slice_id(slice.staged.session, usize::from(slice.staged.slice));
                    match self.pool_slice(slice) {
                        Ok(()) => self.slice_group.push(id),
                        Err(e) => {
                            first_error.get_or_insert(e);
                        }
                    }
                }
                if self.slice_group.is_empty() && !self.held.is_empty() {
                    self.abort_held();
                } else {
                    self.maybe_propose();
                }
                if let Some(e) = first_error {
                    return Err(e);
                }
            }
            ControllerInput::Estimate { block, outcome } => self.on_estimate(block, outcome),
            ControllerInput::Llrs { block, llrs } => self.on_llrs(block, llrs),
            ControllerInput::SliceEstimates { block, outcomes } => {
                self.on_slice_estimates(block, outcomes);
            }
            ControllerInput::Timeout => {
                if let Some(request) = self.last_request.clone() {
                    self.send(request);
                }
            }
            ControllerInput::Frame(message) => self.handle_message(message),
        }
        Ok(())
    }

    /// Pools a session's bits with its Eve separations, kept samples and LLRs.
    fn pool_session(
        &mut self,
        id: u32,
        bits: BitString,
        separations: &[f64],
        samples: SessionSamples,
        llrs: Vec<f64>,
    ) -> Result<(), PostError> {
        if let Some(&separation) = separations.iter().find(|d| !(0.0..=1e6).contains(*d)) {
            return Err(PostError::Separation { id, separation });
        }
        self.check_llrs(id, bits.len(), &llrs)?;
        let counts = separation_counts(separations, bits.len());
        self.ledger.add_session(id, bits)?;
        // Rounded up: the key is sized as if Eve saw a little more, never less.
        let largest = separations.iter().fold(0.0_f64, |m, &d| m.max(d));
        let micros = (largest * 1e6).ceil() as u64;
        if micros > 0 {
            self.separations.insert(id, micros);
            self.separation_counts.insert(id, counts);
        }
        if !samples.is_empty() {
            self.samples.insert(id, samples);
        }
        if !llrs.is_empty() {
            self.llrs
                .insert(id, llrs.into_iter().map(quantise_llr).collect());
        }
        Ok(())
    }

    /// Pools a multilevel session's slice under its slice ID, with its bits' separations
    /// picked from the session's, and keeps its staged material when a slice follows.
    fn pool_slice(&mut self, slice: SliceInput) -> Result<(), PostError> {
        let SliceInput { bits, llrs, staged } = slice;
        let id = super::slice_id(staged.session, usize::from(staged.slice));
        staged
            .check()
            .map_err(|problem| PostError::Staged { id, problem })?;
        if bits.len() != staged.slice_bits() {
            return Err(PostError::Staged {
                id,
                problem: format!(
                    "{} bits for its slice of {}",
                    bits.len(),
                    staged.slice_bits()
                ),
            });
        }
        let separations = staged
            .slicing
            .pick(&staged.separations, usize::from(staged.slice));
        self.pool_session(id, bits, &separations, SessionSamples::new(), llrs)?;
        // The last slice's material too when the block is sized on whole symbols.
        if staged.has_next() || !staged.samples.is_empty() {
            self.staged.insert(id, staged);
        }
        Ok(())
    }

    /// A session's LLRs are one per bit and none NaN, or absent where Cascade reconciles.
    fn check_llrs(&self, id: u32, bits: usize, llrs: &[f64]) -> Result<(), PostError> {
        let problem = if llrs.is_empty() {
            matches!(
                self.ledger.settings.reconciliation,
                ReconciliationMethod::Ldpc(_)
            )
            .then(|| {
                "has no LLRs: postprocess.reconciliation = \"ldpc\" decodes on the \
                 controller's per-bit LLRs (private sensing); odometry sessions need \
                 \"cascade\""
                    .to_owned()
            })
        } else if llrs.len() != bits {
            Some(format!("has {} LLRs for its {bits} bits", llrs.len()))
        } else {
            llrs.iter()
                .position(|l| l.is_nan())
                .map(|i| format!("has a NaN LLR at bit {i}"))
        };
        problem.map_or(Ok(()), |problem| Err(PostError::Llrs { id, problem }))
    }

    fn handle_message(&mut self, message: Message) {
        let current = self.block.as_ref().map(|(b, ..)| *b);
        if current != Some(message.block()) {
            self.ledger
                .outputs
                .push_back(Output::Ignored("a message about another block"));
            return;
        }
        match (std::mem::replace(&mut self.state, State::Idle), message) {
            (
                State::ExpectAgree { nonce },
                Message::Agree {
                    sessions,
                    nonce: robot_nonce,
                    sample,
                    ..
                },
            ) => self.on_agree(nonce, sessions, robot_nonce, &sample),
            (
                State::ExpectAnswer {
                    agreed,
                    mut bob,
                    round,
                },
                Message::Answer {
                    round: answered,
                    parities,
                    ..
                },
            ) if answered == round => match bob.answer(&parities) {
                Ok(step) => self.reconcile(agreed, bob, round, step),
                Err(e) => self.abort(
                    AbortReason::Reconciliation,
                    format!("reconciliation failed: {e}"),
                ),
            },
            (
                State::ExpectSyndrome {
                    agreed,
                    mut decoding,
                },
                Message::Syndrome {
                    round, syndrome, ..
                },
            ) if round == decoding.round() => {
                let block = self.current();
                match decoding.accept(block, &syndrome) {
                    Ok(DecodingStep::Done(outcome)) => self.confirm(agreed, outcome),
                    Ok(DecodingStep::Ask(request)) => {
                        self.state = State::ExpectSyndrome { agreed, decoding };
                        self.request(request);
                    }
                    Err(why) => {
                        if let Some(report) = self.report.as_mut() {
                            report.ldpc_rounds = Some(decoding.round());
                        }
                        self.abort(AbortReason::Reconciliation, why);
                    }
                }
            }
            (
                State::ExpectConfirmed {
                    agreed,
                    reconciled,
                    key,
                    length,
                    assumption,
                    leak_ec,
                },
                Message::Confirmed { tag, .. },
            ) => {
                let context = tag_context(self.current(), &agreed.sessions, &agreed.nonces, length);
                let expected =
                    ConfirmationTag::directional(&reconciled, ROBOT_TO_CONTROLLER, &context);
                if expected.matches(&ConfirmationTag(tag)) {
                    self.commit(agreed, key, &assumption, leak_ec);
                } else {
                    self.abort(
                        AbortReason::Reconciliation,
                        "the robot's tag differs: the reconciled keys differ".into(),
                    );
                }
            }
            (State::ExpectCommitAck, Message::CommitAck { .. }) => self.end_block(),
            (State::ExpectAbortAck, Message::AbortAck { .. }) => self.end_block(),
            (
                State::ExpectConfirmed { .. },
                Message::Reject {
                    reason: RejectReason::TagMismatch,
                    ..
                },
            ) => {
                self.abort(
                    AbortReason::Reconciliation,
                    "the robot found our tag wrong: the reconciled keys differ".into(),
                );
            }
            (
                State::ExpectAgree { .. }
                | State::ExpectAnswer { .. }
                | State::ExpectLlrs { .. }
                | State::ExpectSyndrome { .. }
                | State::ExpectEstimate { .. }
                | State::ExpectConfirmed { .. },
                Message::Reject { reason, .. },
            ) => self.abort(
                AbortReason::Refused,
                format!("the robot refused the block ({reason:?})"),
            ),
            (state, _) => {
                self.state = state;
                self.ledger.outputs.push_back(Output::Ignored(
                    "a message the controller does not expect now",
                ));
            }
        }
    }

    fn current(&self) -> u64 {
        self.block.as_ref().map_or(0, |(b, ..)| *b)
    }

    /// Proposes a block when idle and the pool holds enough bits.
    /// A reconciled block's next slices come first, as one block whatever their bits.
    fn maybe_propose(&mut self) {
        if !self.is_idle() || self.block.is_some() || self.awaiting_slices.is_some() {
            return;
        }
        let mut sessions = Vec::new();
        let mut bits = Pool::new();
        let mut total = 0;
        for id in std::mem::take(&mut self.slice_group) {
            if let Some(session) = self.ledger.pool.remove(&id) {
                total += session.len();
                sessions.push(id);
                bits.insert(id, session);
            }
        }
        if sessions.is_empty() {
            let pooled: usize = self.ledger.pool.values().map(BitString::len).sum();
            if pooled < self.ledger.settings.block_bits {
                return;
            }
            while total < self.ledger.settings.block_bits && sessions.len() < MAX_BLOCK_SESSIONS {
                let Some((id, session)) = self.ledger.pool.pop_first() else {
                    break;
                };
                total += session.len();
                sessions.push(id);
                bits.insert(id, session);
            }
        }
        // The block's bits' separations; a session stored without them (an older snapshot)
        // counts its largest for every bit.
        let mut counts: BTreeMap<u64, u64> = BTreeMap::new();
        let mut largest = 0;
        for id in &sessions {
            let session_largest = self.separations.remove(id).unwrap_or(0);
            largest = largest.max(session_largest);
            let session_bits = bits.get(id).map_or(0, |b| b.len() as u64);
            let session_counts = self
                .separation_counts
                .remove(id)
                .unwrap_or_else(|| BTreeMap::from([(session_largest, session_bits)]));
            for (d, n) in session_counts {
                *counts.entry(d).or_default() += n;
            }
        }
        // What sizes the block whichever bits its sample discloses: the per-bit bound's
        // equivalent separation, never above the largest.
        let removed = sample_size(total, self.ledger.settings.sample_bits) as u64;
        let separation_micros =
            equivalent_separation(&counts, removed, self.ledger.settings.epsilon)
                .map_or(largest, |d| d.min(largest));
        self.block_separation = separation_micros;
        self.block_largest = largest;
        self.block_samples = sessions
            .iter()
            .filter_map(|id| self.samples.remove(id).map(|s| (*id, s)))
            .collect();
        self.block_llrs = sessions
            .iter()
            .filter_map(|id| self.llrs.remove(id).map(|l| (*id, l)))
            .collect();
        self.block_staged = sessions
            .iter()
            .filter_map(|id| self.staged.remove(id).map(|l| (*id, l)))
            .collect();
        let block = self.next_block;
        self.next_block += 1;
        let nonce = self.ledger.nonce();
        // A crash aborts the block with its multilevel sessions' other slices.
        let mut group = self.group_sessions(&sessions);
        group.extend(
            self.block_staged
                .values()
                .flat_map(StagedSession::later_ids),
        );
        self.in_flight = Some(InFlight::Started {
            block,
            sessions: group,
        });
        self.block = Some((block, sessions.clone(), bits));
        self.report = Some(empty_report(block));
        self.state = State::ExpectAgree { nonce };
        self.ledger.outputs.push_back(Output::Persist);
        self.request(Message::Propose {
            block,
            sessions,
            nonce,
            separation_micros,
        });
    }

    fn on_agree(
        &mut self,
        nonce: [u8; 32],
        agreed: Vec<u32>,
        robot_nonce: [u8; 32],
        sample: &[bool],
    ) {
        let Some((block, proposed, bits)) = self.block.as_ref() else {
            return;
        };
        let block = *block;
        if !is_subsequence(&agreed, proposed) {
            return self.abort(
                AbortReason::Refused,
                "the robot agreed to sessions that were not proposed".into(),
            );
        }
        if agreed.is_empty() {
            return self.abort(
                AbortReason::Refused,
                "the robot holds none of the proposed sessions".into(),
            );
        }
        // A measured block's separation is found after reconciliation, over the agreed
        // sessions only.
        if agreed.len() < proposed.len()
            && self.block_separation < self.block_largest
            && !self.ledger.settings.assumption.is_measured()
        {
            return self.abort(
                AbortReason::Refused,
                "the robot holds only some of the proposed sessions: the block's equivalent \
                 separation was found for all of them"
                    .into(),
            );
        }
        let nonces = [nonce, robot_nonce];
        let public = PublicRandomness::new(block, &agreed, &nonces);
        let key = concatenate(bits, &agreed);
        let mask = public.sample(key.len(), self.ledger.settings.sample_bits);
        let (own_sample, kept) = split_sample(&key, &mask);
        if own_sample.len() != sample.len() {
            return self.abort(
                AbortReason::Refused,
                "the robot's sample has the wrong length".into(),
            );
        }
        let errors = own_sample
            .iter()
            .zip(sample)
            .filter(|(a, b)| a != b)
            .count();
        let q = if sample.is_empty() {
            0.0
        } else {
            (errors as f64 / sample.len() as f64).min(0.5)
        };
        if let Some(report) = self.report.as_mut() {
            report.sessions.clone_from(&agreed);
            report.bits = key.len();
            report.sample_bits = sample.len();
            report.sampled = (0..mask.len() as u32)
                .filter(|&i| mask[i as usize])
                .collect();
            report.sample_errors = errors;
            report.q_estimate = q;
            report.reconciled_bits = kept.len();
        }
        let agreed = Agreed {
            sessions: agreed,
            nonces,
            public,
            mask,
            robot_sample: sample.to_vec(),
        };
        if let ReconciliationMethod::Ldpc(settings) = self.ledger.settings.reconciliation {
            if self.recompute_llrs {
                let request = self.llr_request(&agreed);
                self.state = State::ExpectLlrs { agreed, settings };
                // Nothing to repeat while the shell recomputes.
                self.last_request = None;
                self.ledger
                    .outputs
                    .push_back(Output::LlrsNeeded(Box::new(request)));
                return;
            }
            return self.start_ldpc(agreed, settings, None);
        }
        let started = Cascade::new(self.ledger.settings.schedule, q)
            .and_then(|cascade| CascadeBob::start(cascade, kept, agreed.public.cascade()));
        match started {
            Ok((bob, step)) => self.reconcile(agreed, Box::new(bob), 0, step),
            Err(e) => self.abort(
                AbortReason::Reconciliation,
                format!("reconciliation could not start: {e}"),
            ),
        }
    }

    /// What the shell needs to recompute the block's LLRs: the agreed sessions' kept
    /// samples and bit counts, and the disclosed sample with the robot's bits.
    fn llr_request(&self, agreed: &Agreed) -> LlrRequest {
        let bits = |id: &u32| {
            self.block
                .as_ref()
                .and_then(|(_, _, pool)| pool.get(id))
                .map_or(0, BitString::len)
        };
        LlrRequest {
            block: self.current(),
            sessions: agreed
                .sessions
                .iter()
                .map(|id| {
                    let samples = self.block_samples.get(id).cloned().unwrap_or_default();
                    (*id, bits(id), samples)
                })
                .collect(),
            disclosed: (0..agreed.mask.len() as u32)
                .filter(|&i| agreed.mask[i as usize])
                .zip(agreed.robot_sample.iter().copied())
                .collect(),
            staged: agreed
                .sessions
                .iter()
                .filter_map(|id| self.block_staged.get(id).cloned())
                .collect(),
        }
    }

    /// The shell's recomputed LLRs of the block: LDPC starts on them.
    fn on_llrs(&mut self, block: u64, answer: LlrAnswer) {
        if self.block.is_none() || block != self.current() {
            self.ledger
                .outputs
                .push_back(Output::Ignored("LLRs for another block"));
            return;
        }
        match std::mem::replace(&mut self.state, State::Idle) {
            State::ExpectLlrs { agreed, settings } => {
                let (provenance, llrs) = match answer {
                    Ok(recomputed) => (
                        LlrProvenance {
                            model: recomputed.model,
                            fallback: None,
                        },
                        Some(recomputed.llrs),
                    ),
                    Err(why) => (
                        LlrProvenance {
                            model: "prior".into(),
                            fallback: Some(why),
                        },
                        None,
                    ),
                };
                if let Some(report) = self.report.as_mut() {
                    report.llrs = Some(Box::new(provenance));
                }
                self.start_ldpc(agreed, settings, llrs);
            }
            state => {
                self.state = state;
                self.ledger
                    .outputs
                    .push_back(Output::Ignored("LLRs the controller does not expect"));
            }
        }
    }

    /// LDPC: the kept positions' LLRs — `recomputed` (one per raw bit of the block) or
    /// else those pooled with the sessions — then round 1's request for the robot's syndrome.
    fn start_ldpc(
        &mut self,
        agreed: Agreed,
        settings: crate::ldpc::LdpcSettings,
        recomputed: Option<Vec<f64>>,
    ) {
        let mut llrs = Vec::with_capacity(agreed.mask.len());
        let pooled = recomputed.is_none();
        if let Some(report) = self.report.as_mut().filter(|r| r.llrs.is_none()) {
            report.llrs = Some(Box::new(LlrProvenance {
                model: "prior".into(),
                fallback: None,
            }));
        }
        if let Some(recomputed) = recomputed {
            if recomputed.len() != agreed.mask.len() || recomputed.iter().any(|l| l.is_nan()) {
                return self.abort(
                    AbortReason::Reconciliation,
                    format!(
                        "the recomputed LLRs do not cover the block's {} bits ({} given, or \
                         one is not a number)",
                        agreed.mask.len(),
                        recomputed.len()
                    ),
                );
            }
            llrs = recomputed;
        }
        for id in agreed.sessions.iter().filter(|_| pooled) {
            let Some(session) = self.block_llrs.get(id) else {
                return self.abort(
                    AbortReason::Reconciliation,
                    format!(
                        "session {id} has no LLRs: LDPC reconciliation decodes on the \
                         controller's per-bit LLRs"
                    ),
                );
            };
            llrs.extend(session.iter().map(|&l| dequantise_llr(l)));
        }
        if llrs.len() != agreed.mask.len() {
            return self.abort(
                AbortReason::Reconciliation,
                "the block's LLRs do not cover its bits".into(),
            );
        }
        let kept: Vec<f64> = llrs
            .into_iter()
            .zip(&agreed.mask)
            .filter(|(_, sampled)| !**sampled)
            .map(|(l, _)| l)
            .collect();
        let block = self.current();
        match SyndromeDecoding::start(settings, kept, agreed.public.ldpc(), block) {
            Ok((decoding, request)) => {
                self.state = State::ExpectSyndrome {
                    agreed,
                    decoding: Box::new(decoding),
                };
                self.request(request);
            }
            Err(why) => self.abort(
                AbortReason::Reconciliation,
                format!("LDPC reconciliation could not start: {why}"),
            ),
        }
    }

    /// Continues Cascade after round `round` with its next step.
    fn reconcile(
        &mut self,
        agreed: Agreed,
        bob: Box<CascadeBob<ChaCha20Rng>>,
        round: u32,
        step: CascadeStep,
    ) {
        match step {
            CascadeStep::Ask(queries) => self.ask(agreed, bob, round + 1, queries),
            CascadeStep::Done(outcome) => self.confirm(
                agreed,
                Reconciled {
                    corrected: outcome.corrected,
                    leak: outcome.leak,
                    questions: outcome.alice_parities,
                    ldpc_rounds: None,
                },
            ),
        }
    }

    fn ask(
        &mut self,
        agreed: Agreed,
        bob: Box<CascadeBob<ChaCha20Rng>>,
        round: u32,
        queries: Vec<BlockQuery>,
    ) {
        let block = self.current();
        self.state = State::ExpectAnswer { agreed, bob, round };
        self.request(Message::Ask {
            block,
            round,
            queries,
        });
    }

    /// Reconciliation is over: with the plant measured, the shell estimates it first; with
    /// it configured and the block's sessions pooled with their samples, the shell runs the
    /// commands check on them first; otherwise ℓ from the assumption at once.
    fn confirm(&mut self, agreed: Agreed, outcome: Reconciled) {
        let advanced: Vec<StagedSession> = self
            .robot_bits(&agreed, &outcome.corrected)
            .into_iter()
            .filter_map(|(id, robot)| {
                self.block_staged
                    .get(&id)
                    .map(|staged| staged.advanced(&robot))
            })
            .collect();
        self.next_slices = (!self.block_staged.is_empty()).then(|| ReconciledSlices {
            block: self.current(),
            sessions: advanced
                .iter()
                .filter(|s| s.slice < s.slicing.slices)
                .cloned()
                .collect(),
        });
        // Multilevel sessions pooled with their samples: the block is sized on whole
        // symbols once its last slice is reconciled; the lower slices wait.
        let whole_symbols = !advanced.is_empty() && advanced.iter().all(|s| !s.samples.is_empty());
        if whole_symbols {
            return if advanced.iter().any(|s| s.slice < s.slicing.slices) {
                self.hold(agreed, outcome)
            } else {
                self.request_slice_estimates(agreed, outcome, advanced)
            };
        }
        let checked = self.block_staged.is_empty()
            && agreed
                .sessions
                .iter()
                .any(|id| self.block_samples.get(id).is_some_and(|s| !s.is_empty()));
        if self.ledger.settings.assumption.is_measured() || checked {
            let request = self.estimate_request(&agreed, &outcome.corrected);
            self.state = State::ExpectEstimate { agreed, outcome };
            // Nothing to repeat while the shell estimates.
            self.last_request = None;
            self.ledger
                .outputs
                .push_back(Output::EstimateNeeded(request));
            return;
        }
        self.size_as_configured(agreed, outcome);
    }

    /// A lower slice reconciled: held (nothing sent; the robot holds it when the next slice
    /// is proposed), its sessions' next slices computed by the shell.
    fn hold(&mut self, agreed: Agreed, outcome: Reconciled) {
        let sessions = agreed
            .sessions
            .iter()
            .map(|id| self.block_staged.get(id).map_or(*id, |s| s.session))
            .collect();
        let later: Vec<u32> = self
            .block_staged
            .values()
            .flat_map(StagedSession::later_ids)
            .collect();
        let Some(mut held) = self.take_block(agreed, outcome, sessions) else {
            return;
        };
        held.later.clone_from(&later);
        let block = held.block;
        self.held.push(held);
        // A crash now aborts the block's every slice: the held ones and those to come.
        let mut group = self.group_sessions(&[]);
        group.extend(later);
        self.in_flight = Some(InFlight::Started {
            block,
            sessions: group,
        });
        self.block_samples.clear();
        self.block_llrs.clear();
        self.block_staged.clear();
        self.state = State::Idle;
        self.last_request = None;
        self.ledger.outputs.push_back(Output::Persist);
        if let Some(next) = self.next_slices.take().filter(|n| !n.sessions.is_empty()) {
            self.awaiting_slices = Some(next.block);
            self.ledger
                .outputs
                .push_back(Output::SliceReconciled(Box::new(next)));
        }
    }

    /// No next slice of held slices could be pooled: the held block ends as refused (its
    /// `Abort` lists every slice's sessions; the robot drops what it holds of them).
    fn abort_held(&mut self) {
        let Some(last) = self.held.pop() else {
            return;
        };
        // Its sessions' later slices end with it.
        let mut sessions = last.proposed;
        sessions.extend(last.later);
        self.block = Some((last.block, sessions, last.pool));
        self.report = last.report;
        self.abort(
            AbortReason::Refused,
            "no next slice of the block could be pooled: its symbols cannot be estimated whole"
                .into(),
        );
    }

    /// The block in flight, reconciled, taken out to be held or released (`sessions`: the
    /// sessions its slices belong to).
    fn take_block(
        &mut self,
        agreed: Agreed,
        outcome: Reconciled,
        sessions: Vec<u32>,
    ) -> Option<HeldSlice> {
        let (block, proposed, pool) = self.block.take()?;
        Some(HeldSlice {
            block,
            proposed,
            pool,
            agreed,
            outcome,
            report: self.report.take(),
            separation: self.block_separation,
            sessions,
            later: Vec::new(),
        })
    }

    /// The last slice reconciled: the shell estimates the block on whole symbols, every
    /// slice's bits known. Every slice must hold the same sessions (else their symbols are
    /// not whole: refused).
    fn request_slice_estimates(
        &mut self,
        agreed: Agreed,
        outcome: Reconciled,
        sessions: Vec<StagedSession>,
    ) {
        let ids: Vec<u32> = sessions.iter().map(|s| s.session).collect();
        let slices = sessions
            .first()
            .map_or(0, |s| usize::from(s.slicing.slices));
        if self.held.len() + 1 != slices || self.held.iter().any(|h| h.sessions != ids) {
            return self.abort(
                AbortReason::Refused,
                "the block's slices do not hold the same sessions (one dropped out between                  slices): its symbols cannot be estimated whole"
                    .into(),
            );
        }
        let disclosed = self
            .held
            .iter()
            .map(|h| h.agreed.robot_sample.len() as u64)
            .chain([agreed.robot_sample.len() as u64])
            .collect();
        let block = self.current();
        self.state = State::ExpectEstimate { agreed, outcome };
        // Nothing to repeat while the shell estimates.
        self.last_request = None;
        self.ledger
            .outputs
            .push_back(Output::SlicesEstimateNeeded(Box::new(
                SlicesEstimateRequest {
                    block,
                    sessions,
                    disclosed,
                },
            )));
    }

    /// The shell's estimate of a multilevel block: a refusal (or a count that does not
    /// match the slices) refuses every slice; otherwise each slice, held ones first, is
    /// sized from its outcome, confirmed and committed in turn.
    fn on_slice_estimates(&mut self, block: u64, outcomes: Vec<EstimateOutcome>) {
        if self.block.is_none() || block != self.current() {
            self.ledger
                .outputs
                .push_back(Output::Ignored("an estimate for another block"));
            return;
        }
        let (agreed, outcome) = match std::mem::replace(&mut self.state, State::Idle) {
            State::ExpectEstimate { agreed, outcome } => (agreed, outcome),
            state => {
                self.state = state;
                self.ledger.outputs.push_back(Output::Ignored(
                    "an estimate the controller does not expect",
                ));
                return;
            }
        };
        if outcomes.len() != self.held.len() + 1 {
            return self.abort(
                AbortReason::PlantRefused,
                format!(
                    "block refused: {} slice estimates for {} slices",
                    outcomes.len(),
                    self.held.len() + 1
                ),
            );
        }
        if let Some(Err(EstimateRefusal(why))) = outcomes.iter().find(|o| o.is_err()) {
            let why = format!("block refused: {why}");
            return self.abort(AbortReason::PlantRefused, why);
        }
        let measured = self.ledger.settings.assumption.is_measured();
        let steps = outcomes.into_iter().map(|o| {
            o.ok()
                .filter(|_| measured)
                .map(|s| s.min(MAX_SEPARATION_STEPS))
        });
        let Some(last) = self.take_block(agreed, outcome, Vec::new()) else {
            return;
        };
        self.releasing = std::mem::take(&mut self.held)
            .into_iter()
            .chain([last])
            .zip(steps)
            .collect();
        self.release_next();
    }

    /// The next estimated slice: sized from its outcome and confirmed (measured sizing) or
    /// from its own equivalent separation (configured).
    fn release_next(&mut self) {
        let Some((held, steps)) = self.releasing.pop_front() else {
            return;
        };
        self.block = Some((held.block, held.proposed.clone(), held.pool));
        self.report = held.report;
        self.block_separation = held.separation;
        self.in_flight = Some(InFlight::Started {
            block: held.block,
            sessions: self.group_sessions(&held.proposed),
        });
        match steps {
            Some(steps) => {
                let assumption = self.ledger.settings.assumption.with_estimate(steps);
                self.size(held.agreed, held.outcome, assumption, Some(steps));
            }
            None => self.size_as_configured(held.agreed, held.outcome),
        }
    }

    /// `proposed` with the sessions of the multilevel block's other slices, held or being
    /// released: what a crash or an abort ends with the block in flight.
    fn group_sessions(&self, proposed: &[u32]) -> Vec<u32> {
        let mut sessions: Vec<u32> = self
            .held
            .iter()
            .chain(self.releasing.iter().map(|(h, _)| h))
            .flat_map(|h| h.proposed.iter().copied())
            .collect();
        sessions.extend_from_slice(proposed);
        sessions
    }

    /// ℓ from the configured assumption at the block's equivalent separation.
    fn size_as_configured(&mut self, agreed: Agreed, outcome: Reconciled) {
        let assumption = self
            .ledger
            .settings
            .assumption
            .for_block(self.block_separation);
        self.size(agreed, outcome, assumption, None);
    }

    /// What the shell needs to estimate the plant: each agreed session's kept samples and
    /// the robot's bits of it — the reconciled bits with the disclosed sample put back.
    fn estimate_request(&self, agreed: &Agreed, corrected: &BitString) -> EstimateRequest {
        let sessions = self
            .robot_bits(agreed, corrected)
            .into_iter()
            .map(|(id, bits)| {
                let samples = self.block_samples.get(&id).cloned().unwrap_or_default();
                (id, samples, bits)
            })
            .collect();
        EstimateRequest {
            block: self.current(),
            sessions,
            disclosed: agreed.robot_sample.len() as u64,
        }
    }

    /// The robot's bits of each agreed session: the reconciled bits with the disclosed
    /// sample put back.
    fn robot_bits(&self, agreed: &Agreed, corrected: &BitString) -> Vec<(u32, BitString)> {
        let (mut kept, mut disclosed) = (0..corrected.len(), agreed.robot_sample.iter());
        let robot: zeroize::Zeroizing<Vec<bool>> = zeroize::Zeroizing::new(
            agreed
                .mask
                .iter()
                .map(|&sampled| {
                    if sampled {
                        disclosed.next() == Some(&true)
                    } else {
                        kept.next().and_then(|i| corrected.get(i)) == Some(true)
                    }
                })
                .collect(),
        );
        let lengths = self.block.as_ref().map(|(_, _, pool)| pool);
        let mut start = 0;
        agreed
            .sessions
            .iter()
            .map(|id| {
                let len = lengths.and_then(|p| p.get(id)).map_or(0, BitString::len);
                let end = (start + len).min(robot.len());
                let bits = BitString::from_bools(&robot[start..end]);
                start = end;
                (*id, bits)
            })
            .collect()
    }

    /// The shell's estimate: ℓ from the carried separation (measured sizing) or from the
    /// assumption (configured sizing, the block accepted by the commands check), or the
    /// block refused.
    fn on_estimate(&mut self, block: u64, estimate: EstimateOutcome) {
        if self.block.is_none() || block != self.current() {
            self.ledger
                .outputs
                .push_back(Output::Ignored("an estimate for another block"));
            return;
        }
        match std::mem::replace(&mut self.state, State::Idle) {
            State::ExpectEstimate { agreed, outcome } => match estimate {
                Ok(steps) if self.ledger.settings.assumption.is_measured() => {
                    let steps = steps.min(MAX_SEPARATION_STEPS);
                    let assumption = self.ledger.settings.assumption.with_estimate(steps);
                    self.size(agreed, outcome, assumption, Some(steps));
                }
                Ok(_) => self.size_as_configured(agreed, outcome),
                Err(EstimateRefusal(why)) => {
                    self.abort(AbortReason::PlantRefused, format!("block refused: {why}"));
                }
            },
            state => {
                self.state = state;
                self.ledger.outputs.push_back(Output::Ignored(
                    "an estimate the controller does not expect",
                ));
            }
        }
    }

    /// ℓ from the block's `assumption`, then the controller's tag (with the published
    /// `estimate` when the plant was measured).
    fn size(
        &mut self,
        agreed: Agreed,
        outcome: Reconciled,
        assumption: Assumption,
        estimate: Option<u32>,
    ) {
        let n = outcome.corrected.len() as u64;
        let (h_min, length) =
            assumption.output_length(n, outcome.leak, self.ledger.settings.epsilon);
        if let Some(report) = self.report.as_mut() {
            report.questions = outcome.questions;
            report.leak_ec = outcome.leak;
            report.ldpc_rounds = outcome.ldpc_rounds;
            report.h_min = h_min;
            report.length = length.bits;
            report.separation_steps = estimate;
            report.assumption = Some(Box::new(assumption.clone()));
        }
        if length.bits == 0 {
            let reason = length.reason.unwrap_or_else(|| "no secret bits".to_owned());
            return self.abort(AbortReason::NoSecretBits, reason);
        }
        let block = self.current();
        let key = agreed
            .public
            .toeplitz(outcome.corrected.len(), length.bits as usize)
            .and_then(|hash| hash.hash(&outcome.corrected));
        let Ok(key) = key else {
            return self.abort(
                AbortReason::NoSecretBits,
                "the Toeplitz hash could not be built".into(),
            );
        };
        let context = tag_context(block, &agreed.sessions, &agreed.nonces, length.bits);
        let tag = ConfirmationTag::directional(&outcome.corrected, CONTROLLER_TO_ROBOT, &context);
        if let Some(report) = self.report.as_mut() {
            report.leak_confirmation = 2 * crate::confirm::TAG_BITS;
        }
        self.state = State::ExpectConfirmed {
            agreed,
            reconciled: outcome.corrected,
            key,
            length: length.bits,
            assumption,
            leak_ec: outcome.leak,
        };
        self.request(Message::Confirm {
            block,
            length: length.bits,
            tag: tag.0,
            estimate,
        });
    }

    /// The robot's tag proved it prepared the key: commit, durably, then tell it.
    fn commit(&mut self, agreed: Agreed, key: BitString, assumption: &Assumption, leak_ec: u64) {
        let Some((block, proposed, _)) = self.block.as_ref() else {
            return;
        };
        let (block, proposed) = (*block, proposed.clone());
        let key = FinalKey {
            id: key_id(&tag_context(
                block,
                &agreed.sessions,
                &agreed.nonces,
                key.len() as u64,
            )),
            block,
            key,
            sessions: agreed.sessions,
            epsilon: assumption.total_epsilon(self.ledger.settings.epsilon),
            assumption: assumption.describe(),
            reconciliation: Some(KeyReconciliation::new(
                &self.ledger.settings.reconciliation,
                leak_ec,
            )),
        };
        self.ledger.committed.insert(block);
        self.in_flight = Some(InFlight::Committed {
            block,
            sessions: self.group_sessions(&proposed),
        });
        self.state = State::ExpectCommitAck;
        self.ledger.outputs.push_back(Output::Persist);
        self.ledger.outputs.push_back(Output::KeyCommitted(key));
        self.request(Message::Commit { block });
    }

    /// Ends the block without key: durably, then tells the robot.
    fn abort(&mut self, reason: AbortReason, why: String) {
        let Some((block, proposed, _)) = self.block.as_ref() else {
            return;
        };
        let (block, mut sessions) = (*block, proposed.clone());
        if let Some(report) = self.report.as_mut() {
            report.reason = Some(why);
            report.length = 0;
        }
        // Only a block reconciled without a key leaves its later slices decodable; else
        // they end with it, and the robot drops them from its pool — with the slices held or
        // being released of a block sized on whole symbols (their reports end here).
        if reason != AbortReason::NoSecretBits {
            self.next_slices = None;
            let mut later: Vec<u32> = self
                .block_staged
                .values()
                .flat_map(StagedSession::later_ids)
                .collect();
            later.extend(self.group_sessions(&[]));
            if sessions.len() + later.len() <= MAX_BLOCK_SESSIONS {
                sessions.extend(later);
            }
            // The other slices' reports say theirs ended with this one, and why it did.
            let why = self
                .report
                .as_ref()
                .and_then(|r| r.reason.as_ref())
                .map(|why| format!("another slice of the same symbols ended without a key: {why}"));
            let others = std::mem::take(&mut self.held).into_iter().chain(
                std::mem::take(&mut self.releasing)
                    .into_iter()
                    .map(|(h, _)| h),
            );
            for held in others {
                let mut report = held.report.unwrap_or_else(|| empty_report(held.block));
                report.reason.clone_from(&why);
                report.length = 0;
                self.ledger.outputs.push_back(Output::BlockEnded(report));
            }
        }
        self.in_flight = Some(InFlight::Aborting {
            block,
            sessions: sessions.clone(),
            reason,
        });
        self.state = State::ExpectAbortAck;
        self.ledger.outputs.push_back(Output::Persist);
        self.request(Message::Abort {
            block,
            sessions,
            reason,
        });
    }

    /// The robot acknowledged: the block's sessions are spent; propose the next.
    fn end_block(&mut self) {
        if let Some((_, sessions, _)) = self.block.take() {
            // A restored or aborted block may list slices pooled since: none is proposed.
            for id in &sessions {
                if self.ledger.pool.remove(id).is_some() {
                    self.separations.remove(id);
                    self.separation_counts.remove(id);
                    self.samples.remove(id);
                    self.llrs.remove(id);
                    self.staged.remove(id);
                    self.slice_group.retain(|s| s != id);
                }
            }
            self.ledger.spent.extend(sessions);
        }
        self.block_samples.clear();
        self.block_llrs.clear();
        self.block_staged.clear();
        self.in_flight = None;
        self.state = State::Idle;
        self.last_request = None;
        self.ledger.outputs.push_back(Output::Persist);
        if let Some(report) = self.report.take() {
            self.ledger.outputs.push_back(Output::BlockEnded(report));
        }
        if !self.releasing.is_empty() {
            return self.release_next();
        }
        if let Some(next) = self.next_slices.take().filter(|n| !n.sessions.is_empty()) {
            self.awaiting_slices = Some(next.block);
            self.ledger
                .outputs
                .push_back(Output::SliceReconciled(Box::new(next)));
        }
        self.maybe_propose();
    }

    /// Sends a request and remembers it for retransmission.
    fn request(&mut self, message: Message) {
        self.last_request = Some(message.clone());
        self.send(message);
    }

    fn send(&mut self, message: Message) {
        if let Some(report) = self.report.as_mut() {
            report.messages_sent += 1;
            report.bits_sent += message.payload_bits();
        }
        self.ledger.outputs.push_back(Output::Transmit(message));
    }
}

/// A report with only its block number.
pub(super) fn empty_report(block: u64) -> BlockReport {
    BlockReport {
        block,
        ..BlockReport::default()
    }
}

/// Whether `sub` lists distinct elements of `sequence` in its order.
fn is_subsequence(sub: &[u32], sequence: &[u32]) -> bool {
    let mut rest = sequence.iter();
    sub.iter().all(|id| rest.any(|x| x == id))
}
