//! One doublet's two-step residual, boundary to boundary, with its deterministic part
//! removed (docs/estimation.md, "What is estimated").
//!
//! With the reconciled bit pattern `h`, the controller predicts the doublet's end from its
//! start sample through the Euler map, bit included: `m₂(h) = f(f(y(2j), u + sΔ), u' − sΔ)`.
//! The prediction carries every modelled deterministic residual of the doublet (the bit, the
//! turn residual `sTΔv(e(θ) − e(θ + Tω))`, the lateral `sT²vΔω`), so what remains is noise:
//!
//! `r = y(2j+2) − m₂(h) ≈ A₁w₀ + w₁ + η₂ − A₁A₀η₀`,
//!
//! with `Aᵢ = ∂f/∂x` along the path, `wₖ` the motion noise of step k and `ηₖ` the sensor's.
//! In the robot's frame at the doublet's start heading θ₀ (`H(θ)` the rotation about the
//! vertical axis, `z = H(θ₀)ᵀ r`), for motion noise of covariance `Q` in the frame of each
//! step's heading and sensor noise `R` in the world's:
//!
//! `Cov(z) = B₀QB₀ᵀ + B₁QB₁ᵀ + C₀RC₀ᵀ + C₁RC₁ᵀ`,
//! `B₀ = H(θ₀)ᵀA₁H(θ₀)`, `B₁ = H(θ₀)ᵀH(θ₁)`, `C₀ = H(θ₀)ᵀ`, `C₁ = H(θ₀)ᵀA₁A₀`.
//!
//! Consecutive doublets share a boundary sample, so their residuals are correlated (MA(1)
//! through `η`, lag-1 correlation `−R/(2Q + 2R)` per axis); doublets two apart share
//! nothing under white motion noise. Under AR(1) motion noise of lag-one correlation ρ
//! between steps (`w_{k+1} = ρw_k + √(1−ρ²)e_k`, stationary covariance `Q`) the two steps of
//! a doublet correlate too, `Cov(z) = B₀QB₀ᵀ + B₁QB₁ᵀ + ρ(B₀QB₁ᵀ + B₁QB₀ᵀ) + …`
//! (`correlation` estimates ρ).
//!
//! **Three steps** (`private.prior_lag`): the doublet's steps carry `(+1, −(1 + a), +a)·s·Δ`
//! through the actuator's lag. With the lag τ̂ measured (`lag`), the reconciled bits and the
//! wheels' speed at the doublet's start (`entry`: the previous doublet's nominal inputs and
//! bits through τ̂), the means are the steps' mean speeds through τ̂ — the bit's
//! ([`DoubletModel::mean_offsets`]) and the nominal inputs' own transient
//! ([`DoubletInputs::nominal_transient`]) — by the Euler map, `m₃ = f(f(f(y(3j), ū₀), ū₁), ū₂)`,
//! and `r = y(3j+3) − m₃ ≈ A₂A₁w₀ + A₂w₁ + w₂ + η₃ − A₂A₁A₀η₀`: `B₀ = H(θ₀)ᵀA₂A₁H(θ₀)`,
//! `B₁ = H(θ₀)ᵀA₂H(θ₁)`, `B₂ = H(θ₀)ᵀH(θ₂)`, `C₀ = H(θ₀)ᵀ`, `C₁ = H(θ₀)ᵀA₂A₁A₀`, and under
//! AR(1) `Cov(z) = Σᵢₖ ρ^|i−k|·BᵢQBₖᵀ + C₀RC₀ᵀ + C₁RC₁ᵀ`.
//!
//! **Per-wheel slip** (docs/world.md, "Noise"): each wheel's travel in step k,
//! `d_r,l = (v_k ± ω_k·D/2)·T` at the step's applied (mean) speeds, is multiplied by
//! `1 + σ·z`, `z ~ N(0, 1)` per wheel and step — a velocity error constant over the step,
//! like the additive noise, in the robot's frame at the step's heading. Its covariance there
//! is `σ²·Wₖ`, `Wₖ = G·diag(d_r², d_l²)·Gᵀ`, `G = [[½, ½], [0, 0], [1/D, −1/D]]` (along-track,
//! lateral, heading per unit of the wheels' travel noise), independent between steps, so the
//! residual's covariance gains `σ²·M`, `M = Σₖ BₖWₖBₖᵀ` (the slip map), linear in σ².

