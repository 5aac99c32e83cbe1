//! `robokey eve`: eavesdroppers on simulated sessions or on a relay capture (the latter's
//! reports made by robokey-net's `recorded_eve`, printed here).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use robokey::Config;
use robokey::config::EveStrategy;
use robokey::config::SensingMode;
use robokey::eve::ModelErrors;
use robokey::world::Camera;
use robokey_lab::adversary::run_campaigns;
use robokey_lab::output::write;
use robokey_lab::report::adversary::{campaign_markdown, write_campaign};
use robokey_lab::report::private::{PrivateRow, private_markdown, turn_rates_csv};
use robokey_lab::run::with_jobs;
use robokey_lab::secrecy::private::eavesdroppers;
use robokey_net::recorded_eve::{
    BlockVerdict, CaptureReport, Disagreement, Heard, Naming, PrivateCaptureReport, PrivateReport,
    RecordedSessions, check_strategies, explicit_errors, hear,
};

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
    /// block ended, its sessions the captures given in the block's order (the report's
    /// `session_ids`; other sessions are refused, naming both): her realised bound over the block is
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
    check_strategies(&strategies, config.sensing.mode, Naming::Flags)?;
    if args.capture.is_empty() {
        return match config.sensing.mode {
            SensingMode::Odometry => simulated(&args, &config),
            SensingMode::Private => private(&args, &config),
        };
    }
    let sessions = RecordedSessions {
        captures: &args.capture,
        camera_logs: &args.camera_log,
        robot_keys: &args.robot_key,
        controller_keys: &args.controller_key,
        block: args.block.as_deref(),
        strategies: &strategies,
        errors: explicit,
    };
    let heard = hear(sessions, &config, Naming::Flags)?;
    match &heard {
        Heard::Odometry(report) => print_capture(&args.capture[0], report),
        Heard::Private(report) => print_private(&args.capture, report, &config),
    }
    if let Some(out) = &args.out {
        std::fs::create_dir_all(out).with_context(|| format!("create {}", out.display()))?;
        let json = serde_json::to_value(&heard)?;
        write(
            &out.join("capture.json"),
            serde_json::to_string_pretty(&json)? + "\n",
        )?;
    }
    Ok(())
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
            match (f.eve_calibration.passed, f.eve_calibration.worst_bin) {
                (true, _) => "yes".to_string(),
                (false, Some(bin)) => format!(
                    "NO (worst bin: {bin}{})",
                    if bin.under_confident() {
                        ": she learns more than her model says"
                    } else {
                        ""
                    }
                ),
                (false, None) => "NO".to_string(),
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
    let mut values = Vec::new();
    for value in text.split(',') {
        let Ok(number) = value.trim().parse::<f64>() else {
            usage!("--errors {text}: {value:?} is not a number (expected four numbers r,D,W,V)");
        };
        values.push(number);
    }
    explicit_errors(&values).map_err(|e| anyhow::Error::new(e).context(format!("--errors {text}")))
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

/// Prints what every odometry eavesdropper made of the captured session.
fn print_capture(capture: &std::path::Path, report: &CaptureReport) {
    warn_of_shortfalls(capture, &report.shortfalls);
    println!(
        "eve: session {:08x}, {} frames ({} undecodable datagrams)",
        report.session, report.frames, report.undecodable
    );
    if let Some(reason) = &report.session_aborted {
        println!(
            "eve: the session was aborted ({reason}): no key was agreed; the bits below are \
             what she would hold had it finished"
        );
    }
    let key_label = if report.session_aborted.is_some() {
        "would-be key"
    } else {
        "key"
    };
    for heard in &report.strategies {
        let (start, end) = (heard.start_errors, heard.end_errors);
        println!(
            "eve[{}]: {} steps decided, {key_label} {} bits; model errors r {:+.4}, D {:+.4} (started at r {:+.4}, D {:+.4}, W {:+.4}, V {:+.4}){}",
            heard.strategy.name(),
            heard.decided(),
            heard.key_bits,
            end.r,
            end.d,
            start.r,
            start.d,
            start.w,
            start.v,
            heard.tag_flips.map_or(String::new(), |f| format!(
                "; key verified by the confirmation tag after flipping {f} codewords"
            )),
        );
        if let Some(disagreement) = heard.disagreement {
            match disagreement.percent() {
                Some(p) => println!(
                    "eve[{}]: disagrees with the controller's key on {} of {} bits ({p:.2} %)",
                    heard.strategy.name(),
                    disagreement.differing,
                    disagreement.bits
                ),
                None => println!(
                    "eve[{}]: the controller's key is empty",
                    heard.strategy.name()
                ),
            }
        }
    }
}

/// Prints what the private eavesdroppers made of each captured session (`captures`, in
/// order) and her bound over their block.
fn print_private(captures: &[PathBuf], report: &PrivateReport, config: &Config) {
    let world = config.world_model();
    for difference in world.differences(config) {
        println!("eve: the world is not the parties': {difference}");
    }
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
    for (capture, session) in captures.iter().zip(&report.sessions) {
        warn_of_shortfalls(capture, &session.shortfalls);
        print_private_capture(session, &her_camera, config.postprocess.epsilon);
    }
    for verdict in &report.blocks {
        print_block_verdict(verdict);
    }
}

/// `a` against `b`: "n of m bits (p %)", or why they cannot be compared (`a` and `b` bits).
fn differ(disagreement: Option<Disagreement>, a: usize, b: usize) -> String {
    match disagreement {
        Some(d) => format!(
            "{} of {} bits ({:.2} %)",
            d.differing,
            d.bits,
            d.percent().unwrap_or(0.0)
        ),
        None => format!("not comparable: {a} bits against {b}"),
    }
}

/// Prints what every private eavesdropper made of one captured session, against the raw bits
/// given.
fn print_private_capture(report: &PrivateCaptureReport, her_camera: &str, epsilon: f64) {
    println!(
        "eve: session {:08x}, {} frames ({} undecodable datagrams), {} camera samples; \
         her camera {her_camera}",
        report.session, report.frames, report.undecodable, report.camera_samples,
    );
    let (robot, controller) = (
        report.robot_bits.unwrap_or(0),
        report.controller_bits.unwrap_or(0),
    );
    if let Some(vs) = report.controller_vs_robot {
        println!(
            "controller: differs from the robot's raw bits on {}",
            differ(vs, robot, controller)
        );
    }
    for heard in &report.strategies {
        let mut line = format!(
            "eve[{}]: {} doublets decided, key {} bits",
            heard.strategy.name(),
            heard.doublets.len(),
            heard.key_bits
        );
        if let Some(vs) = heard.against_robot {
            line += &format!(
                "; differs from the robot's raw bits on {}",
                differ(vs, robot, heard.key_bits)
            );
        }
        if let Some(vs) = heard.against_controller {
            line += &format!(
                "; from the controller's on {}",
                differ(vs, controller, heard.key_bits)
            );
        }
        println!("{line}");
        if let Some(view) = &heard.view {
            println!(
                "eve[{}]: her view of the robot's {} raw bits, each given the others: {:.4} bit \
                 of information per bit; H_min^ε ≥ {:.1} bits at ε = {epsilon:e}{}",
                heard.strategy.name(),
                view.bits,
                view.information,
                view.h_min,
                if view.missing > 0 {
                    format!(" ({} bits without it: their own LLR counted)", view.missing)
                } else {
                    String::new()
                }
            );
        }
    }
}

/// Prints her realised bound over a block beside the key the agents committed, and a WARNING
/// naming the world's parameters where the key exceeds it.
fn print_block_verdict(verdict: &BlockVerdict) {
    let block = &verdict.reported;
    println!(
        "block {}: {} raw bits of {} sessions, {} amplified; the agents committed a key of {} \
         bits (H_min {:.0} under their assumption); the camera eavesdropper who knows the world \
         supports {} (H_min {:.0} over {} bits: {}; leak {} + {})",
        block.block,
        block.bits,
        block.sessions,
        block.reconciled_bits,
        block.length,
        block.h_min,
        verdict.realised_bits,
        verdict.realised_h_min,
        verdict.amplified,
        verdict.which,
        block.leak_ec,
        block.leak_confirmation
    );
    if verdict.exceeds {
        let world = if verdict.world.is_empty() {
            "the parties' own world".to_owned()
        } else {
            format!(
                "a world the parties' configuration does not describe: {}",
                verdict.world.join("; ")
            )
        };
        println!(
            "WARNING: block {}: the committed key of {} bits exceeds the {} bits the camera \
             eavesdropper's realised view supports, in {world}",
            block.block, block.length, verdict.realised_bits
        );
    }
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
    #[test]
    fn the_terminal_gets_figure_files_instead_of_image_links() {
        let text = super::for_terminal(
            "# Title\n\ntext\n\n![error rates](a.svg)\n\n![b](b.svg)\n",
            std::path::Path::new("out"),
        );
        assert_eq!(text, "# Title\n\ntext\n\nfigures: out/a.svg, out/b.svg\n");
    }
}
