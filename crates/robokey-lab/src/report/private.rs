//! Renders private sensing (docs/private-sensing.md): the figures of one or more (point,
//! adversary) rows — a markdown section and `turn-rates.csv` — and a map's figures, each
//! with its CSV.

use std::path::{Path, PathBuf};

use crate::csv_field::quoted;
use crate::error::LabError;
use crate::experiment::param_label;
use crate::plot::{Interval, LineChart, Series, SeriesStyle};
use crate::secrecy::Rate;
use crate::secrecy::map::{CameraCurve, ParetoPoint, PooledLeak, PrivateMap};
use crate::secrecy::private::{Calibration, PrivateFigures};

/// One row to render: where it comes from and its figures.
pub struct PrivateRow<'a> {
    /// The grid point, `field = value, …` (empty for a single configuration).
    pub point: &'a str,
    /// The adversary's name.
    pub adversary: &'a str,
    /// Its figures.
    pub figures: &'a PrivateFigures,
}

fn percent(rate: Option<&Rate>) -> String {
    rate.map_or("–".into(), |r| {
        format!(
            "{:.2} [{:.2}, {:.2}]",
            100.0 * r.rate,
            100.0 * r.low,
            100.0 * r.high
        )
    })
}

fn interval(x: &[f64; 3]) -> String {
    format!("{:.5} [{:.5}, {:.5}]", x[0], x[1], x[2])
}

/// "pass (worst p …)", or on a failure which way the worst bin fails: its errors against
/// the LLRs' prediction.
fn calibrated(c: &Calibration) -> String {
    match (c.passed, c.worst_bin) {
        (true, _) => format!("pass (worst p {:.3})", c.worst_p),
        (false, Some(bin)) => format!("**FAIL** (worst p {:.3}: {bin})", c.worst_p),
        (false, None) => format!("**FAIL** (worst p {:.3})", c.worst_p),
    }
}

/// The markdown section: one summary row per (point, adversary), then each row's
/// information by the public turn rate against what the model predicts.
#[must_use]
pub fn private_markdown(rows: &[PrivateRow]) -> String {
    let mut md = String::from(
        "## Private sensing\n\n\
         | point | adversary | bits/doublet | doublets | turn-gated % | controller error % | Eve error % | Eve information per bit | predicted | calibration: controller / Eve | J_x mm (protocol off) |\n\
         |---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for row in rows {
        let f = row.figures;
        md.push_str(&format!(
            "| {} | {} | {} | {} | {:.2} | {} | {} | {} | {:.5} | {} / {} | {:.2} ({:.2}) |\n",
            row.point,
            row.adversary,
            f.bits_per_doublet,
            f.doublets,
            100.0 * f.gated_fraction,
            percent(f.controller_error.as_ref()),
            percent(f.eve_error.as_ref()),
            interval(&f.eve_information),
            f.eve_information_predicted,
            calibrated(&f.controller_calibration),
            calibrated(&f.eve_calibration),
            f.jx_mm,
            f.jx_off_mm,
        ));
    }
    md.push_str(
        "\nEve's information per bit is 1 − E[surprisal of the true bit] under her calibrated \
         posterior (95 % normal interval); predicted is the mean of I(d) over the model's \
         separations d of the same bits. Error rates: 95 % Clopper–Pearson intervals. \
         Calibration: 10 equal-count bins, exact Poisson-binomial tails, family-wise \
         α = 10⁻³; a failure names its worst bin's errors against the prediction: \
         under-confident LLRs (fewer errors) are conservative for the controller and, \
         for an eavesdropper, understate what she learns; over-confident ones the \
         reverse. See docs/private-sensing.md.\n",
    );
    for row in rows {
        md.push_str(&format!(
            "\n### {} Eve by public turn rate{}\n\n\
             | turn rate (rad/s) | bits | Eve error % | information per bit | predicted |\n\
             |---|---|---|---|---|\n",
            row.adversary,
            if row.point.is_empty() {
                String::new()
            } else {
                format!(" ({})", row.point)
            }
        ));
        for bin in &row.figures.turn_bins {
            md.push_str(&format!(
                "| {:.2}–{} | {} | {} | {} | {:.5} |\n",
                bin.from,
                if bin.to.is_finite() {
                    format!("{:.2}", bin.to)
                } else {
                    "∞".into()
                },
                bin.bits,
                percent(bin.error.as_ref()),
                interval(&bin.information),
                bin.predicted,
            ));
        }
    }
    md
}

