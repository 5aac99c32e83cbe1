//! A sensor sampled at the sample instants (docs/world.md, "Sensors"): the controller's pose
//! sensor, or the robot's odometry. `y = x(kT + j) + η`: the instant's timing error
//! `j ~ N(0, jitter²)` moves the pose by `j·ẋ` to first order; the odometry also reads its
//! wheels' angles rounded to the encoder resolution.

use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::plant::{Noise, WorldPlant};
use crate::model::{Pose, WheelSpeeds};

/// A pose sensor at the sample instants.
#[derive(Debug)]
pub struct InstantSensor {
    noise: Noise,
    /// The timing error's stream and std (s), when the world has one.
    jitter: Option<(ChaCha8Rng, f64)>,
    /// Encoder resolution (rad), when the sensor is the odometry and the world has one.
    encoder_quantum: Option<f64>,
}

impl InstantSensor {
    /// A sensor with this noise, timing error (stream, std in s; none when 0) and, for the
    /// odometry, encoder resolution (rad; none when 0).
    #[must_use]
    pub fn new(noise: Noise, jitter: (ChaCha8Rng, f64), encoder_quantum: f64) -> Self {
        Self {
            noise,
            jitter: (jitter.1 > 0.0).then_some(jitter),
            encoder_quantum: (encoder_quantum > 0.0).then_some(encoder_quantum),
        }
    }

    /// A sample of the plant's pose now.
    pub fn sample(&mut self, plant: &WorldPlant) -> Pose {
        let mut pose = plant.pose();
        if let Some((rng, std)) = &mut self.jitter {
            let offset: f64 = StandardNormal.sample(rng);
            pose += plant.velocity() * (offset * *std);
        }
        if let Some(quantum) = self.encoder_quantum {
            pose += encoder_error(plant, quantum);
        }
        pose + self.noise.draw()
    }
}

/// The pose error of odometry whose wheel angles read `q·round(φ/q)`: to first order the
/// dead-reckoned pose is off by the current reads' rounding `e = q·round(φ/q) − φ`,
/// `[r(e_r + e_l)/2·cos θ, r(e_r + e_l)/2·sin θ, r(e_r − e_l)/D]`.
fn encoder_error(plant: &WorldPlant, quantum: f64) -> Pose {
    let angles = plant.wheel_angles();
    let read = angles.map(|phi| (phi / quantum).round() * quantum);
    let e: WheelSpeeds = read - angles;
    let drive = plant.drive();
    let along = drive.wheel_radius * (e.x + e.y) / 2.0;
    let theta = plant.pose().z;
    Pose::new(
        along * theta.cos(),
        along * theta.sin(),
        drive.wheel_radius * (e.x - e.y) / drive.axle_length,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Config;
    use crate::model::DiffDrive;
    use crate::rng::{Purpose, stream};
    use crate::world::{PlantStreams, WorldConfig, WorldModel};

    fn plant(world: &WorldConfig) -> WorldPlant {
        let config = Config {
            world: Some(world.clone()),
            ..Default::default()
        };
        WorldPlant::new(
            &WorldModel::of(&config),
            DiffDrive {
                wheel_radius: 0.021,
                axle_length: 0.1047,
            },
            38.0,
            0.2,
            PlantStreams {
                process: stream(1, Purpose::Process, 0),
                slip: stream(1, Purpose::Slip, 0),
            },
            false,
        )
    }

    #[test]
    fn the_encoder_error_is_at_most_half_a_quantum_per_wheel() {
        let mut p = plant(&WorldConfig {
            process_std: Some([0.0; 3]),
            ..WorldConfig::default()
        });
        let quantum = 0.01;
        let mut sensor = InstantSensor::new(
            Noise::new(stream(1, Purpose::Measurement, 0), [0.0; 3]),
            (stream(1, Purpose::Jitter, 0), 0.0),
            quantum,
        );
        p.apply(WheelSpeeds::new(3.0, 3.0));
        for _ in 0..30 {
            p.step();
            let error = sensor.sample(&p) - p.pose();
            // Straight ahead: only the along-track part, at most r·q/2.
            assert!(
                error.xy().norm() <= 0.021 * quantum / 2.0 + 1e-15,
                "{error}"
            );
        }
    }

    #[test]
    fn jitter_moves_a_sample_along_the_velocity() {
        let mut p = plant(&WorldConfig {
            process_std: Some([0.0; 3]),
            ..WorldConfig::default()
        });
        let mut sensor = InstantSensor::new(
            Noise::new(stream(1, Purpose::Measurement, 0), [0.0; 3]),
            (stream(1, Purpose::Jitter, 0), 0.001),
            0.0,
        );
        p.apply(WheelSpeeds::new(4.0, 4.0));
        let n = 2_000;
        let mut offsets = Vec::new();
        for _ in 0..n {
            p.step();
            let error = sensor.sample(&p) - p.pose();
            assert!(error.y.abs() < 1e-15 && error.z.abs() < 1e-15);
            offsets.push(error.x / p.velocity().x);
        }
        let var = offsets.iter().map(|o| o * o).sum::<f64>() / f64::from(n);
        // The variance's standard error is √(2/n)·σ².
        assert!(
            (var - 1e-6).abs() < 4.0 * (2.0 / f64::from(n)).sqrt() * 1e-6,
            "{var}"
        );
    }
}
