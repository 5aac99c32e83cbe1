//! `trace.csv` of one run — written as the run goes, read back row by row, the rows a
//! figure draws, where a sweep keeps a point's — and one run's metrics for the terminal.

use std::collections::VecDeque;
use std::fmt::{Display, Write as _};
use std::io::{self, Write};

use robokey::Metrics;
use robokey::private::PrivateRun;
use robokey::sim::TraceRow;

use crate::error::LabError;

/// Writes `trace.csv` as the rows come: the header on creation, then one line per row, with
/// exactly the columns of docs/experiments.md (N + 1 rows; undefined cells empty).
pub struct TraceCsv<W: Write> {
    out: W,
    line: String,
}

impl<W: Write> TraceCsv<W> {
    /// Writes the header to `out`.
    ///
    /// # Errors
    /// `out` fails.
    pub fn new(mut out: W) -> io::Result<Self> {
        writeln!(out, "{}", TraceRow::COLUMNS.join(","))?;
        Ok(Self {
            out,
            line: String::new(),
        })
    }

    /// Writes one row.
    ///
    /// # Errors
    /// `out` fails.
    pub fn write(&mut self, row: &TraceRow) -> io::Result<()> {
        self.line.clear();
        let mut cells = Cells {
            line: &mut self.line,
            first: true,
        };
        cells.value(row.k);
        cells.value(row.t);
        cells.reals(Some(&row.reference));
        cells.reals(Some(&row.pose));
        cells.reals(Some(&row.measurement));
        cells.reals(row.nominal.as_ref());
        cells.reals(row.u0.as_ref());
        cells.reals(row.u1.as_ref());
        cells.option(row.bit);
        cells.reals(row.dhat.as_ref());
        cells.reals(row.xhat.as_ref());
        cells.option(row.bhat);
        cells.option(row.bhat_eve);
        cells.option(row.bit_omega);
        cells.reals(row.camera.as_ref());
        self.line.push('\n');
        self.out.write_all(self.line.as_bytes())
    }

    /// Flushes and returns the writer.
    ///
    /// # Errors
    /// `out` fails.
    pub fn finish(mut self) -> io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

/// Reads a `trace.csv` back row by row (`origin` names it in errors), handing each row to
/// `sink` in order: the inverse of [`TraceCsv`], exact because every real is written in its
/// shortest round-trip form. Memory does not grow with the number of rows.
///
/// # Errors
/// A wrong header, a row with the wrong number of cells, a cell that does not parse, or the
/// reader fails.
pub fn read_trace(
    text: impl io::BufRead,
    origin: &std::path::Path,
    mut sink: impl FnMut(TraceRow),
) -> Result<(), LabError> {
    let bad = |line: usize, message: String| LabError::Malformed {
        place: format!("{}:{line}", origin.display()),
        message,
    };
    let mut lines = text.lines();
    let header = lines
        .next()
        .transpose()
        .map_err(crate::error::io_at(origin))?;
    if header.as_deref() != Some(TraceRow::COLUMNS.join(",").as_str()) {
        return Err(bad(1, "not a trace (header differs)".into()));
    }
    for (i, line) in lines.enumerate() {
        let line = line.map_err(crate::error::io_at(origin))?;
        let mut cells = TraceCells(line.split(','));
        let row = cells.row().map_err(|why| bad(i + 2, why))?;
        if cells.0.next().is_some() {
            return Err(bad(i + 2, "too many cells".into()));
        }
        sink(row);
    }
    Ok(())
}

/// Where a sweep folder `dir` keeps the trace of point `point`'s replicate 0.
#[must_use]
pub fn point_trace_path(dir: &std::path::Path, point: usize) -> std::path::PathBuf {
    dir.join("traces").join(format!("point-{point}.csv"))
}

/// The paths a trajectory figure draws of the trace file at `path` ([`DrawnRows`]), read
/// without holding the whole trace.
///
/// # Errors
/// As [`read_trace`], or the file cannot be opened.
pub fn drawn_trace(path: &std::path::Path) -> Result<Vec<Vec<TraceRow>>, LabError> {
    let file = std::fs::File::open(path).map_err(crate::error::io_at(path))?;
    let mut drawn = DrawnRows::default();
    read_trace(io::BufReader::new(file), path, |row| drawn.push(row))?;
    Ok(drawn.into_paths())
}

/// Each drawn path with its label: `label` for a whole run, `label, steps a–b` for each
/// end of a long one.
#[must_use]
pub fn labelled_paths<'a>(
    label: &str,
    paths: &'a [Vec<TraceRow>],
) -> Vec<(String, &'a [TraceRow])> {
    let k = |row: Option<&TraceRow>| row.map_or(0, |r| r.k);
    paths
        .iter()
        .map(|p| {
            let text = match paths {
                [_] => label.to_owned(),
                _ => format!("{label}, steps {}–{}", k(p.first()), k(p.last())),
            };
            (text, p.as_slice())
        })
        .collect()
}

