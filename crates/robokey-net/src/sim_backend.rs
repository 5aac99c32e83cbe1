//! A simulated robot behind the agent: the same plant, noise and streams as the simulator,
//! so a clean lockstep session reproduces `robokey run` bit for bit.

use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use robokey::Config;
use robokey::model::{DiffDrive, Pose, WheelSpeeds, clip_wheels, unicycle_step};
use robokey::rng::{Purpose, stream};

use crate::backend::Backend;
use crate::error::NetError;

/// The plant of docs/model.md with true noise drawn from the `(seed, replicate)` streams.
#[derive(Debug)]
pub struct SimBackend {
    pose: Pose,
    wheels: WheelSpeeds,
    started: bool,
    drive: DiffDrive,
    wheel_limit: f64,
    sample_time: f64,
    process_std: Pose,
    measurement_std: Pose,
    process: ChaCha8Rng,
    measurement: ChaCha8Rng,
}

impl SimBackend {
    /// The plant of `config`, noise from replicate `replicate` of `config.run.seed`.
    #[must_use]
    pub fn new(config: &Config, replicate: u64) -> Self {
        let seed = config.run.seed;
        Self {
            pose: Pose::zeros(),
            wheels: WheelSpeeds::zeros(),
            started: false,
            drive: DiffDrive {
                wheel_radius: config.robot.r,
                axle_length: config.robot.axle_length,
            },
            wheel_limit: config.robot.wheel_limit,
            sample_time: config.robot.sample_time,
            process_std: Pose::from(config.noise.process_std),
            measurement_std: Pose::from(config.noise.measurement_std),
            process: stream(seed, Purpose::Process, replicate),
            measurement: stream(seed, Purpose::Measurement, replicate),
        }
    }

    /// The true pose (m, m, rad).
    #[must_use]
    pub fn pose(&self) -> Pose {
        self.pose
    }
}

fn gaussian(rng: &mut ChaCha8Rng, std: &Pose) -> Pose {
    Pose::new(
        StandardNormal.sample(rng),
        StandardNormal.sample(rng),
        StandardNormal.sample(rng),
    )
    .component_mul(std)
}

impl Backend for SimBackend {
    fn sample(&mut self) -> Result<Pose, NetError> {
        if self.started {
            let input = self
                .drive
                .to_unicycle(clip_wheels(self.wheels, self.wheel_limit));
            self.pose = unicycle_step(&self.pose, &input, self.sample_time)
                + gaussian(&mut self.process, &self.process_std);
        }
        self.started = true;
        Ok(self.pose + gaussian(&mut self.measurement, &self.measurement_std))
    }

    fn set_wheels(&mut self, wheels: WheelSpeeds) -> Result<(), NetError> {
        self.wheels = wheels;
        Ok(())
    }

    fn stop(&mut self) {
        self.wheels = WheelSpeeds::zeros();
    }
}
