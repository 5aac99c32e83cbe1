//! Post-processing between the agents (docs/postprocessing.md, "Between the agents"), as a
//! connection drives it: the endpoint's messages encoded and cut into fragments of wire type
//! 16 under fresh message numbers, the peer's fragments reassembled, and every batch of the
//! endpoint's outputs turned into what the shell must do — store, then send.

use std::collections::BTreeSet;

use robokey_secrecy::BitString;
use robokey_secrecy::postprocess::{
    self, BlockReport, ControllerInput, ControllerPost, ControllerSnapshot, EstimateOutcome,
    FinalKey, InFlight, LlrAnswer, Output, PostError, Reassembler, RobotInput, RobotPost,
    RobotSnapshot, SessionSamples, SliceInput, StagedSession, slice_id,
};

use super::computation::{Answer, BlockComputation, Computed};
use super::slices::{first_slice, slice_input, slicing};
use crate::Config;
use crate::estimate::{BlockEstimate, recomputes_llrs};
use crate::protocol::{Outcome, PostFragment};

/// A post-processing endpoint as a connection drives it.
pub trait PostEndpoint {
    /// Its durable state.
    type Snapshot;
    /// Its durable state now.
    fn snapshot(&self) -> Self::Snapshot;
    /// Pools a session's raw bits (`separations`: the controller's Eve separation of each
    /// decided bit, [`ControllerInput::Session`]; `samples`: what it keeps of them for the
    /// block's estimate of the plant; `llrs`: its LLR of each decided bit, for LDPC; the
    /// robot ignores all three).
    ///
    /// # Errors
    /// A duplicate session or one of a size out of bounds.
    fn pool(
        &mut self,
        id: u32,
        bits: BitString,
        separations: Vec<f64>,
        samples: SessionSamples,
        llrs: Vec<f64>,
    ) -> Result<(), PostError>;
    /// Pools a multilevel session slice by slice (docs/postprocessing.md, "Multilevel
    /// slices"): the robot every slice of its `bits` under its slice ID; the controller slice
    /// 0 with `staged`, its decisions and LLRs from `config` ([`slice_input`]).
    ///
    /// # Errors
    /// A duplicate ID, a size out of bounds, or staged material that does not fit.
    fn pool_slices(
        &mut self,
        bits: &[bool],
        staged: StagedSession,
        config: &Config,
    ) -> Result<(), PostError>;
    /// The shell's next slices of `block`, which the endpoint asked for (the robot never
    /// asks).
    ///
    /// # Errors
    /// A slice that does not fit (the others are pooled).
    fn next_slices(&mut self, block: u64, slices: Vec<SliceInput>) -> Result<(), PostError>;
    /// Whether LDPC decodes on LLRs recomputed at block time (the controller's
    /// [`ControllerPost::recompute_llrs`]; the robot has no LLRs).
    fn recompute_llrs(&mut self, recompute: bool);
    /// The shell's recomputed LLRs of `block`, which the endpoint asked for (none: the
    /// pooled ones; the robot never asks).
    fn llrs_recomputed(&mut self, block: u64, llrs: LlrAnswer);
    /// The shell's estimate of the plant for `block`, which the endpoint asked for (the
    /// robot never asks).
    fn estimated(&mut self, block: u64, outcome: EstimateOutcome);
    /// The shell's estimate of a multilevel block on whole symbols, one outcome per slice,
    /// which the endpoint asked for with `block`, its last slice's (the robot never asks).
    fn slices_estimated(&mut self, block: u64, outcomes: Vec<EstimateOutcome>);
    /// A message from the peer.
    fn frame(&mut self, message: postprocess::Message);
    /// The next output.
    fn poll_output(&mut self) -> Option<Output>;
    /// The block left in flight here, and what settles it, if any.
    fn in_flight(&self) -> Option<String>;
}