/// `turn-rates.csv`: one line per (point, adversary, turn-rate bin).
#[must_use]
pub fn turn_rates_csv(rows: &[PrivateRow]) -> String {
    let mut out = String::from(
        "point,adversary,turn_from,turn_to,bits,eve_error,eve_error_low,eve_error_high,information,information_low,information_high,predicted\n",
    );
    for row in rows {
        for bin in &row.figures.turn_bins {
            let error = bin
                .error
                .map_or(",,".into(), |e| format!("{},{},{}", e.rate, e.low, e.high));
            out.push_str(&format!(
                "{},{},{},{},{},{},{},{},{},{}\n",
                quoted(row.point),
                row.adversary,
                bin.from,
                if bin.to.is_finite() {
                    bin.to.to_string()
                } else {
                    String::new()
                },
                bin.bits,
                error,
                bin.information[0],
                bin.information[1],
                bin.information[2],
                bin.predicted,
            ));
        }
    }
    out
}

/// The map's markdown: break-even camera noise per curve, the Pareto front, the leak.
#[must_use]
pub fn map_markdown(map: &PrivateMap, block_bits: usize, epsilon: f64) -> String {
    let mut md = String::new();
    if !map.camera.is_empty() {
        md.push_str(&format!(
            "\n### Secret rate against Eve's camera noise\n\n\
             ![rate against camera noise](private-rate-vs-camera.svg)\n\n\
             Blocks of {block_bits} bits, ε = {epsilon:e} per term. \
             The break-even is the camera noise below which no secret bit is left.\n\n\
             | setting | break-even camera noise | rate at the noisiest camera |\n|---|---|---|\n"
        ));
        for curve in &map.camera {
            let last = curve.points.last().copied().unwrap_or((f64::NAN, f64::NAN));
            md.push_str(&format!(
                "| {} | {} | {:.3} bits/s at {} mm |\n",
                curve.label,
                break_even_text(curve),
                last.1,
                last.0
            ));
        }
    }
    let front: Vec<&ParetoPoint> = map.pareto.iter().filter(|p| p.on_front).collect();
    if map.pareto.len() > 1 {
        md.push_str(&format!(
            "\n### Secret rate against tracking cost\n\n\
             ![Pareto front](private-pareto.svg)\n\n\
             The paper's scheme tracks with J_x = {:.1} mm and yields 0 secret bits (by \
             structure). Private sensing's Pareto front (no other point tracks at least as \
             well with a higher rate):\n\n| point | J_x (mm) | secret bits/s |\n|---|---|---|\n",
            map.paper_jx_mm
        ));
        for p in &front {
            md.push_str(&format!(
                "| {} | {:.2} | {:.3} |\n",
                p.point, p.jx_mm, p.bits_per_second
            ));
        }
    }
    if !map.leak.is_empty() {
        md.push_str(
            "\n### What the commands leak, measured against the model\n\n\
             ![leak](private-leak.svg)\n\n\
             Each marker is one turn-rate bin of one point: the commands eavesdropper's \
             measured information per bit against the mean I(d) the model predicts for the \
             same bits. On the diagonal, the residual leak is the one the model charges.\n",
        );
        if let Some(pooled) = map.pooled_leak() {
            md.push_str(&format!("\n{}\n", pooled_leak_text(&pooled)));
        }
    }
    md
}

