//! `runs.csv`: a column per swept field, `replicate`, then the metrics of
//! [`crate::metric_table::METRICS`]; one row per finished run, in run order. The same table
//! column by column ([`run_columns`]) is `runs.parquet` and the Python package's sweep table.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use crate::error::LabError;
use crate::experiment::{Experiment, value_text};
use crate::metric_table::{METRICS, metric_columns, read_metrics};
use crate::run::RunRow;
use crate::table::{Column, Values};

/// The finished runs of a folder, by run index.
pub type Rows = BTreeMap<usize, RunRow>;

/// The columns of `runs.csv`.
fn columns(experiment: &Experiment) -> Vec<&str> {
    let mut columns: Vec<&str> = experiment.axes.iter().map(|a| a.field.as_str()).collect();
    columns.push("replicate");
    columns.extend(METRICS.iter().map(|m| m.column));
    columns
}

/// `runs.csv` of `rows`: swept values quoted when they hold a comma, a quote or a line
/// break (as an array value does), by the `csv` crate.
#[must_use]
pub fn runs_csv(experiment: &Experiment, rows: &Rows) -> String {
    let mut csv = csv::WriterBuilder::new()
        .terminator(csv::Terminator::Any(b'\n'))
        .from_writer(Vec::new());
    let points: Vec<Vec<String>> = experiment
        .points
        .iter()
        .map(|p| p.params.iter().map(|(_, v)| value_text(v)).collect())
        .collect();
    // Writing UTF-8 text to memory cannot fail.
    let written = "CSV text is written to memory";
    csv.write_record(columns(experiment)).expect(written);
    for row in rows.values() {
        let metrics = METRICS.iter().map(|m| m.value(&row.metrics).cell());
        csv.write_record(
            points[row.point]
                .iter()
                .cloned()
                .chain(std::iter::once(row.replicate.to_string()))
                .chain(metrics),
        )
        .expect(written);
    }
    String::from_utf8(csv.into_inner().expect(written)).expect(written)
}

/// The columns of `runs.csv` for `rows`, typed: one per swept field (its meaning the field's
/// documentation), `replicate`, the metrics.
#[must_use]
pub fn run_columns<'a>(
    experiment: &Experiment,
    rows: impl Iterator<Item = &'a RunRow> + Clone,
) -> Vec<Column> {
    let mut columns: Vec<Column> = experiment
        .axes
        .iter()
        .enumerate()
        .map(|(i, axis)| {
            let meaning = crate::config_doc::doc(&axis.field).unwrap_or_default();
            let values = param_values(
                rows.clone()
                    .map(|r| &experiment.points[r.point].params[i].1),
            );
            Column::new(&axis.field, "", meaning, values)
        })
        .collect();
    columns.push(Column::new(
        "replicate",
        "",
        "the replicate: which of the point's random streams the run used",
        Values::Counts(rows.clone().map(|r| Some(u64::from(r.replicate))).collect()),
    ));
    let metrics: Vec<&robokey::Metrics> = rows.map(|r| &r.metrics).collect();
    columns.extend(metric_columns(&metrics));
    columns
}

