//! Reading a configuration as the user gave it: the table of a file (or none: the
//! defaults), fields set on the command line, and errors that name what set the offending
//! field — the flag as the user wrote it, or the file. Text in, [`Config`] or a named
//! [`ConfigError`] out: the shell reads the file and passes its text and name.

use serde::Deserialize as _;

use super::{Config, ConfigError, parse_table, parse_value, set_path};

/// A config field set on the command line: by `--set field=value`, or by a flag that stands
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

impl Override {
    /// `--set FIELD=VALUE`, from its argument `FIELD=VALUE` (the value is TOML; a bare word
    /// that is not, e.g. `paper`, is a string).
    ///
    /// # Errors
    /// No `=`: the message says what is expected.
    pub fn from_set(text: &str) -> Result<Self, String> {
        let (field, value) = text
            .split_once('=')
            .ok_or_else(|| format!("`{text}`: expected FIELD=VALUE, e.g. controller.kp=1.0"))?;
        Ok(Self {
            field: field.trim().to_owned(),
            value: parse_value(value.trim()),
            flag: format!("--set {text}"),
        })
    }
}

/// A configuration file's text and the name errors give it (its path, as the user wrote it).
#[derive(Clone, Copy, Debug)]
pub struct File<'a> {
    /// The name, e.g. `robot.toml`.
    pub name: &'a str,
    /// Its TOML text.
    pub text: &'a str,
}

impl File<'_> {
    /// The file's table.
    ///
    /// # Errors
    /// The text is not TOML ([`ConfigError::Parse`], naming the file).
    pub fn table(&self) -> Result<toml::Table, ConfigError> {
        parse_table(self.text, self.name)
    }
}

/// Sets each override's field in `table`, in order.
///
/// # Errors
/// An override's path crosses a non-table value: the error names its flag.
pub fn apply(table: &mut toml::Table, overrides: &[Override]) -> Result<(), ConfigError> {
    for o in overrides {
        set_path(table, &o.field, o.value.clone()).map_err(|e| e.with_origin(&o.flag))?;
    }
    Ok(())
}

/// Where a configuration came from, as the user gave it: the file (else "the defaults") and
/// the flags that changed it, e.g. `robot.toml with --seed 3 --set eve.alpha=0.1`.
#[must_use]
pub fn origin(file: Option<&str>, overrides: &[Override]) -> String {
    let base = file.unwrap_or("the defaults").to_owned();
    if overrides.is_empty() {
        base
    } else {
        let flags: Vec<&str> = overrides.iter().map(|o| o.flag.as_str()).collect();
        format!("{base} with {}", flags.join(" "))
    }
}

/// The configuration of `table` (a file's, or empty for the defaults; `file` names it) with
/// `overrides` applied and validated.
///
/// # Errors
/// The first problem, blamed on the flag that caused it ([`blame`]), else on the file.
pub fn load(
    mut table: toml::Table,
    file: Option<&str>,
    overrides: &[Override],
) -> Result<Config, ConfigError> {
    apply(&mut table, overrides)?;
    Config::from_table(table, &origin(file, overrides)).map_err(|e| blame(e, overrides))
}

/// Names the flag behind a configuration error, as the user wrote it, instead of the TOML it
/// was merged into: a value out of range that a flag set (`--delta-v -1: \`protocol.delta_v\`
/// = -1.0 is not allowed …`), or a flag whose value does not fit its field at all (wrong
/// type, unknown field). Other errors are returned as they are.
#[must_use]
pub fn blame(error: ConfigError, overrides: &[Override]) -> ConfigError {
    match &error {
        ConfigError::Invalid {
            field,
            value,
            allowed,
            ..
        } => match overrides
            .iter()
            .rev()
            .find(|o| &o.field == field && &o.value.to_string() == value)
        {
            Some(o) => ConfigError::Invalid {
                origin: o.flag.clone(),
                field: field.clone(),
                value: value.clone(),
                allowed: allowed.clone(),
            },
            None => error,
        },
        ConfigError::Parse { .. } => overrides
            .iter()
            .find_map(|o| {
                let mut alone = toml::Table::new();
                set_path(&mut alone, &o.field, o.value.clone()).ok()?;
                let e = Config::deserialize(toml::Value::Table(alone)).err()?;
                Some(ConfigError::Parse {
                    origin: o.flag.clone(),
                    message: e.message().to_owned(),
                })
            })
            .unwrap_or(error),
    }
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

    /// The error of the defaults with these overrides.
    fn loaded(overrides: &[Override]) -> String {
        load(toml::Table::new(), None, overrides)
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn errors_name_the_flag_the_user_wrote() {
        let delta_v = flag("--delta-v -1", "protocol.delta_v", (-1.0).into());
        assert_eq!(
            loaded(&[delta_v]),
            "--delta-v -1: `protocol.delta_v` = -1.0 is not allowed (allowed: ≥ 0, finite)"
        );
        let kp = flag("--set controller.kp=abc", "controller.kp", "abc".into());
        let text = loaded(&[flag("--seed 3", "run.seed", 3.into()), kp]);
        assert_eq!(
            text,
            "--set controller.kp=abc: invalid type: string \"abc\", expected f64"
        );
        assert!(!text.contains("TOML parse error"), "{text}");
        let unknown = flag("--set controller.gain=2", "controller.gain", 2.into());
        let text = loaded(&[unknown]);
        assert!(
            text.starts_with("--set controller.gain=2: unknown field `gain`"),
            "{text}"
        );
        // An error about a field no flag set keeps its origin: the defaults and the flags.
        let text = loaded(&[flag("--set robot.T=1e-6", "robot.T", 1e-6.into())]);
        assert!(
            text.starts_with(
                "the defaults with --set robot.T=1e-6: `trajectory.laps` = 3 is not allowed"
            ),
            "{text}"
        );
    }

    #[test]
    fn a_file_and_its_flags_load_in_order() {
        let file = File {
            name: "robot.toml",
            text: "[protocol]\ndelta_v = 0.02\n",
        };
        let set = |text: &str| Override::from_set(text).unwrap();
        let overrides = [set("protocol.delta_v=0.03"), set("observer.variant=paper")];
        let config = load(file.table().unwrap(), Some(file.name), &overrides).unwrap();
        assert_eq!(config.protocol.delta_v, 0.03);
        assert_eq!(config.observer.variant, crate::observer::Variant::Paper);
        let err = load(
            file.table().unwrap(),
            Some(file.name),
            &[set("eve.alpha=2.0")],
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.starts_with("--set eve.alpha=2.0: `eve.alpha` = 2.0 is not allowed"),
            "{err}"
        );
        let err = load(
            File {
                name: "bad.toml",
                text: "[protocol]\ndelta_v = -0.5\n",
            }
            .table()
            .unwrap(),
            Some("bad.toml"),
            &[],
        )
        .unwrap_err()
        .to_string();
        assert!(err.starts_with("bad.toml: `protocol.delta_v`"), "{err}");
        assert!(Override::from_set("controller.kp").is_err());
        let err = File {
            name: "broken.toml",
            text: "[protocol\n",
        }
        .table()
        .unwrap_err();
        assert!(err.to_string().starts_with("broken.toml: "), "{err}");
    }
}
