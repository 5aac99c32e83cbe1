//! The subcommands: thin wrappers over robokey-lab.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use robokey::config::source;
use robokey::interrupt::Interrupt;
use robokey_lab::LabError;
use robokey_lab::experiment::{Experiment, experiments_from_table};
use robokey_lab::folder::sweep::{Start, SweepPlan, Swept};
use robokey_lab::folder::{layout, merge};
use robokey_lab::output::write;
use robokey_lab::parquet_table::{TableFormat, write_parquet};
use robokey_lab::reproduce::compute_stages;
use robokey_lab::reproduce::suite::paper_suite;
use robokey_lab::run::with_jobs;
use robokey_lab::trace_table::TraceColumns;
use robokey_lab::{metric_table, report, trace};

use crate::configuration::{FlagOverrides, load_config, read_table};
use crate::exit::{Status, on_signals, usage};
use crate::{ConfigArgs, MergeArgs, ReportArgs, ReproduceArgs, RunArgs, SecrecyArgs, SweepArgs};

/// Prepares an output folder (see [`robokey_lab::output::prepare_output`]) and says which
/// files `--force` kept because robokey did not write them.
pub fn prepare_output(dir: &Path, force: bool) -> Result<()> {
    let kept = robokey_lab::output::prepare_output(dir, force)?;
    if !kept.is_empty() {
        let names: Vec<String> = kept.iter().map(|p| p.display().to_string()).collect();
        eprintln!(
            "{}: --force removed robokey's files and kept {} it did not write: {}",
            dir.display(),
            names.len(),
            names.join(", ")
        );
    }
    Ok(())
}

