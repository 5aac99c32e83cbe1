//! Online identification of the wheel geometry from eavesdropped traffic (the `identify` strategy, docs/threat-model.md):
//! least squares of the measured displacement on the wheel command.
//!
//! Over one period the plant moves by `T·[v cos θ, v sin θ, ω]` plus process noise, with
//! `v = r·(ωr + ωl)/2` and `ω = (r/D)·(ωr − ωl)` of the applied (clipped) wheel speeds
//! (docs/model.md). Both are linear in one unknown: `r` for the forward displacement, `r/D` for
//! the turn. Without the key Eve regresses on the command of her own decision `b̂`; with no
//! decision, on the midpoint `(u0D + u1D)/2`. The midpoint alone is biased: a codeword repeats
//! its bit, and the controller corrects the previous step's `±Δ` in the next midpoint, so
//! midpoint and offset are correlated. Once a key is known (the transcript strategy) she
//! regresses on the command actually applied.

use std::collections::VecDeque;

use crate::model::{DiffDrive, Pose, WheelSpeeds, clip_wheels};

/// One least-squares channel `z = θ·x + noise`, through the origin.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Channel {
    /// `Σ x·z`.
    xz: f64,
    /// `Σ x²`.
    xx: f64,
}

impl Channel {
    /// The prior `θ0`, worth one sample at regressor `x0`.
    fn prior(theta0: f64, x0: f64) -> Self {
        Self {
            xz: theta0 * x0 * x0,
            xx: x0 * x0,
        }
    }

    fn add(&mut self, x: f64, z: f64, weight: f64) {
        self.xz += weight * x * z;
        self.xx += weight * x * x;
    }

    fn estimate(&self) -> f64 {
        self.xz / self.xx
    }
}

/// What one period taught: the responses and both candidate regressors.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Sample {
    step: u32,
    /// The bit she decided for the period, if any.
    decided: Option<u8>,
    /// Forward speed along the heading `θ(k)` (m/s).
    forward: f64,
    /// Turn rate (rad/s).
    turn: f64,
    /// `(ωr + ωl)/2` of the clipped `u0D`, `u1D` (rad/s).
    mean_speed: [f64; 2],
    /// `ωr − ωl` of the clipped `u0D`, `u1D` (rad/s).
    speed_difference: [f64; 2],
}

impl Sample {
    /// The regressors for a known bit, or for the midpoint (`None`).
    fn regressors(&self, bit: Option<u8>) -> (f64, f64) {
        match bit {
            Some(b) => (
                self.mean_speed[usize::from(b & 1)],
                self.speed_difference[usize::from(b & 1)],
            ),
            None => (
                (self.mean_speed[0] + self.mean_speed[1]) / 2.0,
                (self.speed_difference[0] + self.speed_difference[1]) / 2.0,
            ),
        }
    }
}

/// Recursive least-squares estimator of `r` and `r/D`.
#[derive(Clone, Debug)]
pub struct WheelIdentifier {
    wheel_limit: f64,
    sample_time: f64,
    forward: Channel,
    turn: Channel,
    /// The last measurement `(k, y(k))`.
    last_measurement: Option<(u32, Pose)>,
    /// Recent command pairs by step (the plant may apply one before its measurement).
    pairs: VecDeque<(u32, WheelSpeeds, WheelSpeeds)>,
    /// This session's samples, kept so that known bits can replace the midpoint.
    session: Vec<Sample>,
}

/// Command pairs kept while waiting for the measurement that closes their period.
const PAIR_MEMORY: usize = 8;

impl WheelIdentifier {
    /// Starts from `initial` (m), with a prior worth one period at wheel speed `prior_speed`
    /// (rad/s) on each channel; the plant clips wheels at `wheel_limit` (rad/s);
    /// `sample_time` is `T` (s).
    #[must_use]
    pub fn new(initial: DiffDrive, prior_speed: f64, wheel_limit: f64, sample_time: f64) -> Self {
        let r = initial.wheel_radius;
        Self {
            wheel_limit,
            sample_time,
            forward: Channel::prior(r, prior_speed),
            turn: Channel::prior(r / initial.axle_length, 2.0 * prior_speed),
            last_measurement: None,
            pairs: VecDeque::with_capacity(PAIR_MEMORY),
            session: Vec::new(),
        }
    }

    /// Forgets the session's measurements and samples (a new session starts from rest);
    /// keeps the estimates.
    pub fn begin_session(&mut self) {
        self.last_measurement = None;
        self.pairs.clear();
        self.session.clear();
    }

    /// The current estimate of the wheel geometry.
    #[must_use]
    pub fn drive(&self) -> DiffDrive {
        let r = self.forward.estimate();
        let ratio = self.turn.estimate();
        DiffDrive {
            wheel_radius: r,
            axle_length: if ratio > 0.0 { r / ratio } else { f64::NAN },
        }
    }

    /// Records the pair commanded for `step` (rad/s).
    pub fn on_command(&mut self, step: u32, u0: WheelSpeeds, u1: WheelSpeeds) {
        if self.pairs.iter().any(|&(s, ..)| s == step) {
            return;
        }
        if self.pairs.len() == PAIR_MEMORY {
            self.pairs.pop_front();
        }
        self.pairs.push_back((step, u0, u1));
    }

