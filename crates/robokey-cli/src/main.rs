//! The `robokey` command: simulate runs, sweep parameters, report on them, reproduce the
//! paper.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use robokey_lab::run::Shard;

mod commands;
mod configuration;
mod demo;
mod eve;
mod exit;
mod keys;
mod kme;
mod logging;
mod net;
mod prior;
mod ros2;
mod threat;
mod world;
mod wrap;

use configuration::ConfigOptions;
use exit::Status;

/// mimalloc for every allocation of the process: the same results, less CPU spent in the
/// allocator (docs/speed.md).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// Key agreement for remotely controlled robots, through the robot's own motion
/// (Naseri, Lucia, Youssef, IFAC 2023) — simulated, swept, run over authenticated UDP
/// sessions, and counted: how many of the agreed bits are secret, against whom.
#[derive(Parser, Debug)]
#[command(
    name = "robokey",
    version = robokey_lab::VERSION,
    after_help = "Start with `robokey reproduce` (the paper's experiments) and `robokey demo` (a \
                  final key between two agents). The model, protocol, private sensing, secrecy \
                  accounting and threat model are explained in the repository's docs/.\n\n\
                  Exit codes: 0 success (a session: its key confirmed), 1 error, 2 wrong \
                  command line or input file, 3 a session ended without a key, 4 \
                  authentication failed, 5 pending (a block or final key left in flight for a \
                  later session to settle; keys get/delete: the key is pending), 130/143 stopped by SIGINT/SIGTERM after saving what \
                  was done (an interrupted sweep continues with `robokey sweep FILE --resume \
                  DIR`)."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Which diagnostic messages of robokey's libraries (RustDDS, ros2-client: discovery,
    /// matching, QoS) reach stderr: a level (off, error, warn, info, debug, trace) or
    /// TARGET=LEVEL pairs, e.g. `warn,rustdds=debug`. Default: $RUST_LOG, else off.
    #[arg(long, global = true, value_name = "FILTER")]
    log: Option<String>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Simulate one run: print its metrics, write metrics.json, trace.csv and a
    /// trajectory figure.
    #[command(allow_negative_numbers = true)]
    Run(RunArgs),
    /// Run a sweep (a config with a [sweep] table, or a suite of [experiment.NAME]);
    /// Ctrl-C keeps the finished runs, `--resume` continues.
    #[command(allow_negative_numbers = true)]
    Sweep(SweepArgs),
    /// Merge the folders of a sharded sweep, or of a sharded suite, into one.
    Merge(MergeArgs),
    /// Make the figures and report.md of a sweep folder or suite folder from its files alone
    /// (the paper's report for a folder of `robokey reproduce`).
    #[command(allow_negative_numbers = true)]
    Report(ReportArgs),
    /// Regenerate the paper's experiments, figures and report: `robokey sweep` of
    /// experiments/paper.toml, the stages its report renders (secrecy, eavesdropping
    /// campaigns, private sensing, the coarse worlds), then `robokey report`.
    #[command(allow_negative_numbers = true)]
    Reproduce(ReproduceArgs),
    /// Print the resolved configuration (defaults, file, overrides) as TOML, each field
    /// with its unit and meaning as a comment.
    #[command(allow_negative_numbers = true)]
    Config(ConfigArgs),
    /// Count the secret bits of a sweep folder: leakage estimates, reconciliation,
    /// confirmation and finite-key privacy amplification, per point and adversary
    /// (docs/secrecy.md, docs/postprocessing.md).
    #[command(allow_negative_numbers = true)]
    Secrecy(SecrecyArgs),
    /// What a camera of Eve's leaves of the key at a configuration (private sensing): for a
    /// camera per instant (--camera-std) or in frames (--fps, --frame-std), or lists and
    /// ranges of them, its per-instant equivalent and the secret rate of a key sized against
    /// it from the configured physics, as `robokey secrecy` sizes by default (bits per step
    /// and per second; the agents under private sensing size from the measured plant by
    /// default); then the break-even camera, where that rate reaches zero
    /// (docs/threat-model.md). Default camera: the configuration's statement.
    Threat(threat::ThreatArgs),
    /// The prior a calibration run measured: the parties' configuration with what the last
    /// block estimate in the controller's session reports names — the motion noise √Q̂
    /// (`noise.process_std`) and an actuator lag (`private.prior_lag`) — to state on both
    /// agents for the blocks to come, each change and its measurement as comments
    /// (docs/estimation.md, "Causality").
    Prior(prior::PriorArgs),
    /// Write a pairing secret (`DIR/pairing.key`) to install on a robot and its controller.
    Pair(net::PairArgs),
    /// The robot agent: owns the clock and the key bits, drives the wheels, reports odometry
    /// over UDP. Run it ON the robot (see README: where the robot agent runs matters).
    #[command(allow_negative_numbers = true)]
    Robot(net::RobotArgs),
    /// The controller: tracks the reference, offers command pairs, decodes and acks.
    #[command(allow_negative_numbers = true)]
    Controller(net::ControllerArgs),
    /// A faulty network between controller and robot, with an optional pcap capture.
    #[command(allow_negative_numbers = true)]
    Relay(net::RelayArgs),
    /// Print the robokey frames of a pcap capture as robokey parses them (MACs unchecked).
    Frames(net::FramesArgs),
    /// Eavesdroppers of every strategy on simulated sessions (what they learn carries over)
    /// or on a relay capture: error rates, parameter convergence, time to match the
    /// controller, disagreement with the controller's key.
    #[command(allow_negative_numbers = true)]
    Eve(eve::EveArgs),
    /// A simulated Khepera IV speaking kh4server's line protocol, for the kh4 backend; with
    /// --mocap and --camera also the world's sensor streams.
    #[command(allow_negative_numbers = true, name = "kh4-emulator")]
    Kh4Emulator(net::EmulatorArgs),
    /// Record a pose stream of the world (Eve's camera) to a CSV log, until it ends.
    Record(net::RecordArgs),
    /// An emulated ROS 2 differential-drive robot (TurtleBot3-like: /cmd_vel in, /odom out,
    /// localhost only) for `robot --backend ros2`; needs the `ros2` feature (docs/ros2.md).
    #[command(name = "ros2-sim")]
    Ros2Sim(ros2::SimArgs),
    /// The final keys of an agent's store (--store): list, take a key for an application
    /// (each once; the robot's store by the ID the controller's gave), get a whole final key
    /// to compare the stores, delete. Both agents' stores list the same IDs (docs/keys.md).
    #[command(subcommand_required = true)]
    Keys(keys::KeysArgs),
    /// An ETSI GS QKD 014 key-delivery server (HTTPS, mutual TLS) on an agent's store: the
    /// controller's store gives new keys (enc_keys), the robot's the same keys by ID
    /// (dec_keys), each once (docs/keys.md).
    Kme(kme::KmeArgs),
    /// A final key in one command: paired agents on 127.0.0.1 (simulated robot and world,
    /// the relay with faults, stores), session after session until both stores hold the same
    /// final key; shows its ID and length on both sides and checks the bits are equal.
    #[command(allow_negative_numbers = true)]
    Demo(demo::DemoArgs),
}

