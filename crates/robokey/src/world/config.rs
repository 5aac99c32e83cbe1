//! The `[world]` table (docs/world.md): the true physics of the robot and of the sensors
//! around it, apart from what the parties are configured with. Every field is optional: an
//! absent field is the preset's value if a preset names it, else the parties' own.

use serde::{Deserialize, Serialize};

/// How the plant integrates the unicycle over a sample period.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Integration {
    /// One forward-Euler step per period at the heading it starts with (docs/model.md); poses
    /// between the sample instants lie on the straight ramp between them.
    Euler,
    /// The unicycle and the wheels' lag integrated within the period in sub-steps, each an
    /// exact arc at its mean speeds.
    Continuous,
}

impl Integration {
    /// Its name in configurations.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Euler => "euler",
            Self::Continuous => "continuous",
        }
    }
}

/// `[world]`: each field, when present, overrides the preset's value and the parties'.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WorldConfig {
    /// A named world whose values fill the fields left out.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub preset: Option<WorldPreset>,
    /// Additive motion noise std per step `[m, m, rad]` (parties: `noise.process_std`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub process_std: Option<[f64; 3]>,
    /// AR(1) correlation ρ of the motion noise between steps, in (−1, 1) (parties: 0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub process_rho: Option<f64>,
    /// Per-wheel multiplicative slip std: each wheel's travel in a step is multiplied by
    /// `1 + slip_std·z`, `z ~ N(0, 1)` (fraction; parties: 0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slip_std: Option<f64>,
    /// First-order time constant τ of each wheel's speed response to its command (s;
    /// parties: `private.prior_lag`, 0 by default; absent: 0, instantaneous, whatever
    /// they state).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lag: Option<f64>,
    /// Transport delay (dead time) before a command acts (s; parties: 0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub delay: Option<f64>,
    /// `euler` (the parties' map) or `continuous`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub integration: Option<Integration>,
    /// Wheel-speed command resolution (rad/s; commands round to the nearest multiple; 0:
    /// none, the parties').
    #[serde(skip_serializing_if = "Option::is_none")]
    pub command_quantum: Option<f64>,
    /// Encoder resolution (rad of wheel rotation; the odometry reads the wheels' angles
    /// rounded to it; 0: none, the parties').
    #[serde(skip_serializing_if = "Option::is_none")]
    pub encoder_quantum: Option<f64>,
    /// Std of the sample instants' timing error (s; parties: 0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub jitter: Option<f64>,
    /// The controller's sensor as it really is, std `[m, m, rad]` (parties:
    /// `sensing.controller_std`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub controller_std: Option<[f64; 3]>,
    /// Eve's camera frame rate (frames/s, random phase per session): she films the motion
    /// between the instants. Absent: one frame at each sample instant (the parties').
    #[serde(skip_serializing_if = "Option::is_none")]
    pub camera_fps: Option<f64>,
    /// Std of each of her frames `[m, m, rad]`, white and independent between frames.
    /// Absent: `eve.camera_std` at the instants, or at `camera_fps` the per-frame noise that
    /// is worth `eve.camera_std` per instant, `σ_f = σ_e·√(2fT/3)` (docs/world.md).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub camera_frame_std: Option<[f64; 3]>,
}

/// Largest lag and delay (s): a world's memory of its commands stays bounded.
pub const MAX_WORLD_SECONDS: f64 = 1.0;
/// Largest camera frame rate (frames/s).
pub const MAX_CAMERA_FPS: f64 = 1000.0;
/// Largest slip std (fraction of travel): `1 + slip_std·z < 0` then has probability 2.3 %.
pub const MAX_SLIP_STD: f64 = 0.5;
/// Largest jitter std, as a fraction of the sample time `robot.T`.
pub const MAX_JITTER_FRACTION: f64 = 0.1;

/// A world value outside its range: the field (`world.…`), the value and what is allowed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("`{field}` = {value} is not allowed (allowed: {allowed})")]
pub struct WorldFieldError {
    /// Dotted field path, e.g. `world.lag`.
    pub field: String,
    /// The offending value.
    pub value: String,
    /// The allowed range.
    pub allowed: String,
}

fn refuse(field: &str, value: impl std::fmt::Debug, allowed: &str) -> WorldFieldError {
    WorldFieldError {
        field: format!("world.{field}"),
        value: format!("{value:?}"),
        allowed: allowed.to_owned(),
    }
}

fn within(field: &str, x: Option<f64>, low: f64, high: f64) -> Result<(), WorldFieldError> {
    match x {
        Some(x) if !(x >= low && x <= high) => Err(refuse(field, x, &format!("{low} to {high}"))),
        _ => Ok(()),
    }
}