use nalgebra::{Matrix3, Vector3};

use crate::model::{Pose, Unicycle, unicycle_step};
use crate::private::DoubletInputs;
use crate::private::likelihood::{DoubletModel, state_jacobian};

/// The robot-frame axes, for people.
pub(super) const AXES: [&str; 3] = ["along-track", "lateral", "heading"];

/// A doublet's residual and the maps that give its covariance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DoubletResidual {
    /// Doublet index j, or a three-step doublet's step index `3j + k` for its one-step
    /// residuals (residuals of the same parity are independent).
    pub doublet: u32,
    /// `z`: the residual in the robot's frame at the doublet's start (m, m, rad).
    pub value: Pose,
    /// Steps the residual spans: 2, or 3 with a prior lag (1: one step of a three-step
    /// doublet).
    pub steps: u32,
    /// `[B₀, B₁, B₂]`: how each step's motion noise enters `z` (`B₂ = 0` with two steps).
    pub motion_maps: [Matrix3<f64>; 3],
    /// `[C₀, C₁]`: how the end and the start sample's sensor noise enter `z`.
    pub sensor_maps: [Matrix3<f64>; 2],
    /// `M = Σₖ BₖWₖBₖᵀ`: the residual's covariance per unit of the slip's variance σ²
    /// (m², m², rad²; the module's doc).
    pub slip_map: Matrix3<f64>,
    /// The doublet's public nominal inputs (what the homogeneity test classes it by).
    pub inputs: DoubletInputs,
    /// `[u₀, u₁]`: the pose's rate at the end and at the start sample (world frame; m/s,
    /// m/s, rad/s), what moves a sample taken off its instant: each step's applied speed
    /// along the heading sampled after it; zero where the jitter is not modelled.
    pub sample_velocities: [Vector3<f64>; 2],
    /// `j²` (s²): the variance of each sample instant's timing error the sensor's part is
    /// taken at ([`Self::sensor_part`]); 0 without jitter.
    pub jitter_variance: f64,
}

/// `Wₖ = G·diag(d_r², d_l²)·Gᵀ`: one step's slip covariance per unit σ² in the robot's frame
/// at the step's heading, for applied speeds `u` (m/s, rad/s) over `sample_time` T (s) on
/// wheels `axle` D (m) apart; `d_r,l = (v ± ω·D/2)·T`.
#[must_use]
pub fn step_slip_covariance(u: &Unicycle, sample_time: f64, axle: f64) -> Matrix3<f64> {
    let right = (u.x + 0.5 * axle * u.y) * sample_time;
    let left = (u.x - 0.5 * axle * u.y) * sample_time;
    let g = nalgebra::Matrix3x2::new(0.5, 0.5, 0.0, 0.0, 1.0 / axle, -1.0 / axle);
    g * nalgebra::Matrix2::new(right * right, 0.0, 0.0, left * left) * g.transpose()
}

/// `Σₖ BₖWₖBₖᵀ` over the steps' `maps` and applied speeds `applied`.
fn slip_map(
    maps: &[Matrix3<f64>],
    applied: &[Unicycle],
    sample_time: f64,
    axle: f64,
) -> Matrix3<f64> {
    maps.iter()
        .zip(applied)
        .map(|(b, u)| b * step_slip_covariance(u, sample_time, axle) * b.transpose())
        .sum()
}

/// The pose's rate in the world's frame at heading `theta` (rad) for applied speed `u`
/// (m/s, rad/s): `(v·cos θ, v·sin θ, ω)`.
fn sample_velocity(u: &Unicycle, theta: f64) -> Vector3<f64> {
    let (sin, cos) = theta.sin_cos();
    Vector3::new(u.x * cos, u.x * sin, u.y)
}

