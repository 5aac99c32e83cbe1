//! The network subcommands: robot agent, controller, relay, Khepera IV emulator.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use robokey::interrupt::Interrupt;
use robokey::protocol::auth::PairingSecret;
use robokey::protocol::{Pace, Timing};
use robokey::rng::{Purpose, stream};
use robokey_net::agent::controller::{ControllerOptions, run_controller};
use robokey_net::agent::report::{Ending, SessionReport};
use robokey_net::agent::robot::{RobotOptions, run_robot};
use robokey_net::frame_listing::list_frames;
use robokey_net::khepera::{EmulatorOptions, Kh4Backend, Link, Listen, TimeMode, serve};
use robokey_net::pairing::{read_pairing, write_pairing};
use robokey_net::pcap::read as read_capture;
use robokey_net::pose_stream::record as record_stream;
use robokey_net::random::os_rng;
use robokey_net::relay::{Faults, RelayOptions, run_relay};
use robokey_net::sensor::SensorSpec;
use robokey_net::sim_backend::SimBackend;
use robokey_net::world::{StreamAddresses, WorldProcess};

use crate::configuration::{ConfigOptions, WorldNoiseArgs, load_config};
use crate::exit::{Status, Usage, on_signals, usage};

/// Clock of a session.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum PaceArg {
    /// Period T on the wall clock (deployment).
    Realtime,
    /// Virtual clock with a per-step timeout (tests, demos).
    Lockstep,
}

/// Options shared by robot and controller.
#[derive(Args, Debug, Clone)]
pub struct SessionArgs {
    /// Configuration file (TOML); both sides must agree on T, code, Δ, budget, trajectory.
    #[arg(long, short)]
    config: Option<PathBuf>,
    #[command(flatten)]
    options: ConfigOptions,
    /// Write the key here (mode 0600), only once the peer's tag confirmed it.
    #[arg(long)]
    key_out: Option<PathBuf>,
    /// Pool this session's raw bits in the store DIR (created if missing; one per agent and
    /// pairing) and post-process full blocks with the peer into final keys, listed by
    /// `robokey keys list --store DIR` (docs/postprocessing.md). Needs a pairing.
    #[arg(long, value_name = "DIR")]
    store: Option<PathBuf>,
    /// Make final keys under a restricted assumption (`postprocess.assumed_eve_error` in
    /// odometry mode: an Eve who never learns the model); they are labelled restricted.
    #[arg(long, requires = "store")]
    allow_restricted: bool,
    /// Write the session report (JSON) here.
    #[arg(long)]
    report: Option<PathBuf>,
    /// Clock: realtime (period T) or lockstep (virtual clock).
    #[arg(long, value_enum, default_value = "realtime")]
    pace: PaceArg,
    /// Abort after this many seconds without a valid frame.
    #[arg(long, default_value_t = 2.0)]
    silence_timeout: f64,
    /// Lockstep: milliseconds to wait for each command before treating it as missing.
    #[arg(long, default_value_t = 50)]
    step_timeout_ms: u64,
    /// With --store: the block timeout (s). The robot waits this long, with a
    /// post-processing block in flight, for the controller's next post-processing frame,
    /// which may follow the controller's estimate of the plant for the block (seconds for a
    /// multilevel block of 10⁴ bits or one with slip); after it the robot leaves and the block
    /// ends without a key in the next session. The controller, while it computes, repeats its
    /// last post-processing frame every sixth of its own block timeout (5 s by default): give
    /// both agents the same value.
    #[arg(long, default_value_t = Timing::DEFAULT_BLOCK.as_secs_f64())]
    block_timeout: f64,
    /// The pairing file written by `robokey pair`, installed on the robot and the
    /// controller: every frame of the session is authenticated with it.
    #[arg(long, value_name = "FILE")]
    pairing: Option<PathBuf>,
    /// Use a pairing file that group or others may read or write, or that another user owns
    /// (refused by default, as ssh refuses such a private key; fix it with `chmod 600`).
    #[arg(long, requires = "pairing")]
    insecure_pairing_file: bool,
    /// Run without a pairing: anyone on the network can impersonate either side, inject
    /// commands and learn the key. Every output is labelled "passive adversary only".
    #[arg(long, conflicts_with = "pairing")]
    unauthenticated: bool,
}

