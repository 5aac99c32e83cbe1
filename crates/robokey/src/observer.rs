//! The unknown-input observer (corrected NUISE; Gillijns & De Moor 2007, Guo et al.;
//! docs/observer.md), in the corrected and the paper's variant, for m = 1 or 2 unknown inputs.

use nalgebra::{Matrix2, Matrix3, SMatrix, Vector2};

use crate::model::{Heading, Pose, Unicycle, input_matrix, unicycle_step_at};

/// Which algebra of docs/observer.md the observer uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Variant {
    /// Cross-covariance `S = −ΓV` and the closed-form pseudo-inverse of the singular `R̃`.
    Corrected,
    /// The paper's Algorithm 2 as printed: `S = +ΓV`, `R̃` inverted plainly.
    Paper,
}

/// Design parameters of an observer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObserverParams {
    /// Sample time `T` (s).
    pub sample_time: f64,
    /// Process covariance `W = w_var·I`.
    pub w_var: f64,
    /// Measurement covariance `V = v_var·I`.
    pub v_var: f64,
    /// Algebra variant.
    pub variant: Variant,
    /// Number of unknown inputs: 1 (Δv only, `E = [1, 0]ᵀ`) or 2 (`E = I`).
    pub channels: u8,
}

/// What one observer step estimated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InputEstimate {
    /// `E·d̂(k−1)`: the estimated deviation of the applied input from the nominal one,
    /// `[Δv̂, Δω̂]` (m/s, rad/s); Δω̂ is 0 when m = 1.
    pub deviation: Unicycle,
    /// `E·Pᵈ·Eᵀ`, the covariance of `deviation`.
    pub covariance: Matrix2<f64>,
    /// The state estimate `x̂(k)`.
    pub state: Pose,
}

/// The observer could not invert a matrix (non-finite or singular covariances).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("observer covariance became singular or non-finite")]
pub struct ObserverError;

/// An unknown-input observer with `M` unknown inputs.
#[derive(Clone, Debug)]
pub struct Uio<const M: usize> {
    state: Pose,
    covariance: Sym3,
    sample_time: f64,
    w_var: f64,
    v_var: f64,
    e: SMatrix<f64, 2, M>,
    variant: Variant,
}

impl<const M: usize> Uio<M> {
    fn new(params: &ObserverParams, e: SMatrix<f64, 2, M>) -> Self {
        Self {
            state: Pose::zeros(),
            covariance: Sym3::zeros(),
            sample_time: params.sample_time,
            w_var: params.w_var,
            v_var: params.v_var,
            e,
            variant: params.variant,
        }
    }

    /// One step with `u = uU(k−1)` and the measurement `y = y(k)` (docs/observer.md, with
    /// the structure of docs/speed.md: `W = wI`, `V = vI`, `A = I + a·e₃ᵀ`, symmetric
    /// covariances stored by their upper triangle, `S = ∓vΓ`).
    fn step(&mut self, input: &Unicycle, y: &Pose) -> Result<InputEstimate, ObserverError> {
        let (t, v) = (self.sample_time, self.v_var);
        let heading = Heading::of(&self.state);
        // P̃ = A·P·Aᵀ + W
        let p_tilde = self
            .covariance
            .jacobian_congruence(jacobian_column(heading, input, t))
            .plus_diagonal(self.w_var);
        // R*⁻¹ = (P̃ + V)⁻¹
        let r_star_inv = p_tilde.plus_diagonal(v).inverse().ok_or(ObserverError)?;
        // G = B·E
        let g: SMatrix<f64, 3, M> = input_matrix(heading, t) * self.e;
        let r_inv_g = r_star_inv.to_matrix() * g;
        // Pᵈ = (Gᵀ·R*⁻¹·G)⁻¹
        let input_cov = (g.transpose() * r_inv_g)
            .try_inverse()
            .ok_or(ObserverError)?;
        // M = Pᵈ·(R*⁻¹·G)ᵀ,  d̂ = M·(y − f(x̂, u))
        let gain_d = input_cov * r_inv_g.transpose();
        let d = gain_d * (y - unicycle_step_at(&self.state, heading, input, t));
        let deviation = self.e * d;
        // x̂⁻ = f(x̂, u + E·d̂)
        let x_minus = unicycle_step_at(&self.state, heading, &(input + deviation), t);

        // Γ = G·M,  Φ = I − Γ
        let gamma = g * gain_d;
        let phi = Matrix3::identity() - gamma;
        // P⁻ = Φ·P̃·Φᵀ + Γ·V·Γᵀ = Φ·P̃·Φᵀ + v·Γ·Γᵀ
        let p_minus = p_tilde.congruence(&phi).plus(&Sym3::gram(&gamma).scaled(v));
        // S = −Γ·V (corrected) or +Γ·V (paper)
        let s = match self.variant {
            Variant::Corrected => gamma * -v,
            Variant::Paper => gamma * v,
        };
        // R̃ = P⁻ + V + S + Sᵀ
        let r_tilde = p_minus.plus_diagonal(v).plus(&Sym3::sum_with_transpose(&s));
        let r_tilde_inv = match self.variant {
            Variant::Corrected => pseudo_inverse(&r_tilde, &r_inv_g).ok_or(ObserverError)?,
            Variant::Paper => r_tilde.inverse().ok_or(ObserverError)?,
        };
        // L = (P⁻ + S)·R̃⁺
        let l = (p_minus.to_matrix() + s) * r_tilde_inv.to_matrix();
        // x̂ = x̂⁻ + L·(y − x̂⁻)
        let state = x_minus + l * (y - x_minus);
        // P = Ψ·P⁻·Ψᵀ + L·V·Lᵀ − (Ψ·S·Lᵀ + L·Sᵀ·Ψᵀ),  Ψ = I − L; symmetric by construction
        let psi = Matrix3::identity() - l;
        let p = p_minus
            .congruence(&psi)
            .plus(&Sym3::gram(&l).scaled(v))
            .minus(&Sym3::sum_with_transpose(&(psi * s * l.transpose())));
        // An array rather than a chain of matrix iterators: unrolled, no iterator state.
        let [p0, p1, p2, p3, p4, p5] = p.0;
        if ![state.x, state.y, state.z, p0, p1, p2, p3, p4, p5]
            .iter()
            .all(|x| x.is_finite())
        {
            return Err(ObserverError);
        }
        self.state = state;
        self.covariance = p;
        Ok(InputEstimate {
            deviation,
            covariance: self.e * input_cov * self.e.transpose(),
            state,
        })
    }