/// The rotation `H(θ)` about the vertical axis: a robot-frame vector to the world's.
#[must_use]
pub fn rotation(theta: f64) -> Matrix3<f64> {
    let (sin, cos) = theta.sin_cos();
    Matrix3::new(cos, -sin, 0.0, sin, cos, 0.0, 0.0, 0.0, 1.0)
}

impl DoubletResidual {
    /// The residual of doublet `doublet` with public `inputs`, the controller's samples
    /// `start = y(2j)` and `end = y(2j+2)`, and the reconciled bit pattern `pattern`
    /// (v-bit `pattern & 1`, ω-bit `pattern >> 1`), under `model`'s sample time and Δ, on
    /// wheels `axle` D (m) apart (the slip map's).
    #[must_use]
    pub fn new(
        model: &DoubletModel,
        axle: f64,
        doublet: u32,
        inputs: &DoubletInputs,
        start: &Pose,
        end: &Pose,
        pattern: usize,
    ) -> Self {
        let t = model.sample_time;
        let offsets = model.step_offsets(inputs, Some(pattern));
        let [a, b, _] = inputs.applied_steps(offsets);
        let [middle, predicted, _] = inputs.propagate_steps(start, offsets, 2, t);
        let a0 = state_jacobian(start.z, a.x, t);
        let a1 = state_jacobian(middle.z, b.x, t);
        let h0 = rotation(start.z).transpose();
        let motion_maps = [
            h0 * a1 * rotation(start.z),
            h0 * rotation(middle.z),
            Matrix3::zeros(),
        ];
        Self {
            doublet,
            value: h0 * (end - predicted),
            steps: 2,
            motion_maps,
            sensor_maps: [h0, h0 * a1 * a0],
            slip_map: slip_map(&motion_maps[..2], &[a, b], t, axle),
            inputs: *inputs,
            sample_velocities: [Vector3::zeros(); 2],
            jitter_variance: 0.0,
        }
    }

    /// The residual of a three-step doublet (the module's doc) with the steps' mean speeds
    /// through `model`'s lag τ (s) — the bit's, pattern `pattern`, and the nominal inputs'
    /// from the wheels' nominal speed `entry` (m/s, rad/s) at its start — from the
    /// controller's samples `start = y(3j)` and `end = y(3j+3)`, on wheels `axle` D (m) apart.
    #[must_use]
    pub fn three_step(
        model: &DoubletModel,
        axle: f64,
        doublet: u32,
        inputs: &DoubletInputs,
        [start, end]: [&Pose; 2],
        pattern: usize,
        entry: Unicycle,
    ) -> Self {
        let t = model.sample_time;
        let (applied, means) = Self::three_step_means(model, inputs, start, pattern, entry);
        let before = [*start, means[0], means[1]];
        let [a0, a1, a2] = std::array::from_fn(|i| state_jacobian(before[i].z, applied[i].x, t));
        let h0 = rotation(start.z).transpose();
        let motion_maps = [
            h0 * a2 * a1 * rotation(start.z),
            h0 * a2 * rotation(means[0].z),
            h0 * rotation(means[1].z),
        ];
        Self {
            doublet,
            value: h0 * (end - means[2]),
            steps: 3,
            motion_maps,
            sensor_maps: [h0, h0 * a2 * a1 * a0],
            slip_map: slip_map(&motion_maps, &applied, t, axle),
            inputs: *inputs,
            sample_velocities: [Vector3::zeros(); 2],
            jitter_variance: 0.0,
        }
    }

