//! How a series is drawn: the one choice that charts, their markers and their legends share.

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
