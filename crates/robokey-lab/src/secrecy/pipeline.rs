//! The post-processing that ships, run on simulated sessions (docs/secrecy.md): which
//! sessions are pooled, where the error-rate estimate comes from, reconciliation,
//! confirmation and privacy amplification — with every public bit that depends on the key
//! charged as leak, and Eve's min-entropy bound named by its method.

use rand::rngs::ChaCha8Rng;
use robokey::protocol::Outcome;
use robokey::sim::RunOutput;
use robokey_secrecy::confirm::TAG_BITS;
use robokey_secrecy::interval::clopper_pearson_lower;
use robokey_secrecy::min_entropy::{binomial_smooth_min_entropy, output_length};
use robokey_secrecy::{BitString, Cascade, Reconciler, ToeplitzHash};
use serde::Serialize;
use zeroize::Zeroizing;

/// Which sessions are pooled, and what was published over their keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Pooling {
    /// What today's agents do (session protocol v1): each side publishes a 64-bit tag over
    /// its session key and only sessions whose tags matched are kept. Their keys already
    /// agree, so nothing is reconciled, but both tags of every pooled session (128 bits)
    /// are charged.
    Confirmed,
    /// The pipeline of the authenticated session (the session is confirmed over its
    /// transcript, not its key): every session both sides completed is pooled; a disclosed
    /// random sample estimates the error rate and is removed; Cascade reconciles with both
    /// sides' parities charged; the block is confirmed by two 64-bit tags (128 bits).
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
                    matches!(o, Some(Outcome::Confirmed | Outcome::Unconfirmed(_)))
                };
                finished(robot) && finished(controller) && same_positions
            }
        };
        admitted && !run.keys.robot.is_empty()
    }
}

/// Bits of confirmation tags published per confirmation: one 64-bit tag each way.
pub const CONFIRMATION_BITS: u64 = 2 * TAG_BITS;

/// How Eve's smooth min-entropy is bounded: from her realised hard decisions with the
/// binomial bound. Labelled an approximation wherever it appears.
pub const H_MIN_BINOMIAL: &str = "binomial bound on Eve's realised hard-decision errors \
    (approximation: i.i.d. errors; ignores her soft values, her patterns and where her errors fall)";

/// The pooled raw bits of whole sessions, in session order: the robot's key is the
/// reference, the controller's is corrected, Eve's is her guess of the same positions.
#[derive(Default)]
pub struct Pool {
    /// Sessions pooled.
    pub sessions: u32,
    /// Index (in the simulated order) of the last session pooled.
    pub last_session: usize,
    /// The robot's bits.
    pub robot: Zeroizing<Vec<u8>>,
    /// The controller's bits.
    pub controller: Zeroizing<Vec<u8>>,
    /// Eve's bits.
    pub eve: Zeroizing<Vec<u8>>,
}

/// Groups the admitted sessions of `runs`, in order, into pools of at least `block_bits`
/// bits each (whole sessions, so a session's published tags fall in one block).
#[must_use]
pub fn pools(runs: &[RunOutput], pooling: Pooling, block_bits: usize) -> Vec<Pool> {
    let mut full = Vec::new();
    let mut pool = Pool::default();
    for (index, run) in runs.iter().enumerate() {
        if !pooling.admits(run) {
            continue;
        }
        let keys = &run.keys;
        pool.robot.extend_from_slice(&keys.robot);
        pool.controller.extend_from_slice(&keys.controller);
        let eve = keys.eve.as_deref().map_or(&[][..], Vec::as_slice);
        // A position Eve made no guess for counts as known to her: the cautious side.
        pool.eve
            .extend((0..keys.robot.len()).map(|i| eve.get(i).copied().unwrap_or(keys.robot[i])));
        pool.sessions += 1;
        pool.last_session = index;
        if pool.robot.len() >= block_bits {
            full.push(std::mem::take(&mut pool));
        }
    }
    full
}

/// One privacy-amplification block, with every public bit it cost.
#[derive(Clone, Debug, Serialize)]
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
    /// Reconciliation question messages (each answered by one).
    pub reconciliation_messages: u32,
    /// Reconciliation leak: both sides' parities.
    pub leak_ec: u64,
    /// Confirmation tags published over pooled key bits (per-session or per-block).
    pub leak_confirmation: u64,
    /// leak_ec + leak_confirmation.
    pub leak: u64,
    /// Whether the reconciled keys agree (else the block's tags differ and it is dropped).
    pub confirmed: bool,
    /// Eve's errors against the reference on the reconciled positions.
    pub eve_errors: usize,
    /// Lower confidence bound (level 1 − ε_PE) of Eve's error rate.
    pub eve_error_lower: f64,
    /// Lower bound on Eve's smooth min-entropy (bits).
    pub h_min: f64,
    /// How `h_min` was obtained.
    pub h_min_method: &'static str,
    /// w* of the binomial bound.
    pub w_star: u64,
    /// H_min − leak − 2·log₂(1/ε_PA) + 2, before flooring and clamping.
    pub raw_length: f64,
    /// Secret bits ℓ.
    pub secret_bits: u64,
    /// Why ℓ = 0, and whether pooling more could help.
    pub reason: Option<String>,
}

/// Settings of one block's post-processing.
#[derive(Clone, Copy, Debug)]
pub struct BlockSettings {
    /// Which sessions are pooled.
    pub pooling: Pooling,
    /// ε per term (smoothing, amplification, parameter estimation).
    pub epsilon: f64,
    /// Largest disclosed sample (at most a tenth of the block is disclosed).
    pub sample_bits: usize,
}

