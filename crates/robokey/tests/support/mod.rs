//! A session on the virtual network for the protocol tests: the robot and the controller
//! endpoints on a [`Pair`], around a plant whose true pose both the robot and (in private
//! sensing) the controller's sensor read exactly, with chosen messages dropped and chosen
//! sensor samples missing. (Each test binary uses part of it.)
#![allow(dead_code)]

use std::time::Duration;

use rand::rngs::ChaCha20Rng;
use robokey::Config;
use robokey::connection::{ControllerConnection, RobotConnection};
use robokey::pair::{Connected, Ending, LinkFaults, Pair, Side, Surroundings};
use robokey::protocol::{
    Controller, ControllerEvent, ControllerInput, ControllerOutput, Message, Outcome, Robot,
    RobotInput, RobotOutput, SessionPlan, Time, Timing,
};
use robokey::rng::{Purpose, stream};
use robokey::world::{PlantStreams, WorldPlant};

/// What a session ended with.
#[derive(Debug)]
pub struct Session {
    pub robot_key: Vec<u8>,
    pub controller_key: Vec<u8>,
    /// Odometry: each codeword's fate, in decision order.
    pub fates: Vec<bool>,
    /// Private sensing: the doublets decided and those erased, in order.
    pub decided: Vec<u32>,
    pub erased: Vec<u32>,
    pub robot_outcome: Option<Outcome>,
    pub controller_outcome: Option<Outcome>,
    /// How the virtual network's run ended.
    pub ending: Ending,
}

/// The world of one test session.
struct World<D, B> {
    plant: WorldPlant,
    private: bool,
    drop: D,
    blind: B,
    fates: Vec<bool>,
    decided: Vec<u32>,
    erased: Vec<u32>,
    robot_outcome: Option<Outcome>,
    controller_outcome: Option<Outcome>,
}

impl<D: FnMut(Side, &Message) -> bool, B: Fn(u32) -> bool> Surroundings<Robot, Controller>
    for World<D, B>
{
    fn robot_output(
        &mut self,
        now: Time,
        output: RobotOutput,
        robot: &mut Robot,
        controller: &mut Controller,
    ) {
        match output {
            RobotOutput::Sense { step } => {
                if step > 0 {
                    self.plant.step();
                }
                let pose = self.plant.pose();
                robot.handle_input(now, RobotInput::Sample { step, y: pose });
                if self.private && !(self.blind)(step) {
                    controller.handle_input(now, ControllerInput::Sensor { step, pose });
                }
            }
            RobotOutput::Apply(actuation) => self.plant.apply(actuation.wheels),
            RobotOutput::Finished(outcome) => self.robot_outcome = Some(outcome),
            RobotOutput::Transmit(_) => {}
        }
    }

    fn controller_output(
        &mut self,
        _now: Time,
        output: ControllerOutput,
        _robot: &mut Robot,
        _controller: &mut Controller,
    ) {
        let ControllerOutput::Event(event) = output else {
            return;
        };
        match event {
            ControllerEvent::CodewordDecided { accepted, .. } => self.fates.push(accepted),
            ControllerEvent::DoubletDecided(d) => self.decided.push(d.doublet),
            ControllerEvent::DoubletErased { doublet } => self.erased.push(doublet),
            ControllerEvent::Finished(outcome) => self.controller_outcome = Some(outcome),
            _ => {}
        }
    }

    fn intercept(&mut self, from: Side, message: Message) -> Option<Message> {
        (!(self.drop)(from, &message)).then_some(message)
    }

    fn done(&self) -> bool {
        self.robot_outcome.is_some() && self.controller_outcome.is_some()
    }
}

/// How a test session runs: the link's faults each way, the seed of the faults, the key and
/// the motion noise, and the timers.
#[derive(Clone, Copy, Debug, Default)]
pub struct Network {
    pub to_controller: LinkFaults,
    pub to_robot: LinkFaults,
    pub seed: u64,
    pub timing: Timing,
}

