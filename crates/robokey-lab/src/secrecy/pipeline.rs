//! The post-processing that ships, run on simulated sessions (docs/secrecy.md): which
//! sessions are pooled, and — for `complete` pooling — the post-processing endpoints the
//! agents run (`robokey_secrecy::postprocess`), driven in memory. ℓ comes from the stated
//! assumption, as in a deployment; Eve's realised view gives a diagnostic beside it.

use std::collections::BTreeMap;

use rand::RngExt;
use rand::rngs::ChaCha8Rng;
use robokey::config::EveStrategy;
use robokey::protocol::Outcome;
use robokey::sim::RunOutput;
use robokey_secrecy::BitString;
use robokey_secrecy::CascadeSchedule;
use robokey_secrecy::confirm::TAG_BITS;
use robokey_secrecy::interval::clopper_pearson_lower;
use robokey_secrecy::min_entropy::{
    binomial_smooth_min_entropy, output_length, posterior_smooth_min_entropy,
};
use robokey_secrecy::postprocess::{
    AbortReason, Assumption, BlockReport, ControllerInput, ControllerPost, EstimateRefusal,
    LlrProvenance, Message, Output, ReconciliationMethod, RobotInput, RobotPost, SessionSamples,
    Settings, StagedSession,
};
use robokey_secrecy::view_profile::{equivalent_separation, separation_counts};
use serde::{Deserialize, Serialize};
use zeroize::Zeroizing;

use robokey::Config;
use robokey::config::LlrModel;
use robokey::estimate::{BlockEstimate, llr_answer};

/// Which sessions are pooled, and what was published over their keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Pooling {
    /// What today's agents do (session protocol v1): each side publishes a 64-bit tag over
    /// its session key and only sessions whose tags matched are kept. Their keys already
    /// agree, so nothing is reconciled, but both directional key tags of every pooled session (2 × 128 bits)
    /// are charged.
    Confirmed,
    /// The pipeline of the authenticated session (the session is confirmed over its
    /// transcript, not its key): every session both sides completed is pooled and run
    /// through the post-processing endpoints — a disclosed random sample estimates the error
    /// rate and is removed, Cascade reconciles with both sides' parities charged, the block
    /// is confirmed by two 64-bit tags (128 bits) and committed in two phases.
    Complete,
}

impl Pooling {
    /// The name used on the command line and in reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Confirmed => "confirmed",
            Self::Complete => "complete",
        }
    }

    /// Whether `run`'s keys enter the pool.
    #[must_use]
    pub fn admits(self, run: &RunOutput) -> bool {
        let (robot, controller) = (&run.robot_outcome, &run.controller_outcome);
        let same_positions = run.keys.robot.len() == run.keys.controller.len();
        let admitted = match self {
            Self::Confirmed => {
                robot == &Some(Outcome::Confirmed) && controller == &Some(Outcome::Confirmed)
            }
            Self::Complete => {
                let finished = |o: &Option<Outcome>| {
                    matches!(
                        o,
                        Some(Outcome::Confirmed | Outcome::Kept | Outcome::Unconfirmed(_))
                    )
                };
                finished(robot) && finished(controller) && same_positions
            }
        };
        admitted && !run.keys.robot.is_empty()
    }
}

/// Bits of confirmation tags published per post-processing block: one 64-bit tag each way.
pub const CONFIRMATION_BITS: u64 = 2 * TAG_BITS;

/// Bits of key tags the agents publish per confirmed session: one directional 128-bit
/// tag each way over the raw key (docs/wire.md). The session tags do not depend on the key.
pub const SESSION_KEY_TAG_BITS: u64 = 2 * 8 * robokey::protocol::TAG_BYTES as u64;

/// How the realised diagnostic bounds Eve's smooth min-entropy: from her realised hard
/// decisions with the binomial bound. Labelled an approximation wherever it appears.
pub const H_MIN_BINOMIAL: &str = "binomial bound on Eve's realised hard-decision errors \
    on the block's raw bits (approximation: i.i.d. errors; ignores her soft values, her \
    patterns and where her errors fall)";

/// How the realised diagnostic bounds Eve's smooth min-entropy in private sensing: from her
/// own per-bit posteriors (true-noise likelihood, calibration-tested).
pub const H_MIN_POSTERIOR: &str = "posterior bound on Eve's calibrated per-bit posteriors \
    (bits independent given her view: checked against her exact joint posterior on short \
    records)";

