//! Run configuration (README, "One run"; `robokey config` prints every field): TOML, every field optional, unknown fields rejected,
//! validation errors that name the field, the value and the allowed range.

use serde::{Deserialize, Serialize};

use crate::code::{BlockCode, Repetition, hamming74};
use crate::model::DiffDrive;
use crate::observer::Variant;
pub use crate::private::doublet::Labeling;
use crate::private::doublet::Perturbation;
use crate::trajectory::{SQUARE, Trajectory};
use crate::world::{Camera, WorldConfig, WorldModel};

pub mod camera;
pub mod source;

/// Most steps one session may have (a session holds its trace and key in memory).
pub const MAX_STEPS: u64 = 10_000_000;
/// Most trajectory waypoints.
pub const MAX_WAYPOINTS: usize = 10_000;
/// Most replicates per grid point.
pub const MAX_REPLICATES: u32 = 1_000_000;

/// The whole configuration of a run.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Config {
    /// The robot and its plant.
    pub robot: RobotConfig,
    /// True (physical) noise of the plant and odometry.
    pub noise: NoiseConfig,
    /// What the controller decides from: the robot's odometry or its own pose sensor.
    pub sensing: SensingConfig,
    /// The reference trajectory.
    pub trajectory: TrajectoryConfig,
    /// The tracking controller.
    pub controller: ControllerConfig,
    /// The unknown-input observer.
    pub observer: ObserverConfig,
    /// The key-agreement protocol.
    pub protocol: ProtocolConfig,
    /// The block code and key budget.
    pub code: CodeConfig,
    /// The paper's eavesdropper.
    pub eve: EveConfig,
    /// Seeds and replicates.
    pub run: RunConfig,
    /// How the agents turn pooled raw bits into final keys.
    pub postprocess: PostprocessConfig,
    /// Private sensing's doublet shape (docs/private-sensing.md); absent: the defaults.
    #[serde(skip_serializing_if = "PrivateConfig::is_default")]
    pub private: PrivateConfig,
    /// The true physics, apart from what the parties believe (docs/world.md); absent: the
    /// parties' own model.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub world: Option<WorldConfig>,
}

/// `[robot]`
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RobotConfig {
    /// Sample time `T` (s).
    #[serde(rename = "T")]
    pub sample_time: f64,
    /// Wheel radius `r` (m).
    pub r: f64,
    /// Axle length `D` (m).
    #[serde(rename = "D")]
    pub axle_length: f64,
    /// The plant's per-wheel speed limit (rad/s).
    pub wheel_limit: f64,
    /// The resolution the robot's actuator rounds each wheel's speed command to, `q·round(ω/q)`
    /// (rad/s; 0, the default: none): a stated calibration of the model class, which the
    /// parties' likelihood and Eve's modelled view apply to every bit pattern's wheel commands
    /// (docs/estimation.md, "Command quantum"). At most [`MAX_COMMAND_QUANTUM`]. An agreement
    /// term when not 0.
    #[serde(skip_serializing_if = "is_zero")]
    pub command_quantum: f64,
}

/// The largest `robot.command_quantum` (rad/s): a coarser rounding swamps the doublet's wheel
/// offsets (Δv/r = 1.67 rad/s at the defaults).
pub const MAX_COMMAND_QUANTUM: f64 = 1.0;

/// Whether a stated value is 0 (then it is not written out, so that older configurations'
/// digests and dumps are unchanged).
fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

impl RobotConfig {
    /// The wheels' geometry `H` (`r`, `D`).
    #[must_use]
    pub fn drive(&self) -> DiffDrive {
        DiffDrive {
            wheel_radius: self.r,
            axle_length: self.axle_length,
        }
    }
}

impl Default for RobotConfig {
    fn default() -> Self {
        Self {
            sample_time: 0.2,
            r: 0.021,
            axle_length: 0.1047,
            wheel_limit: 38.0,
            command_quantum: 0.0,
        }
    }
}

/// `[noise]`: standard deviations per component and step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NoiseConfig {
    /// Process noise std `[m, m, rad]`.
    pub process_std: [f64; 3],
    /// Measurement noise std `[m, m, rad]`.
    pub measurement_std: [f64; 3],
}

impl Default for NoiseConfig {
    fn default() -> Self {
        Self {
            process_std: [0.004; 3],
            measurement_std: [0.0005; 3],
        }
    }
}

/// What the controller decides from (docs/private-sensing.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SensingMode {
    /// The paper's mode: the robot sends its odometry, which is public.
    Odometry,
    /// The controller reads its own pose sensor; the robot sends no pose; key bits ride on
    /// doublets.
    Private,
}

impl SensingMode {
    /// Its name in configs.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Odometry => "odometry",
            Self::Private => "private",
        }
    }
}

/// `[sensing]`
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensingConfig {
    /// Odometry (the paper's) or private sensing.
    pub mode: SensingMode,
    /// Noise std of the controller's own pose sensor `[m, m, rad]` (private mode).
    pub controller_std: [f64; 3],
}

impl Default for SensingConfig {
    fn default() -> Self {
        Self {
            mode: SensingMode::Odometry,
            controller_std: [0.0005; 3],
        }
    }
}

/// `[trajectory]`
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrajectoryConfig {
    /// Waypoints (m).
    pub waypoints: Vec<[f64; 2]>,
    /// Time per segment (s).
    pub side_time: f64,
    /// Number of laps.
    pub laps: u32,
}

impl Default for TrajectoryConfig {
    fn default() -> Self {
        Self {
            waypoints: SQUARE.to_vec(),
            side_time: 17.0,
            laps: 3,
        }
    }
}

/// Which pose the controller feeds back.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Feedback {
    /// The odometry measurement `y(k)`.
    Measurement,
    /// The observer's estimate `x̂(k)`.
    Estimate,
}

/// `[controller]`
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControllerConfig {
    /// Proportional gain.
    pub kp: f64,
    /// Derivative gain.
    pub kd: f64,
    /// ξ guard (m/s).
    pub xi_eps: f64,
    /// The controller's wheel limit for the rhombus clip (rad/s).
    pub wheel_limit: f64,
    /// Pose fed back.
    pub feedback: Feedback,
}

impl Default for ControllerConfig {
    fn default() -> Self {
        Self {
            kp: 1.1,
            kd: 0.8,
            xi_eps: 1e-3,
            wheel_limit: 8.07,
            feedback: Feedback::Measurement,
        }
    }
}

/// `[observer]`
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ObserverConfig {
    /// Algebra variant.
    pub variant: Variant,
    /// Number of unknown inputs (1 or 2).
    pub m: u8,
    /// Design process variance (`W = W_var·I`).
    #[serde(rename = "W_var")]
    pub w_var: f64,
    /// Design measurement variance (`V = V_var·I`).
    #[serde(rename = "V_var")]
    pub v_var: f64,
}

impl Default for ObserverConfig {
    fn default() -> Self {
        Self {
            variant: Variant::Corrected,
            m: 2,
            w_var: 1e-2,
            v_var: 1e-4,
        }
    }
}

/// `[protocol]`
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProtocolConfig {
    /// `false`: the robot applies the nominal command; no key bits (the J_x baseline).
    pub enabled: bool,
    /// Δv (m/s).
    pub delta_v: f64,
    /// Δω (rad/s); defaults to 0 in odometry mode and to [`DOUBLET_DELTA_OMEGA`] in private
    /// mode, where it carries the second bit of a doublet.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub delta_omega: Option<f64>,
    /// Dimensions a doublet carries in private mode: 1 (on v) or 2 (a second on ω); each
    /// carries log₂ [`Self::levels`] key bits.
    pub bits_per_doublet: u8,
    /// Private mode: amplitude levels per dimension, 2, 4 or 8 — a symbol of log₂ levels
    /// key bits, the first step's offset `a·Δ` with `a ∈ {±1, ±3, …}/√E`, `E = (levels² −
    /// 1)/3` the alphabet's mean square, so Δ keeps the binary alphabet's power.
    #[serde(skip_serializing_if = "ProtocolConfig::is_binary")]
    pub levels: u8,
    /// Private mode with `levels > 2`: which bits label which amplitude.
    #[serde(skip_serializing_if = "Labeling::is_natural")]
    pub labeling: Labeling,
    /// Private mode: doublets whose public nominal turn rate exceeds this carry no bit (rad/s).
    pub max_turn_rate: f64,
}

/// The default Δω (rad/s) of the second bit of a doublet.
pub const DOUBLET_DELTA_OMEGA: f64 = 0.035;

impl Default for ProtocolConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            delta_v: 0.035,
            delta_omega: None,
            bits_per_doublet: 1,
            levels: 2,
            labeling: Labeling::Natural,
            max_turn_rate: 0.5,
        }
    }
}

impl ProtocolConfig {
    /// Two levels per dimension: one key bit per dimension, the binary doublet.
    #[must_use]
    pub fn is_binary(levels: &u8) -> bool {
        *levels == 2
    }

