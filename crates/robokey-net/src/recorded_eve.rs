//! The eavesdroppers on a recorded session, as typed reports ([`hear`]): what each made of a
//! relay capture in odometry sensing ([`CaptureReport`]), of private-sensing captures and her
//! camera's logs ([`PrivateCaptureReport`]), and her realised bound over the post-processing
//! block those sessions made ([`BlockVerdict`]). `robokey eve --capture` prints them and
//! writes their serde form as `capture.json`; the Python package returns that form.

use std::path::{Path, PathBuf};

use robokey::Config;
use robokey::config::{EveStrategy, SensingMode};
use robokey::eve::{ModelErrors, starting_errors};
use robokey::rng::{Purpose, stream};
use robokey::world::Camera;
use robokey_secrecy::gaussian_llr::surprisal;
use robokey_secrecy::postprocess::slice_id;
use robokey_secrecy::{output_length, posterior_smooth_min_entropy};
use serde::ser::SerializeMap;
use serde::{Serialize, Serializer};

use crate::agent::key_file::read_key_file;
use crate::agent::post::BlockSummary;
use crate::agent::report::read_report;
use crate::capture_eve::{PrivateCaptureResult, listen, listen_private, read_session};
use crate::error::NetError;
use crate::pose_stream::{CameraLog, read_log};

/// How the caller names its inputs in errors: the command's flags (`--camera-log`) or
/// Python's keywords (`camera_log=`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Naming {
    /// `robokey eve`'s flags.
    Flags,
    /// `robokey.eve`'s keywords.
    Keywords,
}

impl Naming {
    /// The name of the input `input` (snake case) for this caller.
    #[must_use]
    pub fn of(self, input: &str) -> String {
        match self {
            Self::Flags => format!("--{}", input.replace('_', "-")),
            Self::Keywords => format!("{input}="),
        }
    }
}

/// What to listen to: the captures of recorded sessions and what goes with them.
#[derive(Clone, Copy, Debug)]
pub struct RecordedSessions<'a> {
    /// The captures (odometry sensing: one; private sensing: one per session, in order).
    pub captures: &'a [PathBuf],
    /// Private sensing: her camera's log of each session (one per capture).
    pub camera_logs: &'a [PathBuf],
    /// Private sensing: the robot's key file of each session (none, or one per capture).
    pub robot_keys: &'a [PathBuf],
    /// The controller's key file of each session (none, or one per capture).
    pub controller_keys: &'a [PathBuf],
    /// Private sensing: the agent report of the run in which the sessions' block ended.
    pub block: Option<&'a Path>,
    /// The eavesdroppers (none: the sensing mode's defaults).
    pub strategies: &'a [EveStrategy],
    /// Odometry sensing: her starting errors given explicitly ([`explicit_errors`]).
    pub errors: Option<ModelErrors>,
}

/// What the eavesdroppers made of recorded sessions.
#[derive(Debug, Serialize)]
#[serde(untagged)]
pub enum Heard {
    /// Odometry sensing: one session.
    Odometry(CaptureReport),
    /// Private sensing: each session, and her bound over their block.
    Private(PrivateReport),
}

/// The private eavesdroppers on each session of a block, and her realised bound over it. Its
/// serde form is the one session's report when there is one and no block, else
/// `{"sessions": […], "block": …}`.
#[derive(Debug)]
pub struct PrivateReport {
    /// One report per capture, in order.
    pub sessions: Vec<PrivateCaptureReport>,
    /// Her bound over the block, when its agent report was given — with multilevel symbols
    /// over each block of the sessions' slices that made a key (docs/postprocessing.md,
    /// "Multilevel slices"), in block order.
    pub blocks: Vec<BlockVerdict>,
}

impl Serialize for PrivateReport {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match (self.sessions.as_slice(), self.blocks.split_last()) {
            ([session], None) => session.serialize(serializer),
            (sessions, last) => {
                let mut map = serializer.serialize_map(None)?;
                map.serialize_entry("block", &last.map(|(block, _)| block))?;
                if let Some((_, lower)) = last.filter(|(_, lower)| !lower.is_empty()) {
                    map.serialize_entry("lower_slices", lower)?;
                }
                map.serialize_entry("sessions", sessions)?;
                map.end()
            }
        }
    }
}