    /// Learns from `y(step)` when it closes a period whose command and start are known
    /// (`applied_step` = `step − 1`: no fallback); `decided` is her bit for that period.
    pub fn on_measurement(
        &mut self,
        step: u32,
        y: &Pose,
        applied_step: Option<u32>,
        decided: Option<u8>,
    ) {
        if self.last_measurement.is_some_and(|(k, _)| step <= k) {
            return;
        }
        let previous = self.last_measurement.replace((step, *y));
        let Some((k, start)) = previous else { return };
        let Some(&(_, u0, u1)) = self.pairs.iter().find(|&&(s, ..)| s == k) else {
            return;
        };
        if k + 1 != step || applied_step != Some(k) {
            return;
        }
        let moved = y - start;
        let (sin, cos) = start.z.sin_cos();
        let (c0, c1) = (
            clip_wheels(u0, self.wheel_limit),
            clip_wheels(u1, self.wheel_limit),
        );
        let sample = Sample {
            step: k,
            decided,
            forward: (cos * moved.x + sin * moved.y) / self.sample_time,
            turn: wrap_angle(moved.z) / self.sample_time,
            mean_speed: [(c0.x + c0.y) / 2.0, (c1.x + c1.y) / 2.0],
            speed_difference: [c0.x - c0.y, c1.x - c1.y],
        };
        self.add(&sample, decided, 1.0);
        self.session.push(sample);
    }

    /// Replaces this session's regressors by the applied commands, for the steps whose bit
    /// became known (`bit_of(step)`).
    pub fn learn_bits(&mut self, bit_of: impl Fn(u32) -> Option<u8>) {
        for sample in std::mem::take(&mut self.session) {
            if let Some(bit) = bit_of(sample.step) {
                self.add(&sample, sample.decided, -1.0);
                self.add(&sample, Some(bit), 1.0);
            }
        }
    }

    fn add(&mut self, sample: &Sample, bit: Option<u8>, weight: f64) {
        let (mean_speed, difference) = sample.regressors(bit);
        self.forward.add(mean_speed, sample.forward, weight);
        self.turn.add(difference, sample.turn, weight);
    }
}

/// The angle in `(−π, π]` (rad).
fn wrap_angle(angle: f64) -> f64 {
    let wrapped = angle.rem_euclid(std::f64::consts::TAU);
    if wrapped > std::f64::consts::PI {
        wrapped - std::f64::consts::TAU
    } else {
        wrapped
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::unicycle_step;

    const TRUE: DiffDrive = DiffDrive {
        wheel_radius: 0.021,
        axle_length: 0.1047,
    };

    /// Noise-free periods with a `±` half-difference on the forward speed.
    fn drive_identifier(identifier: &mut WheelIdentifier, bits: impl Fn(u32) -> u8) {
        let mut pose = Pose::zeros();
        for k in 0..4000u32 {
            let mid = WheelSpeeds::new(5.0 + 3.0 * (f64::from(k) * 0.3).sin(), 4.0);
            let half = WheelSpeeds::new(1.0, 1.0);
            let (u0, u1) = (mid + half, mid - half);
            identifier.on_measurement(k, &pose, k.checked_sub(1), None);
            identifier.on_command(k, u0, u1);
            let applied = if bits(k) == 0 { u0 } else { u1 };
            pose = unicycle_step(&pose, &TRUE.to_unicycle(applied), 0.2);
        }
    }

    #[test]
    fn known_bits_recover_the_geometry_exactly() {
        let start = DiffDrive {
            wheel_radius: 0.021 * 1.4,
            axle_length: 0.1047 * 0.6,
        };
        let mut identifier = WheelIdentifier::new(start, 1.0, 38.0, 0.2);
        let bits = |k: u32| (k.wrapping_mul(2_654_435_761) >> 16 & 1) as u8;
        drive_identifier(&mut identifier, bits);
        let error = |drive: DiffDrive| {
            (drive.wheel_radius / TRUE.wheel_radius - 1.0)
                .abs()
                .max((drive.axle_length / TRUE.axle_length - 1.0).abs())
        };
        // Unknown balanced bits: the ± terms only add noise around the midpoint.
        let midpoint = error(identifier.drive());
        assert!(midpoint < 1e-2, "{midpoint}");
        // Known bits leave only the prior (worth one slow period of 4000, 40 % off).
        identifier.learn_bits(|k| Some(bits(k)));
        let labelled = error(identifier.drive());
        assert!(
            labelled < 1e-3 && labelled < midpoint,
            "{labelled} vs {midpoint}"
        );
    }

    #[test]
    fn with_no_data_the_estimate_is_the_start() {
        let start = DiffDrive {
            wheel_radius: 0.03,
            axle_length: 0.1,
        };
        let identifier = WheelIdentifier::new(start, 1.0, 38.0, 0.2);
        assert_eq!(identifier.drive(), start);
    }

    #[test]
    fn angles_wrap_into_the_half_open_interval() {
        assert!((wrap_angle(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap_angle(-0.1) + 0.1).abs() < 1e-12);
    }
}
