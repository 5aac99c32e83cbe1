//! Where private sensing pays (docs/private-sensing.md, "Maps"): the secret rate against
//! Eve's camera noise with its break-even, the Pareto front of secret rate against tracking
//! cost, and the commands eavesdropper's measured leak against the model's. Computed from
//! the results of [`super::analyze()`]; rendered by [`crate::report::private`].

use rayon::prelude::*;
use robokey::Config;
use robokey::config::{EveStrategy, SensingMode};
use robokey::sim::simulate;
use serde::{Deserialize, Serialize};

use super::PointSecrecy;
use crate::error::LabError;
use crate::experiment::{Experiment, param_label};

/// The swept field of Eve's camera noise.
pub const CAMERA_FIELD: &str = "eve.camera_std";

/// One curve of secret rate against Eve's camera noise, every other parameter fixed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraCurve {
    /// The fixed parameters, for people (e.g. "motion 4 mm").
    pub label: String,
    /// `(camera noise (mm), secret bits per second)`, by camera noise.
    pub points: Vec<(f64, f64)>,
    /// Where the rate reaches zero, if it does on the grid.
    pub break_even: Option<BreakEven>,
}

/// The break-even camera noise lies in `(zero_at, positive_at]` (mm): the rate is zero at
/// `zero_at` and at every smaller noise, positive at `positive_at`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BreakEven {
    /// The largest camera noise on the grid with a zero rate (mm).
    pub zero_at: f64,
    /// The next one, with a positive rate (mm).
    pub positive_at: f64,
}

/// One operating point of the Pareto figure.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParetoPoint {
    /// The point's parameters.
    pub point: String,
    /// Mean tracking error J_x (mm).
    pub jx_mm: f64,
    /// Secret bits per second under the stated assumption.
    pub bits_per_second: f64,
    /// No other point tracks at least as well with a higher rate.
    pub on_front: bool,
}

/// One turn-rate bin of the commands eavesdropper: what she measured against the model.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LeakBin {
    /// The index of the point whose sessions the bin counts. A sweep's points share their
    /// seeds, hence their sessions' noise and bits: bins of different points are not
    /// independent measurements (those of one point hold disjoint bits).
    pub point: usize,
    /// Predicted information per bit (bits).
    pub predicted: f64,
    /// Measured information per bit with its 95 % interval (bits).
    #[serde(deserialize_with = "crate::reals::nans_if_null")]
    pub measured: [f64; 3],
    /// Bits in the bin.
    pub bits: u64,
}

/// The figures of a private-sensing map.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PrivateMap {
    /// Rate against camera noise, one curve per setting of the other axes (empty without a
    /// camera axis).
    pub camera: Vec<CameraCurve>,
    /// Every point against the strongest adversary, when the experiment sweeps the
    /// perturbation (a `protocol.*` axis); else empty.
    pub pareto: Vec<ParetoPoint>,
    /// The paper's scheme at its defaults: J_x (mm) with zero secret bits by structure.
    pub paper_jx_mm: f64,
    /// The commands eavesdropper's turn-rate bins over every point she was run on.
    pub leak: Vec<LeakBin>,
}

/// The commands eavesdropper's leak pooled over her turn-rate bins.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PooledLeak {
    /// Measured over predicted information, pooled: Σ nᵢ·mᵢ / Σ nᵢ·pᵢ over the bins (nᵢ
    /// bits measuring mᵢ where the model predicts pᵢ).
    pub ratio: f64,
    /// Its 95 % normal interval. Within a point the bins hold disjoint bits, so their
    /// errors add in quadrature, `σ_p = √Σ_{i∈p} (nᵢ·sᵢ)²` (sᵢ a bin's standard error: its
    /// interval's half-width / 1.96); points may share their sessions (a sweep's common
    /// seeds: the same noise and bits seen through another Δ), so their errors add
    /// linearly, `σ ≤ Σ_p σ_p` (Cauchy–Schwarz, whatever their correlation), and the
    /// pooled ratio's standard error is `σ / Σ nᵢ·pᵢ`.
    pub interval: [f64; 2],
    /// Bins whose measurement lies above the prediction.
    pub above: usize,
    /// The smallest and largest measured/predicted ratio among those.
    pub above_ratios: [f64; 2],
    /// Bins with a measurement.
    pub bins: usize,
}