/// Runs the eavesdroppers on recorded sessions, as `config`'s sensing mode says: odometry
/// sensing, one capture; private sensing, each capture with her camera's log and, with the
/// block's agent report, her bound over the block ([`block_verdicts`]). Errors name the inputs
/// as `naming` says.
///
/// # Errors
/// Inputs that do not fit the mode or each other ([`NetError::Usage`]), a file that cannot be
/// read or does not fit.
pub fn hear(
    sessions: RecordedSessions<'_>,
    config: &Config,
    naming: Naming,
) -> Result<Heard, NetError> {
    let usage = |message: String| Err(NetError::Usage(message));
    let name = |input: &str| naming.of(input);
    let n = sessions.captures.len();
    match (n, config.sensing.mode) {
        (0, _) => usage(format!("{}: give a capture", name("capture"))),
        (_, SensingMode::Odometry) if !sessions.camera_logs.is_empty() => usage(format!(
            "{} is her camera's record of a private-sensing session (set \
             sensing.mode=private); in odometry mode she decides from the robot's measurements",
            name("camera_log")
        )),
        (_, SensingMode::Odometry) if sessions.block.is_some() => usage(format!(
            "{} is a private-sensing block: in odometry mode the key is zero by structure",
            name("block")
        )),
        (1, SensingMode::Odometry) => hear_capture(
            &sessions.captures[0],
            config,
            sessions.strategies,
            sessions.errors,
            sessions.controller_keys.first().map(PathBuf::as_path),
        )
        .map(Heard::Odometry),
        (_, SensingMode::Odometry) => usage(format!(
            "{}: one capture at a time in odometry mode (her learning carries over between \
             sessions only in simulation)",
            name("capture")
        )),
        (_, SensingMode::Private) => hear_private(sessions, config, naming).map(Heard::Private),
    }
}

/// Private sensing: [`hear_private_capture`] on each session, then [`block_verdicts`].
fn hear_private(
    sessions: RecordedSessions<'_>,
    config: &Config,
    naming: Naming,
) -> Result<PrivateReport, NetError> {
    let name = |input: &str| naming.of(input);
    let n = sessions.captures.len();
    if sessions.camera_logs.len() != n {
        return Err(NetError::Usage(format!(
            "{} of a private-sensing session needs her camera's record: one {} FILE per {} \
             ({} captures, {} camera logs; `robokey record --from CAMERA_ADDR --out FILE` \
             during each session)",
            name("capture"),
            name("camera_log"),
            name("capture"),
            n,
            sessions.camera_logs.len()
        )));
    }
    for (input, given) in [
        ("robot_key", sessions.robot_keys.len()),
        ("controller_key", sessions.controller_keys.len()),
    ] {
        if given != 0 && given != n {
            return Err(NetError::Usage(format!(
                "{}: one per {} ({n} captures, {given} given)",
                name(input),
                name("capture")
            )));
        }
    }
    let mut reports = Vec::new();
    let mut block = Vec::new();
    for i in 0..n {
        let key = |paths: &[PathBuf]| paths.get(i).map(|p| read_key_file(p)).transpose();
        let (robot, controller) = (key(sessions.robot_keys)?, key(sessions.controller_keys)?);
        let recording = PrivateRecording {
            capture: &sessions.captures[i],
            camera_log: &sessions.camera_logs[i],
            robot_bits: robot.as_ref().map(|k| k.as_slice()),
            controller_bits: controller.as_ref().map(|k| k.as_slice()),
        };
        let report = hear_private_capture(recording, config, sessions.strategies, naming)?;
        block.push(report.camera_error_probabilities.clone());
        reports.push(report);
    }
    let blocks = match sessions.block {
        Some(report) => {
            let captured: Vec<u32> = reports.iter().map(|r| r.session).collect();
            block_verdicts(report, &captured, &block, config).map_err(|e| match e {
                NetError::Usage(message) => NetError::Usage(format!("{} {message}", name("block"))),
                e => e,
            })?
        }
        None => Vec::new(),
    };
    Ok(PrivateReport {
        sessions: reports,
        blocks,
    })
}

/// Checks that every one of `strategies` is an eavesdropper of `mode`.
///
/// # Errors
/// [`NetError::Usage`] naming the strategy (`strategy` as `naming` says) and the mode's.
pub fn check_strategies(
    strategies: &[EveStrategy],
    mode: SensingMode,
    naming: Naming,
) -> Result<(), NetError> {
    match strategies.iter().find(|s| s.mode() != mode) {
        Some(s) => Err(NetError::Usage(format!(
            "{} {}: does not apply in sensing.mode = {} (allowed: {})",
            naming.of("strategy"),
            s.name(),
            mode.name(),
            EveStrategy::of_mode(mode)
                .iter()
                .map(|a| a.name())
                .collect::<Vec<_>>()
                .join(", ")
        ))),
        None => Ok(()),
    }
}