    /// Key bits a private-mode doublet carries: `bits_per_doublet · log₂ levels`.
    #[must_use]
    pub fn key_bits_per_doublet(&self) -> usize {
        usize::from(self.bits_per_doublet) * self.levels.max(2).trailing_zeros() as usize
    }
}

/// Block code kinds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CodeKind {
    /// Repetition code of length `n_c`.
    Repetition,
    /// Hamming(7,4).
    Hamming74,
}

/// `[code]`
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CodeConfig {
    /// Code family.
    pub kind: CodeKind,
    /// Codeword length; defaults to 3 for repetition and must be 7 for Hamming(7,4).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub n_c: Option<u32>,
    /// Largest Hamming distance to the nearest codeword that is accepted.
    pub accept_max_distance: u32,
    /// Key budget (bits); 0 = no budget.
    pub key_bits: u32,
}

impl Default for CodeConfig {
    fn default() -> Self {
        Self {
            kind: CodeKind::Repetition,
            n_c: None,
            accept_max_distance: 0,
            key_bits: 345,
        }
    }
}

impl CodeConfig {
    /// The codeword length after defaults.
    #[must_use]
    pub fn codeword_length(&self) -> u32 {
        match self.kind {
            CodeKind::Repetition => self.n_c.unwrap_or(3),
            CodeKind::Hamming74 => self.n_c.unwrap_or(7),
        }
    }

    /// Builds the code (call after [`Config::validate`]).
    #[must_use]
    pub fn build(&self) -> std::sync::Arc<dyn BlockCode> {
        match self.kind {
            CodeKind::Repetition => std::sync::Arc::new(
                Repetition::new(self.codeword_length() as usize).expect("validated n_c"),
            ),
            CodeKind::Hamming74 => std::sync::Arc::new(hamming74()),
        }
    }
}

/// How Eve's relative errors are drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Draw {
    /// One draw per parameter.
    Independent,
    /// One draw shared by all parameters.
    Common,
}

/// Which eavesdropper listens (docs/threat-model.md). Each strategy after `mismatch` adds one
/// capability to the one before it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EveStrategy {
    /// Exact model: decides exactly as the controller does.
    Oracle,
    /// The paper's Eve: relative model errors up to α on r, D, W, V, hard bit decisions.
    Mismatch,
    /// `mismatch` deciding codewords by maximum likelihood from `d̂` and `Pᵈ`.
    Soft,
    /// `soft` that starts with errors of `initial_error` on r and D and learns them online.
    Identify,
    /// `identify` that also searches her least reliable bits for the key matching the public
    /// confirmation tag, and learns from the recovered key's bits.
    Transcript,
    /// Private mode, the strongest: exact model, every frame of her own camera, and the
    /// controller's doublet-boundary samples, which the public commands reveal.
    Camera,
    /// Private mode: `camera` without the camera — what the public commands leak.
    Commands,
}

impl EveStrategy {
    /// Every strategy: the odometry mode's in order of capability, then the private mode's.
    pub const ALL: [Self; 7] = [
        Self::Oracle,
        Self::Mismatch,
        Self::Soft,
        Self::Identify,
        Self::Transcript,
        Self::Camera,
        Self::Commands,
    ];

    /// The strategies that apply in `mode`, in the order of [`Self::ALL`].
    #[must_use]
    pub fn of_mode(mode: SensingMode) -> Vec<Self> {
        Self::ALL.into_iter().filter(|s| s.mode() == mode).collect()
    }

    /// The mode whose sessions this strategy listens to.
    #[must_use]
    pub fn mode(self) -> SensingMode {
        match self {
            Self::Camera | Self::Commands => SensingMode::Private,
            _ => SensingMode::Odometry,
        }
    }

    /// The name used in configs and on the command line.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Oracle => "oracle",
            Self::Mismatch => "mismatch",
            Self::Soft => "soft",
            Self::Identify => "identify",
            Self::Transcript => "transcript",
            Self::Camera => "camera",
            Self::Commands => "commands",
        }
    }
}

/// Largest `eve.max_flips`: `2^24` tag computations per session.
pub const MAX_TAG_FLIPS: u32 = 24;

/// Most bits of a window smoother's other doublets, summed over exactly (`2^12` patterns):
/// bounds `eve.smoother_window`.
pub const MAX_NUISANCE_BITS: u32 = 12;

/// `eve.camera_std`'s default `[m, m, rad]`: 8 mm, 8 mm, 8 mrad per sample instant.
pub const DEFAULT_CAMERA_STD: [f64; 3] = [0.008; 3];

/// `[eve]`
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EveConfig {
    /// Whether the run has an eavesdropper.
    pub enabled: bool,
    /// Her strategy; defaults to `mismatch` in odometry mode and `camera` in private mode.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub strategy: Option<EveStrategy>,
    /// Largest relative model error α (fraction) of `mismatch` and `soft`.
    pub alpha: f64,
    /// Independent or common draws.
    pub draw: Draw,
    /// Relative error on r and D (fraction, signs drawn) that `identify` and `transcript`
    /// start from.
    pub initial_error: f64,
    /// Largest number of least-reliable codewords `transcript` flips while searching for
    /// the key that matches the confirmation tag (`2^max_flips` tags at most).
    pub max_flips: u32,
    /// Sessions `robokey eve` simulates; what Eve learns carries over between them.
    pub sessions: u32,
    /// Sliding window (steps) of the error rates `robokey eve` reports.
    pub window: u32,
    /// Eve matches the controller once her windowed error rate stays within this many
    /// percentage points of the controller's.
    pub match_tolerance_pp: f64,
    /// Private mode: std of her camera `[m, m, rad]`, her effective noise per sample instant
    /// after her own filtering (a camera averaging M frames per instant has σ/√M). Not used
    /// when the camera is stated in frames (`camera_fps`, `camera_frame_std`); a value other
    /// than its default is then refused as a second statement.
    pub camera_std: [f64; 3],
    /// Private mode: the camera in camera terms — her frames per second (any phase), given
    /// together with `camera_frame_std`. Eve's modelled view then uses her frames
    /// (docs/threat-model.md).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub camera_fps: Option<f64>,
    /// Private mode: noise std of each of her frames `[m, m, rad]`, white and independent
    /// between frames; given together with `camera_fps`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub camera_frame_std: Option<[f64; 3]>,
    /// Private mode: doublets each side of the window over which the `camera` and
    /// `commands` eavesdroppers smooth (docs/world.md). Absent: 2 where the world's boundary
    /// samples do not screen a doublet from its neighbours, else each doublet on its own.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub smoother_window: Option<u32>,
}

impl Default for EveConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            strategy: None,
            alpha: 0.10,
            draw: Draw::Independent,
            initial_error: 0.40,
            max_flips: 16,
            sessions: 5,
            window: 200,
            match_tolerance_pp: 0.5,
            camera_std: DEFAULT_CAMERA_STD,
            camera_fps: None,
            camera_frame_std: None,
            smoother_window: None,
        }
    }
}

/// `[private]`: what the parties state about the plant when shaping a doublet.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PrivateConfig {
    /// The actuator lag τ (s) the parties assume, a prior of the model class's first-order
    /// lag: 0 (the default) keeps the two-step doublet; τ > 0 makes it three steps
    /// `(+1, −(1 + a), +a)·s·Δ`, `a = e^(−T/τ)`, which leaves a first-order lag of τ no
    /// bit-dependent position or speed at the doublet's end, so that the next commands
    /// reveal nothing of the bit. At most [`MAX_PRIOR_LAG`]. An agreement term.
    pub prior_lag: f64,
}

/// The largest `private.prior_lag` (s): a world's lag is at most this too.
pub const MAX_PRIOR_LAG: f64 = crate::world::MAX_WORLD_SECONDS;

impl PrivateConfig {
    /// Whether it is the default (then it is not written out, so that older
    /// configurations' digests and dumps are unchanged).
    #[must_use]
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }
}

/// `[postprocess]`: the agents' pooled post-processing (docs/postprocessing.md). Both
/// agents must hold the same values: they are part of the configuration digest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PostprocessConfig {
    /// The controller proposes a block once its pool holds at least this many raw bits.
    pub block_bits: u32,
    /// Largest sample disclosed to estimate the error rate (at most a tenth of the block).
    pub sample_bits: u32,
    /// ε of each term (smoothing, amplification, parameter estimation): keys are 4ε-secret.
    pub epsilon: f64,
    /// Odometry mode only — a *restricted* assumption: Eve never learns the model, and her
    /// guesses of the bits err independently with at least this probability. Keys made
    /// under it are labelled restricted and need the agents' `--allow-restricted`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub assumed_eve_error: Option<f64>,
    /// Private sensing: what sizes the keys — the configured physics, or the motion noise
    /// the controller measures per block (docs/estimation.md). Unset, it follows the sensing
    /// mode ([`Sizing::following`]: measured under private sensing, else configured);
    /// [`Config::sizing`] resolves it. Printed only when set.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sizing: Option<Sizing>,
    /// How the pooled bits are reconciled: `cascade` (interactive, on decisions) or `ldpc`
    /// (one-way syndromes decoded on the controller's LLRs; private sensing only). An
    /// agreement term; printed only when `ldpc`.
    #[serde(skip_serializing_if = "Reconciliation::is_cascade")]
    pub reconciliation: Reconciliation,
    /// Private sensing with LDPC: which model the LLRs LDPC decodes on are computed with —
    /// the prior's, online, or the motion noise measured at block time from the disclosed
    /// sample (docs/estimation.md, "Causality"). Unset, it follows the sizing
    /// ([`LlrModel::following`]: measured under the measured sizing with LDPC, else the
    /// prior); [`Config::llr_model`] resolves it. The controller's alone (the robot never sees
    /// LLRs); printed only when set.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub llrs: Option<LlrModel>,
}

