//! Reading configuration files and writing output folders.

use std::path::{Path, PathBuf};

use robokey::config::{ConfigError, parse_table, set_path};

use crate::error::{LabError, io_at};

/// A `--set field=value` override.
#[derive(Clone, Debug, PartialEq)]
pub struct Override {
    /// Dotted field path.
    pub field: String,
    /// New value.
    pub value: toml::Value,
}

/// Reads a TOML file into a table (`None`: an empty table).
///
/// # Errors
/// The file cannot be read or does not parse.
pub fn read_table(path: Option<&Path>) -> Result<toml::Table, LabError> {
    let Some(path) = path else {
        return Ok(toml::Table::new());
    };
    let text = std::fs::read_to_string(path).map_err(io_at(path))?;
    Ok(parse_table(&text, &path.display().to_string())?)
}

/// Applies overrides to a table, attributing errors to `--set`.
///
/// # Errors
/// An override path crosses a non-table value.
pub fn apply_overrides(table: &mut toml::Table, overrides: &[Override]) -> Result<(), LabError> {
    for o in overrides {
        set_path(table, &o.field, o.value.clone())
            .map_err(|e: ConfigError| LabError::from(e.with_origin("--set")))?;
    }
    Ok(())
}

/// Prepares an output folder: creates it, and refuses a non-empty one unless `force`.
///
/// # Errors
/// The folder is not empty (without `force`) or cannot be created.
pub fn prepare_output(dir: &Path, force: bool) -> Result<(), LabError> {
    if !force
        && dir
            .read_dir()
            .is_ok_and(|mut entries| entries.next().is_some())
    {
        return Err(LabError::NotEmpty(dir.to_path_buf()));
    }
    std::fs::create_dir_all(dir).map_err(io_at(dir))
}

/// Writes a file, naming it in the error.
///
/// # Errors
/// The file cannot be written.
pub fn write(path: &Path, contents: impl AsRef<[u8]>) -> Result<PathBuf, LabError> {
    std::fs::write(path, contents).map_err(io_at(path))?;
    Ok(path.to_path_buf())
}