/// The pooled raw bits of whole sessions, in session order: the robot's key is the
/// reference, the controller's is corrected, Eve's is her guess of the same positions.
#[derive(Default)]
pub struct Pool {
    /// Sessions pooled.
    pub sessions: u32,
    /// Raw bits of each session pooled.
    pub lengths: Vec<usize>,
    /// Index of the last session pooled.
    pub last_session: usize,
    /// The robot's bits.
    pub robot: Zeroizing<Vec<u8>>,
    /// The controller's bits.
    pub controller: Zeroizing<Vec<u8>>,
    /// Eve's bits.
    pub eve: Zeroizing<Vec<u8>>,
    /// Private sensing: Eve's calibrated posterior error probability of each bit.
    pub eve_posteriors: Vec<f64>,
    /// Private sensing: each pooled session's controller LLRs, one per bit,
    /// `ln P(view|0) − ln P(view|1)` (empty for a session without), which LDPC
    /// reconciliation decodes on.
    pub controller_llrs: Vec<Vec<f64>>,
    /// Indices (into the runs) of the sessions pooled, in order.
    pub runs: Vec<usize>,
    /// Private sensing: each pooled session's bits' Eve separations — under the camera
    /// statement, or at the worst case of the block's estimate (measured sizing) — that size
    /// the key per bit (empty: the assumption's separation alone sizes it).
    pub separations: Vec<Vec<f64>>,
    /// Measured sizing: the block's estimate.
    pub estimate: Option<BlockEstimate>,
    /// LLRs recomputed at block time: what the controller keeps of each pooled session's
    /// doublets (empty otherwise), as the agents' pool keeps them.
    pub kept: Vec<SessionSamples>,
    /// LLRs recomputed at block time for a multilevel slice ([`Self::slices`]): each pooled
    /// session's staged material as the agents' controller holds it at the slice's block
    /// (the lower slices' bits — the robot's, which a reconciled slice gives the controller —
    /// and the kept doublets; empty otherwise).
    pub staged: Vec<StagedSession>,
}

/// Groups the admitted sessions of `runs`, in order, into pools of at least `block_bits`
/// bits each (whole sessions, so a session's published tags fall in one block); in private
/// sensing with `adversary`'s posteriors.
#[must_use]
pub fn pools(
    runs: &[RunOutput],
    pooling: Pooling,
    block_bits: usize,
    adversary: EveStrategy,
) -> Vec<Pool> {
    let mut full = Vec::new();
    let mut pool = Pool::default();
    for (index, run) in runs.iter().enumerate() {
        if !pooling.admits(run) {
            continue;
        }
        let keys = &run.keys;
        pool.robot.extend_from_slice(&keys.robot);
        pool.controller.extend_from_slice(&keys.controller);
        let eve = eve_key(run, adversary);
        // A position Eve made no guess for counts as known to her: the cautious side.
        pool.eve
            .extend((0..keys.robot.len()).map(|i| eve.get(i).copied().unwrap_or(keys.robot[i])));
        if let Some(private) = &run.private {
            pool.eve_posteriors.extend(private.bits.iter().map(|b| {
                let llr = b.llr_of(adversary);
                1.0 / (1.0 + llr.abs().exp())
            }));
        }
        pool.controller_llrs.push(match &run.private {
            Some(private) if private.bits.len() == keys.robot.len() => {
                private.bits.iter().map(|b| b.controller).collect()
            }
            _ => Vec::new(),
        });
        pool.sessions += 1;
        pool.runs.push(index);
        pool.lengths.push(keys.robot.len());
        pool.last_session = index;
        if pool.robot.len() >= block_bits {
            full.push(std::mem::take(&mut pool));
        }
    }
    full
}

/// Eve's key of `run` as `adversary` hears it (empty when she has none): in private
/// sensing that eavesdropper's (one simulation carries both), else the run's.
#[must_use]
pub fn eve_key(run: &RunOutput, adversary: EveStrategy) -> &[u8] {
    match &run.private {
        Some(private) => private.eve_key(adversary),
        None => run.keys.eve.as_ref(),
    }
    .map_or(&[][..], |key| key.as_slice())
}

/// Eve's realised view of a block: a diagnostic beside the assumption, never what sizes the
/// key.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Realised {
    /// Eve's errors against the robot's raw bits of the block.
    pub eve_errors: usize,
    /// Lower confidence bound (level 1 − ε_PE) of her error rate.
    pub eve_error_lower: f64,
    /// w* of the binomial bound.
    pub w_star: u64,
    /// The smooth min-entropy bound from her realised errors (bits).
    pub h_min: f64,
    /// How.
    pub h_min_method: String,
    /// ℓ that bound would support with the block's leak.
    pub secret_bits: u64,
}