/// Which model the controller's LLRs that LDPC decodes on are computed with
/// (docs/estimation.md, "Causality"). One vocabulary for `postprocess.llrs` and
/// `robokey secrecy --llrs`; unset, [`LlrModel::following`] the sizing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LlrModel {
    /// The prior (`noise.process_std`), online as each doublet is decided.
    Prior,
    /// Recomputed at block time from the kept samples with the motion noise's point
    /// estimate Q̂ from the doublets the disclosed sample holds a bit of (public bits); the
    /// prior where the sample touches too few doublets or the fit refuses them.
    Measured,
    /// Recomputed at block time with the simulated world's own motion noise: an oracle
    /// bound on what recomputation can gain. Simulator only (`robokey secrecy --llrs
    /// world`): no robot knows its true world.
    World,
}

impl LlrModel {
    /// The name used in configurations, on the command line and in reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Prior => "prior",
            Self::Measured => "measured",
            Self::World => "world",
        }
    }

    /// Whether it is the prior.
    #[must_use]
    pub fn is_prior(&self) -> bool {
        *self == Self::Prior
    }

    /// The default that follows what sizes the key and how the bits are reconciled:
    /// [`Self::Measured`] where LDPC decodes and the sizing is not the configured physics
    /// (the measured sizing trusts the block's own motion noise for the key, so its LDPC
    /// decodes on it too; the world sizing, the measured one's comparison, decodes as it
    /// does), else [`Self::Prior`] (the configured sizing trusts the prior, and Cascade
    /// reads no LLRs).
    #[must_use]
    pub fn following(sizing: Sizing, reconciliation: Reconciliation) -> Self {
        if reconciliation == Reconciliation::Ldpc && sizing != Sizing::Configured {
            Self::Measured
        } else {
            Self::Prior
        }
    }
}

/// How post-processing reconciles the controller's bits with the robot's
/// (docs/postprocessing.md). One vocabulary for `postprocess.reconciliation` and
/// `robokey secrecy --reconciliation`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Reconciliation {
    /// Interactive Cascade with BICONF on the controller's decisions: both sides' parities
    /// are charged.
    #[default]
    Cascade,
    /// One-way LDPC: the robot's syndrome, decoded by belief propagation on the controller's
    /// calibrated LLRs (`LdpcSettings::DEFAULT`: m = ⌈1.09·H + 2·√H⌉ for the soft limit H,
    /// ≤ 8 feedback rounds of max(0.04·m, 2·√m), ≤ 200 iterations): every syndrome bit and
    /// ⌈log₂ 9⌉ = 4 bits for the rounds are charged.
    Ldpc,
}

impl Reconciliation {
    /// The name used in configurations, on the command line and in reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Cascade => "cascade",
            Self::Ldpc => "ldpc",
        }
    }

    /// Whether it is Cascade (the default).
    #[must_use]
    pub fn is_cascade(&self) -> bool {
        *self == Self::Cascade
    }
}

/// What sizes private sensing's keys: the configured physics, or the motion noise the
/// controller measures per block (docs/estimation.md). One vocabulary for
/// `postprocess.sizing` and `robokey secrecy --sizing`, whose defaults differ: the agents'
/// [`Sizing::following`] the sensing mode; the lab's, [`Default`], [`Sizing::Configured`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Sizing {
    /// Eve's modelled view from the configured `noise.process_std` (the paper's; over-claims
    /// in a world quieter than configured, docs/world.md).
    #[default]
    Configured,
    /// Eve's modelled view at the worst case of the (1 − ε_est) region of the motion noise
    /// the controller estimates per block; ε_est = ε is a term of the key's ε.
    Measured,
    /// Eve's modelled view, through the measured sizing's steps, at the simulated world's own
    /// motion noise and correlation: a pair configured with the true world. Simulator only
    /// (`robokey secrecy --sizing world`, the comparison for `Measured`): no robot knows its
    /// true world, so the agents refuse it as `postprocess.sizing`.
    World,
}

impl Sizing {
    /// The name used in configurations, on the command line and in reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Configured => "configured",
            Self::Measured => "measured",
            Self::World => "world",
        }
    }

    /// Whether it is the configured physics.
    #[must_use]
    pub fn is_configured(&self) -> bool {
        *self == Self::Configured
    }

    /// The agents' sizing where `postprocess.sizing` is unset: [`Self::Measured`] under
    /// private sensing (its controller sees the robot's own physics through its private
    /// sensor, so the key rests on what it measures, not on `noise.process_std`), else
    /// [`Self::Configured`] (odometry mode measures nothing private). The simulator's
    /// `robokey secrecy --sizing` keeps its own default, configured (the lab's comparison).
    #[must_use]
    pub fn following(mode: SensingMode) -> Self {
        match mode {
            SensingMode::Private => Self::Measured,
            SensingMode::Odometry => Self::Configured,
        }
    }
}

impl Default for PostprocessConfig {
    fn default() -> Self {
        Self {
            block_bits: 10_000,
            sample_bits: 1_000,
            epsilon: 1e-6,
            assumed_eve_error: None,
            sizing: None,
            reconciliation: Reconciliation::Cascade,
            llrs: None,
        }
    }
}

/// `[run]`
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RunConfig {
    /// Master seed of all random streams.
    pub seed: u64,
    /// Runs per configuration (sweep point).
    pub replicates: u32,
}

impl Default for RunConfig {
    fn default() -> Self {
        Self {
            seed: 2023,
            replicates: 10,
        }
    }
}

/// A configuration problem, naming where it came from, the field, the value and what is
/// allowed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// A field's value is outside its allowed range.
    #[error("{origin}: `{field}` = {value} is not allowed (allowed: {allowed})")]
    Invalid {
        /// File or source of the configuration.
        origin: String,
        /// Dotted field path, e.g. `protocol.delta_v`.
        field: String,
        /// The offending value.
        value: String,
        /// The allowed range.
        allowed: String,
    },
    /// The TOML does not parse or does not fit the schema (unknown field, wrong type).
    #[error("{origin}: {message}")]
    Parse {
        /// File or source of the configuration.
        origin: String,
        /// The parser's message, with the location.
        message: String,
    },
}

impl ConfigError {
    /// Whether the error is the user's input (a file or a flag): always, for a
    /// configuration. A command line maps it to its usage exit status.
    #[must_use]
    pub fn is_usage(&self) -> bool {
        true
    }

    /// The same error attributed to `origin` (a file name, `--set`, …).
    #[must_use]
    pub fn with_origin(self, new_origin: &str) -> Self {
        match self {
            Self::Invalid {
                field,
                value,
                allowed,
                ..
            } => Self::Invalid {
                origin: new_origin.to_owned(),
                field,
                value,
                allowed,
            },
            Self::Parse { message, .. } => Self::Parse {
                origin: new_origin.to_owned(),
                message,
            },
        }
    }
}

fn invalid(field: &str, value: impl std::fmt::Debug, allowed: &str) -> ConfigError {
    ConfigError::Invalid {
        origin: String::new(),
        field: field.to_owned(),
        value: format!("{value:?}"),
        allowed: allowed.to_owned(),
    }
}

fn positive(field: &str, x: f64) -> Result<(), ConfigError> {
    if x > 0.0 && x.is_finite() {
        Ok(())
    } else {
        Err(invalid(field, x, "> 0, finite"))
    }
}

fn non_negative(field: &str, x: f64) -> Result<(), ConfigError> {
    if x >= 0.0 && x.is_finite() {
        Ok(())
    } else {
        Err(invalid(field, x, "≥ 0, finite"))
    }
}

impl Config {
    /// Parses TOML text (see [`parse_table`]) and validates it.
    ///
    /// # Errors
    /// A [`ConfigError`] attributed to `origin`.
    pub fn from_toml(text: &str, origin: &str) -> Result<Self, ConfigError> {
        Self::from_table(parse_table(text, origin)?, origin)
    }

