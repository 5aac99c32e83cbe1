//! `robokey demo`: a final key in one command. It runs this binary's own `pair`, `robot`
//! (the simulated plant, which is also the world and serves the controller's motion
//! capture), `relay` (the README's fault mix) and `controller` processes on loopback,
//! session after session, both agents pooling into their stores, until both stores hold the
//! same settled final key — then shows its ID, length and assumption on both sides and
//! checks that the bits are equal, without showing them. Bounded in sessions and time.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use robokey::config::SensingMode;
use robokey::config::source::Override;
use robokey::interrupt::Interrupt;

use crate::configuration::load_config;
use crate::exit::{Status, on_signals, usage};

/// The relay's faults: the README's mix (10 % loss, 5 % duplicates, 5 % reordered, 1 %
/// corrupted, 1 ± 1 ms of delay).
const FAULTS: [&str; 10] = [
    "--loss",
    "0.1",
    "--duplicate",
    "0.05",
    "--reorder",
    "0.05",
    "--corrupt",
    "0.01",
    "--delay",
    "1±1",
];
/// Milliseconds an agent waits for each lockstep step (a lost frame costs this much).
const STEP_TIMEOUT_MS: &str = "20";
/// Seconds without a valid frame after which an agent ends its session.
const SILENCE_TIMEOUT_S: &str = "2";
/// How long a process may take to print the address it listens on.
const START_TIMEOUT: Duration = Duration::from_secs(10);
/// How often the demo looks at its processes and its stop request.
const POLL: Duration = Duration::from_millis(10);

/// What the agents decide from.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum DemoMode {
    /// Private sensing: the controller reads its own motion capture; keys are sized against
    /// Eve's camera (docs/private-sensing.md).
    Private,
    /// The paper's odometry mode: every block ends without a key, and the demo says why.
    Odometry,
}

#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Output folder (created; refused when not empty): the pairing, both stores, and per
    /// session the agents' reports and output.
    #[arg(long, short, default_value = "robokey-out/demo")]
    out: PathBuf,
    /// What the agents decide from.
    #[arg(long, value_enum, default_value = "private")]
    mode: DemoMode,
    /// Most sessions to run.
    #[arg(long, default_value_t = 60)]
    max_sessions: u32,
    /// Most seconds to run (a session that is running then is stopped).
    #[arg(long, default_value_t = 900.0)]
    timeout: f64,
    /// Configuration file (TOML) of both agents.
    #[arg(long, short)]
    config: Option<PathBuf>,
    /// Set any config field of both agents, e.g. `--set postprocess.block_bits=2000`
    /// (repeatable).
    #[arg(long = "set", value_name = "FIELD=VALUE")]
    set: Vec<String>,
}

/// A key as `robokey keys list --json` lists it.
#[derive(Debug, serde::Deserialize)]
struct Listed {
    id: String,
    bits: u64,
    epsilon: f64,
    label: String,
    status: String,
    assumption: String,
    sessions: Vec<u32>,
}

/// The processes of one session. If the demo ends before they do, they get [`GRACE`] to
/// end on their own (a Ctrl-C in the terminal reaches them too: they stop their session and
/// write their reports), then are killed; the stores are crash-safe either way.
struct Running(Vec<Child>);

/// How long processes left running get to end before they are killed.
const GRACE: Duration = Duration::from_secs(1);

impl Running {
    fn any_running(&mut self) -> bool {
        self.0
            .iter_mut()
            .any(|c| c.try_wait().ok().flatten().is_none())
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        let until = Instant::now() + GRACE;
        while self.any_running() && Instant::now() < until {
            std::thread::sleep(POLL);
        }
        for child in &mut self.0 {
            if child.try_wait().ok().flatten().is_none() {
                let _ = child.kill();
                let _ = child.wait();
            }
        }
    }
}

/// The demo's folder, binary, options and bounds.
struct Demo {
    binary: PathBuf,
    out: PathBuf,
    pairing: String,
    /// `--config FILE` and `--set …` for both agents, the mode last.
    settings: Vec<String>,
    mode: SensingMode,
    block_bits: u32,
    deadline: Instant,
    interrupt: Interrupt,
}

