//! The "Private sensing" section of `reproduce` (docs/private-sensing.md): a coarse version of
//! `experiments/private-sensing.toml` — the secret rate against Eve's camera noise with its
//! break-even, and the rate against tracking cost over Δv — whose sentences come from the
//! computed numbers.

use std::fmt::Write as _;
use std::path::Path;

use robokey::config::{EveStrategy, parse_table};
use robokey::interrupt::Interrupt;

use crate::error::LabError;
use crate::experiment::{Experiment, experiments_from_table};
use crate::folder::sweep::{SweepPlan, sweep};
use crate::secrecy::map::{CAMERA_FIELD, PrivateMap, private_map};
use crate::secrecy::render_private::break_even_text;
use crate::secrecy::{PointSecrecy, Pooling, SecrecyOptions, analyze, write_secrecy};

/// The full map, embedded: `reproduce` computes a coarse version of it.
pub const PRIVATE_SENSING_TOML: &str = include_str!("../../../experiments/private-sensing.toml");

/// What the section costs on the 2-core reference machine (s), stated in the report.
pub const BUDGET_SECONDS: u32 = 30;

/// Eve's camera noise (mm) and motion noise (mm) of the coarse map; fewer with `--quick`.
fn coarse_grid(quick: bool) -> (&'static [f64], &'static [f64]) {
    if quick {
        (&[2.0, 4.0, 8.0], &[4.0])
    } else {
        (&[1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 16.0], &[2.0, 4.0])
    }
}

fn millimetres(values: &[f64]) -> toml::Value {
    toml::Value::Array(
        values
            .iter()
            .map(|&mm| toml::Value::Array(vec![(mm / 1e3).into(); 3]))
            .collect(),
    )
}

/// The embedded suite with its axes made coarse: the camera map, and the Δv front with one
/// bit per doublet at three values.
fn coarse_suite(quick: bool) -> Result<Vec<Experiment>, LabError> {
    let origin = "experiments/private-sensing.toml";
    let mut table = parse_table(PRIVATE_SENSING_TOML, origin)?;
    let (camera, motion) = coarse_grid(quick);
    let suite = table
        .get_mut("experiment")
        .and_then(toml::Value::as_table_mut)
        .ok_or_else(|| LabError::Sweep {
            origin: origin.into(),
            message: "no [experiment.*] tables".into(),
        })?;
    suite.remove("pareto-v-omega");
    let mut axis = |experiment: &str, field: &str, value: toml::Value| {
        suite
            .get_mut(experiment)
            .and_then(|e| e.get_mut("sweep"))
            .and_then(toml::Value::as_table_mut)
            .map(|sweep| sweep.insert(field.into(), value))
            .ok_or_else(|| LabError::Sweep {
                origin: origin.into(),
                message: format!("no [experiment.{experiment}.sweep]"),
            })
    };
    axis("camera", CAMERA_FIELD, millimetres(camera))?;
    axis("camera", "noise.process_std", millimetres(motion))?;
    axis(
        "pareto-v",
        "protocol.delta_v",
        toml::Value::Array(vec![0.02.into(), 0.035.into(), 0.05.into()]),
    )?;
    experiments_from_table(table, origin)
}

/// The results of one experiment of the section.
struct Computed {
    experiment: Experiment,
    results: Vec<PointSecrecy>,
    map: Option<PrivateMap>,
    options: SecrecyOptions,
}

fn compute(out: &Path, experiment: Experiment, stop: &Interrupt) -> Result<Computed, LabError> {
    let plan = SweepPlan {
        shard: None,
        resume: false,
    };
    let swept = sweep(
        out,
        std::slice::from_ref(&experiment),
        plan,
        stop,
        &mut |_| {},
        &|| {},
    )?;
    if let Some(signal) = swept.interrupted {
        return Err(LabError::Interrupted(signal));
    }
    let dir = out.join(&experiment.name);
    let defaults = SecrecyOptions::default();
    let mut adversaries = vec![EveStrategy::Camera];
    if experiment.name != "camera" {
        adversaries.push(EveStrategy::Commands);
    }
    let options = SecrecyOptions {
        adversaries,
        pooling: Pooling::Complete,
        block_bits: experiment
            .secrecy
            .block_bits
            .map_or(defaults.block_bits, |b| b as usize),
        epsilon: experiment.secrecy.epsilon.unwrap_or(defaults.epsilon),
        ..defaults
    };
    let results = analyze(&experiment, &options)?;
    let map = private_map(&experiment, &results)?;
    write_secrecy(&dir, &experiment, &results, &options, map.as_ref())?;
    Ok(Computed {
        experiment,
        results,
        map,
        options,
    })
}

