//! The robot's post-processing endpoint: its bits are the reference; it answers the
//! controller's requests, each idempotently, and commits a key only on `Commit`.

use rand::rngs::ChaCha20Rng;
use serde::{Deserialize, Serialize};

use super::controller::empty_report;
use super::ledger::Ledger;
use super::public::PublicRandomness;
use super::syndromes::SyndromeEncoding;
use super::{
    AbortReason, BlockReport, CONTROLLER_TO_ROBOT, FinalKey, KeyReconciliation, MAX_BLOCK_SESSIONS,
    MAX_QUESTIONS, MAX_SEPARATION_STEPS, MAX_SLICES, Message, Output, Pool, PostError,
    ROBOT_TO_CONTROLLER, ReconciliationMethod, RejectReason, Settings, concatenate, key_id,
    split_sample, tag_context,
};
use crate::bitstring::BitString;
use crate::cascade::CascadeAlice;
use crate::confirm::ConfirmationTag;

/// What the robot feeds its endpoint.
#[derive(Debug, Clone)]
pub enum RobotInput {
    /// The raw bits of a session both sides completed.
    Session {
        /// Session ID.
        id: u32,
        /// The robot's bits (the reference) of the session.
        bits: BitString,
    },
    /// A message from the controller.
    Frame(Message),
}

/// A key the robot prepared: persisted, not yet committed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Prepared {
    /// Block number.
    pub block: u64,
    /// The final key.
    pub key: FinalKey,
    /// The robot's tag (repeated if `Confirmed` is lost).
    pub tag: [u8; 8],
    /// The block's report.
    pub report: BlockReport,
}

/// The robot's durable state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotSnapshot {
    /// Sessions pooled and not yet used.
    pub pool: Vec<(u32, BitString)>,
    /// Sessions used or dropped.
    pub spent: Vec<u32>,
    /// The highest block number seen.
    pub highest_block: Option<u64>,
    /// A prepared key.
    pub prepared: Option<Prepared>,
    /// Blocks whose keys were committed.
    pub committed: Vec<u64>,
}

/// The robot's half of reconciliation.
enum Answering {
    /// Cascade: it answers parities.
    Cascade(Box<CascadeAlice<ChaCha20Rng>>),
    /// LDPC: it sends syndromes.
    Ldpc(crate::ldpc::LdpcSettings, Box<SyndromeEncoding>),
}

impl Answering {
    /// leak_EC so far, as the controller counts it: both sides' parities, or every syndrome
    /// bit plus the rounds' count.
    fn leak(&self) -> u64 {
        match self {
            Self::Cascade(alice) => 2 * alice.revealed(),
            Self::Ldpc(settings, encoding) => encoding.sent() + settings.round_count_bits(),
        }
    }

    /// Parities answered, or syndrome bits sent.
    fn questions(&self) -> u64 {
        match self {
            Self::Cascade(alice) => alice.revealed(),
            Self::Ldpc(_, encoding) => encoding.sent(),
        }
    }
}

/// A block the robot agreed to and is reconciling.
struct Reconciling {
    block: u64,
    sessions: Vec<u32>,
    nonces: [[u8; 32]; 2],
    public: PublicRandomness,
    reference: BitString,
    answering: Answering,
    agree: Message,
    /// The block's Eve separation the controller stated (millionths).
    separation_micros: u64,
    last_answer: Option<Message>,
    round: u32,
    report: BlockReport,
}

/// The robot's endpoint. See the [module](super) documentation for the protocol.
pub struct RobotPost {
    ledger: Ledger,
    highest_block: Option<u64>,
    reconciling: Option<Box<Reconciling>>,
    /// Blocks the controller left reconciled when it proposed the next: a multilevel block's
    /// lower slices, which it confirms once the last slice is reconciled and the block
    /// estimated (docs/postprocessing.md, "Multilevel slices"); at most `MAX_SLICES − 1`,
    /// the oldest beyond them dropped with its sessions spent. Not durable, as the block
    /// being reconciled.
    held: Vec<Reconciling>,
    prepared: Option<Prepared>,
}

impl std::fmt::Debug for RobotPost {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RobotPost")
            .field("pooled", &self.ledger.pool.len())
            .field("highest_block", &self.highest_block)
            .field("prepared", &self.prepared.as_ref().map(|p| p.block))
            .field("committed", &self.ledger.committed.len())
            .finish_non_exhaustive()
    }
}