pub fn demo(args: DemoArgs) -> Result<Status> {
    let mode = match args.mode {
        DemoMode::Private => SensingMode::Private,
        DemoMode::Odometry => SensingMode::Odometry,
    };
    let mut set = args.set.clone();
    set.push(format!("sensing.mode={}", mode.name()));
    // The agents would refuse a configuration that does not load: say so before any start.
    let overrides = set
        .iter()
        .map(|text| Override::from_set(text).map_err(crate::exit::Usage))
        .collect::<Result<Vec<_>, _>>()?;
    let config = load_config(args.config.as_deref(), &overrides)?;
    let mut settings: Vec<String> = Vec::new();
    if let Some(config) = &args.config {
        settings.extend(["--config".into(), config.display().to_string()]);
    }
    for text in set {
        settings.extend(["--set".into(), text]);
    }
    if !(args.timeout > 0.0 && args.timeout <= 86_400.0) {
        usage!(
            "--timeout {} is not allowed (allowed: > 0 and ≤ 86400 s)",
            args.timeout
        );
    }
    if args.max_sessions == 0 {
        usage!("--max-sessions 0 is not allowed (allowed: ≥ 1)");
    }
    if args
        .out
        .read_dir()
        .is_ok_and(|mut entries| entries.next().is_some())
    {
        usage!(
            "{} is not empty: remove it, or give another folder with --out",
            args.out.display()
        );
    }
    std::fs::create_dir_all(&args.out).with_context(|| format!("create {}", args.out.display()))?;
    let demo = Demo {
        binary: std::env::current_exe().context("find the robokey binary")?,
        pairing: args.out.join("pairing.key").display().to_string(),
        out: args.out.clone(),
        settings,
        mode,
        block_bits: config.postprocess.block_bits,
        deadline: Instant::now() + Duration::from_secs_f64(args.timeout),
        interrupt: on_signals()?,
    };
    demo.run(args.max_sessions)
}

impl Demo {
    fn run(&self, max_sessions: u32) -> Result<Status> {
        let started = Instant::now();
        self.robokey(&["pair", "--out", &self.out.display().to_string()])?;
        println!(
            "demo: {} sensing, paired agents on 127.0.0.1 through a relay that loses 10 %, \
             duplicates 5 %, reorders 5 % and corrupts 1 % of the datagrams; a block is {} \
             pooled raw bits (postprocess.block_bits) → {}",
            self.mode.name(),
            self.block_bits,
            self.out.display()
        );
        for session in 1..=max_sessions {
            let Some(controller) = self.session(session)? else {
                return Ok(self.stopped(session));
            };
            let post = &controller["post"];
            println!(
                "session {session}: {} raw bits pooled; the pool holds {} of the {} bits a \
                 block needs ({:.0} s)",
                post["session_bits"],
                post["pool_bits"],
                self.block_bits,
                started.elapsed().as_secs_f64()
            );
            for block in post["blocks"].as_array().into_iter().flatten() {
                match block["reason"].as_str() {
                    Some(reason) if block["length"] == 0 => {
                        println!("block {}: no key: {reason}", block["block"]);
                    }
                    _ => println!(
                        "block {}: {} raw bits of {} sessions → a final key of {} bits",
                        block["block"], block["bits"], block["sessions"], block["length"]
                    ),
                }
            }
            if let Some(key) = self.settled_on_both_sides()? {
                self.show(&key, session, started)?;
                return Ok(Status::Success);
            }
            if self.mode == SensingMode::Odometry
                && !post["blocks"].as_array().is_none_or(Vec::is_empty)
            {
                println!(
                    "demo: no final key, by structure: in odometry mode Eve learns the model from \
                     the traffic and decides as the controller does (`robokey demo` without \
                     --mode makes keys by private sensing)"
                );
                return Ok(Status::NoKey);
            }
        }
        println!(
            "demo: no final key within {max_sessions} sessions (--max-sessions): a block needs \
             {} pooled raw bits",
            self.block_bits
        );
        Ok(Status::NoKey)
    }

