//! The subcommands: thin wrappers over robokey-lab.

use std::time::Instant;

use anyhow::{Context, Result, bail};
use robokey::Config;
use robokey_lab::files::{Override, apply_overrides, prepare_output, read_table, write};
use robokey_lab::runner::{Shard, run_experiment, with_jobs};
use robokey_lab::sweep::experiments_from_table;
use robokey_lab::{report, results, trace};

use crate::{ConfigArgs, MergeArgs, ReproduceArgs, RunArgs, SecrecyArgs, SweepArgs};

/// Loads a configuration from an optional file plus overrides.
pub fn load_config(path: Option<&std::path::Path>, overrides: &[Override]) -> Result<Config> {
    let mut table = read_table(path)?;
    if table.contains_key("sweep") || table.contains_key("experiment") {
        bail!(
            "{}: holds a sweep; run it with `robokey sweep`",
            path.map_or_else(String::new, |p| p.display().to_string())
        );
    }
    apply_overrides(&mut table, overrides)?;
    let origin = match (path, overrides.is_empty()) {
        (Some(p), true) => p.display().to_string(),
        (Some(p), false) => format!("{} with --set/flags", p.display()),
        (None, _) => "defaults with --set/flags".to_owned(),
    };
    Ok(Config::from_table(table, &origin)?)
}

/// `--set` overrides plus the ones a command's own flags stand for.
pub struct FlagOverrides(Vec<Override>);

impl FlagOverrides {
    /// Starts from the `--set` overrides.
    pub fn new(set: &[Override]) -> Self {
        Self(set.to_vec())
    }

    /// Sets `field` when the flag was given.
    pub fn flag<V: Into<toml::Value>>(&mut self, field: &str, value: Option<V>) {
        if let Some(value) = value {
            self.0.push(Override {
                field: field.into(),
                value: value.into(),
            });
        }
    }

    /// `--seed`, which TOML holds as a signed integer.
    pub fn seed(&mut self, seed: Option<u64>) -> Result<()> {
        let seed = seed
            .map(i64::try_from)
            .transpose()
            .context("--seed must be below 2^63 (TOML integers are signed)")?;
        self.flag("run.seed", seed);
        Ok(())
    }

    /// Loads the configuration with these overrides.
    pub fn load(&self, path: Option<&std::path::Path>) -> Result<Config> {
        load_config(path, &self.0)
    }
}