/// Her starting relative errors on r, D, W, V given explicitly (every strategy but the
/// oracle starts from them).
///
/// # Errors
/// Not four numbers, or one not in (−1, 1) ([`NetError::Usage`]).
pub fn explicit_errors(values: &[f64]) -> Result<ModelErrors, NetError> {
    let &[r, d, w, v] = values else {
        return Err(NetError::Usage("expected four numbers r,D,W,V".to_owned()));
    };
    if values.iter().any(|e| e.is_nan() || e.abs() >= 1.0) {
        return Err(NetError::Usage(
            "each relative error must be in (−1, 1)".to_owned(),
        ));
    }
    Ok(ModelErrors { r, d, w, v })
}

/// Her starting errors: `explicit` when given (not for the oracle), else drawn from her
/// seeded stream (stream "eve", replicate 0) as the configuration says.
#[must_use]
pub fn errors_of(
    config: &Config,
    strategy: EveStrategy,
    explicit: Option<ModelErrors>,
) -> ModelErrors {
    match explicit {
        Some(errors) if strategy != EveStrategy::Oracle => errors,
        _ => {
            let mut config = config.clone();
            config.eve.strategy = Some(strategy);
            starting_errors(&config, &mut stream(config.run.seed, Purpose::Eve, 0))
        }
    }
}

/// How many of `bits` bits two keys differ on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Disagreement {
    /// Bits that differ.
    pub differing: usize,
    /// Bits compared.
    pub bits: usize,
}

impl Disagreement {
    /// `a` against `b`, or `None` when their lengths differ.
    #[must_use]
    pub fn of(a: &[u8], b: &[u8]) -> Option<Self> {
        (a.len() == b.len()).then(|| Self {
            differing: a.iter().zip(b).filter(|(x, y)| x != y).count(),
            bits: a.len(),
        })
    }

    /// `100 · differing / bits` (%), `None` for an empty key.
    #[must_use]
    pub fn percent(&self) -> Option<f64> {
        (self.bits > 0).then(|| 100.0 * self.differing as f64 / self.bits as f64)
    }
}

/// What the eavesdroppers made of one captured session in odometry sensing.
#[derive(Debug, Serialize)]
pub struct CaptureReport {
    /// Session id (8 hex digits in the serde form).
    #[serde(serialize_with = "session_hex")]
    pub session: u32,
    /// The reason of the session's abort: then no key was agreed.
    pub session_aborted: Option<String>,
    /// Valid frames heard.
    pub frames: usize,
    /// Datagrams that did not decode.
    pub undecodable: usize,
    /// What of the capture could not be read.
    pub shortfalls: Vec<String>,
    /// One report per eavesdropper, in the order asked.
    pub strategies: Vec<StrategyReport>,
}

/// What one odometry eavesdropper made of a captured session.
#[derive(Debug, Serialize)]
pub struct StrategyReport {
    /// Her strategy.
    #[serde(serialize_with = "strategy_name")]
    pub strategy: EveStrategy,
    /// Her starting relative model errors.
    #[serde(serialize_with = "model_errors")]
    pub start_errors: ModelErrors,
    /// Her relative errors on r and D at the end.
    pub end_errors: EndErrors,
    /// Her decision per step (`None`: erased or never decided), index = step.
    pub decisions: Vec<Option<u8>>,
    /// Her key's length (bits).
    pub key_bits: usize,
    /// Codewords she flipped to match the confirmation tag, when she verified her key.
    pub tag_flips: Option<u32>,
    /// Her key against the controller's, when its key file was given (its percentage in the
    /// serde form, `disagreement_pct`).
    #[serde(rename = "disagreement_pct", serialize_with = "disagreement_percent")]
    pub disagreement: Option<Disagreement>,
}

impl StrategyReport {
    /// Steps she decided.
    #[must_use]
    pub fn decided(&self) -> usize {
        self.decisions.iter().flatten().count()
    }
}

/// Her relative errors on the wheel radius r and the axle length D at the end of a session.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct EndErrors {
    /// `r̂ / r − 1`.
    pub r: f64,
    /// `D̂ / D − 1`.
    #[serde(rename = "D")]
    pub d: f64,
}

