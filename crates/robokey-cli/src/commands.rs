//! The subcommands: thin wrappers over robokey-lab.

use std::time::Instant;

use anyhow::{Context, Result, bail};
use robokey::Config;
use robokey_lab::files::{Override, apply_overrides, prepare_output, read_table, write};
use robokey_lab::runner::{Shard, run_experiment, with_jobs};
use robokey_lab::sweep::experiments_from_table;
use robokey_lab::{report, results, trace};

use crate::{ConfigArgs, MergeArgs, ReproduceArgs, RunArgs, SweepArgs};

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

pub fn run(args: RunArgs) -> Result<()> {
    let mut overrides = args.options.set.clone();
    let mut flag = |field: &str, value: toml::Value| {
        overrides.push(Override {
            field: field.into(),
            value,
        })
    };
    if let Some(x) = args.delta_v {
        flag("protocol.delta_v", x.into());
    }
    if let Some(x) = args.delta_omega {
        flag("protocol.delta_omega", x.into());
    }
    if let Some(seed) = args.seed {
        let seed =
            i64::try_from(seed).context("--seed must be below 2^63 (TOML integers are signed)")?;
        flag("run.seed", seed.into());
    }
    if let Some(x) = args.alpha {
        flag("eve.alpha", x.into());
    }
    if args.no_eve {
        flag("eve.enabled", false.into());
    }
    if args.protocol_off {
        flag("protocol.enabled", false.into());
    }
    let config = load_config(args.config.as_deref(), &overrides)?;
    let started = Instant::now();
    let output = robokey::sim::simulate(&config, args.replicate, true)?;
    let elapsed = started.elapsed();
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create", args.out.display()))?;
    let mut json = trace::metrics_json(&output.metrics);
    json.insert("replicate".into(), args.replicate.into());
    json.insert("seed".into(), config.run.seed.into());
    let files = [
        write(&args.out.join("config.resolved.toml"), config.to_toml())?,
        write(
            &args.out.join("metrics.json"),
            serde_json::to_string_pretty(&json)? + "\n",
        )?,
        write(&args.out.join("trace.csv"), trace::trace_csv(&output.trace))?,
    ];
    let figures = report::trajectory_figure(
        &args.out.join("trajectory"),
        &[("robot", &output.trace)],
        None,
    )?;
    let proto = &config.protocol;
    println!(
        "robokey run: seed {}, replicate {}, Δv = {} m/s, Δω = {} rad/s, {}, {} ({:.1} ms)",
        config.run.seed,
        args.replicate,
        proto.delta_v,
        proto.delta_omega,
        if proto.enabled {
            "protocol on"
        } else {
            "protocol off"
        },
        if config.eve.enabled && proto.enabled {
            format!("Eve α = {}", config.eve.alpha)
        } else {
            "no Eve".into()
        },
        elapsed.as_secs_f64() * 1000.0
    );
    print!("{}", trace::metrics_table(&output.metrics));
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