pub fn run(args: RunArgs) -> Result<()> {
    let mut overrides = FlagOverrides::new(&args.options.set);
    overrides.flag("protocol.delta_v", args.delta_v);
    overrides.flag("protocol.delta_omega", args.delta_omega);
    overrides.seed(args.seed)?;
    overrides.flag("eve.alpha", args.alpha);
    overrides.flag("eve.enabled", args.no_eve.then_some(false));
    overrides.flag("protocol.enabled", args.protocol_off.then_some(false));
    let config = overrides.load(args.config.as_deref())?;
    prepare_output(&args.out, args.force)?;
    // The trace goes to disk row by row (memory independent of N); the figure draws a
    // decimated copy.
    let trace_path = args.out.join("trace.csv");
    let file = std::fs::File::create(&trace_path)
        .with_context(|| format!("{}: cannot create", trace_path.display()))?;
    let mut csv = trace::TraceCsv::new(std::io::BufWriter::new(file))?;
    let mut written = Ok(());
    let mut drawn = trace::DrawnRows::default();
    let plan = robokey::protocol::SessionPlan::from_config(&config, args.replicate);
    let started = Instant::now();
    let output =
        robokey::sim::simulate_plan_streaming(&config, plan, args.replicate, &mut |row| {
            if written.is_ok() {
                written = csv.write(&row);
            }
            drawn.push(row);
        })?;
    let elapsed = started.elapsed();
    written
        .and_then(|()| csv.finish().map(drop))
        .with_context(|| format!("{}: cannot write", trace_path.display()))?;
    let mut json = trace::metrics_json(&output.metrics);
    json.insert("replicate".into(), args.replicate.into());
    json.insert("seed".into(), config.run.seed.into());
    let files = [
        write(&args.out.join("config.resolved.toml"), config.to_toml())?,
        write(
            &args.out.join("metrics.json"),
            serde_json::to_string_pretty(&json)? + "\n",
        )?,
        trace_path,
    ];
    let paths = drawn.into_paths();
    let labels: Vec<String> = match paths.as_slice() {
        [_] => vec!["robot".into()],
        _ => paths
            .iter()
            .map(|p| {
                let k = |row: Option<&robokey::sim::TraceRow>| row.map_or(0, |r| r.k);
                format!("robot, steps {}–{}", k(p.first()), k(p.last()))
            })
            .collect(),
    };
    let drawn: Vec<(&str, &[robokey::sim::TraceRow])> = labels
        .iter()
        .map(String::as_str)
        .zip(paths.iter().map(Vec::as_slice))
        .collect();
    let figures = report::trajectory_figure(&args.out.join("trajectory"), &drawn, None)?;
    let proto = &config.protocol;
    println!(
        "robokey run: seed {}, replicate {}, Δv = {} m/s, Δω = {} rad/s, {}, {} ({:.1} ms)",
        config.run.seed,
        args.replicate,
        proto.delta_v,
        config.perturbed_delta_omega(),
        if proto.enabled {
            "protocol on"
        } else {
            "protocol off"
        },
        if config.eve.enabled && proto.enabled {
            use robokey::config::EveStrategy;
            let eve = &config.eve;
            let strategy = config.eve_strategy();
            match strategy {
                EveStrategy::Oracle => "oracle Eve".to_owned(),
                EveStrategy::Mismatch | EveStrategy::Soft => {
                    format!("{} Eve α = {}", strategy.name(), eve.alpha)
                }
                EveStrategy::Identify | EveStrategy::Transcript => format!(
                    "{} Eve starting {} % off",
                    strategy.name(),
                    100.0 * eve.initial_error
                ),
                EveStrategy::Camera => format!(
                    "camera Eve ({} mm, {} mrad)",
                    1e3 * eve.camera_std[0],
                    1e3 * eve.camera_std[2]
                ),
                EveStrategy::Commands => "commands-only Eve".to_owned(),
            }
        } else {
            "no Eve".into()
        },
        elapsed.as_secs_f64() * 1000.0
    );
    print!(
        "{}",
        trace::metrics_table(&output.metrics, output.private.as_ref())
    );
    println!("wrote:");
    for f in files.iter().chain(&figures) {
        println!("  {}", f.display());
    }
    Ok(())
}

pub fn sweep(args: SweepArgs) -> Result<()> {
    let mut table = read_table(Some(&args.config))?;
    apply_overrides(&mut table, &args.options.set)?;
    let experiments = experiments_from_table(table, &args.config.display().to_string())?;
    prepare_output(&args.out, args.force)?;
    let shard = args.shard.unwrap_or(Shard::ALL);
    let started = Instant::now();
    for experiment in &experiments {
        let dir = args.out.join(&experiment.name);
        let records = with_jobs(args.jobs, || run_experiment(experiment, shard))??;
        results::write_sweep(&dir, experiment, &records, &[shard])?;
        println!(
            "{}: {} points × {} replicates{} → {}",
            if experiment.name.is_empty() {
                "sweep"
            } else {
                &experiment.name
            },
            experiment.points.len(),
            experiment.replicates(),
            if shard == Shard::ALL {
                String::new()
            } else {
                format!(" (shard {shard}: {} runs)", records.len())
            },
            dir.display()
        );
    }
    println!("done in {:.2} s", started.elapsed().as_secs_f64());
    Ok(())
}

pub fn merge(args: MergeArgs) -> Result<()> {
    prepare_output(&args.out, args.force)?;
    let experiment = results::merge(&args.dirs, &args.out)?;
    println!(
        "merged {} shard folders: {} runs → {}",
        args.dirs.len(),
        experiment.runs(),
        args.out.display()
    );
    Ok(())
}