impl SessionArgs {
    fn pairing(&self) -> Result<PairingSecret> {
        match (&self.pairing, self.unauthenticated) {
            (Some(path), _) => pairing_from(path, self.insecure_pairing_file),
            (None, true) => {
                eprintln!(
                    "warning: --unauthenticated: anyone on the network can impersonate either side, \
                     inject commands and take the key; every result holds against a passive \
                     adversary only"
                );
                Ok(PairingSecret::unauthenticated())
            }
            (None, false) => usage!(
                "no --pairing FILE: create one with `robokey pair --out DIR` and install it on the \
                 robot and the controller, or pass --unauthenticated (passive adversary only)"
            ),
        }
    }

    fn timing(&self) -> Result<Timing> {
        let silence = seconds("silence-timeout", self.silence_timeout, 0.001)?;
        if !(1..=MAX_SECONDS as u64 * 1000).contains(&self.step_timeout_ms) {
            usage!(
                "--step-timeout-ms {} is not allowed (allowed: 1 to {} ms)",
                self.step_timeout_ms,
                MAX_SECONDS as u64 * 1000
            );
        }
        let pace = match self.pace {
            PaceArg::Realtime => Pace::Realtime,
            PaceArg::Lockstep => Pace::Lockstep,
        };
        let mut timing = Timing::new(pace, silence);
        timing.step_timeout = Duration::from_millis(self.step_timeout_ms);
        // Each agent's own, not an agreement term: it sizes and labels no key, and agents that
        // state it differently cost at most the block in flight (a robot that waits less than
        // the controller's repeat leaves it), never a key either side would not have made.
        timing.block_timeout = seconds("block-timeout", self.block_timeout, 0.001)?;
        Ok(timing)
    }

    /// Prints and writes the report; the exit status follows how the session ended.
    fn finish(&self, report: &SessionReport, interrupt: &Interrupt) -> Result<Status> {
        println!("{}", report.line());
        if let Some(path) = &self.report {
            report.write(path)?;
        }
        Ok(match report.ending {
            Ending::Confirmed | Ending::Kept => Status::Success,
            Ending::InFlight => Status::InFlight,
            Ending::NoKey => Status::NoKey,
            Ending::AuthenticationFailed => Status::AuthenticationFailed,
            Ending::Interrupted => Status::Interrupted(interrupt.signal().unwrap_or(2)),
            Ending::Failed => bail!(
                "{} session failed: {}",
                report.role,
                report.reason.as_deref().unwrap_or("no reason recorded")
            ),
        })
    }
}

/// Reads the pairing file `path` (refused if others may access it, unless `insecure`),
/// printing any warning.
pub fn pairing_from(path: &std::path::Path, insecure: bool) -> Result<PairingSecret> {
    let (secret, warning) = read_pairing(path, insecure)?;
    if let Some(warning) = warning {
        eprintln!("{warning}");
    }
    Ok(secret)
}

#[derive(Args, Debug)]
pub struct PairArgs {
    /// Folder to write `pairing.key` into (created if missing; an existing pairing is
    /// never overwritten).
    #[arg(long)]
    out: PathBuf,
}

/// Writes a fresh pairing secret and prints its public fingerprint.
pub fn pair(args: PairArgs) -> Result<()> {
    let (path, secret) = write_pairing(&args.out, &mut os_rng()?)?;
    println!(
        "wrote {} (mode 0600), fingerprint {}\ninstall it on the robot and on the controller \
         (--pairing FILE); both print the fingerprint at start",
        path.display(),
        secret.fingerprint()
    );
    Ok(())
}

#[derive(Args, Debug)]
pub struct FramesArgs {
    /// A pcap or pcapng capture: from `robokey relay --capture`, tcpdump, dumpcap or
    /// Wireshark (raw IP, Ethernet, Linux cooked or BSD loopback framing).
    capture: PathBuf,
}

/// Prints every datagram of a capture as robokey parses it, one tab-separated line each:
/// number, type, session, seq, step, and the numbers a Measurement (`y`), a Command
/// (`u0D`, `u1D`) or a DoubletCommand (`y_c`, `u`, `u'`) carries. MACs are not checked (no pairing secret needed).
pub fn frames(args: FramesArgs) -> Result<()> {
    let capture = read_capture(&args.capture)?;
    crate::eve::warn_of_shortfalls(&args.capture, &capture.shortfalls);
    for frame in list_frames(&capture.datagrams) {
        let (Some(frame_type), Some(session), Some(seq), Some(step)) =
            (frame.frame_type, frame.session, frame.seq, frame.step)
        else {
            let error = frame.error.unwrap_or_default();
            println!("{}\tundecodable\t\t\t\t{error}", frame.index);
            continue;
        };
        let numbers: Vec<String> = frame.numbers.iter().map(|v| format!("{v:?}")).collect();
        println!(
            "{}\t{frame_type}\t{session}\t{seq}\t{step}\t{}",
            frame.index,
            numbers.join(",")
        );
    }
    Ok(())
}