/// One privacy-amplification block, with every public bit it cost.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Block {
    /// Sessions pooled.
    pub sessions: u32,
    /// Raw bits pooled.
    pub bits: usize,
    /// Disagreements between the controller's and the robot's bits before reconciliation
    /// (the simulator's view: no party knows it).
    pub errors_before: usize,
    /// Positions disclosed to estimate the error rate (removed from the key).
    pub sample_bits: usize,
    /// Disagreements in the disclosed sample.
    pub sample_errors: usize,
    /// The error-rate estimate that sizes reconciliation.
    pub q_estimate: f64,
    /// Where `q_estimate` comes from.
    pub q_source: String,
    /// Bits reconciled and amplified: `bits − sample_bits`.
    pub reconciled_bits: usize,
    /// Post-processing messages, both directions (retransmissions included).
    pub messages: u32,
    /// Their payload bits.
    pub message_bits: u64,
    /// Reconciliation leak: with Cascade both sides' parities; with LDPC every syndrome bit
    /// and ⌈log₂ 9⌉ = 4 bits for the rounds.
    pub leak_ec: u64,
    /// With LDPC reconciliation: `ldpc` and the syndrome rounds used (absent with Cascade).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ldpc_rounds: Option<u32>,
    /// With LDPC reconciliation: the LLRs the controller decoded on — `prior` (online, with
    /// the prior) or the model they were recomputed with at block time (`measured`,
    /// `world`), and why the prior's stayed where recomputation was asked for; absent with
    /// Cascade, which reads no LLRs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub llrs: Option<LlrProvenance>,
    /// Confirmation tags published over pooled key bits (per-session or per-block).
    pub leak_confirmation: u64,
    /// leak_ec + leak_confirmation.
    pub leak: u64,
    /// Whether both sides committed the same key, or neither did.
    pub consistent: bool,
    /// Eve's smooth min-entropy under the stated assumption (bits).
    pub h_min: f64,
    /// The assumption it comes from.
    pub h_min_method: String,
    /// ℓ under the assumption: the key the agents would make.
    pub secret_bits: u64,
    /// Why ℓ = 0, and whether pooling more could help.
    pub reason: Option<String>,
    /// Eve's realised view: the diagnostic.
    pub realised: Realised,
    /// The assumption credits more than the realised view of this adversary supports.
    pub assumption_exceeds_realised: bool,
    /// Measured sizing: what the controller measured for the block.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimate: Option<BlockEstimate>,
    /// Whether the block ended for failed reconciliation (so a multilevel block's later
    /// slices, decoded given it, cannot be either).
    #[serde(skip)]
    pub failed_reconciliation: bool,
}

/// Settings of post-processing in the simulator.
#[derive(Clone, Debug)]
pub struct BlockSettings {
    /// Which sessions are pooled.
    pub pooling: Pooling,
    /// ε per term (smoothing, amplification, parameter estimation).
    pub epsilon: f64,
    /// Largest disclosed sample (at most a tenth of the block).
    pub sample_bits: usize,
    /// Least raw bits per block.
    pub block_bits: usize,
    /// What is assumed about Eve.
    pub assumption: Assumption,
    /// How `complete` pooling reconciles.
    pub reconciliation: ReconciliationMethod,
    /// LDPC: the LLRs recomputed at block time from the pools' kept samples with this
    /// model under the parties' configuration (docs/estimation.md, "Causality"); none: the
    /// prior's, pooled with the sessions.
    pub block_llrs: Option<(Config, LlrModel)>,
}

/// Runs the pools through the pipeline of `settings.pooling`; `public` seeds the
/// endpoints' nonces.
#[must_use]
pub fn post_process(
    pools: &[Pool],
    settings: &BlockSettings,
    public: &mut ChaCha8Rng,
) -> Vec<Block> {
    match settings.pooling {
        Pooling::Confirmed => pools
            .iter()
            .map(|pool| tagged_sessions(pool, settings))
            .collect(),
        Pooling::Complete => through_endpoints(pools, settings, public),
    }
}

/// Today's agents: keys confirmed per session, nothing reconciled, every tag charged.
fn tagged_sessions(pool: &Pool, settings: &BlockSettings) -> Block {
    let n = pool.robot.len();
    let leak_confirmation = u64::from(pool.sessions) * SESSION_KEY_TAG_BITS;
    let h_min = settings
        .assumption
        .for_block(pool.equivalent_separation(settings.epsilon))
        .h_min(n as u64, settings.epsilon);
    let length = output_length(h_min, 0, leak_confirmation, settings.epsilon).ok();
    let mut block = Block {
        sessions: pool.sessions,
        bits: n,
        errors_before: disagreements(&pool.robot, &pool.controller),
        sample_bits: 0,
        sample_errors: 0,
        q_estimate: 0.0,
        q_source: "every pooled session's key tags matched: nothing to reconcile".into(),
        reconciled_bits: n,
        messages: 0,
        message_bits: 0,
        leak_ec: 0,
        ldpc_rounds: None,
        llrs: None,
        leak_confirmation,
        leak: leak_confirmation,
        consistent: pool.robot == pool.controller,
        h_min,
        h_min_method: settings.assumption.describe(),
        secret_bits: length.as_ref().map_or(0, |l| l.bits),
        reason: length.and_then(|l| l.reason),
        realised: realised(pool, &[], n, 0, leak_confirmation, settings.epsilon),
        assumption_exceeds_realised: false,
        estimate: None,
        failed_reconciliation: false,
    };
    finish(&mut block, settings, None);
    block
}