impl PostEndpoint for ControllerPost {
    type Snapshot = ControllerSnapshot;
    fn snapshot(&self) -> ControllerSnapshot {
        ControllerPost::snapshot(self)
    }
    fn pool(
        &mut self,
        id: u32,
        bits: BitString,
        separations: Vec<f64>,
        samples: SessionSamples,
        llrs: Vec<f64>,
    ) -> Result<(), PostError> {
        self.handle_input(ControllerInput::Session {
            id,
            bits,
            separations,
            samples,
            llrs,
        })
    }
    fn pool_slices(
        &mut self,
        _bits: &[bool],
        staged: StagedSession,
        config: &Config,
    ) -> Result<(), PostError> {
        self.handle_input(ControllerInput::StagedSession(slice_input(config, staged)))
    }
    fn next_slices(&mut self, block: u64, slices: Vec<SliceInput>) -> Result<(), PostError> {
        self.handle_input(ControllerInput::NextSlices { block, slices })
    }
    fn recompute_llrs(&mut self, recompute: bool) {
        ControllerPost::recompute_llrs(self, recompute);
    }
    fn llrs_recomputed(&mut self, block: u64, llrs: LlrAnswer) {
        // Never fails: only sessions are checked.
        let _ = self.handle_input(ControllerInput::Llrs { block, llrs });
    }
    fn estimated(&mut self, block: u64, outcome: EstimateOutcome) {
        // An estimate never fails: only sessions are checked.
        let _ = self.handle_input(ControllerInput::Estimate { block, outcome });
    }
    fn slices_estimated(&mut self, block: u64, outcomes: Vec<EstimateOutcome>) {
        // An estimate never fails: only sessions are checked.
        let _ = self.handle_input(ControllerInput::SliceEstimates { block, outcomes });
    }
    fn frame(&mut self, message: postprocess::Message) {
        // A frame never fails: only sessions are checked.
        let _ = self.handle_input(ControllerInput::Frame(message));
    }
    fn poll_output(&mut self) -> Option<Output> {
        ControllerPost::poll_output(self)
    }
    fn in_flight(&self) -> Option<String> {
        Some(match self.snapshot().in_flight? {
            InFlight::Started { block, .. } => {
                format!("block {block} proposed and not committed: the next session aborts it")
            }
            InFlight::Aborting { block, .. } => format!(
                "block {block} aborted here, the robot's AbortAck has not arrived: the next \
                 session repeats the Abort"
            ),
            InFlight::Committed { block, .. } => format!(
                "block {block} committed here, its key pending: the robot's CommitAck has not \
                 arrived; the next session repeats the Commit"
            ),
        })
    }
}

impl PostEndpoint for RobotPost {
    type Snapshot = RobotSnapshot;
    fn snapshot(&self) -> RobotSnapshot {
        RobotPost::snapshot(self)
    }
    fn pool(
        &mut self,
        id: u32,
        bits: BitString,
        _separations: Vec<f64>,
        _samples: SessionSamples,
        _llrs: Vec<f64>,
    ) -> Result<(), PostError> {
        self.handle_input(RobotInput::Session { id, bits })
    }
    fn pool_slices(
        &mut self,
        bits: &[bool],
        staged: StagedSession,
        _config: &Config,
    ) -> Result<(), PostError> {
        for slice in 0..usize::from(staged.slicing.slices) {
            let picked = zeroize::Zeroizing::new(staged.slicing.pick(bits, slice));
            self.handle_input(RobotInput::Session {
                id: slice_id(staged.session, slice),
                bits: BitString::from_bools(&picked),
            })?;
        }
        Ok(())
    }
    fn next_slices(&mut self, _block: u64, _slices: Vec<SliceInput>) -> Result<(), PostError> {
        Ok(())
    }
    fn recompute_llrs(&mut self, _recompute: bool) {}
    fn llrs_recomputed(&mut self, _block: u64, _llrs: LlrAnswer) {}
    fn estimated(&mut self, _block: u64, _outcome: EstimateOutcome) {}
    fn slices_estimated(&mut self, _block: u64, _outcomes: Vec<EstimateOutcome>) {}
    fn frame(&mut self, message: postprocess::Message) {
        let _ = self.handle_input(RobotInput::Frame(message));
    }
    fn poll_output(&mut self) -> Option<Output> {
        RobotPost::poll_output(self)
    }
    fn in_flight(&self) -> Option<String> {
        let block = self.block_in_flight()?;
        Some(if self.snapshot().prepared.is_some() {
            format!(
                "block {block} prepared here, its key pending: the controller's Commit has not \
                 arrived; the next session commits or aborts it"
            )
        } else {
            format!(
                "block {block} was being reconciled; nothing of it is stored: the next \
                 session aborts it"
            )
        })
    }
}