    /// Deserializes and validates a TOML table.
    ///
    /// # Errors
    /// A [`ConfigError`] attributed to `origin`.
    pub fn from_table(table: toml::Table, origin: &str) -> Result<Self, ConfigError> {
        // Every field, the optional ones that print only when set included.
        let mut every = Self::default();
        every.postprocess.assumed_eve_error = Some(0.5);
        every.postprocess.sizing = Some(Sizing::Measured);
        every.postprocess.reconciliation = Reconciliation::Ldpc;
        every.postprocess.llrs = Some(LlrModel::Measured);
        every.eve.smoother_window = Some(0);
        every.eve.camera_fps = Some(1.0);
        every.eve.camera_frame_std = Some([1.0; 3]);
        every.private.prior_lag = 1.0;
        every.robot.command_quantum = 1.0;
        every.protocol.levels = 4;
        every.protocol.labeling = Labeling::Gray;
        let mut known: toml::Table = every
            .to_toml()
            .parse()
            .expect("the default config is valid TOML");
        known.insert(
            "world".to_owned(),
            toml::Value::try_from(WorldConfig::every()).expect("a world always serializes"),
        );
        check_known_fields(&table, &known, "").map_err(|e| e.with_origin(origin))?;
        // Deserializing from text makes toml's error show the offending line and field.
        let text = toml::to_string(&table).map_err(|e| ConfigError::Parse {
            origin: origin.to_owned(),
            message: e.to_string(),
        })?;
        let config: Self =
            toml::from_str(&text).map_err(|e: toml::de::Error| ConfigError::Parse {
                origin: origin.to_owned(),
                message: e.to_string().trim_end().to_owned(),
            })?;
        config.validate().map_err(|e| e.with_origin(origin))?;
        Ok(config)
    }