    /// Prediction across a missing measurement (docs/observer.md): `x̂ ← f(x̂, u)`,
    /// `P ← A P Aᵀ + W + B·diag(Δv², Δω²)·Bᵀ`.
    fn predict(&mut self, input: &Unicycle, delta: &Unicycle) {
        let t = self.sample_time;
        let heading = Heading::of(&self.state);
        // B·diag(|Δv|, |Δω|), whose Gram matrix is B·diag(Δv², Δω²)·Bᵀ
        let b_delta = input_matrix(heading, t) * Matrix2::from_diagonal(&delta.abs());
        self.covariance = self
            .covariance
            .jacobian_congruence(jacobian_column(heading, input, t))
            .plus_diagonal(self.w_var)
            .plus(&Sym3::gram(&b_delta));
        self.state = unicycle_step_at(&self.state, heading, input, t);
    }
}

/// The off-identity column of `A = ∂f/∂x = I + a·e₃ᵀ` at `(x̂, u)`:
/// `a = (−T·v·sin θ̂, T·v·cos θ̂, 0)`, stored as its first two entries.
fn jacobian_column(heading: Heading, input: &Unicycle, t: f64) -> [f64; 2] {
    [-t * input.x * heading.sin, t * input.x * heading.cos]
}

/// A symmetric 3×3 matrix stored by its upper triangle `[s₀₀, s₀₁, s₀₂, s₁₁, s₁₂, s₂₂]`.
/// Products whose result is symmetric compute these six entries only.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Sym3([f64; 6]);

impl Sym3 {
    fn zeros() -> Self {
        Self([0.0; 6])
    }

    /// The six entries `f(i, j)`, `i ≤ j` (written out: `[T; N]::map` is not inlined).
    fn from_fn(f: impl Fn(usize, usize) -> f64) -> Self {
        Self([f(0, 0), f(0, 1), f(0, 2), f(1, 1), f(1, 2), f(2, 2)])
    }

    /// `f` entry by entry.
    fn zip_with(&self, other: &Self, f: impl Fn(f64, f64) -> f64) -> Self {
        let (a, b) = (&self.0, &other.0);
        Self([
            f(a[0], b[0]),
            f(a[1], b[1]),
            f(a[2], b[2]),
            f(a[3], b[3]),
            f(a[4], b[4]),
            f(a[5], b[5]),
        ])
    }

    fn to_matrix(self) -> Matrix3<f64> {
        let [s00, s01, s02, s11, s12, s22] = self.0;
        Matrix3::new(s00, s01, s02, s01, s11, s12, s02, s12, s22)
    }

    /// `S + c·I`.
    fn plus_diagonal(&self, c: f64) -> Self {
        let [s00, s01, s02, s11, s12, s22] = self.0;
        Self([s00 + c, s01, s02, s11 + c, s12, s22 + c])
    }

    fn plus(&self, other: &Self) -> Self {
        self.zip_with(other, |a, b| a + b)
    }

