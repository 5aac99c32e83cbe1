//! The robot's true motion in a world (docs/world.md): the [`Actuator`] and the [`Motion`]
//! driven by the world's noise — AR(1) motion noise `w_k = ρ·w_{k−1} + √(1−ρ²)·e_k`,
//! `e_k ~ N(0, diag(process_std)²)` (`w_0 = e_0`), and per-wheel slip factors `1 + σ·z`
//! drawn once per period from their own streams. Time is an input: the plant advances by
//! whole periods ([`WorldPlant::step`]) or any stretch ([`WorldPlant::advance`]).

use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::actuator::{Actuator, Piece, lagged};
use super::model::WorldModel;
use super::motion::{Motion, StepNoise};
use crate::model::{DiffDrive, Pose, WheelSpeeds};

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

/// The random streams a plant draws from.
#[derive(Debug)]
pub struct PlantStreams {
    /// The motion noise `e_k` (three normals per period).
    pub process: ChaCha8Rng,
    /// The slip `z` (two normals per period, right wheel first), used when the world slips.
    pub slip: ChaCha8Rng,
}

/// The robot's true pose and wheels in a world.
#[derive(Debug)]
pub struct WorldPlant {
    motion: Motion,
    actuator: Actuator,
    pose: Pose,
    /// Each wheel's angle travelled, slip included (rad).
    wheel_angles: WheelSpeeds,
    /// Time since the session began (s), and into the current period.
    elapsed: f64,
    into_period: f64,
    rho: f64,
    slip_std: f64,
    process: Noise,
    slip: ChaCha8Rng,
    /// The noise of the current period.
    noise: StepNoise,
    /// The pose's rate over its last update (m/s, m/s, rad/s).
    velocity: Pose,
    /// Every pose update's end since the trail was last taken, with the time (s); its first
    /// point is the last one taken. Kept only when asked for.
    trail: Option<Vec<(f64, Pose)>>,
    pieces: Vec<Piece>,
    updates: Vec<(f64, Pose)>,
}

impl WorldPlant {
    /// A robot at rest at the origin in `world`, with wheel geometry `drive`, the motors'
    /// limit (rad/s) and sample time `T` (s); `trail` keeps the poses between the instants
    /// (for a camera filming them).
    #[must_use]
    pub fn new(
        world: &WorldModel,
        drive: DiffDrive,
        wheel_limit: f64,
        sample_time: f64,
        streams: PlantStreams,
        trail: bool,
    ) -> Self {
        Self {
            motion: Motion::new(drive, sample_time, world),
            actuator: Actuator::new(world.lag, world.delay, world.command_quantum, wheel_limit),
            pose: Pose::zeros(),
            wheel_angles: WheelSpeeds::zeros(),
            elapsed: 0.0,
            into_period: 0.0,
            rho: world.process_rho,
            slip_std: world.slip_std,
            process: Noise::new(streams.process, world.process_std),
            slip: streams.slip,
            noise: StepNoise::NONE,
            velocity: Pose::zeros(),
            trail: trail.then(|| vec![(0.0, Pose::zeros())]),
            pieces: Vec::new(),
            updates: Vec::new(),
        }
    }

    /// The true pose (m, m, rad).
    #[must_use]
    pub fn pose(&self) -> Pose {
        self.pose
    }

    /// The pose's rate over its last update (m/s, m/s, rad/s): what a sample taken slightly
    /// off its instant sees, to first order.
    #[must_use]
    pub fn velocity(&self) -> Pose {
        self.velocity
    }

    /// Each wheel's angle travelled (rad, right first).
    #[must_use]
    pub fn wheel_angles(&self) -> WheelSpeeds {
        self.wheel_angles
    }

    /// Time since the session began (s).
    #[must_use]
    pub fn elapsed(&self) -> f64 {
        self.elapsed
    }

    /// The wheels' geometry.
    #[must_use]
    pub fn drive(&self) -> DiffDrive {
        self.motion.drive
    }

    /// The wheels are commanded these speeds from now on (rad/s, right first).
    pub fn apply(&mut self, wheels: WheelSpeeds) {
        self.actuator.apply(wheels);
    }

    /// One whole sample period.
    pub fn step(&mut self) {
        let period = self.motion.sample_time;
        self.advance_within(period);
    }

    /// `duration` seconds (split at period boundaries, where the noise is drawn anew; a
    /// remainder below a nanosecond per second of period is not a stretch of its own).
    pub fn advance(&mut self, duration: f64) {
        let slack = self.slack();
        let mut left = duration;
        while left > slack {
            let room = self.motion.sample_time - self.into_period;
            let take = if left <= room + slack { left } else { room };
            self.advance_within(take);
            left -= take;
        }
    }

    /// Rounding allowed in where a period ends (s).
    fn slack(&self) -> f64 {
        1e-9 * self.motion.sample_time
    }

    /// Poses since the trail was last taken, with their times (s); the first is the last
    /// one taken. Empty when the plant keeps no trail.
    pub fn take_trail(&mut self) -> Vec<(f64, Pose)> {
        match &mut self.trail {
            Some(trail) => {
                let last = *trail.last().expect("the trail keeps its last point");
                std::mem::replace(trail, vec![last])
            }
            None => Vec::new(),
        }
    }

