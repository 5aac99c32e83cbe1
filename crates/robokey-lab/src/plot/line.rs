//! Line charts: trajectories (equal aspect), time series and curves with intervals. Every
//! series has its colour and its marker shape, in the legend too, so that curves lying on
//! top of each other stay identifiable; dashed series are dashed in the legend as well.

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::element::DynElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::glyph::{Glyph, Mark};
use super::legend::{Entry, Swatch};
use super::style::{Marks, SeriesStyle};
use super::{Axes, FONT, Figure, PALETTE, PlotError, chart_on, padded_range, save_all};
use crate::csv_field::quoted;

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
    /// Legend label (empty: no legend entry).
    pub label: String,
    /// Points; non-finite ones are skipped.
    pub points: Vec<(f64, f64)>,
    /// How the points are joined.
    pub style: SeriesStyle,
    /// What marks the points.
    pub marks: Marks,
    /// Intervals drawn as bars with caps in the series' colour (may be empty).
    pub intervals: Vec<Interval>,
    /// Palette index of its colour; `None`: its own index (a series that belongs to
    /// another, e.g. a curve's break-even, takes that one's colour).
    pub color: Option<usize>,
    /// Text beside each point, in order (empty: none), e.g. the setting a point stands for.
    pub notes: Vec<String>,
    /// Horizontal shift (x units) of everything drawn of the series, so that series
    /// measured at the same x sit side by side; the CSV keeps the data's x.
    pub dodge: f64,
}

impl Series {
    /// A series with its shapes on its points, without intervals or notes.
    #[must_use]
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>, style: SeriesStyle) -> Self {
        Self {
            label: label.into(),
            points,
            style,
            marks: Marks::Shapes,
            intervals: Vec::new(),
            color: None,
            notes: Vec::new(),
            dodge: 0.0,
        }
    }

    /// A dashed reference line without marks (y = x, a tolerance) through `points`.
    #[must_use]
    pub fn reference(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            marks: Marks::None,
            ..Self::new(label, points, SeriesStyle::Dashed)
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
        save_all(base, self)
    }
}

/// More points than this make a series dense (drawn thin).
const DENSE_POINTS: usize = 1_000;

/// Marks along a line: about this many per series.
const MARKS_PER_LINE: usize = 12;

/// Note font size (pixels).
const NOTE_SIZE: u32 = 14;

/// How one series is drawn: its colour, its marker shape, and how much wider than the
/// last series it is drawn (earlier series are wider, so that series lying on top of each
/// other show as nested stripes rather than hiding one another).
#[derive(Clone, Copy, Debug)]
pub(super) struct Look {
    pub color: RGBColor,
    pub shape: usize,
    pub grow: u32,
}

impl Look {
    /// Series `index` of `count`, coloured by palette index `color`.
    pub(super) fn of(index: usize, count: usize, color: usize) -> Self {
        Self {
            color: PALETTE[color % PALETTE.len()],
            shape: index,
            grow: (count - 1 - index).min(3) as u32,
        }
    }

    /// The legend entry of `series` drawn with this look.
    pub(super) fn entry(self, series: &Series) -> Entry {
        Entry {
            label: series.label.clone(),
            color: self.color,
            swatch: Swatch::Series {
                style: series.style,
                marks: series.marks,
                shape: self.shape,
            },
        }
    }
}

/// A series' drawable values: `(x, y)` and intervals `(x, low, high)`, shifted by its
/// dodge and with y on the chart's scale (log10 on a log axis); non-finite ones dropped.
pub(super) struct Scaled {
    pub points: Vec<(f64, f64)>,
    pub bars: Vec<(f64, f64, f64)>,
}

impl Scaled {
    pub(super) fn of(series: &Series, log_y: bool) -> Self {
        let scale = |y: f64| if log_y { y.log10() } else { y };
        let x = |x: f64| x + series.dodge;
        Self {
            points: series
                .points
                .iter()
                .map(|&(px, py)| (x(px), scale(py)))
                .filter(|(px, py)| px.is_finite() && py.is_finite())
                .collect(),
            bars: series
                .intervals
                .iter()
                .map(|i| (x(i.x), scale(i.low), scale(i.high)))
                .filter(|(bx, lo, hi)| bx.is_finite() && lo.is_finite() && hi.is_finite())
                .collect(),
        }
    }

    /// Every drawn value, for the axes' ranges.
    pub(super) fn extent(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.points
            .iter()
            .copied()
            .chain(self.bars.iter().flat_map(|&(x, lo, hi)| [(x, lo), (x, hi)]))
    }
}