/// Runs each of `strategies` (none: the configuration's `eve.strategy`) on the first session
/// in `capture`, each starting from `explicit` errors or her seeded draw ([`errors_of`]); with
/// the controller's key file, her key is compared with it.
///
/// # Errors
/// The capture or key file cannot be read, the capture's terms differ from `config`, or the
/// controller's key is not of this session (its length differs from hers).
fn hear_capture(
    capture: &Path,
    config: &Config,
    strategies: &[EveStrategy],
    explicit: Option<ModelErrors>,
    controller_key: Option<&Path>,
) -> Result<CaptureReport, NetError> {
    let captured = read_session(capture, config)?;
    let controller = controller_key
        .map(|p| read_key_file(p).map(|k| (p, k)))
        .transpose()?;
    let default = [config.eve_strategy()];
    let strategies = if strategies.is_empty() {
        &default[..]
    } else {
        strategies
    };
    let mut reports = Vec::new();
    for &strategy in strategies {
        let errors = errors_of(config, strategy, explicit);
        let result = listen(&captured, config, strategy, errors);
        let disagreement = match &controller {
            Some((path, key)) => Some(Disagreement::of(key, &result.key).ok_or_else(|| {
                NetError::Usage(format!(
                    "{}: the controller's key has {} bits, Eve's {}: not the same session?",
                    path.display(),
                    key.len(),
                    result.key.len()
                ))
            })?),
            None => None,
        };
        reports.push(StrategyReport {
            strategy,
            start_errors: errors,
            end_errors: EndErrors {
                r: result.model.wheel_radius / config.robot.r - 1.0,
                d: result.model.axle_length / config.robot.axle_length - 1.0,
            },
            key_bits: result.key.len(),
            decisions: result.decisions,
            tag_flips: result.tag_flips,
            disagreement,
        });
    }
    Ok(CaptureReport {
        session: captured.session,
        session_aborted: captured.aborted,
        frames: captured.messages.len(),
        undecodable: captured.undecodable,
        shortfalls: captured.shortfalls,
        strategies: reports,
    })
}

/// One private-sensing session's recording: its capture, her camera's log, and the robot's
/// and the controller's raw bits (their key files) when given.
#[derive(Clone, Copy, Debug)]
struct PrivateRecording<'a> {
    /// The relay's (or tcpdump's …) capture of the session.
    pub capture: &'a Path,
    /// Her camera's pose log of it (`robokey record`).
    pub camera_log: &'a Path,
    /// The robot's raw bits, the reference every error rate is measured against.
    pub robot_bits: Option<&'a [u8]>,
    /// The controller's raw bits.
    pub controller_bits: Option<&'a [u8]>,
}

/// What the private-sensing eavesdroppers made of one captured session.
#[derive(Debug, Serialize)]
pub struct PrivateCaptureReport {
    /// Session id (8 hex digits in the serde form).
    #[serde(serialize_with = "session_hex")]
    pub session: u32,
    /// Valid frames heard.
    pub frames: usize,
    /// Datagrams that did not decode.
    pub undecodable: usize,
    /// What of the capture could not be read.
    pub shortfalls: Vec<String>,
    /// Her camera's samples in the log.
    pub camera_samples: usize,
    /// One report per eavesdropper, in the order asked.
    pub strategies: Vec<PrivateStrategyReport>,
    /// The controller's raw bits against the robot's, when both were given (`None` inside:
    /// their lengths differ).
    #[serde(skip)]
    pub controller_vs_robot: Option<Option<Disagreement>>,
    /// The robot's raw bits given (their number).
    #[serde(skip)]
    pub robot_bits: Option<usize>,
    /// The controller's raw bits given (their number).
    #[serde(skip)]
    pub controller_bits: Option<usize>,
    /// The camera adversary's posterior error probability of each of the robot's raw bits
    /// given the others (empty without the robot's bits or a camera adversary).
    #[serde(skip)]
    pub camera_error_probabilities: Vec<f64>,
}

/// What one private-sensing eavesdropper made of a captured session.
#[derive(Debug, Serialize)]
pub struct PrivateStrategyReport {
    /// Her strategy (`camera` or `commands`).
    #[serde(serialize_with = "strategy_name")]
    pub strategy: EveStrategy,
    /// Every carrying doublet she decided, in doublet order.
    pub doublets: Vec<DecidedDoublet>,
    /// Her key's length (bits): her decisions on the kept doublets.
    pub key_bits: usize,
    /// Her key against the robot's raw bits (`None` inside: their lengths differ).
    #[serde(skip)]
    pub against_robot: Option<Option<Disagreement>>,
    /// Her key against the controller's raw bits (`None` inside: their lengths differ).
    #[serde(skip)]
    pub against_controller: Option<Option<Disagreement>>,
    /// Her view of the robot's raw bits, each given the others, when they were given.
    #[serde(skip)]
    pub view: Option<GivenOthers>,
}

/// One doublet as a private eavesdropper decided it.
#[derive(Debug, Serialize)]
pub struct DecidedDoublet {
    /// Doublet index j.
    pub doublet: u32,
    /// Her log-likelihood ratio `ln P(b=0|E)/P(b=1|E)` of each of its bits.
    pub llr: Vec<f64>,
    /// Her decisions: 1 where the LLR is negative.
    pub bits: Vec<u8>,
    /// Her LLRs given the true bits of the other doublets, when measured.
    pub llr_given_others: Option<Vec<f64>>,
}