impl RobotPost {
    /// A fresh endpoint; `rng_seed` seeds its nonces (from the OS CSPRNG in a deployment).
    ///
    /// # Errors
    /// [`PostError::Settings`].
    pub fn new(settings: Settings, rng_seed: [u8; 32]) -> Result<Self, PostError> {
        Ok(Self::with(Ledger::new(settings, rng_seed)?, None, None))
    }

    fn with(ledger: Ledger, highest_block: Option<u64>, prepared: Option<Prepared>) -> Self {
        Self {
            ledger,
            highest_block,
            reconciling: None,
            held: Vec::new(),
            prepared,
        }
    }

    /// The endpoint after a crash, from its last stored snapshot (a block it was reconciling
    /// is forgotten: the controller aborts it).
    ///
    /// # Errors
    /// [`PostError::Settings`].
    pub fn restore(
        snapshot: RobotSnapshot,
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
        Ok(Self::with(
            ledger,
            snapshot.highest_block,
            snapshot.prepared,
        ))
    }

    /// The durable state to store on [`Output::Persist`].
    #[must_use]
    pub fn snapshot(&self) -> RobotSnapshot {
        RobotSnapshot {
            pool: self.ledger.stored_pool(),
            spent: self.ledger.spent.iter().copied().collect(),
            highest_block: self.highest_block,
            prepared: self.prepared.clone(),
            committed: self.ledger.committed.iter().copied().collect(),
        }
    }

    /// The block in flight here, if any: being reconciled (not durable: the controller
    /// aborts it after a restart) or prepared (its key awaits the `Commit`).
    #[must_use]
    pub fn block_in_flight(&self) -> Option<u64> {
        self.reconciling
            .as_ref()
            .map(|r| r.block)
            .or(self.prepared.as_ref().map(|p| p.block))
    }

    /// The next thing to do.
    pub fn poll_output(&mut self) -> Option<Output> {
        self.ledger.outputs.pop_front()
    }

    /// Feeds one input.
    ///
    /// # Errors
    /// A session that is a duplicate or of a size outside the bounds (nothing changes).
    pub fn handle_input(&mut self, input: RobotInput) -> Result<(), PostError> {
        match input {
            RobotInput::Session { id, bits } => {
                self.ledger.add_session(id, bits)?;
            }
            RobotInput::Frame(message) => self.handle_message(message),
        }
        Ok(())
    }

    fn handle_message(&mut self, message: Message) {
        let block = message.block();
        match message {
            Message::Propose {
                sessions,
                nonce,
                separation_micros,
                ..
            } => self.on_propose(block, sessions, nonce, separation_micros),
            Message::Ask { round, queries, .. } => self.on_ask(block, round, &queries),
            Message::SyndromeAsk {
                round,
                syndrome_bits,
                bhattacharyya,
                ..
            } => self.on_syndrome_ask(block, round, syndrome_bits, bhattacharyya),
            Message::Confirm {
                length,
                tag,
                estimate,
                ..
            } => self.on_confirm(block, length, tag, estimate),
            Message::Commit { .. } => self.on_commit(block),
            Message::Abort {
                sessions, reason, ..
            } => self.on_abort(block, &sessions, reason),
            _ => self.ignore("a message only the robot sends"),
        }
    }

    fn ignore(&mut self, why: &'static str) {
        self.ledger.outputs.push_back(Output::Ignored(why));
    }

    fn reject(&mut self, block: u64, reason: RejectReason) {
        self.ledger
            .outputs
            .push_back(Output::Transmit(Message::Reject { block, reason }));
    }

    fn reconciling(&mut self, block: u64) -> Option<&mut Reconciling> {
        self.reconciling.as_deref_mut().filter(|r| r.block == block)
    }

    /// The block `block` being reconciled or held.
    fn reconciled(&mut self, block: u64) -> Option<&mut Reconciling> {
        if self.reconciling.as_ref().is_some_and(|r| r.block == block) {
            return self.reconciling.as_deref_mut();
        }
        self.held.iter_mut().find(|r| r.block == block)
    }

    /// The block `block` being reconciled or held, taken out.
    fn take_reconciled(&mut self, block: u64) -> Option<Box<Reconciling>> {
        if let Some(r) = self.reconciling.take_if(|r| r.block == block) {
            return Some(r);
        }
        let at = self.held.iter().position(|r| r.block == block)?;
        Some(Box::new(self.held.remove(at)))
    }