    /// The three one-step residuals of a three-step doublet ([`Self::three_step`]'s model):
    /// from each of the controller's samples `[y(3j), y(3j+1), y(3j+2)]` to the next
    /// (`y(3j+3)` the end), the step predicted by the Euler map at its mean speed through
    /// `model`'s lag τ (s) — the bit's offsets of pattern `pattern` and the nominal inputs'
    /// transient from the wheels' nominal speed `entry` (m/s, rad/s) — in the robot's frame
    /// at the step's start sample: `z₃ⱼ₊ₖ = H(θ)ᵀ(y(3j+k+1) − f(y(3j+k), u_k)) ≈ w + η' − Aη`,
    /// covariance `Q + C₀RC₀ᵀ + C₁RC₁ᵀ`. Indexed by step, `3j + k`: residuals two steps apart
    /// share no sample, so each parity half is independent under white noise, as the two-step
    /// doublets' halves are. On wheels `axle` D (m) apart.
    #[must_use]
    pub fn three_step_split(
        model: &DoubletModel,
        axle: f64,
        doublet: u32,
        inputs: &DoubletInputs,
        samples: [&Pose; 4],
        pattern: usize,
        entry: Unicycle,
    ) -> [Self; 3] {
        let (applied, _) = Self::three_step_means(model, inputs, samples[0], pattern, entry);
        std::array::from_fn(|k| {
            Self::one_step(
                model.sample_time,
                axle,
                3 * doublet + k as u32,
                inputs,
                [samples[k], samples[k + 1]],
                &applied[k],
            )
        })
    }

    /// The two one-step residuals of a two-step doublet ([`Self::new`]'s model), from the
    /// controller's samples `[y(2j), y(2j+1), y(2j+2)]` at the steps' applied speeds of
    /// pattern `pattern`, as [`Self::three_step_split`]'s: covariance `Q + C₀RC₀ᵀ + C₁RC₁ᵀ`
    /// whatever the steps' correlation, indexed by step, `2j + k`.
    #[must_use]
    pub fn two_step_split(
        model: &DoubletModel,
        axle: f64,
        doublet: u32,
        inputs: &DoubletInputs,
        samples: [&Pose; 3],
        pattern: usize,
    ) -> [Self; 2] {
        let applied = inputs.applied_steps(model.step_offsets(inputs, Some(pattern)));
        let mut steps: [Self; 2] = std::array::from_fn(|k| {
            Self::one_step(
                model.sample_time,
                axle,
                2 * doublet + k as u32,
                inputs,
                [samples[k], samples[k + 1]],
                &applied[k],
            )
        });
        steps[1].sample_velocities[1] = steps[0].sample_velocities[0];
        steps
    }

    /// This one-step residual's start sample's rate taken from `previous`, the residual of
    /// the step before it ([`Self::sample_velocities`]), where `previous` is that step:
    /// without it the start sample's rate is taken as this step's own applied speed.
    pub fn enter_from(&mut self, previous: &Self) {
        if self.steps == 1 && previous.steps == 1 && previous.doublet + 1 == self.doublet {
            self.sample_velocities[1] = previous.sample_velocities[0];
        }
    }

    /// This residual with the sensor's part taken at timing variance `jitter_variance` j² (s²).
    #[must_use]
    pub fn with_jitter(self, jitter_variance: f64) -> Self {
        Self {
            jitter_variance,
            ..self
        }
    }

    /// Two consecutive one-step residuals ([`Self::two_step_split`],
    /// [`Self::three_step_split`]) joined into one over both steps, in the first's frame:
    /// `z = z_k + H(θ_k)ᵀH(θ_{k+1})·z_{k+1} ≈ w_k + w_{k+1} + η_{k+2} − Aη_k`, motion maps
    /// `[I, H(θ_k)ᵀH(θ_{k+1})]`, indexed by the first's step. The shared sample's noise enters
    /// as `H(θ_k)ᵀ(I − A_{k+1})η_{k+1}`, which the two sensor maps leave out: `I − A` is the
    /// heading's lateral coupling `T·v` (0.02 m/rad at the defaults, a variance of 4·10⁻⁴ of
    /// the sensor's lateral one at 0.5 mm and 0.5 mrad).
    #[must_use]
    pub fn joined(&self, next: &Self) -> Self {
        let turn = self.sensor_maps[0] * next.sensor_maps[0].transpose();
        let motion_maps = [
            self.motion_maps[0],
            turn * next.motion_maps[0],
            Matrix3::zeros(),
        ];
        Self {
            doublet: self.doublet,
            value: self.value + turn * next.value,
            steps: 2,
            motion_maps,
            sensor_maps: [turn * next.sensor_maps[0], self.sensor_maps[1]],
            slip_map: self.slip_map + turn * next.slip_map * turn.transpose(),
            inputs: self.inputs,
            sample_velocities: [next.sample_velocities[0], self.sample_velocities[1]],
            jitter_variance: self.jitter_variance,
        }
    }