/// What post-processing asks of the shell and tells it.
#[derive(Clone, Debug)]
pub enum PostOutput<S> {
    /// Store `snapshot` with the keys committed in it, before anything that follows is sent;
    /// then, when `compact`, rewrite the journal without what the ended block spent.
    Persist {
        /// The endpoint's durable state.
        snapshot: S,
        /// Keys committed in this batch.
        keys: Vec<FinalKey>,
        /// A block ended in this batch.
        compact: bool,
    },
    /// A session's raw bits joined the pool.
    Pooled {
        /// Session id.
        session: u32,
        /// Its raw bits.
        bits: usize,
    },
    /// A session's raw bits did not join the pool, and why.
    NotPooled {
        /// Session id.
        session: u32,
        /// Why.
        reason: String,
    },
    /// A block ended (with or without a key).
    BlockEnded(BlockReport),
    /// The controller estimated the plant for a block (measured sizing), before sizing it.
    Estimated(BlockEstimate),
    /// A message went out (retransmissions included), as this many fragments.
    Sent(usize),
    /// A whole message came in and went to the endpoint.
    Received,
    /// How the exchange ended, when not with every block settled.
    Note(String),
}

/// One side of post-processing: its endpoint, the fragments' reassembly, the numbering of
/// its messages, and the sessions it must never pool again.
#[derive(Debug)]
pub struct PostLink<E> {
    endpoint: E,
    reassembler: Reassembler,
    next_message: u32,
    /// Sessions a stored key lists as sources: their bits are spent.
    spent: BTreeSet<u32>,
    /// The parties' configuration, which the controller's estimate of the plant (measured
    /// sizing) and its commands check read.
    config: Config,
    /// Whether the last [`Self::flush`] ran a block-time computation (the estimate of the
    /// plant or the commands check): the time it took is this side's, not the peer's silence.
    computed: bool,
    /// Whether block-time computations go to the shell ([`Self::deferring`]) rather than
    /// running inside [`Self::flush`].
    defer: bool,
    /// The deferred computation asked for and not answered yet: the job until the shell
    /// takes it, then only its block.
    computing: Option<Computing>,
}

/// A deferred computation, before and after the shell took it.
#[derive(Debug)]
enum Computing {
    Asked(Box<BlockComputation>),
    Taken(u64),
}

impl<E: PostEndpoint> PostLink<E> {
    /// Drives `endpoint` (fresh, or restored from its store) under `config`, never pooling a
    /// session in `spent`.
    pub fn new(mut endpoint: E, spent: BTreeSet<u32>, config: &Config) -> Self {
        endpoint.recompute_llrs(recomputes_llrs(config));
        Self {
            endpoint,
            reassembler: Reassembler::new(),
            next_message: 0,
            spent,
            config: config.clone(),
            computed: false,
            defer: false,
            computing: None,
        }
    }

    /// The same link, its block-time computations handed to the shell
    /// ([`Self::take_computation`], answered with [`Self::answer`]) instead of run inside
    /// [`Self::flush`]: an agent runs them on a worker thread while it keeps answering the
    /// network.
    #[must_use]
    pub fn deferring(mut self) -> Self {
        self.defer = true;
        self
    }

    /// The computation the endpoint waits for, once: the shell runs it
    /// ([`BlockComputation::run`]) and hands back its answer.
    pub fn take_computation(&mut self) -> Option<BlockComputation> {
        match self.computing.take()? {
            Computing::Asked(job) => {
                self.computing = Some(Computing::Taken(job.block()));
                Some(*job)
            }
            taken @ Computing::Taken(_) => {
                self.computing = Some(taken);
                None
            }
        }
    }

    /// Whether a deferred computation is asked for and not answered yet.
    #[must_use]
    pub fn is_computing(&self) -> bool {
        self.computing.is_some()
    }

