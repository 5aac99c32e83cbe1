//! `robokey eve`: eavesdroppers on simulated sessions or on a relay capture.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use robokey::Config;
use robokey::config::EveStrategy;
use robokey::config::SensingMode;
use robokey::eve::{ModelErrors, starting_errors};
use robokey::rng::{Purpose, stream};
use robokey::world::Camera;
use robokey_lab::adversary::run_campaigns;
use robokey_lab::output::write;
use robokey_lab::report::adversary::{campaign_markdown, write_campaign};
use robokey_lab::report::private::{PrivateRow, private_markdown, turn_rates_csv};
use robokey_lab::run::with_jobs;
use robokey_lab::secrecy::private::eavesdroppers;
use robokey_net::agent::key_file::read_key_file;
use robokey_net::capture_eve::{listen, listen_private, read_session};
use robokey_net::pose_stream::{CameraLog, read_log};

use crate::StrategyArg;
use crate::commands::prepare_output;
use crate::configuration::{ConfigOptions, FlagOverrides};
use crate::exit::usage;

#[derive(Args, Debug)]
pub struct EveArgs {
    /// Listen to the session in this capture instead of simulating sessions: pcap or pcapng,
    /// from `robokey relay --capture`, tcpdump, dumpcap or Wireshark. Private sensing:
    /// repeatable, one capture per session, each with its --camera-log (and --robot-key,
    /// --controller-key) in the same order.
    #[arg(long)]
    capture: Vec<PathBuf>,
    /// Configuration (TOML) of the sessions; defaults when omitted.
    #[arg(long, short)]
    config: Option<PathBuf>,
    #[command(flatten)]
    options: ConfigOptions,
    /// Strategies, comma-separated (default: the sensing mode's — oracle, mismatch, soft,
    /// identify, transcript in odometry mode; camera, commands in private sensing; on a
    /// capture: the config's eve.strategy).
    #[arg(long, value_enum, value_delimiter = ',')]
    strategy: Vec<StrategyArg>,
    /// Sessions to simulate, in order (`eve.sessions`; default 5).
    #[arg(long)]
    sessions: Option<u32>,
    /// Independent campaigns of `--sessions` sessions each (new sessions, new starting
    /// errors); the report adds medians and ranges over them.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    campaigns: u32,
    /// Largest relative model error α of mismatch and soft (`eve.alpha`).
    #[arg(long)]
    alpha: Option<f64>,
    /// Relative error on r and D the learning strategies start from (`eve.initial_error`).
    #[arg(long)]
    initial_error: Option<f64>,
    /// Capture: her starting relative errors on r, D, W, V given explicitly, e.g.
    /// `0.05,-0.02,0,0` (every strategy but oracle).
    #[arg(
        long,
        value_name = "R,D,W,V",
        conflicts_with = "alpha",
        requires = "capture"
    )]
    errors: Option<String>,
    /// Capture, private sensing: the agent report (`--report`; the controller's says where
    /// the disclosed sample is, the robot's does not) of the run in which a post-processing
    /// block ended, its sessions the captures given: her realised bound over the block is
    /// printed beside the key the agents committed, with a WARNING naming the world's
    /// parameters where the key exceeds it (docs/world.md).
    #[arg(long, value_name = "REPORT", requires = "robot_key")]
    block: Option<PathBuf>,
    /// Master seed (`run.seed`): the sessions and her draws (stream "eve", replicate c in
    /// campaign c; replicate 0 on a capture).
    #[arg(long)]
    seed: Option<u64>,
    /// Capture: the controller's key file, to measure her disagreement (one per capture).
    #[arg(long, requires = "capture")]
    controller_key: Vec<PathBuf>,
    /// Capture, private sensing (required there): her camera's record of the session, a
    /// pose log written by `robokey record` from the world's camera stream (one per capture).
    #[arg(long, value_name = "FILE", requires = "capture")]
    camera_log: Vec<PathBuf>,
    /// Capture, private sensing: the robot's raw bits (its key file), the reference every
    /// other party's error rate is measured against (one per capture).
    #[arg(long, value_name = "FILE", requires = "camera_log")]
    robot_key: Vec<PathBuf>,
    #[command(flatten)]
    world: crate::world::WorldSpecArgs,
    /// Output folder (simulation: default robokey-out/eve; capture: writes capture.json
    /// when given).
    #[arg(long, short)]
    out: Option<PathBuf>,
    /// Worker threads (0: one per core; at most one per core). Results do not depend on it.
    #[arg(long, short, default_value_t = 0)]
    jobs: usize,
    /// Write into a non-empty output folder of robokey's: its files are removed first,
    /// files robokey does not write are kept (and named).
    #[arg(long)]
    force: bool,
}