/// The x and y ranges covering `scaled`, made square with `equal_aspect`.
pub(super) fn ranges<'a>(
    scaled: impl IntoIterator<Item = &'a Scaled>,
    equal_aspect: bool,
) -> ((f64, f64), (f64, f64)) {
    let extent: Vec<(f64, f64)> = scaled.into_iter().flat_map(Scaled::extent).collect();
    let x = padded_range(extent.iter().map(|p| p.0));
    let y = padded_range(extent.iter().map(|p| p.1));
    if !equal_aspect {
        return (x, y);
    }
    let span = (x.1 - x.0).max(y.1 - y.0);
    let centre = |r: (f64, f64)| (r.0 + r.1) / 2.0;
    let (cx, cy) = (centre(x), centre(y));
    (
        (cx - span / 2.0, cx + span / 2.0),
        (cy - span / 2.0, cy + span / 2.0),
    )
}

/// A chart context of line series.
pub(super) type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Draws `series` (its values `scaled`) on `chart` with `look`; its notes avoid the pixel
/// boxes in `taken`, to which they are added.
pub(super) fn draw_series<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    series: &Series,
    scaled: &Scaled,
    look: Look,
    taken: &mut Vec<PixelBox>,
) -> Result<(), String> {
    let x_range = chart.x_range();
    let cap = 0.006 * (x_range.end - x_range.start);
    let width = if scaled.points.len() > DENSE_POINTS {
        // Dense series are drawn 1 px wide: plotters' raster backend joins wide strokes
        // with mitres, which spike far beyond the data at sharp reversals.
        1
    } else {
        2 + look.grow
    };
    let style = look.color.stroke_width(width);
    let points = &scaled.points;
    match series.style {
        SeriesStyle::Line => chart
            .draw_series(LineSeries::new(points.iter().copied(), style))
            .map(drop),
        SeriesStyle::Dashed => chart
            .draw_series(DashedLineSeries::new(points.iter().copied(), 8, 6, style))
            .map(drop),
        SeriesStyle::Markers => Ok(()),
    }
    .map_err(|e| e.to_string())?;
    let mut elements: Vec<DynElement<'static, DB, (f64, f64)>> = Vec::new();
    for &(x, lo, hi) in &scaled.bars {
        elements.push(PathElement::new(vec![(x, lo), (x, hi)], style).into_dyn());
        for y in [lo, hi] {
            elements.push(PathElement::new(vec![(x - cap, y), (x + cap, y)], style).into_dyn());
        }
    }
    let every = match series.style {
        SeriesStyle::Markers => 1,
        _ => (points.len() / MARKS_PER_LINE).max(1),
    };
    let pixel = |p: (f64, f64)| chart.backend_coord(&p);
    for (i, &at) in points.iter().enumerate().step_by(every) {
        let mark = match series.marks {
            Marks::Shapes => Mark::Shape(look.shape),
            Marks::Arrows => {
                // The way the path goes over the stretch between neighbouring marks: a
                // jittery path's next point may point anywhere.
                let reach = (every / 2).max(1);
                let from = pixel(points[i.saturating_sub(reach)]);
                let to = pixel(points[(i + reach).min(points.len() - 1)]);
                Mark::Arrow(f64::from(to.0 - from.0), f64::from(to.1 - from.1))
            }
            Marks::None => continue,
        };
        elements.push(
            Glyph {
                at,
                mark,
                color: look.color,
                grow: look.grow as i32,
            }
            .into_dyn(),
        );
    }
    chart.draw_series(elements).map_err(|e| e.to_string())?;
    draw_notes(chart, series, scaled, taken)
}

/// A rectangle in pixels: left, top, right, bottom.
pub(super) type PixelBox = (i32, i32, i32, i32);

/// Whether two pixel boxes overlap.
fn overlap(a: PixelBox, b: PixelBox) -> bool {
    a.0 < b.2 && b.0 < a.2 && a.1 < b.3 && b.1 < a.3
}

