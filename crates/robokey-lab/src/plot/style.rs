//! How a series is drawn: the choices that charts, their markers and their legends share.

/// How a series' points are joined.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SeriesStyle {
    /// Solid line.
    Line,
    /// Dashed line (e.g. a reference).
    Dashed,
    /// Markers only.
    Markers,
}

/// What is drawn on a series' points.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Marks {
    /// The series' marker shape: on every point of a `Markers` series, on about a dozen
    /// points along a line, so that lines lying on top of each other stay identifiable.
    #[default]
    Shapes,
    /// Arrowheads along the line, pointing the way it goes (a path's direction).
    Arrows,
    /// Nothing: a reference line (y = x, a tolerance) has no data points to mark.
    None,
}