/// z of a two-sided 95 % normal interval.
const Z95: f64 = 1.959_963_984_540_054;

impl PrivateMap {
    /// The leak pooled over the bins with a finite measurement and a positive prediction;
    /// none without such a bin.
    #[must_use]
    pub fn pooled_leak(&self) -> Option<PooledLeak> {
        let bins: Vec<&LeakBin> = self
            .leak
            .iter()
            .filter(|b| b.measured.iter().all(|m| m.is_finite()) && b.predicted > 0.0)
            .collect();
        let predicted: f64 = bins.iter().map(|b| b.bits as f64 * b.predicted).sum();
        if predicted <= 0.0 {
            return None;
        }
        let measured: f64 = bins.iter().map(|b| b.bits as f64 * b.measured[0]).sum();
        let mut points: Vec<usize> = bins.iter().map(|b| b.point).collect();
        points.sort_unstable();
        points.dedup();
        let std_error: f64 = points
            .iter()
            .map(|&point| {
                bins.iter()
                    .filter(|b| b.point == point)
                    .map(|b| {
                        (b.bits as f64 * (b.measured[2] - b.measured[1]) / (2.0 * Z95)).powi(2)
                    })
                    .sum::<f64>()
                    .sqrt()
            })
            .sum();
        let (ratio, half) = (measured / predicted, Z95 * std_error / predicted);
        let above: Vec<f64> = bins
            .iter()
            .filter(|b| b.measured[0] > b.predicted)
            .map(|b| b.measured[0] / b.predicted)
            .collect();
        Some(PooledLeak {
            ratio,
            interval: [ratio - half, ratio + half],
            above: above.len(),
            above_ratios: [
                above.iter().copied().fold(f64::INFINITY, f64::min),
                above.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            ],
            bins: bins.len(),
        })
    }
}

/// Where a curve of `(camera noise, rate)` sorted by noise reaches zero: the largest noise
/// with a zero rate and the next one, if both exist.
fn break_even(points: &[(f64, f64)]) -> Option<BreakEven> {
    let i = points.iter().rposition(|p| p.1 == 0.0)?;
    Some(BreakEven {
        zero_at: points[i].0,
        positive_at: points.get(i + 1)?.0,
    })
}

/// Marks the points no other point dominates (J_x at most as large and rate at least as
/// high, one of them strictly).
fn mark_front(points: &mut [ParetoPoint]) {
    let all: Vec<(f64, f64)> = points
        .iter()
        .map(|p| (p.jx_mm, p.bits_per_second))
        .collect();
    for p in points.iter_mut() {
        p.on_front = !all.iter().any(|&(jx, rate)| {
            jx <= p.jx_mm && rate >= p.bits_per_second && (jx < p.jx_mm || rate > p.bits_per_second)
        });
    }
}

/// The J_x (mm) of the paper's scheme at its defaults over `replicates` runs, with the
/// motion noise and seed of `like`.
fn paper_jx_mm(like: &Config, replicates: u32) -> Result<f64, LabError> {
    let mut paper = Config {
        noise: like.noise.clone(),
        ..Config::default()
    };
    paper.run.seed = like.run.seed;
    let jx: Vec<f64> = (0..replicates)
        .into_par_iter()
        .map(|r| simulate(&paper, r, false).map(|o| o.metrics.jx))
        .collect::<Result<_, _>>()?;
    Ok(1e3 * jx.iter().sum::<f64>() / f64::from(replicates.max(1)))
}