    /// The shell's answer to a computation: the endpoint takes it (one for another block is
    /// dropped); the estimates behind it are reported in `out`. The next [`Self::flush`]
    /// carries on.
    pub fn answer(&mut self, computed: Computed, out: &mut Vec<PostOutput<E::Snapshot>>) {
        match self.computing {
            Some(Computing::Taken(block)) if block == computed.block => self.computing = None,
            _ => return,
        }
        self.hand(computed, out);
    }

    /// A computation the endpoint asked for: deferred to the shell, or run now and handed
    /// back.
    fn compute(&mut self, job: BlockComputation, out: &mut Vec<PostOutput<E::Snapshot>>) {
        if self.defer {
            self.computing = Some(Computing::Asked(Box::new(job)));
        } else {
            let computed = job.run();
            self.hand(computed, out);
            self.computed = true;
        }
    }

    /// Hands the endpoint a computation's answer, reporting the estimates behind it.
    fn hand(&mut self, computed: Computed, out: &mut Vec<PostOutput<E::Snapshot>>) {
        let block = computed.block;
        match computed.answer {
            Answer::Estimate { estimate, outcome } => {
                out.extend(estimate.map(PostOutput::Estimated));
                self.endpoint.estimated(block, outcome);
            }
            Answer::Llrs(llrs) => self.endpoint.llrs_recomputed(block, llrs),
            Answer::Slices {
                estimates,
                outcomes,
            } => {
                out.extend(estimates.into_iter().map(PostOutput::Estimated));
                self.endpoint.slices_estimated(block, outcomes);
            }
        }
    }

    /// Whether the last flush ran a block-time computation (its answer leaves when the shell
    /// next runs, however long the computation took).
    #[must_use]
    pub fn computed(&self) -> bool {
        self.computed
    }

    /// The endpoint.
    pub fn endpoint(&self) -> &E {
        &self.endpoint
    }

    /// Pools the raw bits of session `id` (one `u8` 0/1 per bit) if the session ended
    /// `outcome` confirmed or kept and its bits are not spent, with what the controller
    /// keeps of it for the block's estimate (`samples`), its LLRs (`llrs`) and, with
    /// multilevel symbols, each decided doublet's likelihoods as kept (`likelihoods`,
    /// [`super::slices::keep_likelihoods`]; all three empty on the robot); says what
    /// happened. Multilevel sessions are pooled slice by slice.
    #[allow(clippy::too_many_arguments)]
    pub fn pool(
        &mut self,
        id: u32,
        outcome: &Outcome,
        bits: &[u8],
        separations: Vec<f64>,
        samples: SessionSamples,
        llrs: Vec<f64>,
        likelihoods: Vec<i16>,
    ) -> PostOutput<E::Snapshot> {
        let refused = |reason: String| PostOutput::NotPooled {
            session: id,
            reason,
        };
        if !matches!(outcome, Outcome::Confirmed | Outcome::Kept) {
            return refused("the session was not confirmed".into());
        }
        if self.spent.contains(&id) {
            return refused(format!(
                "session {id:08x} is a source of a stored key: its bits are spent"
            ));
        }
        let bools: zeroize::Zeroizing<Vec<bool>> =
            zeroize::Zeroizing::new(bits.iter().map(|&b| b == 1).collect());
        let pooled = match slicing(&self.config) {
            Some(slicing) => {
                // The key's doublets' (the first decided ones) likelihoods and separations.
                let doublets = bits.len() / usize::from(slicing.key_bits);
                let mut likelihoods = likelihoods;
                likelihoods.truncate(doublets * slicing.patterns());
                let mut separations = separations;
                separations.truncate(bits.len());
                let mut samples = samples;
                samples.truncate(doublets);
                let staged =
                    first_slice(id, slicing, bits.len(), likelihoods, separations, samples);
                self.endpoint.pool_slices(&bools, staged, &self.config)
            }
            None => self.endpoint.pool(
                id,
                BitString::from_bools(&bools),
                separations,
                samples,
                llrs,
            ),
        };
        match pooled {
            Ok(()) => PostOutput::Pooled {
                session: id,
                bits: bits.len(),
            },
            Err(e) => refused(e.to_string()),
        }
    }