pub fn eve(args: EveArgs) -> Result<()> {
    let mut overrides = FlagOverrides::new(&args.options.set);
    overrides.value("--sessions", "eve.sessions", args.sessions.map(i64::from));
    overrides.value("--alpha", "eve.alpha", args.alpha);
    overrides.value("--initial-error", "eve.initial_error", args.initial_error);
    overrides.seed(args.seed)?;
    let mut config = overrides.load(args.config.as_deref())?;
    args.world.apply(&mut config)?;
    let explicit = args.errors.as_deref().map(parse_errors).transpose()?;
    let strategies: Vec<EveStrategy> = args.strategy.iter().map(|&s| s.into()).collect();
    if let Some(s) = strategies.iter().find(|s| s.mode() != config.sensing.mode) {
        bail!(
            "--strategy {}: does not apply in sensing.mode = {} (allowed: {})",
            s.name(),
            config.sensing.mode.name(),
            EveStrategy::of_mode(config.sensing.mode)
                .iter()
                .map(|a| a.name())
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    match (args.capture.as_slice(), config.sensing.mode) {
        ([_, ..], SensingMode::Private) => on_private_captures(&args, &config),
        ([_, ..], SensingMode::Odometry) if !args.camera_log.is_empty() => usage!(
            "--camera-log is her camera's record of a private-sensing session (set \
             sensing.mode=private); in odometry mode she decides from the robot's measurements"
        ),
        ([_, ..], SensingMode::Odometry) if args.block.is_some() => usage!(
            "--block is a private-sensing block: in odometry mode the key is zero by structure"
        ),
        ([capture], SensingMode::Odometry) => on_capture(&args, capture, &config, explicit),
        ([_, _, ..], SensingMode::Odometry) => usage!(
            "--capture: one capture at a time in odometry mode (her learning carries over \
             between sessions only in simulation)"
        ),
        ([], SensingMode::Odometry) => simulated(&args, &config),
        ([], SensingMode::Private) => private(&args, &config),
    }
}

/// Private sensing: the camera and commands eavesdroppers on `eve.sessions` simulated
/// sessions. They know the model, so there is nothing to learn across campaigns.
fn private(args: &EveArgs, config: &Config) -> Result<()> {
    if args.campaigns != 1 {
        bail!(
            "--campaigns {}: campaigns measure eavesdroppers who learn the model; private \
             sensing's know it (allowed: 1; use --sessions for more data)",
            args.campaigns
        );
    }
    let strategies = simulated_strategies(args, config.sensing.mode);
    let out = output_folder(args)?;
    let started = Instant::now();
    let sessions = config.eve.sessions;
    let measured = with_jobs(args.jobs, || eavesdroppers(config, &strategies, sessions))??;
    let rows: Vec<PrivateRow> = measured
        .iter()
        .map(|(s, figures)| PrivateRow {
            point: "",
            adversary: s.name(),
            figures,
        })
        .collect();
    let mut files = vec![
        write(&out.join("eve.md"), private_markdown(&rows))?,
        write(&out.join("turn-rates.csv"), turn_rates_csv(&rows))?,
        write(
            &out.join("eve.json"),
            serde_json::to_string_pretty(&serde_json::json!(
                measured
                    .iter()
                    .map(|(s, f)| serde_json::json!({ "strategy": s.name(), "figures": f }))
                    .collect::<Vec<_>>()
            ))? + "\n",
        )?,
    ];
    files.push(write(&out.join("config.resolved.toml"), config.to_toml())?);
    let camera = config.modelled_camera_std();
    println!(
        "eve: private sensing, {sessions} sessions, Eve's camera {} mm / {} mrad",
        1e3 * camera[0],
        1e3 * camera[2]
    );
    for (s, f) in &measured {
        let pct = |r: Option<&robokey_lab::secrecy::Rate>| r.map_or(f64::NAN, |r| 100.0 * r.rate);
        println!(
            "  {:<9} error {:.2} % (controller {:.2} %), information {:.5} bit per bit \
             [{:.5}, {:.5}], predicted {:.5}; calibrated: {}",
            s.name(),
            pct(f.eve_error.as_ref()),
            pct(f.controller_error.as_ref()),
            f.eve_information[0],
            f.eve_information[1],
            f.eve_information[2],
            f.eve_information_predicted,
            if f.eve_calibration.passed {
                "yes"
            } else {
                "NO"
            },
        );
    }
    println!(
        "{} files in {} ({:.2} s); by turn rate: {}",
        files.len(),
        out.display(),
        started.elapsed().as_secs_f64(),
        out.join("eve.md").display()
    );
    Ok(())
}

/// `--errors r,D,W,V`.
fn parse_errors(text: &str) -> Result<ModelErrors> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--errors {text}: expected four numbers r,D,W,V"))?;
    let [r, d, w, v] = values[..] else {
        bail!("--errors {text}: expected four numbers r,D,W,V")
    };
    if values.iter().any(|e| e.is_nan() || e.abs() >= 1.0) {
        bail!("--errors {text}: each relative error must be in (−1, 1)");
    }
    Ok(ModelErrors { r, d, w, v })
}

/// Her starting errors: `--errors` when given (not for the oracle), else drawn from her
/// seeded stream as the config says.
fn errors_of(config: &Config, strategy: EveStrategy, explicit: Option<ModelErrors>) -> ModelErrors {
    match explicit {
        Some(errors) if strategy != EveStrategy::Oracle => errors,
        _ => {
            let mut config = config.clone();
            config.eve.strategy = Some(strategy);
            starting_errors(&config, &mut stream(config.run.seed, Purpose::Eve, 0))
        }
    }
}

/// `--strategy`, or every strategy of `mode`.
fn simulated_strategies(args: &EveArgs, mode: SensingMode) -> Vec<EveStrategy> {
    if args.strategy.is_empty() {
        EveStrategy::of_mode(mode)
    } else {
        args.strategy.iter().map(|&s| s.into()).collect()
    }
}

/// A report's markdown as the terminal shows it: the figures' image links become one line
/// naming the files (in `out`), and the blank lines they leave collapse.
fn for_terminal(markdown: &str, out: &std::path::Path) -> String {
    let mut figures = Vec::new();
    let mut text = String::new();
    for line in markdown.lines() {
        match line
            .strip_prefix("![")
            .and_then(|rest| rest.split_once("]("))
            .and_then(|(_, target)| target.strip_suffix(')'))
        {
            Some(file) => figures.push(out.join(file).display().to_string()),
            None if line.is_empty() && text.ends_with("\n\n") => {}
            None => {
                text.push_str(line);
                text.push('\n');
            }
        }
    }
    if !figures.is_empty() {
        text.push_str(&format!("figures: {}\n", figures.join(", ")));
    }
    text
}

/// `--out` (default robokey-out/eve), prepared for writing.
fn output_folder(args: &EveArgs) -> Result<PathBuf> {
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("robokey-out/eve"));
    prepare_output(&out, args.force)?;
    Ok(out)
}