    fn minus(&self, other: &Self) -> Self {
        self.zip_with(other, |a, b| a - b)
    }

    fn scaled(&self, c: f64) -> Self {
        self.zip_with(self, |a, _| a * c)
    }

    fn trace(&self) -> f64 {
        self.0[0] + self.0[3] + self.0[5]
    }

    /// `X + Xᵀ` of any 3×3 `X`.
    fn sum_with_transpose(x: &Matrix3<f64>) -> Self {
        Self::from_fn(|i, j| x[(i, j)] + x[(j, i)])
    }

    /// `X·Xᵀ` of any 3×C `X`.
    fn gram<const C: usize>(x: &SMatrix<f64, 3, C>) -> Self {
        Self::from_fn(|i, j| x.row(i).dot(&x.row(j)))
    }

    /// `F·S·Fᵀ` of any 3×3 `F`: `F·S` in full, then the upper triangle of `(F·S)·Fᵀ`.
    fn congruence(&self, f: &Matrix3<f64>) -> Self {
        let fs = f * self.to_matrix();
        Self::from_fn(|i, j| fs.row(i).dot(&f.row(j)))
    }

    /// `A·S·Aᵀ` for `A = I + a·e₃ᵀ`, `a = (a₀, a₁, 0)`: with `(A·S)ᵢⱼ = Sᵢⱼ + aᵢ·S₂ⱼ`,
    /// `(A·S·Aᵀ)ᵢⱼ = (A·S)ᵢⱼ + aⱼ·(A·S)ᵢ₂` (16 flops instead of 90).
    fn jacobian_congruence(&self, [a0, a1]: [f64; 2]) -> Self {
        let [s00, s01, s02, s11, s12, s22] = self.0;
        // A·S, rows 0 and 1 (row 2 is S's).
        let (as00, as01, as02) = (s00 + a0 * s02, s01 + a0 * s12, s02 + a0 * s22);
        let (as11, as12) = (s11 + a1 * s12, s12 + a1 * s22);
        Self([
            as00 + a0 * as02,
            as01 + a1 * as02,
            as02,
            as11 + a1 * as12,
            as12,
            s22,
        ])
    }

    /// `S⁻¹` by cofactors (the symmetric adjugate over the determinant); `None` when the
    /// determinant is 0.
    fn inverse(&self) -> Option<Self> {
        let [s00, s01, s02, s11, s12, s22] = self.0;
        let c00 = s11 * s22 - s12 * s12;
        let c01 = s02 * s12 - s01 * s22;
        let c02 = s01 * s12 - s02 * s11;
        let determinant = s00 * c00 + s01 * c01 + s02 * c02;
        if determinant == 0.0 {
            return None;
        }
        let c11 = s00 * s22 - s02 * s02;
        let c12 = s01 * s02 - s00 * s12;
        let c22 = s00 * s11 - s01 * s01;
        Some(Self([c00, c01, c02, c11, c12, c22]).scaled(1.0 / determinant))
    }
}

/// Tolerance-free pseudo-inverse of the singular `R̃` whose null space is known to be
/// `span(R*⁻¹G)` (docs/observer.md). Rank 1 (m = 2): `R̃ / tr(R̃)²`; otherwise
/// `(R̃ + QQᵀ)⁻¹ − QQᵀ` with `Q` an orthonormal basis of the null space.
fn pseudo_inverse<const M: usize>(r_tilde: &Sym3, null_space: &SMatrix<f64, 3, M>) -> Option<Sym3> {
    if M == 2 {
        let trace = r_tilde.trace();
        return (trace > 0.0).then(|| r_tilde.scaled(1.0 / (trace * trace)));
    }
    let qqt = Sym3::gram(&orthonormal_columns(null_space)?);
    Some(r_tilde.plus(&qqt).inverse()?.minus(&qqt))
}

/// Gram–Schmidt orthonormalisation of the columns of `a`.
fn orthonormal_columns<const M: usize>(a: &SMatrix<f64, 3, M>) -> Option<SMatrix<f64, 3, M>> {
    let mut q = *a;
    for j in 0..M {
        for i in 0..j {
            let projection = q.column(i).dot(&q.column(j));
            let previous = q.column(i).into_owned();
            q.column_mut(j).axpy(-projection, &previous, 1.0);
        }
        let norm = q.column(j).norm();
        if norm.is_nan() || norm <= 0.0 {
            return None;
        }
        q.column_mut(j).unscale_mut(norm);
    }
    Some(q)
}

/// An observer with 1 or 2 unknown inputs, chosen at run time.
#[derive(Clone, Debug)]
pub enum Observer {
    /// m = 1: only Δv is unknown (`E = [1, 0]ᵀ`).
    One(Uio<1>),
    /// m = 2: Δv and Δω are unknown (`E = I`).
    Two(Uio<2>),
}