    /// What the demo says and returns when a bound or a signal ended it before `session`
    /// finished.
    fn stopped(&self, session: u32) -> Status {
        match self.interrupt.signal() {
            Some(signal) => {
                println!("demo: stopped by signal {signal} during session {session}");
                Status::Interrupted(signal)
            }
            None => {
                println!(
                    "demo: no final key within the time allowed (--timeout); session {session} \
                     was stopped"
                );
                Status::NoKey
            }
        }
    }

    /// Runs `robokey args…` to its end; its stdout.
    fn robokey(&self, args: &[&str]) -> Result<String> {
        let out = Command::new(&self.binary)
            .args(args)
            .output()
            .with_context(|| format!("run robokey {}", args.join(" ")))?;
        if !out.status.success() {
            bail!(
                "robokey {} failed ({}): {}",
                args.join(" "),
                out.status,
                String::from_utf8_lossy(&out.stderr).trim_end()
            );
        }
        Ok(String::from_utf8_lossy(&out.stdout).into_owned())
    }

    /// Starts `robokey args…` with its output to `log`.
    fn start(&self, args: &[String], log: &Path) -> Result<Child> {
        let file =
            std::fs::File::create(log).with_context(|| format!("create {}", log.display()))?;
        Command::new(&self.binary)
            .args(args)
            .stdin(Stdio::null())
            .stdout(file.try_clone()?)
            .stderr(file)
            .spawn()
            .with_context(|| format!("start robokey {}", args.join(" ")))
    }

    /// Waits until `log` has a line holding `marker`; the address after it.
    fn address(&self, log: &Path, marker: &str, running: &mut Running) -> Result<Option<String>> {
        let until = Instant::now() + START_TIMEOUT;
        loop {
            let text = std::fs::read_to_string(log).unwrap_or_default();
            if let Some(rest) = text.split(marker).nth(1)
                && let Some(address) = rest.split([',', '\n', ' ']).next()
                && rest.contains('\n')
            {
                return Ok(Some(address.to_owned()));
            }
            if self.should_stop() {
                return Ok(None);
            }
            let ended = running
                .0
                .iter_mut()
                .any(|c| c.try_wait().ok().flatten().is_some());
            if Instant::now() >= until || ended {
                bail!(
                    "no `{marker}…` from the process whose output is {}: {text}",
                    log.display()
                );
            }
            std::thread::sleep(POLL);
        }
    }

    fn should_stop(&self) -> bool {
        self.interrupt.is_requested() || Instant::now() >= self.deadline
    }

