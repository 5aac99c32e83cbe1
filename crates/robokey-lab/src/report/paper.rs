//! The paper's report (docs/experiments.md): from the folders of a sweep of
//! `experiments/paper.toml` and the stages `reproduce` computed into it, figures and a
//! `report.md` whose sentences are driven by computed trend tests.

use std::fmt::Write as _;
use std::path::Path;

use robokey::sim::TraceRow;
use robokey_secrecy::interval::clopper_pearson;

use super::Report;
use super::figures::{box_chart, boxes, fmt, median_of, trajectory_figure};
use super::paper_sections::{MapPart, adversary_section, private_section, secrecy_section};
use super::trend::{trend, trend_line, trend_sentence};
use crate::adversary::Campaign;
use crate::error::LabError;
use crate::experiment::Experiment;
use crate::folder::layout::read_experiment;
use crate::folder::load::Loaded;
use crate::output::write;
use crate::plot::{BoxGroup, Interval, LineChart, Series, SeriesStyle};
use crate::reproduce::private_suite::{CAMERA_EXPERIMENT, FRONT_EXPERIMENT, PRIVATE_SENSING_DIR};
use crate::reproduce::suite::{PAPER_EXPERIMENTS, paper_suite};
use crate::reproduce::world_suite::{WORLDS_DIR, coarse_suite};
use crate::reproduce::{EVE_DIR, Reproduction, SECRECY_EXPERIMENTS};
use crate::run::RunRow;
use crate::secrecy::Secrecy;
use crate::stats::Summary;

