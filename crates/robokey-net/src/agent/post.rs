//! An agent's post-processing shell (docs/postprocessing.md, "Between the agents"): it opens
//! the store (`--store`) and restores the endpoint from it for the connection to drive, carries
//! out what post-processing asks — store before sending — and reports what happened.

use robokey::Config;
use robokey::connection::{PostEndpoint, PostLink, PostOutput};
use robokey::estimate::BlockEstimate;
use robokey::post_settings::{key_basis, post_settings};
use robokey::protocol::auth::{AuthMode, PairingSecret};
use robokey_secrecy::postprocess::{
    Assumption, BlockReport, LlrProvenance, PostError, SEPARATION_QUANTUM, Settings,
};
use serde::Serialize;

use crate::error::NetError;
use crate::key_store::{KeyLabels, KeyStatus, StoredKey};
use crate::post_store::{PendingKey, PostStore, Snapshot, StoreRecovery};
use crate::random::os_rng;

/// A post-processing endpoint an agent restores from its store.
pub trait StoredEndpoint: PostEndpoint<Snapshot: Snapshot> + Sized {
    /// A fresh endpoint.
    ///
    /// # Errors
    /// Settings out of range.
    fn fresh(settings: Settings, seed: [u8; 32]) -> Result<Self, PostError>;
    /// The endpoint from its stored state.
    ///
    /// # Errors
    /// Settings out of range.
    fn restore(
        snapshot: Self::Snapshot,
        settings: Settings,
        seed: [u8; 32],
    ) -> Result<Self, PostError>;
}

impl StoredEndpoint for robokey_secrecy::postprocess::ControllerPost {
    fn fresh(settings: Settings, seed: [u8; 32]) -> Result<Self, PostError> {
        Self::new(settings, seed)
    }
    fn restore(
        snapshot: Self::Snapshot,
        settings: Settings,
        seed: [u8; 32],
    ) -> Result<Self, PostError> {
        Self::restore(snapshot, settings, seed)
    }
}

