//! Box plots drawn from primitives: box from Q1 to Q3, a median line, whiskers at the
//! minimum and maximum (docs/experiments.md) — never beyond the data.

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;

use super::legend::{Entry, Swatch};
use super::style::{Marks, SeriesStyle};
use super::{Axes, Figure, PALETTE, PlotError, chart_on, padded_range, save_all};
use crate::csv_field::quoted;
use crate::stats::Summary;

/// One coloured series of boxes: values per x position.
#[derive(Clone, Debug, PartialEq)]
pub struct BoxGroup {
    /// Legend label.
    pub label: String,
    /// `(x, values)` per box.
    pub boxes: Vec<(f64, Vec<f64>)>,
}

/// A chart of box groups on a numeric x axis, with optional horizontal reference lines.
#[derive(Clone, Debug, PartialEq)]
pub struct BoxChart {
    /// Title.
    pub title: String,
    /// X-axis label with unit.
    pub x_label: String,
    /// Y-axis label with unit.
    pub y_label: String,
    /// Groups, side by side at each x.
    pub groups: Vec<BoxGroup>,
    /// `(label, y)` dashed horizontal lines.
    pub reference_lines: Vec<(String, f64)>,
}

/// Where one box is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxGeometry {
    /// Centre x.
    pub x: f64,
    /// Half the box width (x units).
    pub half_width: f64,
    /// The statistics drawn: box Q1–Q3, median line, whiskers at min and max.
    pub summary: Summary,
}

impl BoxChart {
    /// The boxes to draw: per group, per x, offset so groups sit side by side; width a
    /// fraction of the smallest x spacing. Empty or all-NaN boxes are skipped.
    #[must_use]
    pub fn geometry(&self) -> Vec<Vec<BoxGeometry>> {
        let mut xs: Vec<f64> = self
            .groups
            .iter()
            .flat_map(|g| g.boxes.iter().map(|b| b.0))
            .collect();
        xs.sort_by(f64::total_cmp);
        xs.dedup();
        let spacing = xs
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(f64::INFINITY, f64::min);
        let spacing = if spacing.is_finite() && spacing > 0.0 {
            spacing
        } else {
            1.0
        };
        let groups = self.groups.len().max(1) as f64;
        let slot = 0.8 * spacing / groups;
        self.groups
            .iter()
            .enumerate()
            .map(|(g, group)| {
                let offset = (g as f64 - (groups - 1.0) / 2.0) * slot;
                group
                    .boxes
                    .iter()
                    .filter_map(|(x, values)| {
                        Some(BoxGeometry {
                            x: x + offset,
                            half_width: 0.4 * slot,
                            summary: Summary::of(values)?,
                        })
                    })
                    .collect()
            })
            .collect()
    }

    /// Writes `base.svg`, `base.png`, `base.pdf` and `base.csv`.
    ///
    /// # Errors
    /// A file cannot be written.
    pub fn save(&self, base: &Path) -> Result<Vec<PathBuf>, PlotError> {
        save_all(base, self)
    }

    /// The colour of group `g`, and after the groups, of reference line `g − groups`.
    fn color(&self, g: usize) -> RGBColor {
        PALETTE[g % PALETTE.len()]
    }
}

impl Figure for BoxChart {
    fn plot_size(&self) -> (u32, u32) {
        (1000, 640)
    }

    fn legend(&self) -> Vec<Entry> {
        let groups = self.groups.iter().enumerate().map(|(g, group)| Entry {
            label: group.label.clone(),
            color: self.color(g),
            swatch: Swatch::Fill,
        });
        let lines = self
            .reference_lines
            .iter()
            .enumerate()
            .map(|(i, (label, _))| Entry {
                label: label.clone(),
                color: self.color(self.groups.len() + i),
                swatch: Swatch::Series {
                    style: SeriesStyle::Dashed,
                    marks: Marks::None,
                    shape: 0,
                },
            });
        groups.chain(lines).collect()
    }