    /// Checks every field against its allowed range.
    ///
    /// # Errors
    /// The first field out of range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let robot = &self.robot;
        positive("robot.T", robot.sample_time)?;
        positive("robot.r", robot.r)?;
        positive("robot.D", robot.axle_length)?;
        positive("robot.wheel_limit", robot.wheel_limit)?;
        if !(0.0..=MAX_COMMAND_QUANTUM).contains(&robot.command_quantum) {
            return Err(invalid(
                "robot.command_quantum",
                robot.command_quantum,
                &format!("0 ≤ q ≤ {MAX_COMMAND_QUANTUM} rad/s (0: none)"),
            ));
        }
        for (i, &x) in self.noise.process_std.iter().enumerate() {
            non_negative(&format!("noise.process_std[{i}]"), x)?;
        }
        for (i, &x) in self.noise.measurement_std.iter().enumerate() {
            non_negative(&format!("noise.measurement_std[{i}]"), x)?;
        }
        let traj = &self.trajectory;
        if traj.waypoints.len() < 2 {
            return Err(invalid(
                "trajectory.waypoints",
                &traj.waypoints,
                "≥ 2 points",
            ));
        }
        if traj.waypoints.iter().flatten().any(|x| !x.is_finite()) {
            return Err(invalid(
                "trajectory.waypoints",
                &traj.waypoints,
                "finite coordinates",
            ));
        }
        positive("trajectory.side_time", traj.side_time)?;
        if traj.laps < 1 {
            return Err(invalid("trajectory.laps", traj.laps, "≥ 1"));
        }
        if traj.waypoints.len() > MAX_WAYPOINTS {
            return Err(invalid(
                "trajectory.waypoints",
                traj.waypoints.len(),
                &format!("at most {MAX_WAYPOINTS} points"),
            ));
        }
        // Bounded before the trajectory is built: an open polyline adds one return segment.
        let steps =
            traj.waypoints.len() as f64 * f64::from(traj.laps) * traj.side_time / robot.sample_time;
        if steps > MAX_STEPS as f64 {
            return Err(invalid(
                "trajectory.laps",
                traj.laps,
                &format!(
                    "at most {MAX_STEPS} steps per session (waypoints × laps × side_time / \
                     robot.T ≈ {steps:.3e} here)"
                ),
            ));
        }
        if self.trajectory().steps(robot.sample_time) == 0 {
            return Err(invalid(
                "trajectory.side_time",
                traj.side_time,
                "long enough for at least one step of robot.T",
            ));
        }
        let ctl = &self.controller;
        positive("controller.kp", ctl.kp)?;
        positive("controller.kd", ctl.kd)?;
        positive("controller.xi_eps", ctl.xi_eps)?;
        positive("controller.wheel_limit", ctl.wheel_limit)?;
        let obs = &self.observer;
        if !(1..=2).contains(&obs.m) {
            return Err(invalid("observer.m", obs.m, "1 or 2"));
        }
        positive("observer.W_var", obs.w_var)?;
        positive("observer.V_var", obs.v_var)?;
        let proto = &self.protocol;
        let delta_omega = self.delta_omega();
        non_negative("protocol.delta_v", proto.delta_v)?;
        non_negative("protocol.delta_omega", delta_omega)?;
        non_negative("protocol.max_turn_rate", proto.max_turn_rate)?;
        if !(1..=2).contains(&proto.bits_per_doublet) {
            return Err(invalid(
                "protocol.bits_per_doublet",
                proto.bits_per_doublet,
                "1 (on v) or 2 (on v and ω)",
            ));
        }
        if ![2, 4, 8].contains(&proto.levels) {
            return Err(invalid("protocol.levels", proto.levels, "2, 4 or 8"));
        }
        for (i, &x) in self.sensing.controller_std.iter().enumerate() {
            positive(&format!("sensing.controller_std[{i}]"), x)?;
        }
        for (i, &x) in self.eve.camera_std.iter().enumerate() {
            positive(&format!("eve.camera_std[{i}]"), x)?;
        }
        self.validate_camera_frames()?;
        match self.sensing.mode {
            SensingMode::Odometry => {
                if proto.enabled && proto.delta_v == 0.0 && delta_omega == 0.0 {
                    return Err(invalid(
                        "protocol.delta_v",
                        proto.delta_v,
                        "> 0, or protocol.delta_omega > 0, while protocol.enabled = true",
                    ));
                }
                if proto.enabled && obs.m == 1 && delta_omega != 0.0 {
                    return Err(invalid(
                        "protocol.delta_omega",
                        delta_omega,
                        "0 with observer.m = 1 (the observer estimates Δv only)",
                    ));
                }
            }
            SensingMode::Private => self.validate_private()?,
        }
        if self.sensing.mode == SensingMode::Odometry && !self.private.is_default() {
            return Err(invalid(
                "private.prior_lag",
                self.private.prior_lag,
                "0 in odometry mode (it shapes private sensing's doublets)",
            ));
        }
        self.validate_wheel_speeds()?;
        if self.eve_strategy().mode() != self.sensing.mode {
            let allowed = match self.sensing.mode {
                SensingMode::Odometry => "oracle, mismatch, soft, identify or transcript",
                SensingMode::Private => {
                    "camera or commands in private mode (the odometry mode's eavesdroppers \
                     decide from odometry the robot no longer sends)"
                }
            };
            return Err(invalid("eve.strategy", self.eve_strategy().name(), allowed));
        }
        let code = &self.code;
        let n_c = code.codeword_length();
        match code.kind {
            CodeKind::Repetition if !(1..=64).contains(&n_c) => {
                return Err(invalid("code.n_c", n_c, "1 to 64 for repetition"));
            }
            CodeKind::Hamming74 if n_c != 7 => {
                return Err(invalid(
                    "code.n_c",
                    n_c,
                    "7 for hamming74 (or leave it out)",
                ));
            }
            _ => {}
        }
        if code.accept_max_distance > n_c {
            return Err(invalid(
                "code.accept_max_distance",
                code.accept_max_distance,
                &format!("0 to code.n_c = {n_c}"),
            ));
        }
        let eve = &self.eve;
        if !(0.0..1.0).contains(&eve.alpha) {
            return Err(invalid("eve.alpha", eve.alpha, "[0, 1)"));
        }
        if !(0.0..1.0).contains(&eve.initial_error) {
            return Err(invalid("eve.initial_error", eve.initial_error, "[0, 1)"));
        }
        if eve.max_flips > MAX_TAG_FLIPS {
            return Err(invalid(
                "eve.max_flips",
                eve.max_flips,
                &format!("0 to {MAX_TAG_FLIPS}"),
            ));
        }
        if let Some(half_width) = eve.smoother_window {
            let bits = u32::from(proto.bits_per_doublet);
            let most = MAX_NUISANCE_BITS / (2 * bits);
            if half_width > most {
                return Err(invalid(
                    "eve.smoother_window",
                    half_width,
                    &format!(
                        "0 to {most} doublets with protocol.bits_per_doublet = {bits} (the \
                         window's other bits are summed over exactly)"
                    ),
                ));
            }
        }
        if eve.sessions < 1 {
            return Err(invalid("eve.sessions", eve.sessions, "≥ 1"));
        }
        if eve.window < 1 {
            return Err(invalid("eve.window", eve.window, "≥ 1 step"));
        }
        if !(eve.match_tolerance_pp >= 0.0 && eve.match_tolerance_pp <= 100.0) {
            return Err(invalid(
                "eve.match_tolerance_pp",
                eve.match_tolerance_pp,
                "[0, 100] percentage points",
            ));
        }
        let post = &self.postprocess;
        if !(64..=1 << 30).contains(&post.block_bits) {
            return Err(invalid(
                "postprocess.block_bits",
                post.block_bits,
                "64 to 2^30",
            ));
        }
        if post.sample_bits > robokey_secrecy::postprocess::MAX_SAMPLE_BITS as u32 {
            return Err(invalid(
                "postprocess.sample_bits",
                post.sample_bits,
                "0 to 2^20",
            ));
        }
        if !(post.epsilon > 0.0 && post.epsilon <= 0.01) {
            return Err(invalid("postprocess.epsilon", post.epsilon, "(0, 0.01]"));
        }
        match (post.assumed_eve_error, self.sensing.mode) {
            (Some(p), SensingMode::Odometry) if !(p > 0.0 && p <= 0.5) => {
                return Err(invalid("postprocess.assumed_eve_error", p, "(0, 0.5]"));
            }
            (Some(p), SensingMode::Private) => {
                return Err(invalid(
                    "postprocess.assumed_eve_error",
                    p,
                    "absent in private mode (the key is sized by the camera statement, \
                     eve.camera_std)",
                ));
            }
            _ => {}
        }
        if post.sizing == Some(Sizing::World) {
            return Err(invalid(
                "postprocess.sizing",
                "world",
                "\"configured\" or \"measured\" (\"world\" sizes at the simulated world's \
                 own physics, which no robot knows: robokey secrecy --sizing world only)",
            ));
        }
        if post.llrs == Some(LlrModel::World) {
            return Err(invalid(
                "postprocess.llrs",
                "world",
                "\"prior\" or \"measured\" (\"world\" computes the LLRs with the simulated \
                 world's own physics, which no robot knows: robokey secrecy --llrs world only)",
            ));
        }
        if post.reconciliation == Reconciliation::Ldpc && self.sensing.mode != SensingMode::Private
        {
            return Err(invalid(
                "postprocess.reconciliation",
                "ldpc",
                "\"cascade\" in odometry mode (LDPC decodes on the controller's per-bit LLRs, \
                 which private sensing gives; sensing.mode = \"private\")",
            ));
        }
        if post.llrs == Some(LlrModel::Measured) && post.reconciliation == Reconciliation::Cascade {
            return Err(invalid(
                "postprocess.llrs",
                "measured",
                "\"prior\" with postprocess.reconciliation = \"cascade\" (Cascade reconciles \
                 the controller's hard decisions, made online with the prior, and reads no \
                 LLRs: recomputed LLRs would change nothing; postprocess.reconciliation = \
                 \"ldpc\" decodes on them)",
            ));
        }
        if post.reconciliation == Reconciliation::Ldpc && post.block_bits > 1 << 22 {
            return Err(invalid(
                "postprocess.block_bits",
                post.block_bits,
                "64 to 4194304 (2^22, one LDPC code's block) with postprocess.reconciliation \
                 = \"ldpc\"",
            ));
        }
        if post.sizing == Some(Sizing::Measured) && self.sensing.mode != SensingMode::Private {
            return Err(invalid(
                "postprocess.sizing",
                "measured",
                "\"configured\" in odometry mode (a measured plant sizes private sensing's \
                 keys; sensing.mode = \"private\")",
            ));
        }
        if let Some(world) = &self.world {
            world
                .validate(robot.sample_time)
                .map_err(|e| ConfigError::Invalid {
                    origin: String::new(),
                    field: e.field,
                    value: e.value,
                    allowed: e.allowed,
                })?;
        }
        if !(1..=MAX_REPLICATES).contains(&self.run.replicates) {
            return Err(invalid(
                "run.replicates",
                self.run.replicates,
                &format!("1 to {MAX_REPLICATES}"),
            ));
        }
        Ok(())
    }

    /// The combinations private sensing refuses (docs/private-sensing.md).
    fn validate_private(&self) -> Result<(), ConfigError> {
        let proto = &self.protocol;
        let lag = self.private.prior_lag;
        if !(0.0..=MAX_PRIOR_LAG).contains(&lag) {
            return Err(invalid(
                "private.prior_lag",
                lag,
                &format!("0 to {MAX_PRIOR_LAG} s (0: the two-step doublet)"),
            ));
        }
        if self.controller.feedback == Feedback::Estimate {
            return Err(invalid(
                "controller.feedback",
                "estimate",
                "\"measurement\" in private mode (an estimate updated with a mid-doublet \
                 sample would carry the bit into the next commands)",
            ));
        }
        if proto.enabled && proto.delta_v == 0.0 {
            return Err(invalid(
                "protocol.delta_v",
                proto.delta_v,
                "> 0 in private mode (the first bit of a doublet rides on v)",
            ));
        }
        if proto.enabled && proto.bits_per_doublet == 2 && self.delta_omega() == 0.0 {
            return Err(invalid(
                "protocol.delta_omega",
                self.delta_omega(),
                "> 0 with protocol.bits_per_doublet = 2",
            ));
        }
        Ok(())
    }

    /// Every wheel speed the controller can offer is one the robot applies: the nominal
    /// command, clipped to `controller.wheel_limit` per wheel, plus the largest per-wheel
    /// offset of the protocol, `k·(Δv + Δω·D/2)/r` (rad/s), stays within `robot.wheel_limit`;
    /// `k` is the largest step of the doublet's shape: 1, or `1 + a` for the three-step
    /// doublet's middle step `−(1 + a)·s·Δ` (`private.prior_lag`), times the alphabet's
    /// largest amplitude `(levels − 1)/√E` (1 for binary doublets).
    /// The robot refuses a pair outside its limit, so a larger Δ would make sessions whose
    /// steps are all erased: no bit, and no word why.
    fn validate_wheel_speeds(&self) -> Result<(), ConfigError> {
        let (robot, controller) = (&self.robot, &self.controller);
        let (delta_v, delta_omega) = if self.protocol.enabled {
            (self.protocol.delta_v, self.perturbed_delta_omega())
        } else {
            (0.0, 0.0)
        };
        let half_axle = robot.axle_length / 2.0;
        // A multilevel alphabet's outermost symbols reach (levels − 1)/√E times Δ.
        let peak = if self.sensing.mode == SensingMode::Private {
            Perturbation::of(self).amplitude(0)
        } else {
            1.0
        };
        let largest_step = (1.0 + self.doublet_settle().unwrap_or(0.0)) * peak;
        let offset = largest_step * (delta_v + delta_omega * half_axle) / robot.r;
        let room = robot.wheel_limit - controller.wheel_limit;
        if room < 0.0 {
            return Err(invalid(
                "controller.wheel_limit",
                controller.wheel_limit,
                &format!(
                    "≤ robot.wheel_limit = {} rad/s, minus the protocol's largest wheel offset \
                     (Δv + Δω·D/2)/r = {offset:.4} rad/s: the robot refuses commands above its \
                     limit",
                    robot.wheel_limit
                ),
            ));
        }
        if offset <= room {
            return Ok(());
        }
        // The three-step doublet's middle step `(1 + a)` and the alphabet's largest amplitude
        // scale the offset.
        let scale = if largest_step > 1.0 {
            format!("{largest_step:.4}·")
        } else {
            String::new()
        };
        let why = format!(
            "the offered wheel speeds reach controller.wheel_limit + {scale}(Δv + Δω·D/2)/r = \
             {} + {offset:.4} = {:.4} rad/s, above robot.wheel_limit = {} rad/s, and the robot \
             refuses such pairs, so no step would carry a bit",
            controller.wheel_limit,
            controller.wheel_limit + offset,
            robot.wheel_limit
        );
        // Name Δω when it alone leaves no room, else Δv, with its largest value that fits.
        Err(if largest_step * delta_omega * half_axle / robot.r > room {
            let most = robot.r * room / half_axle / largest_step;
            invalid(
                "protocol.delta_omega",
                delta_omega,
                &format!("≤ {most:.4} rad/s with these limits: {why}"),
            )
        } else {
            let most = robot.r * room / largest_step - delta_omega * half_axle;
            invalid(
                "protocol.delta_v",
                delta_v,
                &format!("≤ {most:.4} m/s with these limits: {why}"),
            )
        })
    }

    /// Δω (rad/s) after defaults: as set, else [`DOUBLET_DELTA_OMEGA`] in private mode
    /// (used only with two bits per doublet), else 0.
    #[must_use]
    pub fn delta_omega(&self) -> f64 {
        self.protocol
            .delta_omega
            .unwrap_or(match self.sensing.mode {
                SensingMode::Private => DOUBLET_DELTA_OMEGA,
                SensingMode::Odometry => 0.0,
            })
    }

    /// What sizes the agents' keys: `postprocess.sizing` as set, else
    /// [`Sizing::following`] the sensing mode (measured under private sensing, configured in
    /// odometry mode). Every reader of the agents' sizing goes through it.
    #[must_use]
    pub fn sizing(&self) -> Sizing {
        self.postprocess
            .sizing
            .unwrap_or_else(|| Sizing::following(self.sensing.mode))
    }

    /// The LLRs' model the controller decodes on: `postprocess.llrs` where set, else
    /// [`LlrModel::following`] the [`sizing`](Self::sizing) and the reconciliation.
    #[must_use]
    pub fn llr_model(&self) -> LlrModel {
        self.postprocess
            .llrs
            .unwrap_or_else(|| LlrModel::following(self.sizing(), self.postprocess.reconciliation))
    }

    /// The three-step doublet's third-step share `a = e^(−T/τ)` for `private.prior_lag`
    /// τ > 0 in private mode; `None`: the two-step doublet.
    #[must_use]
    pub fn doublet_settle(&self) -> Option<f64> {
        match self.sensing.mode {
            SensingMode::Private => crate::private::doublet::settle_share(
                self.robot.sample_time,
                self.private.prior_lag,
            ),
            SensingMode::Odometry => None,
        }
    }

    /// The Δω (rad/s) that perturbs the inputs: [`Self::delta_omega`], but 0 with one bit
    /// per doublet in private mode (the doublet then carries its bit on v only).
    #[must_use]
    pub fn perturbed_delta_omega(&self) -> f64 {
        if self.sensing.mode == SensingMode::Private && self.protocol.bits_per_doublet == 1 {
            0.0
        } else {
            self.delta_omega()
        }
    }

    /// Eve's camera as the key is sized against it: in frames when `eve.camera_fps` and
    /// `eve.camera_frame_std` are given, else `eve.camera_std` per sample instant.
    #[must_use]
    pub fn camera_statement(&self) -> Camera {
        match (self.eve.camera_fps, self.eve.camera_frame_std) {
            (Some(fps), Some(frame_std)) => Camera::Frames { fps, frame_std },
            _ => Camera::Instants {
                std: self.eve.camera_std,
            },
        }
    }

    /// The per-instant camera noise `[m, m, rad]` Eve's modelled view uses: the
    /// [`camera_statement`](Self::camera_statement) at `robot.T`.
    #[must_use]
    pub fn modelled_camera_std(&self) -> [f64; 3] {
        self.camera_statement()
            .per_instant_std(self.robot.sample_time)
    }

    /// The camera in frames: both fields or neither, a frame rate in (0, 1000] frames/s,
    /// positive frame noise, and `eve.camera_std` left at its default (one statement).
    fn validate_camera_frames(&self) -> Result<(), ConfigError> {
        let eve = &self.eve;
        match (eve.camera_fps, eve.camera_frame_std) {
            (None, None) => return Ok(()),
            (Some(fps), None) => {
                return Err(invalid(
                    "eve.camera_frame_std",
                    "(absent)",
                    &format!(
                        "given with eve.camera_fps = {fps} (the noise of each frame, m, m, rad)"
                    ),
                ));
            }
            (None, Some(std)) => {
                return Err(invalid(
                    "eve.camera_fps",
                    "(absent)",
                    &format!("given with eve.camera_frame_std = {std:?} (frames per second)"),
                ));
            }
            (Some(fps), Some(frame_std)) => {
                if !(fps > 0.0 && fps <= crate::world::MAX_CAMERA_FPS) {
                    return Err(invalid(
                        "eve.camera_fps",
                        fps,
                        &format!("> 0 and at most {} frames/s", crate::world::MAX_CAMERA_FPS),
                    ));
                }
                for (i, &x) in frame_std.iter().enumerate() {
                    positive(&format!("eve.camera_frame_std[{i}]"), x)?;
                }
            }
        }
        if eve.camera_std != DEFAULT_CAMERA_STD {
            return Err(invalid(
                "eve.camera_std",
                eve.camera_std,
                "its default when the camera is stated in frames (eve.camera_fps, \
                 eve.camera_frame_std): one statement of her camera, not two",
            ));
        }
        Ok(())
    }

    /// Eve's strategy after defaults: as set, else `mismatch` (odometry) or `camera`
    /// (private).
    #[must_use]
    pub fn eve_strategy(&self) -> EveStrategy {
        self.eve.strategy.unwrap_or(match self.sensing.mode {
            SensingMode::Odometry => EveStrategy::Mismatch,
            SensingMode::Private => EveStrategy::Camera,
        })
    }

    /// The reference trajectory.
    ///
    /// # Panics
    /// If the configuration was not validated.
    #[must_use]
    pub fn trajectory(&self) -> Trajectory {
        let t = &self.trajectory;
        Trajectory::new(&t.waypoints, t.side_time, t.laps).expect("validated trajectory")
    }

    /// The world the simulated plant and sensors live in, and the eavesdroppers know.
    #[must_use]
    pub fn world_model(&self) -> WorldModel {
        WorldModel::of(self)
    }

    /// The configuration as TOML, every field explicit (`code.n_c` resolved; a `[world]`
    /// resolved field by field, and left out when it is the parties' own model).
    #[must_use]
    pub fn to_toml(&self) -> String {
        let mut resolved = self.clone();
        resolved.code.n_c = Some(self.code.codeword_length());
        resolved.protocol.delta_omega = Some(self.delta_omega());
        resolved.eve.strategy = Some(self.eve_strategy());
        let world = self.world_model();
        resolved.world = (self.world.is_some() && world != WorldModel::ideal(self))
            .then(|| world.to_table(self.world.as_ref().and_then(|w| w.preset)));
        toml::to_string(&resolved).expect("a config always serializes")
    }
}