pub fn run(args: RunArgs) -> Result<()> {
    let mut overrides = FlagOverrides::new(&args.options.set);
    overrides.value("--delta-v", "protocol.delta_v", args.delta_v);
    overrides.value("--delta-omega", "protocol.delta_omega", args.delta_omega);
    overrides.seed(args.seed)?;
    overrides.value("--alpha", "eve.alpha", args.alpha);
    overrides.switch("--no-eve", args.no_eve, "eve.enabled", false);
    overrides.switch(
        "--protocol-off",
        args.protocol_off,
        "protocol.enabled",
        false,
    );
    let config = overrides.load(args.config.as_deref())?;
    prepare_output(&args.out, args.force)?;
    // In CSV the trace goes to disk row by row (memory independent of N); in Parquet it is
    // collected column by column and written at the end. The figure draws a decimated copy.
    let format = TableFormat::from(args.format);
    let trace_path = args.out.join(format!("trace.{}", format.extension()));
    let mut csv = match format {
        TableFormat::Csv => {
            let file = std::fs::File::create(&trace_path)
                .with_context(|| format!("{}: cannot create", trace_path.display()))?;
            Some(trace::TraceCsv::new(std::io::BufWriter::new(file))?)
        }
        TableFormat::Parquet => None,
    };
    let mut columns = TraceColumns::default();
    let mut written = Ok(());
    let mut drawn = trace::DrawnRows::default();
    let plan = robokey::protocol::SessionPlan::from_config(&config, args.replicate);
    let started = Instant::now();
    let output =
        robokey::sim::simulate_plan_streaming(&config, plan, args.replicate, &mut |row| {
            match &mut csv {
                Some(csv) if written.is_ok() => written = csv.write(&row),
                Some(_) => {}
                None => columns.push(&row),
            }
            drawn.push(row);
        })?;
    let elapsed = started.elapsed();
    match csv {
        Some(csv) => written
            .and_then(|()| csv.finish().map(drop))
            .with_context(|| format!("{}: cannot write", trace_path.display()))?,
        None => {
            write_parquet(&trace_path, &columns.into_columns(), &[])?;
        }
    }
    let mut json = metric_table::metrics_json(&output.metrics);
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
    let labelled = trace::labelled_paths("robot", &paths);
    let drawn: Vec<(&str, &[robokey::sim::TraceRow])> =
        labelled.iter().map(|(l, p)| (l.as_str(), *p)).collect();
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
                EveStrategy::Camera => {
                    // Per instant: her frames' equivalent when the camera is stated in frames.
                    let camera = config.modelled_camera_std();
                    format!(
                        "camera Eve ({} mm, {} mrad)",
                        1e3 * camera[0],
                        1e3 * camera[2]
                    )
                }
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

pub fn sweep(args: SweepArgs) -> Result<Status> {
    let set = &args.options.set;
    let mut table = read_table(&args.config)?;
    source::apply(&mut table, set)?;
    let experiments =
        experiments_from_table(table, &args.config.display().to_string()).map_err(|e| match e {
            LabError::Config(e) => LabError::Config(source::blame(e, set)),
            other => other,
        })?;
    if args.shard.is_some() && matches!(args.format, crate::FormatArg::Parquet) {
        usage!(
            "--shard with --format parquet: shards are merged from their runs.csv; sweep the \
             shards in CSV and give --format parquet to `robokey merge`"
        );
    }
    let (out, resume) = output(&args.out, args.resume.as_deref(), args.force)?;
    let stop = on_signals()?;
    let plan = SweepPlan {
        shard: args.shard,
        resume,
        format: args.format.into(),
    };
    let swept = sweep_into(&out, &experiments, plan, args.jobs, &stop)?;
    let mut again = vec![
        "robokey".to_owned(),
        "sweep".into(),
        shell_word(&args.config.display().to_string()),
    ];
    again.extend(args.options.set.iter().map(|o| shell_word(&o.flag)));
    Ok(finish(&swept, &out, again))
}

/// The folder a sweep writes: `--resume DIR` (which must exist), else `--out` made ready.
fn output(out: &Path, resume: Option<&Path>, force: bool) -> Result<(PathBuf, bool)> {
    match resume {
        Some(dir) if !dir.is_dir() => {
            usage!("--resume {}: no such folder", dir.display())
        }
        Some(dir) => Ok((dir.to_path_buf(), true)),
        None => {
            prepare_output(out, force)?;
            Ok((out.to_path_buf(), false))
        }
    }
}

/// Sweeps on `jobs` threads, announcing each experiment before it runs.
fn sweep_into(
    out: &Path,
    experiments: &[Experiment],
    plan: SweepPlan,
    jobs: usize,
    stop: &Interrupt,
) -> Result<Swept> {
    let started = Instant::now();
    let swept = with_jobs(jobs, || {
        robokey_lab::folder::sweep::sweep(out, experiments, plan, stop, &mut announce, &|| {})
    })??;
    if swept.interrupted.is_none() {
        println!("swept in {:.2} s", started.elapsed().as_secs_f64());
    }
    Ok(swept)
}

/// `dv-sweep: 11 points × 10 replicates (shard 1/2: 55 runs) → out/dv-sweep`.
fn announce(start: &Start) {
    let e = start.experiment;
    let mut what = Vec::new();
    if start.shards != [robokey_lab::run::Shard::ALL] {
        let shards: Vec<String> = start.shards.iter().map(ToString::to_string).collect();
        what.push(format!(
            "shard {}: {} runs",
            shards.join(", "),
            start.planned
        ));
    }
    if start.done > 0 {
        what.push(format!(
            "resumed: {} of {} runs done",
            start.done, start.planned
        ));
    }
    println!(
        "{}: {} × {}{} → {}",
        if e.name.is_empty() { "sweep" } else { &e.name },
        count(e.points.len(), "point"),
        count(e.replicates() as usize, "replicate"),
        if what.is_empty() {
            String::new()
        } else {
            format!(" ({})", what.join("; "))
        },
        start.dir.display()
    );
}

/// The status of a sweep; when interrupted, says what was kept and how to continue
/// (`again`: the command that made it, to which `--resume` is added).
fn finish(swept: &Swept, out: &Path, mut again: Vec<String>) -> Status {
    let Some(signal) = swept.interrupted else {
        return Status::Success;
    };
    let (done, planned) = swept
        .experiments
        .iter()
        .fold((0, 0), |(d, p), e| (d + e.done, p + e.planned));
    eprintln!(
        "interrupted by {}: {done} of {planned} runs done and saved in {}",
        signal_name(signal),
        out.display()
    );
    if swept.experiments.len() > 1 {
        for e in &swept.experiments {
            eprintln!(
                "  {}: {}",
                e.name,
                match (e.done, e.complete()) {
                    (_, true) => "complete".to_owned(),
                    (0, false) => "not started".to_owned(),
                    (done, false) => format!("{done} of {} runs", e.planned),
                }
            );
        }
    }
    again.push(format!(
        "--resume {}",
        shell_word(&out.display().to_string())
    ));
    eprintln!("continue with: {}", again.join(" "));
    Status::Interrupted(signal)
}

/// `1 point`, `11 points`.
fn count(n: usize, noun: &str) -> String {
    format!("{n} {noun}{}", if n == 1 { "" } else { "s" })
}

fn signal_name(signal: usize) -> String {
    match signal {
        2 => "SIGINT".into(),
        15 => "SIGTERM".into(),
        n => format!("signal {n}"),
    }
}

/// A word for a shell command line: as is when it holds nothing the shell would read,
/// else single-quoted.
fn shell_word(word: &str) -> String {
    let plain = !word.is_empty()
        && word
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c));
    if plain {
        word.to_owned()
    } else if let Some(flag) = word.strip_prefix("--set ") {
        format!("--set {}", shell_word(flag))
    } else {
        format!("'{}'", word.replace('\'', "'\\''"))
    }
}

