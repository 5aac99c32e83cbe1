//! Small multiples: one panel per subject (e.g. per eavesdropper), all on the same axes, so
//! that series which would lie on top of each other in one chart are read side by side.
//! A label means the same series in every panel: same colour, same marker, one legend entry.

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;

use super::legend::Entry;
use super::line::{Look, Scaled, Series, draw_series, ranges, series_csv};
use super::{Axes, FONT, Figure, PlotError, chart_on, save_all};

/// One panel: its title and its series.
#[derive(Clone, Debug, PartialEq)]
pub struct Panel {
    /// Title (what the panel is about).
    pub title: String,
    /// Series, drawn in order.
    pub series: Vec<Series>,
}

/// Panels on shared axes, two columns when there are more than three.
#[derive(Clone, Debug, PartialEq)]
pub struct Panels {
    /// Title of the figure.
    pub title: String,
    /// X-axis label with unit (under the bottom row).
    pub x_label: String,
    /// Y-axis label with unit (left of the left column).
    pub y_label: String,
    /// The panels, row by row.
    pub panels: Vec<Panel>,
    /// Logarithmic y axis (points with y ≤ 0 are skipped).
    pub log_y: bool,
}

/// Height of one row of panels (pixels).
const ROW_HEIGHT: u32 = 300;
/// Height of the figure's title (pixels).
const TITLE_HEIGHT: u32 = 50;

impl Panels {
    /// Writes `base.svg`, `base.png`, `base.pdf` and `base.csv`.
    ///
    /// # Errors
    /// A file cannot be written.
    pub fn save(&self, base: &Path) -> Result<Vec<PathBuf>, PlotError> {
        save_all(base, self)
    }

    /// Columns and rows of the grid.
    fn grid(&self) -> (usize, usize) {
        let columns = if self.panels.len() > 3 { 2 } else { 1 };
        (columns, self.panels.len().div_ceil(columns).max(1))
    }

    /// The distinct series labels, in order of first appearance: a series' index among
    /// them picks its look.
    fn labels(&self) -> Vec<&str> {
        let mut labels: Vec<&str> = Vec::new();
        for series in self.panels.iter().flat_map(|p| &p.series) {
            if !labels.contains(&series.label.as_str()) {
                labels.push(&series.label);
            }
        }
        labels
    }

    fn look(&self, labels: &[&str], series: &Series) -> Look {
        let index = labels
            .iter()
            .position(|l| *l == series.label)
            .unwrap_or_default();
        Look::of(index, labels.len(), series.color.unwrap_or(index))
    }
}

impl Figure for Panels {
    fn plot_size(&self) -> (u32, u32) {
        let (_, rows) = self.grid();
        (1000, TITLE_HEIGHT + rows as u32 * ROW_HEIGHT)
    }

    fn legend(&self) -> Vec<Entry> {
        let labels = self.labels();
        labels
            .iter()
            .filter(|l| !l.is_empty())
            .filter_map(|label| {
                let series = self
                    .panels
                    .iter()
                    .flat_map(|p| &p.series)
                    .find(|s| s.label == *label)?;
                Some(self.look(&labels, series).entry(series))
            })
            .collect()
    }

    fn draw_plot<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let scaled: Vec<Vec<Scaled>> = self
            .panels
            .iter()
            .map(|p| p.series.iter().map(|s| Scaled::of(s, self.log_y)).collect())
            .collect();
        let (x, y) = ranges(scaled.iter().flatten(), false);
        let (title, cells) = area.split_vertically(TITLE_HEIGHT);
        title
            .titled(&self.title, (FONT, 24))
            .map_err(|e| e.to_string())?;
        let (columns, rows) = self.grid();
        let labels = self.labels();
        let cells = cells.split_evenly((rows, columns));
        for (i, ((panel, scaled), cell)) in self.panels.iter().zip(&scaled).zip(&cells).enumerate()
        {
            let (row, column) = (i / columns, i % columns);
            let mut chart = chart_on(
                cell,
                &Axes {
                    title: &panel.title,
                    title_size: 18,
                    x_label: if row + 1 == rows || i + columns >= self.panels.len() {
                        &self.x_label
                    } else {
                        ""
                    },
                    y_label: if column == 0 { &self.y_label } else { "" },
                    x,
                    y,
                    x_ticks: 6,
                    y_log10: self.log_y,
                },
            )?;
            let mut taken = Vec::new();
            for (series, scaled) in panel.series.iter().zip(scaled) {
                draw_series(
                    &mut chart,
                    series,
                    scaled,
                    self.look(&labels, series),
                    &mut taken,
                )?;
            }
        }
        Ok(())
    }

    fn csv(&self) -> String {
        let series: Vec<(Option<&str>, &Series)> = self
            .panels
            .iter()
            .flat_map(|p| p.series.iter().map(|s| (Some(p.title.as_str()), s)))
            .collect();
        series_csv(&series)
    }
}