/// A private eavesdropper's view of the robot's raw bits of a capture, each given the others.
#[derive(Debug)]
pub struct GivenOthers {
    /// Raw bits measured.
    pub bits: usize,
    /// Mean information `1 − S` per bit (bits), `S` the surprisal of the true bit.
    pub information: f64,
    /// Her posterior error probability `q = 1 / (1 + e^|LLR|)` of each bit.
    pub error_probabilities: Vec<f64>,
    /// Bits whose view given the others was not measured (their own LLR taken).
    pub missing: usize,
    /// `H_min^ε` of the bits given her view (bits), at the configuration's ε.
    pub h_min: f64,
}

/// Runs the private-sensing eavesdroppers `strategies` (none: camera and commands) on one
/// recorded session, who know the world of `config`. Errors name the camera log as `naming`
/// says.
///
/// # Errors
/// A file cannot be read; the camera log films otherwise than the world's camera (frames
/// against instants, [`NetError::Usage`]).
fn hear_private_capture(
    recording: PrivateRecording<'_>,
    config: &Config,
    strategies: &[EveStrategy],
    naming: Naming,
) -> Result<PrivateCaptureReport, NetError> {
    let captured = read_session(recording.capture, config)?;
    let camera = read_log(recording.camera_log)?;
    let path = format!(
        "{} {}",
        naming.of("camera_log"),
        recording.camera_log.display()
    );
    match (&camera, config.world_model().camera) {
        (CameraLog::Frames(_), Camera::Instants { .. }) => {
            return Err(NetError::Usage(format!(
                "{path}: a log of frames between the instants, but the world's camera films \
                 at the instants (set world.camera_fps)"
            )));
        }
        (CameraLog::Instants(_), Camera::Frames { .. }) => {
            return Err(NetError::Usage(format!(
                "{path}: a log of samples at the instants, but the world's camera films frames \
                 at world.camera_fps"
            )));
        }
        _ => {}
    }
    let (robot, controller) = (recording.robot_bits, recording.controller_bits);
    let heard = listen_private(&captured, &camera, config, robot);
    let bits = config.protocol.key_bits_per_doublet();
    let all = EveStrategy::of_mode(config.sensing.mode);
    let strategies = if strategies.is_empty() {
        &all[..]
    } else {
        strategies
    };
    let mut reports = Vec::new();
    let mut camera_error_probabilities = Vec::new();
    for &strategy in strategies {
        let camera_adversary = strategy != EveStrategy::Commands;
        let key = if camera_adversary {
            &heard.camera_key
        } else {
            &heard.commands_key
        };
        let doublets = heard
            .doublets
            .iter()
            .filter_map(|d| {
                let (evidence, given) = d.of(camera_adversary)?;
                let llr = evidence.llr[..bits].to_vec();
                Some(DecidedDoublet {
                    doublet: d.doublet,
                    bits: llr.iter().map(|&l| u8::from(l < 0.0)).collect(),
                    llr,
                    llr_given_others: given.map(|g| g.llr[..bits].to_vec()),
                })
            })
            .collect();
        let view = robot
            .map(|robot| given_others_view(&heard, robot, bits, camera_adversary, config))
            .transpose()?;
        if camera_adversary && let Some(view) = &view {
            camera_error_probabilities.clone_from(&view.error_probabilities);
        }
        reports.push(PrivateStrategyReport {
            strategy,
            doublets,
            key_bits: key.len(),
            against_robot: robot.map(|r| Disagreement::of(r, key)),
            against_controller: controller.map(|c| Disagreement::of(c, key)),
            view,
        });
    }
    Ok(PrivateCaptureReport {
        session: captured.session,
        frames: captured.messages.len(),
        undecodable: captured.undecodable,
        shortfalls: captured.shortfalls,
        camera_samples: camera.len(),
        strategies: reports,
        controller_vs_robot: robot.zip(controller).map(|(r, c)| Disagreement::of(r, c)),
        robot_bits: robot.map(<[u8]>::len),
        controller_bits: controller.map(<[u8]>::len),
        camera_error_probabilities,
    })
}