pub fn merge(args: MergeArgs) -> Result<()> {
    prepare_output(&args.out, args.force)?;
    let experiments = merge::merge(&args.dirs, &args.out, args.format.into())?;
    for e in experiments.iter().filter(|e| !e.name.is_empty()) {
        println!(
            "{}: {} runs → {}",
            e.name,
            e.runs(),
            args.out.join(&e.name).display()
        );
    }
    println!(
        "merged {} shard folders: {} runs → {}",
        args.dirs.len(),
        experiments.iter().map(Experiment::runs).sum::<usize>(),
        args.out.display()
    );
    Ok(())
}

pub fn report(args: ReportArgs) -> Result<()> {
    make_report(&args.dir, args.jobs)
}

/// `robokey report` on `dir`: prints the headline findings and where the report is.
fn make_report(dir: &Path, jobs: usize) -> Result<()> {
    let started = Instant::now();
    let made = with_jobs(jobs, || report::report(dir))??;
    print!("{}", made.summary);
    println!("report: {}", made.path.display());
    println!("reported in {:.2} s", started.elapsed().as_secs_f64());
    Ok(())
}

pub fn reproduce(args: ReproduceArgs) -> Result<Status> {
    let experiments = paper_suite(args.quick)?;
    let (out, resume) = output(&args.out, args.resume.as_deref(), args.force)?;
    let stop = on_signals()?;
    let plan = SweepPlan {
        shard: None,
        resume,
        format: TableFormat::Csv,
    };
    let swept = sweep_into(&out, &experiments, plan, args.jobs, &stop)?;
    let mut again = vec!["robokey".to_owned(), "reproduce".into()];
    if args.quick {
        again.push("--quick".into());
    }
    let status = finish(&swept, &out, again);
    if status != Status::Success {
        return Ok(status);
    }
    let started = Instant::now();
    match with_jobs(args.jobs, || compute_stages(&out, args.quick, &stop))? {
        Ok(times) => {
            let parts: Vec<String> = times
                .iter()
                .map(|(stage, seconds)| format!("{stage} {seconds:.2} s"))
                .collect();
            println!(
                "computed the report's stages in {:.2} s (side by side: {})",
                started.elapsed().as_secs_f64(),
                parts.join(", ")
            );
        }
        Err(LabError::Interrupted(signal)) => {
            eprintln!(
                "interrupted by {} while computing the report's stages; the sweep is complete: \
                 `robokey reproduce --resume {}{}` computes them and writes the report",
                signal_name(signal),
                shell_word(&out.display().to_string()),
                if args.quick { " --quick" } else { "" }
            );
            return Ok(Status::Interrupted(signal));
        }
        Err(e) => return Err(e.into()),
    }
    make_report(&out, args.jobs)?;
    Ok(Status::Success)
}

pub fn config(args: ConfigArgs) -> Result<()> {
    let config = load_config(args.config.as_deref(), &args.options.set)?;
    print!("{}", robokey_lab::config_doc::annotated_toml(&config));
    Ok(())
}

