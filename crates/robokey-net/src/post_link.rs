//! Post-processing between the agents (docs/postprocessing.md, "Between the agents"): after
//! a session both sides confirmed, each agent pools its raw bits in its store; the
//! controller then drives the post-processing endpoints over the session's authenticated
//! channel — fragments of wire type 16 — until no block is in flight, and the robot answers
//! until the controller's `Done`. A key is written to both stores only through the
//! endpoints' two-phase commit.

use std::path::Path;
use std::time::Instant;

use robokey::Config;
use robokey::post_settings::post_settings;
use robokey::protocol::auth::{Delivery, PairingSecret};
use robokey::protocol::{Message, Outcome, PostFragment};
use robokey_secrecy::BitString;
use robokey_secrecy::postprocess::{
    self, Assumption, BlockReport, ControllerInput, ControllerPost, ControllerSnapshot, InFlight,
    Output, PostError, Reassembler, RobotInput, RobotPost, RobotSnapshot, Settings,
};
use serde::Serialize;

use crate::error::NetError;
use crate::key_store::{KeyStatus, StoredKey};
use crate::post_store::{PendingKey, PostStore, Snapshot, StoreRecovery};
use crate::session::{Courtesy, Timing, os_rng};
use crate::transport::Transport;

/// A post-processing endpoint as the agents drive it.
pub trait PostEndpoint: Sized {
    /// Its durable state.
    type Snapshot: Snapshot;
    /// A fresh endpoint.
    ///
    /// # Errors
    /// Settings out of range.
    fn new(settings: Settings, seed: [u8; 32]) -> Result<Self, PostError>;
    /// The endpoint from its stored state.
    ///
    /// # Errors
    /// Settings out of range.
    fn restore(
        snapshot: Self::Snapshot,
        settings: Settings,
        seed: [u8; 32],
    ) -> Result<Self, PostError>;
    /// Its durable state now.
    fn snapshot(&self) -> Self::Snapshot;
    /// Pools a session's raw bits (`separation`: the controller's largest Eve separation
    /// over them; the robot ignores it).
    ///
    /// # Errors
    /// A duplicate session or one of a size out of bounds.
    fn pool(&mut self, id: u32, bits: BitString, separation: f64) -> Result<(), PostError>;
    /// A message from the peer.
    fn frame(&mut self, message: postprocess::Message);
    /// The next output.
    fn poll_output(&mut self) -> Option<Output>;
    /// The block left in flight here, and what settles it, if any.
    fn in_flight(&self) -> Option<String>;
}

