//! Reading configuration files and writing output folders.

use std::path::{Path, PathBuf};

use robokey::config::{ConfigError, parse_table, set_path};

use crate::error::{LabError, io_at};

/// A config field set on the command line: by `--set field=value` or by a flag that stands
/// for a field (`--delta-v 0.03`).
#[derive(Clone, Debug, PartialEq)]
pub struct Override {
    /// Dotted field path.
    pub field: String,
    /// New value.
    pub value: toml::Value,
    /// The flag as the user wrote it, e.g. `--set protocol.delta_v=0.03`, for errors.
    pub flag: String,
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

/// Applies overrides to a table, attributing errors to their flags.
///
/// # Errors
/// An override path crosses a non-table value.
pub fn apply_overrides(table: &mut toml::Table, overrides: &[Override]) -> Result<(), LabError> {
    for o in overrides {
        set_path(table, &o.field, o.value.clone())
            .map_err(|e: ConfigError| LabError::from(e.with_origin(&o.flag)))?;
    }
    Ok(())
}

/// Names the flag behind a configuration error, as the user wrote it, instead of the TOML it
/// was merged into: a value out of range that a flag set (`--delta-v -1: \`protocol.delta_v\`
/// = -1.0 is not allowed …`), or a flag whose value does not fit its field at all (wrong
/// type, unknown field). Other errors are returned as they are.
#[must_use]
pub fn blame_flags(error: LabError, overrides: &[Override]) -> LabError {
    use serde::Deserialize as _;
    let LabError::Config(config_error) = error else {
        return error;
    };
    if let ConfigError::Invalid {
        field,
        value,
        allowed,
        ..
    } = &config_error
        && let Some(o) = overrides
            .iter()
            .rev()
            .find(|o| &o.field == field && &o.value.to_string() == value)
    {
        return LabError::Config(ConfigError::Invalid {
            origin: o.flag.clone(),
            field: field.clone(),
            value: value.clone(),
            allowed: allowed.clone(),
        });
    }
    if let ConfigError::Parse { .. } = &config_error {
        for o in overrides {
            let mut alone = toml::Table::new();
            if set_path(&mut alone, &o.field, o.value.clone()).is_err() {
                continue;
            }
            if let Err(e) = robokey::Config::deserialize(toml::Value::Table(alone)) {
                return LabError::Config(ConfigError::Parse {
                    origin: o.flag.clone(),
                    message: e.message().to_owned(),
                });
            }
        }
    }
    LabError::Config(config_error)
}

/// Files by which a folder is recognised as robokey's output (at its top, or in a
/// subfolder of a suite).
const OUTPUT_MARKERS: [&str; 5] = [
    "manifest.json",
    "config.resolved.toml",
    "report.md",
    "metrics.json",
    "secrecy.json",
];

/// Whether `dir` holds robokey's output: a marker file at its top or one level down.
fn is_robokey_output(dir: &Path) -> bool {
    let has_marker = |d: &Path| OUTPUT_MARKERS.iter().any(|m| d.join(m).is_file());
    has_marker(dir)
        || dir.read_dir().is_ok_and(|entries| {
            entries
                .flatten()
                .any(|e| e.path().is_dir() && has_marker(&e.path()))
        })
}

/// Prepares an output folder: creates it; a non-empty one is refused, or with `force`
/// emptied first — so no stale file of an earlier run survives beside the new ones — but
/// only if it holds robokey's output (never an arbitrary folder).
///
/// # Errors
/// The folder is not empty (without `force`), is not robokey's output (with `force`), or
/// cannot be emptied or created.
pub fn prepare_output(dir: &Path, force: bool) -> Result<(), LabError> {
    let non_empty = dir
        .read_dir()
        .is_ok_and(|mut entries| entries.next().is_some());
    if non_empty {
        if !force {
            return Err(LabError::NotEmpty(dir.to_path_buf()));
        }
        if !is_robokey_output(dir) {
            return Err(LabError::NotOutput(dir.to_path_buf()));
        }
        std::fs::remove_dir_all(dir).map_err(io_at(dir))?;
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

#[cfg(test)]
mod tests {
    use super::*;

    fn flag(flag: &str, field: &str, value: toml::Value) -> Override {
        Override {
            field: field.into(),
            value,
            flag: flag.into(),
        }
    }

    /// The error of the defaults with these overrides, blamed.
    fn blamed(overrides: &[Override]) -> String {
        let mut table = toml::Table::new();
        apply_overrides(&mut table, overrides).unwrap();
        let error = robokey::Config::from_table(table, "the defaults").unwrap_err();
        blame_flags(error.into(), overrides).to_string()
    }

    #[test]
    fn errors_name_the_flag_the_user_wrote() {
        let delta_v = flag("--delta-v -1", "protocol.delta_v", (-1.0).into());
        assert_eq!(
            blamed(&[delta_v]),
            "--delta-v -1: `protocol.delta_v` = -1.0 is not allowed (allowed: ≥ 0, finite)"
        );
        let kp = flag("--set controller.kp=abc", "controller.kp", "abc".into());
        let text = blamed(&[flag("--seed 3", "run.seed", 3.into()), kp]);
        assert_eq!(
            text,
            "--set controller.kp=abc: invalid type: string \"abc\", expected f64"
        );
        assert!(!text.contains("TOML parse error"), "{text}");
        let unknown = flag("--set controller.gain=2", "controller.gain", 2.into());
        let text = blamed(&[unknown]);
        assert!(
            text.starts_with("--set controller.gain=2: unknown field `gain`"),
            "{text}"
        );
        // An error about a field no flag set keeps its origin.
        let text = blamed(&[flag("--set robot.T=1e-6", "robot.T", 1e-6.into())]);
        assert!(
            text.starts_with("the defaults: `trajectory.laps` = 3 is not allowed"),
            "{text}"
        );
    }

    #[test]
    fn force_empties_robokey_output_and_nothing_else() {
        let dir = std::env::temp_dir().join(format!("robokey-files-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("point")).unwrap();
        std::fs::write(dir.join("point/manifest.json"), "{}").unwrap();
        std::fs::write(dir.join("stale.csv"), "old").unwrap();
        assert!(matches!(
            prepare_output(&dir, false),
            Err(LabError::NotEmpty(_))
        ));
        prepare_output(&dir, true).unwrap();
        assert!(
            dir.read_dir().unwrap().next().is_none(),
            "stale files survived"
        );
        std::fs::write(dir.join("thesis.tex"), "precious").unwrap();
        assert!(matches!(
            prepare_output(&dir, true),
            Err(LabError::NotOutput(_))
        ));
        assert!(dir.join("thesis.tex").exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