pub fn secrecy(args: SecrecyArgs) -> Result<()> {
    use robokey::config::SensingMode;
    use robokey_lab::report::private::break_even_text;
    use robokey_lab::report::secrecy::write_secrecy;
    use robokey_lab::run::sessions::SessionBank;
    use robokey_lab::secrecy::{Secrecy, SecrecyRequest};
    let request = SecrecyRequest {
        adversaries: args.adversaries.iter().map(|&a| a.into()).collect(),
        epsilon: args.eps,
        block_bits: args.block,
        blocks: args.blocks,
        pooling: args.pooling.map(Into::into),
        sample_bits: args.sample_bits,
        max_sessions: args.max_sessions,
        assumed_eve_error: args.assume_eve_error,
        sizing: args.sizing.map(Into::into),
        reconciliation: args.reconciliation.map(Into::into),
        llrs: args.llrs.map(Into::into),
    };
    if let Err(e) = request.validate() {
        usage!("{}", e.message(&format!("{} {}", e.option.flag(), e.value)));
    }
    // A sweep folder, or a suite folder whose subfolders are sweeps.
    let folders =
        layout::experiment_dirs(&args.sweep_dir)?.unwrap_or_else(|| vec![args.sweep_dir.clone()]);
    // Every folder's options resolved, and refused, before any is computed.
    let mut analyses = Vec::with_capacity(folders.len());
    for folder in folders {
        let experiment = layout::read_experiment(&folder, &layout::folder_name(&folder))?;
        match request.options(&experiment) {
            Ok(options) => analyses.push((folder, experiment, options)),
            Err(e) => usage!(
                "{}: {}",
                folder.display(),
                e.message(&format!("{} {}", e.option.flag(), e.value))
            ),
        }
    }
    let started = Instant::now();
    for (folder, experiment, options) in analyses {
        if !experiment.points[0].config.protocol.enabled {
            println!("{}: protocol off, no key: skipped", folder.display());
            continue;
        }
        let mode = experiment.points[0].config.sensing.mode;
        let secrecy = with_jobs(args.jobs, || {
            Secrecy::compute(&experiment, &options, &mut SessionBank::new())
        })??;
        let mut files = secrecy.write(&folder)?;
        files.extend(write_secrecy(
            &folder,
            &experiment,
            &secrecy,
            args.format.into(),
        )?);
        let (results, map) = (&secrecy.results, &secrecy.map);
        println!("{}:", folder.display());
        if let Some(reason) = results.iter().find_map(|r| r.structural_zero.as_deref()) {
            print!("{}", wrapped(&format!("secret key rate 0: {reason}")));
        }
        if let Some(first) = results
            .first()
            .filter(|_| args.assume_eve_error.is_some() || mode == SensingMode::Private)
        {
            print!(
                "{}",
                wrapped(
                    &if results.iter().all(|r| r.assumption == first.assumption) {
                        format!("key sized under: {}", first.assumption)
                    } else {
                        format!(
                            "key sized under each point's own assumption (column `assumption` of \
                         secrecy.csv), e.g.: {}",
                            first.assumption
                        )
                    }
                )
            );
        }
        print!("{}", secrecy_table(results));
        for sentence in robokey_lab::report::world::over_claim_sentences(
            &robokey_lab::report::world::over_claims(&experiment, results),
        ) {
            print!("{}", wrapped(&sentence));
        }
        if let Some(map) = &map {
            for curve in &map.camera {
                print!(
                    "{}",
                    wrapped(&format!(
                        "break-even camera noise, {}: {}",
                        curve.label,
                        break_even_text(curve)
                    ))
                );
            }
            if map.pareto.len() > 1
                && let Some(best) = map
                    .pareto
                    .iter()
                    .filter(|p| p.on_front)
                    .max_by(|a, b| a.bits_per_second.total_cmp(&b.bits_per_second))
            {
                print!(
                    "{}",
                    wrapped(&format!(
                        "best rate: {:.3} secret bits/s at {} (J_x {:.1} mm; the paper's \
                         scheme: 0 at J_x {:.1} mm)",
                        best.bits_per_second, best.point, best.jx_mm, map.paper_jx_mm
                    ))
                );
            }
        }
        let names: Vec<String> = files
            .iter()
            .filter_map(|f| f.strip_prefix(&folder).ok())
            .map(|f| f.display().to_string())
            .collect();
        print!(
            "{}",
            wrapped(&format!(
                "wrote {} (every detail: secrecy.md)",
                names.join(", ")
            ))
        );
    }
    println!("done in {:.2} s", started.elapsed().as_secs_f64());
    Ok(())
}