/// Her view of each of the robot's raw bits (kept doublets in order, `bits` per doublet) given
/// the others, from the `camera` or the `commands` adversary.
fn given_others_view(
    heard: &PrivateCaptureResult,
    robot: &[u8],
    bits: usize,
    camera: bool,
    config: &Config,
) -> Result<GivenOthers, NetError> {
    let mut view = GivenOthers {
        bits: 0,
        information: 0.0,
        error_probabilities: Vec::new(),
        missing: 0,
        h_min: 0.0,
    };
    for (&j, truth) in heard.kept.iter().zip(robot.chunks_exact(bits)) {
        let Some((own, given)) = heard
            .doublets
            .iter()
            .find(|d| d.doublet == j)
            .and_then(|d| d.of(camera))
        else {
            continue;
        };
        view.missing += usize::from(given.is_none()) * bits;
        let evidence = given.unwrap_or(own);
        for (i, &bit) in truth.iter().enumerate() {
            let llr = evidence.llr[i];
            view.information += 1.0 - surprisal(if bit == 0 { llr } else { -llr });
            view.error_probabilities.push(1.0 / (1.0 + llr.abs().exp()));
            view.bits += 1;
        }
    }
    view.information /= view.bits.max(1) as f64;
    view.h_min =
        posterior_smooth_min_entropy(&view.error_probabilities, config.postprocess.epsilon)
            .map_err(|e| NetError::Usage(format!("postprocess.epsilon: {e}")))?
            .h_min;
    Ok(view)
}

/// Her realised bound over a block beside the key the agents committed.
#[derive(Debug, Serialize)]
pub struct BlockVerdict {
    /// Block number.
    pub block: u64,
    /// Raw bits it pooled.
    pub raw_bits: usize,
    /// The key the agents committed (bits).
    pub committed_bits: u64,
    /// The key her realised view supports (bits): `ℓ = ⌊H_min^ε − leak_ec − t − 2 log₂(1/ε)⌋`.
    pub realised_bits: u64,
    /// `H_min^ε` of the amplified bits given her view (bits).
    pub realised_h_min: f64,
    /// Whether the committed key exceeds what her view supports.
    pub exceeds: bool,
    /// How the world differs from the parties' configuration (empty: their own world).
    pub world: Vec<String>,
    /// The block as the agent's report tells it.
    #[serde(skip)]
    pub reported: BlockSummary,
    /// Bits her bound is over.
    #[serde(skip)]
    pub amplified: usize,
    /// Which bits those are.
    #[serde(skip)]
    pub which: &'static str,
}

/// Her realised bound over the blocks of the agent report `report` (the camera adversary's
/// posterior error probabilities `q` of each of the `captured` sessions' raw bits, sessions
/// in order), each beside the key the agents committed. The blocks are those that made a
/// key over the captured sessions — with multilevel symbols over one of their slices each,
/// its bits then the slice's of each session (docs/postprocessing.md, "Multilevel slices")
/// — in report order, or else the report's last that made a key. Her bound is over the bits
/// each block amplified (`amplified_bits`).
///
/// # Errors
/// The report cannot be read or holds no block that made a key, that block names other
/// sessions than `captured` (or another order), or it pooled another number of bits than `q`
/// holds ([`NetError::Usage`]).
pub fn block_verdicts(
    report: &Path,
    captured: &[u32],
    q: &[Vec<f64>],
    config: &Config,
) -> Result<Vec<BlockVerdict>, NetError> {
    let name = report.display();
    let json = read_report(report)?;
    let blocks: Vec<BlockSummary> = serde_json::from_value(json["post"]["blocks"].clone())
        .map_err(|e| NetError::Usage(format!("{name}: no post-processing blocks in it: {e}")))?;
    let slicing = robokey::connection::slices::slicing(config);
    let slices = slicing.map_or(1, |s| usize::from(s.slices));
    let ids_at = |slice: usize| -> Vec<String> {
        captured
            .iter()
            .map(|&id| format!("{:08x}", slice_id(id, slice)))
            .collect()
    };
    let keyed: Vec<BlockSummary> = blocks.into_iter().filter(|b| b.length > 0).collect();
    let mut over_captured: Vec<(BlockSummary, usize)> = keyed
        .iter()
        .filter_map(|b| {
            (0..slices)
                .find(|&slice| b.session_ids == ids_at(slice))
                .map(|slice| (b.clone(), slice))
        })
        .collect();
    if over_captured.is_empty() {
        let Some(last) = keyed.last() else {
            return Err(NetError::Usage(format!(
                "{name}: no block of this run made a key (its report's post.blocks)"
            )));
        };
        over_captured.push((last.clone(), 0));
    }
    over_captured
        .into_iter()
        .map(|(block, slice)| {
            let q: Vec<f64> = match slicing {
                Some(slicing) => q.iter().flat_map(|s| slicing.pick(s, slice)).collect(),
                None => q.concat(),
            };
            verdict_of(&name.to_string(), block, &ids_at(slice), &q, config)
        })
        .collect()
}