fn simulated(args: &EveArgs, config: &Config) -> Result<()> {
    let strategies = simulated_strategies(args, config.sensing.mode);
    let out = output_folder(args)?;
    let started = Instant::now();
    let campaign = with_jobs(args.jobs, || {
        run_campaigns(config, &strategies, args.campaigns)
    })??;
    let mut files = vec![campaign.write(&out)?];
    files.extend(write_campaign(&out, &campaign)?);
    write(&out.join("config.resolved.toml"), config.to_toml())?;
    print!("{}", for_terminal(&campaign_markdown(&campaign), &out));
    println!(
        "\n{} × {} sessions × {} strategies in {:.2} s; wrote {} files to {}",
        args.campaigns,
        config.eve.sessions,
        strategies.len(),
        started.elapsed().as_secs_f64(),
        files.len() + 1,
        out.display()
    );
    Ok(())
}

fn on_capture(
    args: &EveArgs,
    capture: &std::path::Path,
    config: &Config,
    explicit: Option<ModelErrors>,
) -> Result<()> {
    let strategies: Vec<EveStrategy> = if args.strategy.is_empty() {
        vec![config.eve_strategy()]
    } else {
        args.strategy.iter().map(|&s| s.into()).collect()
    };
    let captured = read_session(capture, config)?;
    warn_of_shortfalls(capture, &captured.shortfalls);
    let controller = args
        .controller_key
        .first()
        .map(|p| read_key_file(p))
        .transpose()?;
    println!(
        "eve: session {:08x}, {} frames ({} undecodable datagrams)",
        captured.session,
        captured.messages.len(),
        captured.undecodable
    );
    if let Some(reason) = &captured.aborted {
        println!(
            "eve: the session was aborted ({reason}): no key was agreed; the bits below are \
             what she would hold had it finished"
        );
    }
    let key_label = if captured.aborted.is_some() {
        "would-be key"
    } else {
        "key"
    };
    let mut reports = Vec::new();
    for strategy in strategies {
        let errors = errors_of(config, strategy, explicit);
        let result = listen(&captured, config, strategy, errors);
        let decided = result.decisions.iter().flatten().count();
        let (r, d) = (
            result.model.wheel_radius / config.robot.r - 1.0,
            result.model.axle_length / config.robot.axle_length - 1.0,
        );
        println!(
            "eve[{}]: {decided} steps decided, {key_label} {} bits; model errors r {:+.4}, D {:+.4} (started at r {:+.4}, D {:+.4}, W {:+.4}, V {:+.4}){}",
            strategy.name(),
            result.key.len(),
            r,
            d,
            errors.r,
            errors.d,
            errors.w,
            errors.v,
            result.tag_flips.map_or(String::new(), |f| format!(
                "; key verified by the confirmation tag after flipping {f} codewords"
            )),
        );
        let disagreement = match (
            &controller,
            args.controller_key.first().map(|p| p.as_path()),
        ) {
            (Some(key), Some(path)) => {
                if key.len() != result.key.len() {
                    bail!(
                        "{}: the controller's key has {} bits, Eve's {}: not the same session?",
                        path.display(),
                        key.len(),
                        result.key.len()
                    );
                }
                let differ = key
                    .iter()
                    .zip(result.key.iter())
                    .filter(|(a, b)| a != b)
                    .count();
                let pct = (!key.is_empty()).then(|| 100.0 * differ as f64 / key.len() as f64);
                match pct {
                    Some(p) => println!(
                        "eve[{}]: disagrees with the controller's key on {differ} of {} bits ({p:.2} %)",
                        strategy.name(),
                        key.len()
                    ),
                    None => println!("eve[{}]: the controller's key is empty", strategy.name()),
                }
                pct
            }
            _ => None,
        };
        reports.push(serde_json::json!({
            "strategy": strategy.name(),
            "start_errors": { "r": errors.r, "D": errors.d, "W": errors.w, "V": errors.v },
            "end_errors": { "r": r, "D": d },
            "decisions": result.decisions,
            "key_bits": result.key.len(),
            "tag_flips": result.tag_flips,
            "disagreement_pct": disagreement,
        }));
    }
    if let Some(out) = &args.out {
        std::fs::create_dir_all(out).with_context(|| format!("create {}", out.display()))?;
        let json = serde_json::json!({
            "session": format!("{:08x}", captured.session),
            "session_aborted": captured.aborted,
            "frames": captured.messages.len(),
            "undecodable": captured.undecodable,
            "shortfalls": captured.shortfalls,
            "strategies": reports,
        });
        write(
            &out.join("capture.json"),
            serde_json::to_string_pretty(&json)? + "\n",
        )?;
    }
    Ok(())
}