#[derive(Args, Debug)]
struct RunArgs {
    /// Configuration file (TOML); defaults apply to every field it leaves out.
    #[arg(long, short)]
    config: Option<PathBuf>,
    /// Δv (m/s): `protocol.delta_v`.
    #[arg(long)]
    delta_v: Option<f64>,
    /// Δω (rad/s): `protocol.delta_omega`.
    #[arg(long)]
    delta_omega: Option<f64>,
    /// Master seed: `run.seed`.
    #[arg(long)]
    seed: Option<u64>,
    /// Which replicate's random streams to use.
    #[arg(long, default_value_t = 0)]
    replicate: u32,
    /// Eve's model error α (fraction): `eve.alpha`.
    #[arg(long)]
    alpha: Option<f64>,
    /// Run without an eavesdropper.
    #[arg(long)]
    no_eve: bool,
    /// Protocol off: the robot applies the nominal command (J_x baseline).
    #[arg(long)]
    protocol_off: bool,
    #[command(flatten)]
    options: ConfigOptions,
    /// Output folder (refused when not empty, unless --force).
    #[arg(long, short, default_value = "robokey-out/run")]
    out: PathBuf,
    /// Write into a non-empty output folder of robokey's: its files are removed first,
    /// files robokey does not write are kept (and named).
    #[arg(long)]
    force: bool,
    /// The trace's format: trace.csv, or trace.parquet (each column's unit and meaning in
    /// its metadata; docs/python.md).
    #[arg(long, value_enum, default_value_t = FormatArg::Csv)]
    format: FormatArg,
}

