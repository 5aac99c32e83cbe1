//! Named worlds (docs/world.md, "Presets": where each value comes from).

use std::f64::consts::PI;

use super::config::{Integration, WorldConfig, WorldPreset};

/// Khepera IV encoder pulses per wheel turn (K-Team: 19,456).
const KHEPERA_PULSES_PER_TURN: f64 = 19_456.0;
/// Khepera IV speed unit (m/s of wheel rim) and wheel radius (m): 0.6781 mm/s, 21 mm.
const KHEPERA_SPEED_UNIT: f64 = 0.6781e-3;
const KHEPERA_WHEEL_RADIUS: f64 = 0.021;
/// Dynamixel XL430-W250 velocity unit (rev/min) and encoder steps per turn.
const DYNAMIXEL_VELOCITY_UNIT_RPM: f64 = 0.229;
const DYNAMIXEL_STEPS_PER_TURN: f64 = 4096.0;

impl WorldPreset {
    /// Its values (the fields it leaves out are the parties').
    #[must_use]
    pub fn values(self) -> WorldConfig {
        match self {
            Self::Ideal => WorldConfig::default(),
            Self::KheperaIv => WorldConfig {
                process_std: Some([0.001, 0.001, 0.002]),
                slip_std: Some(0.02),
                jitter: Some(0.001),
                ..Self::KheperaIvNoiseFree.values()
            },
            Self::KheperaIvNoiseFree => WorldConfig {
                process_std: Some([0.0; 3]),
                slip_std: Some(0.0),
                lag: Some(0.03),
                delay: Some(0.01),
                integration: Some(Integration::Continuous),
                command_quantum: Some(KHEPERA_SPEED_UNIT / KHEPERA_WHEEL_RADIUS),
                encoder_quantum: Some(2.0 * PI / KHEPERA_PULSES_PER_TURN),
                jitter: Some(0.0),
                ..WorldConfig::default()
            },
            Self::Turtlebot3Burger => WorldConfig {
                process_std: Some([0.002, 0.002, 0.005]),
                slip_std: Some(0.03),
                lag: Some(0.05),
                delay: Some(0.02),
                integration: Some(Integration::Continuous),
                command_quantum: Some(DYNAMIXEL_VELOCITY_UNIT_RPM * 2.0 * PI / 60.0),
                encoder_quantum: Some(2.0 * PI / DYNAMIXEL_STEPS_PER_TURN),
                jitter: Some(0.002),
                ..WorldConfig::default()
            },
        }
    }
}

impl std::fmt::Display for WorldPreset {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_are_valid_and_named_both_ways() {
        for preset in WorldPreset::ALL {
            preset.values().validate(0.2).unwrap();
            assert_eq!(WorldPreset::named(preset.name()), Some(preset));
            let text = toml::to_string(&WorldConfig {
                preset: Some(preset),
                ..WorldConfig::default()
            })
            .unwrap();
            assert!(text.contains(preset.name()), "{text}");
        }
        assert_eq!(WorldPreset::named("khepera"), None);
        assert_eq!(WorldPreset::Ideal.values(), WorldConfig::default());
    }
}