    /// One step's residual `H(θ)ᵀ(to − f(from, applied))` at applied speed `applied` (m/s,
    /// rad/s) over `sample_time` T (s), in the robot's frame at the sample `from`'s heading θ;
    /// on wheels `axle` D (m) apart; `index` its step index.
    fn one_step(
        sample_time: f64,
        axle: f64,
        index: u32,
        inputs: &DoubletInputs,
        [from, to]: [&Pose; 2],
        applied: &Unicycle,
    ) -> Self {
        let t = sample_time;
        let h = rotation(from.z).transpose();
        let a = state_jacobian(from.z, applied.x, t);
        let motion_maps = [Matrix3::identity(), Matrix3::zeros(), Matrix3::zeros()];
        Self {
            doublet: index,
            value: h * (to - unicycle_step(from, applied, t)),
            steps: 1,
            motion_maps,
            sensor_maps: [h, h * a],
            slip_map: slip_map(&motion_maps[..1], std::slice::from_ref(applied), t, axle),
            inputs: *inputs,
            sample_velocities: [to.z, from.z].map(|theta| sample_velocity(applied, theta)),
            jitter_variance: 0.0,
        }
    }

    /// A three-step doublet's steps at their mean speeds through `model`'s lag τ (m/s,
    /// rad/s: the nominal inputs, the bit's offsets of pattern `pattern` and the nominal
    /// inputs' own transient from the wheels' speed `entry`), and the poses they predict
    /// after each step from `start` by the Euler map, `[m₁, m₂, m₃]`.
    #[must_use]
    pub fn three_step_means(
        model: &DoubletModel,
        inputs: &DoubletInputs,
        start: &Pose,
        pattern: usize,
        entry: Unicycle,
    ) -> ([Unicycle; 3], [Pose; 3]) {
        let t = model.sample_time;
        let mut offsets = model.mean_offsets(inputs, Some(pattern));
        let (transient, _) = inputs.nominal_transient(entry, 3, model.lag, t);
        for (offset, nominal) in offsets.iter_mut().zip(transient) {
            *offset += nominal;
        }
        (
            inputs.applied_steps(offsets),
            inputs.propagate_steps(start, offsets, 3, t),
        )
    }

    /// `B₀QB₀ᵀ + B₁QB₁ᵀ + ρ·(B₀QB₁ᵀ + B₁QB₀ᵀ)`: the motion noise's part of `Cov(z)` for
    /// AR(1) motion noise of stationary covariance `Q` in the robot's frame and lag-one
    /// correlation `rho` between steps (`rho = 0`: white); with three steps
    /// `Σᵢₖ ρ^|i−k|·BᵢQBₖᵀ`.
    #[must_use]
    pub fn motion_part(&self, q: &Matrix3<f64>, rho: f64) -> Matrix3<f64> {
        let [b0, b1, b2] = &self.motion_maps;
        if self.steps == 1 {
            return b0 * q * b0.transpose();
        }
        let cross = b0 * q * b1.transpose();
        let two =
            b0 * q * b0.transpose() + b1 * q * b1.transpose() + rho * (cross + cross.transpose());
        if self.steps == 2 {
            return two;
        }
        let late = b1 * q * b2.transpose();
        let far = b0 * q * b2.transpose();
        two + b2 * q * b2.transpose()
            + rho * (late + late.transpose())
            + rho * rho * (far + far.transpose())
    }

    /// `σ²·M`: per-wheel slip's part of `Cov(z)` for the slip's variance `slip_variance` σ².
    #[must_use]
    pub fn slip_part(&self, slip_variance: f64) -> Matrix3<f64> {
        slip_variance * self.slip_map
    }

