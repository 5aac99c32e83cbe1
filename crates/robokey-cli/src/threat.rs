//! `robokey threat`: what a camera of Eve's leaves of the key at a configuration (the
//! figures come from `robokey_lab::threat`; this renders them).

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use robokey::config::camera::best_phase_energy;
use robokey::world::Camera;
use robokey_lab::run::with_jobs;
use robokey_lab::threat::{BreakEven, Threat, threat};

use crate::configuration::{ConfigOptions, load_config};
use crate::exit::usage;

/// Most cameras one call evaluates (each simulates the sessions of a block).
const MAX_CAMERAS: usize = 100;

/// `robokey threat`.
#[derive(Args, Debug)]
pub struct ThreatArgs {
    /// Configuration file (TOML); defaults apply to every field it leaves out. It is
    /// evaluated in private sensing whatever its `sensing.mode`.
    #[arg(long, short)]
    config: Option<PathBuf>,
    #[command(flatten)]
    options: ConfigOptions,
    /// Eve's camera per sample instant (mm, the same for x and y, and mrad for θ), her
    /// effective noise after her own filtering: a value, a list `2,4,8` or a range
    /// `FROM:TO:STEP`.
    #[arg(long, value_name = "MM")]
    camera_std: Option<String>,
    /// Eve's camera in camera terms: frames per second (value, list or range), with
    /// --frame-std; every combination of the two is evaluated.
    #[arg(long, value_name = "FPS", requires = "frame_std")]
    fps: Option<String>,
    /// Noise of each of her frames (mm, and mrad for θ), white: value, list or range.
    #[arg(long, value_name = "MM", requires = "fps")]
    frame_std: Option<String>,
    /// Print the figures as JSON.
    #[arg(long)]
    json: bool,
    /// Worker threads (0: one per core; at most one per core). Results do not depend on it.
    #[arg(long, short, default_value_t = 0)]
    jobs: usize,
}

/// `FROM:TO:STEP` (inclusive, to a thousandth of a step) or a comma-separated list of
/// positive numbers.
fn values(flag: &str, text: &str) -> Result<Vec<f64>> {
    let number = |s: &str| -> Result<f64> {
        match s.trim().parse::<f64>() {
            Ok(x) if x.is_finite() => Ok(x),
            _ => usage!("{flag} {text}: `{s}` is not a number"),
        }
    };
    let parts: Vec<&str> = text.split(':').collect();
    let list = match parts.as_slice() {
        [from, to, step] => {
            let (from, to, step) = (number(from)?, number(to)?, number(step)?);
            if !(step > 0.0 && to >= from) {
                usage!("{flag} {text}: a range FROM:TO:STEP needs STEP > 0 and TO ≥ FROM");
            }
            let count = ((to - from) / step + 1e-3).floor() as usize + 1;
            if count > MAX_CAMERAS {
                usage!("{flag} {text}: {count} values (allowed: at most {MAX_CAMERAS})");
            }
            (0..count).map(|i| from + i as f64 * step).collect()
        }
        [_] => text.split(',').map(number).collect::<Result<Vec<_>>>()?,
        _ => usage!("{flag} {text}: a list `2,4,8` or a range FROM:TO:STEP"),
    };
    if let Some(bad) = list.iter().find(|&&x| x <= 0.0) {
        usage!("{flag} {text}: {bad} is not allowed (allowed: > 0)");
    }
    Ok(list)
}

/// The cameras the flags name, or the configuration's own statement.
fn cameras(args: &ThreatArgs, own: Camera) -> Result<Vec<Camera>> {
    let mut out = Vec::new();
    if let Some(text) = &args.camera_std {
        for mm in values("--camera-std", text)? {
            out.push(Camera::Instants {
                std: [mm * 1e-3; 3],
            });
        }
    }
    if let (Some(fps), Some(frame_std)) = (&args.fps, &args.frame_std) {
        let frame_std = values("--frame-std", frame_std)?;
        for f in values("--fps", fps)? {
            for &mm in &frame_std {
                out.push(Camera::Frames {
                    fps: f,
                    frame_std: [mm * 1e-3; 3],
                });
            }
        }
    }
    if out.len() > MAX_CAMERAS {
        usage!(
            "{} cameras asked for (allowed: at most {MAX_CAMERAS})",
            out.len()
        );
    }
    if out.is_empty() {
        out.push(own);
    }
    Ok(out)
}

/// Runs `robokey threat`.
///
/// # Errors
/// A wrong command line or configuration (exit 2), or a session that aborts.
pub fn run(args: &ThreatArgs) -> Result<()> {
    let config = load_config(args.config.as_deref(), &args.options.set)?;
    let cameras = cameras(args, config.camera_statement())?;
    let figures = with_jobs(args.jobs, || threat(&config, &cameras))??;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&figures)?);
    } else {
        print!("{}", render(&figures, &cameras));
    }
    Ok(())
}

/// The figures as text: one line per camera, then the break-even (per instant, and per
/// frame at each frame rate asked about).
fn render(figures: &Threat, cameras: &[Camera]) -> String {
    let mut text = format!(
        "private sensing at T = {} s; each key sized against the camera of its line: one \
         block of {} raw bits, ε = {:e} per term (the key is 4ε-secret)\n\n",
        figures.sample_time, figures.block_bits, figures.epsilon
    );
    let width = figures
        .cameras
        .iter()
        .map(|c| c.statement.chars().count())
        .max()
        .unwrap_or(0)
        .max(6);
    text.push_str(&format!(
        "{:<width$}  {:>17}  {:>7}  {:>11}  {:>10}\n",
        "camera", "per instant (mm)", "ℓ bits", "bits/step", "bits/s"
    ));
    let mut reasons = Vec::new();
    for c in &figures.cameras {
        let mark = c.zero_reason.as_ref().map_or(String::new(), |reason| {
            reasons.push(reason.clone());
            format!(" [{}]", reasons.len())
        });
        text.push_str(&format!(
            "{:<width$}  {:>17.2}  {:>7}  {:>11.4}  {:>10.4}{mark}\n",
            c.statement, c.per_instant_mm[0], c.secret_bits, c.bits_per_step, c.bits_per_second
        ));
    }
    for (i, reason) in reasons.iter().enumerate() {
        text.push_str(&format!("[{}] {reason}\n", i + 1));
    }
    text.push('\n');
    let mut rates: Vec<f64> = cameras
        .iter()
        .filter_map(|c| match c {
            Camera::Frames { fps, .. } => Some(*fps),
            Camera::Instants { .. } => None,
        })
        .collect();
    rates.dedup();
    let per_frame = |mm: f64, fps: f64| mm * best_phase_energy(fps, figures.sample_time).sqrt();
    match figures.break_even {
        BreakEven::Between {
            zero_at_mm,
            positive_at_mm,
        } => {
            text.push_str(&format!(
                "break-even camera: between {zero_at_mm:.2} mm (no secret bit) and \
                 {positive_at_mm:.2} mm (secret bits) per instant\n"
            ));
            for fps in rates {
                text.push_str(&format!(
                    "  at {fps} frames/s: between {:.2} and {:.2} mm per frame\n",
                    per_frame(zero_at_mm, fps),
                    per_frame(positive_at_mm, fps)
                ));
            }
        }
        BreakEven::Below { mm } => text.push_str(&format!(
            "break-even camera: below {mm} mm per instant (even that camera leaves secret bits)\n"
        )),
        BreakEven::Above { mm } => text.push_str(&format!(
            "break-even camera: above {mm} mm per instant (even that camera leaves no secret bit)\n"
        )),
    }
    text
}