/// Private sensing on captures: the `camera` and `commands` eavesdroppers on each relay
/// capture and her camera log, with the error rates against the robot's raw bits when given;
/// with `--block`, her realised bound over the block those sessions made.
fn on_private_captures(args: &EveArgs, config: &Config) -> Result<()> {
    let n = args.capture.len();
    if args.camera_log.len() != n {
        usage!(
            "--capture of a private-sensing session needs her camera's record: one --camera-log \
             FILE per --capture ({} captures, {} camera logs; `robokey record --from \
             CAMERA_ADDR --out FILE` during each session)",
            n,
            args.camera_log.len()
        );
    }
    for (flag, given) in [
        ("--robot-key", args.robot_key.len()),
        ("--controller-key", args.controller_key.len()),
    ] {
        if given != 0 && given != n {
            usage!("{flag}: one per --capture ({n} captures, {given} given)");
        }
    }
    let world = config.world_model();
    for difference in world.differences(config) {
        println!("eve: the world is not the parties': {difference}");
    }
    let mut sessions = Vec::new();
    let mut block = Vec::new();
    for i in 0..n {
        let key = |paths: &[PathBuf]| paths.get(i).map(|p| read_key_file(p)).transpose();
        let (robot, controller) = (key(&args.robot_key)?, key(&args.controller_key)?);
        let (json, camera_view) = on_private_capture(
            args,
            config,
            &args.capture[i],
            &args.camera_log[i],
            robot.as_ref().map(|k| k.as_slice()),
            controller.as_ref().map(|k| k.as_slice()),
        )?;
        block.extend(camera_view);
        sessions.push(json);
    }
    let verdict = match &args.block {
        Some(report) => Some(block_verdict(report, &block, config)?),
        None => None,
    };
    if let Some(out) = &args.out {
        std::fs::create_dir_all(out).with_context(|| format!("create {}", out.display()))?;
        let json = match (sessions.len(), verdict) {
            (1, None) => sessions.remove(0),
            (_, verdict) => serde_json::json!({ "sessions": sessions, "block": verdict }),
        };
        write(
            &out.join("capture.json"),
            serde_json::to_string_pretty(&json)? + "\n",
        )?;
    }
    Ok(())
}

