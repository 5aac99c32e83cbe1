//! Tables handed to Python column by column: each column's name, unit and values as one
//! native-endian buffer plus a buffer of which rows are defined, which the package wraps into
//! numpy arrays and Arrow tables without a per-value Python object (`robokey._table`).

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};
use robokey::Metrics;
use robokey_lab::metric_table::{METRICS, MetricValue};
use robokey_lab::table::{Column, Values};

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

/// A column as the tuple the package reads: `(name, unit, description, dtype, data, valid)`,
/// where `dtype` is numpy's name for the values (`"str"`: `data` is a list of str) and `valid`
/// is None when every row is defined.
fn column_to_py(py: Python<'_>, column: Column) -> PyResult<Bound<'_, PyAny>> {
    let Column {
        name,
        unit,
        description,
        values,
    } = column;
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

/// A table as Python receives it: the tuples [`column_to_py`] makes.
pub type PyColumns<'py> = Vec<Bound<'py, PyAny>>;

/// Columns as a list of the tuples [`column_to_py`] makes.
///
/// # Errors
/// Python cannot allocate them.
pub fn to_py(py: Python<'_>, columns: Vec<Column>) -> PyResult<PyColumns<'_>> {
    columns.into_iter().map(|c| column_to_py(py, c)).collect()
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
