//! A doublet: two steps that carry one or two key bits as `u + s·Δ` then `u' − s·Δ`, so that
//! the robot returns to its nominal path — or, with a prior actuator lag τ > 0, three steps
//! `u + s·Δ`, `u' − (1 + a)·s·Δ`, `u' + a·s·Δ` with `a = e^(−T/τ)`, which leave a first-order
//! lag no position or speed residual at the doublet's end (docs/private-sensing.md).

use nalgebra::Vector2;

use serde::{Deserialize, Serialize};

use crate::model::{DiffDrive, Pose, Unicycle, unicycle_step};
use crate::world::{lagged, quantise};

/// The sign a bit gives its perturbation: `s = +1` for bit 0, `−1` for bit 1.
#[must_use]
pub fn sign(bit: u8) -> f64 {
    if bit == 0 { 1.0 } else { -1.0 }
}

/// The most key bits a doublet carries: two dimensions of an 8-level alphabet.
pub const MAX_BITS: usize = 6;

/// The key bits a doublet carries: a symbol on v and, with two dimensions, one on ω, each
/// of log₂ `levels` bits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Perturbation {
    /// `Δ = [Δv, Δω]` (m/s, rad/s).
    pub delta: Unicycle,
    /// Dimensions: 1 (on v) or 2 (on v and ω).
    pub bits_per_doublet: u8,
    /// The third step's share `a = e^(−T/τ)` of the first step's offset, for a prior
    /// actuator lag τ > 0 (s): a three-step doublet; `None`: two steps (τ = 0).
    pub settle: Option<f64>,
    /// Amplitude levels per dimension: 2, 4 or 8.
    pub levels: u8,
    /// Which label bits pick which amplitude.
    pub labeling: Labeling,
}

/// The three-step doublet's third-step share `a = e^(−T/τ)` for sample time `T` and prior
/// lag `τ` (s); `None` (two steps) for `τ = 0`.
///
/// With a first-order lag `dv/dt = (c − v)/τ`, a step `c` held for `T` from the speed offset
/// `e₀` ends at `e₁ = c + (e₀ − c)·a` and moves `c·T + (e₀ − c)·τ·(1 − a)`. For offsets
/// `(1, −(1 + a), a)` from rest: `e₁ = 1 − a`, `e₂ = a − 1`, `e₃ = 0`, and the three
/// displacements sum to `T·(1 − (1 + a) + a) + τ·(1 − a)·(−1 + 2 − 1) = 0`.
#[must_use]
pub fn settle_share(sample_time: f64, prior_lag: f64) -> Option<f64> {
    (prior_lag > 0.0).then(|| (-sample_time / prior_lag).exp())
}

impl Perturbation {
    /// A binary doublet: one key bit per dimension.
    #[must_use]
    pub fn binary(delta: Unicycle, bits_per_doublet: u8, settle: Option<f64>) -> Self {
        Self {
            delta,
            bits_per_doublet,
            settle,
            levels: 2,
            labeling: Labeling::Natural,
        }
    }

    /// Key bits per dimension, `log₂ levels`.
    #[must_use]
    pub fn bits_per_symbol(&self) -> usize {
        self.levels.trailing_zeros() as usize
    }

    /// Key bits per doublet: `bits_per_doublet · log₂ levels` (at most [`MAX_BITS`]).
    #[must_use]
    pub fn key_bits(&self) -> usize {
        usize::from(self.bits_per_doublet) * self.bits_per_symbol()
    }

    /// Number of bit patterns a doublet can carry, `2^key_bits`. Pattern `h` holds the
    /// v-symbol's label in its low `m = log₂ levels` bits and the ω-symbol's in the next `m`
    /// (binary: v-bit `h & 1`, ω-bit `h >> 1`).
    #[must_use]
    pub fn patterns(&self) -> usize {
        1 << self.key_bits()
    }

    /// The dimension (0: v, 1: ω) key bit `i` of a doublet belongs to.
    #[must_use]
    pub fn dimension_of(&self, bit: usize) -> usize {
        bit / self.bits_per_symbol()
    }