    /// `C₀(R + j²u₀u₀ᵀ)C₀ᵀ + C₁(R + j²u₁u₁ᵀ)C₁ᵀ`: the sensor's part of `Cov(z)` for `R` in
    /// the world's frame, each sample moved by its timing error along its rate `uᵢ`
    /// ([`Self::sample_velocities`], j² = [`Self::jitter_variance`]).
    #[must_use]
    pub fn sensor_part(&self, r: &Matrix3<f64>) -> Matrix3<f64> {
        let plain: Matrix3<f64> = self.sensor_maps.iter().map(|c| c * r * c.transpose()).sum();
        if self.jitter_variance == 0.0 {
            return plain;
        }
        plain + self.jitter_variance * self.jitter_map()
    }

    /// `C₀u₀u₀ᵀC₀ᵀ + C₁u₁u₁ᵀC₁ᵀ`: the sensor's part of `Cov(z)` per unit of the timing
    /// variance j² (m²/s², m²/s², rad²/s²).
    #[must_use]
    pub fn jitter_map(&self) -> Matrix3<f64> {
        self.sensor_maps
            .iter()
            .zip(&self.sample_velocities)
            .map(|(c, u)| {
                let moved = c * u;
                moved * moved.transpose()
            })
            .sum()
    }

    /// `E[z zₙₑₓₜᵀ]`'s sensor part for `next`, the residual after this one, which shares
    /// this one's end sample as its start: `−C₀(R + j²u₀u₀ᵀ)C₁,ₙₑₓₜᵀ` (the MA(1) term; `R`
    /// in the world's frame, j² this residual's).
    #[must_use]
    pub fn shared_sensor_product(&self, next: &Self, r: &Matrix3<f64>) -> Matrix3<f64> {
        let plain = -(self.sensor_maps[0] * r * next.sensor_maps[1].transpose());
        if self.jitter_variance == 0.0 {
            return plain;
        }
        plain - self.jitter_variance * self.shared_jitter_product(next)
    }