/// A swept field's values, typed: integers, reals (integers among reals as reals), flags,
/// else the text `runs.csv` writes (strings, arrays).
fn param_values<'a>(values: impl Iterator<Item = &'a toml::Value> + Clone) -> Values {
    use toml::Value;
    if values.clone().all(Value::is_integer) {
        return Values::Integers(values.filter_map(Value::as_integer).collect());
    }
    if values.clone().all(|v| v.is_integer() || v.is_float()) {
        return Values::Reals(
            values
                .map(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
                .collect(),
        );
    }
    if values.clone().all(Value::is_bool) {
        return Values::Flags(values.map(Value::as_bool).collect());
    }
    Values::Texts(values.map(value_text).collect())
}

/// Reads the rows of a `runs.csv` (`origin` names it in errors), checking that every row
/// belongs to the experiment's grid: the inverse of [`runs_csv`].
///
/// # Errors
/// A header that is not the experiment's, a row whose swept values are not a point of the
/// grid, a replicate out of range, a metric cell that does not parse.
pub fn read_runs(
    experiment: &Experiment,
    text: &str,
    origin: &Path,
) -> Result<Vec<RunRow>, LabError> {
    let bad = |line: u64, message: String| LabError::Malformed {
        place: format!("{}:{line}", origin.display()),
        message,
    };

    let axes = experiment.axes.len();
    let point_of: HashMap<Vec<String>, usize> = experiment
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| (p.params.iter().map(|(_, v)| value_text(v)).collect(), i))
        .collect();
    let replicates = experiment.replicates() as usize;
    let mut reader = csv::ReaderBuilder::new()
        .flexible(true)
        .from_reader(text.as_bytes());
    if reader.headers().ok().map(|h| h.iter().collect::<Vec<_>>()) != Some(columns(experiment)) {
        return Err(bad(1, "header does not match the sweep".into()));
    }
    reader
        .records()
        .map(|record| {
            let record = record.map_err(|e| {
                let line = e.position().map_or(0, csv::Position::line);
                bad(line, e.to_string())
            })?;
            let line = record.position().map_or(0, csv::Position::line);
            let params: Vec<String> = record.iter().take(axes).map(str::to_owned).collect();
            let point = *point_of
                .get(&params)
                .ok_or_else(|| bad(line, format!("parameters {params:?} are not on the grid")))?;
            let replicate = record
                .get(axes)
                .and_then(|r| r.parse::<usize>().ok())
                .filter(|&r| r < replicates)
                .ok_or_else(|| bad(line, "bad replicate".into()))?;
            let cells = record.iter().skip(axes + 1).collect::<Vec<_>>();
            let metrics = read_metrics(cells.into_iter()).map_err(|why| bad(line, why))?;
            Ok(RunRow {
                run: point * replicates + replicate,
                point,
                replicate: replicate as u32,
                metrics,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_read_back_from_runs_csv_exactly() {
        let experiment = Experiment::from_table(
            "t",
            "[run]\nreplicates = 2\n[sweep]\n\"protocol.enabled\" = [true, false]\n\
             \"noise.process_std\" = [[0.004, 0.004, 0.004]]\n"
                .parse()
                .unwrap(),
            "t.toml",
        )
        .unwrap();
        let rows: Rows = (0..4)
            .map(|run| {
                let (point, replicate) = (run / 2, (run % 2) as u32);
                let config = &experiment.points[point].config;
                let output = robokey::sim::simulate(config, replicate, false).unwrap();
                let row = RunRow {
                    run,
                    point,
                    replicate,
                    metrics: output.metrics,
                };
                (run, row)
            })
            .collect();
        let csv = runs_csv(&experiment, &rows);
        assert!(
            csv.lines()
                .nth(1)
                .unwrap()
                .starts_with("true,\"[0.004, 0.004, 0.004]\",0,")
        );
        let back = read_runs(&experiment, &csv, Path::new("runs.csv")).unwrap();
        assert_eq!(back, rows.values().cloned().collect::<Vec<_>>());
        let err = read_runs(
            &experiment,
            &csv.replacen("true,", "maybe,", 1),
            Path::new("r"),
        )
        .unwrap_err()
        .to_string();
        assert!(err.starts_with("r:2: parameters [\"maybe\""), "{err}");
        let short = csv.lines().take(2).collect::<Vec<_>>().join("\n") + ",1\n";
        let err = read_runs(&experiment, &short, Path::new("r"))
            .unwrap_err()
            .to_string();
        assert_eq!(err, "r:2: 26 metric cells, expected 25");
        let err = read_runs(&experiment, "replicate\n", Path::new("r"))
            .unwrap_err()
            .to_string();
        assert_eq!(err, "r:1: header does not match the sweep");
    }
}