fn each(
    field: &str,
    x: Option<[f64; 3]>,
    ok: fn(f64) -> bool,
    allowed: &str,
) -> Result<(), WorldFieldError> {
    match x {
        Some(values) => match values.iter().position(|&v| !ok(v)) {
            Some(i) => Err(refuse(&format!("{field}[{i}]"), values[i], allowed)),
            None => Ok(()),
        },
        None => Ok(()),
    }
}

impl WorldConfig {
    /// Every field present (the schema of the table, for naming unknown fields).
    #[must_use]
    pub fn every() -> Self {
        Self {
            preset: Some(WorldPreset::Ideal),
            process_std: Some([0.0; 3]),
            process_rho: Some(0.0),
            slip_std: Some(0.0),
            lag: Some(0.0),
            delay: Some(0.0),
            integration: Some(Integration::Euler),
            command_quantum: Some(0.0),
            encoder_quantum: Some(0.0),
            jitter: Some(0.0),
            controller_std: Some([1.0; 3]),
            camera_fps: Some(1.0),
            camera_frame_std: Some([1.0; 3]),
        }
    }

    /// Checks each present field against its range; `sample_time` is `robot.T` (s), which
    /// bounds the jitter.
    ///
    /// # Errors
    /// The first field out of range.
    pub fn validate(&self, sample_time: f64) -> Result<(), WorldFieldError> {
        let non_negative = |x: f64| x >= 0.0 && x.is_finite();
        let positive = |x: f64| x > 0.0 && x.is_finite();
        each("process_std", self.process_std, non_negative, "≥ 0, finite")?;
        if let Some(rho) = self.process_rho
            && !(rho > -1.0 && rho < 1.0)
        {
            return Err(refuse("process_rho", rho, "−1 < ρ < 1 (open)"));
        }
        within("slip_std", self.slip_std, 0.0, MAX_SLIP_STD)?;
        within("lag", self.lag, 0.0, MAX_WORLD_SECONDS)?;
        within("delay", self.delay, 0.0, MAX_WORLD_SECONDS)?;
        for (field, x) in [
            ("command_quantum", self.command_quantum),
            ("encoder_quantum", self.encoder_quantum),
        ] {
            if let Some(x) = x
                && !non_negative(x)
            {
                return Err(refuse(field, x, "≥ 0, finite (0: none)"));
            }
        }
        within(
            "jitter",
            self.jitter,
            0.0,
            MAX_JITTER_FRACTION * sample_time,
        )?;
        each(
            "controller_std",
            self.controller_std,
            positive,
            "> 0, finite",
        )?;
        if let Some(fps) = self.camera_fps
            && !(fps > 0.0 && fps <= MAX_CAMERA_FPS)
        {
            return Err(refuse(
                "camera_fps",
                fps,
                &format!("> 0 and at most {MAX_CAMERA_FPS} frames/s"),
            ));
        }
        each(
            "camera_frame_std",
            self.camera_frame_std,
            positive,
            "> 0, finite",
        )?;
        Ok(())
    }

    /// The `[world]` table of a world file's text (TOML holding that table and nothing
    /// else), its fields checked by name; their ranges are checked with the configuration
    /// it joins ([`crate::Config::validate`]).
    ///
    /// # Errors
    /// A [`crate::config::ConfigError`] attributed to `origin`: the text does not parse,
    /// holds another table or value, or the table an unknown field or a wrong type.
    pub fn from_file_text(text: &str, origin: &str) -> Result<Self, crate::config::ConfigError> {
        let parse_error = |message: String| crate::config::ConfigError::Parse {
            origin: origin.to_owned(),
            message,
        };
        let mut table = crate::config::parse_table(text, origin)?;
        if let Some(other) = table.keys().find(|k| *k != "world") {
            return Err(parse_error(format!(
                "a world file holds a [world] table and nothing else; `{other}` is not part of \
                 it (the parties' settings belong in their configuration)"
            )));
        }
        let world = table
            .remove("world")
            .ok_or_else(|| parse_error("a world file holds a [world] table; it has none".into()))?;
        world
            .try_into::<Self>()
            .map_err(|e| parse_error(format!("[world]: {}", e.to_string().trim_end())))
    }

    /// This table's fields, each falling back on `under`'s where absent.
    #[must_use]
    pub fn over(&self, under: &Self) -> Self {
        Self {
            preset: self.preset.or(under.preset),
            process_std: self.process_std.or(under.process_std),
            process_rho: self.process_rho.or(under.process_rho),
            slip_std: self.slip_std.or(under.slip_std),
            lag: self.lag.or(under.lag),
            delay: self.delay.or(under.delay),
            integration: self.integration.or(under.integration),
            command_quantum: self.command_quantum.or(under.command_quantum),
            encoder_quantum: self.encoder_quantum.or(under.encoder_quantum),
            jitter: self.jitter.or(under.jitter),
            controller_std: self.controller_std.or(under.controller_std),
            camera_fps: self.camera_fps.or(under.camera_fps),
            camera_frame_std: self.camera_frame_std.or(under.camera_frame_std),
        }
    }
}