/// What `reproduce` computed into a folder of the paper's suite, read back.
pub(super) struct PaperStages {
    /// With the small grids of `reproduce --quick`.
    quick: bool,
    /// The secrecy of the sweeps of [`SECRECY_EXPERIMENTS`], with their headings.
    secrecy: Vec<(Experiment, Secrecy, &'static str)>,
    /// The eavesdropping campaigns.
    campaign: Campaign,
    /// The private-sensing map: against Eve's camera noise, and over Δv.
    camera: MapPart,
    front: MapPart,
    /// The worlds the parties' configuration does not describe (absent in a reproduction
    /// made before worlds existed).
    worlds: Vec<MapPart>,
}

impl PaperStages {
    /// Reads the stages of the paper's suite folder `out`, whose experiments are `loaded`.
    ///
    /// # Errors
    /// [`LabError::Uncomputed`] when `reproduce.json` does not vouch for them; a stage's file
    /// that does not read back.
    pub(super) fn read(out: &Path, loaded: &[Loaded]) -> Result<Self, LabError> {
        let Some(Reproduction { quick }) = Reproduction::read(out)? else {
            let swept_as = |quick: bool| {
                paper_suite(quick).is_ok_and(|suite| {
                    suite.iter().all(|e| {
                        loaded.iter().any(|l| {
                            l.experiment.name == e.name
                                && l.experiment.resolved_toml() == e.resolved_toml()
                        })
                    })
                })
            };
            let command = |quick: bool| {
                format!(
                    "compute them with `robokey reproduce --resume {}{}`",
                    out.display(),
                    if quick { " --quick" } else { "" }
                )
            };
            let how = if swept_as(false) {
                command(false)
            } else if swept_as(true) {
                command(true)
            } else {
                "it was not swept as `robokey reproduce` sweeps experiments/paper.toml (10 \
                 replicates per point, or 3 with --quick), so `reproduce --resume` cannot \
                 continue it"
                    .to_owned()
            };
            return Err(LabError::Uncomputed {
                dir: out.to_path_buf(),
                how,
            });
        };
        let secrecy = SECRECY_EXPERIMENTS
            .iter()
            .map(|&(name, title)| {
                let experiment = loaded
                    .iter()
                    .find(|l| l.experiment.name == name)
                    .map(|l| l.experiment.clone())
                    .ok_or_else(|| LabError::NotSweep(out.join(name)))?;
                let secrecy = Secrecy::read(&out.join(name), &experiment)?;
                Ok((experiment, secrecy, title))
            })
            .collect::<Result<_, LabError>>()?;
        let part = |name: &str| -> Result<MapPart, LabError> {
            let dir = out.join(PRIVATE_SENSING_DIR).join(name);
            let experiment = read_experiment(&dir, name)?;
            let secrecy = Secrecy::read(&dir, &experiment)?;
            Ok(MapPart {
                experiment,
                secrecy,
            })
        };
        let worlds_dir = out.join(WORLDS_DIR);
        let worlds = if worlds_dir.exists() {
            coarse_suite(quick)?
                .iter()
                .map(|e| {
                    let dir = worlds_dir.join(&e.name);
                    let experiment = read_experiment(&dir, &e.name)?;
                    let secrecy = Secrecy::read(&dir, &experiment)?;
                    Ok(MapPart {
                        experiment,
                        secrecy,
                    })
                })
                .collect::<Result<_, LabError>>()?
        } else {
            Vec::new()
        };
        Ok(Self {
            quick,
            secrecy,
            campaign: Campaign::read(&out.join(EVE_DIR))?,
            camera: part(CAMERA_EXPERIMENT)?,
            front: part(FRONT_EXPERIMENT)?,
            worlds,
        })
    }
}

/// The values of one metric per run (undefined runs skipped), with the run's parameter.
fn column(
    experiment: &Experiment,
    records: &[RunRow],
    field: &str,
    metric: impl Fn(&robokey::Metrics) -> Option<f64>,
) -> Vec<(f64, f64)> {
    records
        .iter()
        .filter_map(|r| {
            let x = experiment.points[r.point]
                .params
                .iter()
                .find(|(f, _)| f == field)
                .and_then(|(_, v)| v.as_float())?;
            Some((x, metric(&r.metrics)?))
        })
        .collect()
}

/// Who decides a bit of the joint counts `n_acc`, indexed s·4 + ŝc·2 + ŝa.
#[derive(Clone, Copy)]
enum Decider {
    /// The controller: ŝc.
    Controller,
    /// Eve: ŝa.
    Eve,
}

impl Decider {
    /// Whether the decider is wrong (its bit differs from s) at joint-count index `i`.
    fn wrong(self, i: usize) -> bool {
        let decided = match self {
            Self::Controller => (i >> 1) & 1,
            Self::Eve => i & 1,
        };
        (i >> 2) != decided
    }
}

/// The error of `decider` on the accepted key bits per value of `field` (× 100, as %),
/// pooled over the runs: `(x, rate %, low %, high %)` with a two-sided 95 % Clopper–Pearson
/// interval, from the joint counts `n_acc` (s, ŝc, ŝa) of each run.
fn accepted_errors(
    experiment: &Experiment,
    records: &[RunRow],
    field: &str,
    decider: Decider,
) -> Vec<(f64, f64, f64, f64)> {
    let mut pooled: Vec<(f64, u64, u64)> = Vec::new();
    for r in records {
        let Some(x) = experiment.points[r.point]
            .params
            .iter()
            .find(|(f, _)| f == field)
            .and_then(|(_, v)| v.as_float())
        else {
            continue;
        };
        let Some(counts) = r.metrics.n_acc else {
            continue;
        };
        let wrong: u64 = (0..8)
            .filter(|&i| decider.wrong(i))
            .map(|i| counts[i])
            .sum();
        let total: u64 = counts.iter().sum();
        match pooled.iter_mut().find(|p| p.0 == 100.0 * x) {
            Some(p) => {
                p.1 += wrong;
                p.2 += total;
            }
            None => pooled.push((100.0 * x, wrong, total)),
        }
    }
    pooled
        .into_iter()
        .filter_map(|(x, wrong, total)| {
            let ci = clopper_pearson(wrong, total, 0.95).ok()?;
            Some((
                x,
                100.0 * wrong as f64 / total as f64,
                100.0 * ci.lower,
                100.0 * ci.upper,
            ))
        })
        .collect()
}

/// The paper's report from its suite's folders (`loaded`, holding every experiment of
/// [`PAPER_EXPERIMENTS`]) and the stages `reproduce` computed into `out`. Its sections are
/// drawn side by side on the current rayon pool, then written in order.
pub(super) fn paper_report(
    out: &Path,
    loaded: &[Loaded],
    stages: &PaperStages,
) -> Result<Report, LabError> {
    let secrecy: Vec<(&Experiment, &Secrecy, &str)> = stages
        .secrecy
        .iter()
        .map(|(experiment, secrecy, title)| (experiment, secrecy, *title))
        .collect();
    let private_out = out.join(PRIVATE_SENSING_DIR);
    let ((sweeps, secrecy), ((adversaries, private), worlds)) = rayon::join(
        || {
            rayon::join(
                || sweep_sections(out, loaded, stages.quick),
                || secrecy_section(out, &secrecy),
            )
        },
        || {
            rayon::join(
                || {
                    rayon::join(
                        || adversary_section(&out.join(EVE_DIR), &stages.campaign),
                        || private_section(&private_out, &stages.camera, &stages.front),
                    )
                },
                || super::paper_sections::world_section(&out.join(WORLDS_DIR), &stages.worlds),
            )
        },
    );
    let (mut md, mut terminal) = (String::new(), String::new());
    for (section, lines) in [sweeps?, secrecy?, adversaries?, private?, worlds?] {
        md.push_str(&section);
        terminal.push_str(&lines);
    }
    let path = write(&out.join("report.md"), md)?;
    Ok(Report {
        path,
        summary: terminal,
    })
}

/// The sections of the sweeps: key agreement against Δv, Eve against α, the trajectory,
/// the deviations from the paper; their figures go to `out/figures`. Markdown and terminal
/// lines.
fn sweep_sections(
    out: &Path,
    loaded: &[Loaded],
    quick: bool,
) -> Result<(String, String), LabError> {
    let find = |name: &str| {
        loaded
            .iter()
            .find(|l| l.experiment.name == name)
            .map(|l| (&l.experiment, l.rows.as_slice(), &l.traces))
            .ok_or_else(|| LabError::NotSweep(out.join(name)))
    };
    let (dv, dv_runs, _) = find(PAPER_EXPERIMENTS[0])?;
    let (eve, eve_runs, _) = find(PAPER_EXPERIMENTS[1])?;
    let (_, baseline_runs, _) = find(PAPER_EXPERIMENTS[2])?;
    let (trajectory, _, trajectory_traces) = find(PAPER_EXPERIMENTS[3])?;
    let figures = out.join("figures");
    std::fs::create_dir_all(&figures).map_err(crate::error::io_at(&figures))?;

    // Figure: accepted % and correct % against Δv.
    let dv_field = "protocol.delta_v";
    let accepted = column(dv, dv_runs, dv_field, |m| m.accepted_pct);
    let correct = column(dv, dv_runs, dv_field, |m| m.correct_pct);
    let jx = column(dv, dv_runs, dv_field, |m| Some(1000.0 * m.jx));
    let ber = column(dv, dv_runs, dv_field, |m| {
        m.ber_controller.map(|b| 100.0 * b)
    });
    let baseline_jx: Vec<f64> = baseline_runs
        .iter()
        .map(|r| 1000.0 * r.metrics.jx)
        .collect();
    let baseline_median = median_of(&baseline_jx);
    box_chart(
        "Accepted codewords against Δv",
        "Δv (m/s)",
        "accepted (%)",
        vec![BoxGroup {
            label: "accepted %".into(),
            boxes: boxes(&accepted),
        }],
        Vec::new(),
        &figures.join("dv-acceptance"),
    )?;
    // On its own axis: near 100 %, it would be squashed beside the accepted share.
    box_chart(
        "Correct accepted key bits against Δv",
        "Δv (m/s)",
        "correct (%)",
        vec![BoxGroup {
            label: "correct %".into(),
            boxes: boxes(&correct),
        }],
        Vec::new(),
        &figures.join("dv-correct"),
    )?;
    box_chart(
        "Tracking error Jₓ against Δv",
        "Δv (m/s)",
        "Jₓ (mm)",
        vec![BoxGroup {
            label: "Jₓ, protocol on".into(),
            boxes: boxes(&jx),
        }],
        baseline_median
            .map(|m| ("protocol off (median)".to_owned(), m))
            .into_iter()
            .collect(),
        &figures.join("dv-jx"),
    )?;
    let alpha_field = "eve.alpha";
    let disagreement: Vec<(f64, f64)> =
        column(eve, eve_runs, alpha_field, |m| m.eve_disagreement_pct)
            .into_iter()
            .map(|(a, d)| (100.0 * a, d))
            .collect();
    // Side by side at each α (dodged by ±0.15 %), so that neither interval hides the other.
    let eve_errors = accepted_errors(eve, eve_runs, alpha_field, Decider::Eve);
    let accepted_series = |decider, label: String, dodge: f64| {
        let errors = match decider {
            Decider::Eve => eve_errors.clone(),
            Decider::Controller => accepted_errors(eve, eve_runs, alpha_field, decider),
        };
        Series {
            intervals: errors
                .iter()
                .map(|&(x, _, low, high)| Interval { x, low, high })
                .collect(),
            dodge,
            ..Series::new(
                label,
                errors.iter().map(|&(x, rate, ..)| (x, rate)).collect(),
                SeriesStyle::Line,
            )
        }
    };
    LineChart {
        title: "Error on the accepted key bits against Eve's model error α".into(),
        x_label: "α (%)".into(),
        y_label: "wrong on accepted bits (%), 95 % Clopper–Pearson".into(),
        series: vec![
            accepted_series(
                Decider::Eve,
                format!("Eve (pooled over {} runs per α)", eve.replicates()),
                -0.15,
            ),
            accepted_series(
                Decider::Controller,
                format!("controller (pooled over {} runs per α)", eve.replicates()),
                0.15,
            ),
        ],
        equal_aspect: false,
        log_y: false,
    }
    .save(&figures.join("eve-error-accepted"))
    .map_err(|e| LabError::Plot {
        path: figures.join("eve-error-accepted"),
        message: e.to_string(),
    })?;
    let lap_steps = trajectory.points[0]
        .config
        .trajectory
        .waypoints
        .len()
        .saturating_sub(1) as f64
        * trajectory.points[0].config.trajectory.side_time
        / trajectory.points[0].config.robot.sample_time;
    let traces: Vec<(&str, &[TraceRow])> = trajectory_traces
        .iter()
        .filter_map(|(&point, paths)| {
            let on = trajectory.points[point].config.protocol.enabled;
            Some((
                if on {
                    "robot, protocol on (Δv = 0.035 m/s)"
                } else {
                    "robot, protocol off"
                },
                paths.first()?.as_slice(),
            ))
        })
        .collect();
    trajectory_figure(
        &figures.join("trajectory"),
        &traces,
        Some(lap_steps.round() as usize),
    )?;

    // Tests and report.
    let accepted_trend = trend(&accepted);
    let correct_trend = trend(&correct);
    let jx_trend = trend(&jx);
    let eve_trend = trend(&disagreement);
    let mut md = String::new();
    let replicates = dv.replicates();
    let _ = writeln!(
        md,
        "# robokey — reproduction of Naseri, Lucia, Youssef (IFAC 2023)\n"
    );
    let _ = writeln!(
        md,
        "Generated by `robokey report{q}` from a sweep of experiments/paper.toml (`robokey \
         reproduce{q}` runs both; robokey v{}, commit {}), seed {}, {} replicates per point, \
         replicate seeds shared by all points (common random numbers). Box plots: median, \
         quartiles (linear interpolation), whiskers at min and max. Trend tests: Spearman's ρ over \
         all runs with a two-sided permutation p-value.\n",
        env!("CARGO_PKG_VERSION"),
        env!("ROBOKEY_GIT_COMMIT"),
        dv.points[0].config.run.seed,
        replicates,
        q = if quick { " --quick" } else { "" },
    );
    let _ = writeln!(
        md,
        "**Noise calibration.** The plant's true noise (process std 4 mm, 4 mm, 4 mrad; odometry std 0.5 mm, 0.5 mm, \
         0.5 mrad per step) was chosen so that the paper's qualitative results appear; the acceptance trend therefore \
         holds partly by construction.\n"
    );
    let _ = writeln!(md, "## Key agreement against Δv (Eve at α = 10 %)\n");
    let _ = writeln!(
        md,
        "| Δv (m/s) | accepted % | correct % | controller BER % | J_x (mm) |"
    );
    let _ = writeln!(md, "|---|---|---|---|---|");
    let mut terminal = String::new();
    for (x, acc) in boxes(&accepted) {
        let of = |pairs: &[(f64, f64)]| {
            median_of(
                &pairs
                    .iter()
                    .filter(|p| p.0 == x)
                    .map(|p| p.1)
                    .collect::<Vec<_>>(),
            )
        };
        let row = format!(
            "| {x} | {} | {} | {} | {} |",
            fmt(median_of(&acc), 1),
            fmt(of(&correct), 2),
            fmt(of(&ber), 2),
            fmt(of(&jx), 1)
        );
        let _ = writeln!(md, "{row}");
        let _ = writeln!(
            terminal,
            "Δv = {x:<6} accepted {:>5}%  correct {:>6}%  J_x {:>5} mm",
            fmt(median_of(&acc), 1),
            fmt(of(&correct), 2),
            fmt(of(&jx), 1)
        );
    }
    let _ = writeln!(
        md,
        "\nMedians over {replicates} runs per point. Protocol off: J_x median {} mm.\n",
        fmt(baseline_median, 1)
    );
    let _ = writeln!(md, "![accepted](figures/dv-acceptance.svg)\n");
    let _ = writeln!(
        md,
        "{}\n",
        trend_sentence(
            "The accepted share",
            "Δv",
            &accepted_trend,
            "it rises with Δv",
            1.0
        )
    );
    let _ = writeln!(md, "![correct](figures/dv-correct.svg)\n");
    let _ = writeln!(
        md,
        "{} Wrong accepted bits are rare but possible at any Δv (≈ 0.03 per run at 0.035), so the paper's \
         \"all correct for Δv ≥ 0.035\" is a statement about 10 runs.\n",
        trend_sentence(
            "The correct share",
            "Δv",
            &correct_trend,
            "it rises with Δv and reaches 100 % for Δv ≥ 0.035",
            1.0
        )
    );
    let _ = writeln!(md, "![Jₓ](figures/dv-jx.svg)\n");
    let _ = writeln!(
        md,
        "{}\n",
        trend_sentence(
            "The tracking error J_x",
            "Δv",
            &jx_trend,
            "it grows with Δv, above the protocol-off baseline",
            1.0
        )
    );
    let _ = writeln!(md, "## Eve against her model error α (Δv = 0.035)\n");
    let _ = writeln!(
        md,
        "| α (%) | Eve disagreement %, median | max | Eve wrong on accepted bits %, pooled [95 % CI] |"
    );
    let _ = writeln!(md, "|---|---|---|---|");
    for (a, d) in boxes(&disagreement) {
        let s = Summary::of(&d);
        let pooled = eve_errors
            .iter()
            .find(|e| e.0 == a)
            .map_or("–".into(), |e| {
                format!("{:.3} [{:.3}, {:.3}]", e.1, e.2, e.3)
            });
        let _ = writeln!(
            md,
            "| {a:.0} | {} | {} | {pooled} |",
            fmt(s.map(|s| s.median), 2),
            fmt(s.map(|s| s.max), 2)
        );
        let _ = writeln!(
            terminal,
            "α = {a:>3.0} %   Eve disagreement median {:>5}%",
            fmt(s.map(|s| s.median), 2)
        );
    }
    let _ = writeln!(md, "\n![Eve](figures/eve-error-accepted.svg)\n");
    let _ = writeln!(
        md,
        "{} Under the paper's eavesdropper model (docs/protocol.md) an error on r only biases Eve's nominal v by e_r·v (≤ 8.8 mm/s at 10 %, against \
         Δv = 35 mm/s), and with m = 2 an error on D stays in the ω channel, so she is barely hurt.\n",
        trend_sentence(
            "Eve's disagreement",
            "α",
            &eve_trend,
            "it rises with α over [0, 10] %",
            1.0
        )
    );
    let _ = writeln!(
        md,
        "## Trajectory (replicate 0, first lap)\n\n![trajectory](figures/trajectory.svg)\n"
    );
    let _ = writeln!(
        md,
        "## Deviations from the paper\n\n\
         - 11 grid values instead of \"10\", so that 0.035 is on the Δv grid and 0 on the α grid.\n\
         - The plant's true noise is a calibration (above), not the observer's design covariances W, V.\n\
         - The errata of the paper's Algorithm 2 are fixed (docs/observer.md): cross-covariance −ΓV, balanced L, W/V naming, uU(k−1).\n"
    );
    let _ = writeln!(
        terminal,
        "{}",
        trend_line("accepted share", "Δv", &accepted_trend, 1.0)
    );
    let _ = writeln!(
        terminal,
        "{}",
        trend_line("correct share", "Δv", &correct_trend, 1.0)
    );
    let _ = writeln!(terminal, "{}", trend_line("J_x", "Δv", &jx_trend, 1.0));
    let _ = writeln!(
        terminal,
        "{}",
        trend_line("Eve's disagreement", "α", &eve_trend, 1.0)
    );
    Ok((md, terminal))
}
