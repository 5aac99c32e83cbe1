//! Line charts: trajectories (equal aspect), time series and curves with intervals. Every
//! series has its colour and its marker shape, in the legend too, so that curves lying on
//! top of each other stay identifiable; dashed series are dashed in the legend as well.

use std::path::{Path, PathBuf};

use plotters::element::DynElement;

use plotters::prelude::*;

use super::glyph::Glyph;
use super::style::SeriesStyle;

use super::{
    Axes, FONT, Figure, PALETTE, PlotError, chart_on, csv_text, legend_corner, padded_range,
    save_all,
};

/// A vertical interval at `x` (e.g. a 95 % confidence interval), in the series' units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    /// Where (x units).
    pub x: f64,
    /// Lower end.
    pub low: f64,
    /// Upper end.
    pub high: f64,
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
    /// Intervals drawn as bars with caps in the series' colour (may be empty).
    pub intervals: Vec<Interval>,
}

impl Series {
    /// A series without intervals.
    #[must_use]
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>, style: SeriesStyle) -> Self {
        Self {
            label: label.into(),
            points,
            style,
            intervals: Vec::new(),
        }
    }
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
    /// Writes `base.svg`, `base.png`, `base.pdf` and `base.csv`.
    ///
    /// # Errors
    /// A file cannot be written.
    pub fn save(&self, base: &Path) -> Result<Vec<PathBuf>, PlotError> {
        let size = if self.equal_aspect {
            (860, 900)
        } else {
            (1000, 640)
        };
        save_all(base, size, self)
    }
}

/// More points than this make a series dense (drawn thin).
const DENSE_POINTS: usize = 1_000;

/// Markers along a line: about this many per series.
const MARKERS_PER_LINE: usize = 12;

impl Figure for LineChart {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String> {
        let log_y = self.log_y;
        let scale = |y: f64| if log_y { y.log10() } else { y };
        let finite = |s: &Series| -> Vec<(f64, f64)> {
            s.points
                .iter()
                .map(|&(x, y)| (x, scale(y)))
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .collect()
        };
        let bars = |s: &Series| -> Vec<(f64, f64, f64)> {
            s.intervals
                .iter()
                .map(|i| (i.x, scale(i.low), scale(i.high)))
                .filter(|(x, lo, hi)| x.is_finite() && lo.is_finite() && hi.is_finite())
                .collect()
        };
        let all: Vec<(f64, f64)> = self
            .series
            .iter()
            .flat_map(|s| {
                finite(s).into_iter().chain(
                    bars(s)
                        .into_iter()
                        .flat_map(|(x, lo, hi)| [(x, lo), (x, hi)]),
                )
            })
            .collect();
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
        let cap = 0.006 * (x_range.1 - x_range.0);
        for (i, series) in self.series.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            // Earlier series are drawn wider, so that series lying on top of each other
            // show as nested stripes rather than hiding one another.
            let grow = (self.series.len() - 1 - i).min(3) as u32;
            // Dense series are drawn 1 px wide: plotters' raster backend joins wide strokes
            // with mitres, which spike far beyond the data at sharp reversals.
            let width = if series.points.len() > DENSE_POINTS {
                1
            } else {
                2 + grow
            };
            let style = color.stroke_width(width);
            let points = finite(series);
            let mut elements: Vec<DynElement<'static, DB, (f64, f64)>> = Vec::new();
            for (x, lo, hi) in bars(series) {
                elements.push(PathElement::new(vec![(x, lo), (x, hi)], style).into_dyn());
                for y in [lo, hi] {
                    elements
                        .push(PathElement::new(vec![(x - cap, y), (x + cap, y)], style).into_dyn());
                }
            }
            let every = match series.style {
                SeriesStyle::Markers => 1,
                _ => (points.len() / MARKERS_PER_LINE).max(1),
            };
            elements.extend(points.iter().step_by(every).map(|&at| {
                Glyph {
                    at,
                    shape: Some(i),
                    color,
                    grow: grow as i32,
                    legend: None,
                }
                .into_dyn()
            }));
            match series.style {
                SeriesStyle::Line => chart
                    .draw_series(LineSeries::new(points.clone(), style))
                    .map(|_| ()),
                SeriesStyle::Dashed => chart
                    .draw_series(DashedLineSeries::new(points.clone(), 8, 6, style))
                    .map(|_| ()),
                SeriesStyle::Markers => Ok(()),
            }
            .map_err(|e| e.to_string())?;
            let kind = series.style;
            chart
                .draw_series(elements)
                .map_err(|e| e.to_string())?
                .label(&series.label)
                .legend(move |at| Glyph {
                    at,
                    shape: Some(i),
                    color,
                    grow: 0,
                    legend: Some(kind),
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

    fn csv(&self) -> String {
        let mut out = String::from("series,x,y,low,high\n");
        for series in &self.series {
            let label = csv_text(&series.label);
            for &(x, y) in &series.points {
                let interval = series.intervals.iter().find(|i| i.x == x);
                out.push_str(&format!(
                    "{label},{x},{y},{},{}\n",
                    interval.map_or(String::new(), |i| i.low.to_string()),
                    interval.map_or(String::new(), |i| i.high.to_string()),
                ));
            }
        }
        out
    }
}