/// A named world: `world.preset` or `--world NAME`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WorldPreset {
    /// The parties' own model: every field as they are configured.
    Ideal,
    /// A Khepera IV on a lab floor: its speed unit and encoder pulse, an estimated motor lag,
    /// delay, timing jitter, slip and motion noise.
    KheperaIv,
    /// The Khepera IV's mechanics without motion noise, slip or jitter: the world the Khepera
    /// emulator had before worlds existed.
    KheperaIvNoiseFree,
    /// A ROBOTIS TurtleBot3 Burger: its Dynamixel XL430's velocity unit and encoder, and
    /// estimated lag, delay, jitter, slip and motion noise.
    Turtlebot3Burger,
}

impl WorldPreset {
    /// Every preset, in the order the docs list them.
    pub const ALL: [Self; 4] = [
        Self::Ideal,
        Self::KheperaIv,
        Self::KheperaIvNoiseFree,
        Self::Turtlebot3Burger,
    ];

    /// Its name in configurations and on the command line.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Ideal => "ideal",
            Self::KheperaIv => "khepera-iv",
            Self::KheperaIvNoiseFree => "khepera-iv-noise-free",
            Self::Turtlebot3Burger => "turtlebot3-burger",
        }
    }

    /// The preset of this name.
    #[must_use]
    pub fn named(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_values_are_named_with_their_range() {
        let cases: [(WorldConfig, &str, &str); 9] = [
            (
                WorldConfig {
                    lag: Some(-0.01),
                    ..WorldConfig::default()
                },
                "world.lag",
                "0 to 1",
            ),
            (
                WorldConfig {
                    delay: Some(-1.0),
                    ..WorldConfig::default()
                },
                "world.delay",
                "0 to 1",
            ),
            (
                WorldConfig {
                    command_quantum: Some(-0.1),
                    ..WorldConfig::default()
                },
                "world.command_quantum",
                "≥ 0",
            ),
            (
                WorldConfig {
                    encoder_quantum: Some(f64::NAN),
                    ..WorldConfig::default()
                },
                "world.encoder_quantum",
                "≥ 0",
            ),
            (
                WorldConfig {
                    process_rho: Some(1.0),
                    ..WorldConfig::default()
                },
                "world.process_rho",
                "−1 < ρ < 1",
            ),
            (
                WorldConfig {
                    camera_fps: Some(0.0),
                    ..WorldConfig::default()
                },
                "world.camera_fps",
                "> 0",
            ),
            (
                WorldConfig {
                    process_std: Some([0.001, -0.001, 0.0]),
                    ..WorldConfig::default()
                },
                "world.process_std[1]",
                "≥ 0",
            ),
            (
                WorldConfig {
                    jitter: Some(0.05),
                    ..WorldConfig::default()
                },
                "world.jitter",
                "0 to 0.02",
            ),
            (
                WorldConfig {
                    slip_std: Some(0.7),
                    ..WorldConfig::default()
                },
                "world.slip_std",
                "0 to 0.5",
            ),
        ];
        for (world, field, allowed) in cases {
            let error = world.validate(0.2).unwrap_err();
            let text = error.to_string();
            assert_eq!(error.field, field, "{text}");
            assert!(text.contains(allowed), "{text}");
        }
        WorldConfig::every().validate(0.2).unwrap();
    }

    #[test]
    fn a_world_file_holds_a_world_table_and_nothing_else() {
        let world = WorldConfig::from_file_text(
            "[world]\npreset = \"khepera-iv\"\nlag = 0.05\n",
            "lab.toml",
        )
        .unwrap();
        assert_eq!(world.lag, Some(0.05));
        assert_eq!(world.preset, Some(WorldPreset::KheperaIv));
        for (text, expected) in [
            ("[robot]\nT = 0.1\n", "`robot` is not part of it"),
            ("lag = 0.05\n", "`lag` is not part of it"),
            ("", "it has none"),
            ("[world]\nlagg = 0.05\n", "lagg"),
            ("[world]\nlag = \"slow\"\n", "lag"),
            ("[world", "lab.toml"),
        ] {
            let error = WorldConfig::from_file_text(text, "lab.toml")
                .unwrap_err()
                .to_string();
            assert!(
                error.contains("lab.toml") && error.contains(expected),
                "{error}"
            );
        }
    }
}