    fn on_propose(
        &mut self,
        block: u64,
        proposed: Vec<u32>,
        nonce: [u8; 32],
        separation_micros: u64,
    ) {
        if let Some(r) = self.reconciling(block) {
            let agree = r.agree.clone();
            return self.send(agree);
        }
        if self.highest_block.is_some_and(|h| block <= h) {
            return self.ignore("a proposal for a block already seen");
        }
        if self.prepared.is_some() {
            return self.reject(block, RejectReason::Busy);
        }
        if proposed.len() > MAX_BLOCK_SESSIONS {
            return self.ignore("a proposal with too many sessions");
        }
        // The block left reconciling is held (a multilevel block's lower slice, confirmed
        // later); the oldest beyond what one block's slices need is dropped, its sessions
        // spent (they were disclosed).
        if let Some(old) = self.reconciling.take() {
            self.held.push(*old);
            if self.held.len() >= MAX_SLICES {
                let oldest = self.held.remove(0);
                self.ledger.spent.extend(oldest.sessions);
            }
        }
        self.highest_block = Some(block);
        let mut agreed = Vec::new();
        let mut bits = Pool::new();
        for id in proposed {
            if let Some(session) = self.ledger.pool.remove(&id) {
                agreed.push(id);
                bits.insert(id, session);
            }
        }
        let robot_nonce = self.ledger.nonce();
        let nonces = [nonce, robot_nonce];
        let public = PublicRandomness::new(block, &agreed, &nonces);
        let key = concatenate(&bits, &agreed);
        let mask = public.sample(key.len(), self.ledger.settings.sample_bits);
        let (sample, reference) = split_sample(&key, &mask);
        let mut report = empty_report(block);
        report.sessions.clone_from(&agreed);
        report.bits = key.len();
        report.sample_bits = sample.len();
        report.reconciled_bits = reference.len();
        let agree = Message::Agree {
            block,
            sessions: agreed.clone(),
            nonce: robot_nonce,
            sample,
        };
        let answering = match self.ledger.settings.reconciliation {
            ReconciliationMethod::Cascade => Answering::Cascade(Box::new(CascadeAlice::new(
                reference.clone(),
                self.ledger.settings.schedule,
                public.cascade(),
            ))),
            ReconciliationMethod::Ldpc(settings) => {
                Answering::Ldpc(settings, Box::new(SyndromeEncoding::new()))
            }
        };
        self.reconciling = Some(Box::new(Reconciling {
            block,
            sessions: agreed,
            nonces,
            public,
            reference,
            answering,
            agree: agree.clone(),
            separation_micros,
            last_answer: None,
            round: 0,
            report,
        }));
        self.send(agree);
    }

    fn on_ask(&mut self, block: u64, round: u32, queries: &[crate::cascade::BlockQuery]) {
        let schedule = self.ledger.settings.schedule;
        let Some(r) = self.reconciling(block) else {
            return self.unknown(block);
        };
        if round == r.round {
            return self.repeat_answer(block, "a repeated question round");
        }
        if round != r.round + 1 {
            return self.ignore("a question round out of order");
        }
        let n = r.reference.len();
        let Answering::Cascade(alice) = &mut r.answering else {
            return self.reject(block, RejectReason::BadQuestions);
        };
        let revealed = alice.revealed();
        if queries.len() > MAX_QUESTIONS
            || u64::from(round) > u64::from(max_rounds(n, &schedule)) + revealed
            || revealed.saturating_add(queries.len() as u64) > 2 * n as u64
        {
            // More than an honest schedule asks: a paired peer cannot make the robot work
            // without bound.
            return self.reject(block, RejectReason::BadQuestions);
        }
        match alice.answer(queries) {
            Ok(parities) => {
                self.record_answer(
                    round,
                    Message::Answer {
                        block,
                        round,
                        parities,
                    },
                );
            }
            Err(_) => self.reject(block, RejectReason::BadQuestions),
        }
    }