    /// `(C₀u₀)(C₁,ₙₑₓₜu₀)ᵀ`: the shared sample's timing error's part of
    /// `−E[z zₙₑₓₜᵀ]` per unit of j² (m²/s², rad²/s² on the diagonal).
    #[must_use]
    pub fn shared_jitter_product(&self, next: &Self) -> Matrix3<f64> {
        let u = self.sample_velocities[0];
        (self.sensor_maps[0] * u) * (next.sensor_maps[1] * u).transpose()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use crate::model::Unicycle;
    use crate::private::doublet_model;

    /// The default robot's axle length D (m).
    const AXLE: f64 = 0.1047;

    /// A noise-free doublet leaves no residual whatever its bits and turn, when the
    /// residual is formed with the bits that rode on it.
    #[test]
    fn the_bits_and_the_turn_leave_no_residual() {
        let mut config = Config::default();
        config.protocol.bits_per_doublet = 2;
        let model = doublet_model(&config);
        let inputs = DoubletInputs {
            first: Unicycle::new(0.1, 0.4),
            second: Unicycle::new(0.09, 0.3),
        };
        let start = Pose::new(0.2, -0.4, 1.1);
        for pattern in 0..4 {
            let offset = model.perturbation.offset(pattern);
            let end = inputs.propagate(&start, offset, model.sample_time)[1];
            let r = DoubletResidual::new(&model, AXLE, 3, &inputs, &start, &end, pattern);
            assert!(r.value.norm() < 1e-15, "{pattern}: {}", r.value);
            // With the wrong pattern the bit's 14 mm (or its turn residual) remains.
            let wrong = DoubletResidual::new(&model, AXLE, 3, &inputs, &start, &end, pattern ^ 1);
            assert!(wrong.value.norm() > 1e-4, "{pattern}: {}", wrong.value);
        }
    }

    /// A two-step doublet's one-step residuals joined ([`DoubletResidual::joined`]) are its
    /// two-step residual but for the middle sample's `H(θ₀)ᵀ(I − A₁)δ`: nothing without noise,
    /// and with the middle sample moved by δ (0.1, −0.2 mm, 0.3 mrad) the two differ by that
    /// term (`T·v·δ_θ`, 6 μm here) to within δ's second order (below 10⁻⁸).
    #[test]
    fn joined_steps_are_the_doublets_residual_but_for_the_middle_sample() {
        let model = doublet_model(&Config::default());
        let inputs = DoubletInputs {
            first: Unicycle::new(0.1, 0.4),
            second: Unicycle::new(0.1, 0.4),
        };
        let start = Pose::new(0.2, -0.4, 1.1);
        let t = model.sample_time;
        for pattern in 0..2 {
            let offset = model.perturbation.offset(pattern);
            let [middle, end] = inputs.propagate(&start, offset, t);
            let split = |middle: &Pose| {
                let [a, b] = DoubletResidual::two_step_split(
                    &model,
                    AXLE,
                    3,
                    &inputs,
                    [&start, middle, &end],
                    pattern,
                );
                a.joined(&b)
            };
            let clean = split(&middle);
            assert!(clean.value.norm() < 1e-15, "{pattern}: {}", clean.value);
            assert_eq!((clean.doublet, clean.steps), (6, 2));
            let delta = Pose::new(1e-4, -2e-4, 3e-4);
            let whole = DoubletResidual::new(&model, AXLE, 3, &inputs, &start, &end, pattern);
            let moved = split(&(middle + delta));
            let [_, second] = inputs.applied(offset);
            let coupling = Matrix3::identity() - state_jacobian(middle.z, second.x, t);
            let expected = whole.value + rotation(start.z).transpose() * coupling * delta;
            assert!(
                (moved.value - expected).norm() < 1e-8,
                "{pattern}: {} against {expected}",
                moved.value
            );
            assert!((expected - whole.value).norm() <= t * second.x * delta.z + 1e-12);
        }
    }

    /// On a straight doublet the maps are the identity up to the heading's lateral
    /// coupling `T·v`: `Cov(z) = 2Q + 2R` to that order.
    #[test]
    fn on_a_straight_doublet_the_covariance_is_twice_q_plus_r() {
        let model = doublet_model(&Config::default());
        let inputs = DoubletInputs {
            first: Unicycle::new(0.1, 0.0),
            second: Unicycle::new(0.1, 0.0),
        };
        let start = Pose::new(0.0, 0.0, 0.7);
        let r = DoubletResidual::new(&model, AXLE, 0, &inputs, &start, &start, 0);
        let q = Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, 2.0, 3.0));
        let two_q = r.motion_part(&q, 0.0);
        let coupling = model.sample_time * 0.135;
        assert!(
            (two_q - 2.0 * q).abs().max() < 3.0 * 3.0 * coupling,
            "{two_q}"
        );
        assert!((two_q[(0, 0)] - 2.0).abs() < 1e-12, "along-track: {two_q}");
    }

    /// On a straight doublet the slip map's along-track and heading entries are exact: each
    /// step's wheels travel `d = v·T` at its applied speed (the bit's offset included), so
    /// `M_along = Σ d²/2` and `M_heading = Σ 2d²/D²` over the two steps, and nothing crosses
    /// between them.
    #[test]
    fn the_slip_map_follows_each_steps_wheel_travel() {
        let model = doublet_model(&Config::default());
        let inputs = DoubletInputs {
            first: Unicycle::new(0.1, 0.0),
            second: Unicycle::new(0.1, 0.0),
        };
        let start = Pose::new(0.0, 0.0, 0.7);
        for pattern in 0..2 {
            let r = DoubletResidual::new(&model, AXLE, 0, &inputs, &start, &start, pattern);
            let t = model.sample_time;
            let [a, b] = inputs.applied(model.perturbation.offset(pattern));
            let squares = (a.x * t).powi(2) + (b.x * t).powi(2);
            assert!(
                (r.slip_map[(0, 0)] - squares / 2.0).abs() < 1e-15,
                "{}",
                r.slip_map
            );
            let heading = 2.0 * squares / (AXLE * AXLE);
            assert!(
                (r.slip_map[(2, 2)] / heading - 1.0).abs() < 1e-12,
                "{}",
                r.slip_map
            );
            assert!(r.slip_map[(0, 2)].abs() < 1e-15, "{}", r.slip_map);
            assert_eq!(r.slip_part(0.0025), 0.0025 * r.slip_map);
        }
    }
}
