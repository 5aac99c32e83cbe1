//! Line charts: trajectories (equal aspect) and time series.

use std::path::{Path, PathBuf};

use plotters::prelude::*;

use super::{
    Axes, FONT, Figure, PALETTE, PlotError, chart_on, legend_corner, padded_range, save_both,
};

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SeriesStyle {
    /// Solid line.
    Line,
    /// Dashed line (e.g. a reference).
    Dashed,
    /// Markers only.
    Markers,
}

/// One named series of `(x, y)` points.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Points; non-finite ones are skipped.
    pub points: Vec<(f64, f64)>,
    /// Drawing style.
    pub style: SeriesStyle,
}

/// A chart of line series.
#[derive(Clone, Debug, PartialEq)]
pub struct LineChart {
    /// Title.
    pub title: String,
    /// X-axis label with unit.
    pub x_label: String,
    /// Y-axis label with unit.
    pub y_label: String,
    /// Series, drawn in order.
    pub series: Vec<Series>,
    /// Same scale on both axes (a square looks square).
    pub equal_aspect: bool,
    /// Logarithmic y axis (points with y ≤ 0 are skipped).
    pub log_y: bool,
}

impl LineChart {
    /// Writes `base.svg` and `base.png`.
    ///
    /// # Errors
    /// A file cannot be written.
    pub fn save(&self, base: &Path) -> Result<Vec<PathBuf>, PlotError> {
        let size = if self.equal_aspect {
            (860, 900)
        } else {
            (1000, 640)
        };
        save_both(base, size, self)
    }
}

impl Figure for LineChart {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String> {
        let log_y = self.log_y;
        let finite = |s: &Series| -> Vec<(f64, f64)> {
            s.points
                .iter()
                .map(|&(x, y)| (x, if log_y { y.log10() } else { y }))
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .collect()
        };
        let all: Vec<(f64, f64)> = self.series.iter().flat_map(finite).collect();
        let (mut x_range, mut y_range) = (
            padded_range(all.iter().map(|p| p.0)),
            padded_range(all.iter().map(|p| p.1)),
        );
        if self.equal_aspect {
            let span = (x_range.1 - x_range.0).max(y_range.1 - y_range.0);
            let centre = |r: (f64, f64)| (r.0 + r.1) / 2.0;
            let (cx, cy) = (centre(x_range), centre(y_range));
            x_range = (cx - span / 2.0, cx + span / 2.0);
            y_range = (cy - span / 2.0, cy + span / 2.0);
        }
        let mut chart = chart_on(
            root,
            &Axes {
                title: &self.title,
                x_label: &self.x_label,
                y_label: &self.y_label,
                x: x_range,
                y: y_range,
                x_ticks: 10,
                y_log10: log_y,
            },
        )?;
        for (i, series) in self.series.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            let style = color.stroke_width(2);
            let points = finite(series);
            let anno = match series.style {
                SeriesStyle::Line => chart.draw_series(LineSeries::new(points, style)),
                SeriesStyle::Dashed => {
                    chart.draw_series(DashedLineSeries::new(points, 8, 6, style))
                }
                SeriesStyle::Markers => chart.draw_series(
                    points
                        .into_iter()
                        .map(|p| Circle::new(p, 3, color.filled())),
                ),
            }
            .map_err(|e| e.to_string())?;
            anno.label(&series.label).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(2))
            });
        }
        chart
            .configure_series_labels()
            .label_font((FONT, 16))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK.mix(0.4))
            .position(legend_corner(&all, x_range, y_range))
            .draw()
            .map_err(|e| e.to_string())
    }
}