#[derive(Args, Debug)]
struct SweepArgs {
    /// Sweep file: config fields plus [sweep] axes, or [experiment.NAME] tables.
    config: PathBuf,
    #[command(flatten)]
    options: ConfigOptions,
    /// Output folder (a suite writes one subfolder per experiment).
    #[arg(long, short, default_value = "robokey-out/sweep")]
    out: PathBuf,
    /// Worker threads (0: one per core; at most one per core). Results do not depend on it.
    #[arg(long, short, default_value_t = 0)]
    jobs: usize,
    /// Run only shard m of n (1-based, round-robin over runs); merge with `robokey merge`.
    #[arg(long, value_name = "M/N")]
    shard: Option<Shard>,
    /// Write into a non-empty output folder of robokey's: its files are removed first,
    /// files robokey does not write are kept (and named).
    #[arg(long, conflicts_with = "resume")]
    force: bool,
    /// Continue the interrupted sweep in DIR (instead of --out): run only the runs it does not
    /// hold yet. Give the same sweep file and --set options (checked); the shard is the
    /// folder's. It ends byte-identical to a sweep that was never interrupted.
    #[arg(long, value_name = "DIR", conflicts_with = "out")]
    resume: Option<PathBuf>,
    /// The runs table's and traces' format: runs.csv, or runs.parquet (each column's unit
    /// and meaning in its metadata). A folder is written in Parquet once it holds every run
    /// (an interrupted one stays CSV, to be resumed with the same --format); report, merge
    /// and --resume do not read runs.parquet.
    #[arg(long, value_enum, default_value_t = FormatArg::Csv)]
    format: FormatArg,
}

#[derive(Args, Debug)]
struct MergeArgs {
    /// Shard folders of one sweep (or of one experiment of a suite), or of a suite: then
    /// each experiment's subfolders are merged.
    #[arg(required = true)]
    dirs: Vec<PathBuf>,
    /// Output folder.
    #[arg(long, short)]
    out: PathBuf,
    /// Write into a non-empty output folder of robokey's: its files are removed first,
    /// files robokey does not write are kept (and named).
    #[arg(long)]
    force: bool,
    /// The merged runs table's and traces' format: runs.csv, or runs.parquet (as `sweep
    /// --format parquet` writes them).
    #[arg(long, value_enum, default_value_t = FormatArg::Csv)]
    format: FormatArg,
}

#[derive(Args, Debug)]
struct ReportArgs {
    /// A complete sweep folder (with config.resolved.toml), a suite folder of them, or a
    /// merge of shards; the paper's report needs the stages `robokey reproduce` computes.
    #[arg(value_name = "SWEEP_DIR")]
    dir: PathBuf,
    /// Worker threads (0: one per core; at most one per core). Results do not depend on it.
    #[arg(long, short, default_value_t = 0)]
    jobs: usize,
}

#[derive(Args, Debug)]
struct ReproduceArgs {
    /// Output folder.
    #[arg(long, short, default_value = "robokey-out/reproduce")]
    out: PathBuf,
    /// Worker threads (0: one per core; at most one per core). Results do not depend on it.
    #[arg(long, short, default_value_t = 0)]
    jobs: usize,
    /// 3 replicates per point instead of 10, 5 eavesdropping campaigns instead of 20,
    /// 2,000-bit secrecy blocks instead of 10,000, and a smaller private-sensing map.
    #[arg(long)]
    quick: bool,
    /// Write into a non-empty output folder of robokey's: its files are removed first,
    /// files robokey does not write are kept (and named).
    #[arg(long, conflicts_with = "resume")]
    force: bool,
    /// Continue the reproduction in DIR (instead of --out; with the same --quick): sweep only
    /// the missing runs, compute the report's stages, then write the report. Also completes
    /// a merge of shards of experiments/paper.toml swept as reproduce sweeps it.
    #[arg(long, value_name = "DIR", conflicts_with = "out")]
    resume: Option<PathBuf>,
}