/// Terminal width the long lines are wrapped to.
const TERMINAL_COLUMNS: usize = 100;

/// A sentence wrapped to [`TERMINAL_COLUMNS`], indented by two spaces (four after its
/// first line).
fn wrapped(text: &str) -> String {
    crate::wrap::wrap(text, " ", "   ", TERMINAL_COLUMNS)
}

/// The secrecy results for the terminal: one line per point and adversary, each reason why
/// a realised ℓ is what it is once below the table, warnings wrapped. secrecy.md keeps the
/// detail (messages, H_min, intervals, assumptions).
fn secrecy_table(results: &[robokey_lab::secrecy::PointSecrecy]) -> String {
    let mut notes: Vec<String> = Vec::new();
    let mut rows: Vec<[String; 8]> = vec![
        [
            "point",
            "adversary",
            "raw b/step",
            "Eve wrong",
            "leak EC+tags",
            "ℓ bits",
            "ℓ b/s",
            "realised ℓ",
        ]
        .map(String::from),
    ];
    for r in results {
        let note = r
            .zero_reason
            .clone()
            .unwrap_or_else(|| "holds only under the stated assumption".into());
        let index = notes.iter().position(|n| *n == note).unwrap_or_else(|| {
            notes.push(note);
            notes.len() - 1
        });
        let leak =
            |f: fn(&robokey_lab::secrecy::Block) -> u64| -> u64 { r.blocks.iter().map(f).sum() };
        rows.push([
            r.point.clone(),
            format!("{} ({})", r.adversary, r.adversary_class.name()),
            format!("{:.4}", r.raw_bits_per_step),
            r.eve_error_accepted
                .map_or("–".into(), |x| format!("{:.3} %", 100.0 * x.rate)),
            format!("{}+{}", leak(|b| b.leak_ec), leak(|b| b.leak_confirmation)),
            r.secret_bits.to_string(),
            format!("{:.4}", r.secret_bits_per_second),
            format!("{} [{}]", r.realised_secret_bits, index + 1),
        ]);
    }
    let mut widths = [0; 8];
    for row in &rows {
        for (width, cell) in widths.iter_mut().zip(row) {
            *width = (*width).max(cell.chars().count());
        }
    }
    let mut out = String::new();
    for row in &rows {
        let mut line = String::new();
        for (i, (cell, &width)) in row.iter().zip(&widths).enumerate() {
            let pad = " ".repeat(width - cell.chars().count());
            // Names left, numbers right.
            if i < 2 {
                line.push_str(&format!("  {cell}{pad}"));
            } else {
                line.push_str(&format!("  {pad}{cell}"));
            }
        }
        out.push_str(line.trim_end());
        out.push('\n');
    }
    for (i, note) in notes.iter().enumerate() {
        out.push_str(&wrapped(&format!("[{}] realised ℓ: {note}", i + 1)));
    }
    for r in results.iter().filter(|r| r.assumption_exceeds_realised) {
        out.push_str(&wrapped(&format!(
            "WARNING: the assumption credits {} bits at {}, more than the {} Eve's realised view \
             supports ({}): this adversary violates it",
            r.secret_bits, r.point, r.adversary, r.realised_secret_bits
        )));
    }
    out.push_str(&world_blocks(results));
    out.push_str(&measured_blocks(results));
    out
}

