//! The metrics of one run ([`Metrics`], docs/experiments.md), declared once in [`METRICS`]:
//! each metric's column (in `runs.csv`, `summary.json` and `metrics.json`), its unit, how it
//! is read from and written into [`Metrics`], and how reports show it. Every file and report
//! that lists metrics derives from this table.

use robokey::Metrics;

use crate::table::{Cell, Column, Values};

/// One metric value, typed for CSV and JSON.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MetricValue {
    /// A real number, or undefined.
    Real(Option<f64>),
    /// A count, or undefined.
    Count(Option<u64>),
    /// A flag, or undefined.
    Flag(Option<bool>),
}

impl MetricValue {
    /// As a real number (flags as 0/1), if defined.
    #[must_use]
    pub fn as_f64(self) -> Option<f64> {
        match self {
            Self::Real(x) => x,
            Self::Count(n) => n.map(|n| n as f64),
            Self::Flag(b) => b.map(|b| f64::from(u8::from(b))),
        }
    }

    /// As a CSV cell: empty when undefined; reals in their shortest round-trip form, so a
    /// cell reads back exactly.
    #[must_use]
    pub fn cell(self) -> String {
        fn text(value: Option<impl ToString>) -> String {
            value.map_or_else(String::new, |v| v.to_string())
        }
        match self {
            Self::Real(x) => text(x),
            Self::Count(n) => text(n),
            Self::Flag(b) => text(b),
        }
    }

    /// As JSON: `null` when undefined.
    #[must_use]
    pub fn json(self) -> serde_json::Value {
        use serde_json::Value;
        match self {
            Self::Real(x) => x.map_or(Value::Null, Value::from),
            Self::Count(n) => n.map_or(Value::Null, Value::from),
            Self::Flag(b) => b.map_or(Value::Null, Value::from),
        }
    }
}

impl From<MetricValue> for Cell {
    fn from(value: MetricValue) -> Self {
        match value {
            MetricValue::Real(x) => Self::Real(x),
            MetricValue::Count(n) => Self::Count(n),
            MetricValue::Flag(b) => Self::Flag(b),
        }
    }
}

/// Where a metric lives in [`Metrics`]: a reader and a writer of its field.
#[derive(Clone, Copy)]
enum Field {
    /// A count, or undefined.
    Count(
        fn(&Metrics) -> Option<u64>,
        fn(&mut Metrics) -> &mut Option<u64>,
    ),
    /// A real number, or undefined.
    Real(
        fn(&Metrics) -> Option<f64>,
        fn(&mut Metrics) -> &mut Option<f64>,
    ),
    /// A real number that every run defines.
    Required(fn(&Metrics) -> f64, fn(&mut Metrics) -> &mut f64),
    /// A flag, or undefined.
    Flag(
        fn(&Metrics) -> Option<bool>,
        fn(&mut Metrics) -> &mut Option<bool>,
    ),
    /// Cell `index` of a table of 8 joint counts, all defined or all undefined.
    Joint(
        fn(&Metrics) -> Option<[u64; 8]>,
        fn(&mut Metrics) -> &mut Option<[u64; 8]>,
        usize,
    ),
}

/// How reports show a metric: in `unit` (the stored value times `scale`), with `digits`
/// decimals.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shown {
    /// The name people read, e.g. "controller BER".
    pub name: &'static str,
    /// The file name of its figure (without extension).
    pub file: &'static str,
    /// The unit shown, e.g. "%".
    pub unit: &'static str,
    /// The factor from the stored unit to the shown one.
    pub scale: f64,
    /// Decimals shown.
    pub digits: usize,
}

/// One metric.
#[derive(Clone, Copy)]
pub struct Metric {
    /// Its column in `runs.csv` and key in `summary.json` and `metrics.json`.
    pub column: &'static str,
    /// The stored value's unit (empty for counts and flags).
    pub unit: &'static str,
    /// What it measures (docs/experiments.md, "Metrics of one run").
    pub meaning: &'static str,
    field: Field,
    /// How reports of any sweep show it (`None`: only in the files).
    pub shown: Option<Shown>,
}

impl std::fmt::Debug for Metric {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Metric")
            .field("column", &self.column)
            .field("unit", &self.unit)
            .finish_non_exhaustive()
    }
}

/// A count field of [`Metrics`].
macro_rules! count {
    ($field:ident) => {
        Field::Count(|m| m.$field, |m| &mut m.$field)
    };
}

/// A real field of [`Metrics`], possibly undefined.
macro_rules! real {
    ($field:ident) => {
        Field::Real(|m| m.$field, |m| &mut m.$field)
    };
}

/// The 8 cells of a joint-count table of [`Metrics`], columns `<table>_000` … `<table>_111`
/// (index `4·first + 2·second + third`).
macro_rules! joint {
    ($table:ident, $meaning:literal) => {
        [
            joint!($table, $meaning, "000", 0),
            joint!($table, $meaning, "001", 1),
            joint!($table, $meaning, "010", 2),
            joint!($table, $meaning, "011", 3),
            joint!($table, $meaning, "100", 4),
            joint!($table, $meaning, "101", 5),
            joint!($table, $meaning, "110", 6),
            joint!($table, $meaning, "111", 7),
        ]
    };
    ($table:ident, $meaning:literal, $bits:literal, $index:literal) => {
        Metric {
            column: concat!(stringify!($table), "_", $bits),
            unit: "",
            meaning: concat!($meaning, $bits),
            field: Field::Joint(|m| m.$table, |m| &mut m.$table, $index),
            shown: None,
        }
    };
}

