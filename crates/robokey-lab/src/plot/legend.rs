//! Legends, drawn in a column of their own to the right of the plot: no entry ever covers a
//! point, a line or an error bar, whatever the data.

use plotters::coord::Shift;
use plotters::element::{Drawable, PointCollection};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters_backend::{BackendCoord, DrawingErrorKind};

use super::FONT;
use super::glyph::{MARKER_SIZE, Mark, marker};
use super::style::{Marks, SeriesStyle};

/// What an entry shows left of its label.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Swatch {
    /// A series: its stroke (none for markers only) and what marks its points.
    Series {
        /// Solid, dashed or no stroke.
        style: SeriesStyle,
        /// Its marks.
        marks: Marks,
        /// Its marker shape.
        shape: usize,
    },
    /// A filled box (a box plot's group).
    Fill,
}

/// One legend entry.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Entry {
    /// The label.
    pub label: String,
    /// The series' colour.
    pub color: RGBColor,
    /// What is drawn beside the label.
    pub swatch: Swatch,
}

/// Label font size (pixels).
const FONT_SIZE: u32 = 16;
/// Height of one entry (pixels).
const ROW: i32 = 24;
/// Width of a swatch (pixels).
const SWATCH: i32 = 28;
/// Space between a swatch and its label, and around the column (pixels).
const GAP: i32 = 10;

/// Width (pixels) of the column that holds `entries`; 0 without entries.
pub(super) fn width(entries: &[Entry]) -> u32 {
    if entries.is_empty() {
        return 0;
    }
    let font: FontDesc = (FONT, FONT_SIZE).into_font();
    let text = entries
        .iter()
        .map(|e| font.box_size(&e.label).map_or(0, |(w, _)| w))
        .max()
        .unwrap_or(0);
    text + (3 * GAP + SWATCH) as u32
}

/// Draws `entries` one under the other in `area`, the first centred `top` pixels down.
pub(super) fn draw<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[Entry],
    top: i32,
) -> Result<(), String> {
    let font = (FONT, FONT_SIZE)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Left, VPos::Center));
    for (i, entry) in entries.iter().enumerate() {
        let y = top + i as i32 * ROW;
        area.draw(&SwatchGlyph {
            at: (GAP, y),
            swatch: entry.swatch,
            color: entry.color,
        })
        .map_err(|e| e.to_string())?;
        area.draw(&Text::new(
            entry.label.as_str(),
            (2 * GAP + SWATCH, y),
            font.clone(),
        ))
        .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// An entry's swatch, its left end at `at`.
struct SwatchGlyph {
    at: BackendCoord,
    swatch: Swatch,
    color: RGBColor,
}

impl<'a> PointCollection<'a, BackendCoord> for &'a SwatchGlyph {
    type Point = &'a BackendCoord;
    type IntoIter = std::iter::Once<&'a BackendCoord>;

    fn point_iter(self) -> Self::IntoIter {
        std::iter::once(&self.at)
    }
}

impl<DB: DrawingBackend> Drawable<DB> for SwatchGlyph {
    fn draw<I: Iterator<Item = BackendCoord>>(
        &self,
        mut points: I,
        backend: &mut DB,
        _: (u32, u32),
    ) -> Result<(), DrawingErrorKind<DB::ErrorType>> {
        let Some((x, y)) = points.next() else {
            return Ok(());
        };
        let (style, marks, shape) = match self.swatch {
            Swatch::Fill => {
                return backend.draw_rect(
                    (x, y - 7),
                    (x + SWATCH, y + 7),
                    &self.color.mix(0.5).filled(),
                    true,
                );
            }
            Swatch::Series {
                style,
                marks,
                shape,
            } => (style, marks, shape),
        };
        let stroke = self.color.stroke_width(2);
        match style {
            SeriesStyle::Line => backend.draw_line((x, y), (x + SWATCH, y), &stroke)?,
            SeriesStyle::Dashed => {
                backend.draw_line((x, y), (x + 9, y), &stroke)?;
                backend.draw_line((x + SWATCH - 9, y), (x + SWATCH, y), &stroke)?;
            }
            SeriesStyle::Markers => {}
        }
        let centre = (x + SWATCH / 2, y);
        match marks {
            Marks::Shapes => marker(backend, centre, Mark::Shape(shape), MARKER_SIZE, self.color),
            Marks::Arrows => marker(
                backend,
                centre,
                Mark::Arrow(1.0, 0.0),
                MARKER_SIZE,
                self.color,
            ),
            Marks::None => Ok(()),
        }
    }
}