/// "between A and B mm", "below A mm" or "not reached".
pub fn break_even_text(curve: &CameraCurve) -> String {
    match curve.break_even {
        Some(b) => format!("between {} and {} mm", b.zero_at, b.positive_at),
        None if curve.points.first().is_some_and(|p| p.1 > 0.0) => format!(
            "below {} mm (positive on the whole grid)",
            curve.points[0].0
        ),
        None => "not reached: zero on the whole grid".into(),
    }
}

/// A point's parameters (`field = value, …`, as [`crate::experiment::describe`] writes
/// them) for a note beside it, e.g. "Δv 0.035 m/s"; the text itself if it does not read.
fn point_note(point: &str) -> String {
    let Ok(table) = format!("point = {{ {point} }}").parse::<toml::Table>() else {
        return point.to_owned();
    };
    let mut labels = Vec::new();
    let mut stack: Vec<(String, &toml::Value)> = table
        .get("point")
        .map(|v| (String::new(), v))
        .into_iter()
        .collect();
    while let Some((field, value)) = stack.pop() {
        match value {
            toml::Value::Table(t) => stack.extend(t.iter().map(|(k, v)| {
                let key = if field.is_empty() {
                    k.clone()
                } else {
                    format!("{field}.{k}")
                };
                (key, v)
            })),
            _ => labels.push(param_label(&field, value)),
        }
    }
    labels.sort();
    labels.join(", ")
}

/// The pooled leak in words: the ratio, its interval, the bins above the identity line and
/// what that means.
#[must_use]
pub fn pooled_leak_text(pooled: &PooledLeak) -> String {
    let [low, high] = pooled.interval;
    let meaning = if low > 1.0 {
        "the commands reveal more than the model predicts: the leak charged for them is too \
         small by about this factor"
    } else if high < 1.0 {
        "the commands reveal less than the model predicts: the leak charged for them is \
         conservative"
    } else {
        "the measurement is consistent with the model's prediction"
    };
    let above = if pooled.above > 0 {
        format!(
            " ({:.1}–{:.1}× the prediction)",
            pooled.above_ratios[0], pooled.above_ratios[1]
        )
    } else {
        String::new()
    };
    format!(
        "Pooled over the {} bins (each weighted by its bits), the commands eavesdropper \
         measured {:.2} × the predicted information (95 % interval {low:.2}–{high:.2}, the \
         points' errors added linearly: a sweep's points share their sessions, so their bins \
         are not independent); {} of {} bins lie above the identity line{above}. Per-bin \
         intervals are wide; the pooled ratio is what they say together: {meaning}.",
        pooled.bins, pooled.ratio, pooled.above, pooled.bins
    )
}

/// Saves `chart` as `base.{svg,png,pdf,csv}`, its error naming the figure.
pub(super) fn save(chart: &LineChart, base: &Path) -> Result<Vec<PathBuf>, LabError> {
    chart.save(base).map_err(|e| LabError::Plot {
        path: base.to_path_buf(),
        message: e.to_string(),
    })
}

