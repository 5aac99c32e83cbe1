//! Figures as SVG and PNG, drawn with plotters and a bundled font (DejaVu Sans, licence in
//! `assets/DejaVuSans.LICENSE`), so no system fonts are needed. Box plots are drawn from
//! primitives with [`crate::stats::Summary`]: plotters' own whiskers are wrong.

mod boxes;
mod line;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

pub use boxes::{BoxChart, BoxGeometry, BoxGroup};
pub use line::{LineChart, Series, SeriesStyle};

/// A figure could not be drawn or written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlotError {
    /// The backend failed (file not writable, encoding error).
    #[error("{path}: {message}")]
    Draw {
        /// The file.
        path: PathBuf,
        /// What failed.
        message: String,
    },
}

/// Font family name under which the bundled font is registered.
const FONT: &str = "sans-serif";

/// Registers the bundled font once.
fn register_font() {
    static DONE: OnceLock<()> = OnceLock::new();
    DONE.get_or_init(|| {
        let bytes: &'static [u8] = include_bytes!("../../assets/DejaVuSans.ttf");
        // The bundled file is a valid TrueType font; failure would be a packaging bug.
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, bytes);
    });
}

/// Series colours, colour-blind safe (Okabe–Ito).
const PALETTE: [RGBColor; 6] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
];

/// Something drawable on any plotters backend.
trait Figure {
    /// Draws the figure on `root`.
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String>;
}

/// Draws `figure` into `base.svg` and `base.png` of `size` pixels.
fn save_both(
    base: &Path,
    size: (u32, u32),
    figure: &impl Figure,
) -> Result<Vec<PathBuf>, PlotError> {
    register_font();
    let svg = base.with_extension("svg");
    let png = base.with_extension("png");
    let fail = |path: &Path, message: String| PlotError::Draw {
        path: path.to_path_buf(),
        message,
    };
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        figure.draw(&root).map_err(|m| fail(&svg, m))?;
        root.present().map_err(|e| fail(&svg, e.to_string()))?;
    }
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        figure.draw(&root).map_err(|m| fail(&png, m))?;
        root.present().map_err(|e| fail(&png, e.to_string()))?;
    }
    Ok(vec![svg, png])
}

/// The axes every chart shares.
struct Axes<'a> {
    title: &'a str,
    x_label: &'a str,
    y_label: &'a str,
    x: (f64, f64),
    y: (f64, f64),
    /// Number of x tick labels.
    x_ticks: usize,
    /// The y values are `log10` of the quantity; ticks show the quantity.
    y_log10: bool,
}

/// A chart context on `root` with a title, labelled axes and light grid, white background.
fn chart_on<'a, DB: DrawingBackend>(
    root: &'a DrawingArea<DB, plotters::coord::Shift>,
    axes: &Axes<'_>,
) -> Result<ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>, String> {
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let mut chart = ChartBuilder::on(root)
        .caption(axes.title, (FONT, 24))
        .margin(20)
        .x_label_area_size(55)
        .y_label_area_size(75)
        .build_cartesian_2d(axes.x.0..axes.x.1, axes.y.0..axes.y.1)
        .map_err(|e| e.to_string())?;
    let ticks_of_log10 = |v: &f64| format!("{}", significant(10f64.powf(*v)));
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(axes.x_label)
        .y_desc(axes.y_label)
        .label_style((FONT, 15))
        .axis_desc_style((FONT, 18))
        .x_labels(axes.x_ticks)
        .light_line_style(WHITE.mix(0.0));
    if axes.y_log10 {
        mesh.y_label_formatter(&ticks_of_log10);
    }
    mesh.draw().map_err(|e| e.to_string())?;
    Ok(chart)
}

/// `x` rounded to two significant digits.
fn significant(x: f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let scale = 10f64.powi(1 - x.abs().log10().floor() as i32);
    (x * scale).round() / scale
}

/// A `[lo, hi]` range covering `values` with a 5 % margin (a unit span when degenerate).
fn padded_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let span = hi - lo;
    if span <= 0.0 {
        let pad = if lo == 0.0 { 1.0 } else { lo.abs() * 0.1 };
        return (lo - pad, hi + pad);
    }
    (lo - 0.05 * span, hi + 0.05 * span)
}

/// The legend goes in the corner (a 35 % × 30 % region of the plot), or the centre, holding
/// the fewest of `points`.
fn legend_corner(points: &[(f64, f64)], x: (f64, f64), y: (f64, f64)) -> SeriesLabelPosition {
    // Regions as fractions of the axes: (position, x from, x to, y from, y to).
    let regions = [
        (SeriesLabelPosition::UpperRight, 0.65, 1.0, 0.7, 1.0),
        (SeriesLabelPosition::UpperLeft, 0.0, 0.35, 0.7, 1.0),
        (SeriesLabelPosition::LowerRight, 0.65, 1.0, 0.0, 0.3),
        (SeriesLabelPosition::LowerLeft, 0.0, 0.35, 0.0, 0.3),
        (SeriesLabelPosition::MiddleMiddle, 0.3, 0.7, 0.35, 0.65),
    ];
    let fraction = |v: f64, r: (f64, f64)| (v - r.0) / (r.1 - r.0);
    regions
        .into_iter()
        .min_by_key(|&(_, x0, x1, y0, y1)| {
            points
                .iter()
                .filter(|&&(px, py)| {
                    let (fx, fy) = (fraction(px, x), fraction(py, y));
                    (x0..=x1).contains(&fx) && (y0..=y1).contains(&fy)
                })
                .count()
        })
        .map_or(SeriesLabelPosition::UpperRight, |r| r.0)
}
