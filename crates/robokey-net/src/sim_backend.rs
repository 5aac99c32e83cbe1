//! A simulated robot behind the agent: the same plant, noise and streams as the simulator,
//! so a clean lockstep session reproduces `robokey run` bit for bit. With
//! [`SimBackend::with_world`] it also serves the world's sensor streams (private sensing).

use rand::rngs::ChaCha8Rng;
use robokey::Config;
use robokey::config::SensingMode;
use robokey::model::{DiffDrive, Pose, WheelSpeeds, clip_wheels, unicycle_step};
use robokey::rng::{Purpose, stream};

use crate::backend::Backend;
use crate::error::NetError;
use crate::world::{WorldSensors, gaussian};

/// The plant of docs/model.md with true noise drawn from the `(seed, replicate)` streams.
#[derive(Debug)]
pub struct SimBackend {
    pose: Pose,
    wheels: WheelSpeeds,
    /// The next sample instant.
    step: u32,
    drive: DiffDrive,
    wheel_limit: f64,
    sample_time: f64,
    process_std: Pose,
    process: ChaCha8Rng,
    /// Odometry noise (odometry mode; in private sensing the robot sends no pose and the
    /// measurement stream is the controller's sensor's).
    odometry: Option<(ChaCha8Rng, Pose)>,
    world: Option<WorldSensors>,
}

impl SimBackend {
    /// The plant of `config`, noise from replicate `replicate` of `config.run.seed`.
    #[must_use]
    pub fn new(config: &Config, replicate: u64) -> Self {
        let seed = config.run.seed;
        Self {
            pose: Pose::zeros(),
            wheels: WheelSpeeds::zeros(),
            step: 0,
            drive: DiffDrive {
                wheel_radius: config.robot.r,
                axle_length: config.robot.axle_length,
            },
            wheel_limit: config.robot.wheel_limit,
            sample_time: config.robot.sample_time,
            process_std: Pose::from(config.noise.process_std),
            process: stream(seed, Purpose::Process, replicate),
            odometry: (config.sensing.mode == SensingMode::Odometry).then(|| {
                (
                    stream(seed, Purpose::Measurement, replicate),
                    Pose::from(config.noise.measurement_std),
                )
            }),
            world: None,
        }
    }

    /// The same plant, serving the world's sensor streams from its true pose.
    #[must_use]
    pub fn with_world(mut self, world: WorldSensors) -> Self {
        self.world = Some(world);
        self
    }

    /// The true pose (m, m, rad).
    #[must_use]
    pub fn pose(&self) -> Pose {
        self.pose
    }
}

impl Backend for SimBackend {
    fn sample(&mut self) -> Result<Pose, NetError> {
        if self.step > 0 {
            let input = self
                .drive
                .to_unicycle(clip_wheels(self.wheels, self.wheel_limit));
            self.pose = unicycle_step(&self.pose, &input, self.sample_time)
                + gaussian(&mut self.process, &self.process_std);
        }
        if let Some(world) = &mut self.world {
            world.publish(self.step, &self.pose);
        }
        self.step += 1;
        Ok(match &mut self.odometry {
            Some((noise, std)) => self.pose + gaussian(noise, std),
            None => self.pose,
        })
    }
    fn set_wheels(&mut self, wheels: WheelSpeeds) -> Result<(), NetError> {
        self.wheels = wheels;
        Ok(())
    }

    fn stop(&mut self) {
        self.wheels = WheelSpeeds::zeros();
    }
}
