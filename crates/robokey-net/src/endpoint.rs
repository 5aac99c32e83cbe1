//! The endpoints of either sensing mode as the agents drive them: the odometry mode's
//! (`RobotEndpoint`, `ControllerEndpoint`) and private sensing's (`PrivateRobotEndpoint`,
//! `PrivateControllerEndpoint`) take the same inputs and emit the same outputs.

use rand::CryptoRng;
use robokey::Config;
use robokey::config::SensingMode;
use robokey::private::{PrivateControllerEndpoint, PrivatePlan, PrivateRobotEndpoint};
use robokey::protocol::{
    Confirmer, ControllerEndpoint, ControllerInput, ControllerOutput, RobotEndpoint, RobotInput,
    RobotOutput, SessionPlan,
};

/// What a session decides fates of, and how big it is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shape {
    /// Steps N.
    pub steps: u32,
    /// Sample time T (s).
    pub sample_time: f64,
    /// Units whose fates the session decides: codewords, or doublets in private sensing.
    pub units: u32,
    /// Key bits a kept unit adds (k_c, or the bits per doublet).
    pub bits_per_unit: usize,
    /// Whether the units are doublets (private sensing).
    pub doublets: bool,
    /// Whether key bits are sent (false: the J_x baseline).
    pub enabled: bool,
}

impl Shape {
    /// Whether step `k` starts a doublet.
    #[must_use]
    pub fn starts_doublet(&self, step: u32) -> bool {
        self.doublets && step.is_multiple_of(2) && step + 2 <= self.steps
    }
}

/// The shape of a validated configuration's sessions.
#[must_use]
pub fn shape(config: &Config) -> Shape {
    match config.sensing.mode {
        SensingMode::Odometry => {
            let plan = SessionPlan::from_config(config, 0);
            Shape {
                steps: plan.steps,
                sample_time: plan.sample_time,
                units: plan.codewords(),
                bits_per_unit: plan.code.k(),
                doublets: false,
                enabled: plan.enabled,
            }
        }
        SensingMode::Private => {
            let plan = PrivatePlan::from_config(config, 0);
            Shape {
                steps: plan.steps,
                sample_time: plan.sample_time,
                units: plan.doublets(),
                bits_per_unit: usize::from(plan.perturbation.bits_per_doublet),
                doublets: true,
                enabled: plan.enabled,
            }
        }
    }
}

/// A robot endpoint.
pub trait RobotSide {
    /// Feeds one input.
    fn handle_input(&mut self, input: RobotInput);
    /// The next output, if any.
    fn poll_output(&mut self) -> Option<RobotOutput>;
    /// The step whose command the robot waits for.
    fn next_command(&self) -> u32;
    /// Whether the session is over.
    fn is_done(&self) -> bool;
    /// Commands applied to the wheels.
    fn commands_applied(&self) -> u32;
    /// The robot's key (raw bits in private sensing).
    fn key(&self) -> &[u8];
}

macro_rules! robot_side {
    ($endpoint:ty) => {
        impl RobotSide for $endpoint {
            fn handle_input(&mut self, input: RobotInput) {
                <$endpoint>::handle_input(self, input);
            }
            fn poll_output(&mut self) -> Option<RobotOutput> {
                <$endpoint>::poll_output(self)
            }
            fn next_command(&self) -> u32 {
                <$endpoint>::next_command(self)
            }
            fn is_done(&self) -> bool {
                <$endpoint>::is_done(self)
            }
            fn commands_applied(&self) -> u32 {
                <$endpoint>::commands_applied(self)
            }
            fn key(&self) -> &[u8] {
                <$endpoint>::key(self)
            }
        }
    };
}

robot_side!(RobotEndpoint);
robot_side!(PrivateRobotEndpoint);

/// The robot endpoint of `config`'s sensing mode for a bound session, confirming with the
/// session layer's `confirmer`, its key bits from `key_source`.
pub fn robot<R: CryptoRng + ?Sized>(
    config: &Config,
    session: u32,
    confirmer: Confirmer,
    key_source: &mut R,
) -> Box<dyn RobotSide> {
    match config.sensing.mode {
        SensingMode::Odometry => {
            let mut plan = SessionPlan::from_config(config, session);
            plan.confirmer = confirmer;
            Box::new(RobotEndpoint::new(plan, key_source))
        }
        SensingMode::Private => {
            let mut plan = PrivatePlan::from_config(config, session);
            plan.confirmer = confirmer;
            Box::new(PrivateRobotEndpoint::new(plan, key_source))
        }
    }
}

/// A controller endpoint.
pub trait ControllerSide {
    /// Feeds one input.
    fn handle_input(&mut self, input: ControllerInput);
    /// The next output, if any.
    fn poll_output(&mut self) -> Option<ControllerOutput>;
    /// The controller's key (its decisions in private sensing).
    fn key(&self) -> &[u8];
}

macro_rules! controller_side {
    ($endpoint:ty) => {
        impl ControllerSide for $endpoint {
            fn handle_input(&mut self, input: ControllerInput) {
                <$endpoint>::handle_input(self, input);
            }
            fn poll_output(&mut self) -> Option<ControllerOutput> {
                <$endpoint>::poll_output(self)
            }
            fn key(&self) -> &[u8] {
                <$endpoint>::key(self)
            }
        }
    };
}

controller_side!(ControllerEndpoint);
controller_side!(PrivateControllerEndpoint);

/// The controller endpoint of `config`'s sensing mode for an established session.
#[must_use]
pub fn controller(config: &Config, session: u32, confirmer: Confirmer) -> Box<dyn ControllerSide> {
    match config.sensing.mode {
        SensingMode::Odometry => {
            let mut plan = SessionPlan::from_config(config, session);
            plan.confirmer = confirmer;
            Box::new(ControllerEndpoint::new(config, plan))
        }
        SensingMode::Private => {
            let mut plan = PrivatePlan::from_config(config, session);
            plan.confirmer = confirmer;
            Box::new(PrivateControllerEndpoint::new(config, plan))
        }
    }
}