#[derive(Args, Debug)]
struct SecrecyArgs {
    /// A sweep folder (with config.resolved.toml), or a suite folder of them.
    #[arg(value_name = "SWEEP_DIR")]
    sweep_dir: PathBuf,
    /// Adversaries to evaluate (repeatable); reports list the strongest class first.
    /// Default: oracle, identify, mismatch in odometry mode; camera, commands in private
    /// sensing (docs/private-sensing.md).
    #[arg(long = "adversary", value_enum)]
    adversaries: Vec<StrategyArg>,
    /// ε per term (smoothing, amplification, parameter estimation, and with `--sizing
    /// measured` the motion-noise region); the key is 4ε-secret (5ε with `--sizing measured`).
    /// Default: the sweep file's `[secrecy] epsilon`, else 1e-6.
    #[arg(long)]
    eps: Option<f64>,
    /// Least pooled raw bits per privacy-amplification block (whole sessions are pooled).
    /// Default: the sweep file's `[secrecy] block_bits`, else 10000.
    #[arg(long)]
    block: Option<u64>,
    /// Blocks to fill per point (more sessions are simulated as needed).
    #[arg(long, default_value_t = 1)]
    blocks: usize,
    /// Which sessions are pooled: `confirmed` (today's agents: sessions whose key tags
    /// matched, their tags charged) or `complete` (the authenticated session's pipeline:
    /// every completed session, sampled error estimate, Cascade, one block confirmation).
    /// Default: confirmed in odometry mode, complete in private sensing (the only one there).
    #[arg(long, value_enum)]
    pooling: Option<PoolingArg>,
    /// Largest sample disclosed to estimate the error rate with `--pooling complete` (at
    /// most a tenth of the block).
    #[arg(long, default_value_t = 1_000)]
    sample_bits: usize,
    /// Most sessions simulated per point and adversary. Default: 2,000 per 10,000 bits the
    /// blocks need (--blocks × --block), so that a large block is filled, at most 1000000.
    #[arg(long)]
    max_sessions: Option<u32>,
    /// State what the key is sized against: Eve's guesses err independently with at least
    /// this probability, in (0, 0.5] (a restricted assumption in odometry mode). Without
    /// it the key length is zero by structure; the realised view of each adversary is
    /// reported beside it either way.
    #[arg(long, value_name = "P")]
    assume_eve_error: Option<f64>,
    /// Private sensing: what sizes the key. `configured`: Eve's view from the configured
    /// `noise.process_std` (the paper's; reproduce uses it). `measured`: from the motion
    /// noise the controller estimates per block from its own samples and the reconciled
    /// bits, at the worst case of the estimate's (1 − ε_est) region, ε_est = --eps a term of
    /// the key's ε (the key is then 5ε-secret); a block outside the model class is refused,
    /// naming the test (docs/estimation.md); with `protocol.levels` 4 or 8 each slice is sized
    /// from its own bits under the block's one estimate. `world`: as `measured`, at the simulated world's
    /// own motion noise and correlation instead of an estimate — a pair configured with the
    /// true world, the comparison for `measured`. Default: the sweep file's `[secrecy]
    /// sizing`, else configured — the lab's comparison and `reproduce`'s figures; the agents'
    /// `postprocess.sizing` has its own default, following `sensing.mode` (measured under
    /// private sensing).
    #[arg(long, value_enum)]
    sizing: Option<SizingArg>,
    /// How `complete` pooling reconciles (docs/postprocessing.md). `cascade`: interactive
    /// Cascade with BICONF on the controller's decisions, both sides' parities charged
    /// (reproduce uses it). `ldpc`: the robot's one-way LDPC syndrome decoded by belief
    /// propagation on the controller's calibrated LLRs (m = ⌈1.09·H + 2·√H⌉ for the soft
    /// limit H, ≤ 8 feedback rounds of max(0.04·m, 2·√m)), every syndrome bit and 4 bits for
    /// the rounds charged; private sensing only. The agents' `postprocess.reconciliation`.
    /// Default: the sweep file's `[secrecy] reconciliation`, else cascade.
    #[arg(long, value_enum)]
    reconciliation: Option<ReconciliationArg>,
    /// With LDPC, which model the controller's LLRs are computed with (docs/estimation.md,
    /// "Causality"). `prior`: online, with the configured motion noise. `measured`: at
    /// block time from the kept samples, with the motion noise estimated from the disclosed
    /// sample's doublets. `world`: with the simulated world's own motion noise (an oracle
    /// bound, simulator only). Default: each point's `postprocess.llrs`, else following the
    /// sizing — `measured` under `--sizing measured` or `world` with LDPC, `prior` under
    /// `--sizing configured`. Cascade
    /// reads no LLRs: `measured` and `world` are refused where it reconciles
    /// (`--reconciliation cascade`, the sweep file's, or the default).
    #[arg(long, value_enum)]
    llrs: Option<LlrsArg>,
    /// Worker threads (0: one per core; at most one per core). Results do not depend on it.
    #[arg(long, short, default_value_t = 0)]
    jobs: usize,
    /// The secrecy table's format: secrecy.csv, or secrecy.parquet (each column's unit and
    /// meaning in its metadata).
    #[arg(long, value_enum, default_value_t = FormatArg::Csv)]
    format: FormatArg,
}

