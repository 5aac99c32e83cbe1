//! `--world PRESET|FILE` (docs/world.md): the world a command without a world in its
//! configuration simulates — the simulated robot's, the emulators', the one the eavesdroppers
//! of `robokey eve --capture` know.

use std::path::Path;

use anyhow::Result;
use clap::Args;
use robokey::Config;
use robokey::world::{WorldConfig, WorldPreset};

use crate::exit::usage;

/// The world of a command that simulates or knows one.
#[derive(Args, Debug, Clone, Default)]
pub struct WorldSpecArgs {
    /// The world: a preset (ideal, khepera-iv, khepera-iv-noise-free, turtlebot3-burger) or a
    /// TOML file holding a [world] table (docs/world.md). Default: the configuration's
    /// [world], else `ideal` — the parties' own model.
    #[arg(long, value_name = "PRESET|FILE")]
    pub world: Option<String>,
}

impl WorldSpecArgs {
    /// `config` with this world (checked against `config`'s `robot.T`), or as it is.
    ///
    /// # Errors
    /// Neither a preset nor a readable file, or a file that is not a valid world (named by
    /// the file, the field, the value and the allowed range).
    pub fn apply(&self, config: &mut Config) -> Result<()> {
        let Some(spec) = &self.world else {
            return Ok(());
        };
        let world = match WorldPreset::named(spec) {
            Some(preset) => WorldConfig {
                preset: Some(preset),
                ..WorldConfig::default()
            },
            None if Path::new(spec).is_file() => {
                let text = std::fs::read_to_string(spec)
                    .map_err(|e| anyhow::anyhow!("--world {spec}: cannot read it: {e}"))?;
                WorldConfig::from_file_text(&text, spec)
                    .map_err(|e| crate::exit::Usage(e.to_string()))?
            }
            None => {
                let names: Vec<&str> = WorldPreset::ALL.iter().map(|p| p.name()).collect();
                usage!(
                    "--world {spec}: neither a preset ({}) nor a file",
                    names.join(", ")
                );
            }
        };
        config.world = Some(world);
        config
            .validate()
            .map_err(|e| crate::exit::Usage(e.with_origin(spec).to_string()))?;
        Ok(())
    }
}