/// Writes the map's figures into `dir` (each with the CSV of what it draws).
///
/// # Errors
/// A file cannot be written.
pub fn write_map(
    dir: &Path,
    map: &PrivateMap,
    block_bits: usize,
    epsilon: f64,
) -> Result<Vec<PathBuf>, LabError> {
    let mut files = Vec::new();
    let chart = |title: &str, x_label: &str, y_label: &str, series: Vec<Series>| LineChart {
        title: title.into(),
        x_label: x_label.into(),
        y_label: y_label.into(),
        series,
        equal_aspect: false,
        log_y: false,
    };
    if !map.camera.is_empty() {
        let mut series: Vec<Series> = map
            .camera
            .iter()
            .map(|c| Series::new(c.label.clone(), c.points.clone(), SeriesStyle::Line))
            .collect();
        // Each curve's break-even in that curve's colour: a vertical line at the largest
        // camera noise with a zero rate (the break-even lies within one grid step above).
        let top = map
            .camera
            .iter()
            .flat_map(|c| c.points.iter().map(|p| p.1))
            .fold(0.0, f64::max);
        for (i, curve) in map.camera.iter().enumerate() {
            if let Some(b) = curve.break_even {
                series.push(Series {
                    color: Some(i),
                    ..Series::reference(
                        format!("break-even above {} mm, {}", b.zero_at, curve.label),
                        vec![(b.zero_at, 0.0), (b.zero_at, top)],
                    )
                });
            }
        }
        files.extend(save(
            &chart(
                &format!(
                    "Secret bits per second against Eve's camera noise (ε = {:e}, blocks of {block_bits} bits)",
                    4.0 * epsilon
                ),
                "Eve's camera noise per sample instant (mm)",
                "secret bits per second",
                series,
            ),
            &dir.join("private-rate-vs-camera"),
        )?);
    }
    if map.pareto.len() > 1 {
        let mut front: Vec<(f64, f64)> = map
            .pareto
            .iter()
            .filter(|p| p.on_front)
            .map(|p| (p.jx_mm, p.bits_per_second))
            .collect();
        front.sort_by(|a, b| a.0.total_cmp(&b.0));
        let every = map
            .pareto
            .iter()
            .map(|p| (p.jx_mm, p.bits_per_second))
            .collect();
        let notes = map.pareto.iter().map(|p| point_note(&p.point)).collect();
        files.extend(save(
            &chart(
                "Secret rate against tracking cost",
                "tracking error Jₓ (mm)",
                "secret bits per second",
                vec![
                    Series {
                        notes,
                        ..Series::new("private sensing, every point", every, SeriesStyle::Markers)
                    },
                    Series::new("Pareto front", front, SeriesStyle::Line),
                    Series::new(
                        "the paper's scheme (0 by structure)",
                        vec![(map.paper_jx_mm, 0.0)],
                        SeriesStyle::Markers,
                    ),
                ],
            ),
            &dir.join("private-pareto"),
        )?);
    }
    if !map.leak.is_empty() {
        let top = map
            .leak
            .iter()
            .map(|b| b.predicted.max(b.measured[0]))
            .fold(0.0, f64::max);
        let measured = Series {
            intervals: map
                .leak
                .iter()
                .map(|b| Interval {
                    x: b.predicted,
                    low: b.measured[1],
                    high: b.measured[2],
                })
                .collect(),
            ..Series::new(
                "turn-rate bins (commands Eve), 95 % intervals",
                map.leak
                    .iter()
                    .map(|b| (b.predicted, b.measured[0]))
                    .collect(),
                SeriesStyle::Markers,
            )
        };
        let mut series = vec![
            measured,
            Series::reference("measured = predicted", vec![(0.0, 0.0), (top, top)]),
        ];
        if let Some(pooled) = map.pooled_leak() {
            let [low, high] = pooled.interval;
            series.push(Series::reference(
                format!(
                    "pooled: measured = {:.2} × predicted (95 % {low:.2}–{high:.2})",
                    pooled.ratio
                ),
                vec![
                    (0.0, 0.0),
                    (top / pooled.ratio.max(1.0), top * pooled.ratio.min(1.0)),
                ],
            ));
        }
        files.extend(save(
            &chart(
                "What the commands leak: measured against the model",
                "predicted information per bit (bits)",
                "measured information per bit (bits)",
                series,
            ),
            &dir.join("private-leak"),
        )?);
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::secrecy::private::BinErrors;

    #[test]
    fn a_failure_is_rendered_with_its_worst_bin_and_direction() {
        let mut c = Calibration {
            bits: 2_000,
            passed: false,
            worst_p: 1e-9,
            worst_bin: Some(BinErrors {
                observed: 1,
                predicted: 60.64,
            }),
        };
        assert_eq!(
            calibrated(&c),
            "**FAIL** (worst p 0.000: 1 error where 60.6 predicted, under-confident)"
        );
        c.worst_bin = Some(BinErrors {
            observed: 90,
            predicted: 60.0,
        });
        assert!(calibrated(&c).ends_with("over-confident)"));
        c.passed = true;
        c.worst_p = 0.147;
        assert_eq!(calibrated(&c), "pass (worst p 0.147)");
    }
}
