//! A world's plant and the sensors around it, drawn from the simulator's random streams
//! (docs/world.md): what `robokey run` simulates and what the network worlds — the simulated
//! robot, the Khepera IV and ROS 2 emulators — serve, number for number.

use rand::rngs::ChaCha8Rng;

use super::camera::{Frame, FrameCamera};
use super::model::Camera;
use super::plant::{Noise, PlantStreams, WorldPlant};
use super::sensor::InstantSensor;
use crate::config::{Config, SensingMode};
use crate::model::{DiffDrive, Pose, WheelSpeeds};
use crate::rng::Purpose;

/// Eve's camera as the world has it.
#[derive(Debug)]
enum EveCamera {
    /// One frame at each sample instant, with this noise.
    Instants(Noise),
    /// Frames at a rate, filming the motion between the instants.
    Frames(FrameCamera),
}

/// What the sensors saw at a sample instant.
#[derive(Clone, Debug, PartialEq)]
pub struct Observed {
    /// The true pose (m, m, rad).
    pub pose: Pose,
    /// The sample of the `measurement` stream: the robot's odometry in odometry mode, the
    /// controller's own sensor in private sensing.
    pub measured: Pose,
    /// Private sensing: Eve's camera at the instant (a camera at the instants).
    pub filmed: Option<Pose>,
    /// Private sensing: Eve's frames since the previous instant (a camera at a rate).
    pub frames: Vec<Frame>,
}

/// A world's plant and its sensors for one session.
#[derive(Debug)]
pub struct Scene {
    plant: WorldPlant,
    measurement: InstantSensor,
    camera: Option<EveCamera>,
}

impl Scene {
    /// The world of `config` for one session, each noise from `stream(purpose)` (the
    /// simulator's `(seed, purpose, replicate)` streams); a robot at rest at the origin.
    /// With `sensing` private, Eve's camera films it and the `measurement` stream is the
    /// controller's own sensor's; with odometry, it is the robot's odometry (std
    /// `noise.measurement_std`, the encoders' resolution).
    #[must_use]
    pub fn new(
        config: &Config,
        sensing: SensingMode,
        stream: impl Fn(Purpose) -> ChaCha8Rng,
    ) -> Self {
        let world = config.world_model();
        let drive = DiffDrive {
            wheel_radius: config.robot.r,
            axle_length: config.robot.axle_length,
        };
        let private = sensing == SensingMode::Private;
        let (std, encoder) = if private {
            (world.controller_std, 0.0)
        } else {
            (config.noise.measurement_std, world.encoder_quantum)
        };
        let camera = private.then(|| match world.camera {
            Camera::Instants { std } => {
                EveCamera::Instants(Noise::new(stream(Purpose::Camera), std))
            }
            Camera::Frames { fps, frame_std } => EveCamera::Frames(FrameCamera::new(
                fps,
                Noise::new(stream(Purpose::Camera), frame_std),
                stream(Purpose::CameraPhase),
            )),
        });
        Self {
            plant: WorldPlant::new(
                &world,
                drive,
                config.robot.wheel_limit,
                config.robot.sample_time,
                PlantStreams {
                    process: stream(Purpose::Process),
                    slip: stream(Purpose::Slip),
                },
                matches!(camera, Some(EveCamera::Frames(_))),
            ),
            measurement: InstantSensor::new(
                Noise::new(stream(Purpose::Measurement), std),
                (stream(Purpose::Jitter), world.jitter),
                encoder,
            ),
            camera,
        }
    }

    /// The robot's plant.
    #[must_use]
    pub fn plant(&self) -> &WorldPlant {
        &self.plant
    }

    /// The wheels are commanded these speeds from now on (rad/s, right first).
    pub fn apply(&mut self, wheels: WheelSpeeds) {
        self.plant.apply(wheels);
    }

    /// One whole sample period.
    pub fn step(&mut self) {
        self.plant.step();
    }

    /// `duration` seconds of motion.
    pub fn advance(&mut self, duration: f64) {
        self.plant.advance(duration);
    }

    /// The sensors at this sample instant (and Eve's frames since the previous one).
    pub fn observe(&mut self) -> Observed {
        let pose = self.plant.pose();
        let measured = self.measurement.sample(&self.plant);
        let (filmed, frames) = match &mut self.camera {
            Some(EveCamera::Instants(noise)) => (Some(pose + noise.draw()), Vec::new()),
            Some(EveCamera::Frames(camera)) => {
                let mut frames = Vec::new();
                camera.film(&self.plant.take_trail(), &mut frames);
                (None, frames)
            }
            None => (None, Vec::new()),
        };
        Observed {
            pose,
            measured,
            filmed,
            frames,
        }
    }
}