/// The cells of one trace line, read in column order.
struct TraceCells<'a>(std::str::Split<'a, char>);

impl TraceCells<'_> {
    fn option<T: std::str::FromStr>(&mut self) -> Result<Option<T>, String> {
        match self.0.next() {
            None => Err("too few cells".into()),
            Some("") => Ok(None),
            Some(cell) => cell
                .parse()
                .map(Some)
                .map_err(|_| format!("`{cell}` is not a number")),
        }
    }

    fn value<T: std::str::FromStr>(&mut self) -> Result<T, String> {
        self.option()?
            .ok_or_else(|| "an empty cell where a value belongs".into())
    }

    fn reals<const N: usize>(&mut self) -> Result<Option<[f64; N]>, String> {
        let mut values = [0.0; N];
        let mut defined = 0;
        for value in &mut values {
            if let Some(x) = self.option()? {
                *value = x;
                defined += 1;
            }
        }
        match defined {
            0 => Ok(None),
            n if n == N => Ok(Some(values)),
            _ => Err("a vector with some cells empty".into()),
        }
    }

    fn required<const N: usize>(&mut self) -> Result<[f64; N], String> {
        self.reals()?
            .ok_or_else(|| "empty cells where a vector belongs".into())
    }

    /// The row, in the order [`TraceCsv::write`] writes it.
    fn row(&mut self) -> Result<TraceRow, String> {
        Ok(TraceRow {
            k: self.value()?,
            t: self.value()?,
            reference: self.required()?,
            pose: self.required()?,
            measurement: self.required()?,
            nominal: self.reals()?,
            u0: self.reals()?,
            u1: self.reals()?,
            bit: self.option()?,
            dhat: self.reals()?,
            xhat: self.reals()?,
            bhat: self.option()?,
            bhat_eve: self.option()?,
            bit_omega: self.option()?,
            camera: self.reals()?,
        })
    }
}

/// The cells of one CSV line, comma-separated; an undefined value is an empty cell.
struct Cells<'a> {
    line: &'a mut String,
    first: bool,
}

impl Cells<'_> {
    fn value(&mut self, value: impl Display) {
        if !std::mem::take(&mut self.first) {
            self.line.push(',');
        }
        let _ = write!(self.line, "{value}");
    }

    fn option(&mut self, value: Option<impl Display>) {
        match value {
            Some(v) => self.value(v),
            None => self.value(""),
        }
    }

    fn reals<const N: usize>(&mut self, values: Option<&[f64; N]>) {
        for i in 0..N {
            self.option(values.map(|v| v[i]));
        }
    }
}

/// The rows a trajectory figure draws: the first [`DrawnRows::HALF`] and the last
/// [`DrawnRows::HALF`]. A run of up to twice that is drawn whole; a longer one as its
/// beginning and its end, so the figure stays readable and small at any N (thinning a
/// path that repeats its laps would alias it) while `trace.csv` keeps every row.
#[derive(Clone, Debug, Default)]
pub struct DrawnRows {
    first: Vec<TraceRow>,
    last: VecDeque<TraceRow>,
}

impl DrawnRows {
    /// Rows kept at each end.
    pub const HALF: usize = 2048;

    /// Offers the next row.
    pub fn push(&mut self, row: TraceRow) {
        if self.first.len() < Self::HALF {
            self.first.push(row);
            return;
        }
        if self.last.len() == Self::HALF {
            self.last.pop_front();
        }
        self.last.push_back(row);
    }

