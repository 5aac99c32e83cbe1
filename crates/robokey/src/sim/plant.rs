//! The simulated physics: the robot's true pose under its wheels and motion noise, and the
//! sensors that observe it with their own noise (docs/model.md).

use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::model::{DiffDrive, Pose, WheelSpeeds, clip_wheels, unicycle_step};

/// Independent Gaussian noise per pose component, from its own seeded stream.
#[derive(Debug)]
pub struct Noise {
    rng: ChaCha8Rng,
    std: Pose,
}

impl Noise {
    /// Noise of standard deviation `std` (m, m, rad) drawn from `rng`.
    #[must_use]
    pub fn new(rng: ChaCha8Rng, std: [f64; 3]) -> Self {
        Self {
            rng,
            std: Pose::from(std),
        }
    }

    /// One draw: `z ∘ std`, `z ~ N(0, I₃)` (three normals, in order).
    pub fn draw(&mut self) -> Pose {
        let z = Pose::new(
            StandardNormal.sample(&mut self.rng),
            StandardNormal.sample(&mut self.rng),
            StandardNormal.sample(&mut self.rng),
        );
        z.component_mul(&self.std)
    }
}

/// A sensor: the true pose plus its noise, `y = x + η`.
#[derive(Debug)]
pub struct Sensor(Noise);

impl Sensor {
    /// A sensor with this noise.
    #[must_use]
    pub fn new(noise: Noise) -> Self {
        Self(noise)
    }

    /// A sample of `pose`.
    pub fn sample(&mut self, pose: &Pose) -> Pose {
        pose + self.0.draw()
    }
}

/// The robot's true pose, driven by the wheels it last applied: the Euler map of the
/// unicycle, `x(k+1) = f(x(k), H·clip(u_D(k))) + w(k)`, `w ~ N(0, Q)` (docs/model.md).
#[derive(Debug)]
pub struct Plant {
    pose: Pose,
    wheels: WheelSpeeds,
    drive: DiffDrive,
    wheel_limit: f64,
    sample_time: f64,
    motion: Noise,
}

impl Plant {
    /// A robot at rest at the origin, with wheel geometry `drive`, the plant's wheel limit
    /// (rad/s), sample time `T` (s) and motion noise `motion`.
    #[must_use]
    pub fn new(drive: DiffDrive, wheel_limit: f64, sample_time: f64, motion: Noise) -> Self {
        Self {
            pose: Pose::zeros(),
            wheels: WheelSpeeds::zeros(),
            drive,
            wheel_limit,
            sample_time,
            motion,
        }
    }

    /// The true pose `x(k)`.
    #[must_use]
    pub fn pose(&self) -> Pose {
        self.pose
    }

    /// The wheels apply these speeds from now on (rad/s, right first).
    pub fn apply(&mut self, wheels: WheelSpeeds) {
        self.wheels = wheels;
    }

    /// One sample period under the applied wheels, clipped to the plant's limit.
    pub fn step(&mut self) {
        let applied = self
            .drive
            .to_unicycle(clip_wheels(self.wheels, self.wheel_limit));
        self.pose = unicycle_step(&self.pose, &applied, self.sample_time) + self.motion.draw();
    }
}
