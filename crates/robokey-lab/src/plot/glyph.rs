//! A series' marker — one of five shapes, or an arrowhead along its path — as one plotters
//! element drawn with backend primitives.

use plotters::element::{Drawable, PointCollection};
use plotters::prelude::*;
use plotters_backend::{BackendCoord, DrawingErrorKind};

/// Marker radius (pixels) of the last series; earlier ones are larger (see `grow`).
pub(super) const MARKER_SIZE: i32 = 4;

/// What a marker looks like.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Mark {
    /// Shape `n` of five, cycled: circle, triangle, square, cross, diamond.
    Shape(usize),
    /// An arrowhead pointing along `(dx, dy)` (pixels, y down).
    Arrow(f64, f64),
}

/// A marker at `at`.
pub(super) struct Glyph<C> {
    /// Where (chart or backend coordinates).
    pub at: C,
    /// Which marker.
    pub mark: Mark,
    /// Colour.
    pub color: RGBColor,
    /// How much larger than the last series' marker (pixels), so that coinciding markers
    /// stay visible behind each other.
    pub grow: i32,
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
        match points.next() {
            Some(at) => marker(backend, at, self.mark, MARKER_SIZE + self.grow, self.color),
            None => Ok(()),
        }
    }
}

/// Draws `mark` of radius `s` (pixels) centred at `(x, y)`.
pub(super) fn marker<DB: DrawingBackend>(
    backend: &mut DB,
    (x, y): BackendCoord,
    mark: Mark,
    s: i32,
    color: RGBColor,
) -> Result<(), DrawingErrorKind<DB::ErrorType>> {
    let (fill, stroke) = (color.filled(), color.stroke_width(2));
    let shape = match mark {
        Mark::Shape(shape) => shape,
        Mark::Arrow(dx, dy) => return arrowhead(backend, (x, y), (dx, dy), s + 3, &fill),
    };
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

/// A filled arrowhead of length `2·s` (pixels) centred at `(x, y)`, its tip along
/// `(dx, dy)`; nothing when the direction is undefined.
fn arrowhead<DB: DrawingBackend>(
    backend: &mut DB,
    (x, y): BackendCoord,
    (dx, dy): (f64, f64),
    s: i32,
    fill: &ShapeStyle,
) -> Result<(), DrawingErrorKind<DB::ErrorType>> {
    let norm = dx.hypot(dy);
    if norm == 0.0 || !norm.is_finite() {
        return Ok(());
    }
    let (ux, uy) = (dx / norm, dy / norm);
    let s = f64::from(s);
    let at = |along: f64, across: f64| {
        (
            x + (along * ux - across * uy).round() as i32,
            y + (along * uy + across * ux).round() as i32,
        )
    };
    backend.fill_polygon([at(s, 0.0), at(-s, 0.8 * s), at(-s, -0.8 * s)], fill)
}