/// Writes each note beside its point, at the first of four places (right, left, above,
/// below) that covers no earlier note, no point of the series and stays in the plot.
fn draw_notes<DB: DrawingBackend>(
    chart: &Chart<'_, DB>,
    series: &Series,
    scaled: &Scaled,
    taken: &mut Vec<PixelBox>,
) -> Result<(), String> {
    if series.notes.is_empty() {
        return Ok(());
    }
    let area = chart.plotting_area();
    let ((left, right), (top, bottom)) = {
        let (x, y) = area.get_pixel_range();
        ((x.start, x.end), (y.start, y.end))
    };
    let font = (FONT, NOTE_SIZE).into_font().color(&BLACK);
    let points: Vec<(i32, i32)> = scaled
        .points
        .iter()
        .map(|p| chart.backend_coord(p))
        .collect();
    taken.extend(points.iter().map(|&(x, y)| (x - 6, y - 6, x + 6, y + 6)));
    for (note, &(x, y)) in series.notes.iter().zip(&points) {
        let (w, h) = area
            .estimate_text_size(note, &font)
            .map_err(|e| e.to_string())?;
        let (w, h) = (w as i32, h as i32);
        let places = [
            (x + 10, y - h / 2),
            (x - 10 - w, y - h / 2),
            (x - w / 2, y - 12 - h),
            (x - w / 2, y + 12),
        ];
        let boxes = places.map(|(l, t)| (l, t, l + w, t + h));
        let inside = |b: &PixelBox| b.0 >= left && b.2 <= right && b.1 >= top && b.3 <= bottom;
        let chosen = boxes
            .iter()
            .find(|b| inside(b) && !taken.iter().any(|t| overlap(**b, *t)))
            .or_else(|| boxes.iter().find(|b| inside(b)))
            .copied()
            .unwrap_or(boxes[0]);
        taken.push(chosen);
        area.strip_coord_spec()
            .draw(&Text::new(
                note.as_str(),
                (chosen.0 - left, chosen.1 - top),
                font.pos(Pos::new(HPos::Left, VPos::Top)),
            ))
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

impl Figure for LineChart {
    fn plot_size(&self) -> (u32, u32) {
        if self.equal_aspect {
            (860, 900)
        } else {
            (1000, 640)
        }
    }

    fn legend(&self) -> Vec<Entry> {
        let count = self.series.len();
        self.series
            .iter()
            .enumerate()
            .filter(|(_, s)| !s.label.is_empty())
            .map(|(i, s)| Look::of(i, count, s.color.unwrap_or(i)).entry(s))
            .collect()
    }

    fn draw_plot<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let scaled: Vec<Scaled> = self
            .series
            .iter()
            .map(|s| Scaled::of(s, self.log_y))
            .collect();
        let (x, y) = ranges(&scaled, self.equal_aspect);
        let mut chart = chart_on(
            area,
            &Axes {
                title: &self.title,
                title_size: 24,
                x_label: &self.x_label,
                y_label: &self.y_label,
                x,
                y,
                x_ticks: 10,
                y_log10: self.log_y,
            },
        )?;
        let count = self.series.len();
        let mut taken = Vec::new();
        for (i, (series, scaled)) in self.series.iter().zip(&scaled).enumerate() {
            let look = Look::of(i, count, series.color.unwrap_or(i));
            draw_series(&mut chart, series, scaled, look, &mut taken)?;
        }
        Ok(())
    }

    fn csv(&self) -> String {
        let series: Vec<(Option<&str>, &Series)> = self.series.iter().map(|s| (None, s)).collect();
        series_csv(&series)
    }
}

/// The CSV of `series`, each with the panel it is drawn in (if any): `series,x,y,low,high`,
/// with a `panel` column first when they are drawn in panels and a `note` column last when
/// any point has one.
pub(super) fn series_csv(series: &[(Option<&str>, &Series)]) -> String {
    let panels = series.iter().any(|(panel, _)| panel.is_some());
    let noted = series.iter().any(|(_, s)| !s.notes.is_empty());
    let mut out = String::from(if panels { "panel," } else { "" });
    out.push_str("series,x,y,low,high");
    out.push_str(if noted { ",note\n" } else { "\n" });
    for (panel, s) in series {
        let label = quoted(&s.label);
        for (i, &(x, y)) in s.points.iter().enumerate() {
            if let Some(panel) = panel {
                out.push_str(&quoted(panel));
                out.push(',');
            }
            let interval = s.intervals.iter().find(|i| i.x == x);
            out.push_str(&format!(
                "{label},{x},{y},{},{}",
                interval.map_or(String::new(), |i| i.low.to_string()),
                interval.map_or(String::new(), |i| i.high.to_string()),
            ));
            if noted {
                out.push(',');
                out.push_str(&s.notes.get(i).map_or(String::new(), |n| quoted(n)));
            }
            out.push('\n');
        }
    }
    out
}
