//! A series' marker, and its legend glyph (a solid or dashed stroke with the marker on it),
//! as one plotters element drawn with backend primitives.

use plotters::element::{Drawable, PointCollection};
use plotters::prelude::*;
use plotters_backend::{BackendCoord, DrawingErrorKind};

use super::style::SeriesStyle;

/// Marker radius (pixels) of the last series; earlier ones are larger (see `size`).
const MARKER_SIZE: i32 = 4;
/// Legend glyph width (pixels).
const LEGEND_WIDTH: i32 = 26;

/// A marker of shape `shape` (cycled over five) at `at`, or with `legend`, the legend glyph
/// of a series of that style starting at `at`.
pub struct Glyph<C> {
    /// Where (chart or backend coordinates).
    pub at: C,
    /// Which shape: circle, triangle, square, cross, diamond; none for a bare stroke.
    pub shape: Option<usize>,
    /// Colour.
    pub color: RGBColor,
    /// How much larger than the last series' marker (pixels), so that coinciding markers
    /// stay visible behind each other.
    pub grow: i32,
    /// Draw the legend glyph of a series of this style instead of a bare marker.
    pub legend: Option<SeriesStyle>,
}

impl<'a, C: 'a> PointCollection<'a, C> for &'a Glyph<C> {
    type Point = &'a C;
    type IntoIter = std::iter::Once<&'a C>;

    fn point_iter(self) -> Self::IntoIter {
        std::iter::once(&self.at)
    }
}

impl<C, DB: DrawingBackend> Drawable<DB> for Glyph<C> {
    fn draw<I: Iterator<Item = BackendCoord>>(
        &self,
        mut points: I,
        backend: &mut DB,
        _: (u32, u32),
    ) -> Result<(), DrawingErrorKind<DB::ErrorType>> {
        let Some((x, y)) = points.next() else {
            return Ok(());
        };
        let stroke = self.color.stroke_width(2);
        let centre = match self.legend {
            None => (x, y),
            Some(style) => {
                match style {
                    SeriesStyle::Line => {
                        backend.draw_line((x, y), (x + LEGEND_WIDTH, y), &stroke)?
                    }
                    SeriesStyle::Dashed => {
                        backend.draw_line((x, y), (x + 8, y), &stroke)?;
                        backend.draw_line((x + 18, y), (x + LEGEND_WIDTH, y), &stroke)?;
                    }
                    SeriesStyle::Markers => {}
                }
                (x + LEGEND_WIDTH / 2, y)
            }
        };
        match self.shape {
            Some(shape) => marker(backend, centre, shape, MARKER_SIZE + self.grow, self.color),
            None => Ok(()),
        }
    }
}

/// Draws marker `shape` of radius `s` (pixels) centred at `(x, y)`.
fn marker<DB: DrawingBackend>(
    backend: &mut DB,
    (x, y): BackendCoord,
    shape: usize,
    s: i32,
    color: RGBColor,
) -> Result<(), DrawingErrorKind<DB::ErrorType>> {
    let (fill, stroke) = (color.filled(), color.stroke_width(2));
    match shape % 5 {
        0 => backend.draw_circle((x, y), s as u32, &fill, true),
        1 => backend.fill_polygon(
            [(x, y - s - 1), (x + s + 1, y + s), (x - s - 1, y + s)],
            &fill,
        ),
        2 => backend.draw_rect((x - s, y - s), (x + s, y + s), &fill, true),
        3 => {
            backend.draw_line((x - s, y - s), (x + s, y + s), &stroke)?;
            backend.draw_line((x - s, y + s), (x + s, y - s), &stroke)
        }
        _ => backend.fill_polygon(
            [
                (x, y - s - 1),
                (x + s + 1, y),
                (x, y + s + 1),
                (x - s - 1, y),
            ],
            &fill,
        ),
    }
}