/// Measured sizing (docs/estimation.md): what the controller measured for each block, and
/// the separation that sized it, or why the block was refused.
fn measured_blocks(results: &[robokey_lab::secrecy::PointSecrecy]) -> String {
    let mut out = String::new();
    for r in results {
        for (i, b) in r.blocks.iter().enumerate() {
            let Some(e) = &b.estimate else { continue };
            let three = |s: [f64; 3]| format!("{:.3} mm, {:.3} mm, {:.3} mrad", s[0], s[1], s[2]);
            out.push_str(&wrapped(&match &e.refused {
                Some(why) => format!(
                    "{}, {}: block {} refused ({} doublets): {why}",
                    r.point,
                    r.adversary,
                    i + 1,
                    e.doublets
                ),
                None => {
                    format!(
                        "{}, {}: block {}: motion noise measured over {} doublets: √Q̂ = {} \
                     (along-track, lateral, heading), AR(1) correlation between steps ρ̂ = \
                     {:.3}; worst case of its (1 − {:e}) region: ρ in [{:.3}, {:.3}], √Q_low \
                     = {} at ρ = {:.3}; Eve's largest separation there {:.4}, her bits' \
                     equivalent {:.4} (published); ℓ = {} bits",
                        r.point,
                        r.adversary,
                        i + 1,
                        e.doublets,
                        three(e.point_std_mm),
                        e.correlation,
                        e.epsilon,
                        e.correlation_interval[0],
                        e.correlation_interval[1],
                        three(e.lower_std_mm),
                        e.correlation_interval[1],
                        e.largest,
                        e.separation,
                        b.secret_bits
                    ) + &slip_record(e)
                        + &jitter_record(e)
                }
            }));
        }
    }
    out
}

/// A block sized with the slip it measured (docs/estimation.md, "Per-wheel slip"): the slip
/// and its interval; nothing for the others.
fn slip_record(e: &robokey::estimate::BlockEstimate) -> String {
    match e.slip {
        Some([point, low, high]) if e.slip_sized => format!(
            "; per-wheel slip measured σ̂ = {:.2} % of each wheel's travel [{:.2} %, {:.2} %] at \
             ε_est/3, Eve's bits sized as pairs of Gaussians with their own covariances (the \
             published separation bounds no more than they do)",
            100.0 * point,
            100.0 * low,
            100.0 * high
        ),
        _ => String::new(),
    }
}

/// A block's sample-timing jitter measured (docs/estimation.md, "Sample-timing jitter"):
/// its point and interval, and where each end went (a three-step block's Eve's view takes
/// the controller's samples with the sensor's noise alone, below the lower end).
fn jitter_record(e: &robokey::estimate::BlockEstimate) -> String {
    let view = if e.lag.is_some() {
        "Eve's view with none (below its lower end)"
    } else {
        "its lower end in Eve's view"
    };
    match e.jitter.as_deref() {
        Some(&[point, low, high]) => format!(
            "; the controller's sample-timing jitter ĵ = {:.2} ms [{:.2} ms, {:.2} ms] at \
             ε_est/10, its upper end under Q, {view}",
            1e3 * point,
            1e3 * low,
            1e3 * high
        ),
        None => String::new(),
    }
}

/// Where a point's world is not the parties' (docs/world.md): for each block, ℓ beside the
/// realised bound of the eavesdropper who knows the world, and a WARNING naming the world's
/// parameters wherever ℓ exceeds it.
fn world_blocks(results: &[robokey_lab::secrecy::PointSecrecy]) -> String {
    let mut out = String::new();
    let camera = robokey::config::EveStrategy::Camera.name();
    for r in results
        .iter()
        .filter(|r| !r.world_differences.is_empty() && r.adversary == camera)
    {
        let world = r.world_differences.join("; ");
        out.push_str(&wrapped(&format!(
            "{}, {} Eve who knows the world ({world}):",
            r.point, r.adversary
        )));
        for (i, b) in r.blocks.iter().enumerate() {
            let verdict = if b.assumption_exceeds_realised {
                "EXCEEDS"
            } else {
                "within"
            };
            out.push_str(&format!(
                "    block {}: ℓ {} bits, her realised bound {} bits ({verdict}; {} raw bits)\n",
                i + 1,
                b.secret_bits,
                b.realised.secret_bits,
                b.bits
            ));
            if b.assumption_exceeds_realised {
                out.push_str(&wrapped(&format!(
                    "WARNING: block {} at {}: ℓ = {} bits exceeds the {} bits the {} \
                     eavesdropper's realised view supports in a world the parties' \
                     configuration does not describe: {world}",
                    i + 1,
                    r.point,
                    b.secret_bits,
                    b.realised.secret_bits,
                    r.adversary
                )));
            }
        }
    }
    out
}