/// Her realised bound over `block` (its sessions `captured`, her posteriors `q` of its raw
/// bits in pool order) beside the key the agents committed; `name` the report's.
fn verdict_of(
    name: &str,
    block: BlockSummary,
    captured: &[String],
    q: &[f64],
    config: &Config,
) -> Result<BlockVerdict, NetError> {
    // A report of an agent before `session_ids` names none: the bit count below checks it.
    if !block.session_ids.is_empty() && block.session_ids != captured {
        return Err(NetError::Usage(format!(
            "{name}: block {} pooled sessions {}, the captures are sessions {}: give the \
             block's sessions, in its order",
            block.block,
            block.session_ids.join(", "),
            captured.join(", ")
        )));
    }
    if q.len() != block.bits {
        return Err(NetError::Usage(format!(
            "{name}: block {} pooled {} raw bits of {} sessions, the captures' robot keys hold \
             {}: give the block's sessions, in order",
            block.block,
            block.bits,
            block.sessions,
            q.len()
        )));
    }
    let epsilon = config.postprocess.epsilon;
    let (kept, which) = amplified_bits(q, &block);
    let secrecy =
        |e: robokey_secrecy::MinEntropyError| NetError::Usage(format!("postprocess.epsilon: {e}"));
    let h_min = posterior_smooth_min_entropy(&kept, epsilon)
        .map_err(secrecy)?
        .h_min;
    let realised =
        output_length(h_min, block.leak_ec, block.leak_confirmation, epsilon).map_err(secrecy)?;
    Ok(BlockVerdict {
        block: block.block,
        raw_bits: block.bits,
        committed_bits: block.length,
        realised_bits: realised.bits,
        realised_h_min: h_min,
        exceeds: block.length > realised.bits,
        world: config.world_model().differences(config),
        amplified: kept.len(),
        which,
        reported: block,
    })
}

/// Her posterior error probabilities `q` (pool order) of the bits the block amplified, and
/// which they are: the bits outside the disclosed sample where the report says where it is
/// (the controller's), else all but the `sample_bits` bits she knows least — a bound that
/// never credits her uncertainty she may not have, lower than hers by up to the sample's
/// share of her uncertainty.
fn amplified_bits(q: &[f64], block: &BlockSummary) -> (Vec<f64>, &'static str) {
    let mut disclosed = vec![false; q.len()];
    for &i in &block.sampled {
        if let Some(d) = disclosed.get_mut(i as usize) {
            *d = true;
        }
    }
    if !block.sampled.is_empty() && disclosed.iter().filter(|&&d| d).count() == block.sample_bits {
        let kept = q
            .iter()
            .zip(&disclosed)
            .filter(|(_, d)| !**d)
            .map(|(&p, _)| p)
            .collect();
        return (kept, "those outside the disclosed sample");
    }
    let mut kept: Vec<f64> = q.iter().map(|&p| p.min(1.0 - p)).collect();
    kept.sort_by(|a, b| b.total_cmp(a));
    kept.drain(..block.sample_bits.min(kept.len()));
    (
        kept,
        "the report does not say where the sample is, so those she knows best",
    )
}

/// A session id as 8 hex digits.
fn session_hex<S: Serializer>(session: &u32, serializer: S) -> Result<S::Ok, S::Error> {
    serializer.serialize_str(&format!("{session:08x}"))
}

/// A strategy by its name.
fn strategy_name<S: Serializer>(strategy: &EveStrategy, serializer: S) -> Result<S::Ok, S::Error> {
    serializer.serialize_str(strategy.name())
}

/// Relative model errors as `{"r", "D", "W", "V"}`.
fn model_errors<S: Serializer>(errors: &ModelErrors, serializer: S) -> Result<S::Ok, S::Error> {
    let mut map = serializer.serialize_map(Some(4))?;
    map.serialize_entry("r", &errors.r)?;
    map.serialize_entry("D", &errors.d)?;
    map.serialize_entry("W", &errors.w)?;
    map.serialize_entry("V", &errors.v)?;
    map.end()
}

/// A disagreement as its percentage (null without one, or for an empty key).
fn disagreement_percent<S: Serializer>(
    disagreement: &Option<Disagreement>,
    serializer: S,
) -> Result<S::Ok, S::Error> {
    disagreement.and_then(|d| d.percent()).serialize(serializer)
}