/// The `complete` pipeline: every pooled session handed to the two endpoints, in order,
/// messages delivered in memory until both are quiet.
fn through_endpoints(
    pools: &[Pool],
    settings: &BlockSettings,
    public: &mut ChaCha8Rng,
) -> Vec<Block> {
    let protocol = Settings {
        block_bits: settings.block_bits,
        sample_bits: settings.sample_bits,
        epsilon: settings.epsilon,
        schedule: CascadeSchedule::BICONF,
        assumption: settings.assumption.clone(),
        reconciliation: settings.reconciliation,
    };
    let (Ok(mut controller), Ok(mut robot)) = (
        ControllerPost::new(protocol.clone(), public.random()),
        RobotPost::new(protocol, public.random()),
    ) else {
        return Vec::new();
    };
    let ldpc = matches!(settings.reconciliation, ReconciliationMethod::Ldpc(_));
    controller.recompute_llrs(ldpc && settings.block_llrs.is_some());
    // What the controller kept of each session, and a slice's staged material, by its ID
    // (the sessions in order).
    let kept: Vec<Option<&SessionSamples>> = pools
        .iter()
        .flat_map(|p| (0..p.lengths.len()).map(|i| p.kept.get(i)))
        .collect();
    let staged: Vec<Option<&StagedSession>> = pools
        .iter()
        .flat_map(|p| (0..p.lengths.len()).map(|i| p.staged.get(i)))
        .collect();
    for (id, (((robot_bits, controller_bits), separations), llrs)) in pools
        .iter()
        .flat_map(|p| {
            let separations = p
                .separations
                .iter()
                .cloned()
                .chain(std::iter::repeat(Vec::new()));
            // Only LDPC decodes on them (Cascade's pool would only carry them).
            let llrs = p
                .controller_llrs
                .iter()
                .filter(|_| ldpc)
                .cloned()
                .chain(std::iter::repeat(Vec::new()));
            p.session_bits().into_iter().zip(separations).zip(llrs)
        })
        .enumerate()
    {
        let id = id as u32;
        let _ = robot.handle_input(RobotInput::Session {
            id,
            bits: robot_bits,
        });
        let _ = controller.handle_input(ControllerInput::Session {
            id,
            bits: controller_bits,
            // Configured sizing: the camera statement's per-bit separations; measured: the
            // bits' at their block's worst case (the block's estimate is answered below,
            // when the controller asks, and sizes the key).
            separations,
            samples: Vec::new(),
            llrs,
        });
    }
    let mut controller_reports = Vec::new();
    let mut robot_reports = BTreeMap::new();
    // Why the controller ended a block without a key, when it did.
    let mut aborted: BTreeMap<u64, AbortReason> = BTreeMap::new();
    let mut keys = (Vec::new(), Vec::new());
    let (mut to_robot, mut to_controller): (Vec<Message>, Vec<Message>) = (Vec::new(), Vec::new());
    loop {
        while let Some(output) = controller.poll_output() {
            match output {
                Output::Transmit(m) => {
                    if let Message::Abort { block, reason, .. } = &m {
                        aborted.insert(*block, *reason);
                    }
                    to_robot.push(m);
                }
                Output::BlockEnded(report) => controller_reports.push(report),
                Output::KeyCommitted(key) => keys.0.push(key),
                Output::LlrsNeeded(mut request) => {
                    // The agents' computation on what their pool keeps
                    // (`estimate::block_llrs`): the lab's pools keep the samples beside.
                    for (id, _, samples) in &mut request.sessions {
                        if let Some(Some(session)) = kept.get(*id as usize) {
                            samples.clone_from(session);
                        }
                    }
                    request.staged = request
                        .sessions
                        .iter()
                        .filter_map(|(id, ..)| staged.get(*id as usize).copied().flatten())
                        .cloned()
                        .collect();
                    let llrs = settings.block_llrs.as_ref().map_or_else(
                        || Err("no model to recompute the LLRs with".to_owned()),
                        |(config, basis)| llr_answer(config, &request, *basis),
                    );
                    let _ = controller.handle_input(ControllerInput::Llrs {
                        block: request.block,
                        llrs,
                    });
                }
                Output::EstimateNeeded(request) => {
                    // The block's estimate, computed from the same samples and robot bits
                    // before (blocks are the pools, in order).
                    let outcome = pools
                        .get(request.block as usize)
                        .and_then(|pool| pool.estimate.as_ref())
                        .map_or_else(
                            || {
                                Err(EstimateRefusal(
                                    "no estimate of the plant for the block".into(),
                                ))
                            },
                            BlockEstimate::outcome,
                        );
                    let _ = controller.handle_input(ControllerInput::Estimate {
                        block: request.block,
                        outcome,
                    });
                }
                // The lab's slices are pooled whole (`Pool::slices`), none staged.
                Output::Persist
                | Output::Ignored(_)
                | Output::SliceReconciled(_)
                | Output::SlicesEstimateNeeded(_) => {}
            }
        }
        while let Some(output) = robot.poll_output() {
            match output {
                Output::Transmit(m) => to_controller.push(m),
                Output::BlockEnded(report) => {
                    robot_reports.insert(report.block, report);
                }
                Output::KeyCommitted(key) => keys.1.push(key),
                Output::Persist
                | Output::Ignored(_)
                | Output::EstimateNeeded(_)
                | Output::LlrsNeeded(_)
                | Output::SliceReconciled(_)
                | Output::SlicesEstimateNeeded(_) => {}
            }
        }
        if to_robot.is_empty() && to_controller.is_empty() {
            break;
        }
        for m in std::mem::take(&mut to_robot) {
            let _ = robot.handle_input(RobotInput::Frame(m));
        }
        for m in std::mem::take(&mut to_controller) {
            let _ = controller.handle_input(ControllerInput::Frame(m));
        }
    }
    controller_reports
        .iter()
        .zip(pools)
        .map(|(report, pool)| {
            let committed = |list: &Vec<robokey_secrecy::postprocess::FinalKey>| {
                list.iter()
                    .find(|k| k.block == report.block)
                    .map(|k| k.key.clone())
            };
            let consistent = committed(&keys.0) == committed(&keys.1);
            endpoint_block(
                report,
                robot_reports.get(&report.block),
                pool,
                consistent,
                aborted.get(&report.block).copied(),
                settings,
            )
        })
        .collect()
}