impl PostEndpoint for ControllerPost {
    type Snapshot = ControllerSnapshot;
    fn new(settings: Settings, seed: [u8; 32]) -> Result<Self, PostError> {
        ControllerPost::new(settings, seed)
    }
    fn restore(
        s: ControllerSnapshot,
        settings: Settings,
        seed: [u8; 32],
    ) -> Result<Self, PostError> {
        ControllerPost::restore(s, settings, seed)
    }
    fn snapshot(&self) -> ControllerSnapshot {
        ControllerPost::snapshot(self)
    }
    fn pool(&mut self, id: u32, bits: BitString, separation: f64) -> Result<(), PostError> {
        self.handle_input(ControllerInput::Session {
            id,
            bits,
            separation,
        })
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
    fn new(settings: Settings, seed: [u8; 32]) -> Result<Self, PostError> {
        RobotPost::new(settings, seed)
    }
    fn restore(s: RobotSnapshot, settings: Settings, seed: [u8; 32]) -> Result<Self, PostError> {
        RobotPost::restore(s, settings, seed)
    }
    fn snapshot(&self) -> RobotSnapshot {
        RobotPost::snapshot(self)
    }
    fn pool(&mut self, id: u32, bits: BitString, _separation: f64) -> Result<(), PostError> {
        self.handle_input(RobotInput::Session { id, bits })
    }
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

/// What post-processing did during one agent run, for its report.
#[derive(Clone, Debug, Default, Serialize)]
pub struct PostReport {
    /// The store.
    pub store: String,
    /// The assumption about Eve that sizes the keys.
    pub assumption: String,
    /// Whether it is restricted (keys labelled so).
    pub restricted: bool,
    /// Raw bits this session added to the pool (0 if it was not pooled).
    pub session_bits: usize,
    /// Why this session's bits were not pooled, if so.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_pooled: Option<String>,
    /// Raw bits in the pool after this run.
    pub pool_bits: usize,
    /// The controller proposes a block at this many pooled bits.
    pub block_bits: usize,
    /// Blocks that ended during this run.
    pub blocks: Vec<BlockSummary>,
    /// Keys committed during this run (IDs), pending or settled.
    pub keys: Vec<String>,
    /// Keys pending in the store when the run ended: committed or prepared here, not yet
    /// acknowledged by the peer, withheld from `keys get` until a later session settles them.
    pub pending_keys: Vec<PendingKey>,
    /// The block this run left in flight, and what settles it (the exit code is then 5).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub in_flight: Option<String>,
    /// What opening the store found and repaired.
    #[serde(flatten)]
    pub recovery: StoreRecovery,
    /// Post-processing messages sent (retransmissions included).
    pub messages_sent: u32,
    /// Whole messages received and handed to the endpoint (which may ignore a stale one).
    pub messages_received: u32,
    /// How the exchange ended, when not with every block settled.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

/// One block, as reported.
#[derive(Clone, Debug, Serialize)]
pub struct BlockSummary {
    /// Block number.
    pub block: u64,
    /// Sessions pooled into it.
    pub sessions: usize,
    /// Raw bits.
    pub bits: usize,
    /// Bits disclosed to estimate the error rate.
    pub sample_bits: usize,
    /// Disagreements in the sample (controller only).
    pub sample_errors: usize,
    /// Bits reconciled.
    pub reconciled_bits: usize,
    /// Cascade leak (bits).
    pub leak_ec: u64,
    /// Confirmation tags (bits).
    pub leak_confirmation: u64,
    /// Eve's smooth min-entropy under the assumption (bits).
    pub h_min: f64,
    /// The key length ℓ (0: no key).
    pub length: u64,
    /// Why no key, if so.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
}

impl From<&BlockReport> for BlockSummary {
    fn from(r: &BlockReport) -> Self {
        Self {
            block: r.block,
            sessions: r.sessions.len(),
            bits: r.bits,
            sample_bits: r.sample_bits,
            sample_errors: r.sample_errors,
            reconciled_bits: r.reconciled_bits,
            leak_ec: r.leak_ec,
            leak_confirmation: r.leak_confirmation,
            h_min: r.h_min,
            length: r.length,
            reason: r.reason.clone(),
        }
    }
}

/// One side of post-processing: its endpoint, its store and its half of the link.
pub struct PostSide<E: PostEndpoint> {
    endpoint: E,
    store: PostStore<E::Snapshot>,
    reassembler: Reassembler,
    next_message: u32,
    role: &'static str,
    /// What happened, for the report.
    pub report: PostReport,
}

impl<E: PostEndpoint> PostSide<E> {
    /// The post-processing side of an agent run with `--store store` (none without), for
    /// `pairing`: post-processing runs only over an authenticated channel.
    ///
    /// # Errors
    /// `--store` with `--unauthenticated`, or [`Self::open`]'s.
    pub fn for_agent(
        config: &Config,
        store: Option<&std::path::PathBuf>,
        pairing: &PairingSecret,
        allow_restricted: bool,
    ) -> Result<Option<Self>, NetError> {
        let Some(dir) = store else {
            return Ok(None);
        };
        if pairing.mode() != robokey::protocol::auth::AuthMode::Paired {
            return Err(NetError::Usage(
                "--store needs a paired session: post-processing over an unauthenticated \
                 channel would hand the keys to anyone in the middle (drop --unauthenticated)"
                    .into(),
            ));
        }
        Self::open(config, dir, pairing, allow_restricted).map(Some)
    }

    /// Opens the store at `dir` and restores the endpoint from it, for `pairing`. A
    /// restricted assumption needs `allow_restricted`.
    ///
    /// # Errors
    /// A restricted assumption without `allow_restricted`; the store cannot be opened
    /// (in use, another role or pairing, unreadable).
    pub fn open(
        config: &Config,
        dir: &Path,
        pairing: &PairingSecret,
        allow_restricted: bool,
    ) -> Result<Self, NetError> {
        let settings = post_settings(config);
        let restricted = settings.assumption.is_restricted();
        if restricted && !allow_restricted {
            return Err(NetError::Usage(format!(
                "postprocess.assumed_eve_error = {} states a restricted assumption (an Eve who \
                 never learns the model), which the odometry mode's traffic does not support \
                 (docs/threat-model.md): pass --allow-restricted to make keys under it anyway; \
                 they are labelled restricted",
                config.postprocess.assumed_eve_error.unwrap_or_default()
            )));
        }
        let (store, recovery) = PostStore::open(dir, pairing, restricted)?;
        let mut seed = [0_u8; 32];
        rand::RngExt::fill(&mut os_rng()?, &mut seed[..]);
        let endpoint = match recovery.snapshot {
            Some(snapshot) => E::restore(snapshot, settings.clone(), seed),
            None => E::new(settings.clone(), seed),
        }
        .map_err(|e| NetError::Usage(format!("post-processing: {e}")))?;
        let report = PostReport {
            store: dir.display().to_string(),
            assumption: match &settings.assumption {
                Assumption::GaussianViews { statement, .. } => format!(
                    "{statement}; each block sized by the largest separation of Eve's view over \
                     its bits, computed by the controller from its samples"
                ),
                other => other.describe(),
            },
            restricted,
            block_bits: settings.block_bits,
            pending_keys: store.pending(),
            recovery: recovery.figures,
            ..PostReport::default()
        };
        if let Some(recovered) = report.recovered() {
            eprintln!("store {}: {recovered}", dir.display());
        }
        Ok(Self {
            endpoint,
            store,
            reassembler: Reassembler::new(),
            next_message: 0,
            role: E::Snapshot::ROLE,
            report,
        })
    }

    /// Pools the raw bits of session `id` (one `u8` 0/1 per bit) if the session ended
    /// `outcome` confirmed or kept; the next [`Self::flush`] stores them. A session that was
    /// not, or that the endpoint refuses (a duplicate ID, no bits), is reported and left out.
    pub fn pool(&mut self, id: u32, outcome: Option<&Outcome>, bits: &[u8], separation: f64) {
        if !matches!(outcome, Some(Outcome::Confirmed | Outcome::Kept)) {
            self.report.not_pooled = Some("the session was not confirmed".into());
            return;
        }
        if self.store.is_source(id) {
            let why = format!("session {id:08x} is a source of a stored key: its bits are spent");
            println!("{}: {why}", self.role);
            self.report.not_pooled = Some(why);
            return;
        }
        let before = pool_bits(&self.endpoint.snapshot());
        let bools: zeroize::Zeroizing<Vec<bool>> =
            zeroize::Zeroizing::new(bits.iter().map(|&b| b == 1).collect());
        match self
            .endpoint
            .pool(id, BitString::from_bools(&bools), separation)
        {
            Ok(()) => {
                self.report.session_bits = bits.len();
                println!(
                    "{}: session {id:08x} pooled: {} raw bits, {} in the pool (a block at {})",
                    self.role,
                    bits.len(),
                    before + bits.len(),
                    self.report.block_bits
                );
            }
            Err(e) => {
                println!("{}: session {id:08x} not pooled: {e}", self.role);
                self.report.not_pooled = Some(e.to_string());
            }
        }
    }

    /// Takes the endpoint's outputs as one batch — stores the snapshot with the keys
    /// committed in it, compacts after a block, then transmits — and says whether it sent.
    ///
    /// # Errors
    /// The store or the socket fails.
    pub fn flush(&mut self, transport: &mut Transport) -> Result<bool, NetError> {
        let (mut persist, mut keys, mut sends, mut ended) = (false, Vec::new(), Vec::new(), false);
        while let Some(output) = self.endpoint.poll_output() {
            match output {
                Output::Transmit(message) => sends.push(message),
                Output::Persist => persist = true,
                Output::KeyCommitted(key) => keys.push(key),
                Output::BlockEnded(report) => {
                    ended = true;
                    self.block_ended(&report);
                }
                Output::Ignored(_) => {}
            }
        }
        if persist || !keys.is_empty() {
            let mut snapshot = self.endpoint.snapshot();
            for key in self.store.persist(&mut snapshot, &keys)? {
                announce_key(&key);
                self.report.keys.push(key.id.clone());
            }
            self.report.pool_bits = pool_bits(&snapshot);
            if ended {
                self.store.compact(&mut snapshot)?;
            }
        }
        let sent = !sends.is_empty();
        for message in &sends {
            self.send(transport, message)?;
        }
        Ok(sent)
    }

    fn block_ended(&mut self, report: &BlockReport) {
        let summary = BlockSummary::from(report);
        match &summary.reason {
            // A block whose commit the restarted controller repeated: its key was stored
            // before the crash, and the figures went with the process.
            None if summary.bits == 0 => println!(
                "{}: block {}: the robot acknowledged the commit repeated after a restart",
                self.role, summary.block
            ),
            None => println!(
                "{}: block {}: {} raw bits of {} sessions, {} disclosed ({} differ), {} \
                 reconciled, leak {} + {} bits, H_min {:.0} → key of {} bits",
                self.role,
                summary.block,
                summary.bits,
                summary.sessions,
                summary.sample_bits,
                summary.sample_errors,
                summary.reconciled_bits,
                summary.leak_ec,
                summary.leak_confirmation,
                summary.h_min,
                summary.length
            ),
            // A block a restart aborted has no figures here.
            Some(reason) if summary.bits == 0 => {
                println!("{}: block {}: no key: {reason}", self.role, summary.block);
            }
            Some(reason) => println!(
                "{}: block {}: {} raw bits of {} sessions, no key: {reason}",
                self.role, summary.block, summary.bits, summary.sessions
            ),
        }
        self.report.blocks.push(summary);
    }

    /// Sends `message` as fragments under a fresh message number.
    fn send(
        &mut self,
        transport: &mut Transport,
        message: &postprocess::Message,
    ) -> Result<(), NetError> {
        let bytes = postprocess::encode(message);
        if !postprocess::fits(bytes.len()) {
            return Err(NetError::Usage(format!(
                "a post-processing message of {} bytes exceeds the {} bytes its fragments can \
                 carry: lower postprocess.block_bits",
                bytes.len(),
                postprocess::MAX_MESSAGE_BYTES
            )));
        }
        let number = self.next_message;
        self.next_message = self.next_message.wrapping_add(1);
        for (index, count, chunk) in postprocess::fragments(&bytes) {
            transport.send(
                PostFragment {
                    message: number,
                    index,
                    count,
                    bytes: chunk.to_vec(),
                }
                .into(),
            )?;
        }
        self.report.messages_sent += 1;
        Ok(())
    }

    /// Takes a post-processing fragment from the peer; the message it completes, if any,
    /// goes to the endpoint.
    pub fn receive(&mut self, fragment: &PostFragment) {
        if let Some(whole) = self.reassembler.accept(
            fragment.message,
            fragment.index,
            fragment.count,
            &fragment.bytes,
        ) && let Ok(decoded) = postprocess::decode(&whole)
        {
            self.report.messages_received += 1;
            self.endpoint.frame(decoded);
        }
    }

    /// The report, with the pool, the pending keys and the block in flight as they stand.
    #[must_use]
    pub fn finish(self) -> PostReport {
        let mut report = self.report;
        report.pool_bits = pool_bits(&self.endpoint.snapshot());
        report.pending_keys = self.store.pending();
        report.in_flight = self.endpoint.in_flight();
        report
    }
}

impl PostSide<ControllerPost> {
    /// Drives post-processing until no block is in flight, answering the robot's repeated
    /// closing messages with `courtesy` meanwhile. A robot silent for the silence timeout
    /// leaves its block in flight: the next session settles it (aborted, or its commit
    /// repeated). Returns whether the robot's `Done` came.
    ///
    /// # Errors
    /// The store or the socket fails, or a stop was requested.
    pub fn run(
        &mut self,
        transport: &mut Transport,
        timing: &Timing,
        courtesy: &mut Courtesy<'_>,
    ) -> Result<bool, NetError> {
        let interval = timing.retransmit_interval();
        let mut peer_done = false;
        let mut heard = Instant::now();
        let mut timer = Instant::now() + interval;
        loop {
            if self.flush(transport)? {
                timer = Instant::now() + interval;
            }
            if self.endpoint.is_idle() {
                return Ok(peer_done);
            }
            if heard.elapsed() >= timing.silence_timeout {
                self.report.note = Some(format!(
                    "the robot did not answer post-processing for {:.1} s (does it run with \
                     --store?): the block in flight is settled in the next session",
                    timing.silence_timeout.as_secs_f64()
                ));
                return Ok(peer_done);
            }
            match transport.recv_until(timer)? {
                Some(Delivery::Message(Message::Post(fragment))) => {
                    self.receive(&fragment);
                    heard = Instant::now();
                }
                Some(Delivery::Message(message)) => {
                    // No `Done` yet: it would end the robot's wait for post-processing.
                    peer_done |= courtesy.answer(transport, &message, false)?;
                }
                Some(_) => {}
                None if Instant::now() >= timer => {
                    timer = Instant::now() + interval;
                    let _ = self.endpoint.handle_input(ControllerInput::Timeout);
                }
                None => {}
            }
        }
    }
}

/// Raw bits in a snapshot's pool.
fn pool_bits<S: Snapshot>(snapshot: &S) -> usize {
    snapshot.pool().iter().map(|(_, bits)| bits.len()).sum()
}

/// Prints a key committed in a batch, and whether it is pending.
fn announce_key(key: &StoredKey) {
    let status = match &key.status {
        KeyStatus::Settled => "settled".to_owned(),
        KeyStatus::Pending(reason) => format!("pending ({reason})"),
    };
    println!(
        "{}: key {} committed: {} bits, ε {:.0e}, {status}, secret under: {}",
        key.role, key.id, key.bits, key.epsilon, key.assumption
    );
}

impl PostReport {
    /// What opening the store repaired, in words, if anything.
    #[must_use]
    pub fn recovered(&self) -> Option<String> {
        let r = &self.recovery;
        let parts: Vec<String> = [
            (r.torn_bytes, "torn journal bytes cut"),
            (r.keys_recovered as u64, "committed keys written"),
            (r.keys_settled as u64, "pending keys settled"),
            (r.pending_removed as u64, "aborted pending keys removed"),
            (
                r.pending_superseded as u64,
                "pending keys the journal does not know marked superseded",
            ),
            (
                r.sessions_already_spent as u64,
                "pooled sessions dropped as sources of stored keys",
            ),
        ]
        .iter()
        .filter(|(n, _)| *n > 0)
        .map(|(n, what)| format!("{n} {what}"))
        .collect();
        (!parts.is_empty()).then(|| format!("recovered on opening: {}", parts.join(", ")))
    }

    /// One clause for the agent's terminal line: keys, pending keys, the block in flight and
    /// what the store recovered.
    #[must_use]
    pub fn line(&self) -> String {
        let mut line = format!(
            "post-processing: {} keys committed, {} pending in the store, {} bits pooled",
            self.keys.len(),
            self.pending_keys.len(),
            self.pool_bits
        );
        if let Some(in_flight) = &self.in_flight {
            line += &format!("; left in flight: {in_flight}");
        }
        if let Some(recovered) = self.recovered() {
            line += &format!("; {recovered}");
        }
        line
    }
}