    /// LDPC: the syndrome of the asked round's new checks, once per round (a repeated request
    /// gets the same answer).
    fn on_syndrome_ask(&mut self, block: u64, round: u32, syndrome_bits: u32, bhattacharyya: u16) {
        let Some(r) = self.reconciling(block) else {
            return self.unknown(block);
        };
        if round == r.round && round > 0 {
            return self.repeat_answer(block, "a repeated syndrome round");
        }
        let seed = r.public.ldpc();
        let Answering::Ldpc(settings, encoding) = &mut r.answering else {
            return self.reject(block, RejectReason::BadQuestions);
        };
        match encoding.answer(
            round,
            syndrome_bits,
            bhattacharyya,
            &r.reference,
            seed,
            settings,
        ) {
            Ok(syndrome) => {
                self.record_answer(
                    round,
                    Message::Syndrome {
                        block,
                        round,
                        syndrome,
                    },
                );
            }
            Err(reason) => self.reject(block, reason),
        }
    }

    /// Sends the answer to round `round` of the block being reconciled and keeps it for a
    /// repeated request.
    fn record_answer(&mut self, round: u32, answer: Message) {
        if let Some(r) = self.reconciling(answer.block()) {
            r.round = round;
            r.last_answer = Some(answer.clone());
        }
        self.send(answer);
    }

    /// Sends again the last answer of the block being reconciled (`what`: a request that has
    /// none).
    fn repeat_answer(&mut self, block: u64, what: &'static str) {
        match self.reconciling(block).and_then(|r| r.last_answer.clone()) {
            Some(answer) => self.send(answer),
            None => self.ignore(what),
        }
    }

    fn on_confirm(&mut self, block: u64, length: u64, tag: [u8; 8], estimate: Option<u32>) {
        if let Some(prepared) = self.prepared.as_ref().filter(|p| p.block == block) {
            let confirmed = Message::Confirmed {
                block,
                tag: prepared.tag,
            };
            return self.send(confirmed);
        }
        if self.prepared.is_some() {
            // One key prepared at a time: the held slices are confirmed one after another.
            return self.reject(block, RejectReason::Busy);
        }
        let settings = self.ledger.settings.clone();
        let Some(r) = self.reconciled(block) else {
            return self.unknown(block);
        };
        let n = r.reference.len() as u64;
        let leak_ec = r.answering.leak();
        // ℓ recomputed from what was carried: with the plant measured, the estimate's
        // separation (which the robot cannot check, docs/threat-model.md); otherwise the
        // separation proposed with the block.
        let assumption = match (settings.assumption.is_measured(), estimate) {
            (true, Some(steps)) if steps <= MAX_SEPARATION_STEPS => {
                settings.assumption.with_estimate(steps)
            }
            (false, None) => settings.assumption.for_block(r.separation_micros),
            _ => return self.reject(block, RejectReason::LengthMismatch),
        };
        let (h_min, expected) = assumption.output_length(n, leak_ec, settings.epsilon);
        if expected.bits != length || length == 0 {
            return self.reject(block, RejectReason::LengthMismatch);
        }
        let context = tag_context(block, &r.sessions, &r.nonces, length);
        let theirs = ConfirmationTag::directional(&r.reference, CONTROLLER_TO_ROBOT, &context);
        if !theirs.matches(&ConfirmationTag(tag)) {
            return self.reject(block, RejectReason::TagMismatch);
        }
        let key = r
            .public
            .toeplitz(r.reference.len(), length as usize)
            .and_then(|hash| hash.hash(&r.reference));
        let Ok(key) = key else {
            return self.reject(block, RejectReason::LengthMismatch);
        };
        let ours = ConfirmationTag::directional(&r.reference, ROBOT_TO_CONTROLLER, &context);
        let mut report = r.report.clone();
        report.questions = r.answering.questions();
        report.leak_ec = leak_ec;
        if matches!(r.answering, Answering::Ldpc(..)) {
            report.ldpc_rounds = Some(r.round);
        }
        report.leak_confirmation = 2 * crate::confirm::TAG_BITS;
        report.h_min = h_min;
        report.length = length;
        report.separation_steps = estimate;
        report.assumption = Some(Box::new(assumption.clone()));
        let key = FinalKey {
            id: key_id(&context),
            block,
            key,
            sessions: r.sessions.clone(),
            epsilon: assumption.total_epsilon(settings.epsilon),
            assumption: assumption.describe(),
            reconciliation: Some(KeyReconciliation::new(&settings.reconciliation, leak_ec)),
        };
        if let Some(done) = self.take_reconciled(block) {
            self.ledger.spent.extend(done.sessions);
        }
        self.prepared = Some(Prepared {
            block,
            key,
            tag: ours.0,
            report,
        });
        self.ledger.outputs.push_back(Output::Persist);
        self.send(Message::Confirmed { block, tag: ours.0 });
    }