/// The format of the tables a command writes.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum FormatArg {
    /// Comma-separated text.
    Csv,
    /// Apache Parquet, each column's unit and meaning in its field's metadata.
    Parquet,
}

impl From<FormatArg> for robokey_lab::parquet_table::TableFormat {
    fn from(format: FormatArg) -> Self {
        match format {
            FormatArg::Csv => Self::Csv,
            FormatArg::Parquet => Self::Parquet,
        }
    }
}

/// How `robokey secrecy` reconciles (docs/postprocessing.md).
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum ReconciliationArg {
    /// Interactive Cascade on the controller's decisions.
    Cascade,
    /// One-way LDPC syndromes decoded on the controller's LLRs (private sensing).
    Ldpc,
}

impl From<ReconciliationArg> for robokey_lab::secrecy::Reconciliation {
    fn from(r: ReconciliationArg) -> Self {
        match r {
            ReconciliationArg::Cascade => Self::Cascade,
            ReconciliationArg::Ldpc => Self::Ldpc,
        }
    }
}

/// What sizes private sensing's key in `robokey secrecy` (docs/estimation.md).
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum SizingArg {
    /// The configured motion noise.
    Configured,
    /// The motion noise the controller measures per block, at its region's worst case.
    Measured,
    /// The simulated world's own motion noise and correlation (a pair configured with the
    /// true world).
    World,
}

impl From<SizingArg> for robokey_lab::secrecy::Sizing {
    fn from(s: SizingArg) -> Self {
        match s {
            SizingArg::Configured => Self::Configured,
            SizingArg::Measured => Self::Measured,
            SizingArg::World => Self::World,
        }
    }
}

/// Which model the controller's LLRs are computed with in `robokey secrecy`
/// (docs/estimation.md, "Causality").
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum LlrsArg {
    /// The configured motion noise, online.
    Prior,
    /// The motion noise estimated at block time from the disclosed sample.
    Measured,
    /// The simulated world's own motion noise (an oracle bound).
    World,
}

impl From<LlrsArg> for robokey_lab::secrecy::LlrModel {
    fn from(l: LlrsArg) -> Self {
        match l {
            LlrsArg::Prior => Self::Prior,
            LlrsArg::Measured => Self::Measured,
            LlrsArg::World => Self::World,
        }
    }
}