impl Observer {
    /// A new observer at `x̂ = 0`, `P = 0`. Returns `None` unless `channels` is 1 or 2.
    #[must_use]
    pub fn new(params: &ObserverParams) -> Option<Self> {
        match params.channels {
            1 => Some(Self::One(Uio::new(
                params,
                SMatrix::<f64, 2, 1>::new(1.0, 0.0),
            ))),
            2 => Some(Self::Two(Uio::new(params, Matrix2::identity()))),
            _ => None,
        }
    }

    /// One observer step with the nominal input `uU(k−1)` and measurement `y(k)`:
    /// estimates `d̂(k−1)` and `x̂(k)`.
    ///
    /// # Errors
    /// [`ObserverError`] when a covariance becomes singular or non-finite.
    pub fn step(&mut self, input: &Unicycle, y: &Pose) -> Result<InputEstimate, ObserverError> {
        match self {
            Self::One(uio) => uio.step(input, y),
            Self::Two(uio) => uio.step(input, y),
        }
    }

    /// Propagates across a missing measurement, treating the unknown `±Δ` (m/s, rad/s) as
    /// extra process noise (docs/observer.md).
    pub fn predict(&mut self, input: &Unicycle, delta: &Unicycle) {
        match self {
            Self::One(uio) => uio.predict(input, delta),
            Self::Two(uio) => uio.predict(input, delta),
        }
    }

    /// The state estimate `x̂`.
    #[must_use]
    pub fn state(&self) -> Pose {
        match self {
            Self::One(uio) => uio.state,
            Self::Two(uio) => uio.state,
        }
    }

    /// The state covariance `P`.
    #[must_use]
    pub fn covariance(&self) -> Matrix3<f64> {
        match self {
            Self::One(uio) => uio.covariance.to_matrix(),
            Self::Two(uio) => uio.covariance.to_matrix(),
        }
    }
}

/// Decides the applied bit from the estimated applied wheel speeds `ûD` (docs/protocol.md):
/// 0 if `‖ûD − u0D‖ < ‖ûD − u1D‖`, else 1.
///
/// For speed the squared distances decide when they can: the rounded square root is
/// monotone, so `‖·‖₀² ≥ ‖·‖₁²` gives 1, and `‖·‖₀² < (1 − 2⁻⁴⁸)·‖·‖₁²` (a normal
/// `‖·‖₁²`) gives 0 because the roots then differ by more than their rounding. Only closer
/// squares (or subnormal ones) take both roots, so every decision is the one the roots give.
#[must_use]
pub fn decide_bit(estimated: &Vector2<f64>, u0: &Vector2<f64>, u1: &Vector2<f64>) -> u8 {
    const CLEARLY_SHORTER: f64 = 1.0 - 1.0 / (1u64 << 48) as f64;
    let (to_u0, to_u1) = (
        (estimated - u0).norm_squared(),
        (estimated - u1).norm_squared(),
    );
    let farther = to_u0 >= to_u1;
    let clearly_nearer = to_u1 >= f64::MIN_POSITIVE && to_u0 < to_u1 * CLEARLY_SHORTER;
    // `|`, not `||`: the bit is random, a branch on it would be mispredicted half the time.
    if farther | clearly_nearer {
        return u8::from(farther);
    }
    u8::from(to_u0.sqrt() >= to_u1.sqrt())
}

/// `ln p(d̂ | b = 1) − ln p(d̂ | b = 0)` for the estimate `d̂ ~ N(d_b, Pᵈ)`, where `d0`, `d1`
/// are the deviations (m/s, rad/s) that applying `u0D` or `u1D` would produce. `Pᵈ` is
/// inverted on its range (m = 1: only Δv is observed); a degenerate `Pᵈ` gives 0.
#[must_use]
pub fn log_likelihood_ratio(estimate: &InputEstimate, d0: &Unicycle, d1: &Unicycle) -> f64 {
    let eigen = nalgebra::SymmetricEigen::new(estimate.covariance);
    let largest = eigen.eigenvalues.amax();
    if !(largest.is_finite() && largest > 0.0) {
        return 0.0;
    }
    let inverse_on_range = eigen
        .eigenvalues
        .map(|l| if l > largest * 1e-12 { 1.0 / l } else { 0.0 });
    let precision = eigen.eigenvectors
        * Matrix2::from_diagonal(&inverse_on_range)
        * eigen.eigenvectors.transpose();
    let distance = |d: &Unicycle| {
        let e = estimate.deviation - d;
        (e.transpose() * precision * e).x
    };
    0.5 * (distance(d0) - distance(d1))
}

/// The observer step as it was before docs/speed.md: every product dense, as the equations
/// of docs/observer.md read. The structured step is checked against it.
#[cfg(test)]
mod dense_reference {
    use nalgebra::{Matrix3, SMatrix};