/// A block from the endpoints' reports; `aborted`: why the controller ended it without a
/// key, if it did.
fn endpoint_block(
    report: &BlockReport,
    robot: Option<&BlockReport>,
    pool: &Pool,
    consistent: bool,
    aborted: Option<AbortReason>,
    settings: &BlockSettings,
) -> Block {
    let leak = report.leak_ec + report.leak_confirmation;
    let mut block = Block {
        sessions: pool.sessions,
        bits: report.bits,
        errors_before: disagreements(&pool.robot, &pool.controller),
        sample_bits: report.sample_bits,
        sample_errors: report.sample_errors,
        q_estimate: report.q_estimate,
        q_source: format!(
            "disclosed random sample of {} positions ({} disagreed), removed from the key",
            report.sample_bits, report.sample_errors
        ),
        reconciled_bits: report.reconciled_bits,
        messages: report.messages_sent + robot.map_or(0, |r| r.messages_sent),
        message_bits: report.bits_sent + robot.map_or(0, |r| r.bits_sent),
        leak_ec: report.leak_ec,
        ldpc_rounds: report.ldpc_rounds,
        llrs: report.llrs.as_deref().cloned(),
        leak_confirmation: report.leak_confirmation,
        leak,
        consistent,
        h_min: report.h_min,
        h_min_method: report
            .assumption
            .as_deref()
            .unwrap_or(&settings.assumption)
            .describe(),
        secret_bits: report.length,
        reason: report.reason.clone(),
        realised: realised(
            pool,
            &report.sampled,
            report.reconciled_bits,
            report.leak_ec,
            2 * TAG_BITS,
            settings.epsilon,
        ),
        assumption_exceeds_realised: false,
        estimate: pool.estimate.clone(),
        failed_reconciliation: aborted == Some(AbortReason::Reconciliation),
    };
    finish(&mut block, settings, aborted);
    if let Some(why) = pool.estimate.as_ref().and_then(|e| e.refused.clone()) {
        // Refused outside the model class: no pooling advice, the class does not cover it.
        block.reason = Some(format!("block refused: {why}"));
    }
    block
}

/// Flags an assumption that credits more than the realised view, and adds pooling advice.
fn finish(block: &mut Block, settings: &BlockSettings, aborted: Option<AbortReason>) {
    block.assumption_exceeds_realised = block.secret_bits > block.realised.secret_bits;
    if block.secret_bits == 0
        && let Some(why) = block.reason.as_mut()
    {
        why.push_str(&match aborted {
            None | Some(AbortReason::NoSecretBits) => pooling_advice(
                settings,
                block.sessions,
                block.reconciled_bits,
                block.h_min,
                block.leak_ec,
            ),
            Some(AbortReason::Reconciliation) => "; the block failed reconciliation (the two \
                 sides' keys still differed, or Cascade could not finish, or LDPC could not \
                 decode): it is discarded, not short, so pooling more does not help; the next \
                 block starts afresh"
                .to_owned(),
            Some(AbortReason::PlantRefused) => "; the controller's estimate of the plant refused \
                 it (outside the model class): pooling more does not help"
                .to_owned(),
            Some(AbortReason::Refused | AbortReason::Restart) => "; the block was ended by the \
                 protocol (refused or restarted), not for want of secrecy: pooling more does \
                 not help"
                .to_owned(),
        });
    }
}