pub fn reproduce(args: ReproduceArgs) -> Result<()> {
    prepare_output(&args.out, args.force)?;
    let started = Instant::now();
    let report = with_jobs(args.jobs, || report::reproduce(&args.out, args.quick))??;
    println!("{}", report.summary);
    println!("report: {}", report.path.display());
    println!("done in {:.2} s", started.elapsed().as_secs_f64());
    Ok(())
}

pub fn config(args: ConfigArgs) -> Result<()> {
    print!(
        "{}",
        load_config(args.config.as_deref(), &args.options.set)?.to_toml()
    );
    Ok(())
}

pub fn secrecy(args: SecrecyArgs) -> Result<()> {
    use robokey::config::SensingMode;
    use robokey_lab::secrecy::map::private_map;
    use robokey_lab::secrecy::render_private::break_even_text;
    use robokey_lab::secrecy::{
        Pooling, SecrecyOptions, analyze, default_adversaries, write_secrecy,
    };
    use robokey_lab::sweep::{MAX_BLOCK_BITS, MIN_BLOCK_BITS};
    if let Some(eps) = args.eps
        && !(eps > 0.0 && eps < 1.0)
    {
        bail!("--eps {eps} is not allowed (allowed: (0, 1))");
    }
    if let Some(block) = args.block
        && !(MIN_BLOCK_BITS..=MAX_BLOCK_BITS).contains(&block)
    {
        bail!(
            "--block {block} is not allowed (allowed: {MIN_BLOCK_BITS} to {MAX_BLOCK_BITS} bits)"
        );
    }
    if !(1..=1_000).contains(&args.blocks) {
        bail!(
            "--blocks {} is not allowed (allowed: 1 to 1000)",
            args.blocks
        );
    }
    if !(1..=1_000_000).contains(&args.max_sessions) {
        bail!(
            "--max-sessions {} is not allowed (allowed: 1 to 1000000)",
            args.max_sessions
        );
    }
    if let Some(p) = args.assume_eve_error
        && !(p > 0.0 && p <= 0.5)
    {
        bail!("--assume-eve-error {p} is not allowed (allowed: (0, 0.5])");
    }
    let options = SecrecyOptions {
        adversaries: args.adversaries.iter().map(|&a| a.into()).collect(),
        blocks: args.blocks,
        sample_bits: args.sample_bits,
        max_sessions: args.max_sessions,
        assumed_eve_error: args.assume_eve_error,
        ..SecrecyOptions::default()
    };
    // A sweep folder, or a suite folder whose subfolders are sweeps.
    let mut folders = Vec::new();
    if args.run_dir.join("config.resolved.toml").exists() {
        folders.push(args.run_dir.clone());
    } else {
        let entries = std::fs::read_dir(&args.run_dir)
            .with_context(|| format!("{}: cannot read", args.run_dir.display()))?;
        let mut subs: Vec<_> = entries
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.join("config.resolved.toml").exists())
            .collect();
        subs.sort();
        folders.extend(subs);
    }
    if folders.is_empty() {
        bail!(
            "{}: no config.resolved.toml here or in its subfolders (is it a sweep folder?)",
            args.run_dir.display()
        );
    }
    let started = Instant::now();
    for folder in folders {
        let origin = folder.join("config.resolved.toml");
        let text = std::fs::read_to_string(&origin)
            .with_context(|| format!("{}: cannot read", origin.display()))?;
        let table = robokey::config::parse_table(&text, &origin.display().to_string())?;
        let name = folder
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let experiment = robokey_lab::sweep::Experiment::from_table(
            &name,
            table,
            &origin.display().to_string(),
        )?;
        if !experiment.points[0].config.protocol.enabled {
            println!("{}: protocol off, no key: skipped", folder.display());
            continue;
        }
        // Adversaries and pooling default by the sweep's sensing mode.
        let mode = experiment.points[0].config.sensing.mode;
        let options = SecrecyOptions {
            adversaries: if options.adversaries.is_empty() {
                default_adversaries(mode)
            } else {
                options.adversaries.clone()
            },
            epsilon: args
                .eps
                .or(experiment.secrecy.epsilon)
                .unwrap_or(options.epsilon),
            block_bits: args
                .block
                .or(experiment.secrecy.block_bits)
                .map_or(options.block_bits, |b| b as usize),
            pooling: args.pooling.map_or(
                match mode {
                    SensingMode::Odometry => Pooling::Confirmed,
                    SensingMode::Private => Pooling::Complete,
                },
                Into::into,
            ),
            ..options.clone()
        };
        let results = with_jobs(args.jobs, || analyze(&experiment, &options))??;
        let map = with_jobs(args.jobs, || private_map(&experiment, &results))??;
        let files = write_secrecy(&folder, &experiment, &results, &options, map.as_ref())?;
        println!("{}:", folder.display());
        if let Some(reason) = results.iter().find_map(|r| r.structural_zero) {
            println!("  secret key rate 0: {reason}");
        }
        if let Some(first) = results
            .first()
            .filter(|_| args.assume_eve_error.is_some() || mode == SensingMode::Private)
        {
            if results.iter().all(|r| r.assumption == first.assumption) {
                println!("  key sized under: {}", first.assumption);
            } else {
                println!(
                    "  key sized under each point's own assumption (column `assumption` of \
                     secrecy.csv), e.g.: {}",
                    first.assumption
                );
            }
        }
        for r in &results {
            let sum = |f: fn(&robokey_lab::secrecy::Block) -> u64| -> u64 {
                r.blocks.iter().map(f).sum()
            };
            println!(
                "  {:<28} {:<10} ({}) raw {:.4} bits/step, Eve wrong on {:.3} % of raw-key bits, {} messages, leak {} (EC) + {} (tags), ℓ {} = {:.5} bits/step ({:.4} bits/s); realised: H_min {:.1}, ℓ {}{}",
                r.point,
                r.adversary,
                r.adversary_class.name(),
                r.raw_bits_per_step,
                r.eve_error_accepted.map_or(f64::NAN, |x| 100.0 * x.rate),
                sum(|b| u64::from(b.messages)),
                sum(|b| b.leak_ec),
                sum(|b| b.leak_confirmation),
                r.secret_bits,
                r.secret_bits_per_step,
                r.secret_bits_per_second,
                r.blocks.iter().map(|b| b.realised.h_min).sum::<f64>(),
                r.realised_secret_bits,
                r.zero_reason.as_ref().map_or_else(
                    || "; holds only under the stated assumption".to_owned(),
                    |why| format!(": {why}")
                )
            );
            if r.assumption_exceeds_realised {
                println!(
                    "  WARNING: the assumption credits {} bits, more than the {} Eve's realised view supports ({}): this adversary violates it",
                    r.secret_bits, r.adversary, r.realised_secret_bits
                );
            }
        }
        if let Some(map) = &map {
            for curve in &map.camera {
                println!(
                    "  break-even camera noise, {}: {}",
                    curve.label,
                    break_even_text(curve)
                );
            }
            if map.pareto.len() > 1
                && let Some(best) = map
                    .pareto
                    .iter()
                    .filter(|p| p.on_front)
                    .max_by(|a, b| a.bits_per_second.total_cmp(&b.bits_per_second))
            {
                println!(
                    "  best rate: {:.3} secret bits/s at {} (J_x {:.1} mm; the paper's scheme: \
                     0 at J_x {:.1} mm)",
                    best.bits_per_second, best.point, best.jx_mm, map.paper_jx_mm
                );
            }
        }
        println!(
            "  wrote {}",
            files
                .iter()
                .map(|f| f.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    println!("done in {:.2} s", started.elapsed().as_secs_f64());
    Ok(())
}