    /// The amplitude of symbol label `label`: `(levels − 1 − 2i)/√E` with `i` the label's
    /// amplitude index under the labeling and `E = (levels² − 1)/3` the alphabet's mean
    /// square (binary: `s = +1` for bit 0, `−1` for bit 1).
    #[must_use]
    pub fn amplitude(&self, label: usize) -> f64 {
        let levels = f64::from(self.levels);
        let index = self
            .labeling
            .index(label & usize::from(self.levels).saturating_sub(1)) as f64;
        let mean_square = (levels * levels - 1.0) / 3.0;
        (levels - 1.0 - 2.0 * index) / mean_square.sqrt()
    }

    /// The first step's offset `a·Δ` for pattern `h` (the later steps apply its shares).
    #[must_use]
    pub fn offset(&self, pattern: usize) -> Unicycle {
        let m = self.bits_per_symbol();
        let omega = if self.bits_per_doublet == 2 {
            self.amplitude(pattern >> m) * self.delta.y
        } else {
            0.0
        };
        Unicycle::new(self.amplitude(pattern) * self.delta.x, omega)
    }

    /// Steps a doublet occupies: 2, or 3 with a prior lag.
    #[must_use]
    pub fn steps(&self) -> u32 {
        if self.settle.is_some() { 3 } else { 2 }
    }

    /// Each step's offset for the first step's offset `offset`: `[o, −o]`, or
    /// `[o, −(1 + a)·o, a·o]` with a prior lag (the unused third entry zero for two steps).
    #[must_use]
    pub fn step_offsets(&self, offset: Unicycle) -> [Unicycle; 3] {
        match self.settle {
            None => [offset, -offset, Unicycle::zeros()],
            Some(a) => [offset, -(1.0 + a) * offset, a * offset],
        }
    }

    /// Each step's mean offset speed through a first-order lag `lag` τ (s) from wheels that
    /// carried no offset before the doublet, for the steps' commanded offsets `commanded`
    /// ([`Self::step_offsets`], rounded as the wheels receive them by
    /// [`DoubletInputs::rounded`]): for step offset `c` from speed offset `e`,
    /// `c + (e − c)·(τ/T)·(1 − d)`, then `e ← c + (e − c)·d`, `d = e^(−T/τ)`; `commanded`
    /// without lag. What moves the robot under the model's lag: the likelihood's means use it.
    #[must_use]
    pub fn mean_offsets(
        &self,
        commanded: [Unicycle; 3],
        lag: f64,
        sample_time: f64,
    ) -> [Unicycle; 3] {
        if lag <= 0.0 {
            return commanded;
        }
        let mut speed = Unicycle::zeros();
        commanded.map(|c| {
            let (mean, end) = lagged(c, speed, sample_time, lag);
            speed = end;
            mean
        })
    }

    /// The pattern of a doublet's bit word (the robot's `v | ω << m` draws): its low
    /// [`Self::key_bits`] bits.
    #[must_use]
    pub fn pattern(&self, word: u64) -> usize {
        (word & ((1 << self.key_bits()) - 1)) as usize
    }
}

/// How the robot's actuator rounds each wheel's speed command (docs/world.md,
/// `command_quantum`), as the parties state it (`robot.command_quantum`): an input `u` reaches
/// the wheels as `H·q·round(H⁻¹·u/q)` ([`quantise`], the world actuator's own rounding).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommandRounding {
    /// The wheels' geometry `H`.
    pub drive: DiffDrive,
    /// The resolution `q` (rad/s per wheel), > 0.
    pub quantum: f64,
}

impl CommandRounding {
    /// The rounding of `drive`'s wheels to `quantum` (rad/s); `None` for 0 (no rounding).
    #[must_use]
    pub fn new(drive: DiffDrive, quantum: f64) -> Option<Self> {
        (quantum > 0.0).then_some(Self { drive, quantum })
    }