/// Runs one session of `config` on `network`; `drop(from, message)` removes a message sent
/// `from` a side, `blind(k)` the controller's sensor sample k (private sensing). The robot's
/// key and the plant's motion noise (`config`'s) come from streams of the network's seed.
pub fn session(
    config: &Config,
    network: Network,
    drop: impl FnMut(Side, &Message) -> bool,
    blind: impl Fn(u32) -> bool,
) -> Session {
    let plan = SessionPlan::from_config(config, 1);
    let agreed = plan.agreed.clone();
    let robot = Robot::new(
        plan.clone(),
        network.timing,
        &mut stream(9, Purpose::Key, network.seed),
        Time::ZERO,
    );
    let controller = Controller::new(config, plan.clone(), network.timing, Time::ZERO);
    let mut world = World {
        plant: WorldPlant::new(
            &config.world_model(),
            agreed.drive,
            config.robot.wheel_limit,
            agreed.sample_time,
            PlantStreams {
                process: stream(9, Purpose::Process, network.seed),
                slip: stream(9, Purpose::Slip, network.seed),
            },
            false,
        ),
        private: plan.private().is_some(),
        drop,
        blind,
        fates: Vec::new(),
        decided: Vec::new(),
        erased: Vec::new(),
        robot_outcome: None,
        controller_outcome: None,
    };
    let mut pair = Pair::new(
        robot,
        controller,
        network.to_controller,
        network.to_robot,
        network.seed,
    );
    // Long enough for the run, every retransmission and both silence timeouts.
    let limit = Duration::from_secs_f64(agreed.sample_time * f64::from(agreed.steps + 1))
        + network.timing.silence_timeout * 4;
    let ending = pair.drive(&mut world, limit);
    Session {
        robot_key: pair.robot.key().to_vec(),
        controller_key: pair.controller.key().to_vec(),
        fates: world.fates,
        decided: world.decided,
        erased: world.erased,
        robot_outcome: world.robot_outcome,
        controller_outcome: world.controller_outcome,
        ending,
    }
}

/// The two sides' addresses on the virtual network, for tests of whole connections.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Address {
    Robot,
    Controller,
}

impl std::fmt::Display for Address {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{self:?}")
    }
}

/// The plant of a conversation of `config` between two connections, its process noise and
/// slip from streams of `seed`.
pub fn connection_plant(config: &Config, seed: u64) -> WorldPlant {
    let agreed = SessionPlan::from_config(config, 0).agreed;
    WorldPlant::new(
        &config.world_model(),
        agreed.drive,
        config.robot.wheel_limit,
        agreed.sample_time,
        PlantStreams {
            process: stream(seed, Purpose::Process, 0),
            slip: stream(seed, Purpose::Slip, 0),
        },
        false,
    )
}

/// The robot asked for sample `step`: the plant moves on one period (after the first) and
/// its true pose is what the sensors read.
pub fn sensed(plant: &mut WorldPlant, step: u32) -> robokey::model::Pose {
    if step > 0 {
        plant.step();
    }
    plant.pose()
}

/// The connection layer's robot on the virtual network (its keys drawn from ChaCha20).
pub type RobotSide = Connected<RobotConnection<Address, ChaCha20Rng>, Address>;

/// The connection layer's controller on the virtual network.
pub type ControllerSide = Connected<ControllerConnection<Address>, Address>;

/// The plant's part of the robot endpoint's `event`: a `Sense` reads the true pose for the
/// robot and, when given, the controller's sensor (private sensing); an `Apply` turns the
/// wheels. The endpoint's other events are not the plant's.
pub fn drive_plant(
    plant: &mut WorldPlant,
    now: Time,
    event: RobotOutput,
    robot: &mut RobotSide,
    controller_sensor: Option<&mut ControllerSide>,
) {
    match event {
        RobotOutput::Sense { step } => {
            let pose = sensed(plant, step);
            robot.connection.handle_sample(now, step, pose);
            if let Some(controller) = controller_sensor {
                controller.connection.handle_sensor(now, step, pose);
            }
        }
        RobotOutput::Apply(a) => plant.apply(a.wheels),
        _ => {}
    }
}