fn disagreements(a: &[u8], b: &[u8]) -> usize {
    a.iter().zip(b).filter(|(x, y)| x != y).count()
}

/// Eve's realised view of a block: from her calibrated posteriors when she has them
/// on the positions kept after the disclosed `sampled` ones (private sensing), else from
/// her realised errors on the block's raw bits with the binomial bound on `n` reconciled
/// bits; and the ℓ that would support.
fn realised(
    pool: &Pool,
    sampled: &[u32],
    n: usize,
    leak_ec: u64,
    tags: u64,
    epsilon: f64,
) -> Realised {
    let errors = disagreements(&pool.robot, &pool.eve);
    let total = pool.robot.len().max(1) as u64;
    let lower = clopper_pearson_lower(errors as u64, total, epsilon)
        .unwrap_or(0.0)
        .min(0.5);
    let (h_min, w_star, method) = if pool.eve_posteriors.is_empty() {
        let bound = binomial_smooth_min_entropy(n as u64, lower, epsilon).ok();
        (
            bound.as_ref().map_or(0.0, |b| b.h_min),
            bound.map_or(0, |b| b.w_star),
            H_MIN_BINOMIAL,
        )
    } else {
        let mut disclosed = sampled.iter().map(|&i| i as usize).peekable();
        let q: Vec<f64> = pool
            .eve_posteriors
            .iter()
            .enumerate()
            .filter(|&(i, _)| disclosed.next_if_eq(&i).is_none())
            .map(|(_, &q)| q.min(1.0 - q))
            .collect();
        debug_assert_eq!(q.len(), n, "kept positions and reconciled bits disagree");
        let bound = posterior_smooth_min_entropy(&q, epsilon).ok();
        (bound.map_or(0.0, |b| b.h_min), 0, H_MIN_POSTERIOR)
    };
    Realised {
        eve_errors: errors,
        eve_error_lower: lower,
        w_star,
        h_min,
        h_min_method: method.to_owned(),
        secret_bits: output_length(h_min, leak_ec, tags, epsilon).map_or(0, |l| l.bits),
    }
}

/// A multilevel block's slices decode given the earlier slices' reconciled bits: when
/// one of a pool's `slices` consecutive blocks failed reconciliation, the later ones cannot
/// be decoded and yield no key.
pub fn fail_later_slices(blocks: &mut [Block], slices: usize) {
    for group in blocks.chunks_mut(slices) {
        let Some(first) = group.iter().position(|b| b.failed_reconciliation) else {
            continue;
        };
        for block in &mut group[first + 1..] {
            block.secret_bits = 0;
            block.failed_reconciliation = true;
            block.assumption_exceeds_realised = false;
            block.reason = Some(
                "an earlier slice of the block failed reconciliation: this slice's LLRs are \
                 conditioned on it"
                    .to_owned(),
            );
        }
    }
}

impl Pool {
    /// The pool's multilevel slices (docs/secrecy.md, "Multilevel doublets"): slice `s`
    /// holds the bits at place `s` of every symbol's label (`m` = `slices` bits per symbol,
    /// `key_bits` per doublet, bit `i` of a session at place `(i mod key_bits) mod m`),
    /// each session's in order, with the controller's LLRs given the lower slices and its
    /// decisions their signs. The first slice counts the pool's sessions, the others none
    /// (the same sessions). With the pool's kept doublets each slice carries its sessions'
    /// staged material, for LLRs recomputed at block time.
    #[must_use]
    pub fn slices(&self, key_bits: usize, slices: usize) -> Vec<Self> {
        let slicing = robokey_secrecy::postprocess::Slicing {
            key_bits: key_bits as u8,
            slices: slices as u8,
        };
        let place = |i: usize| slicing.slice_of(i);
        (0..slices)
            .map(|slice| {
                let mut out = Self {
                    sessions: if slice == 0 { self.sessions } else { 0 },
                    last_session: self.last_session,
                    runs: self.runs.clone(),
                    ..Self::default()
                };
                let mut start = 0;
                for (session, &len) in self.lengths.iter().enumerate() {
                    let picked: Vec<usize> = (0..len).filter(|&i| place(i) == slice).collect();
                    let llrs = self.controller_llrs.get(session).filter(|l| l.len() == len);
                    let pick =
                        |all: &[u8]| picked.iter().map(|&i| all[start + i]).collect::<Vec<_>>();
                    out.robot.extend(pick(&self.robot));
                    out.eve.extend(pick(&self.eve));
                    match llrs {
                        Some(llrs) => out
                            .controller
                            .extend(picked.iter().map(|&i| u8::from(llrs[i] < 0.0))),
                        None => out.controller.extend(pick(&self.controller)),
                    }
                    if self.eve_posteriors.len() == self.robot.len() {
                        out.eve_posteriors
                            .extend(picked.iter().map(|&i| self.eve_posteriors[start + i]));
                    }
                    out.controller_llrs.push(
                        llrs.map(|l| picked.iter().map(|&i| l[i]).collect())
                            .unwrap_or_default(),
                    );
                    if let Some(separations) = self.separations.get(session) {
                        out.separations.push(if separations.len() == len {
                            picked.iter().map(|&i| separations[i]).collect()
                        } else {
                            separations.clone()
                        });
                    }
                    if let Some(kept) = self.kept.get(session) {
                        out.staged.push(StagedSession {
                            session: session as u32,
                            slice: slice as u8,
                            slicing,
                            likelihoods: Vec::new(),
                            separations: Vec::new(),
                            known: BitString::from_bools(&Zeroizing::new(
                                (0..len)
                                    .map(|i| place(i) < slice && self.robot[start + i] == 1)
                                    .collect::<Vec<bool>>(),
                            )),
                            samples: kept.clone(),
                        });
                    }
                    out.lengths.push(picked.len());
                    start += len;
                }
                out
            })
            .collect()
    }