    /// Advances within the current period: `duration` at most what is left of it.
    fn advance_within(&mut self, duration: f64) {
        if self.into_period == 0.0 {
            self.draw_noise();
        }
        self.pieces.clear();
        self.actuator.advance(duration, &mut self.pieces);
        let slip = self.noise.slip.unwrap_or([1.0, 1.0]);
        for piece in &self.pieces {
            let mean = lagged(piece.command, piece.start, piece.duration, self.motion.lag).0;
            self.wheel_angles +=
                WheelSpeeds::new(mean.x * slip[0], mean.y * slip[1]) * piece.duration;
        }
        self.updates.clear();
        let start = self.pose;
        self.pose =
            self.motion
                .integrate(start, &self.pieces, &self.noise, &mut self.updates, None);
        let mut before = (0.0, start);
        if let Some(&(offset, end)) = self.updates.last() {
            if self.updates.len() > 1 {
                before = self.updates[self.updates.len() - 2];
            }
            if offset > before.0 {
                self.velocity = (end - before.1) / (offset - before.0);
            }
        }
        if let Some(trail) = &mut self.trail {
            trail.extend(
                self.updates
                    .iter()
                    .map(|&(t, pose)| (self.elapsed + t, pose)),
            );
        }
        self.elapsed += duration;
        self.into_period += duration;
        if self.into_period >= self.motion.sample_time - self.slack() {
            self.into_period = 0.0;
        }
    }

    fn draw_noise(&mut self) {
        let fresh = self.process.draw();
        let displacement = if self.rho == 0.0 || self.elapsed == 0.0 {
            fresh
        } else {
            self.noise.displacement * self.rho + fresh * (1.0 - self.rho * self.rho).sqrt()
        };
        let slip = (self.slip_std > 0.0).then(|| {
            let mut factor = || {
                let z: f64 = StandardNormal.sample(&mut self.slip);
                1.0 + self.slip_std * z
            };
            [factor(), factor()]
        });
        self.noise = StepNoise { displacement, slip };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Config;
    use crate::model::{clip_wheels, unicycle_step};
    use crate::rng::{Purpose, stream};

    fn streams(seed: u64) -> PlantStreams {
        PlantStreams {
            process: stream(seed, Purpose::Process, 0),
            slip: stream(seed, Purpose::Slip, 0),
        }
    }

    const DRIVE: DiffDrive = DiffDrive {
        wheel_radius: 0.021,
        axle_length: 0.1047,
    };

    /// The ideal world's plant is the parties' Euler map with white noise, number for
    /// number: `x(k+1) = f(x(k), H·clip(u_D(k))) + w(k)`.
    #[test]
    fn the_ideal_plant_is_the_parties_map() {
        let config = Config::default();
        let world = WorldModel::ideal(&config);
        let mut plant = WorldPlant::new(&world, DRIVE, 38.0, 0.2, streams(7), false);
        let mut noise = Noise::new(stream(7, Purpose::Process, 0), config.noise.process_std);
        let mut expected = Pose::zeros();
        for k in 0..50 {
            let wheels = WheelSpeeds::new(f64::from(k) * 0.9, 40.0 - f64::from(k));
            plant.apply(wheels);
            plant.step();
            expected = unicycle_step(
                &expected,
                &DRIVE.to_unicycle(clip_wheels(wheels, 38.0)),
                0.2,
            ) + noise.draw();
            assert_eq!(plant.pose(), expected, "step {k}");
        }
    }

    /// Advancing a period in pieces draws the same noise as one step and, with the
    /// continuous motion, lands on the same pose to rounding.
    #[test]
    fn a_period_in_pieces_is_a_period() {
        let config = Config {
            world: Some(crate::world::WorldConfig {
                integration: Some(crate::world::Integration::Continuous),
                lag: Some(0.05),
                process_rho: Some(0.5),
                slip_std: Some(0.05),
                ..Default::default()
            }),
            ..Default::default()
        };
        let world = WorldModel::of(&config);
        let mut whole = WorldPlant::new(&world, DRIVE, 38.0, 0.2, streams(3), true);
        let mut pieces = WorldPlant::new(&world, DRIVE, 38.0, 0.2, streams(3), true);
        for k in 0..20 {
            let wheels = WheelSpeeds::new(4.0 + f64::from(k % 3), 3.0);
            whole.apply(wheels);
            pieces.apply(wheels);
            whole.step();
            pieces.advance(0.05);
            pieces.advance(0.1);
            pieces.advance(0.05);
            assert!((whole.pose() - pieces.pose()).norm() < 1e-9, "step {k}");
        }
        assert!((whole.elapsed() - 4.0).abs() < 1e-12);
        let trail = pieces.take_trail();
        assert!(
            trail.windows(2).all(|w| w[0].0 < w[1].0),
            "{:?}",
            &trail[..6]
        );
        assert_eq!(pieces.take_trail().len(), 1);
    }

    /// The AR(1) noise keeps its stationary variance and has lag-1 correlation ρ.
    #[test]
    fn correlated_noise_has_its_variance_and_correlation() {
        let config = Config {
            world: Some(crate::world::WorldConfig {
                process_rho: Some(0.9),
                ..Default::default()
            }),
            ..Default::default()
        };
        let world = WorldModel::of(&config);
        let mut plant = WorldPlant::new(&world, DRIVE, 38.0, 0.2, streams(11), false);
        let n = 40_000;
        let mut draws = Vec::with_capacity(n);
        for _ in 0..n {
            let before = plant.pose();
            plant.step();
            draws.push((plant.pose() - before).x);
        }
        let var = draws.iter().map(|w| w * w).sum::<f64>() / n as f64;
        let lag1 = draws.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / (n - 1) as f64 / var;
        // Effective sample size n(1−ρ)/(1+ρ) ≈ 2,100: the variance within 4 standard errors.
        let se = 0.004_f64.powi(2) * (2.0 / 2_100.0_f64).sqrt();
        assert!((var - 0.004_f64.powi(2)).abs() < 4.0 * se, "{var}");
        assert!((lag1 - 0.9).abs() < 0.02, "{lag1}");
    }
}
