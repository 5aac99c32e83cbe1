//! `robokey prior`: the prior a calibration run measured, as the configuration to state on
//! both agents (docs/estimation.md, "Causality"). The figures come from
//! `robokey::estimate::prior`; this reads the controller's reports and renders them.

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::Args;
use robokey::estimate::BlockEstimate;
use robokey::estimate::prior::measured_prior;
use robokey_net::agent::report::read_report;

use crate::configuration::{ConfigOptions, load_config};
use crate::exit::usage;

/// Largest report read (bytes): a session's report is tens of kilobytes.
const MAX_REPORT_BYTES: u64 = 64 << 20;

/// `robokey prior`.
#[derive(Args, Debug)]
pub struct PriorArgs {
    /// The controller's session reports (`robokey controller --report`), oldest first: the
    /// last block estimate among them names the prior.
    #[arg(required = true, value_name = "REPORT")]
    reports: Vec<PathBuf>,
    /// The parties' configuration file (TOML) to state the prior in; defaults apply to every
    /// field it leaves out.
    #[arg(long, short)]
    config: Option<PathBuf>,
    #[command(flatten)]
    options: ConfigOptions,
}

/// The block estimates of the controller's report at `path`, in the order it made them.
fn estimates(path: &Path) -> Result<Vec<BlockEstimate>> {
    let name = path.display();
    let size = match std::fs::metadata(path) {
        Ok(meta) => meta.len(),
        Err(e) => usage!("{name}: cannot read the report: {e}"),
    };
    if size > MAX_REPORT_BYTES {
        usage!("{name}: {size} bytes (allowed: a session report of at most {MAX_REPORT_BYTES})");
    }
    let report = read_report(path)?;
    if report["role"] != "controller" {
        usage!(
            "{name}: role {} (allowed: a controller's report; only the controller estimates \
             the plant)",
            report["role"]
        );
    }
    match report["post"].get("estimates") {
        None => Ok(Vec::new()),
        Some(list) => match serde_json::from_value(list.clone()) {
            Ok(list) => Ok(list),
            Err(e) => usage!("{name}: post.estimates is not a list of block estimates: {e}"),
        },
    }
}

/// `text` as comment lines of at most 95 characters.
fn comment(text: &str) -> String {
    crate::wrap::wrap(text, "#", "#", 95)
}

/// Prints the parties' configuration with the prior the reports' last block estimate names,
/// each change and what measured it as comments above it.
///
/// # Errors
/// A report cannot be read, is not a controller's, or no report holds a block estimate
/// (usage errors, exit 2); the configuration is invalid.
pub fn run(args: &PriorArgs) -> Result<()> {
    let config = load_config(args.config.as_deref(), &args.options.set)?;
    let mut last = None;
    for path in &args.reports {
        if let Some(estimate) = estimates(path)?.pop() {
            last = Some((path, estimate));
        }
    }
    let Some((path, estimate)) = last else {
        usage!(
            "no block estimate in {} (allowed: the report of a controller session that \
             estimated a block: private sensing with a --store, after a block was reconciled)",
            args.reports
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        );
    };
    let (prior, changes) = measured_prior(&config, &estimate);
    prior.validate()?;
    let mut header = format!(
        "The prior measured by the controller over {} doublets ({}, its last block \
         estimate): state it on both agents (`--config` this file) for the blocks to come. No \
         key's length rests on it; a prior far from the robot costs bits, and a lag left \
         unstated is refused (docs/estimation.md, \"Causality\").",
        estimate.doublets,
        path.display()
    );
    if let Some(why) = &estimate.refused {
        header += &format!(" That block was refused: {why}.");
    }
    let mut out = comment(&header);
    if changes.is_empty() {
        out += &comment("It measured nothing the prior holds: the configuration is unchanged.");
    }
    for change in &changes {
        out += &comment(&format!(
            "{} = {} (was {}): {}.",
            change.field, change.measured, change.stated, change.why
        ));
    }
    let flags: Vec<String> = changes
        .iter()
        .map(|c| format!("--set {}={}", c.field, c.measured.replace([' ', '"'], "")))
        .collect();
    if !flags.is_empty() {
        out += &comment(&format!("As flags: {}", flags.join(" ")));
    }
    out.push('\n');
    out += &robokey_lab::config_doc::annotated_toml(&prior);
    print!("{out}");
    Ok(())
}