    /// Each pooled session's (robot, controller) bits, in order.
    /// The equivalent separation of the pool's bits (millionths) at smoothing `epsilon`,
    /// nothing disclosed: as the controller's endpoint finds it for a block.
    fn equivalent_separation(&self, epsilon: f64) -> u64 {
        let mut counts = BTreeMap::new();
        for (separations, &bits) in self.separations.iter().zip(&self.lengths) {
            for (d, n) in separation_counts(separations, bits) {
                *counts.entry(d).or_insert(0_u64) += n;
            }
        }
        let largest = counts.keys().next_back().copied().unwrap_or(0);
        equivalent_separation(&counts, 0, epsilon).unwrap_or(largest)
    }

    fn session_bits(&self) -> Vec<(BitString, BitString)> {
        let mut out = Vec::new();
        let mut start = 0;
        for &len in &self.lengths {
            let take = |key: &[u8]| -> BitString {
                let bits: Zeroizing<Vec<bool>> =
                    Zeroizing::new(key[start..start + len].iter().map(|&b| b == 1).collect());
                BitString::from_bools(&bits)
            };
            out.push((take(&self.robot), take(&self.controller)));
            start += len;
        }
        out
    }
}

/// Whether a larger block could give ℓ > 0: only if Eve's min-entropy per raw bit exceeds
/// the leak that grows with the block (reconciliation, and per-session tags when they are
/// published); then the fixed costs (a block tag, 2·log₂(1/ε_PA) − 2) fade.
fn pooling_advice(
    settings: &BlockSettings,
    sessions: u32,
    bits: usize,
    h_min: f64,
    leak_ec: u64,
) -> String {
    let growing = leak_ec
        + match settings.pooling {
            Pooling::Confirmed => u64::from(sessions) * SESSION_KEY_TAG_BITS,
            Pooling::Complete => 0,
        };
    let fixed = match settings.pooling {
        Pooling::Confirmed => 0.0,
        Pooling::Complete => CONFIRMATION_BITS as f64,
    } + 2.0 * (1.0 / settings.epsilon).log2()
        - 2.0;
    let n = bits.max(1) as f64;
    let (entropy_rate, leak_rate) = (h_min / n, growing as f64 / n);
    if entropy_rate > leak_rate {
        let needed = fixed / (entropy_rate - leak_rate);
        format!(
            "; pooling more can help: Eve's min-entropy ({entropy_rate:.4} bit per raw bit) \
             exceeds the leak that grows with the block ({leak_rate:.4}), so blocks of about \
             {needed:.0} bits would cover the fixed {fixed:.0} bits"
        )
    } else {
        format!(
            "; pooling cannot help: Eve's min-entropy ({entropy_rate:.4} bit per raw bit) \
             grows no faster than the leak ({leak_rate:.4} bit per raw bit)"
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A block of `n` agreeing bits (Eve wrong on every other one) finished as the
    /// controller ended it: `aborted`, with `why`.
    fn ended(n: usize, why: &str, aborted: Option<AbortReason>) -> Block {
        let settings = BlockSettings {
            pooling: Pooling::Complete,
            epsilon: 1e-6,
            sample_bits: 0,
            block_bits: n,
            assumption: Assumption::IndependentErrors { error_rate: 0.2 },
            reconciliation: ReconciliationMethod::Cascade,
            block_llrs: None,
        };
        let bits: Vec<u8> = (0..n).map(|i| (i % 2) as u8).collect();
        let pool = Pool {
            eve: Zeroizing::new(bits.iter().map(|b| 1 - b).collect()),
            robot: Zeroizing::new(bits.clone()),
            controller: Zeroizing::new(bits),
            sessions: 1,
            lengths: vec![n],
            ..Pool::default()
        };
        let mut block = tagged_sessions(&pool, &settings);
        block.secret_bits = 0;
        block.reason = Some(why.to_owned());
        finish(&mut block, &settings, aborted);
        block
    }

    #[test]
    fn a_block_failing_reconciliation_says_so_and_gives_no_pooling_advice() {
        let block = ended(
            2_000,
            "the robot's tag differs: the reconciled keys differ",
            Some(AbortReason::Reconciliation),
        );
        let why = block.reason.unwrap();
        assert!(why.contains("the robot's tag differs"), "{why}");
        assert!(why.contains("failed reconciliation"), "{why}");
        assert!(why.contains("pooling more does not help"), "{why}");
        assert!(!why.contains("pooling more can help"), "{why}");
    }

    #[test]
    fn a_block_refused_by_the_protocol_gives_no_pooling_advice() {
        let why = ended(
            2_000,
            "the robot refused the block",
            Some(AbortReason::Refused),
        )
        .reason
        .unwrap();
        assert!(why.contains("not for want of secrecy"), "{why}");
        assert!(!why.contains("pooling more can help"), "{why}");
    }

    /// The lab's `complete` pipeline with LDPC: the controller's LLRs of each session go to
    /// its endpoint, both sides commit the same key, and the block's leak is the robot's
    /// syndrome (+ 4 bits for the rounds), far below Cascade's on the same pool.
    #[test]
    fn ldpc_in_the_lab_makes_the_same_key_with_less_leak_than_cascade() {
        use rand::SeedableRng;
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (sessions, length) = (8, 1_500);
        let mut pool = Pool {
            sessions,
            lengths: vec![length; sessions as usize],
            ..Pool::default()
        };
        for _ in 0..sessions {
            let mut llrs = Vec::new();
            for _ in 0..length {
                let bit = u8::from(rng.random::<bool>());
                // A calibrated LLR erring at 2 %: |L| = ln(0.98/0.02), the sign wrong with
                // probability 0.02.
                let wrong = rng.random::<f64>() < 0.02;
                let magnitude = (0.98_f64 / 0.02).ln();
                let says_one = (bit == 1) != wrong;
                llrs.push(if says_one { -magnitude } else { magnitude });
                pool.robot.push(bit);
                pool.controller.push(u8::from(says_one));
                pool.eve.push(bit);
            }
            pool.controller_llrs.push(llrs);
        }
        let settings = |reconciliation| BlockSettings {
            pooling: Pooling::Complete,
            epsilon: 1e-6,
            sample_bits: 100,
            block_bits: 10_000,
            assumption: Assumption::IndependentErrors { error_rate: 0.3 },
            reconciliation,
            block_llrs: None,
        };
        let run = |reconciliation| {
            let blocks = post_process(
                std::slice::from_ref(&pool),
                &settings(reconciliation),
                &mut ChaCha8Rng::seed_from_u64(1),
            );
            assert_eq!(blocks.len(), 1);
            blocks.into_iter().next().unwrap()
        };
        let ldpc = run(ReconciliationMethod::Ldpc(
            robokey_secrecy::ldpc::LdpcSettings::DEFAULT,
        ));
        let cascade = run(ReconciliationMethod::Cascade);
        assert!(ldpc.consistent && ldpc.secret_bits > 0, "{ldpc:?}");
        let rounds = ldpc.ldpc_rounds.expect("LDPC reports its rounds");
        assert!((1..=9).contains(&rounds));
        // m = ⌈1.09 · H + 2 · √H⌉ for H = n · h₂(0.02) ≈ 0.14 n, at most 8 rounds of
        // ⌈max(0.04·m, 2·√m)⌉ more, and 4 bits for the rounds.
        let n = ldpc.reconciled_bits as f64;
        let soft = n * robokey_secrecy::entropy::binary_entropy(0.02);
        let first = (1.09 * soft + 2.0 * soft.sqrt()).ceil();
        let rounds = robokey_secrecy::ldpc::LdpcSettings::DEFAULT.round_bits(first as usize);
        let most = first + 8.0 * rounds as f64 + 4.0;
        let leak = ldpc.leak_ec as f64;
        assert!(leak >= first && leak <= most, "{leak} for {first}..={most}");
        assert_eq!(cascade.ldpc_rounds, None);
        assert!(ldpc.leak_ec < cascade.leak_ec && ldpc.secret_bits > cascade.secret_bits);
    }

    #[test]
    fn a_block_too_short_for_its_key_gets_pooling_advice() {
        // 200 bits with Eve wrong on a fifth of them cannot cover 2·log₂(1/ε) + tags, but
        // her min-entropy grows with the block while nothing else does.
        let why = ended(
            200,
            "no secret bits: too short",
            Some(AbortReason::NoSecretBits),
        )
        .reason
        .unwrap();
        assert!(why.contains("pooling more can help"), "{why}");
    }
}
