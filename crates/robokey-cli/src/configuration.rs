//! The command line's configuration: the `--config` file, `--set` and the flags that stand
//! for a field, read into a [`Config`] by `robokey::config::source` (errors name the flag or
//! the file the user wrote).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use robokey::Config;
use robokey::config::source::{self, File, Override};

use crate::exit::usage;

/// Options shared by commands that read a configuration.
#[derive(Args, Debug, Clone)]
pub struct ConfigOptions {
    /// Set any config field, e.g. `--set controller.kp=1.0` (repeatable).
    #[arg(long = "set", value_name = "FIELD=VALUE", value_parser = Override::from_set)]
    pub set: Vec<Override>,
}

/// The table of a TOML file (the file read here, its name in errors).
///
/// # Errors
/// The file cannot be read, or is not TOML.
pub fn read_table(path: &Path) -> Result<toml::Table> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path).with_context(|| name.clone())?;
    Ok(File {
        name: &name,
        text: &text,
    }
    .table()?)
}

/// Loads a configuration from an optional file plus overrides; errors name the flag the
/// user wrote.
///
/// # Errors
/// The file cannot be read, holds a sweep, or the configuration is invalid.
pub fn load_config(path: Option<&Path>, overrides: &[Override]) -> Result<Config> {
    let table = path.map(read_table).transpose()?.unwrap_or_default();
    if table.contains_key("sweep") || table.contains_key("experiment") {
        usage!(
            "{}: holds a sweep; run it with `robokey sweep`",
            path.map_or_else(String::new, |p| p.display().to_string())
        );
    }
    let name = path.map(|p| p.display().to_string());
    Ok(source::load(table, name.as_deref(), overrides)?)
}

/// `--set` overrides plus the ones a command's own flags stand for.
pub struct FlagOverrides(Vec<Override>);

impl FlagOverrides {
    /// Starts from the `--set` overrides.
    pub fn new(set: &[Override]) -> Self {
        Self(set.to_vec())
    }

    /// Sets `field` when `flag` was given with a value.
    pub fn value<V: Into<toml::Value> + std::fmt::Display>(
        &mut self,
        flag: &str,
        field: &str,
        value: Option<V>,
    ) {
        if let Some(value) = value {
            self.0.push(Override {
                field: field.into(),
                flag: format!("{flag} {value}"),
                value: value.into(),
            });
        }
    }

    /// Sets `field` to `value` when the switch `flag` was given.
    pub fn switch(&mut self, flag: &str, given: bool, field: &str, value: bool) {
        if given {
            self.0.push(Override {
                field: field.into(),
                value: value.into(),
                flag: flag.into(),
            });
        }
    }

    /// `--seed`, which TOML holds as a signed integer.
    ///
    /// # Errors
    /// A seed TOML cannot hold.
    pub fn seed(&mut self, seed: Option<u64>) -> Result<()> {
        if let Some(seed) = seed {
            let Ok(signed) = i64::try_from(seed) else {
                usage!(
                    "--seed {seed} is not allowed (allowed: 0 to 2^63 − 1; TOML integers are signed)"
                );
            };
            self.0.push(Override {
                field: "run.seed".into(),
                value: signed.into(),
                flag: format!("--seed {seed}"),
            });
        }
        Ok(())
    }

    /// Loads the configuration with these overrides.
    ///
    /// # Errors
    /// As [`load_config`].
    pub fn load(&self, path: Option<&Path>) -> Result<Config> {
        load_config(path, &self.0)
    }
}

/// The world of an emulator (`kh4-emulator`, `ros2-sim`): its seed, the parties'
/// configuration whose values it takes where it sets none, and `--world`.
#[derive(Args, Debug)]
pub struct WorldNoiseArgs {
    /// Seed of the world's noise, drawn from the simulator's random streams of this seed:
    /// kh4-emulator's motion and sensors (replicate i for the i-th connection), ros2-sim's
    /// (replicate 0).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Configuration (TOML): the parties' values the world takes where it sets none (motion
    /// noise, the sensors' noise), the wheel geometry (`robot.r`, `robot.D`), a [world].
    #[arg(long, short)]
    config: Option<PathBuf>,
    #[command(flatten)]
    options: ConfigOptions,
    #[command(flatten)]
    world: crate::world::WorldSpecArgs,
}

impl WorldNoiseArgs {
    /// The configuration with `--world`, its `run.seed` the seed.
    ///
    /// # Errors
    /// As [`load_config`], or a `--world` that is neither a preset nor a valid world file.
    pub fn load(&self) -> Result<Config> {
        let mut config = load_config(self.config.as_deref(), &self.options.set)?;
        self.world.apply(&mut config)?;
        config.run.seed = self.seed;
        Ok(config)
    }
}
