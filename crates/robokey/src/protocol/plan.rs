//! What both endpoints agree on before a session starts.

use std::sync::Arc;

use crate::code::BlockCode;
use crate::config::Config;
use crate::model::{DiffDrive, Unicycle};

/// The agreed session parameters, derived from the configuration.
#[derive(Clone, Debug)]
pub struct SessionPlan {
    /// Session id.
    pub session: u32,
    /// SHA-256 of the resolved configuration.
    pub config_digest: [u8; 32],
    /// Sample time `T` (s).
    pub sample_time: f64,
    /// Number of commands `N`; the stop command is sent at step `N`.
    pub steps: u32,
    /// Whether key bits are sent (false: the J_x baseline).
    pub enabled: bool,
    /// `Δ = [Δv, Δω]` (m/s, rad/s).
    pub delta: Unicycle,
    /// The block code.
    pub code: Arc<dyn BlockCode>,
    /// Largest accepted distance to the nearest codeword.
    pub accept_max_distance: u32,
    /// The agreed wheel geometry.
    pub drive: DiffDrive,
    /// Consecutive missing commands after which the robot stops its wheels.
    pub max_hold: u32,
}

impl SessionPlan {
    /// The plan of a validated configuration. The run is `N` commands long: the
    /// trajectory's length, cut short when the key budget (`⌊key_bits/k_c⌋` messages) is
    /// spent earlier.
    #[must_use]
    pub fn from_config(config: &Config, session: u32) -> Self {
        let code = config.code.build();
        let trajectory_steps = config.trajectory().steps(config.robot.sample_time) as u32;
        let budget_steps = match config.code.key_bits {
            0 => u32::MAX,
            bits => (bits / code.k() as u32).saturating_mul(code.n() as u32),
        };
        let steps = if config.protocol.enabled {
            trajectory_steps.min(budget_steps)
        } else {
            trajectory_steps
        };
        Self {
            session,
            config_digest: config_digest(config),
            sample_time: config.robot.sample_time,
            steps,
            enabled: config.protocol.enabled,
            delta: Unicycle::new(config.protocol.delta_v, config.protocol.delta_omega),
            code,
            accept_max_distance: config.code.accept_max_distance,
            drive: DiffDrive {
                wheel_radius: config.robot.r,
                axle_length: config.robot.axle_length,
            },
            max_hold: 2,
        }
    }

    /// Number of complete codewords (a trailing partial codeword is dropped).
    #[must_use]
    pub fn codewords(&self) -> u32 {
        if self.enabled {
            self.steps / self.code.n() as u32
        } else {
            0
        }
    }

    /// Codeword index and bit position of step `k`.
    #[must_use]
    pub fn position(&self, step: u32) -> (u32, u32) {
        let n = self.code.n() as u32;
        (step / n, step % n)
    }
}

/// SHA-256 of the resolved configuration's TOML.
#[must_use]
pub fn config_digest(config: &Config) -> [u8; 32] {
    use sha2::Digest;
    sha2::Sha256::digest(config.to_toml().as_bytes()).into()
}