/// One captured session: prints every adversary's decisions against the raw bits given;
/// returns its `capture.json` and the camera adversary's posterior error probability of each
/// of the robot's raw bits given the others (empty without the robot's bits).
fn on_private_capture(
    args: &EveArgs,
    config: &Config,
    capture: &std::path::Path,
    camera_log: &std::path::Path,
    robot: Option<&[u8]>,
    controller: Option<&[u8]>,
) -> Result<(serde_json::Value, Vec<f64>)> {
    let strategies = simulated_strategies(args, config.sensing.mode);
    let captured = read_session(capture, config)?;
    warn_of_shortfalls(capture, &captured.shortfalls);
    let camera = read_log(camera_log)?;
    let world = config.world_model();
    match (&camera, world.camera) {
        (CameraLog::Frames(_), Camera::Instants { .. }) => usage!(
            "--camera-log {}: a log of frames between the instants, but the world's camera \
             films at the instants (give --world with world.camera_fps)",
            camera_log.display()
        ),
        (CameraLog::Instants(_), Camera::Frames { .. }) => usage!(
            "--camera-log {}: a log of samples at the instants, but the world's camera films \
             frames at world.camera_fps",
            camera_log.display()
        ),
        _ => {}
    }
    let heard = listen_private(&captured, &camera, config, robot);
    let her_camera = match world.camera {
        Camera::Instants { std } => format!(
            "{} mm / {} mrad at the instants",
            1e3 * std[0],
            1e3 * std[2]
        ),
        Camera::Frames { fps, frame_std } => format!(
            "{} mm / {} mrad per frame at {fps} frames/s",
            1e3 * frame_std[0],
            1e3 * frame_std[2]
        ),
    };
    println!(
        "eve: session {:08x}, {} frames ({} undecodable datagrams), {} camera samples; \
         her camera {her_camera}",
        captured.session,
        captured.messages.len(),
        captured.undecodable,
        camera.len(),
    );
    // `differ(a, b)`: "n of m bits (p %)", or why they cannot be compared.
    let differ = |a: &[u8], b: &[u8]| -> String {
        if a.len() != b.len() {
            return format!("not comparable: {} bits against {}", a.len(), b.len());
        }
        let n = a.iter().zip(b).filter(|(x, y)| x != y).count();
        let pct = 100.0 * n as f64 / a.len().max(1) as f64;
        format!("{n} of {} bits ({pct:.2} %)", a.len())
    };
    if let (Some(robot), Some(controller)) = (robot, controller) {
        println!(
            "controller: differs from the robot's raw bits on {}",
            differ(robot, controller)
        );
    }
    let bits = usize::from(config.protocol.bits_per_doublet);
    let mut reports = Vec::new();
    let mut camera_view = Vec::new();
    for strategy in strategies {
        let camera_adversary = strategy != EveStrategy::Commands;
        let key = if camera_adversary {
            &heard.camera_key
        } else {
            &heard.commands_key
        };
        let decided: Vec<serde_json::Value> = heard
            .doublets
            .iter()
            .map(|d| {
                let (evidence, given) = if camera_adversary {
                    (d.camera, d.camera_given_others)
                } else {
                    (d.commands, d.commands_given_others)
                };
                let llr = &evidence.llr[..bits];
                serde_json::json!({
                    "doublet": d.doublet,
                    "llr": llr,
                    "bits": llr.iter().map(|&l| u8::from(l < 0.0)).collect::<Vec<_>>(),
                    "llr_given_others": given.map(|g| g.llr[..bits].to_vec()),
                })
            })
            .collect();
        let mut line = format!(
            "eve[{}]: {} doublets decided, key {} bits",
            strategy.name(),
            decided.len(),
            key.len()
        );
        if let Some(robot) = robot {
            line += &format!(
                "; differs from the robot's raw bits on {}",
                differ(robot, key)
            );
        }
        if let Some(controller) = controller {
            line += &format!("; from the controller's on {}", differ(controller, key));
        }
        println!("{line}");
        if let Some(robot) = robot {
            let view = given_others_view(&heard, robot, bits, camera_adversary);
            println!(
                "eve[{}]: her view of the robot's {} raw bits, each given the others: {:.4} bit \
                 of information per bit; H_min^ε ≥ {:.1} bits at ε = {:e}{}",
                strategy.name(),
                view.bits,
                view.information,
                robokey_secrecy::posterior_smooth_min_entropy(
                    &view.error_probabilities,
                    config.postprocess.epsilon
                )?
                .h_min,
                config.postprocess.epsilon,
                if view.missing > 0 {
                    format!(" ({} bits without it: their own LLR counted)", view.missing)
                } else {
                    String::new()
                }
            );
            if camera_adversary {
                camera_view = view.error_probabilities;
            }
        }
        reports.push(serde_json::json!({
            "strategy": strategy.name(),
            "doublets": decided,
            "key_bits": key.len(),
        }));
    }
    let json = serde_json::json!({
        "session": format!("{:08x}", captured.session),
        "frames": captured.messages.len(),
        "undecodable": captured.undecodable,
        "shortfalls": captured.shortfalls,
        "camera_samples": camera.len(),
        "strategies": reports,
    });
    Ok((json, camera_view))
}