    /// The paths to draw: one when no row was left out, else the beginning and the end.
    #[must_use]
    pub fn into_paths(self) -> Vec<Vec<TraceRow>> {
        let contiguous = self
            .last
            .front()
            .is_none_or(|r| Some(r.k) == self.first.last().map(|f| f.k + 1));
        if contiguous {
            let mut whole = self.first;
            whole.extend(self.last);
            vec![whole]
        } else {
            vec![self.first, self.last.into()]
        }
    }
}

/// A human-readable metrics table for the terminal.
#[must_use]
pub fn metrics_table(metrics: &Metrics, private: Option<&PrivateRun>) -> String {
    let mut out = String::new();
    let show = |x: Option<f64>, unit: &str| {
        x.map_or_else(|| "undefined".to_owned(), |x| format!("{x:.3}{unit}"))
    };
    if let Some(p) = private {
        let rows = [
            (
                "doublets",
                format!("{} ({} without a bit: turn-gated)", p.doublets, p.gated),
            ),
            ("raw key bits", p.bits.len().to_string()),
            (
                "controller BER",
                show(metrics.ber_controller.map(|x| 100.0 * x), " %"),
            ),
            ("Eve BER", show(metrics.ber_eve.map(|x| 100.0 * x), " %")),
            ("J_x", show(Some(1000.0 * metrics.jx), " mm")),
            (
                "raw keys equal",
                metrics.key_match.map_or("undefined".into(), |b| {
                    format!("{b} (post-processing reconciles them: robokey secrecy)")
                }),
            ),
        ];
        for (name, value) in rows {
            let _ = writeln!(out, "  {name:<18} {value}");
        }
        return out;
    }
    let rows = [
        (
            "codewords sent",
            metrics.codewords_sent.map_or("-".into(), |n| n.to_string()),
        ),
        (
            "accepted",
            metrics.accepted.map_or("-".into(), |n| n.to_string()),
        ),
        ("accepted %", show(metrics.accepted_pct, " %")),
        ("correct %", show(metrics.correct_pct, " %")),
        (
            "controller BER",
            show(metrics.ber_controller.map(|x| 100.0 * x), " %"),
        ),
        ("Eve BER", show(metrics.ber_eve.map(|x| 100.0 * x), " %")),
        ("J_x", show(Some(1000.0 * metrics.jx), " mm")),
        ("Eve disagreement", show(metrics.eve_disagreement_pct, " %")),
        (
            "K_c = K_r",
            metrics
                .key_match
                .map_or("undefined".into(), |b| b.to_string()),
        ),
    ];
    for (name, value) in rows {
        let _ = writeln!(out, "  {name:<18} {value}");
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A whole trace in memory.
    fn trace_csv(rows: &[TraceRow]) -> String {
        let mut csv = TraceCsv::new(Vec::new()).unwrap();
        for row in rows {
            csv.write(row).unwrap();
        }
        String::from_utf8(csv.finish().unwrap()).unwrap()
    }

    fn parse_trace_csv(text: &str, origin: &std::path::Path) -> Result<Vec<TraceRow>, LabError> {
        let mut rows = Vec::new();
        read_trace(text.as_bytes(), origin, |row| rows.push(row))?;
        Ok(rows)
    }

    #[test]
    fn trace_has_n_plus_one_rows_and_exact_columns() {
        let run = robokey::sim::simulate(&robokey::Config::default(), 0, true).unwrap();
        let csv = trace_csv(&run.trace);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines.len(), 1 + 1021);
        // docs/experiments.md's 24 columns, then b_omega and Eve's camera (private sensing).
        assert_eq!(lines[0].split(',').count(), 28);
        assert!(lines[0].ends_with(",b_omega,eve_x,eve_y,eve_theta"));
        assert!(lines.iter().all(|l| l.split(',').count() == 28));
        assert!(lines[1..].iter().all(|l| l.ends_with(",,,,")));
        // Row 0 has no decision; the last row has no nominal command and no bit.
        let first: Vec<&str> = lines[1].split(',').collect();
        assert_eq!(first[22], "");
        let last: Vec<&str> = lines[1021].split(',').collect();
        assert_eq!((last[10], last[16]), ("", ""));
        assert_eq!(last[12], "0");
    }

    /// Streams a run's rows to `trace.csv` as the simulation hands them over.
    fn streamed_csv(config: &robokey::Config) -> (String, DrawnRows) {
        let plan = robokey::protocol::SessionPlan::from_config(config, 0);
        let mut csv = TraceCsv::new(Vec::new()).unwrap();
        let mut drawn = DrawnRows::default();
        robokey::sim::simulate_plan_streaming(config, plan, 0, &mut |row| {
            csv.write(&row).unwrap();
            drawn.push(row);
        })
        .unwrap();
        (String::from_utf8(csv.finish().unwrap()).unwrap(), drawn)
    }

    #[test]
    fn streamed_trace_equals_the_one_kept_in_memory() {
        let private = robokey::Config::from_toml(
            "[sensing]\nmode = \"private\"\n[protocol]\nbits_per_doublet = 2\n",
            "test",
        )
        .unwrap();
        for config in [robokey::Config::default(), private] {
            let kept = robokey::sim::simulate(&config, 0, true).unwrap().trace;
            let (streamed, drawn) = streamed_csv(&config);
            assert_eq!(streamed, trace_csv(&kept));
            let origin = std::path::Path::new("trace.csv");
            assert_eq!(parse_trace_csv(&streamed, origin).unwrap(), kept);
            // Up to 2·DrawnRows::HALF rows, a figure draws every row.
            assert_eq!(drawn.into_paths(), vec![kept]);
        }
    }

    #[test]
    fn damaged_traces_are_refused_naming_the_line() {
        let csv = trace_csv(
            &robokey::sim::simulate(&robokey::Config::default(), 0, true)
                .unwrap()
                .trace,
        );
        let origin = std::path::Path::new("t.csv");
        let cut = csv.replacen(",0.2,", ",x,", 1);
        let err = parse_trace_csv(&cut, origin).unwrap_err().to_string();
        assert!(err.contains("t.csv:3") && err.contains("`x`"), "{err}");
        let mut lines = csv.lines();
        let header = lines.next().unwrap();
        let row = lines.next().unwrap();
        // The last (empty) cell left out.
        let short = format!("{header}\n{}\n", &row[..row.len() - 1]);
        let err = parse_trace_csv(&short, origin).unwrap_err().to_string();
        assert!(err.contains("t.csv:2: too few cells"), "{err}");
    }

    #[test]
    fn drawn_rows_are_the_beginning_and_the_end() {
        let mut drawn = DrawnRows::default();
        let n = 10 * DrawnRows::HALF as u32;
        for k in 0..=n {
            drawn.push(TraceRow {
                k,
                ..TraceRow::default()
            });
        }
        let paths = drawn.into_paths();
        let ks: Vec<Vec<u32>> = paths
            .iter()
            .map(|p| p.iter().map(|r| r.k).collect())
            .collect();
        let half = DrawnRows::HALF as u32;
        assert_eq!(
            ks,
            vec![(0..half).collect::<Vec<_>>(), (n + 1 - half..=n).collect()]
        );
    }

    #[test]
    fn a_private_trace_has_the_camera_and_both_bits() {
        let config = robokey::Config::from_toml(
            "[sensing]\nmode = \"private\"\n[protocol]\nbits_per_doublet = 2\n",
            "test",
        )
        .unwrap();
        let run = robokey::sim::simulate(&config, 0, true).unwrap();
        let csv = trace_csv(&run.trace);
        let rows: Vec<Vec<&str>> = csv
            .lines()
            .skip(1)
            .map(|l| l.split(',').collect())
            .collect();
        assert!(rows.iter().all(|r| r.len() == 28 && !r[25].is_empty()));
        // Both steps of a doublet carry its two bits; the decision is on its second step.
        let doublets_with_bits = run.private.unwrap().bits.len() / 2;
        let carried = rows.iter().filter(|r| !r[16].is_empty()).count();
        assert_eq!(carried, 2 * doublets_with_bits);
        assert!(rows.iter().all(|r| r[16].is_empty() == r[24].is_empty()));
        let decided = rows.iter().filter(|r| !r[22].is_empty()).count();
        assert_eq!(decided, doublets_with_bits);
    }
}