    /// The input `u` (m/s, rad/s) as the wheels receive it: `H·q·round(H⁻¹·u/q)`.
    #[must_use]
    pub fn round(&self, input: Unicycle) -> Unicycle {
        self.drive
            .to_unicycle(quantise(self.drive.to_wheels(input), self.quantum))
    }
}

/// The public nominal inputs of a doublet: both come from the controller's sample at its
/// start, the second through the open-loop prediction with the first. A three-step doublet
/// holds the second nominal input through its third step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DoubletInputs {
    /// `u(2j)` (m/s, rad/s).
    pub first: Unicycle,
    /// `u'(2j+1)` (m/s, rad/s).
    pub second: Unicycle,
}

impl DoubletInputs {
    /// The public nominal turn rate `max(|ω(2j)|, |ω'(2j+1)|)` (rad/s) that gates the doublet.
    #[must_use]
    pub fn turn_rate(&self) -> f64 {
        self.first.y.abs().max(self.second.y.abs())
    }

    /// The two inputs applied with the first step's offset: `[u + offset, u' − offset]`.
    #[must_use]
    pub fn applied(&self, offset: Unicycle) -> [Unicycle; 2] {
        [self.first + offset, self.second - offset]
    }

    /// The steps' offsets `offsets` ([`Perturbation::step_offsets`]) as the wheels receive
    /// them under `rounding`: `õᵢ = R(uᵢ + oᵢ) − uᵢ` with `u = [u, u', u']` and `R` the
    /// rounding ([`CommandRounding::round`]), so that `uᵢ + õᵢ` is the rounded command. Each
    /// wheel rounds on its own, so `õ` differs between the bit's values in more than sign
    /// and moves the heading too. `offsets` unchanged without rounding.
    #[must_use]
    pub fn rounded(
        &self,
        offsets: [Unicycle; 3],
        rounding: Option<&CommandRounding>,
    ) -> [Unicycle; 3] {
        let Some(rounding) = rounding else {
            return offsets;
        };
        let nominal = [self.first, self.second, self.second];
        std::array::from_fn(|i| rounding.round(nominal[i] + offsets[i]) - nominal[i])
    }

    /// The inputs of each of the doublet's steps for its step offsets
    /// ([`Perturbation::step_offsets`]): `[u + o₀, u' + o₁, u' + o₂]` (the third unused with
    /// two steps).
    #[must_use]
    pub fn applied_steps(&self, offsets: [Unicycle; 3]) -> [Unicycle; 3] {
        [
            self.first + offsets[0],
            self.second + offsets[1],
            self.second + offsets[2],
        ]
    }

    /// The nominal inputs of each of the doublet's `steps` steps (2 or 3), `[u, u', u']`,
    /// through a first-order lag `lag` τ (s) from wheels at the nominal speed `entry` (m/s,
    /// rad/s) at the doublet's start: each step's mean speed less its command, and the speed
    /// at the doublet's end. For step command `c` from speed `e`, the mean is
    /// `c + (e − c)·(τ/T)·(1 − d)` and the end `c + (e − c)·d`, `d = e^(−T/τ)` (the lag is
    /// linear in the wheels, so in `(v, ω)`, and a bit's offsets add to it:
    /// [`Perturbation::mean_offsets`]). Without lag: no transient, the end at `u'`.
    #[must_use]
    pub fn nominal_transient(
        &self,
        entry: Unicycle,
        steps: u32,
        lag: f64,
        sample_time: f64,
    ) -> ([Unicycle; 3], Unicycle) {
        let mut transient = [Unicycle::zeros(); 3];
        if lag <= 0.0 {
            return (transient, self.second);
        }
        let mut speed = entry;
        for (i, slot) in transient.iter_mut().take(steps as usize).enumerate() {
            let command = if i == 0 { self.first } else { self.second };
            let (mean, end) = lagged(command, speed, sample_time, lag);
            *slot = mean - command;
            speed = end;
        }
        (transient, speed)
    }