/// A post-processing block as an agent's report tells it (`post.blocks`, the last that made
/// a key).
#[derive(serde::Deserialize)]
struct ReportedBlock {
    block: u64,
    sessions: usize,
    bits: usize,
    sample_bits: usize,
    /// The sample's positions in the block (the controller's report; absent in the robot's).
    #[serde(default)]
    sampled: Vec<u32>,
    reconciled_bits: usize,
    leak_ec: u64,
    leak_confirmation: u64,
    h_min: f64,
    length: u64,
}

/// Her realised bound over the block of `report` (the camera adversary's posterior error
/// probabilities `q` of its raw bits, in pool order), beside the key the agents committed; a
/// WARNING naming the world's parameters where the key exceeds it. Her bound is over the
/// bits the block amplified ([`amplified_bits`]). Returns the JSON of it.
fn block_verdict(
    report: &std::path::Path,
    q: &[f64],
    config: &Config,
) -> Result<serde_json::Value> {
    let text = std::fs::read_to_string(report)
        .with_context(|| format!("read the agent report {}", report.display()))?;
    let json: serde_json::Value = serde_json::from_str(&text)
        .with_context(|| format!("{}: not an agent's JSON report", report.display()))?;
    let blocks: Vec<ReportedBlock> = serde_json::from_value(json["post"]["blocks"].clone())
        .with_context(|| format!("{}: no post-processing blocks in it", report.display()))?;
    let Some(block) = blocks.into_iter().rev().find(|b| b.length > 0) else {
        usage!(
            "--block {}: no block of this run made a key (its report's post.blocks)",
            report.display()
        );
    };
    if q.len() != block.bits {
        usage!(
            "--block {}: block {} pooled {} raw bits of {} sessions, the captures' robot keys \
             hold {}: give the block's sessions, in order",
            report.display(),
            block.block,
            block.bits,
            block.sessions,
            q.len()
        );
    }
    let epsilon = config.postprocess.epsilon;
    let (kept, which) = amplified_bits(q, &block);
    let h_min = robokey_secrecy::posterior_smooth_min_entropy(&kept, epsilon)?.h_min;
    let realised =
        robokey_secrecy::output_length(h_min, block.leak_ec, block.leak_confirmation, epsilon)?;
    println!(
        "block {}: {} raw bits of {} sessions, {} amplified; the agents committed a key of {} \
         bits (H_min {:.0} under their assumption); the camera eavesdropper who knows the world \
         supports {} (H_min {:.0} over {} bits: {which}; leak {} + {})",
        block.block,
        block.bits,
        block.sessions,
        block.reconciled_bits,
        block.length,
        block.h_min,
        realised.bits,
        h_min,
        kept.len(),
        block.leak_ec,
        block.leak_confirmation
    );
    let exceeds = block.length > realised.bits;
    let differences = config.world_model().differences(config);
    if exceeds {
        let world = if differences.is_empty() {
            "the parties' own world".to_owned()
        } else {
            format!(
                "a world the parties' configuration does not describe: {}",
                differences.join("; ")
            )
        };
        println!(
            "WARNING: block {}: the committed key of {} bits exceeds the {} bits the camera \
             eavesdropper's realised view supports, in {world}",
            block.block, block.length, realised.bits
        );
    }
    Ok(serde_json::json!({
        "block": block.block,
        "raw_bits": block.bits,
        "committed_bits": block.length,
        "realised_bits": realised.bits,
        "realised_h_min": h_min,
        "exceeds": exceeds,
        "world": differences,
    }))
}

