//! Which physics breaks which assumption (docs/world.md, "Over-claims"): for a sweep whose
//! world is not the parties', the key's over-claim — ℓ minus the ℓ the realised view of the
//! eavesdropper who knows the world supports, before either is clamped at zero (the
//! difference of their min-entropy bounds: the leak cancels), per raw bit amplified (the
//! pooled raw bits less the disclosed sample, the bits both bounds are over) — against the
//! world parameter swept, beside her information per raw bit and its interval.

use std::path::{Path, PathBuf};

use crate::error::LabError;
use crate::experiment::{Experiment, axis_label, param_label, param_number};
use crate::output::write;
use crate::plot::{Interval, LineChart, Series, SeriesStyle};
use crate::secrecy::PointSecrecy;

/// One point's over-claim against one adversary.
#[derive(Clone, Debug, PartialEq)]
pub struct OverClaim {
    /// The point's parameters, for people.
    pub point: String,
    /// The adversary.
    pub adversary: String,
    /// The first axis' value in the units people read, if numeric.
    pub x: Option<f64>,
    /// The other axes' setting, for a legend.
    pub setting: String,
    /// `(Σ H_min under the assumption − Σ H_min of her realised view) / Σ n` over the point's
    /// blocks, `n` the raw bits amplified (bits per raw bit; negative: the assumption gives
    /// her more).
    pub per_raw_bit: f64,
    /// ℓ under the assumption, summed over the blocks (bits).
    pub secret_bits: u64,
    /// ℓ her realised view supports, summed over the blocks (bits).
    pub realised_bits: u64,
    /// Raw bits amplified: pooled, less the disclosed sample.
    pub raw_bits: usize,
    /// Her information per raw bit `1 − mean S` with its 95 % interval (NaN when unknown).
    pub information: [f64; 3],
    /// Her error rate on the raw bits (NaN when unknown).
    pub error_rate: f64,
    /// What the world differs in from the parties' configuration.
    pub world: String,
}

/// The over-claims of the results whose world is not the parties' (empty otherwise).
#[must_use]
pub fn over_claims(experiment: &Experiment, results: &[PointSecrecy]) -> Vec<OverClaim> {
    results
        .iter()
        .filter(|r| !r.world_differences.is_empty() && !r.blocks.is_empty())
        .map(|r| {
            let params = &experiment.points[r.point_index].params;
            let raw_bits: usize = r.blocks.iter().map(|b| b.reconciled_bits).sum();
            let assumed: f64 = r.blocks.iter().map(|b| b.h_min).sum();
            let realised: f64 = r.blocks.iter().map(|b| b.realised.h_min).sum();
            let figures = r.private.as_ref();
            OverClaim {
                point: r.point.clone(),
                adversary: r.adversary.clone(),
                x: params.first().and_then(|(f, v)| param_number(f, v)),
                setting: params
                    .iter()
                    .skip(1)
                    .map(|(f, v)| param_label(f, v))
                    .collect::<Vec<_>>()
                    .join(", "),
                per_raw_bit: (assumed - realised) / raw_bits.max(1) as f64,
                secret_bits: r.blocks.iter().map(|b| b.secret_bits).sum(),
                realised_bits: r.blocks.iter().map(|b| b.realised.secret_bits).sum(),
                raw_bits,
                information: figures.map_or([f64::NAN; 3], |f| f.eve_information),
                error_rate: figures
                    .and_then(|f| f.eve_error)
                    .map_or(f64::NAN, |e| e.rate),
                world: r.world_differences.join("; "),
            }
        })
        .collect()
}

/// The over-claims as CSV, one row per point and adversary.
#[must_use]
pub fn over_claim_csv(rows: &[OverClaim]) -> String {
    let mut out = String::from(
        "point,adversary,over_claim_per_raw_bit,secret_bits,realised_secret_bits,raw_bits,\
         eve_information_per_bit,eve_information_low,eve_information_high,eve_error_rate,world\n",
    );
    let quoted = |s: &str| format!("\"{}\"", s.replace('"', "\"\""));
    for r in rows {
        out.push_str(&format!(
            "{},{},{:.6},{},{},{},{:.6},{:.6},{:.6},{:.6},{}\n",
            quoted(&r.point),
            r.adversary,
            r.per_raw_bit,
            r.secret_bits,
            r.realised_bits,
            r.raw_bits,
            r.information[0],
            r.information[1],
            r.information[2],
            r.error_rate,
            quoted(&r.world)
        ));
    }
    out
}