    /// The noise-free poses after each of `steps` steps (2 or 3) from `start` with the
    /// steps' offsets `offsets` ([`Self::applied_steps`]; with two steps the third entry
    /// repeats the end).
    #[must_use]
    pub fn propagate_steps(
        &self,
        start: &Pose,
        offsets: [Unicycle; 3],
        steps: u32,
        sample_time: f64,
    ) -> [Pose; 3] {
        let [a, b, c] = self.applied_steps(offsets);
        let first = unicycle_step(start, &a, sample_time);
        let second = unicycle_step(&first, &b, sample_time);
        if steps == 2 {
            return [first, second, second];
        }
        [first, second, unicycle_step(&second, &c, sample_time)]
    }

    /// The noise-free poses `[x(2j+1), x(2j+2)]` from `start` with `offset` on the first step,
    /// by the Euler map of the model, sample time `T` (s).
    #[must_use]
    pub fn propagate(&self, start: &Pose, offset: Unicycle, sample_time: f64) -> [Pose; 2] {
        let [a, b] = self.applied(offset);
        let middle = unicycle_step(start, &a, sample_time);
        [middle, unicycle_step(&middle, &b, sample_time)]
    }
}

/// The position a v-bit leaves at the end of a doublet, `s·T·Δv·(e(θ) − e(θ + T·ω))` (m),
/// with `θ` the heading at the doublet's start and `ω` the first step's turn rate: zero on a
/// straight segment, first order in the turn `T·ω` otherwise.
#[must_use]
pub fn v_residual(theta: f64, first_turn_rate: f64, s: f64, delta_v: f64, t: f64) -> Vector2<f64> {
    let e = |angle: f64| Vector2::new(angle.cos(), angle.sin());
    s * t * delta_v * (e(theta) - e(theta + t * first_turn_rate))
}

/// To first order in `T·Δω`, the position an ω-bit leaves at the end of a doublet:
/// `s·T²·v'·Δω·e⊥(θ₁)` (m), lateral to the heading `θ₁` after the first nominal step, with
/// `v'` the second step's nominal speed.
#[must_use]
pub fn omega_residual(
    theta_1: f64,
    second_speed: f64,
    s: f64,
    delta_omega: f64,
    t: f64,
) -> Vector2<f64> {
    s * t * t * second_speed * delta_omega * Vector2::new(-theta_1.sin(), theta_1.cos())
}

/// A pose difference `δ` at a doublet's end in the frame of its start heading `θ`:
/// `[δ·e(θ), sgn(ω)·δ·e⊥(θ), δθ]` (m, m, rad), `e(θ) = (cos θ, sin θ)`, `e⊥(θ) = (−sin θ,
/// cos θ)`, the heading difference wrapped to (−π, π]. The cross axis points toward the
/// first step's turn `ω` (left on a straight segment), so that what the turn leaves adds up
/// over doublets turning either way.
#[must_use]
pub fn in_doublet_frame(delta: &Pose, theta: f64, first_turn_rate: f64) -> [f64; 3] {
    let (sin, cos) = theta.sin_cos();
    let toward_turn = if first_turn_rate < 0.0 { -1.0 } else { 1.0 };
    [
        delta.x * cos + delta.y * sin,
        toward_turn * (-delta.x * sin + delta.y * cos),
        delta.z.sin().atan2(delta.z.cos()),
    ]
}

/// Which label bits pick which of a multilevel alphabet's amplitudes (docs/private-sensing.md,
/// "Multilevel doublets"). Label `b`'s amplitude index `i` (amplitude `(levels − 1 − 2i)/√E`):
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Labeling {
    /// `i = b`: the lowest bit alternates between neighbouring amplitudes (the fine slice),
    /// each higher bit separates sets twice as far apart (set partitioning).
    Natural,
    /// `i = gray⁻¹(b)`: neighbouring amplitudes differ in one bit.
    Gray,
}