fn bits(key: &[u8]) -> BitString {
    let bools: Zeroizing<Vec<bool>> = Zeroizing::new(key.iter().map(|&b| b == 1).collect());
    BitString::from_bools(&bools)
}

/// Splits off a uniformly random sample of `size` positions (public randomness): returns
/// its disagreements and the three keys without it.
fn disclose(pool: &Pool, size: usize, public: &mut ChaCha8Rng) -> (usize, [Zeroizing<Vec<u8>>; 3]) {
    let n = pool.robot.len();
    let mut disclosed = vec![false; n];
    for i in rand::seq::index::sample(public, n, size) {
        disclosed[i] = true;
    }
    let errors = (0..n)
        .filter(|&i| disclosed[i] && pool.robot[i] != pool.controller[i])
        .count();
    let keep = |key: &[u8]| -> Zeroizing<Vec<u8>> {
        Zeroizing::new(
            key.iter()
                .zip(&disclosed)
                .filter(|(_, d)| !**d)
                .map(|(b, _)| *b)
                .collect(),
        )
    };
    (
        errors,
        [keep(&pool.robot), keep(&pool.controller), keep(&pool.eve)],
    )
}

/// Runs one pool through the pipeline of `settings.pooling`; `public` supplies the public
/// randomness (sample, Cascade permutations, Toeplitz seed).
#[must_use]
pub fn post_process(pool: &Pool, settings: &BlockSettings, public: &mut ChaCha8Rng) -> Block {
    let n = pool.robot.len();
    let errors_before = pool
        .robot
        .iter()
        .zip(pool.controller.iter())
        .filter(|(a, b)| a != b)
        .count();
    let eps = settings.epsilon;
    let (sample_bits, sample_errors, q_estimate, q_source, keys) = match settings.pooling {
        Pooling::Confirmed => (
            0,
            0,
            0.0,
            "every pooled session's key tags matched: nothing to reconcile".to_owned(),
            [
                pool.robot.clone(),
                pool.controller.clone(),
                pool.eve.clone(),
            ],
        ),
        Pooling::Complete => {
            let size = settings.sample_bits.min(n / 10);
            let (errors, keys) = disclose(pool, size, public);
            let q = if size == 0 {
                0.0
            } else {
                (errors as f64 / size as f64).min(0.5)
            };
            let source = format!(
                "disclosed random sample of {size} positions ({errors} disagreed), removed from the key"
            );
            (size, errors, q, source, keys)
        }
    };
    let [robot, controller, eve] = keys;
    let m = robot.len();
    let (alice, bob) = (bits(&robot), bits(&controller));
    let (leak_ec, messages, confirmed) = match settings.pooling {
        Pooling::Confirmed => (0, 0, alice == bob),
        Pooling::Complete => {
            match Cascade::biconf(q_estimate).and_then(|c| c.reconcile(&alice, &bob, public)) {
                Ok(r) => (r.leak, r.messages, r.corrected == alice),
                // A failed reconciliation publishes at most the whole key's worth.
                Err(_) => (2 * m as u64, 0, false),
            }
        }
    };
    let leak_confirmation = match settings.pooling {
        Pooling::Confirmed => u64::from(pool.sessions) * CONFIRMATION_BITS,
        Pooling::Complete => CONFIRMATION_BITS,
    };
    let eve_errors = robot.iter().zip(eve.iter()).filter(|(a, b)| a != b).count();
    let eve_error_lower = clopper_pearson_lower(eve_errors as u64, m as u64, eps)
        .unwrap_or(0.0)
        .min(0.5);
    let entropy = binomial_smooth_min_entropy(m as u64, eve_error_lower, eps).ok();
    let h_min = entropy.as_ref().map_or(0.0, |e| e.h_min);
    let length = output_length(h_min, leak_ec, leak_confirmation, eps).ok();
    let raw_length = length.as_ref().map_or(f64::NEG_INFINITY, |l| l.raw);
    let (mut secret_bits, mut reason) = length.map_or(
        (0, Some("the bound could not be evaluated".to_owned())),
        |l| (l.bits, l.reason),
    );
    if !confirmed {
        secret_bits = 0;
        reason = Some(
            "reconciliation left errors: the block's confirmation tags differ and it is dropped"
                .into(),
        );
    } else if secret_bits > 0 {
        // Amplify as the agents will. The reconciled keys are equal, so one hash stands for
        // both sides; its cost is part of the measured wall time.
        let hashed = ToeplitzHash::random(m, secret_bits as usize, public)
            .and_then(|hash| hash.hash(&alice));
        if hashed.is_err() {
            secret_bits = 0;
            reason = Some("the Toeplitz hash could not be built".into());
        }
    } else if let Some(why) = reason.as_mut() {
        why.push_str(&pooling_advice(settings, pool.sessions, m, h_min, leak_ec));
    }
    Block {
        sessions: pool.sessions,
        bits: n,
        errors_before,
        sample_bits,
        sample_errors,
        q_estimate,
        q_source,
        reconciled_bits: m,
        reconciliation_messages: messages,
        leak_ec,
        leak_confirmation,
        leak: leak_ec + leak_confirmation,
        confirmed,
        eve_errors,
        eve_error_lower,
        h_min,
        h_min_method: H_MIN_BINOMIAL,
        w_star: entropy.map_or(0, |e| e.w_star),
        raw_length,
        secret_bits,
        reason,
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
            Pooling::Confirmed => u64::from(sessions) * CONFIRMATION_BITS,
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
