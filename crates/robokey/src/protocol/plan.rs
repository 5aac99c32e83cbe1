//! What both endpoints agree on before a session starts: the parameters every session shares
//! ([`Agreed`]) and those of its sensing mode ([`ModePlan`]).

use std::sync::Arc;

use super::auth::Confirmer;
use super::terms::config_digest;
use crate::code::BlockCode;
use crate::config::{Config, SensingMode};
use crate::model::{DiffDrive, Unicycle};
use crate::private::doublet::DoubletInputs;
use crate::private::likelihood::doublet_model;
use crate::private::plan::PrivatePlan;

/// The agreed session parameters, derived from the configuration.
#[derive(Clone, Debug)]
pub struct SessionPlan {
    /// What every session agrees on, whatever its sensing mode.
    pub agreed: Agreed,
    /// What its sensing mode adds.
    pub mode: ModePlan,
}

/// What every session agrees on.
#[derive(Clone, Debug)]
pub struct Agreed {
    /// Session id.
    pub session: u32,
    /// SHA-256 of the agreement terms.
    pub config_digest: [u8; 32],
    /// Sample time `T` (s).
    pub sample_time: f64,
    /// Number of commands `N`; the stop command is sent at step `N`.
    pub steps: u32,
    /// Whether key bits are sent (false: the J_x baseline).
    pub enabled: bool,
    /// The agreed wheel geometry.
    pub drive: DiffDrive,
    /// Consecutive missing commands after which the robot stops its wheels.
    pub max_hold: u32,
    /// The robot's wheel-speed limit (rad/s): it applies no command beyond it.
    pub wheel_limit: f64,
    /// Computes the confirmation tags: the session layer's once a network handshake is
    /// done, [`Confirmer::public`] otherwise (the simulator).
    pub confirmer: Confirmer,
}

/// The parameters of a session's sensing mode.
#[derive(Clone, Debug)]
pub enum ModePlan {
    /// The paper's scheme: the controller decides from the robot's odometry.
    Odometry(OdometryPlan),
    /// Private sensing: the controller decides from its own pose sensor.
    Private(PrivatePlan),
}

/// The odometry mode's parameters: command pairs `H⁻¹(uU ± Δ)` and a block code.
#[derive(Clone, Debug)]
pub struct OdometryPlan {
    /// `Δ = [Δv, Δω]` (m/s, rad/s).
    pub delta: Unicycle,
    /// The block code.
    pub code: Arc<dyn BlockCode>,
    /// Largest accepted distance to the nearest codeword.
    pub accept_max_distance: u32,
}

impl OdometryPlan {
    /// Codeword index and bit position of step `k`.
    #[must_use]
    pub fn position(&self, step: u32) -> (u32, u32) {
        let n = self.code.n() as u32;
        (step / n, step % n)
    }
}

impl SessionPlan {
    /// The plan of a validated configuration for session `session`. An odometry session is
    /// `N` commands long: the trajectory's length, cut short when the key budget
    /// (`⌊key_bits/k_c⌋` messages) is spent earlier; a private one is the trajectory's length.
    #[must_use]
    pub fn from_config(config: &Config, session: u32) -> Self {
        let trajectory_steps = config.trajectory().steps(config.robot.sample_time) as u32;
        let (steps, mode) = match config.sensing.mode {
            SensingMode::Odometry => {
                let code = config.code.build();
                let budget_steps = match config.code.key_bits {
                    0 => u32::MAX,
                    bits => (bits / code.k() as u32).saturating_mul(code.n() as u32),
                };
                let steps = if config.protocol.enabled {
                    trajectory_steps.min(budget_steps)
                } else {
                    trajectory_steps
                };
                let plan = OdometryPlan {
                    delta: Unicycle::new(config.protocol.delta_v, config.delta_omega()),
                    code,
                    accept_max_distance: config.code.accept_max_distance,
                };
                (steps, ModePlan::Odometry(plan))
            }
            SensingMode::Private => {
                let plan = PrivatePlan {
                    perturbation: doublet_model(config).perturbation,
                    max_turn_rate: config.protocol.max_turn_rate,
                };
                (trajectory_steps, ModePlan::Private(plan))
            }
        };
        let digest = config_digest(config);
        Self {
            agreed: Agreed {
                session,
                config_digest: digest,
                confirmer: Confirmer::public(session, &digest),
                sample_time: config.robot.sample_time,
                steps,
                enabled: config.protocol.enabled,
                drive: DiffDrive {
                    wheel_radius: config.robot.r,
                    axle_length: config.robot.axle_length,
                },
                max_hold: 2,
                wheel_limit: config.robot.wheel_limit,
            },
            mode,
        }
    }

    /// The same plan for session `session`, confirming with `confirmer` (the session
    /// layer's, once a network handshake bound the session).
    #[must_use]
    pub fn for_session(mut self, session: u32, confirmer: Confirmer) -> Self {
        self.agreed.session = session;
        self.agreed.confirmer = confirmer;
        self
    }

    /// Units whose fates the session decides: complete codewords (a trailing partial one is
    /// dropped; none with the protocol off) or doublets `⌊N/L⌋` (`L` steps per doublet).
    #[must_use]
    pub fn units(&self) -> u32 {
        match &self.mode {
            ModePlan::Odometry(_) if !self.agreed.enabled => 0,
            ModePlan::Odometry(o) => self.agreed.steps / o.code.n() as u32,
            ModePlan::Private(p) => self.agreed.steps / p.steps_per_doublet(),
        }
    }

    /// Key bits a kept unit adds: `k_c`, or the bits per doublet.
    #[must_use]
    pub fn bits_per_unit(&self) -> usize {
        match &self.mode {
            ModePlan::Odometry(o) => o.code.k(),
            ModePlan::Private(p) => p.perturbation.key_bits(),
        }
    }

    /// The odometry mode's parameters, if this is an odometry session.
    #[must_use]
    pub fn odometry(&self) -> Option<&OdometryPlan> {
        match &self.mode {
            ModePlan::Odometry(o) => Some(o),
            ModePlan::Private(_) => None,
        }
    }

    /// Private sensing's parameters, if this is a private session.
    #[must_use]
    pub fn private(&self) -> Option<&PrivatePlan> {
        match &self.mode {
            ModePlan::Private(p) => Some(p),
            ModePlan::Odometry(_) => None,
        }
    }

    /// Whether a doublet with these public inputs carries bits: private sensing, the
    /// protocol on, and its nominal turn rate within the gate.
    #[must_use]
    pub fn carries(&self, inputs: &DoubletInputs) -> bool {
        self.private()
            .is_some_and(|p| p.carries(self.agreed.enabled, inputs))
    }

    /// Steps per doublet in private sensing, `L` (2, or 3 with a prior lag); 2 otherwise.
    #[must_use]
    pub fn steps_per_doublet(&self) -> u32 {
        self.private().map_or(2, PrivatePlan::steps_per_doublet)
    }

    /// Whether step `k` starts a doublet (private sensing; never in odometry mode).
    #[must_use]
    pub fn starts_doublet(&self, step: u32) -> bool {
        self.private().is_some_and(|p| {
            let steps = p.steps_per_doublet();
            step.is_multiple_of(steps) && step + steps <= self.agreed.steps
        })
    }
}