    use super::{InputEstimate, ObserverError, ObserverParams, Variant, orthonormal_columns};
    use crate::model::{Heading, Pose, Unicycle, input_matrix, unicycle_step};

    /// One dense step from `(x̂, P)`; returns the estimate and the new `P`.
    pub(super) fn step<const M: usize>(
        params: &ObserverParams,
        e: SMatrix<f64, 2, M>,
        (state, covariance): (&Pose, &Matrix3<f64>),
        input: &Unicycle,
        y: &Pose,
    ) -> Result<(InputEstimate, Matrix3<f64>), ObserverError> {
        let t = params.sample_time;
        let w = Matrix3::identity() * params.w_var;
        let v = Matrix3::identity() * params.v_var;
        let (sin, cos) = state.z.sin_cos();
        let a = Matrix3::new(
            1.0,
            0.0,
            -t * input.x * sin,
            0.0,
            1.0,
            t * input.x * cos,
            0.0,
            0.0,
            1.0,
        );
        let g: SMatrix<f64, 3, M> = input_matrix(Heading { sin, cos }, t) * e;
        let p_tilde = a * covariance * a.transpose() + w;
        let r_star_inv = (p_tilde + v).try_inverse().ok_or(ObserverError)?;
        let r_inv_g = r_star_inv * g;
        let input_cov = (g.transpose() * r_inv_g)
            .try_inverse()
            .ok_or(ObserverError)?;
        let gain_d = input_cov * r_inv_g.transpose();
        let d = gain_d * (y - unicycle_step(state, input, t));
        let deviation = e * d;
        let x_minus = unicycle_step(state, &(input + deviation), t);

        let gamma = g * gain_d;
        let phi = Matrix3::identity() - gamma;
        let p_minus = phi * p_tilde * phi.transpose() + gamma * v * gamma.transpose();
        let s = match params.variant {
            Variant::Corrected => -gamma * v,
            Variant::Paper => gamma * v,
        };
        let r_tilde = p_minus + v + s + s.transpose();
        let r_tilde_inv = match params.variant {
            Variant::Corrected => pseudo_inverse(&r_tilde, &r_inv_g).ok_or(ObserverError)?,
            Variant::Paper => r_tilde.try_inverse().ok_or(ObserverError)?,
        };
        let l = (p_minus + s) * r_tilde_inv;
        let state = x_minus + l * (y - x_minus);
        let psi = Matrix3::identity() - l;
        let p = psi * p_minus * psi.transpose() + l * v * l.transpose()
            - psi * s * l.transpose()
            - l * s.transpose() * psi.transpose();
        let p = (p + p.transpose()) * 0.5;
        if !state.iter().chain(p.iter()).all(|x| x.is_finite()) {
            return Err(ObserverError);
        }
        let estimate = InputEstimate {
            deviation,
            covariance: e * input_cov * e.transpose(),
            state,
        };
        Ok((estimate, p))
    }