/// Her posterior error probabilities `q` (pool order) of the bits the block amplified, and
/// which they are: the bits outside the disclosed sample where the report says where it is
/// (the controller's), else all but the `sample_bits` bits she knows least — a bound that
/// never credits her uncertainty she may not have, lower than hers by up to the sample's
/// share of her uncertainty.
fn amplified_bits(q: &[f64], block: &ReportedBlock) -> (Vec<f64>, &'static str) {
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

/// A private eavesdropper's view of the robot's raw bits of a capture.
struct GivenOthers {
    /// Raw bits measured.
    bits: usize,
    /// Mean information `1 − S` per bit (bits).
    information: f64,
    /// Her posterior error probability of each bit.
    error_probabilities: Vec<f64>,
    /// Bits whose view given the others was not measured (their own LLR taken).
    missing: usize,
}

/// Her view of each of the robot's raw bits (kept doublets in order, `bits` per doublet) given
/// the others, from the `camera` or the `commands` adversary.
fn given_others_view(
    heard: &robokey_net::capture_eve::PrivateCaptureResult,
    robot: &[u8],
    bits: usize,
    camera: bool,
) -> GivenOthers {
    use robokey_secrecy::gaussian_llr::surprisal;
    let mut view = GivenOthers {
        bits: 0,
        information: 0.0,
        error_probabilities: Vec::new(),
        missing: 0,
    };
    for (&j, truth) in heard.kept.iter().zip(robot.chunks_exact(bits)) {
        let Some(d) = heard.doublets.iter().find(|d| d.doublet == j) else {
            continue;
        };
        let (own, given) = if camera {
            (d.camera, d.camera_given_others)
        } else {
            (d.commands, d.commands_given_others)
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
    view
}

/// Says on stderr what of `capture` could not be read (a cut-off end, packets cut by the
/// snap length): the results hold for what was read.
pub fn warn_of_shortfalls(capture: &std::path::Path, shortfalls: &[String]) {
    for shortfall in shortfalls {
        eprintln!("warning: {}: {shortfall}", capture.display());
    }
}

#[cfg(test)]
mod tests {
    fn block(sample_bits: usize, sampled: Vec<u32>) -> super::ReportedBlock {
        super::ReportedBlock {
            block: 0,
            sessions: 1,
            bits: 4,
            sample_bits,
            sampled,
            reconciled_bits: 4 - sample_bits,
            leak_ec: 0,
            leak_confirmation: 0,
            h_min: 0.0,
            length: 1,
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

    #[test]
    fn the_terminal_gets_figure_files_instead_of_image_links() {
        let text = super::for_terminal(
            "# Title\n\ntext\n\n![error rates](a.svg)\n\n![b](b.svg)\n",
            std::path::Path::new("out"),
        );
        assert_eq!(text, "# Title\n\ntext\n\nfigures: out/a.svg, out/b.svg\n");
    }
}