/// Where the robot agent's wheels are.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum BackendArg {
    /// A simulated plant with the configured true noise.
    Sim,
    /// A Khepera IV through kh4server (or its emulator).
    Kh4,
    /// A ROS 2 differential-drive robot (/cmd_vel out, /odom in) on this computer, or
    /// `robokey ros2-sim`; needs a build with the `ros2` feature (docs/ros2.md).
    Ros2,
}

#[derive(Args, Debug)]
pub struct RobotArgs {
    /// UDP address to listen on, e.g. 0.0.0.0:7000 (port 0: any; the address is printed).
    #[arg(long, value_parser = socket_address)]
    listen: SocketAddr,
    /// Motors and odometry.
    #[arg(long, value_enum, default_value = "sim")]
    backend: BackendArg,
    /// kh4server link for `--backend kh4`: a serial device (e.g. /dev/rfcomm0) or tcp:HOST:PORT.
    #[arg(long)]
    kh4: Option<String>,
    /// TESTS ONLY: draw the key bits (and the simulated noise) from seeded streams instead
    /// of the OS CSPRNG; the session then equals `robokey run --seed S`.
    #[arg(long)]
    seed: Option<u64>,
    /// Seconds to wait for a controller.
    #[arg(long, default_value_t = 60.0)]
    wait: f64,
    #[command(flatten)]
    world: WorldArgs,
    #[command(flatten)]
    world_spec: crate::world::WorldSpecArgs,
    #[command(flatten)]
    session: SessionArgs,
    #[command(flatten)]
    ros2: crate::ros2::Ros2RobotArgs,
}

/// The world's sensor streams (private sensing): what the outside sees of the plant.
#[derive(Args, Debug, Clone)]
pub struct WorldArgs {
    /// Serve the controller's motion capture (the world's controller sensor: noise
    /// `world.controller_std`, else `sensing.controller_std`) on this TCP address (port 0:
    /// any; printed). Its link must be private: localhost or a cable.
    #[arg(long, value_name = "ADDR")]
    mocap: Option<SocketAddr>,
    /// Serve Eve's camera (the world's camera: at the instants with noise `eve.camera_std`,
    /// or frames between them at `world.camera_fps`, else at the stated `eve.camera_fps`) on
    /// this TCP address (port 0: any; printed); `robokey record` writes it to a camera log.
    #[arg(long, value_name = "ADDR")]
    camera: Option<SocketAddr>,
}

impl WorldArgs {
    /// The streams asked for.
    fn addresses(&self) -> StreamAddresses {
        StreamAddresses {
            mocap: self.mocap,
            camera: self.camera,
        }
    }
}

#[derive(Args, Debug)]
pub struct ControllerArgs {
    /// The robot agent's UDP address (HOST:PORT; a host name resolves to its first address).
    #[arg(long, value_parser = socket_address)]
    robot: SocketAddr,
    /// Private sensing (required there): the controller's own pose sensor, `mocap:ADDR`
    /// for the world's motion capture, or `ros2:TOPIC` for a geometry_msgs/PoseStamped topic
    /// read on localhost only (needs the `ros2` feature and --pace lockstep). Its link must
    /// be private: localhost or a cable, never the lab network (motion-capture systems and
    /// ROS 2 multicast there by default).
    #[arg(long, value_name = "SPEC")]
    sensor: Option<String>,
    /// Local address to bind.
    #[arg(long, value_parser = socket_address)]
    bind: Option<SocketAddr>,
    /// Threads of a block's estimate at block time (0: one per core; at most one per core),
    /// started with the session. The keys do not depend on it.
    #[arg(long, short, default_value_t = 0)]
    jobs: usize,
    #[command(flatten)]
    session: SessionArgs,
    #[command(flatten)]
    ros2: crate::ros2::Ros2SensorArgs,
}

