//! The Python exceptions: robokey's named errors as Python exceptions whose message is the
//! command line's and whose attributes are the error's fields.

use pyo3::exceptions::{PyKeyboardInterrupt, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use robokey::config::ConfigError as LibConfigError;
use robokey_lab::LabError;

pyo3::create_exception!(
    robokey,
    ConfigError,
    PyValueError,
    "A configuration field out of its allowed range, or a configuration that does not parse \
     or fit the schema. Attributes: `origin` (what set it: `config`, `seed=…`, the defaults), \
     `field` (dotted path), `value` and `allowed` (the allowed range); the last three are None \
     for a parse error (an unknown field, a wrong type), whose message says what is wrong."
);
pyo3::create_exception!(
    robokey,
    SweepError,
    PyValueError,
    "A sweep definition that cannot be run: an axis that is empty, unknown or not a list or \
     range, zip axes of different lengths, a [secrecy] table out of range."
);
pyo3::create_exception!(
    robokey,
    InputError,
    PyValueError,
    "A folder, file or option that does not fit what was asked: not a sweep folder, an \
     interrupted or sharded sweep, a file that does not read back as robokey wrote it, an \
     adversary the sensing mode does not have."
);
pyo3::create_exception!(
    robokey,
    SimulationError,
    PyRuntimeError,
    "A simulated session aborted (the message names the replicate and why)."
);

/// A configuration error as [`ConfigError`], its fields as attributes.
pub fn config_error(py: Python<'_>, error: &LibConfigError) -> PyErr {
    let err = ConfigError::new_err(error.to_string());
    let (origin, field, value, allowed) = match error {
        LibConfigError::Invalid {
            origin,
            field,
            value,
            allowed,
        } => (origin, Some(field), Some(value), Some(allowed)),
        LibConfigError::Parse { origin, .. } => (origin, None, None, None),
        _ => return err,
    };
    with_attributes(
        py,
        err,
        &[
            ("origin", Some(origin)),
            ("field", field),
            ("value", value),
            ("allowed", allowed),
        ],
    )
}

/// `err` with these attributes set (None as Python's None).
fn with_attributes(py: Python<'_>, err: PyErr, attributes: &[(&str, Option<&String>)]) -> PyErr {
    for (name, text) in attributes {
        if let Err(failed) = err.value(py).setattr(*name, *text) {
            return failed;
        }
    }
    err
}

/// An error of the experiment shell as the Python exception of its kind.
pub fn lab_error(py: Python<'_>, error: LabError) -> PyErr {
    let message = error.to_string();
    match error {
        LabError::Config(e) => config_error(py, &e),
        LabError::Sweep { .. } => SweepError::new_err(message),
        LabError::Sim(_) => SimulationError::new_err(message),
        LabError::Io { .. } => PyOSError::new_err(message),
        LabError::Interrupted(_) => PyKeyboardInterrupt::new_err(message),
        LabError::Malformed { .. } => InputError::new_err(message),
        other if other.is_usage() => InputError::new_err(message),
        _ => PyRuntimeError::new_err(message),
    }
}

pyo3::create_exception!(
    robokey,
    OptionError,
    PyValueError,
    "An analysis option out of its allowed range (the message is the command line's, naming \
     the keyword). Attributes: `option` (the keyword), `value`, `allowed`."
);

/// An option of a secrecy request out of range, as [`OptionError`].
pub fn option_error(py: Python<'_>, error: &robokey_lab::secrecy::OptionError) -> PyErr {
    let keyword = error.option.keyword().to_owned();
    let err = OptionError::new_err(error.message(&format!("{keyword}={}", error.value)));
    with_attributes(
        py,
        err,
        &[
            ("option", Some(&keyword)),
            ("value", Some(&error.value)),
            ("allowed", Some(&error.allowed)),
        ],
    )
}

/// An error of the network shell (reading a capture or a key store) as the Python exception
/// of its kind: a file that is not what was asked (a malformed capture, store or pairing
/// file; a store of another pairing) is [`InputError`], a failed read `OSError`.
pub fn net_error(error: robokey_net::NetError) -> PyErr {
    use robokey_net::NetError;
    let message = error.to_string();
    match error {
        NetError::Io { .. } => PyOSError::new_err(message),
        NetError::Capture { .. } | NetError::Store { .. } | NetError::Usage(_) => {
            InputError::new_err(message)
        }
        _ => PyRuntimeError::new_err(message),
    }
}