    /// One session in `out/session-NNN`; the controller's report, or `None` when the demo
    /// was stopped during it.
    fn session(&self, session: u32) -> Result<Option<serde_json::Value>> {
        let dir = self.out.join(format!("session-{session:03}"));
        std::fs::create_dir_all(&dir).with_context(|| format!("create {}", dir.display()))?;
        let file = |name: &str| dir.join(name).display().to_string();
        let store = |role: &str| self.out.join(role).display().to_string();
        let common: Vec<String> = [
            "--pace",
            "lockstep",
            "--pairing",
            &self.pairing,
            "--step-timeout-ms",
            STEP_TIMEOUT_MS,
            "--silence-timeout",
            SILENCE_TIMEOUT_S,
        ]
        .iter()
        .map(|s| (*s).to_owned())
        .chain(self.settings.iter().cloned())
        .collect();
        let mut running = Running(Vec::new());
        let mut robot: Vec<String> = ["robot", "--listen", "127.0.0.1:0", "--backend", "sim"]
            .map(String::from)
            .to_vec();
        robot.extend([
            "--store".into(),
            store("robot"),
            "--report".into(),
            file("robot.json"),
        ]);
        if self.mode == SensingMode::Private {
            robot.extend(["--mocap".into(), "127.0.0.1:0".into()]);
        }
        robot.extend(common.iter().cloned());
        let robot_log = dir.join("robot.out");
        running.0.push(self.start(&robot, &robot_log)?);
        let Some(robot_address) = self.address(&robot_log, "listening on ", &mut running)? else {
            return Ok(None);
        };
        let mocap = match self.mode {
            SensingMode::Private => {
                match self.address(&robot_log, "motion capture on ", &mut running)? {
                    Some(address) => Some(address),
                    None => return Ok(None),
                }
            }
            SensingMode::Odometry => None,
        };
        let mut relay: Vec<String> = [
            "relay",
            "--listen",
            "127.0.0.1:0",
            "--forward",
            &robot_address,
            "--idle-exit",
            "3",
            "--seed",
        ]
        .map(String::from)
        .to_vec();
        relay.push(session.to_string());
        relay.extend(FAULTS.map(String::from));
        let relay_log = dir.join("relay.out");
        running.0.push(self.start(&relay, &relay_log)?);
        let Some(relay_address) = self.address(&relay_log, "relay listening on ", &mut running)?
        else {
            return Ok(None);
        };
        let mut controller: Vec<String> = ["controller", "--robot", &relay_address]
            .map(String::from)
            .to_vec();
        controller.extend([
            "--store".into(),
            store("controller"),
            "--report".into(),
            file("controller.json"),
        ]);
        if let Some(address) = mocap {
            controller.extend(["--sensor".into(), format!("mocap:{address}")]);
        }
        controller.extend(common);
        running
            .0
            .push(self.start(&controller, &dir.join("controller.out"))?);
        while running.any_running() {
            if self.should_stop() {
                return Ok(None);
            }
            std::thread::sleep(POLL);
        }
        let report = dir.join("controller.json");
        let text = std::fs::read_to_string(&report).with_context(|| {
            format!(
                "session {session} left no controller report: see {}",
                dir.join("controller.out").display()
            )
        })?;
        Ok(Some(
            serde_json::from_str(&text).with_context(|| format!("read {}", report.display()))?,
        ))
    }

    /// The keys of `role`'s store.
    fn keys(&self, role: &str) -> Result<Vec<Listed>> {
        let store = self.out.join(role).display().to_string();
        let json = self.robokey(&[
            "keys",
            "list",
            "--json",
            "--store",
            &store,
            "--pairing",
            &self.pairing,
        ])?;
        serde_json::from_str(&json).context("read `robokey keys list --json`")
    }

    /// The first key both stores list as settled, under the same ID and length.
    fn settled_on_both_sides(&self) -> Result<Option<Listed>> {
        let robot = self.keys("robot")?;
        Ok(self.keys("controller")?.into_iter().find(|key| {
            key.status == "settled"
                && robot
                    .iter()
                    .any(|r| r.id == key.id && r.status == "settled" && r.bits == key.bits)
        }))
    }

    /// Shows `key` on both sides, checks its bits are equal without printing them.
    fn show(&self, key: &Listed, sessions: u32, started: Instant) -> Result<()> {
        let bits = |role: &str| {
            let store = self.out.join(role).display().to_string();
            self.robokey(&[
                "keys",
                "get",
                "--store",
                &store,
                "--pairing",
                &self.pairing,
                &key.id,
            ])
            .map(zeroize::Zeroizing::new)
        };
        let equal = *bits("robot")? == *bits("controller")?;
        println!(
            "demo: a final key after {sessions} sessions ({:.0} s), in both stores:",
            started.elapsed().as_secs_f64()
        );
        for role in ["robot", "controller"] {
            println!(
                "  {role:<10}  ID {}  {} bits  ε {:.0e}  {}  {}  from {} sessions  ({}/{role})",
                key.id,
                key.bits,
                key.epsilon,
                key.label,
                key.status,
                key.sessions.len(),
                self.out.display(),
            );
        }
        println!("  secret under: {}", key.assumption);
        if !equal {
            bail!("the two stores hold different bits under ID {}", key.id);
        }
        println!(
            "  the bits are equal on both sides (compared here, not shown); to use the key:\n  \
             robokey keys get --store {}/controller --pairing {} {}",
            self.out.display(),
            self.pairing,
            key.id
        );
        Ok(())
    }
}