    fn pseudo_inverse<const M: usize>(
        r_tilde: &Matrix3<f64>,
        null_space: &SMatrix<f64, 3, M>,
    ) -> Option<Matrix3<f64>> {
        if M == 2 {
            let trace = r_tilde.trace();
            return (trace > 0.0).then(|| r_tilde / (trace * trace));
        }
        let q = orthonormal_columns(null_space)?;
        let qqt = q * q.transpose();
        Some((r_tilde + qqt).try_inverse()? - qqt)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::unicycle_step;
    use nalgebra::SymmetricEigen;
    use proptest::prelude::*;

    fn params(channels: u8, variant: Variant) -> ObserverParams {
        ObserverParams {
            sample_time: 0.2,
            w_var: 1e-2,
            v_var: 1e-4,
            variant,
            channels,
        }
    }

    /// Drives a noise-free unicycle with nominal inputs plus `delta` and returns the
    /// largest error of the recovered deviation.
    fn max_recovery_error(channels: u8, variant: Variant, delta: Unicycle) -> f64 {
        let mut obs = Observer::new(&params(channels, variant)).unwrap();
        let mut pose = Pose::zeros();
        let mut worst: f64 = 0.0;
        for k in 0..300 {
            let nominal = Unicycle::new(
                0.05 + 0.02 * (k as f64 * 0.05).sin(),
                0.3 * (k as f64 * 0.03).cos(),
            );
            let sign = if k % 3 == 0 { -1.0 } else { 1.0 };
            pose = unicycle_step(&pose, &(nominal + delta * sign), 0.2);
            let est = obs.step(&nominal, &pose).unwrap();
            worst = worst.max((est.deviation - delta * sign).norm());
        }
        worst
    }

    #[test]
    fn noise_free_observer_recovers_the_applied_deviation() {
        let both = Unicycle::new(0.035, 0.2);
        assert!(max_recovery_error(2, Variant::Corrected, both) < 1e-9);
        let v_only = Unicycle::new(0.035, 0.0);
        assert!(max_recovery_error(1, Variant::Corrected, v_only) < 1e-9);
        assert!(max_recovery_error(2, Variant::Paper, both) < 1e-9);
    }

    /// Builds `R̃` and `R*⁻¹G` as the observer does at a given state.
    fn r_tilde_at<const M: usize>(
        e: SMatrix<f64, 2, M>,
        theta: f64,
        p: Matrix3<f64>,
    ) -> (Matrix3<f64>, SMatrix<f64, 3, M>) {
        let v = Matrix3::identity() * 1e-4;
        let (sin, cos) = theta.sin_cos();
        let g = input_matrix(Heading { sin, cos }, 0.2) * e;
        let p_tilde = p + Matrix3::identity() * 1e-2;
        let r_inv = (p_tilde + v).try_inverse().unwrap();
        let m = (g.transpose() * r_inv * g).try_inverse().unwrap() * g.transpose() * r_inv;
        let gamma = g * m;
        let phi = Matrix3::identity() - gamma;
        let p_minus = phi * p_tilde * phi.transpose() + gamma * v * gamma.transpose();
        let s = -gamma * v;
        (p_minus + v + s + s.transpose(), r_inv * g)
    }

    fn truncated_pinv(a: &Matrix3<f64>, rank: usize) -> Matrix3<f64> {
        let eig = SymmetricEigen::new(*a);
        let mut order: Vec<usize> = (0..3).collect();
        order.sort_by(|&i, &j| {
            eig.eigenvalues[j]
                .abs()
                .total_cmp(&eig.eigenvalues[i].abs())
        });
        let mut out = Matrix3::zeros();
        for &i in &order[..rank] {
            let v = eig.eigenvectors.column(i);
            out += v * v.transpose() / eig.eigenvalues[i];
        }
        out
    }

    fn check_rank_and_pinv<const M: usize>(e: SMatrix<f64, 2, M>, theta: f64, p: Matrix3<f64>) {
        let (r_tilde, null) = r_tilde_at(e, theta, p);
        let eig = SymmetricEigen::new(r_tilde).eigenvalues;
        let largest = eig.abs().max();
        let zeros = eig.iter().filter(|x| x.abs() < 1e-12 * largest).count();
        assert_eq!(zeros, M, "eigenvalues {eig}");
        let upper = Sym3::from_fn(|i, j| r_tilde[(i, j)]);
        let closed = pseudo_inverse(&upper, &null).unwrap().to_matrix();
        let reference = truncated_pinv(&r_tilde, 3 - M);
        let scale = reference.abs().max();
        assert!(
            (closed - reference).abs().max() < 1e-12 * scale,
            "{closed} vs {reference}"
        );
    }

    #[test]
    fn r_tilde_has_rank_three_minus_m_and_closed_form_pinv_matches_eigendecomposition() {
        let p = Matrix3::new(2e-3, 1e-4, 0.0, 1e-4, 3e-3, 2e-4, 0.0, 2e-4, 1e-3);
        for &theta in &[0.0, 0.7, 2.5, -4.0] {
            check_rank_and_pinv(Matrix2::identity(), theta, p);
            check_rank_and_pinv(SMatrix::<f64, 2, 1>::new(1.0, 0.0), theta, p);
        }
    }

    #[test]
    fn decision_picks_the_nearer_command() {
        let u0 = Vector2::new(5.0, 5.0);
        let u1 = Vector2::new(4.0, 4.0);
        assert_eq!(decide_bit(&Vector2::new(4.9, 4.8), &u0, &u1), 0);
        assert_eq!(decide_bit(&Vector2::new(4.2, 4.1), &u0, &u1), 1);
    }

    /// The squared distances decide as the distances do, also where they are within a few
    /// ulps of each other (equal roots of unequal squares: 1), subnormal, infinite or NaN.
    #[test]
    fn decision_from_squared_distances_is_the_decision_from_distances() {
        let by_norms = |e: &Vector2<f64>, u0: &Vector2<f64>, u1: &Vector2<f64>| {
            u8::from((e - u0).norm() >= (e - u1).norm())
        };
        use rand::{RngExt, SeedableRng};
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(31);
        let mut cases = Vec::new();
        for _ in 0..20_000 {
            let e = Vector2::new(rng.random_range(-5.0..5.0), rng.random_range(-5.0..5.0));
            let u0 = Vector2::new(rng.random_range(-5.0..5.0), rng.random_range(-5.0..5.0));
            // u1 is u0 mirrored through e, nudged by a few ulps: distances within rounding.
            let nudge = f64::EPSILON * f64::from(rng.random_range(-8..=8));
            let u1 = e * 2.0 - u0 + (e - u0) * nudge;
            cases.push((e, u0, u1));
            cases.push((e, u0, e * 2.0 - u0));
            let far = Vector2::new(rng.random_range(-5.0..5.0), rng.random_range(-5.0..5.0));
            cases.push((e, u0, far));
        }
        let tiny = f64::MIN_POSITIVE.sqrt() / 4.0;
        for special in [0.0, tiny, -tiny, f64::INFINITY, f64::NAN, 1e300] {
            let z = Vector2::zeros();
            cases.push((z, Vector2::new(special, 0.0), Vector2::new(0.0, tiny)));
            cases.push((z, Vector2::new(0.0, tiny), Vector2::new(special, special)));
        }
        let mut ties = 0;
        for (e, u0, u1) in &cases {
            assert_eq!(decide_bit(e, u0, u1), by_norms(e, u0, u1), "{e} {u0} {u1}");
            let (a, b) = ((e - u0).norm_squared(), (e - u1).norm_squared());
            ties += usize::from(a < b && a.sqrt() == b.sqrt());
        }
        assert!(
            ties > 100,
            "the close cases reached only {ties} equal roots"
        );
    }

    #[test]
    fn likelihood_ratio_is_the_gaussian_closed_form() {
        let (delta, x) = (0.035, 0.01);
        let estimate = |covariance| InputEstimate {
            deviation: Unicycle::new(x, 0.2),
            covariance,
            state: Pose::zeros(),
        };
        let (d0, d1) = (Unicycle::new(delta, 0.0), Unicycle::new(-delta, 0.0));
        // m = 1: Δω̂ carries no information, only Δv counts.
        let one = estimate(Matrix2::new(4e-4, 0.0, 0.0, 0.0));
        let expected = -2.0 * x * delta / 4e-4;
        assert!((log_likelihood_ratio(&one, &d0, &d1) - expected).abs() < 1e-9);
        // m = 2, diagonal: the ω components of d0 and d1 are equal and cancel.
        let two = estimate(Matrix2::new(4e-4, 0.0, 0.0, 1e-2));
        assert!((log_likelihood_ratio(&two, &d0, &d1) - expected).abs() < 1e-9);
        assert_eq!(
            log_likelihood_ratio(&estimate(Matrix2::zeros()), &d0, &d1),
            0.0
        );
    }

    /// Largest absolute difference of two equally shaped matrices.
    fn max_difference<const R: usize, const C: usize>(
        a: &SMatrix<f64, R, C>,
        b: &SMatrix<f64, R, C>,
    ) -> f64 {
        (a - b).abs().max()
    }

    /// Steps the structured observer and the dense reference from the same `(x̂, P)`;
    /// returns `|Δd̂|`, `|Δx̂|` and `|ΔP|` relative to `|P|`.
    fn compare_one_step<const M: usize>(
        uio: &mut Uio<M>,
        params: &ObserverParams,
        input: &Unicycle,
        y: &Pose,
    ) -> (InputEstimate, [f64; 3]) {
        let before = (uio.state, uio.covariance.to_matrix());
        let (dense, dense_p) =
            dense_reference::step(params, uio.e, (&before.0, &before.1), input, y).unwrap();
        let structured = uio.step(input, y).unwrap();
        let p = uio.covariance.to_matrix();
        let differences = [
            max_difference(&structured.deviation, &dense.deviation),
            max_difference(&structured.state, &dense.state),
            max_difference(&p, &dense_p) / dense_p.abs().max(),
        ];
        assert!(
            max_difference(&structured.covariance, &dense.covariance)
                <= 1e-12 * dense.covariance.abs().max()
        );
        (dense, differences)
    }

    fn random_states_agree<const M: usize>(e: SMatrix<f64, 2, M>, variant: Variant) -> [f64; 3] {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(20);
        let params = params(M as u8, variant);
        let mut worst = [0.0f64; 3];
        for _ in 0..2000 {
            let mut uio = Uio::new(&params, e);
            uio.state = Pose::new(
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(-20.0..20.0),
            );
            let root = Matrix3::from_fn(|_, _| rng.random_range(-0.1..0.1));
            let p = root * root.transpose();
            uio.covariance = Sym3::from_fn(|i, j| p[(i, j)]);
            let input = Unicycle::new(rng.random_range(-0.1..0.1), rng.random_range(-1.0..1.0));
            let applied = input + Unicycle::new(rng.random_range(-0.05..0.05), 0.0);
            let noise = Pose::from_fn(|_, _| rng.random_range(-0.01..0.01));
            let y = unicycle_step(&uio.state, &applied, 0.2) + noise;
            let (_, differences) = compare_one_step(&mut uio, &params, &input, &y);
            for (w, d) in worst.iter_mut().zip(differences) {
                *w = w.max(d);
            }
        }
        worst
    }

    /// From 2,000 random states and covariances per variant and m, the structured step
    /// agrees with the dense one to reassociation: `|Δd̂|`, `|Δx̂|` ≤ 1e-12, `|ΔP|` ≤ 1e-10
    /// relative.
    #[test]
    fn structured_step_matches_the_dense_reference_from_random_states() {
        for variant in [Variant::Corrected, Variant::Paper] {
            for worst in [
                random_states_agree(Matrix2::identity(), variant),
                random_states_agree(SMatrix::<f64, 2, 1>::new(1.0, 0.0), variant),
            ] {
                eprintln!(
                    "{variant:?}: |Δd̂| {:.1e} |Δx̂| {:.1e} |ΔP|/|P| {:.1e}",
                    worst[0], worst[1], worst[2]
                );
                assert!(
                    worst[0] <= 1e-12 && worst[1] <= 1e-12 && worst[2] <= 1e-10,
                    "{worst:?}"
                );
            }
        }
    }

    /// Replays whole simulated runs (default, m = 1, paper variant; three replicates each)
    /// through the structured observer and, separately, the dense reference: every `d̂`
    /// agrees to 1e-12 and every bit decision is the same.
    #[test]
    fn structured_observer_decides_whole_runs_as_the_dense_reference() {
        use crate::config::Config;
        use crate::sim::simulate;
        let mut configs = vec![Config::default(); 3];
        configs[1].observer.m = 1;
        configs[2].observer.variant = Variant::Paper;
        let mut worst: f64 = 0.0;
        for config in &configs {
            let params = crate::protocol::controller::observer_params(config);
            let drive = crate::model::DiffDrive {
                wheel_radius: config.robot.r,
                axle_length: config.robot.axle_length,
            };
            for replicate in 0..3 {
                let trace = simulate(config, replicate, true).unwrap().trace;
                let mut structured = Observer::new(&params).unwrap();
                let mut dense = (Pose::zeros(), Matrix3::zeros());
                let e = match &structured {
                    Observer::One(_) => Matrix2::new(1.0, 0.0, 0.0, 0.0),
                    Observer::Two(_) => Matrix2::identity(),
                };
                for rows in trace.windows(2) {
                    let Some(nominal) = rows[0].nominal else {
                        continue;
                    };
                    let (input, y) = (Unicycle::from(nominal), Pose::from(rows[1].measurement));
                    let new = structured.step(&input, &y).unwrap();
                    let (old, p) = match params.channels {
                        1 => dense_reference::step(
                            &params,
                            e.fixed_columns::<1>(0).into_owned(),
                            (&dense.0, &dense.1),
                            &input,
                            &y,
                        ),
                        _ => dense_reference::step(&params, e, (&dense.0, &dense.1), &input, &y),
                    }
                    .unwrap();
                    dense = (old.state, p);
                    worst = worst.max(max_difference(&new.deviation, &old.deviation));
                    let (Some(u0), Some(u1)) = (rows[0].u0, rows[0].u1) else {
                        continue;
                    };
                    let (u0, u1) = (Vector2::from(u0), Vector2::from(u1));
                    let decide = |d: &Unicycle| decide_bit(&drive.to_wheels(input + d), &u0, &u1);
                    assert_eq!(decide(&new.deviation), decide(&old.deviation));
                }
            }
        }
        eprintln!("whole runs: |Δd̂| ≤ {worst:.1e}");
        assert!(worst <= 1e-12, "{worst}");
    }

    proptest! {
        #[test]
        fn covariance_stays_symmetric_positive_semidefinite(
            channels in 1u8..=2,
            paper in any::<bool>(),
            inputs in proptest::collection::vec((-0.1f64..0.1, -1.0f64..1.0, -0.01f64..0.01, -0.01f64..0.01, -0.01f64..0.01), 1..60),
        ) {
            let variant = if paper { Variant::Paper } else { Variant::Corrected };
            let mut obs = Observer::new(&params(channels, variant)).unwrap();
            let mut pose = Pose::zeros();
            for (v, w, nx, ny, nt) in inputs {
                let u = Unicycle::new(v, w);
                pose = unicycle_step(&pose, &u, 0.2) + Pose::new(nx, ny, nt);
                obs.step(&u, &pose).unwrap();
                let p = obs.covariance();
                prop_assert!((p - p.transpose()).abs().max() == 0.0);
                let min_eig = SymmetricEigen::new(p).eigenvalues.min();
                prop_assert!(min_eig >= -1e-12 * p.abs().max().max(1e-300), "min eigenvalue {}", min_eig);
            }
        }
    }
}