/// The section's markdown and its terminal summary; files go to `out/private-sensing/`.
///
/// # Errors
/// A file cannot be written, the embedded suite is inconsistent, or the stop was requested.
pub fn private_section(
    out: &Path,
    quick: bool,
    stop: &Interrupt,
) -> Result<(String, String), LabError> {
    let out = out.join("private-sensing");
    let computed: Vec<Computed> = coarse_suite(quick)?
        .into_iter()
        .map(|e| compute(&out, e, stop))
        .collect::<Result<_, _>>()?;
    let find = |name: &str| {
        computed
            .iter()
            .find(|c| c.experiment.name == name)
            .ok_or_else(|| LabError::Merge(format!("no [experiment.{name}] computed")))
    };
    let camera = find("camera")?;
    let front = find("pareto-v")?;
    let mut md = String::from("\n## Private sensing: a key that is secret, and against whom\n\n");
    let mut terminal = String::new();
    // The defaults: Δv = 0.035 on the front experiment, camera adversary.
    let default = front.results.iter().find(|r| {
        r.adversary == EveStrategy::Camera.name()
            && (front.experiment.points[r.point_index]
                .config
                .protocol
                .delta_v
                - 0.035)
                .abs()
                < 1e-12
    });
    let paper_jx = front.map.as_ref().map_or(f64::NAN, |m| m.paper_jx_mm);
    if let Some(d) = default {
        let jx = d.private.as_ref().map_or(f64::NAN, |p| p.jx_mm);
        let _ = writeln!(
            md,
            "The paper's scheme yields **0** secret bits by structure (everything the controller \
             decides from is public but r and D, which an eavesdropper learns). With private \
             sensing at the defaults (Δv = 0.035 m/s, one bit per doublet, motion noise 4 mm, \
             controller sensor 0.5 mm), robokey makes **{:.3} secret bits per second** \
             ({:.4} per step; blocks of {} bits, ε = {:e} per term) with J_x = {jx:.1} mm \
             (the paper's scheme: {paper_jx:.1} mm). This holds under the stated physical \
             assumption: {}.\n",
            d.secret_bits_per_second,
            d.secret_bits_per_step,
            front.options.block_bits,
            front.options.epsilon,
            d.assumption
        );
        let _ = writeln!(
            terminal,
            "private sensing: {:.3} secret bits/s at the defaults (Eve's camera ≥ 8 mm; the \
             paper's scheme: 0)",
            d.secret_bits_per_second
        );
    }
    if let Some(map) = &camera.map {
        let _ = writeln!(
            md,
            "The key exists only while Eve's camera is worse than a break-even noise, which \
             depends on the motion noise (a calibration):\n"
        );
        for curve in &map.camera {
            let _ = writeln!(md, "- {}: {}", curve.label, break_even_text(curve));
            let _ = writeln!(
                terminal,
                "  break-even camera noise, {}: {}",
                curve.label,
                break_even_text(curve)
            );
        }
        let _ = writeln!(
            md,
            "\n![rate against camera noise](private-sensing/camera/private-rate-vs-camera.svg)\n"
        );
    }
    if let Some(map) = &front.map {
        let (inside, bins) = map.leak.iter().fold((0, 0), |(inside, all), b| {
            (
                inside + usize::from(b.measured[1] <= b.predicted && b.predicted <= b.measured[2]),
                all + 1,
            )
        });
        let _ = writeln!(
            md,
            "![Pareto front](private-sensing/pareto-v/private-pareto.svg)\n\n\
             What the public commands leak is charged, not assumed away: the commands \
             eavesdropper's measured information lies within its 95 % interval of the model's \
             prediction in {inside} of {bins} turn-rate bins.\n\n\
             ![leak](private-sensing/pareto-v/private-leak.svg)\n"
        );
    }
    let _ = writeln!(
        md,
        "A coarse map, computed within a budget of about {BUDGET_SECONDS} s on 2 cores. The \
         full one is `robokey sweep experiments/private-sensing.toml` followed by \
         `robokey secrecy` on its folder. Tables: `private-sensing/*/secrecy.md`; how it \
         works: docs/private-sensing.md.\n"
    );
    Ok((md, terminal))
}