impl Labeling {
    /// The default, natural labeling.
    #[must_use]
    pub fn is_natural(&self) -> bool {
        *self == Self::Natural
    }

    /// Its name in a configuration file.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Natural => "natural",
            Self::Gray => "gray",
        }
    }

    /// The amplitude index of label `label`.
    #[must_use]
    pub fn index(self, label: usize) -> usize {
        match self {
            Self::Natural => label,
            Self::Gray => {
                // gray⁻¹: the prefix XOR of the label's bits from the top.
                let mut index = label;
                let mut shift = label >> 1;
                while shift != 0 {
                    index ^= shift;
                    shift >>= 1;
                }
                index
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: f64 = 0.2;

    fn end_shift(
        inputs: &DoubletInputs,
        start: &Pose,
        perturbation: &Perturbation,
        h: usize,
    ) -> Vector2<f64> {
        let nominal = inputs.propagate(start, Unicycle::zeros(), T)[1];
        let perturbed = inputs.propagate(start, perturbation.offset(h), T)[1];
        (perturbed - nominal).xy()
    }

    #[test]
    fn a_doublet_on_a_straight_segment_returns_to_the_nominal_pose() {
        let inputs = DoubletInputs {
            first: Unicycle::new(0.1, 0.0),
            second: Unicycle::new(0.1, 0.0),
        };
        let p = Perturbation::binary(Unicycle::new(0.035, 0.0), 1, None);
        for h in 0..2 {
            let shift = end_shift(&inputs, &Pose::new(0.3, -0.2, 0.7), &p, h);
            assert!(shift.norm() < 1e-15, "{shift}");
        }
    }

    /// A noise-free doublet on a turning segment returns to the nominal path up to the
    /// residual `s·T·Δv·(e(θ) − e(θ + Tω))` (exact for the Euler map), and an ω-bit leaves
    /// the lateral `s·T²·v'·Δω` to first order.
    #[test]
    fn a_turning_doublet_leaves_the_predicted_residual() {
        let start = Pose::new(1.0, 0.5, 0.9);
        for &omega in &[0.1, 0.5, -1.2, 2.0] {
            let inputs = DoubletInputs {
                first: Unicycle::new(0.12, omega),
                second: Unicycle::new(0.1, omega * 0.8),
            };
            let p = Perturbation::binary(Unicycle::new(0.035, 0.0), 1, None);
            for h in 0..2 {
                let s = sign(h as u8);
                let predicted = v_residual(start.z, omega, s, 0.035, T);
                let shift = end_shift(&inputs, &start, &p, h);
                assert!(
                    (shift - predicted).norm() < 1e-15,
                    "ω {omega}: {shift} vs {predicted}"
                );
                assert!(predicted.norm() > 0.5 * T * 0.035 * (T * omega).abs());
            }
            let p2 = Perturbation::binary(Unicycle::new(0.0, 0.035), 2, None);
            let theta_1 = start.z + T * omega;
            for h in [0, 2] {
                let s = sign((h >> 1) as u8);
                let predicted = omega_residual(theta_1, 0.1, s, 0.035, T);
                let shift = end_shift(&inputs, &start, &p2, h);
                // Second order: the neglected term is ½·T·v'·(T·Δω)².
                let bound = 0.5 * T * 0.1 * (T * 0.035_f64).powi(2) * 1.01;
                assert!((shift - predicted).norm() < bound, "{shift} vs {predicted}");
            }
        }
    }

    #[test]
    fn the_doublet_frame_points_along_the_heading_and_toward_the_turn() {
        let theta: f64 = 0.6;
        let along = Pose::new(theta.cos(), theta.sin(), 0.0);
        let left = Pose::new(-theta.sin(), theta.cos(), 7.0);
        let close = |a: [f64; 3], b: [f64; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12);
        assert!(close(in_doublet_frame(&along, theta, 0.3), [1.0, 0.0, 0.0]));
        let wrapped = 7.0 - 2.0 * std::f64::consts::PI;
        assert!(close(
            in_doublet_frame(&left, theta, 0.3),
            [0.0, 1.0, wrapped]
        ));
        assert!(close(
            in_doublet_frame(&left, theta, -0.3),
            [0.0, -1.0, wrapped]
        ));
    }

    /// Through the world's first-order lag τ, the three-step offsets `(1, −(1 + a), a)` with
    /// `a = e^(−T/τ)` leave the wheel at rest and no displacement at the doublet's end (to
    /// rounding), where the two-step doublet leaves `τ·(1 − a)²` per unit offset.
    #[test]
    fn the_three_step_doublet_leaves_a_first_order_lag_nothing() {
        use nalgebra::Vector2 as WheelSpeeds;
        for tau in [0.02, 0.05, 0.1, 0.5] {
            let p = Perturbation::binary(Unicycle::new(1.0, 0.0), 1, settle_share(T, tau));
            let a = p.settle.expect("three steps");
            let run = |steps: &[Unicycle]| {
                steps
                    .iter()
                    .fold((0.0, WheelSpeeds::zeros()), |(moved, speed), u| {
                        let (mean, end) = lagged(WheelSpeeds::new(u.x, u.x), speed, T, tau);
                        (moved + mean.x * T, end)
                    })
            };
            let offsets = p.step_offsets(p.offset(0));
            let (moved, speed) = run(&offsets);
            assert!(
                moved.abs() < 1e-15 && speed.x.abs() < 1e-15,
                "τ {tau}: {moved} {speed}"
            );
            let (two_step, _) = run(&[offsets[0], -offsets[0]]);
            let expected = tau * (1.0 - a) * (1.0 - a);
            assert!(
                (two_step - expected).abs() < 1e-12,
                "τ {tau}: {two_step} vs {expected}"
            );
        }
        assert_eq!(settle_share(T, 0.0), None);
    }

    const DRIVE: DiffDrive = DiffDrive {
        wheel_radius: 0.021,
        axle_length: 0.1047,
    };

    /// The rounded offsets are the world actuator's rounding: a noise-free plant with
    /// `command_quantum` q, driven by the doublet's unrounded wheel commands, lands where the
    /// model's rounded steps put it, step by step. The bit's two values then move the
    /// heading differently (each wheel rounds on its own), which the unrounded `±o` misses;
    /// without a quantum the offsets are untouched.
    #[test]
    fn rounded_offsets_follow_the_world_actuator() {
        use crate::Config;
        use crate::rng::{Purpose, stream};
        use crate::world::{PlantStreams, WorldConfig, WorldModel, WorldPlant};
        let q = 0.1;
        let config = Config {
            world: Some(WorldConfig {
                process_std: Some([0.0; 3]),
                command_quantum: Some(q),
                ..Default::default()
            }),
            ..Default::default()
        };
        let world = WorldModel::of(&config);
        let rounding = CommandRounding::new(DRIVE, q).expect("q > 0");
        let inputs = DoubletInputs {
            first: Unicycle::new(0.1013, 0.237),
            second: Unicycle::new(0.0987, 0.211),
        };
        let p = Perturbation::binary(Unicycle::new(0.035, 0.0), 1, None);
        let mut turns = [0.0; 2];
        for (h, turn) in turns.iter_mut().enumerate() {
            let commanded = p.step_offsets(p.offset(h));
            assert_eq!(inputs.rounded(commanded, None), commanded);
            let offsets = inputs.rounded(commanded, Some(&rounding));
            let model = inputs.propagate_steps(&Pose::zeros(), offsets, 2, T);
            let streams = PlantStreams {
                process: stream(1, Purpose::Process, 0),
                slip: stream(1, Purpose::Slip, 0),
            };
            let mut plant = WorldPlant::new(&world, DRIVE, 38.0, T, streams, false);
            for (k, u) in inputs.applied_steps(commanded)[..2].iter().enumerate() {
                plant.apply(DRIVE.to_wheels(*u));
                plant.step();
                assert!((plant.pose() - model[k]).norm() < 1e-12, "h {h} step {k}");
            }
            *turn = offsets[0].y + offsets[1].y;
        }
        // The bit's values leave different net turns (T·Σω̃ differs by a wheel step's worth).
        assert!((turns[0] - turns[1]).abs() > 0.5 * q * DRIVE.wheel_radius / DRIVE.axle_length);
    }

    #[test]
    fn patterns_and_offsets() {
        let two = Perturbation::binary(Unicycle::new(0.035, 0.02), 2, None);
        assert_eq!(two.patterns(), 4);
        assert_eq!(two.offset(0), Unicycle::new(0.035, 0.02));
        assert_eq!(two.offset(3), Unicycle::new(-0.035, -0.02));
        assert_eq!(two.pattern(0b111), 3);
        let one = Perturbation::binary(Unicycle::new(0.035, 0.02), 1, None);
        assert_eq!(one.offset(1), Unicycle::new(-0.035, 0.0));
        assert_eq!(one.pattern(0b11), 1);
    }

    fn alphabet(levels: u8, labeling: Labeling) -> Perturbation {
        Perturbation {
            delta: Unicycle::new(1.0, 1.0),
            bits_per_doublet: 2,
            settle: None,
            levels,
            labeling,
        }
    }

    /// Every alphabet has the binary alphabet's power (mean square 1), evenly spaced
    /// amplitudes `2/√E` apart, and its labeling: natural flips the lowest bit between
    /// neighbours, Gray exactly one bit; binary is `±1`.
    #[test]
    fn multilevel_alphabets_keep_the_binary_power_and_their_labeling() {
        for levels in [2_u8, 4, 8] {
            let n = usize::from(levels);
            let step = 2.0 / ((n * n - 1) as f64 / 3.0).sqrt();
            for labeling in [Labeling::Natural, Labeling::Gray] {
                let p = alphabet(levels, labeling);
                let mean_square = (0..n).map(|b| p.amplitude(b).powi(2)).sum::<f64>() / n as f64;
                assert!((mean_square - 1.0).abs() < 1e-12, "{levels} {labeling:?}");
                // Labels in order of decreasing amplitude.
                let mut labels: Vec<usize> = (0..n).collect();
                labels.sort_by(|&a, &b| p.amplitude(b).total_cmp(&p.amplitude(a)));
                for pair in labels.windows(2) {
                    let gap = p.amplitude(pair[0]) - p.amplitude(pair[1]);
                    assert!((gap - step).abs() < 1e-12, "{levels} {labeling:?}: {gap}");
                    let differ = pair[0] ^ pair[1];
                    match labeling {
                        Labeling::Gray => assert_eq!(differ.count_ones(), 1),
                        Labeling::Natural => assert_eq!(differ & 1, 1),
                    }
                }
            }
        }
        let binary = alphabet(2, Labeling::Natural);
        assert_eq!([binary.amplitude(0), binary.amplitude(1)], [1.0, -1.0]);
        assert_eq!(binary.offset(2), Unicycle::new(1.0, -1.0));
    }

    /// A 4-level doublet on two dimensions: 4 key bits, 16 patterns, the v label in the low
    /// two bits of the pattern and the ω label in the next two.
    #[test]
    fn a_multilevel_pattern_holds_both_labels() {
        let p = alphabet(4, Labeling::Natural);
        assert_eq!((p.key_bits(), p.patterns()), (4, 16));
        let a = |label: usize| p.amplitude(label);
        assert_eq!(p.offset(0b10_01), Unicycle::new(a(1), a(2)));
        assert_eq!(p.pattern(0b1_10_01), 0b10_01);
        assert_eq!(
            (p.dimension_of(0), p.dimension_of(1), p.dimension_of(2)),
            (0, 0, 1)
        );
        let five = 5.0_f64.sqrt();
        assert!((a(0) - 3.0 / five).abs() < 1e-15 && (a(3) + 3.0 / five).abs() < 1e-15);
    }
}