#[derive(Args, Debug)]
pub struct RelayArgs {
    /// Address the controller sends to.
    #[arg(long, value_parser = socket_address)]
    listen: SocketAddr,
    /// The robot agent's address.
    #[arg(long, value_parser = socket_address)]
    forward: SocketAddr,
    /// Loss probability per datagram.
    #[arg(long, default_value_t = 0.0)]
    loss: f64,
    /// Duplication probability.
    #[arg(long, default_value_t = 0.0)]
    duplicate: f64,
    /// Reordering probability (the datagram is held back so later ones overtake it).
    #[arg(long, default_value_t = 0.0)]
    reorder: f64,
    /// One-way delay, `MS` or `MS±MS` (also `MS+-MS`).
    #[arg(long, default_value = "0")]
    delay: String,
    /// Probability of flipping one bit.
    #[arg(long, default_value_t = 0.0)]
    corrupt: f64,
    /// Seed of the fault streams.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Record every datagram to this pcap file (LINKTYPE_RAW: IPv4 or IPv6 and UDP headers
    /// with checksums, made up by the relay).
    #[arg(long)]
    capture: Option<PathBuf>,
    /// Record datagrams as delivered (after faults) instead of as sent.
    #[arg(long)]
    capture_after_faults: bool,
    /// Exit after this many seconds without traffic (default: run until killed).
    #[arg(long)]
    idle_exit: Option<f64>,
}

pub fn robot(args: RobotArgs) -> Result<Status> {
    let mut config = load_config(args.session.config.as_deref(), &args.session.options.set)?;
    let timing = args.session.timing()?;
    if args.kh4.is_some() && !matches!(args.backend, BackendArg::Kh4) {
        usage!("--kh4 is used only with --backend kh4 (the backend is sim)");
    }
    if args.world_spec.world.is_some() && !matches!(args.backend, BackendArg::Sim) {
        usage!(
            "--world is the simulated robot's (--backend sim): a real robot's world is the room \
             (with kh4-emulator or ros2-sim, pass --world to the emulator)"
        );
    }
    args.world_spec.apply(&mut config)?;
    if args.world.addresses().any() {
        if matches!(args.backend, BackendArg::Kh4) {
            usage!(
                "--mocap and --camera are served by the world: with --backend kh4 pass them to \
                 `robokey kh4-emulator` (a real robot's world is the room)"
            );
        }
        if config.sensing.mode != robokey::config::SensingMode::Private {
            usage!(
                "--mocap and --camera serve private sensing's streams (set \
                 sensing.mode=private): in odometry mode the controller reads the robot's \
                 measurements"
            );
        }
    }
    let options = RobotOptions {
        listen: args.listen,
        timing,
        wait_for_hello: seconds("wait", args.wait, 0.0)?,
        key_out: args.session.key_out.clone(),
        pairing: args.session.pairing()?,
        interrupt: on_signals()?,
        store: args.session.store.clone(),
        allow_restricted: args.session.allow_restricted,
    };
    match args.seed {
        Some(seed) => {
            eprintln!(
                "warning: --seed {seed}: the key bits come from a seeded stream, not the OS \
                 CSPRNG: anyone who knows the seed knows the key (tests only)"
            );
            config.run.seed = seed;
            finish_robot(&args, &config, &options, &mut stream(seed, Purpose::Key, 0))
        }
        None => {
            // The simulated plant's noise is not key material; it just differs per session.
            use rand::RngExt;
            config.run.seed = os_rng()?.random();
            finish_robot(&args, &config, &options, &mut os_rng()?)
        }
    }
}

fn finish_robot<R: rand::CryptoRng>(
    args: &RobotArgs,
    config: &robokey::Config,
    options: &RobotOptions,
    key_source: &mut R,
) -> Result<Status> {
    let report = match args.backend {
        BackendArg::Sim => {
            let world = WorldProcess::new(config, config.sensing.mode, &args.world.addresses())?;
            if let Some(streams) = world.describe() {
                println!("{streams}");
            }
            let mut backend = SimBackend::new(world, config.sensing.mode);
            run_robot(config, &mut backend, key_source, options)?
        }
        BackendArg::Kh4 => {
            let link = args
                .kh4
                .as_deref()
                .context("--backend kh4 needs --kh4 DEVICE or --kh4 tcp:HOST:PORT")?;
            let drive = robokey::model::DiffDrive {
                wheel_radius: config.robot.r,
                axle_length: config.robot.axle_length,
            };
            let mut backend = Kh4Backend::start(Link::open(link, Duration::from_secs(1))?, drive)?;
            run_robot(config, &mut backend, key_source, options)?
        }
        BackendArg::Ros2 => crate::ros2::run_robot(&args.ros2, config, options, key_source)?,
    };
    args.session.finish(&report, &options.interrupt)
}

