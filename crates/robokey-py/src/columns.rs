//! Tables handed to Python column by column: each column's name, unit and values as one
//! native-endian buffer plus a buffer of which rows are defined, which the package wraps into
//! numpy arrays and Arrow tables without a per-value Python object (`robokey._table`).

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};
use robokey::Metrics;
use robokey_lab::metric_table::{METRICS, MetricValue};
use robokey_lab::trace_table::{TRACE_COLUMNS, TraceValue};

/// The values of one column.
pub enum Values {
    /// Real numbers, or undefined.
    Reals(Vec<Option<f64>>),
    /// Non-negative integers, or undefined.
    Counts(Vec<Option<u64>>),
    /// Signed integers.
    Integers(Vec<i64>),
    /// Flags, or undefined.
    Flags(Vec<Option<bool>>),
    /// Text.
    Texts(Vec<String>),
}

/// One named column with its unit and what it means (either may be empty).
pub struct Column {
    /// Its name.
    pub name: String,
    /// The unit of its values.
    pub unit: String,
    /// What it holds, for the schema's metadata (may be empty).
    pub description: String,
    /// Its values.
    pub values: Values,
}

/// A buffer of `values` (undefined ones as `fill`) and, when some are undefined, a byte per
/// row saying which are defined.
fn buffers<T: Copy, const N: usize>(
    values: &[Option<T>],
    fill: T,
    bytes: fn(T) -> [u8; N],
) -> (Vec<u8>, Option<Vec<u8>>) {
    let data = values
        .iter()
        .flat_map(|v| bytes(v.unwrap_or(fill)))
        .collect();
    let valid = values
        .iter()
        .any(Option::is_none)
        .then(|| values.iter().map(|v| u8::from(v.is_some())).collect());
    (data, valid)
}

impl Column {
    /// As the tuple the package reads: `(name, unit, description, dtype, data, valid)`, where
    /// `dtype` is numpy's name for the values (`"str"`: `data` is a list of str) and `valid`
    /// is None when every row is defined.
    fn into_py(self, py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
        let Self {
            name,
            unit,
            description,
            values,
        } = self;
        let (dtype, (data, valid)) = match values {
            Values::Texts(texts) => {
                let none: Option<Vec<u8>> = None;
                return (name, unit, description, "str", texts, none)
                    .into_pyobject(py)
                    .map(Bound::into_any);
            }
            Values::Reals(v) => ("float64", buffers(&v, 0.0, f64::to_ne_bytes)),
            Values::Counts(v) => ("uint64", buffers(&v, 0, u64::to_ne_bytes)),
            Values::Flags(v) => ("bool", buffers(&v, false, |b| [u8::from(b)])),
            Values::Integers(v) => (
                "int64",
                (v.iter().flat_map(|x| x.to_ne_bytes()).collect(), None),
            ),
        };
        let valid = valid.map(|v| PyBytes::new(py, &v));
        (
            name,
            unit,
            description,
            dtype,
            PyBytes::new(py, &data),
            valid,
        )
            .into_pyobject(py)
            .map(Bound::into_any)
    }
}

/// A table as Python receives it: the tuples [`Column::into_py`] makes.
pub type PyColumns<'py> = Vec<Bound<'py, PyAny>>;

/// Columns as a list of the tuples [`Column::into_py`] makes.
///
/// # Errors
/// Python cannot allocate them.
pub fn to_py(py: Python<'_>, columns: Vec<Column>) -> PyResult<PyColumns<'_>> {
    columns.into_iter().map(|c| c.into_py(py)).collect()
}

/// The column of `metric`-typed values.
fn metric_values(values: impl Iterator<Item = MetricValue>, kind: MetricValue) -> Values {
    match kind {
        MetricValue::Real(_) => Values::Reals(values.map(MetricValue::as_f64).collect()),
        MetricValue::Count(_) => Values::Counts(
            values
                .map(|v| match v {
                    MetricValue::Count(n) => n,
                    _ => None,
                })
                .collect(),
        ),
        MetricValue::Flag(_) => Values::Flags(
            values
                .map(|v| match v {
                    MetricValue::Flag(b) => b,
                    _ => None,
                })
                .collect(),
        ),
    }
}

/// One column per metric of [`METRICS`] (`runs.csv`'s), a row per run.
#[must_use]
pub fn metric_columns(runs: &[&Metrics]) -> Vec<Column> {
    METRICS
        .iter()
        .map(|metric| Column {
            name: metric.column.to_owned(),
            unit: metric.unit.to_owned(),
            description: String::new(),
            values: metric_values(
                runs.iter().map(|m| metric.value(m)),
                metric.value(&Metrics::default()),
            ),
        })
        .collect()
}

/// The metrics of one run as a dict in column order, undefined ones None (`metrics.json`).
///
/// # Errors
/// Python cannot allocate it.
pub fn metrics_dict<'py>(py: Python<'py>, metrics: &Metrics) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    for metric in &METRICS {
        match metric.value(metrics) {
            MetricValue::Real(x) => dict.set_item(metric.column, x)?,
            MetricValue::Count(n) => dict.set_item(metric.column, n)?,
            MetricValue::Flag(b) => dict.set_item(metric.column, b)?,
        }
    }
    Ok(dict)
}

/// The units of [`METRICS`] by column (empty for counts and flags).
///
/// # Errors
/// Python cannot allocate it.
pub fn metric_units(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let dict = PyDict::new(py);
    for metric in &METRICS {
        dict.set_item(metric.column, metric.unit)?;
    }
    Ok(dict)
}

/// Collects a trace's rows into its columns ([`TRACE_COLUMNS`]) as they come.
#[derive(Default)]
pub struct TraceColumns {
    values: Vec<Vec<TraceValue>>,
}

impl TraceColumns {
    /// Takes one row.
    pub fn push(&mut self, row: &robokey::sim::TraceRow) {
        if self.values.is_empty() {
            self.values = TRACE_COLUMNS.iter().map(|_| Vec::new()).collect();
        }
        for (column, values) in TRACE_COLUMNS.iter().zip(&mut self.values) {
            values.push(column.value(row));
        }
    }

    /// The columns.
    #[must_use]
    pub fn into_columns(self) -> Vec<Column> {
        let mut values = self.values;
        values.resize_with(TRACE_COLUMNS.len(), Vec::new);
        TRACE_COLUMNS
            .iter()
            .zip(values)
            .map(|(column, values)| Column {
                name: column.name.to_owned(),
                unit: column.unit.to_owned(),
                description: String::new(),
                values: match column.value(&robokey::sim::TraceRow::default()) {
                    TraceValue::Real(_) => Values::Reals(
                        values
                            .into_iter()
                            .map(|v| match v {
                                TraceValue::Real(x) => x,
                                TraceValue::Count(n) => n.map(|n| n as f64),
                            })
                            .collect(),
                    ),
                    TraceValue::Count(_) => Values::Counts(
                        values
                            .into_iter()
                            .map(|v| match v {
                                TraceValue::Count(n) => n,
                                TraceValue::Real(_) => None,
                            })
                            .collect(),
                    ),
                },
            })
            .collect()
    }
}