#[cfg(test)]
mod tests {
    fn block(sample_bits: usize, sampled: Vec<u32>) -> super::BlockSummary {
        super::BlockSummary {
            block: 0,
            sessions: 1,
            session_ids: vec!["00000001".into()],
            bits: 4,
            sample_bits,
            sample_errors: 0,
            sampled,
            reconciled_bits: 4 - sample_bits,
            leak_ec: 0,
            ldpc_rounds: None,
            llrs: None,
            leak_confirmation: 0,
            h_min: 0.0,
            length: 1,
            separation: None,
            reason: None,
        }
    }

    #[test]
    fn her_bound_leaves_out_the_disclosed_sample_where_the_report_says_where_it_is() {
        let q = [0.1, 0.4, 0.2, 0.3];
        let (kept, _) = super::amplified_bits(&q, &block(2, vec![0, 3]));
        assert_eq!(kept, [0.4, 0.2]);
        // Without positions, the bits she knows least (largest error probability) go.
        let (kept, which) = super::amplified_bits(&q, &block(2, Vec::new()));
        assert_eq!(kept, [0.2, 0.1]);
        assert!(which.contains("does not say"), "{which}");
        // Positions that do not make the sample (out of range) are not trusted.
        let (kept, _) = super::amplified_bits(&q, &block(2, vec![0, 9]));
        assert_eq!(kept, [0.2, 0.1]);
    }

    /// A block report that names its sessions is checked against the captures': other
    /// sessions, or the same in another order, are refused naming both lists; the block's own
    /// order is accepted.
    #[test]
    fn a_block_is_checked_on_the_sessions_its_report_names_in_its_order() {
        let mut summary = block(0, Vec::new());
        summary.sessions = 2;
        summary.session_ids = vec!["0000000b".into(), "0000000a".into()];
        summary.bits = 2;
        summary.reconciled_bits = 2;
        let report = serde_json::json!({ "post": { "blocks": [summary] } });
        let path = std::env::temp_dir().join(format!(
            "robokey-block-sessions-{}.json",
            std::process::id()
        ));
        std::fs::write(&path, report.to_string()).unwrap();
        let config = robokey::Config::default();
        let q = [vec![0.1], vec![0.2]];
        let refused = super::block_verdicts(&path, &[0xa, 0xb], &q, &config).unwrap_err();
        assert!(
            refused.to_string().contains(
                "pooled sessions 0000000b, 0000000a, the captures are sessions 0000000a, 0000000b"
            ),
            "{refused}"
        );
        let verdicts = super::block_verdicts(&path, &[0xb, 0xa], &q, &config);
        std::fs::remove_file(&path).unwrap();
        assert_eq!(verdicts.unwrap()[0].raw_bits, 2);
    }

    /// The verdict's `world` (capture.json's `block.world`, and the WARNING's words) names
    /// what differs from the parties' statement: a command quantum they state is theirs.
    #[test]
    fn a_blocks_world_names_the_command_quantum_the_parties_state() {
        let world_of = |stated: f64, world: f64| {
            let config = robokey::Config::from_toml(
                &format!(
                    "[sensing]\nmode = \"private\"\n[robot]\ncommand_quantum = {stated}\n\
                     [world]\ncommand_quantum = {world}\n"
                ),
                "t",
            )
            .unwrap();
            let verdict = super::verdict_of(
                "r",
                block(0, Vec::new()),
                &["00000001".into()],
                &[0.5; 4],
                &config,
            )
            .unwrap();
            serde_json::to_value(&verdict).unwrap()["world"].clone()
        };
        assert_eq!(world_of(0.1, 0.1), serde_json::json!([]));
        assert_eq!(
            world_of(0.1, 0.0323),
            serde_json::json!(["world.command_quantum = 0.0323 (parties: 0.1)"])
        );
    }

    #[test]
    fn explicit_errors_are_four_relative_errors_in_the_open_unit_interval() {
        assert!(super::explicit_errors(&[0.05, -0.02, 0.0, 0.0]).is_ok());
        for bad in [
            &[0.1, 0.2, 0.3][..],
            &[1.0, 0.0, 0.0, 0.0],
            &[f64::NAN, 0.0, 0.0, 0.0],
        ] {
            assert!(
                super::explicit_errors(bad).unwrap_err().is_usage(),
                "{bad:?}"
            );
        }
    }

    #[test]
    fn a_disagreement_counts_differing_bits_and_refuses_other_lengths() {
        let d = super::Disagreement::of(&[0, 1, 1, 0], &[0, 0, 1, 1]).unwrap();
        assert_eq!((d.differing, d.bits, d.percent()), (2, 4, Some(50.0)));
        assert!(super::Disagreement::of(&[0, 1], &[0]).is_none());
        assert_eq!(super::Disagreement::of(&[], &[]).unwrap().percent(), None);
    }
}