pub fn controller(args: ControllerArgs) -> Result<Status> {
    let config = load_config(args.session.config.as_deref(), &args.session.options.set)?;
    let bind = args.bind.unwrap_or_else(|| {
        if args.robot.is_ipv4() {
            "0.0.0.0:0"
        } else {
            "[::]:0"
        }
        .parse()
        .expect("valid address")
    });
    let timing = args.session.timing()?;
    let sensor = match args.sensor.as_deref() {
        Some(text) => Some(match text.strip_prefix("ros2:") {
            Some(topic) => crate::ros2::sensor(topic, &args.ros2, &config, timing.pace)?,
            None => SensorSpec::parse(text)?,
        }),
        None => None,
    };
    let options = ControllerOptions {
        robot: args.robot,
        bind,
        timing,
        key_out: args.session.key_out.clone(),
        session: None,
        pairing: args.session.pairing()?,
        interrupt: on_signals()?,
        sensor,
        store: args.session.store.clone(),
        allow_restricted: args.session.allow_restricted,
        jobs: args.jobs,
    };
    let report = run_controller(&config, &options)?;
    args.session.finish(&report, &options.interrupt)
}

fn probability(name: &str, p: f64) -> Result<f64> {
    if (0.0..=1.0).contains(&p) {
        Ok(p)
    } else {
        usage!("--{name} {p} is not allowed (allowed: a probability in [0, 1])")
    }
}

/// Parses `MS`, `MS±MS` or `MS+-MS`.
fn parse_delay(text: &str) -> Result<(Duration, Duration)> {
    let (mean, jitter) = match text.split_once('±').or_else(|| text.split_once("+-")) {
        Some((m, j)) => (m, j),
        None => (text, "0"),
    };
    let ms = |s: &str| -> Result<Duration> {
        let v: f64 = s
            .trim()
            .parse()
            .with_context(|| format!("--delay {text}: `{s}` is not a number of milliseconds"))?;
        if !(0.0..=MAX_SECONDS * 1000.0).contains(&v) {
            usage!(
                "--delay {text}: {v} ms is not allowed (allowed: 0 to {} ms)",
                MAX_SECONDS * 1000.0
            );
        }
        Ok(Duration::from_secs_f64(v / 1000.0))
    };
    Ok((ms(mean)?, ms(jitter)?))
}

pub fn relay(args: RelayArgs) -> Result<Status> {
    let (delay, jitter) = parse_delay(&args.delay)?;
    let faults = Faults {
        loss: probability("loss", args.loss)?,
        duplicate: probability("duplicate", args.duplicate)?,
        reorder: probability("reorder", args.reorder)?,
        corrupt: probability("corrupt", args.corrupt)?,
        delay,
        jitter,
    };
    let options = RelayOptions {
        listen: args.listen,
        forward: args.forward,
        faults,
        seed: args.seed,
        capture: args.capture,
        capture_after_faults: args.capture_after_faults,
        idle_exit: args
            .idle_exit
            .map(|s| seconds("idle-exit", s, 0.0))
            .transpose()?,
        interrupt: on_signals()?,
    };
    let stats = run_relay(&options)?;
    println!("relay: {}", serde_json::to_string(&stats)?);
    Ok(match options.interrupt.signal() {
        Some(signal) => Status::Interrupted(signal),
        None => Status::Success,
    })
}

/// `HOST:PORT` or `IP:PORT` (IPv6 in brackets); a host name resolves to its first address.
fn socket_address(text: &str) -> Result<SocketAddr, String> {
    use std::net::ToSocketAddrs;
    let hint = "expected HOST:PORT, e.g. 127.0.0.1:7000, localhost:7000 or [::1]:7000";
    text.to_socket_addrs()
        .map_err(|e| format!("{e}; {hint}"))?
        .next()
        .ok_or_else(|| format!("`{text}` resolves to no address; {hint}"))
}

/// Longest duration any option takes (s): a day.
const MAX_SECONDS: f64 = 86_400.0;

/// A duration option in seconds, checked against `[least, MAX_SECONDS]`.
fn seconds(name: &str, value: f64, least: f64) -> Result<Duration> {
    if !(least..=MAX_SECONDS).contains(&value) {
        usage!("--{name} {value} is not allowed (allowed: {least} to {MAX_SECONDS} seconds)");
    }
    Ok(Duration::from_secs_f64(value))
}

