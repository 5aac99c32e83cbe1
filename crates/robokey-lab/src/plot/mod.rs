//! Figures as SVG, PNG and vector PDF, each with the CSV of what it draws, drawn with
//! plotters and a bundled font (DejaVu Sans, licence in `assets/DejaVuSans.LICENSE`,
//! embedded in the PDF), so no system fonts are needed. Box plots are drawn from primitives
//! with [`crate::stats::Summary`]: plotters' own whiskers are wrong.

mod boxes;
mod glyph;
mod legend;
mod line;
mod panels;
mod style;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

pub use boxes::{BoxChart, BoxGeometry, BoxGroup};
pub use line::{Interval, LineChart, Series};
pub use panels::{Panel, Panels};
pub use style::{Marks, SeriesStyle};

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

/// The bundled font.
const FONT_BYTES: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");

/// Registers the bundled font once.
fn register_font() {
    static DONE: OnceLock<()> = OnceLock::new();
    DONE.get_or_init(|| {
        // The bundled file is a valid TrueType font; failure would be a packaging bug.
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, FONT_BYTES);
    });
}

/// Series colours, colour-blind safe (Okabe–Ito), ordered so that the similar pairs (blue
/// and sky blue, vermilion and orange) are as far apart as eight colours allow.
const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(0, 0, 0),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(240, 228, 66),
];

/// A figure: a plot drawable on any plotters backend, its legend, drawn in a column of its
/// own to the right of the plot, and the data it draws.
trait Figure {
    /// Size of the plot (pixels), the legend's column excluded.
    fn plot_size(&self) -> (u32, u32);

    /// The legend's entries, in order.
    fn legend(&self) -> Vec<legend::Entry>;

    /// Draws the plot — title, axes, data — on `area`.
    fn draw_plot<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<(), String>;

    /// The data drawn, as CSV with a header, for people who restyle the figure.
    fn csv(&self) -> String;
}

/// Where the legend's first entry is centred, from the top (pixels): level with the top of
/// a plot's axes, under its title.
const LEGEND_TOP: i32 = 76;

/// Draws `figure` on `root`: a white background, the plot, and its legend column (of
/// `legend_width` pixels) at the right.
fn draw_figure<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    figure: &impl Figure,
    legend_width: u32,
) -> Result<(), String> {
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let entries = figure.legend();
    if entries.is_empty() {
        return figure.draw_plot(root);
    }
    let (plot, column) = root.split_horizontally(root.dim_in_pixel().0 - legend_width);
    figure.draw_plot(&plot)?;
    legend::draw(&column, &entries, LEGEND_TOP)
}

/// A PDF of `svg` with the bundled font embedded (vector: nothing rasterised).
fn svg_to_pdf(svg: &str) -> Result<Vec<u8>, String> {
    let mut options = svg2pdf::usvg::Options::default();
    let fonts = options.fontdb_mut();
    fonts.load_font_data(FONT_BYTES.to_vec());
    fonts.set_sans_serif_family("DejaVu Sans");
    let tree = svg2pdf::usvg::Tree::from_str(svg, &options).map_err(|e| e.to_string())?;
    svg2pdf::to_pdf(
        &tree,
        svg2pdf::ConversionOptions::default(),
        svg2pdf::PageOptions::default(),
    )
    .map_err(|e| e.to_string())
}

/// Draws `figure` into `base.svg`, `base.png` and `base.pdf`, and writes its data to
/// `base.csv`.
fn save_all(base: &Path, figure: &impl Figure) -> Result<Vec<PathBuf>, PlotError> {
    register_font();
    let legend_width = legend::width(&figure.legend());
    let (width, height) = figure.plot_size();
    let size = (width + legend_width, height);
    let svg = base.with_extension("svg");
    let png = base.with_extension("png");
    let fail = |path: &Path, message: String| PlotError::Draw {
        path: path.to_path_buf(),
        message,
    };
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        draw_figure(&root, figure, legend_width).map_err(|m| fail(&svg, m))?;
        root.present().map_err(|e| fail(&svg, e.to_string()))?;
    }
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        draw_figure(&root, figure, legend_width).map_err(|m| fail(&png, m))?;
        root.present().map_err(|e| fail(&png, e.to_string()))?;
    }
    let pdf = base.with_extension("pdf");
    let drawn = std::fs::read_to_string(&svg).map_err(|e| fail(&svg, e.to_string()))?;
    std::fs::write(&pdf, svg_to_pdf(&drawn).map_err(|m| fail(&pdf, m))?)
        .map_err(|e| fail(&pdf, e.to_string()))?;
    let csv = base.with_extension("csv");
    std::fs::write(&csv, figure.csv()).map_err(|e| fail(&csv, e.to_string()))?;
    Ok(vec![svg, png, pdf, csv])
}

/// The axes every chart shares.
struct Axes<'a> {
    title: &'a str,
    /// Title font size (pixels).
    title_size: u32,
    x_label: &'a str,
    y_label: &'a str,
    x: (f64, f64),
    y: (f64, f64),
    /// Number of x tick labels.
    x_ticks: usize,
    /// The y values are `log10` of the quantity; ticks show the quantity.
    y_log10: bool,
}

/// A chart context on `area` with a title, labelled axes and a light grid.
fn chart_on<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    axes: &Axes<'_>,
) -> Result<ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>, String> {
    let mut chart = ChartBuilder::on(area)
        .caption(axes.title, (FONT, axes.title_size))
        .margin(20)
        .x_label_area_size(55)
        .y_label_area_size(75)
        .build_cartesian_2d(axes.x.0..axes.x.1, axes.y.0..axes.y.1)
        .map_err(|e| e.to_string())?;
    let ticks_of_log10 = |v: &f64| tick_label(10f64.powf(*v), 2);
    let ticks = |v: &f64| tick_label(*v, 6);
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(axes.x_label)
        .y_desc(axes.y_label)
        .label_style((FONT, 15))
        .axis_desc_style((FONT, 18))
        .x_labels(axes.x_ticks)
        .x_label_formatter(&ticks)
        .light_line_style(WHITE.mix(0.0));
    if axes.y_log10 {
        mesh.y_label_formatter(&ticks_of_log10);
    } else {
        mesh.y_label_formatter(&ticks);
    }
    mesh.draw().map_err(|e| e.to_string())?;
    Ok(chart)
}

/// `x` rounded to `digits` significant digits, written without a trailing `.0` (a tick at
/// 1000 reads "1000", not "1000.0").
fn tick_label(x: f64, digits: i32) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let scale = 10f64.powi(digits - 1 - x.abs().log10().floor() as i32);
    let rounded = (x * scale).round() / scale;
    if rounded.fract() == 0.0 && rounded.abs() < 1e15 {
        format!("{rounded:.0}")
    } else {
        format!("{rounded}")
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_have_no_spurious_decimals() {
        assert_eq!(tick_label(1000.0, 6), "1000");
        assert_eq!(tick_label(0.30000000000000004, 6), "0.3");
        assert_eq!(tick_label(0.035, 6), "0.035");
        assert_eq!(tick_label(10f64.powf(-3.0), 2), "0.001");
        assert_eq!(tick_label(0.0, 6), "0");
    }
}