/// The map of `results` (private-sensing points of `experiment`).
///
/// # Errors
/// A paper run fails to simulate (never with a validated experiment).
pub fn private_map(
    experiment: &Experiment,
    results: &[PointSecrecy],
) -> Result<Option<PrivateMap>, LabError> {
    let Some(first) = experiment.points.first() else {
        return Ok(None);
    };
    if first.config.sensing.mode != SensingMode::Private {
        return Ok(None);
    }
    let strongest: Vec<&PointSecrecy> = results
        .iter()
        .filter(|r| r.adversary == EveStrategy::Camera.name())
        .collect();
    let mut camera: Vec<CameraCurve> = Vec::new();
    if experiment.axes.iter().any(|a| a.field == CAMERA_FIELD) {
        for r in &strongest {
            let point = &experiment.points[r.point_index];
            let label = point
                .params
                .iter()
                .filter(|(f, _)| f != CAMERA_FIELD)
                .map(|(f, v)| param_label(f, v))
                .collect::<Vec<_>>()
                .join(", ");
            let label = if label.is_empty() {
                "every point".to_owned()
            } else {
                label
            };
            let xy = (
                1e3 * point.config.eve.camera_std[0],
                r.secret_bits_per_second,
            );
            match camera.iter_mut().find(|c| c.label == label) {
                Some(curve) => curve.points.push(xy),
                None => camera.push(CameraCurve {
                    label,
                    points: vec![xy],
                    break_even: None,
                }),
            }
        }
        for curve in &mut camera {
            curve.points.sort_by(|a, b| a.0.total_cmp(&b.0));
            curve.break_even = break_even(&curve.points);
        }
    }
    // A Pareto front over what the operator chooses: the perturbation.
    let over_delta = experiment
        .axes
        .iter()
        .any(|a| a.field.starts_with("protocol."));
    let mut pareto: Vec<ParetoPoint> = strongest
        .iter()
        .filter(|_| over_delta)
        .filter_map(|r| {
            Some(ParetoPoint {
                point: r.point.clone(),
                jx_mm: r.private.as_ref()?.jx_mm,
                bits_per_second: r.secret_bits_per_second,
                on_front: false,
            })
        })
        .collect();
    mark_front(&mut pareto);
    let leak = results
        .iter()
        .filter(|r| r.adversary == EveStrategy::Commands.name())
        .filter_map(|r| Some((r.point_index, r.private.as_ref()?)))
        .flat_map(|(point, f)| f.turn_bins.iter().map(move |b| (point, b)))
        .map(|(point, b)| LeakBin {
            point,
            predicted: b.predicted,
            measured: b.information,
            bits: b.bits,
        })
        .collect();
    Ok(Some(PrivateMap {
        camera,
        pareto,
        paper_jx_mm: paper_jx_mm(&first.config, first.config.run.replicates.max(10))?,
        leak,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_break_even_is_bracketed_by_the_grid() {
        let curve = [(1.0, 0.0), (2.0, 0.0), (3.0, 0.2), (4.0, 0.5)];
        let b = break_even(&curve).unwrap();
        assert_eq!((b.zero_at, b.positive_at), (2.0, 3.0));
        assert!(break_even(&[(1.0, 0.1), (2.0, 0.3)]).is_none());
        assert!(break_even(&[(1.0, 0.0), (2.0, 0.0)]).is_none());
    }

    #[test]
    fn the_front_keeps_only_undominated_points() {
        let point = |jx: f64, rate: f64| ParetoPoint {
            point: String::new(),
            jx_mm: jx,
            bits_per_second: rate,
            on_front: false,
        };
        let mut points = vec![
            point(12.4, 0.0),
            point(12.9, 0.85),
            point(13.6, 0.66),
            point(14.0, 0.9),
            point(14.0, 0.9),
        ];
        mark_front(&mut points);
        let front: Vec<bool> = points.iter().map(|p| p.on_front).collect();
        assert_eq!(front, [true, true, false, true, true]);
    }

    fn bin(point: usize, predicted: f64, measured: f64, half_width: f64, bits: u64) -> LeakBin {
        LeakBin {
            point,
            predicted,
            measured: [measured, measured - half_width, measured + half_width],
            bits,
        }
    }

    /// Bins of one point hold disjoint bits: their errors add in quadrature. Two points
    /// that share their sessions measure the same noise twice: their errors add linearly,
    /// so pooling a point with itself leaves the ratio's interval as wide as one point's.
    #[test]
    fn points_that_share_sessions_do_not_narrow_the_pooled_interval() {
        let one_point = PrivateMap {
            camera: Vec::new(),
            pareto: Vec::new(),
            paper_jx_mm: 0.0,
            leak: vec![
                bin(0, 0.001, 0.0015, 0.001, 1000),
                bin(0, 0.002, 0.003, 0.001, 1000),
            ],
        };
        let single = one_point.pooled_leak().unwrap();
        assert!((single.ratio - 1.5).abs() < 1e-12);
        // √(1² + 1²)·1000·(0.001/1.96)·1.96 / 3 = √2/3.
        let half = (single.interval[1] - single.interval[0]) / 2.0;
        assert!((half - 2f64.sqrt() / 3.0).abs() < 1e-12, "{half}");
        let twice = PrivateMap {
            leak: [
                one_point.leak.clone(),
                one_point
                    .leak
                    .iter()
                    .map(|b| LeakBin { point: 1, ..*b })
                    .collect(),
            ]
            .concat(),
            ..one_point.clone()
        };
        let pooled = twice.pooled_leak().unwrap();
        assert!((pooled.ratio - 1.5).abs() < 1e-12);
        for (a, b) in pooled.interval.iter().zip(single.interval) {
            assert!(
                (a - b).abs() < 1e-12,
                "{:?} vs {:?}",
                pooled.interval,
                single.interval
            );
        }
        assert_eq!((pooled.bins, pooled.above), (4, 4));
    }

    /// Seeded: the commands eavesdropper's measured information pooled over her turn-rate
    /// bins agrees with the model's prediction in the parties' own world — the ratio's 95 %
    /// interval holds 1 — and the interval is narrow enough to have seen the 1.61 that
    /// pooling shared sessions as independent once suggested (half-width below 0.3; ≈ 0.22
    /// expected from ≈ 9·10⁴ bits at Δv = 0.05 m/s).
    #[test]
    fn the_commands_leak_pooled_over_turn_rates_is_what_the_model_predicts() {
        let config = Config::from_toml(
            "[sensing]\nmode = \"private\"\n[protocol]\ndelta_v = 0.05\n[run]\nseed = 11\n",
            "test",
        )
        .unwrap();
        let runs: Vec<_> = (0..200)
            .into_par_iter()
            .map(|r| simulate(&config, r, false).unwrap())
            .collect();
        let figures = super::super::private::figures(
            &config,
            &runs,
            EveStrategy::Commands,
            &super::super::private::OffRuns::default(),
        )
        .unwrap();
        let map = PrivateMap {
            camera: Vec::new(),
            pareto: Vec::new(),
            paper_jx_mm: 0.0,
            leak: figures
                .turn_bins
                .iter()
                .map(|b| LeakBin {
                    point: 0,
                    predicted: b.predicted,
                    measured: b.information,
                    bits: b.bits,
                })
                .collect(),
        };
        let pooled = map.pooled_leak().unwrap();
        let [low, high] = pooled.interval;
        assert!(
            low <= 1.0 && 1.0 <= high,
            "{} [{low}, {high}]",
            pooled.ratio
        );
        assert!(high - low < 0.6, "{} [{low}, {high}]", pooled.ratio);
    }

    #[test]
    fn legends_name_the_physics() {
        let mm4: toml::Value = toml::Value::Array(vec![0.004.into(); 3]);
        assert_eq!(param_label("noise.process_std", &mm4), "motion noise 4 mm");
        assert_eq!(
            param_label("protocol.delta_v", &0.035.into()),
            "Δv 0.035 m/s"
        );
        assert_eq!(
            param_label("eve.alpha", &0.05.into()),
            "Eve's model error α 5 %"
        );
        assert_eq!(param_label("run.seed", &7.into()), "run.seed = 7");
    }
}