    /// Takes a fragment from the peer; a message it completes goes to the endpoint.
    pub fn receive(&mut self, fragment: &PostFragment, out: &mut Vec<PostOutput<E::Snapshot>>) {
        if let Some(whole) = self.reassembler.accept(
            fragment.message,
            fragment.index,
            fragment.count,
            &fragment.bytes,
        ) && let Ok(decoded) = postprocess::decode(&whole)
        {
            out.push(PostOutput::Received);
            self.endpoint.frame(decoded);
        }
    }

    /// Takes the endpoint's outputs as one batch: what to store first (the snapshot with the
    /// keys committed in it, compaction after a block), the blocks that ended, then the
    /// fragments to send. Returns the fragments.
    ///
    /// # Errors
    /// A message too long for its fragments (`postprocess.block_bits` too large).
    pub fn flush(
        &mut self,
        out: &mut Vec<PostOutput<E::Snapshot>>,
    ) -> Result<Vec<PostFragment>, String> {
        let (mut persist, mut keys, mut sends, mut ended) = (false, Vec::new(), Vec::new(), false);
        let mut blocks = Vec::new();
        self.computed = false;
        while let Some(output) = self.endpoint.poll_output() {
            match output {
                // Block-time computations, from the samples the pool kept and the robot's
                // bits: run now, or handed to the shell (`Self::deferring`).
                Output::EstimateNeeded(request) => {
                    self.compute(BlockComputation::estimate(&self.config, request), out);
                }
                Output::LlrsNeeded(request) => {
                    self.compute(BlockComputation::llrs(&self.config, request), out);
                }
                Output::SlicesEstimateNeeded(request) => {
                    self.compute(BlockComputation::slices(&self.config, request), out);
                }
                Output::SliceReconciled(reconciled) => {
                    // The next slices' LLRs given the robot's bits of the reconciled ones:
                    // the simulator's computation (`slices::slice_input`).
                    let slices = reconciled
                        .sessions
                        .into_iter()
                        .map(|staged| slice_input(&self.config, staged))
                        .collect();
                    if let Err(e) = self.endpoint.next_slices(reconciled.block, slices) {
                        out.push(PostOutput::Note(format!(
                            "a slice after block {} was not pooled: {e}",
                            reconciled.block
                        )));
                    }
                }
                Output::Transmit(message) => sends.push(message),
                Output::Persist => persist = true,
                Output::KeyCommitted(key) => keys.push(key),
                Output::BlockEnded(report) => {
                    ended = true;
                    blocks.push(report);
                }
                Output::Ignored(_) => {}
            }
        }
        if persist || !keys.is_empty() {
            out.push(PostOutput::Persist {
                snapshot: self.endpoint.snapshot(),
                keys,
                compact: ended,
            });
        }
        out.extend(blocks.into_iter().map(PostOutput::BlockEnded));
        let mut fragments = Vec::new();
        for message in &sends {
            let bytes = postprocess::encode(message);
            if !postprocess::fits(bytes.len()) {
                return Err(format!(
                    "a post-processing message of {} bytes exceeds the {} bytes its fragments \
                     can carry: lower postprocess.block_bits",
                    bytes.len(),
                    postprocess::MAX_MESSAGE_BYTES
                ));
            }
            let number = self.next_message;
            self.next_message = self.next_message.wrapping_add(1);
            let before = fragments.len();
            fragments.extend(postprocess::fragments(&bytes).map(|(index, count, chunk)| {
                PostFragment {
                    message: number,
                    index,
                    count,
                    bytes: chunk.to_vec(),
                }
            }));
            out.push(PostOutput::Sent(fragments.len() - before));
        }
        Ok(fragments)
    }
}

impl PostLink<ControllerPost> {
    /// Whether no block is in flight: the controller has nothing more to drive.
    pub fn is_idle(&self) -> bool {
        self.endpoint.is_idle()
    }

    /// The retransmission timer fired: the endpoint repeats what is unanswered.
    pub fn on_timeout(&mut self) {
        let _ = self.endpoint.handle_input(ControllerInput::Timeout);
    }
}