/// Which sessions `robokey secrecy` pools (docs/secrecy.md).
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum PoolingArg {
    /// Sessions whose key tags matched (today's agents); their tags are charged.
    Confirmed,
    /// Every completed session, through the agents' post-processing endpoints: sampled
    /// error estimate, Cascade, one block confirmation, two-phase commit.
    Complete,
}

impl From<PoolingArg> for robokey_lab::secrecy::Pooling {
    fn from(p: PoolingArg) -> Self {
        match p {
            PoolingArg::Confirmed => Self::Confirmed,
            PoolingArg::Complete => Self::Complete,
        }
    }
}

/// Eavesdropper strategies (docs/threat-model.md); each after `mismatch` adds to the one before.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum StrategyArg {
    /// Exact model: decides as the controller does.
    Oracle,
    /// The paper's Eve: model errors up to eve.alpha, hard decisions.
    Mismatch,
    /// mismatch + maximum-likelihood codeword decisions from d̂ and Pᵈ.
    Soft,
    /// soft + starts eve.initial_error off on r and D and identifies them online.
    Identify,
    /// identify + tests her least reliable bits against the confirmation tag, learns from the
    /// recovered key.
    Transcript,
    /// Private sensing, the strongest: exact model, her own camera (eve.camera_std), the
    /// controller's boundary samples the commands reveal.
    Camera,
    /// Private sensing: camera without the camera (what the public commands leak).
    Commands,
}

impl From<StrategyArg> for robokey::config::EveStrategy {
    fn from(arg: StrategyArg) -> Self {
        match arg {
            StrategyArg::Oracle => Self::Oracle,
            StrategyArg::Mismatch => Self::Mismatch,
            StrategyArg::Soft => Self::Soft,
            StrategyArg::Identify => Self::Identify,
            StrategyArg::Transcript => Self::Transcript,
            StrategyArg::Camera => Self::Camera,
            StrategyArg::Commands => Self::Commands,
        }
    }
}

#[derive(Args, Debug)]
struct ConfigArgs {
    /// Configuration file (TOML).
    #[arg(long, short)]
    config: Option<PathBuf>,
    #[command(flatten)]
    options: ConfigOptions,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // The commands that talk over sockets keep SIGPIPE ignored (a closed socket is an error
    // they handle); every other one only writes files and the terminal.
    if !matches!(
        cli.command,
        Command::Robot(_)
            | Command::Controller(_)
            | Command::Relay(_)
            | Command::Kh4Emulator(_)
            | Command::Record(_)
            | Command::Ros2Sim(_)
    ) {
        exit::end_on_broken_pipe();
    }
    if let Err(error) = logging::install(cli.log.as_deref()) {
        return exit::code(Err(error));
    }
    let done = |result: anyhow::Result<()>| result.map(|()| Status::Success);
    let result = match cli.command {
        Command::Run(args) => done(commands::run(args)),
        Command::Sweep(args) => commands::sweep(args),
        Command::Merge(args) => done(commands::merge(args)),
        Command::Report(args) => done(commands::report(args)),
        Command::Reproduce(args) => commands::reproduce(args),
        Command::Config(args) => done(commands::config(args)),
        Command::Secrecy(args) => done(commands::secrecy(args)),
        Command::Threat(args) => done(threat::run(&args)),
        Command::Prior(args) => done(prior::run(&args)),
        Command::Pair(args) => done(net::pair(args)),
        Command::Robot(args) => net::robot(args),
        Command::Controller(args) => net::controller(args),
        Command::Relay(args) => net::relay(args),
        Command::Frames(args) => done(net::frames(args)),
        Command::Eve(args) => done(eve::eve(args)),
        Command::Kh4Emulator(args) => done(net::kh4_emulator(args)),
        Command::Record(args) => net::record(args),
        Command::Ros2Sim(args) => ros2::ros2_sim(args),
        Command::Keys(args) => done(keys::keys(args)),
        Command::Kme(args) => kme::kme(args),
        Command::Demo(args) => demo::demo(args),
    };
    exit::code(result)
}