/// A percentage, shown as stored.
const fn percent(name: &'static str, file: &'static str, digits: usize) -> Option<Shown> {
    Some(Shown {
        name,
        file,
        unit: "%",
        scale: 1.0,
        digits,
    })
}

/// Every metric, in column order: the list of docs/experiments.md, then the 16 joint counts.
pub static METRICS: [Metric; 25] = {
    let [b0, b1, b2, b3, b4, b5, b6, b7] = joint!(
        n_bce,
        "count of applied bits whose (b, controller's b̂, Eve's b̂) is "
    );
    let [a0, a1, a2, a3, a4, a5, a6, a7] = joint!(
        n_acc,
        "count of accepted key bits whose (robot's s, controller's ŝ, Eve's ŝ) is "
    );
    [
        Metric {
            column: "codewords_sent",
            unit: "",
            meaning: "complete codewords of the run",
            field: count!(codewords_sent),
            shown: None,
        },
        Metric {
            column: "accepted",
            unit: "",
            meaning: "codewords accepted",
            field: count!(accepted),
            shown: None,
        },
        Metric {
            column: "accepted_pct",
            unit: "%",
            meaning: "codewords accepted / sent · 100",
            field: real!(accepted_pct),
            shown: percent("accepted", "accepted", 1),
        },
        Metric {
            column: "correct_pct",
            unit: "%",
            meaning: "share of accepted key bits where the controller's key equals the robot's",
            field: real!(correct_pct),
            shown: percent("correct", "correct", 2),
        },
        Metric {
            column: "ber_controller",
            unit: "fraction",
            meaning: "fraction of applied bits the controller decided wrongly",
            field: real!(ber_controller),
            shown: Some(Shown {
                name: "controller BER",
                file: "ber",
                unit: "%",
                scale: 100.0,
                digits: 2,
            }),
        },
        Metric {
            column: "ber_eve",
            unit: "fraction",
            meaning: "fraction of applied bits Eve decided wrongly",
            field: real!(ber_eve),
            shown: None,
        },
        Metric {
            column: "jx",
            unit: "m",
            meaning: "J_x = (1/N)·Σ ‖(px, py)(k) − (xr, yr)(k)‖₂ on the true pose",
            field: Field::Required(|m| m.jx, |m| &mut m.jx),
            shown: Some(Shown {
                name: "J_x",
                file: "jx",
                unit: "mm",
                scale: 1000.0,
                digits: 1,
            }),
        },
        Metric {
            column: "eve_disagreement_pct",
            unit: "%",
            meaning: "share of key positions where Eve's key differs from the controller's",
            field: real!(eve_disagreement_pct),
            shown: percent("Eve disagreement", "eve-disagreement", 2),
        },
        Metric {
            column: "key_match",
            unit: "",
            meaning: "whether the controller's key equals the robot's",
            field: Field::Flag(|m| m.key_match, |m| &mut m.key_match),
            shown: None,
        },
        b0,
        b1,
        b2,
        b3,
        b4,
        b5,
        b6,
        b7,
        a0,
        a1,
        a2,
        a3,
        a4,
        a5,
        a6,
        a7,
    ]
};

impl Metric {
    /// Its value in `metrics`.
    #[must_use]
    pub fn value(&self, metrics: &Metrics) -> MetricValue {
        match self.field {
            Field::Count(get, _) => MetricValue::Count(get(metrics)),
            Field::Real(get, _) => MetricValue::Real(get(metrics)),
            Field::Required(get, _) => MetricValue::Real(Some(get(metrics))),
            Field::Flag(get, _) => MetricValue::Flag(get(metrics)),
            Field::Joint(get, _, index) => MetricValue::Count(get(metrics).map(|t| t[index])),
        }
    }

    /// Its value as reports show it (in [`Shown::unit`]), if it is shown and defined.
    #[must_use]
    pub fn shown_value(&self, metrics: &Metrics) -> Option<f64> {
        let shown = self.shown?;
        Some(shown.scale * self.value(metrics).as_f64()?)
    }
}

/// One column per metric of [`METRICS`] (`runs.csv`'s), a row per run.
#[must_use]
pub fn metric_columns(runs: &[&Metrics]) -> Vec<Column> {
    METRICS
        .iter()
        .map(|metric| {
            let values = Values::of_cells(
                &metric.value(&Metrics::default()).into(),
                runs.iter().map(|m| metric.value(m).into()),
            );
            Column::new(metric.column, metric.unit, metric.meaning, values)
        })
        .collect()
}

