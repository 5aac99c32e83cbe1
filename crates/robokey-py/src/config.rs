//! A configuration as Python gives it — None (the defaults), a TOML string, or a dict — read
//! into the table the library validates, with `seed=` standing for `run.seed` as the command
//! line's `--seed` does (errors name `seed=…` then, as the command line names its flag).

use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use robokey::Config;
use robokey::config::ConfigError;
use robokey::config::set_path;
use robokey::config::source::{self, File, Override};

use crate::errors::config_error;

/// What errors call a configuration given as a dict or a TOML string: the argument's name.
pub const ORIGIN: &str = "config";

/// The table of `config`: empty for None; a TOML string parsed; a dict converted, its
/// top-level keys with a dot (`"protocol.delta_v"`) taken as field paths.
///
/// # Errors
/// [`crate::errors::ConfigError`]: TOML that does not parse, a value TOML cannot hold.
pub fn table(py: Python<'_>, config: Option<&Bound<'_, PyAny>>) -> PyResult<toml::Table> {
    let Some(config) = config.filter(|c| !c.is_none()) else {
        return Ok(toml::Table::new());
    };
    if let Ok(text) = config.cast::<PyString>() {
        let text: String = text.extract()?;
        return File {
            name: ORIGIN,
            text: &text,
        }
        .table()
        .map_err(|e| config_error(py, &e));
    }
    let Ok(dict) = config.cast::<PyDict>() else {
        return Err(config_error(
            py,
            &ConfigError::Parse {
                origin: ORIGIN.to_owned(),
                message: format!(
                    "a {} is not a configuration (allowed: None, a dict or a TOML string)",
                    type_name(config)
                ),
            },
        ));
    };
    let mut table = toml::Table::new();
    for (key, value) in dict.iter() {
        let key: String = key.extract()?;
        let value = toml_value(py, &value, &key)?;
        if key.contains('.') {
            set_path(&mut table, &key, value)
                .map_err(|e| config_error(py, &e.with_origin(ORIGIN)))?;
        } else {
            table.insert(key, value);
        }
    }
    Ok(table)
}

/// `seed=` as an override of `run.seed`, named `seed=…` in errors.
#[must_use]
pub fn seed_override(seed: Option<i64>) -> Vec<Override> {
    seed.map(|seed| Override {
        field: "run.seed".into(),
        value: seed.into(),
        flag: format!("seed={seed}"),
    })
    .into_iter()
    .collect()
}

/// The validated configuration of `config` with `seed=` applied, as `robokey run` loads its
/// file and flags.
///
/// # Errors
/// [`crate::errors::ConfigError`] naming the field, value and allowed range.
pub fn load(
    py: Python<'_>,
    config: Option<&Bound<'_, PyAny>>,
    seed: Option<i64>,
) -> PyResult<Config> {
    let table = table(py, config)?;
    let name = config.filter(|c| !c.is_none()).map(|_| ORIGIN);
    if table.contains_key("sweep") || table.contains_key("experiment") {
        return Err(config_error(
            py,
            &ConfigError::Parse {
                origin: ORIGIN.to_owned(),
                message: "holds a sweep; run it with `robokey.sweep`".into(),
            },
        ));
    }
    source::load(table, name, &seed_override(seed)).map_err(|e| config_error(py, &e))
}

/// A Python value as a TOML value (`path` names it in errors).
fn toml_value(py: Python<'_>, value: &Bound<'_, PyAny>, path: &str) -> PyResult<toml::Value> {
    if let Ok(b) = value.cast::<PyBool>() {
        return Ok(toml::Value::Boolean(b.is_true()));
    }
    if value.is_instance_of::<PyInt>() {
        return Ok(toml::Value::Integer(value.extract()?));
    }
    if value.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(value.extract()?));
    }
    if let Ok(s) = value.cast::<PyString>() {
        return Ok(toml::Value::String(s.extract()?));
    }
    if let Ok(dict) = value.cast::<PyDict>() {
        let mut table = toml::Table::new();
        for (key, item) in dict.iter() {
            let key: String = key.extract()?;
            let item = toml_value(py, &item, &format!("{path}.{key}"))?;
            table.insert(key, item);
        }
        return Ok(toml::Value::Table(table));
    }
    if value.is_instance_of::<PyList>() || value.is_instance_of::<PyTuple>() {
        return value
            .try_iter()?
            .enumerate()
            .map(|(i, item)| toml_value(py, &item?, &format!("{path}[{i}]")))
            .collect::<PyResult<Vec<_>>>()
            .map(toml::Value::Array);
    }
    // numpy's scalars and other numbers: integers by `__index__`, reals by `__float__`.
    if value.hasattr("__index__")? {
        return Ok(toml::Value::Integer(value.extract()?));
    }
    if value.hasattr("__float__")? {
        return Ok(toml::Value::Float(
            value.call_method0("__float__")?.extract()?,
        ));
    }
    Err(config_error(
        py,
        &ConfigError::Invalid {
            origin: ORIGIN.to_owned(),
            field: path.to_owned(),
            value: value.repr()?.to_string(),
            allowed: "a bool, int, float, str, list, tuple or dict".into(),
        },
    ))
}

/// The type's name of `value`, for messages.
fn type_name(value: &Bound<'_, PyAny>) -> String {
    value
        .get_type()
        .name()
        .map_or_else(|_| "value".to_owned(), |n| n.to_string())
}
