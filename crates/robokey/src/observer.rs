//! The unknown-input observer (corrected NUISE; Gillijns & De Moor 2007, Guo et al.;
//! docs/observer.md), in the corrected and the paper's variant, for m = 1 or 2 unknown inputs.

use nalgebra::{Matrix2, Matrix3, SMatrix, Vector2};

use crate::model::{Pose, Unicycle, input_matrix, unicycle_step};

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
    covariance: Matrix3<f64>,
    sample_time: f64,
    w: Matrix3<f64>,
    v: Matrix3<f64>,
    e: SMatrix<f64, 2, M>,
    variant: Variant,
}

impl<const M: usize> Uio<M> {
    fn new(params: &ObserverParams, e: SMatrix<f64, 2, M>) -> Self {
        Self {
            state: Pose::zeros(),
            covariance: Matrix3::zeros(),
            sample_time: params.sample_time,
            w: Matrix3::identity() * params.w_var,
            v: Matrix3::identity() * params.v_var,
            e,
            variant: params.variant,
        }
    }

    /// One step with `u = uU(k−1)` and the measurement `y = y(k)`.
    fn step(&mut self, input: &Unicycle, y: &Pose) -> Result<InputEstimate, ObserverError> {
        let t = self.sample_time;
        let a = state_jacobian(&self.state, input, t);
        let g: SMatrix<f64, 3, M> = input_matrix(self.state.z, t) * self.e;
        let p_tilde = a * self.covariance * a.transpose() + self.w;
        let r_star_inv = (p_tilde + self.v).try_inverse().ok_or(ObserverError)?;
        let r_inv_g = r_star_inv * g;
        let input_cov = (g.transpose() * r_inv_g)
            .try_inverse()
            .ok_or(ObserverError)?;
        let gain_d = input_cov * r_inv_g.transpose();
        let d = gain_d * (y - unicycle_step(&self.state, input, t));
        let deviation = self.e * d;
        let x_minus = unicycle_step(&self.state, &(input + deviation), t);

        let gamma = g * gain_d;
        let phi = Matrix3::identity() - gamma;
        let p_minus = phi * p_tilde * phi.transpose() + gamma * self.v * gamma.transpose();
        let s = match self.variant {
            Variant::Corrected => -gamma * self.v,
            Variant::Paper => gamma * self.v,
        };
        let r_tilde = p_minus + self.v + s + s.transpose();
        let r_tilde_inv = match self.variant {
            Variant::Corrected => pseudo_inverse(&r_tilde, &r_inv_g).ok_or(ObserverError)?,
            Variant::Paper => r_tilde.try_inverse().ok_or(ObserverError)?,
        };
        let l = (p_minus + s) * r_tilde_inv;
        let state = x_minus + l * (y - x_minus);
        let psi = Matrix3::identity() - l;
        let p = psi * p_minus * psi.transpose() + l * self.v * l.transpose()
            - psi * s * l.transpose()
            - l * s.transpose() * psi.transpose();
        let p = (p + p.transpose()) * 0.5;
        if !state.iter().chain(p.iter()).all(|x| x.is_finite()) {
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
        let a = state_jacobian(&self.state, input, t);
        let b = input_matrix(self.state.z, t);
        let extra = Matrix2::from_diagonal(&delta.component_mul(delta));
        self.covariance = a * self.covariance * a.transpose() + self.w + b * extra * b.transpose();
        self.state = unicycle_step(&self.state, input, t);
    }
}

/// `A = ∂f/∂x` at `(x̂, u)`.
fn state_jacobian(state: &Pose, input: &Unicycle, t: f64) -> Matrix3<f64> {
    let (sin, cos) = state.z.sin_cos();
    Matrix3::new(
        1.0,
        0.0,
        -t * input.x * sin,
        0.0,
        1.0,
        t * input.x * cos,
        0.0,
        0.0,
        1.0,
    )
}

/// Tolerance-free pseudo-inverse of the singular `R̃` whose null space is known to be
/// `span(R*⁻¹G)` (docs/observer.md). Rank 1 (m = 2): `R̃ / tr(R̃)²`; otherwise
/// `(R̃ + QQᵀ)⁻¹ − QQᵀ` with `Q` an orthonormal basis of the null space.
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
            Self::One(uio) => uio.covariance,
            Self::Two(uio) => uio.covariance,
        }
    }
}

/// Decides the applied bit from the estimated applied wheel speeds `ûD` (docs/protocol.md):
/// 0 if `‖ûD − u0D‖ < ‖ûD − u1D‖`, else 1.
#[must_use]
pub fn decide_bit(estimated: &Vector2<f64>, u0: &Vector2<f64>, u1: &Vector2<f64>) -> u8 {
    u8::from((estimated - u0).norm() >= (estimated - u1).norm())
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

#[cfg(test)]
mod tests {
    use super::*;
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
        let g = input_matrix(theta, 0.2) * e;
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
        let closed = pseudo_inverse(&r_tilde, &null).unwrap();
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
