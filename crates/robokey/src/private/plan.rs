//! What both private-sensing endpoints agree on before a session starts.

use super::doublet::{DoubletInputs, Perturbation};
use super::session::doublet_model;
use crate::config::Config;
use crate::model::DiffDrive;
use crate::protocol::{Confirmer, config_digest};

/// The agreed parameters of a private-sensing session, derived from the configuration.
#[derive(Clone, Debug)]
pub struct PrivatePlan {
    /// Sample time `T` (s).
    pub sample_time: f64,
    /// Number of steps `N`: the trajectory's length (private sensing has no key budget). The
    /// stop command is sent at step `N`.
    pub steps: u32,
    /// Whether doublets carry bits (false: the J_x baseline).
    pub enabled: bool,
    /// The bits a doublet carries and their Δ.
    pub perturbation: Perturbation,
    /// Doublets whose public nominal turn rate exceeds this carry no bit (rad/s).
    pub max_turn_rate: f64,
    /// The agreed wheel geometry.
    pub drive: DiffDrive,
    /// The robot's wheel-speed limit (rad/s): it applies no input beyond it.
    pub wheel_limit: f64,
    /// Consecutive missing commands after which the robot stops its wheels.
    pub max_hold: u32,
    /// Computes the confirmation tags: the session layer's once a network handshake is
    /// done, [`Confirmer::public`] otherwise (the simulator).
    pub confirmer: Confirmer,
}

impl PrivatePlan {
    /// The plan of a validated private-sensing configuration for session `session`.
    #[must_use]
    pub fn from_config(config: &Config, session: u32) -> Self {
        Self {
            sample_time: config.robot.sample_time,
            steps: config.trajectory().steps(config.robot.sample_time) as u32,
            enabled: config.protocol.enabled,
            perturbation: doublet_model(config).perturbation,
            max_turn_rate: config.protocol.max_turn_rate,
            drive: DiffDrive {
                wheel_radius: config.robot.r,
                axle_length: config.robot.axle_length,
            },
            wheel_limit: config.robot.wheel_limit,
            max_hold: 2,
            confirmer: Confirmer::public(session, &config_digest(config)),
        }
    }

    /// Number of doublets `⌊N/2⌋`: doublet j occupies steps `2j` and `2j + 1`; with `N` odd
    /// the last step is lone.
    #[must_use]
    pub fn doublets(&self) -> u32 {
        self.steps / 2
    }

    /// Whether step `k` starts a doublet (rather than being a lone last step or the stop).
    #[must_use]
    pub fn starts_doublet(&self, step: u32) -> bool {
        step.is_multiple_of(2) && step + 2 <= self.steps
    }

    /// Whether a doublet with these public inputs carries bits: the protocol is on and its
    /// nominal turn rate passes the gate.
    #[must_use]
    pub fn carries(&self, inputs: &DoubletInputs) -> bool {
        self.enabled && inputs.turn_rate() <= self.max_turn_rate
    }
}