    fn draw_plot<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let geometry = self.geometry();
        let boxes = || geometry.iter().flatten();
        let x_range = padded_range(
            boxes().flat_map(|b| [b.x - 2.0 * b.half_width, b.x + 2.0 * b.half_width]),
        );
        let y_range = padded_range(
            boxes()
                .flat_map(|b| [b.summary.min, b.summary.max])
                .chain(self.reference_lines.iter().map(|r| r.1)),
        );
        let x_values = self.groups.iter().flat_map(|g| g.boxes.iter()).count();
        let mut chart = chart_on(
            area,
            &Axes {
                title: &self.title,
                title_size: 24,
                x_label: &self.x_label,
                y_label: &self.y_label,
                x: x_range,
                y: y_range,
                x_ticks: x_values.clamp(2, 12),
                y_log10: false,
            },
        )?;
        for (g, shapes) in geometry.iter().enumerate() {
            let color = self.color(g);
            let mut elements: Vec<DynElement<'static, DB, (f64, f64)>> = Vec::new();
            for b in shapes {
                let s = b.summary;
                let (left, right) = (b.x - b.half_width, b.x + b.half_width);
                let cap = b.half_width * 0.5;
                elements.push(
                    Rectangle::new([(left, s.q1), (right, s.q3)], color.mix(0.25).filled())
                        .into_dyn(),
                );
                elements.push(
                    Rectangle::new([(left, s.q1), (right, s.q3)], color.stroke_width(2)).into_dyn(),
                );
                elements.push(
                    PathElement::new(
                        vec![(left, s.median), (right, s.median)],
                        BLACK.stroke_width(3),
                    )
                    .into_dyn(),
                );
                for (from, to) in [(s.q3, s.max), (s.q1, s.min)] {
                    elements.push(
                        PathElement::new(vec![(b.x, from), (b.x, to)], color.stroke_width(2))
                            .into_dyn(),
                    );
                    elements.push(
                        PathElement::new(
                            vec![(b.x - cap, to), (b.x + cap, to)],
                            color.stroke_width(2),
                        )
                        .into_dyn(),
                    );
                }
            }
            chart.draw_series(elements).map_err(|e| e.to_string())?;
        }
        for (i, (_, y)) in self.reference_lines.iter().enumerate() {
            let color = self.color(self.groups.len() + i);
            chart
                .draw_series(DashedLineSeries::new(
                    [(x_range.0, *y), (x_range.1, *y)],
                    10,
                    6,
                    color.stroke_width(2),
                ))
                .map_err(|e| e.to_string())?;
        }
        Ok(())
    }

    fn csv(&self) -> String {
        let mut out = String::from("group,x,count,min,q1,median,q3,max,mean\n");
        for (group, boxes) in self.groups.iter().zip(self.geometry()) {
            let label = quoted(&group.label);
            // The unshifted x of each box: the group's own x values, in order.
            let xs = group.boxes.iter().filter(|b| Summary::of(&b.1).is_some());
            for ((x, _), b) in xs.zip(boxes) {
                let s = b.summary;
                out.push_str(&format!(
                    "{label},{x},{},{},{},{},{},{},{}\n",
                    s.count, s.min, s.q1, s.median, s.q3, s.max, s.mean
                ));
            }
        }
        for (label, y) in &self.reference_lines {
            out.push_str(&format!("{},,,,,{y},,,\n", quoted(label)));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chart() -> BoxChart {
        BoxChart {
            title: "Test box chart".into(),
            x_label: "Δv (m/s)".into(),
            y_label: "%".into(),
            groups: vec![
                BoxGroup {
                    label: "a".into(),
                    boxes: vec![
                        (0.02, vec![1.0, 2.0, 3.0, 4.0]),
                        (0.03, vec![5.0, 9.0, 7.0]),
                    ],
                },
                BoxGroup {
                    label: "b".into(),
                    boxes: vec![(0.02, vec![2.0]), (0.03, vec![])],
                },
            ],
            reference_lines: vec![("ref".into(), 6.0)],
        }
    }

    #[test]
    fn boxes_show_hand_computed_quartiles_and_never_leave_the_data() {
        let geometry = chart().geometry();
        let first = geometry[0][0].summary;
        assert_eq!(
            (first.q1, first.median, first.q3, first.min, first.max),
            (1.75, 2.5, 3.25, 1.0, 4.0)
        );
        let second = geometry[0][1].summary;
        assert_eq!((second.q1, second.median, second.q3), (6.0, 7.0, 8.0));
        assert_eq!(geometry[1].len(), 1, "the empty box is skipped");
        // Groups sit side by side, without overlapping.
        assert!(
            geometry[0][0].x + geometry[0][0].half_width
                <= geometry[1][0].x - geometry[1][0].half_width + 1e-12
        );
    }

    #[test]
    fn saves_svg_png_pdf_and_csv() {
        let dir = std::env::temp_dir().join(format!("robokey-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let files = chart().save(&dir.join("boxes")).unwrap();
        let svg = std::fs::read_to_string(&files[0]).unwrap();
        assert!(svg.contains("Test box chart"));
        assert!(std::fs::metadata(&files[1]).unwrap().len() > 1000);
        let pdf = std::fs::read(&files[2]).unwrap();
        assert!(pdf.starts_with(b"%PDF"));
        // The bundled font is embedded (subset), not referenced.
        assert!(pdf.windows(8).any(|w| w == b"FontFile"), "no embedded font");
        let csv = std::fs::read_to_string(&files[3]).unwrap();
        assert_eq!(
            csv.lines().collect::<Vec<_>>(),
            [
                "group,x,count,min,q1,median,q3,max,mean",
                "\"a\",0.02,4,1,1.75,2.5,3.25,4,2.5",
                "\"a\",0.03,3,5,6,7,8,9,7",
                "\"b\",0.02,1,2,2,2,2,2,2",
                "\"ref\",,,,,6,,,",
            ]
        );
        let empty = BoxChart {
            groups: Vec::new(),
            ..chart()
        };
        empty.save(&dir.join("empty")).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