    fn on_commit(&mut self, block: u64) {
        if self.ledger.committed.contains(&block) {
            return self.send(Message::CommitAck { block });
        }
        let Some(prepared) = self.prepared.take_if(|p| p.block == block) else {
            return self.unknown(block);
        };
        self.ledger.committed.insert(block);
        self.ledger.outputs.push_back(Output::Persist);
        self.ledger
            .outputs
            .push_back(Output::KeyCommitted(prepared.key));
        self.ledger
            .outputs
            .push_back(Output::BlockEnded(prepared.report));
        self.send(Message::CommitAck { block });
    }

    fn on_abort(&mut self, block: u64, sessions: &[u32], reason: AbortReason) {
        if self.ledger.committed.contains(&block) {
            return self.ignore("an abort of a committed block");
        }
        let mut reports = Vec::new();
        if self.prepared.as_ref().is_some_and(|p| p.block == block) {
            reports.extend(self.prepared.take().map(|p| p.report));
        }
        // Held slices of the aborted block's symbols end with it (the controller lists
        // their sessions), in block order.
        let (ended, kept): (Vec<_>, Vec<_>) = std::mem::take(&mut self.held)
            .into_iter()
            .partition(|r| r.block == block || r.sessions.iter().any(|id| sessions.contains(id)));
        self.held = kept;
        for r in ended {
            self.ledger.spent.extend(r.sessions.iter().copied());
            reports.push(r.report);
        }
        if let Some(r) = self
            .reconciling
            .take_if(|r| r.block == block || r.sessions.iter().any(|id| sessions.contains(id)))
        {
            self.ledger.spent.extend(r.sessions.iter().copied());
            reports.push(r.report);
        }
        for id in sessions {
            self.ledger.pool.remove(id);
            self.ledger.spent.insert(*id);
        }
        self.highest_block = self.highest_block.max(Some(block));
        self.ledger.outputs.push_back(Output::Persist);
        for mut report in reports {
            report.reason = Some(match reason {
                AbortReason::PlantRefused => "block refused: the controller's estimate of the \
                                              plant refused it (the test and its value are in \
                                              the controller's report)"
                    .into(),
                AbortReason::NoSecretBits
                | AbortReason::Reconciliation
                | AbortReason::Restart
                | AbortReason::Refused => "the controller aborted the block".into(),
            });
            report.length = 0;
            self.ledger.outputs.push_back(Output::BlockEnded(report));
        }
        self.send(Message::AbortAck { block });
    }

    /// A request about a block the robot is not reconciling: stale if it is older, prepared
    /// or committed (a late duplicate); unknown otherwise (the robot restarted).
    fn unknown(&mut self, block: u64) {
        let stale = self.highest_block.is_some_and(|h| block < h)
            || self.prepared.as_ref().is_some_and(|p| p.block == block)
            || self.ledger.committed.contains(&block);
        if stale {
            return self.ignore("a request about a finished block");
        }
        self.reject(block, RejectReason::UnknownBlock);
    }

    fn send(&mut self, message: Message) {
        let report = match (&mut self.reconciling, &mut self.prepared) {
            (Some(r), _) if r.block == message.block() => Some(&mut r.report),
            (_, Some(p)) if p.block == message.block() => Some(&mut p.report),
            _ => None,
        };
        if let Some(report) = report {
            report.messages_sent += 1;
            report.bits_sent += message.payload_bits();
        }
        self.ledger.outputs.push_back(Output::Transmit(message));
    }
}

/// The question rounds the robot answers for a block of `n` bits before any parity is out:
/// twice what an honest `schedule` asks of an error-free block — each pass and each BICONF round
/// one round of parities and at most `⌈log₂ n⌉ + 1` rounds of binary search — plus a fixed
/// margin. Every parity revealed allows one round more (an honest binary search asks at least
/// one per round), and the parities are capped at `2n` (beyond `n` no secret can be left; an
/// honest schedule at error rates near 30 % may reveal about `n`): a paired controller makes the
/// robot compute at most `2n` parities over at most `max_rounds + 2n` rounds per block.
#[must_use]
pub fn max_rounds(n: usize, schedule: &crate::cascade::CascadeSchedule) -> u32 {
    let depth = usize::BITS - n.leading_zeros() + 1;
    let passes = schedule.passes + schedule.biconf_streak_for(n) + 1;
    2 * passes * (depth + 1) + 64
}
