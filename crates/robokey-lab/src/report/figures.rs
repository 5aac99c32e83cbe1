//! The figures and numbers reports share: trajectories, box charts, medians, and numbers
//! with a dash where undefined.

use std::path::{Path, PathBuf};

use robokey::sim::TraceRow;

use crate::error::LabError;
use crate::plot::{BoxChart, BoxGroup, LineChart, Marks, Series, SeriesStyle};
use crate::stats::Summary;

/// Draws a trajectory figure: each named robot path with arrowheads along it (the way it
/// goes), the reference of the first trace, and where the robot starts; `steps` limits the
/// figure to the first steps (e.g. one lap).
///
/// # Errors
/// The figure cannot be written.
pub fn trajectory_figure(
    base: &Path,
    paths: &[(&str, &[TraceRow])],
    steps: Option<usize>,
) -> Result<Vec<PathBuf>, LabError> {
    let take = steps.map_or(usize::MAX, |s| s + 1);
    let mut series: Vec<Series> = paths
        .iter()
        .map(|(label, rows)| Series {
            marks: Marks::Arrows,
            ..Series::new(
                (*label).to_owned(),
                rows.iter()
                    .take(take)
                    .map(|r| (r.pose[0], r.pose[1]))
                    .collect(),
                SeriesStyle::Line,
            )
        })
        .collect();
    // The reference last, on top of the robot paths.
    if let Some((_, rows)) = paths.first() {
        series.push(Series::new(
            "reference",
            rows.iter()
                .take(take)
                .map(|r| (r.reference[0], r.reference[1]))
                .collect(),
            SeriesStyle::Dashed,
        ));
        if let Some(start) = rows.first() {
            series.push(Series {
                notes: vec!["start".to_owned()],
                ..Series::new(
                    "start",
                    vec![(start.pose[0], start.pose[1])],
                    SeriesStyle::Markers,
                )
            });
        }
    }
    let chart = LineChart {
        title: "Trajectory".into(),
        x_label: "x (m)".into(),
        y_label: "y (m)".into(),
        series,
        equal_aspect: true,
        log_y: false,
    };
    chart.save(base).map_err(|e| LabError::Plot {
        path: base.to_path_buf(),
        message: e.to_string(),
    })
}

/// Groups `(x, y)` pairs into boxes per distinct x.
pub(crate) fn boxes(pairs: &[(f64, f64)]) -> Vec<(f64, Vec<f64>)> {
    let mut out: Vec<(f64, Vec<f64>)> = Vec::new();
    for &(x, y) in pairs {
        match out.iter_mut().find(|(bx, _)| *bx == x) {
            Some((_, ys)) => ys.push(y),
            None => out.push((x, vec![y])),
        }
    }
    out
}

/// Draws a box chart into `base`.{svg,png,pdf,csv}.
pub(crate) fn box_chart(
    title: &str,
    x_label: &str,
    y_label: &str,
    groups: Vec<BoxGroup>,
    reference_lines: Vec<(String, f64)>,
    base: &Path,
) -> Result<Vec<PathBuf>, LabError> {
    let chart = BoxChart {
        title: title.into(),
        x_label: x_label.into(),
        y_label: y_label.into(),
        groups,
        reference_lines,
    };
    chart.save(base).map_err(|e| LabError::Plot {
        path: base.to_path_buf(),
        message: e.to_string(),
    })
}

/// A number with `digits` decimals, or – when undefined.
pub(crate) fn fmt(x: Option<f64>, digits: usize) -> String {
    x.map_or_else(|| "–".into(), |x| format!("{x:.digits$}"))
}

/// The median, if any value.
pub(crate) fn median_of(values: &[f64]) -> Option<f64> {
    Summary::of(values).map(|s| s.median)
}