impl StoredEndpoint for robokey_secrecy::postprocess::RobotPost {
    fn fresh(settings: Settings, seed: [u8; 32]) -> Result<Self, PostError> {
        Self::new(settings, seed)
    }
    fn restore(
        snapshot: Self::Snapshot,
        settings: Settings,
        seed: [u8; 32],
    ) -> Result<Self, PostError> {
        Self::restore(snapshot, settings, seed)
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
    /// The controller's estimates of the plant during this run, one per block it sized
    /// (measured sizing; empty otherwise).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub estimates: Vec<BlockEstimate>,
    /// The wall time (s) of each block-time computation during this run (the controller's
    /// estimate of the plant, commands check or LLRs, on its worker thread).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub computing_seconds: Vec<f64>,
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

/// One block, as reported (and read back from a report by `robokey eve --block`).
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct BlockSummary {
    /// Block number.
    pub block: u64,
    /// Sessions pooled into it.
    pub sessions: usize,
    /// Their IDs in block order, in hex as the session reports write them (`session`): which
    /// sessions' captures and robot keys make the block's raw bits, in that order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub session_ids: Vec<String>,
    /// Raw bits.
    pub bits: usize,
    /// Bits disclosed to estimate the error rate.
    pub sample_bits: usize,
    /// Disagreements in the sample (controller only).
    pub sample_errors: usize,
    /// Where the sample is in the block's raw bits, in order: public, as the post-processing
    /// messages disclose it (controller only; empty on the robot's side).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sampled: Vec<u32>,
    /// Bits reconciled.
    pub reconciled_bits: usize,
    /// Reconciliation leak (bits): Cascade's parities of both sides, or every LDPC syndrome
    /// bit and 4 bits for the rounds.
    pub leak_ec: u64,
    /// With LDPC reconciliation: the syndrome rounds used (absent with Cascade).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ldpc_rounds: Option<u32>,
    /// With LDPC reconciliation, on the controller: the LLRs it decoded on — `prior`
    /// (online, with the prior) or the model they were recomputed with at block time
    /// (`measured`), and why the prior's stayed where `postprocess.llrs` asked for them
    /// recomputed; absent with Cascade.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub llrs: Option<LlrProvenance>,
    /// Confirmation tags (bits).
    pub leak_confirmation: u64,
    /// Eve's smooth min-entropy under the assumption (bits).
    pub h_min: f64,
    /// The key length ℓ (0: no key).
    pub length: u64,
    /// With the plant measured: the block's worst-case separation as published in
    /// `Confirm` (a multiple of 2⁻⁸), which both sides sized ℓ from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub separation: Option<f64>,
    /// Why no key, if so.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
}

impl From<&BlockReport> for BlockSummary {
    fn from(r: &BlockReport) -> Self {
        Self {
            block: r.block,
            sessions: r.sessions.len(),
            session_ids: r.sessions.iter().map(|id| format!("{id:08x}")).collect(),
            bits: r.bits,
            sample_bits: r.sample_bits,
            sample_errors: r.sample_errors,
            sampled: r.sampled.clone(),
            reconciled_bits: r.reconciled_bits,
            leak_ec: r.leak_ec,
            ldpc_rounds: r.ldpc_rounds,
            llrs: r.llrs.as_deref().cloned(),
            leak_confirmation: r.leak_confirmation,
            h_min: r.h_min,
            length: r.length,
            separation: r
                .separation_steps
                .map(|steps| f64::from(steps) * SEPARATION_QUANTUM),
            reason: r.reason.clone(),
        }
    }
}

/// An agent's store and what its post-processing did.
pub struct AgentStore<E: StoredEndpoint> {
    store: PostStore<E::Snapshot>,
    role: &'static str,
    /// What happened, for the report.
    pub report: PostReport,
}

impl<E: StoredEndpoint> AgentStore<E> {
    /// The post-processing of an agent run with `--store store` (none without), for
    /// `pairing`: post-processing runs only over an authenticated channel. Returns the link
    /// for the connection and the store.
    ///
    /// # Errors
    /// `--store` with `--unauthenticated`, or [`Self::open`]'s.
    pub fn for_agent(
        config: &Config,
        store: Option<&std::path::PathBuf>,
        pairing: &PairingSecret,
        allow_restricted: bool,
    ) -> Result<Option<(PostLink<E>, Self)>, NetError> {
        let Some(dir) = store else {
            return Ok(None);
        };
        if pairing.mode() != AuthMode::Paired {
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
        dir: &std::path::Path,
        pairing: &PairingSecret,
        allow_restricted: bool,
    ) -> Result<(PostLink<E>, Self), NetError> {
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
        let labels = KeyLabels {
            restricted,
            basis: key_basis(config),
        };
        let (store, recovery) = PostStore::open(dir, pairing, labels)?;
        let mut seed = [0_u8; 32];
        rand::RngExt::fill(&mut os_rng()?, &mut seed[..]);
        let endpoint = match recovery.snapshot {
            Some(snapshot) => E::restore(snapshot, settings.clone(), seed),
            None => E::fresh(settings.clone(), seed),
        }
        .map_err(|e| NetError::Usage(format!("post-processing: {e}")))?;
        let report = PostReport {
            store: dir.display().to_string(),
            assumption: match &settings.assumption {
                Assumption::GaussianViews { statement, .. } => format!(
                    "{statement}; each block sized by the largest separation of Eve's view over \
                     its bits, computed by the controller from its samples"
                ),
                Assumption::MeasuredViews {
                    statement,
                    estimation_epsilon,
                    estimate_leak,
                    ..
                } => format!(
                    "{statement}; each block sized by the largest separation of Eve's view over \
                     its bits at the worst case of the (1 − {estimation_epsilon:e}) region of the \
                     plant the controller measures at block time from its samples, published in \
                     Confirm and charged {estimate_leak:.1} bits; ε_est = {estimation_epsilon:e} \
                     is a term of the key's ε"
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
        let link = PostLink::new(endpoint, store.sources().clone(), config);
        let store = Self {
            store,
            role: <E::Snapshot as Snapshot>::ROLE,
            report,
        };
        Ok((link, store))
    }

    /// Carries out what post-processing asks (`endpoint` is the link's, for the pool's size):
    /// stores before anything that follows is sent, and reports.
    ///
    /// # Errors
    /// The store fails.
    pub fn apply(&mut self, output: PostOutput<E::Snapshot>, endpoint: &E) -> Result<(), NetError> {
        match output {
            PostOutput::Persist {
                mut snapshot,
                keys,
                compact,
            } => {
                for key in self.store.persist(&mut snapshot, &keys)? {
                    announce_key(&key);
                    self.report.keys.push(key.id.clone());
                }
                self.report.pool_bits = pool_bits(&snapshot);
                if compact {
                    self.store.compact(&mut snapshot)?;
                }
            }
            PostOutput::Pooled { session, bits } => {
                self.report.session_bits = bits;
                println!(
                    "{}: session {session:08x} pooled: {bits} raw bits, {} in the pool (a block \
                     at {})",
                    self.role,
                    pool_bits(&endpoint.snapshot()),
                    self.report.block_bits
                );
            }
            PostOutput::NotPooled { session, reason } => {
                println!("{}: session {session:08x} not pooled: {reason}", self.role);
                self.report.not_pooled = Some(reason);
            }
            PostOutput::BlockEnded(report) => self.block_ended(&report),
            PostOutput::Estimated(estimate) => {
                match &estimate.refused {
                    Some(why) => println!(
                        "{}: the plant's estimate over {} doublets refuses the block: {why}",
                        self.role, estimate.doublets
                    ),
                    None => println!(
                        "{}: the plant measured over {} doublets: motion noise √Q̂ {:.2} mm, \
                         {:.2} mm, {:.2} mrad, AR(1) correlation between steps ρ̂ {:.3}; over \
                         the (1 − {:e}) region, ρ in [{:.3}, {:.3}], lowest {:.2} mm, {:.2} mm, \
                         {:.2} mrad{}; Eve's largest separation at its worst case {:.4}, her \
                         bits' equivalent {:.4} (published)",
                        self.role,
                        estimate.doublets,
                        estimate.point_std_mm[0],
                        estimate.point_std_mm[1],
                        estimate.point_std_mm[2],
                        estimate.correlation,
                        estimate.epsilon,
                        estimate.correlation_interval[0],
                        estimate.correlation_interval[1],
                        estimate.lower_std_mm[0],
                        estimate.lower_std_mm[1],
                        estimate.lower_std_mm[2],
                        measured_clauses(&estimate),
                        estimate.largest,
                        estimate.separation
                    ),
                }
                self.report.estimates.push(estimate);
            }
            PostOutput::Sent(_) => self.report.messages_sent += 1,
            PostOutput::Received => self.report.messages_received += 1,
            PostOutput::Note(note) => self.report.note = Some(note),
        }
        Ok(())
    }

    /// The report, with the pool, the pending keys and the block in flight as they stand.
    #[must_use]
    pub fn finish(self, endpoint: &E) -> PostReport {
        let mut report = self.report;
        report.pool_bits = pool_bits(&endpoint.snapshot());
        report.pending_keys = self.store.pending();
        report.in_flight = endpoint.in_flight();
        report
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
        if let Some(why) = summary.llrs.as_ref().and_then(|l| l.fallback.as_ref()) {
            println!(
                "{}: block {}: LDPC decoded on the prior's LLRs, not recomputed: {why}",
                self.role, summary.block
            );
        }
        self.report.blocks.push(summary);
    }
}

/// What an estimate measured beside `Q` and ρ, as clauses of the agent's line: the lag's
/// interval (three-step doublets), the slip's with whether the block was sized with it, and
/// the sample-timing jitter's (docs/estimation.md, "Sample-timing jitter").
fn measured_clauses(estimate: &BlockEstimate) -> String {
    let mut clauses = String::new();
    if let Some([tau, low, high]) = estimate.lag {
        clauses += &format!("; lag τ̂ {tau:.4} s [{low:.4}, {high:.4}]");
    }
    if let Some([sigma, low, high]) = estimate.slip {
        let sized = if estimate.slip_sized {
            "sized with it"
        } else {
            "not sized: not seen"
        };
        clauses += &format!(
            "; per-wheel slip σ̂ {:.2} % [{:.2} %, {:.2} %], {sized}",
            100.0 * sigma,
            100.0 * low,
            100.0 * high
        );
    }
    if let Some(&[point, low, high]) = estimate.jitter.as_deref() {
        clauses += &format!(
            "; sample-timing jitter ĵ {:.2} ms [{:.2} ms, {:.2} ms]",
            1e3 * point,
            1e3 * low,
            1e3 * high
        );
    }
    clauses
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The agent's line names each estimate measured beside `Q` and ρ with its interval, the
    /// jitter in milliseconds; nothing for what the block did not measure.
    #[test]
    fn the_line_names_the_lag_the_slip_and_the_jitter_measured() {
        let mut estimate: BlockEstimate = serde_json::from_str(
            r#"{"doublets": 4000, "point_std_mm": [1.0, 1.0, 1.0],
                "lower_std_mm": [0.9, 0.9, 0.9], "correlation": 0.0,
                "correlation_interval": [-0.02, 0.03], "epsilon": 1e-6,
                "separation": 0.5, "largest": 0.6}"#,
        )
        .unwrap();
        assert_eq!(measured_clauses(&estimate), "");
        estimate.lag = Some([0.0499, 0.0481, 0.0513]);
        estimate.slip = Some([0.0, 0.0, 0.012]);
        estimate.jitter = Some(Box::new([0.00470, 0.0, 0.00693]));
        assert_eq!(
            measured_clauses(&estimate),
            "; lag τ̂ 0.0499 s [0.0481, 0.0513]; per-wheel slip σ̂ 0.00 % [0.00 %, 1.20 %], \
             not sized: not seen; sample-timing jitter ĵ 4.70 ms [0.00 ms, 6.93 ms]"
        );
    }
}