/// Rejects fields that the configuration does not have, naming their full path and the
/// fields allowed there.
fn check_known_fields(
    table: &toml::Table,
    known: &toml::Table,
    prefix: &str,
) -> Result<(), ConfigError> {
    for (key, value) in table {
        let path = format!("{prefix}{key}");
        match (known.get(key), value) {
            (None, _) => {
                let allowed: Vec<&str> = known.keys().map(String::as_str).collect();
                return Err(ConfigError::Parse {
                    origin: String::new(),
                    message: format!(
                        "unknown field `{path}` (allowed here: {})",
                        allowed.join(", ")
                    ),
                });
            }
            (Some(toml::Value::Table(inner)), toml::Value::Table(given)) => {
                check_known_fields(given, inner, &format!("{path}."))?;
            }
            _ => {}
        }
    }
    Ok(())
}

/// Parses TOML text into a table, attributing errors to `origin`.
///
/// # Errors
/// [`ConfigError::Parse`] with the parser's message and location.
pub fn parse_table(text: &str, origin: &str) -> Result<toml::Table, ConfigError> {
    text.parse::<toml::Table>().map_err(|e| ConfigError::Parse {
        origin: origin.to_owned(),
        message: e.to_string(),
    })
}

/// Sets the dotted `path` (e.g. `controller.kp`) in `table` to `value`, creating tables on
/// the way. Whether the field exists is checked when the table is deserialized.
///
/// # Errors
/// [`ConfigError::Parse`] when the path is empty or crosses a non-table value.
pub fn set_path(
    table: &mut toml::Table,
    path: &str,
    value: toml::Value,
) -> Result<(), ConfigError> {
    let bad = |why: &str| ConfigError::Parse {
        origin: String::new(),
        message: format!("cannot set `{path}`: {why}"),
    };
    let mut parts: Vec<&str> = path.split('.').collect();
    let last = parts
        .pop()
        .filter(|s| !s.is_empty())
        .ok_or_else(|| bad("empty field name"))?;
    let mut current = table;
    for part in parts {
        let entry = current
            .entry(part.to_owned())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        current = entry
            .as_table_mut()
            .ok_or_else(|| bad(&format!("`{part}` is not a table")))?;
    }
    current.insert(last.to_owned(), value);
    Ok(())
}

/// Parses the right-hand side of `--set field=value` as a TOML value; a bare word that is
/// not valid TOML (e.g. `paper`) is taken as a string.
#[must_use]
pub fn parse_value(text: &str) -> toml::Value {
    format!("v = {text}")
        .parse::<toml::Table>()
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(text.to_owned()))
}