/// How the emulated robot's time advances.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum TimeArg {
    /// Each encoder read advances one period T: a session runs in seconds.
    Virtual,
    /// The wheels turn with the wall clock.
    Real,
}

#[derive(Args, Debug)]
pub struct EmulatorArgs {
    /// `tcp:ADDR` (port 0: any), or `pty` (a new pseudo-terminal pair; the agent opens the
    /// device it prints, e.g. `--kh4 /dev/pts/3`). The address or device is printed.
    #[arg(long)]
    listen: String,
    /// Time mode.
    #[arg(long, value_enum, default_value = "virtual")]
    time: TimeArg,
    /// Virtual time advanced per encoder read (s).
    #[arg(long, default_value_t = 0.2)]
    period: f64,
    #[command(flatten)]
    noise: WorldNoiseArgs,
    #[command(flatten)]
    world: WorldArgs,
}

pub fn kh4_emulator(args: EmulatorArgs) -> Result<()> {
    let listen = match args.listen.strip_prefix("tcp:") {
        Some(address) => Listen::Tcp(address.parse().map_err(|_| {
            Usage(format!(
                "--listen {}: `{address}` is not an IP address and port (e.g. tcp:127.0.0.1:7200)",
                args.listen
            ))
        })?),
        None if args.listen == "pty" => Listen::Pty,
        None => usage!("--listen {}: expected tcp:ADDR or pty", args.listen),
    };
    if !(args.period > 0.0 && args.period.is_finite()) {
        usage!("--period {} is not allowed (allowed: > 0 s)", args.period);
    }
    let time = match args.time {
        TimeArg::Virtual => TimeMode::Virtual(Duration::from_secs_f64(args.period)),
        TimeArg::Real => TimeMode::Real,
    };
    serve(&EmulatorOptions {
        listen,
        time,
        world: args.noise.load()?,
        connections: None,
        sensors: args.world.addresses(),
    })?;
    Ok(())
}

#[derive(Args, Debug)]
pub struct RecordArgs {
    /// The pose stream's TCP address (e.g. the world's camera, `--camera` of the emulator
    /// or of a simulated robot).
    #[arg(long, value_name = "ADDR")]
    from: SocketAddr,
    /// The log file to create (CSV `step,x,y,theta`, or `time,x,y,theta` for a camera
    /// filming between the instants; an existing file is refused).
    #[arg(long)]
    out: PathBuf,
}

/// Records a pose stream to a log until the stream ends (or a signal).
pub fn record(args: RecordArgs) -> Result<Status> {
    let interrupt = on_signals()?;
    let samples = record_stream(args.from, &args.out, || interrupt.is_requested())?;
    println!(
        "recorded {samples} samples from {} to {}",
        args.from,
        args.out.display()
    );
    Ok(match interrupt.signal() {
        Some(signal) => Status::Interrupted(signal),
        None => Status::Success,
    })
}

#[cfg(test)]
mod tests {
    use clap::Parser;
    use std::time::Duration;

    /// The controller's `--block-timeout`: parsed into its timing (which its repeat while it
    /// computes is a sixth of), 30 s by default, refused out of range naming the option, the
    /// value and the range.
    #[test]
    fn the_controllers_block_timeout_is_parsed_and_bounded() {
        let timing = |extra: &[&str]| {
            let base = [
                "robokey",
                "controller",
                "--robot",
                "127.0.0.1:7000",
                "--unauthenticated",
            ];
            let cli = crate::Cli::try_parse_from([&base[..], extra].concat()).unwrap();
            let crate::Command::Controller(args) = cli.command else {
                panic!("not the controller: {:?}", cli.command)
            };
            args.session.timing()
        };
        assert_eq!(timing(&[]).unwrap().block_timeout, Duration::from_secs(30));
        assert_eq!(
            timing(&["--block-timeout", "12.5"]).unwrap().block_timeout,
            Duration::from_millis(12_500)
        );
        for bad in ["0", "-1", "86401", "NaN"] {
            let refused = timing(&["--block-timeout", bad]).unwrap_err();
            assert!(refused.is::<crate::exit::Usage>(), "{refused}");
            assert_eq!(
                refused.to_string(),
                format!("--block-timeout {bad} is not allowed (allowed: 0.001 to 86400 seconds)")
            );
        }
    }
}