/// One sentence per point, made from the numbers: for the `camera` eavesdropper whether
/// the key is over-claimed (or would be, where no key is committed), e.g. "With world.lag = 0.05 (parties: 0.0), the key claims 0.399
/// bits per raw bit more than the camera eavesdropper's realised view supports (she learns
/// 0.779 [0.771, 0.786] bits per raw bit, errs on 6.2 %)."; for the `commands` one what the
/// boundary samples alone give her.
#[must_use]
pub fn over_claim_sentences(rows: &[OverClaim]) -> Vec<String> {
    rows.iter()
        .map(|r| {
            if r.adversary == "commands" {
                return format!(
                    "With {}, the commands eavesdropper, without a camera, learns {:.3} [{:.3}, \
                     {:.3}] bits per raw bit from the boundary samples alone (errs on {:.1} %).",
                    r.world,
                    r.information[0],
                    r.information[1],
                    r.information[2],
                    100.0 * r.error_rate
                );
            }
            let verdict = if r.per_raw_bit > 0.0 && r.secret_bits == 0 {
                format!(
                    "the assumption claims {:.3} bits per raw bit more than the {} \
                     eavesdropper's realised view supports, but the parties commit no key there",
                    r.per_raw_bit, r.adversary
                )
            } else if r.per_raw_bit > 0.0 {
                format!(
                    "the key claims {:.3} bits per raw bit more than the {} eavesdropper's \
                     realised view supports",
                    r.per_raw_bit, r.adversary
                )
            } else {
                format!(
                    "the key claims {:.3} bits per raw bit less than the {} eavesdropper's \
                     realised view supports: not over-claimed",
                    -r.per_raw_bit, r.adversary
                )
            };
            let learns = if r.information[0].is_finite() {
                format!(
                    " (she learns {:.3} [{:.3}, {:.3}] bits per raw bit, errs on {:.1} %)",
                    r.information[0],
                    r.information[1],
                    r.information[2],
                    100.0 * r.error_rate
                )
            } else {
                String::new()
            };
            format!("With {}, {verdict}{learns}.", r.world)
        })
        .collect()
}

/// The section of `secrecy.md` on a world that is not the parties': the sentences, and
/// where the figure and table are (empty when every point's world is the parties').
#[must_use]
pub fn over_claim_markdown(rows: &[OverClaim]) -> String {
    if rows.is_empty() {
        return String::new();
    }
    let mut out = String::from(
        "\n## The world is not the parties' configuration\n\nThe realised views are those of \
         the eavesdroppers who know the world (docs/world.md). The over-claim is ℓ minus the ℓ \
         her realised view supports, before clamping at zero, per raw bit pooled \
         (`world-overclaim-table.csv`, figure `world-overclaim`).\n\n",
    );
    for sentence in over_claim_sentences(rows) {
        out.push_str(&format!("- {sentence}\n"));
    }
    out
}

/// Writes `world-overclaim.{svg,png,pdf,csv}` (the over-claim against the first axis, one
/// series per adversary and setting of the other axes, her information's interval drawn as
/// a second series) and `world-overclaim-table.csv` into `dir`; none when no point's world
/// differs from the parties'.
///
/// # Errors
/// A file cannot be written.
pub fn write_over_claims(
    dir: &Path,
    experiment: &Experiment,
    results: &[PointSecrecy],
) -> Result<Vec<PathBuf>, LabError> {
    let rows = over_claims(experiment, results);
    if rows.is_empty() {
        return Ok(Vec::new());
    }
    let mut files = vec![write(
        &dir.join("world-overclaim-table.csv"),
        over_claim_csv(&rows),
    )?];
    let Some(axis) = experiment.axes.first() else {
        return Ok(files);
    };
    let mut series: Vec<Series> = Vec::new();
    for r in &rows {
        let Some(x) = r.x else { continue };
        let context = if r.setting.is_empty() {
            String::new()
        } else {
            format!(", {}", r.setting)
        };
        for (label, y, interval) in [
            (
                format!("over-claim vs {} Eve{context}", r.adversary),
                r.per_raw_bit,
                None,
            ),
            (
                format!("{} Eve's information per raw bit{context}", r.adversary),
                r.information[0],
                Some((r.information[1], r.information[2])),
            ),
        ] {
            let index = series
                .iter()
                .position(|s| s.label == label)
                .unwrap_or_else(|| {
                    series.push(Series::new(label, Vec::new(), SeriesStyle::Line));
                    series.len() - 1
                });
            series[index].points.push((x, y));
            if let Some((low, high)) = interval {
                series[index].intervals.push(Interval { x, low, high });
            }
        }
    }
    if series.is_empty() {
        return Ok(files);
    }
    let chart = LineChart {
        title: format!("Over-claim against {}", axis_label(&axis.field)),
        x_label: axis_label(&axis.field),
        y_label: "bits per raw bit".into(),
        series,
        equal_aspect: false,
        log_y: false,
    };
    let base = dir.join("world-overclaim");
    files.extend(chart.save(&base).map_err(|e| LabError::Plot {
        path: base.clone(),
        message: e.to_string(),
    })?);
    Ok(files)
}