/// The doublets a configuration makes (here, beside the fields it reads, so that the doublet
/// does not depend on the configuration).
impl Perturbation {
    /// The doublets of `config`: its Δ (Δω 0 with one dimension), dimensions, shape and
    /// alphabet.
    #[must_use]
    pub fn of(config: &Config) -> Self {
        Self {
            delta: crate::model::Unicycle::new(
                config.protocol.delta_v,
                config.perturbed_delta_omega(),
            ),
            bits_per_doublet: config.protocol.bits_per_doublet,
            settle: config.doublet_settle(),
            levels: config.protocol.levels,
            labeling: config.protocol.labeling,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_round_trip_and_validate() {
        let config = Config::default();
        config.validate().unwrap();
        let back = Config::from_toml(&config.to_toml(), "resolved").unwrap();
        assert_eq!(back.code.codeword_length(), 3);
        assert_eq!(Config::from_toml("", "empty").unwrap(), Config::default());
        assert_eq!(config.trajectory().steps(config.robot.sample_time), 1020);
    }

    #[test]
    fn errors_name_origin_field_value_and_range() {
        let err = Config::from_toml("[protocol]\ndelta_v = 0.0\n", "my.toml").unwrap_err();
        let text = err.to_string();
        assert!(
            text.contains("my.toml") && text.contains("protocol.delta_v"),
            "{text}"
        );
        assert!(text.contains("0.0") && text.contains("> 0"), "{text}");

        for (toml, field, allowed) in [
            ("[eve]\nmax_flips = 30\n", "eve.max_flips", "0 to 24"),
            (
                "[eve]\ninitial_error = 1.0\n",
                "eve.initial_error",
                "[0, 1)",
            ),
            ("[eve]\nstrategy = \"psychic\"\n", "psychic", "transcript"),
        ] {
            let text = Config::from_toml(toml, "e.toml").unwrap_err().to_string();
            assert!(text.contains(field) && text.contains(allowed), "{text}");
        }

        let err = Config::from_toml("[robot]\nmass = 1.0\n", "a.toml").unwrap_err();
        assert!(
            err.to_string().contains("unknown field `robot.mass`"),
            "{err}"
        );
        let err = Config::from_toml("[robot]\nT = \"fast\"\n", "a.toml").unwrap_err();
        assert!(err.to_string().contains("a.toml"), "{err}");

        let err = Config::from_toml("[eve]\nalpha = 1.5\n", "b.toml").unwrap_err();
        assert!(err.to_string().contains("eve.alpha"), "{err}");

        let err =
            Config::from_toml("[code]\nkind = \"hamming74\"\nn_c = 5\n", "c.toml").unwrap_err();
        assert!(err.to_string().contains("code.n_c"), "{err}");
        assert_eq!(
            Config::from_toml("[code]\nkind = \"hamming74\"\n", "d")
                .unwrap()
                .code
                .codeword_length(),
            7
        );
    }

    /// Multilevel doublets: 2, 4 or 8 levels; accepted with measured sizing (the agents
    /// size a block's slices together) and in every world (the window smoother judges
    /// symbols too); the wheel limit counts
    /// the outermost amplitude; the
    /// resolved TOML names the alphabet only when it is not binary.
    #[test]
    fn multilevel_doublets_are_checked() {
        let private = |extra: &str| format!("[sensing]\nmode = \"private\"\n{extra}");
        let refused = |toml: &str, field: &str| {
            let text = Config::from_toml(&private(toml), "m.toml")
                .unwrap_err()
                .to_string();
            assert!(text.contains(field), "{toml}: {text}");
        };
        refused("[protocol]\nlevels = 3\n", "2, 4 or 8");
        Config::from_toml(
            &private("[protocol]\nlevels = 4\n[postprocess]\nsizing = \"measured\"\n"),
            "m",
        )
        .unwrap();
        // Every world: the window smoother judges symbols too.
        for world in [
            "[world]\npreset = \"khepera-iv\"\n",
            "[eve]\nsmoother_window = 2\n",
        ] {
            Config::from_toml(&private(&format!("[protocol]\nlevels = 4\n{world}")), "w").unwrap();
        }
        // Δv = 0.3 m/s: its wheel offset Δv/r = 14.3 rad/s fits the 38 − 22 = 16 rad/s of
        // room, the 4-level alphabet's outermost 3/√5·Δv/r = 19.2 rad/s does not.
        let fast = "[controller]\nwheel_limit = 22.0\n[protocol]\ndelta_v = 0.3\n";
        Config::from_toml(&private(fast), "f").unwrap();
        refused(&format!("{fast}levels = 4\n"), "protocol.delta_v");
        let four = Config::from_toml(
            &private("[protocol]\nlevels = 4\nlabeling = \"gray\"\n"),
            "g",
        )
        .unwrap();
        let text = four.to_toml();
        assert!(
            text.contains("levels = 4") && text.contains("labeling = \"gray\""),
            "{text}"
        );
        let back = Config::from_toml(&text, "back").unwrap();
        assert_eq!(
            (back.protocol.levels, back.protocol.labeling),
            (4, Labeling::Gray)
        );
        assert!(!Config::default().to_toml().contains("levels"));
        assert_eq!(four.protocol.key_bits_per_doublet(), 2);
    }

    #[test]
    fn ldpc_reconciliation_needs_private_sensing_and_a_code_sized_block() {
        let ldpc = "[postprocess]\nreconciliation = \"ldpc\"\n";
        let text = Config::from_toml(ldpc, "l.toml").unwrap_err().to_string();
        assert!(
            text.contains("postprocess.reconciliation") && text.contains("odometry"),
            "{text}"
        );
        let private = format!("[sensing]\nmode = \"private\"\n{ldpc}");
        let config = Config::from_toml(&private, "p.toml").unwrap();
        assert_eq!(config.postprocess.reconciliation, Reconciliation::Ldpc);
        assert!(config.to_toml().contains("reconciliation = \"ldpc\""));
        let large = format!("{private}block_bits = 5000000\n");
        let text = Config::from_toml(&large, "b.toml").unwrap_err().to_string();
        assert!(text.contains("postprocess.block_bits"), "{text}");
        // Cascade reads the decisions, never the LLRs: recomputing them is refused.
        let cascade = "[sensing]\nmode = \"private\"\n[postprocess]\nllrs = \"measured\"\n";
        let text = Config::from_toml(cascade, "c.toml")
            .unwrap_err()
            .to_string();
        assert!(
            text.contains("c.toml")
                && text.contains("postprocess.llrs")
                && text.contains("measured")
                && text.contains("Cascade reconciles"),
            "{text}"
        );
        let measured = Config::from_toml(&format!("{private}llrs = \"measured\"\n"), "m").unwrap();
        assert_eq!(measured.postprocess.llrs, Some(LlrModel::Measured));
        assert_eq!(measured.llr_model(), LlrModel::Measured);
    }

    /// Every sensing mode × `postprocess.sizing` unset or stated: unset follows the mode
    /// (private → measured, odometry → configured); a stated value stays and is written out
    /// (an unset one is not), so a dump reads back to the same sizing; measured in odometry
    /// mode and world anywhere are refused, naming the field.
    #[test]
    fn the_sizing_follows_the_sensing_mode_unless_stated() {
        for (mode, sizing, resolved) in [
            ("odometry", "", Some(Sizing::Configured)),
            ("odometry", "configured", Some(Sizing::Configured)),
            ("odometry", "measured", None),
            ("odometry", "world", None),
            ("private", "", Some(Sizing::Measured)),
            ("private", "configured", Some(Sizing::Configured)),
            ("private", "measured", Some(Sizing::Measured)),
            ("private", "world", None),
        ] {
            let stated = if sizing.is_empty() {
                String::new()
            } else {
                format!("[postprocess]\nsizing = \"{sizing}\"\n")
            };
            let text = format!("[sensing]\nmode = \"{mode}\"\n{stated}");
            let case = format!("{mode}, sizing {sizing:?}");
            match (Config::from_toml(&text, "s.toml"), resolved) {
                (Ok(config), Some(resolved)) => {
                    assert_eq!(config.sizing(), resolved, "{case}");
                    let dumped = config.to_toml();
                    assert_eq!(dumped.contains("sizing"), !sizing.is_empty(), "{case}");
                    let again = Config::from_toml(&dumped, "dump").unwrap();
                    assert_eq!(
                        again.postprocess.sizing, config.postprocess.sizing,
                        "{case}"
                    );
                }
                (Err(error), None) => {
                    let error = error.to_string();
                    assert!(
                        error.contains("postprocess.sizing") && error.contains(sizing),
                        "{case}: {error}"
                    );
                }
                (got, want) => panic!("{case}: {got:?}, expected {want:?}"),
            }
        }
    }

    #[test]
    fn unset_llrs_follow_the_resolved_sizing_and_a_stated_model_stays() {
        let config = |post: &str| {
            let text = format!("[sensing]\nmode = \"private\"\n[postprocess]\n{post}");
            Config::from_toml(&text, "p.toml").unwrap()
        };
        let ldpc = "reconciliation = \"ldpc\"\n";
        let sized = "sizing = \"measured\"\n";
        let configured = "sizing = \"configured\"\n";
        for (post, model) in [
            (format!("{ldpc}{sized}"), LlrModel::Measured),
            // Unset, the sizing follows private sensing: measured.
            (ldpc.to_owned(), LlrModel::Measured),
            (format!("{ldpc}{configured}"), LlrModel::Prior),
            (sized.to_owned(), LlrModel::Prior),
            (String::new(), LlrModel::Prior),
            (format!("{ldpc}{sized}llrs = \"prior\"\n"), LlrModel::Prior),
            (
                format!("{ldpc}{configured}llrs = \"measured\"\n"),
                LlrModel::Measured,
            ),
        ] {
            let parsed = config(&post);
            assert_eq!(parsed.llr_model(), model, "{post}");
            // What the agents' controller asks its shell for at block time.
            assert_eq!(
                crate::estimate::recomputes_llrs(&parsed),
                model == LlrModel::Measured,
                "{post}"
            );
            // A stated model is written out, an unset one is not: a dump reads back the same.
            let dumped = parsed.to_toml();
            assert_eq!(
                dumped.contains("llrs ="),
                post.contains("llrs ="),
                "{dumped}"
            );
            let again = Config::from_toml(&dumped, "dump").unwrap();
            assert_eq!(again.llr_model(), model, "{dumped}");
        }
        // Not an agreement term: the robot never sees LLRs.
        let unset = config(&format!("{ldpc}{sized}"));
        let stated = config(&format!("{ldpc}{sized}llrs = \"prior\"\n"));
        assert_eq!(
            crate::protocol::config_digest(&unset),
            crate::protocol::config_digest(&stated)
        );
        let text = Config::from_toml("[postprocess]\nreconciliation = \"polar\"\n", "x")
            .unwrap_err()
            .to_string();
        assert!(text.contains("polar"), "{text}");
    }

    #[test]
    fn the_camera_in_frames_is_one_statement_with_both_fields() {
        for (toml, field, allowed) in [
            (
                "camera_fps = 30.0\n",
                "eve.camera_frame_std",
                "given with eve.camera_fps",
            ),
            (
                "camera_frame_std = [0.016, 0.016, 0.016]\n",
                "eve.camera_fps",
                "given with eve.camera_frame_std",
            ),
            (
                "camera_fps = 0.0\ncamera_frame_std = [0.016, 0.016, 0.016]\n",
                "eve.camera_fps",
                "> 0 and at most 1000",
            ),
            (
                "camera_fps = 30.0\ncamera_frame_std = [0.016, 0.0, 0.016]\n",
                "eve.camera_frame_std[1]",
                "> 0",
            ),
            (
                "camera_fps = 30.0\ncamera_frame_std = [0.016, 0.016, 0.016]\n\
                 camera_std = [0.004, 0.004, 0.004]\n",
                "eve.camera_std",
                "one statement of her camera",
            ),
        ] {
            let text = Config::from_toml(&format!("[eve]\n{toml}"), "e.toml")
                .unwrap_err()
                .to_string();
            assert!(text.contains(field) && text.contains(allowed), "{text}");
        }
        let config = Config::from_toml(
            "[eve]\ncamera_fps = 30.0\ncamera_frame_std = [0.016, 0.016, 0.016]\n",
            "f.toml",
        )
        .unwrap();
        // 6 frames per step, the worst phase a frame at each instant: 16 mm / √4.056.
        let modelled = config.modelled_camera_std();
        assert!((modelled[0] - 0.016 / (1.0f64 + 110.0 / 36.0).sqrt()).abs() < 1e-12);
        assert_eq!(Config::default().modelled_camera_std(), DEFAULT_CAMERA_STD);
    }

    #[test]
    fn a_delta_whose_offered_wheel_speeds_exceed_the_robots_limit_is_named() {
        // r = 0.021 m, D = 0.1047 m, limits 8.07 (controller) and 38 rad/s (robot): the
        // wheel offset Δv/r may be at most 29.93 rad/s, Δv ≤ 0.62853 m/s.
        let field_and_allowed = |toml: &str| match Config::from_toml(toml, "t").unwrap_err() {
            ConfigError::Invalid { field, allowed, .. } => (field, allowed),
            other => panic!("{other}"),
        };
        for delta_v in ["1.0", "35.0", "1e308", "0.6286"] {
            let (field, allowed) = field_and_allowed(&format!("[protocol]\ndelta_v = {delta_v}\n"));
            assert_eq!(field, "protocol.delta_v");
            assert!(
                allowed.starts_with("≤ 0.6285 m/s") && allowed.contains("robot.wheel_limit = 38"),
                "{allowed}"
            );
        }
        Config::from_toml("[protocol]\ndelta_v = 0.6285\n", "t").unwrap();
        // Δω alone: its offset Δω·D/(2r) may be at most 29.93 rad/s, Δω ≤ 12.0063 rad/s.
        let (field, allowed) =
            field_and_allowed("[protocol]\ndelta_v = 0.0\ndelta_omega = 12.01\n");
        assert_eq!(field, "protocol.delta_omega");
        assert!(allowed.starts_with("≤ 12.0063 rad/s"), "{allowed}");
        // A controller allowed to command more than the robot applies.
        let (field, _) = field_and_allowed("[robot]\nwheel_limit = 6.0\n");
        assert_eq!(field, "controller.wheel_limit");
        // Without the protocol only the controller's limit counts.
        Config::from_toml("[protocol]\nenabled = false\ndelta_v = 35.0\n", "t").unwrap();
    }

    /// The stated command quantum: 0 to 1 rad/s, named when outside; an agreement term only
    /// when not 0, and not written out at 0.
    #[test]
    fn the_command_quantum_is_bounded_and_an_agreement_term_when_stated() {
        for q in ["-0.01", "1.5", "nan"] {
            match Config::from_toml(&format!("[robot]\ncommand_quantum = {q}\n"), "t") {
                Err(ConfigError::Invalid { field, allowed, .. }) => {
                    assert_eq!(field, "robot.command_quantum");
                    assert!(allowed.starts_with("0 ≤ q ≤ 1 rad/s"), "{allowed}");
                }
                other => panic!("{q}: {other:?}"),
            }
        }
        let private = "[sensing]\nmode = \"private\"\n";
        let stated = Config::from_toml(
            &format!("{private}[robot]\ncommand_quantum = 0.0323\n"),
            "t",
        )
        .unwrap();
        let plain = Config::from_toml(private, "t").unwrap();
        let line = "robot.command_quantum = 0.0323\n";
        assert!(crate::protocol::agreement_terms(&stated).contains(line));
        assert!(!crate::protocol::agreement_terms(&plain).contains("command_quantum"));
        assert!(!plain.to_toml().contains("command_quantum"));
        assert!(stated.to_toml().contains("command_quantum = 0.0323"));
    }

    #[test]
    fn the_prior_lag_is_named_out_of_range_and_its_middle_step_within_the_wheel_limit() {
        let error = |toml: &str| match Config::from_toml(toml, "t").unwrap_err() {
            ConfigError::Invalid { field, allowed, .. } => (field, allowed),
            other => panic!("{other}"),
        };
        let private = "[sensing]\nmode = \"private\"\n";
        for lag in ["-0.01", "1.5", "nan"] {
            let (field, allowed) = error(&format!("{private}[private]\nprior_lag = {lag}\n"));
            assert_eq!(field, "private.prior_lag");
            assert!(allowed.starts_with("0 to 1 s"), "{allowed}");
        }
        let (field, allowed) = error("[private]\nprior_lag = 0.05\n");
        assert_eq!(field, "private.prior_lag");
        assert!(allowed.contains("odometry mode"), "{allowed}");
        // With τ = 100 ms the middle step is (1 + e^(−2))·Δv: Δv ≤ 0.62853 / 1.13534.
        let shaped = format!("{private}[private]\nprior_lag = 0.1\n");
        let (field, allowed) = error(&format!("{shaped}[protocol]\ndelta_v = 0.5537\n"));
        assert_eq!(field, "protocol.delta_v");
        assert!(
            allowed.starts_with("≤ 0.5536 m/s") && allowed.contains("1.1353·(Δv"),
            "{allowed}"
        );
        let config = Config::from_toml(&format!("{shaped}[protocol]\ndelta_v = 0.5536\n"), "t");
        assert_eq!(config.unwrap().doublet_settle(), Some((-2.0f64).exp()));
    }

    #[test]
    fn a_world_is_written_only_when_it_is_not_the_parties() {
        let plain = Config::default().to_toml();
        assert!(!plain.contains("[world]"));
        let ideal = Config::from_toml("[world]\npreset = \"ideal\"\n", "w").unwrap();
        assert_eq!(ideal.to_toml(), plain);
        let lagged = Config::from_toml("[world]\nlag = 0.05\n", "w").unwrap();
        let text = lagged.to_toml();
        assert!(
            text.contains("[world]") && text.contains("lag = 0.05"),
            "{text}"
        );
        let back = Config::from_toml(&text, "back").unwrap();
        assert_eq!(back.world_model(), lagged.world_model());
        for (toml, names) in [
            ("[world]\nlag = -0.1\n", ["w.toml", "world.lag"]),
            ("[world]\npreset = \"mars\"\n", ["mars", "khepera-iv"]),
            (
                "[world]\nmass = 1.0\n",
                ["unknown field `world.mass`", "slip_std"],
            ),
            (
                "[world]\nprocess_rho = -1.0\n",
                ["world.process_rho", "−1 < ρ < 1"],
            ),
        ] {
            let text = Config::from_toml(toml, "w.toml").unwrap_err().to_string();
            assert!(names.iter().all(|n| text.contains(n)), "{text}");
        }
    }

    #[test]
    fn paths_and_values_can_be_set() {
        let mut table = toml::Table::new();
        set_path(&mut table, "controller.kp", parse_value("1.0")).unwrap();
        set_path(&mut table, "observer.variant", parse_value("paper")).unwrap();
        let config = Config::from_table(table, "--set").unwrap();
        assert_eq!(config.controller.kp, 1.0);
        assert_eq!(config.observer.variant, Variant::Paper);
        let mut table = toml::Table::new();
        set_path(&mut table, "controller.gain", parse_value("1")).unwrap();
        assert!(Config::from_table(table, "--set").is_err());
    }
}