/// The metrics as a JSON object in column order (`metrics.json`).
#[must_use]
pub fn metrics_json(metrics: &Metrics) -> serde_json::Map<String, serde_json::Value> {
    METRICS
        .iter()
        .map(|m| (m.column.to_owned(), m.value(metrics).json()))
        .collect()
}

/// A cell: `None` when empty, else its value.
fn parse_cell<T: std::str::FromStr>(column: &str, cell: &str) -> Result<Option<T>, String> {
    if cell.is_empty() {
        return Ok(None);
    }
    cell.parse()
        .map(Some)
        .map_err(|_| format!("`{column}` = `{cell}` does not parse"))
}

/// Reads the metrics of a run from its cells in column order (the inverse of
/// [`MetricValue::cell`]: reals are written in their shortest round-trip form, so they read
/// back exactly).
///
/// # Errors
/// The number of cells is not the number of metrics, a cell does not parse as its metric,
/// `jx` is empty, or a joint-count table is partly empty.
pub fn read_metrics<'a>(cells: impl ExactSizeIterator<Item = &'a str>) -> Result<Metrics, String> {
    if cells.len() != METRICS.len() {
        return Err(format!(
            "{} metric cells, expected {}",
            cells.len(),
            METRICS.len()
        ));
    }
    let mut metrics = Metrics::default();
    // Joint-count cells left empty: their table must then be undefined as a whole.
    let mut empty_joint_cells = Vec::new();
    for (metric, cell) in METRICS.iter().zip(cells) {
        let column = metric.column;
        match metric.field {
            Field::Count(_, slot) => *slot(&mut metrics) = parse_cell(column, cell)?,
            Field::Real(_, slot) => *slot(&mut metrics) = parse_cell(column, cell)?,
            Field::Required(_, slot) => {
                *slot(&mut metrics) =
                    parse_cell(column, cell)?.ok_or_else(|| format!("`{column}` is empty"))?;
            }
            Field::Flag(_, slot) => *slot(&mut metrics) = parse_cell(column, cell)?,
            Field::Joint(get, slot, index) => match parse_cell(column, cell)? {
                Some(count) => slot(&mut metrics).get_or_insert([0; 8])[index] = count,
                None => empty_joint_cells.push(get),
            },
        }
    }
    if empty_joint_cells.iter().any(|get| get(&metrics).is_some()) {
        return Err("joint counts partly empty".into());
    }
    Ok(metrics)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_columns_are_those_of_docs_experiments() {
        let columns: Vec<&str> = METRICS.iter().map(|m| m.column).collect();
        assert_eq!(
            columns[..9],
            [
                "codewords_sent",
                "accepted",
                "accepted_pct",
                "correct_pct",
                "ber_controller",
                "ber_eve",
                "jx",
                "eve_disagreement_pct",
                "key_match"
            ]
        );
        assert_eq!(columns[9], "n_bce_000");
        assert_eq!(columns[14], "n_bce_101");
        assert_eq!(columns[24], "n_acc_111");
        let docs = include_str!("../../../docs/experiments.md");
        for column in &columns[..9] {
            assert!(docs.contains(&format!("`{column}`")), "{column}");
        }
    }

    /// Each shown metric's scale is the conversion from its stored unit to the shown one.
    #[test]
    fn shown_scales_convert_the_stored_units() {
        let factor = |from: &str, to: &str| match (from, to) {
            (a, b) if a == b => Some(1.0),
            ("fraction", "%") => Some(100.0),
            ("m", "mm") => Some(1000.0),
            _ => None,
        };
        let shown: Vec<(&Metric, Shown)> =
            METRICS.iter().filter_map(|m| Some((m, m.shown?))).collect();
        assert_eq!(shown.len(), 5);
        for (metric, shown) in shown {
            assert_eq!(
                factor(metric.unit, shown.unit),
                Some(shown.scale),
                "{metric:?} shown in {}",
                shown.unit
            );
        }
    }

    #[test]
    fn metrics_read_back_from_their_cells_exactly() {
        for config in [robokey::Config::default(), {
            let mut off = robokey::Config::default();
            off.protocol.enabled = false;
            off
        }] {
            let metrics = robokey::sim::simulate(&config, 1, false).unwrap().metrics;
            let cells: Vec<String> = METRICS.iter().map(|m| m.value(&metrics).cell()).collect();
            let back = read_metrics(cells.iter().map(String::as_str)).unwrap();
            assert_eq!(back, metrics);
        }
        let mut cells = vec!["1"; 25];
        cells[1] = "x";
        let err = read_metrics(cells.iter().copied()).unwrap_err();
        assert_eq!(err, "`accepted` = `x` does not parse");
        let err = read_metrics(["1"].into_iter()).unwrap_err();
        assert_eq!(err, "1 metric cells, expected 25");
        let mut cells = vec!["1"; 25];
        cells[6] = "";
        assert_eq!(
            read_metrics(cells.iter().copied()).unwrap_err(),
            "`jx` is empty"
        );
        cells[6] = "0.02";
        cells[8] = "true";
        cells[12] = "";
        assert_eq!(
            read_metrics(cells.iter().copied()).unwrap_err(),
            "joint counts partly empty"
        );
    }
}
