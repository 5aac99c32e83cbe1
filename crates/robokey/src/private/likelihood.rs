//! The true-noise likelihood of a doublet's bits given what one party observed
//! (docs/private-sensing.md, "Decisions").
//!
//! Model: `x(k+1) = f(x(k), u(k)) + w(k)`, `w ~ N(0, Q)` with `Q` the true motion noise,
//! AR(1)-correlated between steps at `ρ` (`Cov(wᵢ, wₖ) = ρ^|i−k|·Q`; white at `ρ = 0`), and
//! observations `y = x + η`, `η ~ N(0, R)` of the party's sensor. For each bit pattern `h`
//! the means `m₁(h), m₂(h)` of `x(2j+1), x(2j+2)` are propagated exactly (the Euler map, from
//! the start estimate, so the residual a bit leaves through a turn is in them); the
//! covariance is propagated through the Jacobians `Aᵢ = ∂f/∂x` of each pattern's path:
//! `C₁₁ = A₀P₀A₀ᵀ + Q`, `C₁₂ = C₁₁A₁ᵀ + ρQ`, `C₂₂ = A₁C₁₁A₁ᵀ + Q + ρ(A₁Q + QA₁ᵀ)`. Never the
//! observer's design covariances.
//!
//! **The start and the steps' correlation.** The start estimate's error `x(Lj) − ŷ` (covariance
//! `P₀`) is taken as uncorrelated with every step's noise: the view's start is a sample (or
//! samples fused), whose error is sensor noise, and the likelihood conditions on it alone, the
//! pose itself diffuse beyond it. The previous step's noise `w(Lj−1)`, which correlates with
//! `w(Lj)` by `ρQ`, is in `x(Lj)`, not in the estimate's error, so `w(Lj)` enters marginally,
//! `N(0, Q)`: what the previous doublet's samples say of it is left out (a marginal likelihood,
//! valid, not the sharpest). With `Sₖ = Cov(δₖ, wₖ)` the pose error's correlation with the next
//! step's noise (`S₀ = 0`), `Sₖ₊₁ = ρ(AₖSₖ + Q)`, and
//! `Cₖ₊₁,ₖ₊₁ = AₖCₖₖAₖᵀ + Q + AₖSₖ + SₖᵀAₖᵀ`, `Cᵢₖ = Cᵢ,ₖ₋₁Aₖ₋₁ᵀ + ρ^(k−1−i)·Sᵢ` (`i < k`).
//!
//! A three-step doublet (`private.prior_lag`) adds `x(3j+3)`: the steps' offsets are
//! `(+1, −(1 + a), +a)·s·Δ`, so under the model the bit's signature in the samples is
//! `E[y(3j+1) − x̄] ≈ s·T·Δ`, `E[y(3j+2) − x̄] ≈ −a·s·T·Δ` and `E[y(3j+3) − x̄] ≈ 0` on a
//! straight segment (`x̄` the nominal path; the turn's residual is in the exact means), with
//! `C₃₃`, `C₂₃`, `C₁₃` by the same recursion (`C₃₃ = A₂C₂₂A₂ᵀ + Q`, `C₂₃ = C₂₂A₂ᵀ`,
//! `C₁₃ = C₁₂A₂ᵀ` when white): the same Gaussian likelihood over the observed poses among the
//! three.

use nalgebra::allocator::Allocator;
use nalgebra::{
    Cholesky, DMatrix, DVector, DefaultAllocator, Dim, Matrix3, Matrix6, OMatrix, OVector, Vector3,
    Vector6,
};

use robokey_secrecy::special::ln_add_exp;

use super::doublet::{CommandRounding, DoubletInputs, MAX_BITS, Perturbation};
use crate::config::Config;
use crate::model::{Pose, Unicycle};

/// The true-noise doublet model of `config`: its parties' motion noise, white.
#[must_use]
pub fn doublet_model(config: &Config) -> DoubletModel {
    doublet_model_with(config, config.noise.process_std)
}

/// `config`'s doublet model with white motion noise `process_std` (m, m, rad per step): the
/// world's, for an eavesdropper who knows it.
#[must_use]
pub fn doublet_model_with(config: &Config, process_std: [f64; 3]) -> DoubletModel {
    let q = process_std.map(|s| s * s);
    DoubletModel {
        sample_time: config.robot.sample_time,
        process_covariance: Matrix3::from_diagonal(&q.into()),
        correlation: 0.0,
        perturbation: Perturbation::of(config),
        lag: config.private.prior_lag,
        rounding: CommandRounding::new(config.robot.drive(), config.robot.command_quantum),
    }
}

/// A direct Gaussian observation of a pose: `y = x + η`, `η ~ N(0, R)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseObservation {
    /// `y` (m, m, rad).
    pub value: Pose,
    /// `R` (m², m², rad²).
    pub covariance: Matrix3<f64>,
}

impl PoseObservation {
    /// An observation with independent components of standard deviation `std`.
    #[must_use]
    pub fn new(value: Pose, std: [f64; 3]) -> Self {
        Self {
            value,
            covariance: Matrix3::from_diagonal(
                &Vector3::from(std).component_mul(&Vector3::from(std)),
            ),
        }
    }

    /// Two independent observations of the same pose fused (exact for Gaussians):
    /// `R = (R₁⁻¹ + R₂⁻¹)⁻¹`, `y = R·(R₁⁻¹y₁ + R₂⁻¹y₂)`.
    #[must_use]
    pub fn fuse(&self, other: &Self) -> Self {
        let (i1, i2) = (inverse(&self.covariance), inverse(&other.covariance));
        let covariance = inverse(&(i1 + i2));
        Self {
            value: covariance * (i1 * self.value + i2 * other.value),
            covariance,
        }
    }
}

fn inverse(m: &Matrix3<f64>) -> Matrix3<f64> {
    m.try_inverse().unwrap_or_else(Matrix3::zeros)
}

/// What one party holds about a doublet of `L` steps: an estimate of its start pose, and
/// observations of the pose after its first step, after the second of three, and at its
/// end, if any.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DoubletView {
    /// `x(Lj)`: estimate and its covariance `P₀`.
    pub start: PoseObservation,
    /// `x(Lj+1)`, if observed.
    pub middle: Option<PoseObservation>,
    /// `x(3j+2)` of a three-step doublet, if observed (`None` with two steps).
    pub late: Option<PoseObservation>,
    /// `x(Lj+L)`, if observed.
    pub end: Option<PoseObservation>,
    /// The wheels' nominal speed at the doublet's start (m/s, rad/s) as the model's lag left
    /// the earlier nominal inputs: with it a three-step doublet's means follow the nominal
    /// inputs through the lag too ([`DoubletInputs::nominal_transient`]); `None`: the
    /// nominal inputs act at once and only the bit's offsets lag. Not used with two steps.
    pub entry: Option<Unicycle>,
}

impl DoubletView {
    /// A three-step doublet's observed poses among `x(3j+1), x(3j+2), x(3j+3)`, each with its
    /// index among the three.
    pub(crate) fn three_step_observed(&self) -> Vec<(usize, &PoseObservation)> {
        [&self.middle, &self.late, &self.end]
            .into_iter()
            .enumerate()
            .filter_map(|(i, y)| y.as_ref().map(|y| (i, y)))
            .collect()
    }
}

/// The camera Eve's view of a doublet as the controller can model it (never her realised
/// view): her stated per-instant noise `camera_std` around the controller's own `samples`
/// `y(Lj) … y(Lj+L)` (`L + 1` of them), fused at the boundaries with the controller's
/// samples of noise `controller_std`, which the commands reveal to her.
#[must_use]
pub fn stated_camera_view(
    samples: impl AsRef<[Pose]>,
    controller_std: [f64; 3],
    camera_std: [f64; 3],
) -> DoubletView {
    let samples = samples.as_ref();
    let own = |k: usize| PoseObservation::new(samples[k], controller_std);
    let camera = |k: usize| PoseObservation::new(samples[k], camera_std);
    let last = samples.len() - 1;
    DoubletView {
        start: own(0).fuse(&camera(0)),
        middle: Some(camera(1)),
        late: (last == 3).then(|| camera(2)),
        end: Some(own(last).fuse(&camera(last))),
        entry: None,
    }
}

/// The true-noise model of a doublet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DoubletModel {
    /// Sample time `T` (s).
    pub sample_time: f64,
    /// Motion noise covariance `Q` per step.
    pub process_covariance: Matrix3<f64>,
    /// ρ: the motion noise's lag-one correlation between steps, `Cov(wᵢ, wₖ) = ρ^|i−k|·Q`
    /// (AR(1); the module's doc). 0, white, for the parties' prior and every eavesdropper's
    /// model; the controller's LLRs recomputed at block time fit it.
    pub correlation: f64,
    /// The bits and their Δ.
    pub perturbation: Perturbation,
    /// The first-order actuator lag τ (s) a three-step doublet's means assume: the parties'
    /// prior (`private.prior_lag`), or the world's for an eavesdropper who knows it. Not
    /// used with two steps.
    pub lag: f64,
    /// How the wheels round each step's command (`robot.command_quantum`, or the world's for
    /// an eavesdropper who knows it): every pattern's means and Jacobians follow the rounded
    /// commands ([`DoubletInputs::rounded`]); `None`: no rounding.
    pub rounding: Option<CommandRounding>,
}

/// What a party can say about each bit of a doublet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BitEvidence {
    /// `ln P(view | bit 0) − ln P(view | bit 1)`, the other bits marginalised (uniform);
    /// entries beyond the doublet's key bits are 0.
    pub llr: [f64; MAX_BITS],
    /// The Mahalanobis distance between the bit's two hypotheses under the model, the other
    /// bits known (the larger over their values): the consistent Gaussian LLR has mean `d²/2`
    /// and variance `d²`, and the error rate is `Q(d/2)`.
    pub separation: [f64; MAX_BITS],
}

impl BitEvidence {
    /// The bits decided by the LLRs' signs, bit `i` at `1 << i` (a bit is 1 when its LLR is
    /// negative; an absent bit, LLR 0, reads 0): binary, `v | ω << 1`.
    #[must_use]
    pub fn bits(&self) -> u64 {
        self.llr
            .iter()
            .enumerate()
            .fold(0, |word, (i, &llr)| word | u64::from(llr < 0.0) << i)
    }
}

/// The most bit patterns a doublet can carry, `2^MAX_BITS`.
pub const MAX_PATTERNS: usize = 1 << MAX_BITS;

/// Each bit's separation from the patterns' pairwise `distance`: the largest over the
/// other bits' values of the distance between the patterns differing in that bit alone; 0
/// for an absent bit.
pub(crate) fn separations_by(
    perturbation: &Perturbation,
    distance: impl Fn(usize, usize) -> f64,
) -> [f64; MAX_BITS] {
    let patterns = perturbation.patterns();
    let mut separation = [0.0; MAX_BITS];
    for (i, slot) in separation
        .iter_mut()
        .enumerate()
        .take(perturbation.key_bits())
    {
        let mut pairs = (0..patterns)
            .filter(|h| h >> i & 1 == 0)
            .map(|h| distance(h, h | 1 << i));
        let first = pairs.next().unwrap_or(0.0);
        *slot = pairs.fold(first, f64::max);
    }
    separation
}

/// The evidence of each bit from the patterns' log-likelihoods `ll` (the other bits
/// marginalised) and their pairwise `distance` ([`separations_by`]).
pub(crate) fn bit_evidence(
    ll: &[f64],
    perturbation: &Perturbation,
    distance: impl Fn(usize, usize) -> f64,
) -> BitEvidence {
    BitEvidence {
        llr: bit_llrs(ll, perturbation, |_| (0, 0)),
        separation: separations_by(perturbation, distance),
    }
}

/// Each bit's LLR as multistage reconciliation decodes it: given `word`'s bits of the
/// symbols' lower slices (bit `j`'s slice is its place `j mod m` in its symbol's label, `m =
/// log₂ levels`), which the earlier slices' reconciliation gave the controller, the bits of
/// its own and higher slices marginalised. Binary: the marginal LLRs.
#[must_use]
pub fn staged_llrs(ll: &[f64], perturbation: &Perturbation, word: u64) -> [f64; MAX_BITS] {
    let m = perturbation.bits_per_symbol();
    let word = perturbation.pattern(word);
    let lower = |slice: usize| {
        (0..perturbation.key_bits())
            .filter(|j| j % m < slice)
            .fold(0, |mask, j| mask | 1 << j)
    };
    bit_llrs(ll, perturbation, |i| (lower(i % m), word))
}

/// Each bit's LLR from the patterns' log-likelihoods `ll` given `word`'s bits before it in
/// the doublet, the later ones marginalised ([`DoubletModel::chain_llrs`]): summed over the
/// bits, `Σᵢ ln(1 + e^{∓Lᵢ}) = −ln P(symbols | view)` of the true symbols `word`.
#[must_use]
pub(crate) fn chained_llrs(ll: &[f64], perturbation: &Perturbation, word: u64) -> [f64; MAX_BITS] {
    let word = perturbation.pattern(word);
    bit_llrs(ll, perturbation, |i| ((1 << i) - 1, word))
}

/// `ln Σ exp(ll[h])` over the patterns `h < patterns` whose bit `bit` is `value`, given
/// `known`: the patterns must also agree with `word` on the bits of mask `known`.
fn ln_sum_where(
    ll: &[f64],
    patterns: usize,
    bit: usize,
    value: usize,
    known: (usize, usize),
) -> f64 {
    let (mask, word) = known;
    let mut terms = (0..patterns)
        .filter(|h| (h >> bit) & 1 == value && h & mask == word & mask)
        .map(|h| ll[h]);
    let first = terms.next().unwrap_or(f64::NEG_INFINITY);
    terms.fold(first, ln_add_exp)
}

/// Each bit's LLR from the patterns' log-likelihoods `ll`: `ln Σ_{h: bᵢ=0} p(view|h) −
/// ln Σ_{h: bᵢ=1} p(view|h)` over the patterns agreeing with `word` on the bits `known`,
/// the rest marginalised.
fn bit_llrs(
    ll: &[f64],
    perturbation: &Perturbation,
    known: impl Fn(usize) -> (usize, usize),
) -> [f64; MAX_BITS] {
    let patterns = perturbation.patterns();
    let mut llr = [0.0; MAX_BITS];
    for (i, slot) in llr.iter_mut().enumerate().take(perturbation.key_bits()) {
        *slot =
            ln_sum_where(ll, patterns, i, 0, known(i)) - ln_sum_where(ll, patterns, i, 1, known(i));
    }
    llr
}

/// `∂f/∂x` of the Euler map at heading `θ` and speed `v` (m/s).
pub(crate) fn state_jacobian(theta: f64, speed: f64, sample_time: f64) -> Matrix3<f64> {
    let (sin, cos) = theta.sin_cos();
    Matrix3::new(
        1.0,
        0.0,
        -sample_time * speed * sin,
        0.0,
        1.0,
        sample_time * speed * cos,
        0.0,
        0.0,
        1.0,
    )
}

/// The covariances of the poses after each of a doublet's `N` steps (the module's doc): from
/// a start of covariance `P₀` uncorrelated with the steps' noise, through the steps'
/// Jacobians `Aₖ`, under motion noise `Cov(wᵢ, wₖ) = ρ^|i−k|·Q`. At `ρ = 0` the white
/// recursion `Cₖ₊₁,ₖ₊₁ = AₖCₖₖAₖᵀ + Q`, `Cᵢₖ = Cᵢᵢ·(Aₖ₋₁ ⋯ Aᵢ)ᵀ`, term for term.
struct PathCovariance<const N: usize> {
    /// `Aₖ`, step `k`'s Jacobian.
    jacobians: [Matrix3<f64>; N],
    /// The pose after step `k`'s covariance `Cₖ₊₁,ₖ₊₁`.
    diagonal: [Matrix3<f64>; N],
    /// The pose after step `k`'s covariance with step `k + 1`'s noise, `Sₖ₊₁`.
    carried: [Matrix3<f64>; N],
    /// ρ.
    correlation: f64,
}

impl<const N: usize> PathCovariance<N> {
    fn new(
        start: &Matrix3<f64>,
        jacobians: [Matrix3<f64>; N],
        q: &Matrix3<f64>,
        correlation: f64,
    ) -> Self {
        let mut diagonal = [Matrix3::zeros(); N];
        let mut carried = [Matrix3::zeros(); N];
        let (mut previous, mut s) = (*start, Matrix3::zeros());
        for (k, a) in jacobians.iter().enumerate() {
            diagonal[k] = a * previous * a.transpose() + q;
            if correlation != 0.0 {
                let a_s = a * s;
                diagonal[k] += a_s + a_s.transpose();
                s = correlation * (a_s + q);
                carried[k] = s;
            }
            previous = diagonal[k];
        }
        Self {
            jacobians,
            diagonal,
            carried,
            correlation,
        }
    }

    /// The covariance of the poses after steps `i` and `k`.
    fn block(&self, i: usize, k: usize) -> Matrix3<f64> {
        if i > k {
            return self.block(k, i).transpose();
        }
        (i + 1..=k).fold(self.diagonal[i], |c, step| {
            let c = c * self.jacobians[step].transpose();
            if self.correlation == 0.0 {
                c
            } else {
                c + self.correlation.powi((step - i - 1) as i32) * self.carried[i]
            }
        })
    }
}

/// One pattern's predicted observations: the residuals' mean and covariance, stacked over
/// the observed poses.
#[allow(
    clippy::large_enum_variant,
    reason = "a short-lived stack value on the decision path: boxing would allocate per pattern"
)]
enum Prediction {
    Both {
        mean: Vector6<f64>,
        covariance: Matrix6<f64>,
    },
    One {
        mean: Vector3<f64>,
        covariance: Matrix3<f64>,
    },
    /// A three-step doublet's observed poses among `x(3j+1), x(3j+2), x(3j+3)`.
    Three {
        mean: DVector<f64>,
        covariance: DMatrix<f64>,
    },
    None,
}

impl DoubletModel {
    fn predict(&self, inputs: &DoubletInputs, view: &DoubletView, pattern: usize) -> Prediction {
        if self.perturbation.settle.is_some() {
            return self.predict_three(inputs, view, pattern);
        }
        let t = self.sample_time;
        let offsets = self.step_offsets(inputs, Some(pattern));
        let [a, b, _] = inputs.applied_steps(offsets);
        let start = &view.start;
        let [m1, m2, _] = inputs.propagate_steps(&start.value, offsets, 2, t);
        let path = PathCovariance::new(
            &start.covariance,
            [
                state_jacobian(start.value.z, a.x, t),
                state_jacobian(m1.z, b.x, t),
            ],
            &self.process_covariance,
            self.correlation,
        );
        let (c11, c12, c22) = (path.block(0, 0), path.block(0, 1), path.block(1, 1));
        match (&view.middle, &view.end) {
            (Some(y1), Some(y2)) => {
                let mut covariance = Matrix6::zeros();
                covariance
                    .fixed_view_mut::<3, 3>(0, 0)
                    .copy_from(&(c11 + y1.covariance));
                covariance.fixed_view_mut::<3, 3>(0, 3).copy_from(&c12);
                covariance
                    .fixed_view_mut::<3, 3>(3, 0)
                    .copy_from(&c12.transpose());
                covariance
                    .fixed_view_mut::<3, 3>(3, 3)
                    .copy_from(&(c22 + y2.covariance));
                let mut mean = Vector6::zeros();
                mean.fixed_rows_mut::<3>(0).copy_from(&(y1.value - m1));
                mean.fixed_rows_mut::<3>(3).copy_from(&(y2.value - m2));
                Prediction::Both { mean, covariance }
            }
            (Some(y1), None) => Prediction::One {
                mean: y1.value - m1,
                covariance: c11 + y1.covariance,
            },
            (None, Some(y2)) => Prediction::One {
                mean: y2.value - m2,
                covariance: c22 + y2.covariance,
            },
            (None, None) => Prediction::None,
        }
    }

    /// [`Self::predict`] for a three-step doublet: the means `m₁, m₂, m₃` of
    /// `x(3j+1), x(3j+2), x(3j+3)` by the Euler map with the steps' mean offsets through the
    /// model's lag ([`Perturbation::mean_offsets`]) plus, when the view knows the wheels'
    /// speed at the start, the nominal inputs' own transient through it
    /// ([`DoubletInputs::nominal_transient`]), and their covariances `Cᵢₖ` (`PathCovariance`),
    /// stacked over the observed poses with their covariance `R` added.
    fn predict_three(
        &self,
        inputs: &DoubletInputs,
        view: &DoubletView,
        pattern: usize,
    ) -> Prediction {
        let start = &view.start;
        let (means, jacobians, _) = self.three_step_path(inputs, view, pattern);
        let path = PathCovariance::new(
            &start.covariance,
            jacobians,
            &self.process_covariance,
            self.correlation,
        );
        let observed = view.three_step_observed();
        if observed.is_empty() {
            return Prediction::None;
        }
        let n = 3 * observed.len();
        let mut mean = DVector::zeros(n);
        let mut covariance = DMatrix::zeros(n, n);
        for (row, &(i, y)) in observed.iter().enumerate() {
            mean.fixed_rows_mut::<3>(3 * row)
                .copy_from(&(y.value - means[i]));
            for (col, &(k, _)) in observed.iter().enumerate() {
                let block = if i == k {
                    path.block(i, i) + y.covariance
                } else {
                    path.block(i, k)
                };
                covariance
                    .fixed_view_mut::<3, 3>(3 * row, 3 * col)
                    .copy_from(&block);
            }
        }
        Prediction::Three { mean, covariance }
    }

    /// A three-step doublet's mean path for `pattern`: the means `m₁, m₂, m₃` of
    /// `x(3j+1), x(3j+2), x(3j+3)` ([`Self::predict_three`]), the steps' Jacobians
    /// `A₀, A₁, A₂` along it and the steps' applied mean speeds (m/s, rad/s).
    pub(crate) fn three_step_path(
        &self,
        inputs: &DoubletInputs,
        view: &DoubletView,
        pattern: usize,
    ) -> ([Pose; 3], [Matrix3<f64>; 3], [Unicycle; 3]) {
        let t = self.sample_time;
        let mut offsets = self.mean_offsets(inputs, Some(pattern));
        if let Some(entry) = view.entry {
            let (transient, _) = inputs.nominal_transient(entry, 3, self.lag, t);
            for (offset, nominal) in offsets.iter_mut().zip(transient) {
                *offset += nominal;
            }
        }
        let applied = inputs.applied_steps(offsets);
        let start = &view.start;
        let means = inputs.propagate_steps(&start.value, offsets, 3, t);
        let before = [start.value, means[0], means[1]];
        let jacobians: [Matrix3<f64>; 3] =
            std::array::from_fn(|i| state_jacobian(before[i].z, applied[i].x, t));
        (means, jacobians, applied)
    }

    /// The steps' commanded offsets of pattern `h` (`None`: the nominal inputs alone) with
    /// `inputs`, as the wheels receive them under the model's rounding
    /// ([`Perturbation::step_offsets`], [`DoubletInputs::rounded`]).
    #[must_use]
    pub fn step_offsets(&self, inputs: &DoubletInputs, pattern: Option<usize>) -> [Unicycle; 3] {
        let offsets = pattern.map_or([Unicycle::zeros(); 3], |h| {
            self.perturbation.step_offsets(self.perturbation.offset(h))
        });
        inputs.rounded(offsets, self.rounding.as_ref())
    }

    /// Pattern `h`'s mean step offsets under the model (`None`: the nominal inputs'): its
    /// rounded commanded offsets ([`Self::step_offsets`]) through its lag
    /// ([`Perturbation::mean_offsets`]).
    #[must_use]
    pub fn mean_offsets(&self, inputs: &DoubletInputs, pattern: Option<usize>) -> [Unicycle; 3] {
        self.perturbation.mean_offsets(
            self.step_offsets(inputs, pattern),
            self.lag,
            self.sample_time,
        )
    }

    /// The noise-free end pose `x(Lj+L)` of pattern `h` from `start` under the model.
    #[must_use]
    pub fn end_of(&self, inputs: &DoubletInputs, start: &Pose, pattern: Option<usize>) -> Pose {
        let offsets = self.mean_offsets(inputs, pattern);
        let steps = self.perturbation.steps();
        inputs.propagate_steps(start, offsets, steps, self.sample_time)[steps as usize - 1]
    }

    /// `ln p(view | pattern h)` up to a constant common to all patterns, for every pattern
    /// ([`Perturbation::patterns`]; unused entries are −∞).
    #[must_use]
    pub fn log_likelihoods(
        &self,
        inputs: &DoubletInputs,
        view: &DoubletView,
    ) -> [f64; MAX_PATTERNS] {
        log_likelihoods_of(&self.factored(inputs, view))
    }

    /// Every pattern's prediction of `view`, its covariance factored once for both its
    /// log-likelihood and its distances to the others.
    fn factored(&self, inputs: &DoubletInputs, view: &DoubletView) -> Vec<Factored> {
        (0..self.perturbation.patterns())
            .map(|h| Factored::of(self.predict(inputs, view, h)))
            .collect()
    }

    /// The LLR and separation of each bit, the other bits marginalised (entries beyond the
    /// key bits are 0).
    #[must_use]
    pub fn evidence(&self, inputs: &DoubletInputs, view: &DoubletView) -> BitEvidence {
        self.evidence_and_likelihoods(inputs, view).0
    }

    /// [`Self::evidence`] with the patterns' log-likelihoods it came from
    /// ([`Self::log_likelihoods`]).
    #[must_use]
    pub fn evidence_and_likelihoods(
        &self,
        inputs: &DoubletInputs,
        view: &DoubletView,
    ) -> (BitEvidence, [f64; MAX_PATTERNS]) {
        let factored = self.factored(inputs, view);
        let ll = log_likelihoods_of(&factored);
        let evidence = bit_evidence(&ll, &self.perturbation, |a, b| {
            factored[a].distance_to(&factored[b])
        });
        (evidence, ll)
    }

    /// Each bit's LLR given the true bits before it in the doublet (`word`'s bits `< i`),
    /// the later ones marginalised: by the chain rule `Σᵢ ln(1 + e^{∓Lᵢ})` is the surprisal
    /// `−ln P(symbols | view)` of the doublet's true symbols, so a bound summed over these
    /// is a bound on the symbol string, not on bits judged apart.
    #[must_use]
    pub fn chain_llrs(
        &self,
        inputs: &DoubletInputs,
        view: &DoubletView,
        word: u64,
    ) -> [f64; MAX_BITS] {
        chained_llrs(
            &self.log_likelihoods(inputs, view),
            &self.perturbation,
            word,
        )
    }

    /// Each bit's separation: the Mahalanobis distance between its two hypotheses, the
    /// other bits known (the larger over their values); 0 for an absent bit. It depends on
    /// the view's covariances and, through the path's Jacobians, on its start value only.
    #[must_use]
    pub fn separations(&self, inputs: &DoubletInputs, view: &DoubletView) -> [f64; MAX_BITS] {
        let factored = self.factored(inputs, view);
        separations_by(&self.perturbation, |a, b| {
            factored[a].distance_to(&factored[b])
        })
    }

    /// The separations that size a key from `view`: [`Self::separations`], but for a
    /// three-step doublet the largest over the lags `0, τ/4, τ/2, 3τ/4, τ` of the model's
    /// prior τ — the lag smooths the bit's signature (less after the first step, more after
    /// the second), so neither end of `[0, τ]` is Eve's best view for every bit, and a world
    /// with less lag than the prior must not make the key over-claim. A grid, not a proof
    /// over the interval; a world with more lag than the prior is the commands check's.
    #[must_use]
    pub fn sizing_separations(
        &self,
        inputs: &DoubletInputs,
        view: &DoubletView,
    ) -> [f64; MAX_BITS] {
        if self.perturbation.settle.is_none() {
            return self.separations(inputs, view);
        }
        (0..=4)
            .map(|i| {
                let model = Self {
                    lag: self.lag * f64::from(i) / 4.0,
                    ..*self
                };
                model.separations(inputs, view)
            })
            .fold([0.0; MAX_BITS], |worst, d| {
                std::array::from_fn(|i| worst[i].max(d[i]))
            })
    }

    /// Whether every pattern's predicted covariance of `view` is positive definite: only then
    /// is [`Self::separations`] a distance (it reads 0 otherwise).
    #[must_use]
    pub fn covariances_positive(&self, inputs: &DoubletInputs, view: &DoubletView) -> bool {
        self.factored(inputs, view)
            .iter()
            .all(Factored::positive_definite)
    }
}

/// `ln p(view | pattern h)` of every pattern from its factored prediction (unused entries
/// −∞; a pattern the view does not observe, 0).
fn log_likelihoods_of(factored: &[Factored]) -> [f64; MAX_PATTERNS] {
    let mut out = [f64::NEG_INFINITY; MAX_PATTERNS];
    for (slot, prediction) in out.iter_mut().zip(factored) {
        *slot = prediction.ln_density();
    }
    out
}

/// A pattern's `Prediction` with its covariance's Cholesky factor (`None` when it is not
/// positive definite).
#[allow(
    clippy::large_enum_variant,
    reason = "held per pattern of one view on the decision path, as `Prediction` is: boxing \
              would allocate per pattern"
)]
enum Factored {
    Both(Gaussian<nalgebra::U6>),
    One(Gaussian<nalgebra::U3>),
    Three(Gaussian<nalgebra::Dyn>),
    None,
}

/// A predicted residual `r` and the factor of its covariance `S`.
struct Gaussian<D: Dim>
where
    DefaultAllocator: Allocator<D, D> + Allocator<D>,
{
    mean: OVector<f64, D>,
    factor: Option<Cholesky<f64, D>>,
}

impl<D: Dim> Gaussian<D>
where
    DefaultAllocator: Allocator<D, D> + Allocator<D>,
{
    fn new(mean: OVector<f64, D>, covariance: OMatrix<f64, D, D>) -> Self {
        Self {
            mean,
            factor: Cholesky::new(covariance),
        }
    }

    /// `−½·(rᵀS⁻¹r + ln det S)`: the Gaussian log-density of the residual up to its
    /// constant; −∞ when `S` is not positive definite.
    fn ln_density(&self) -> f64 {
        self.factor.as_ref().map_or(f64::NEG_INFINITY, |c| {
            -0.5 * (c.solve(&self.mean).dot(&self.mean) + c.ln_determinant())
        })
    }

    /// `√(dᵀS⁻¹d)` with `d = other − r`, under this covariance; 0 when `S` is not positive
    /// definite.
    fn distance_to(&self, other: &OVector<f64, D>) -> f64 {
        self.factor.as_ref().map_or(0.0, |c| {
            let d = other - &self.mean;
            c.solve(&d).dot(&d).sqrt()
        })
    }
}

impl Factored {
    fn of(prediction: Prediction) -> Self {
        match prediction {
            Prediction::Both { mean, covariance } => Self::Both(Gaussian::new(mean, covariance)),
            Prediction::One { mean, covariance } => Self::One(Gaussian::new(mean, covariance)),
            Prediction::Three { mean, covariance } => Self::Three(Gaussian::new(mean, covariance)),
            Prediction::None => Self::None,
        }
    }

    fn ln_density(&self) -> f64 {
        match self {
            Self::Both(g) => g.ln_density(),
            Self::One(g) => g.ln_density(),
            Self::Three(g) => g.ln_density(),
            Self::None => 0.0,
        }
    }

    /// Mahalanobis distance between this pattern's predicted observations and `other`'s,
    /// under this one's covariance (0 between views of different shapes).
    fn distance_to(&self, other: &Self) -> f64 {
        match (self, other) {
            (Self::Both(g), Self::Both(o)) => g.distance_to(&o.mean),
            (Self::One(g), Self::One(o)) => g.distance_to(&o.mean),
            (Self::Three(g), Self::Three(o)) => g.distance_to(&o.mean),
            _ => 0.0,
        }
    }

    fn positive_definite(&self) -> bool {
        match self {
            Self::Both(g) => g.factor.is_some(),
            Self::One(g) => g.factor.is_some(),
            Self::Three(g) => g.factor.is_some(),
            Self::None => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Labeling;
    use crate::private::doublet::settle_share;

    const T: f64 = 0.2;

    /// A three-step doublet on a straight segment whose nominal speed changes: the poses a
    /// first-order lag τ really gives (integrated in 20,000 sub-steps per step, independent
    /// of the closed forms) are the model's means when the view knows the wheels' speed at
    /// the start, to the sub-steps' error; without it the nominal inputs' transient is left
    /// in the residual (millimetres at 100 ms).
    #[test]
    fn the_nominal_inputs_lag_is_in_the_means_when_the_entry_speed_is_known() {
        let tau = 0.1;
        let model = DoubletModel {
            sample_time: T,
            process_covariance: Matrix3::from_diagonal_element(1e-6),
            correlation: 0.0,
            perturbation: Perturbation::binary(Unicycle::new(0.035, 0.0), 1, settle_share(T, tau)),
            lag: tau,
            rounding: None,
        };
        let inputs = DoubletInputs {
            first: Unicycle::new(0.12, 0.0),
            second: Unicycle::new(0.07, 0.0),
        };
        let entry = Unicycle::new(0.09, 0.0);
        let substeps = 20_000;
        let h = T / f64::from(substeps);
        for pattern in 0..2 {
            let offsets = model
                .perturbation
                .step_offsets(model.perturbation.offset(pattern));
            let commands = [
                inputs.first + offsets[0],
                inputs.second + offsets[1],
                inputs.second + offsets[2],
            ];
            let (mut x, mut v) = (0.0, entry.x);
            let mut poses = [Pose::zeros(); 3];
            for (pose, c) in poses.iter_mut().zip(commands) {
                for _ in 0..substeps {
                    let next = c.x + (v - c.x) * (-h / tau).exp();
                    x += 0.5 * (v + next) * h;
                    v = next;
                }
                *pose = Pose::new(x, 0.0, 0.0);
            }
            let observed = |pose: Pose| Some(PoseObservation::new(pose, [5e-4, 5e-4, 1e-3]));
            let view = |entry: Option<Unicycle>| DoubletView {
                start: PoseObservation::new(Pose::zeros(), [5e-4, 5e-4, 1e-3]),
                middle: observed(poses[0]),
                late: observed(poses[1]),
                end: observed(poses[2]),
                entry,
            };
            let residual = |entry| match model.predict(&inputs, &view(entry), pattern) {
                Prediction::Three { mean, .. } => mean.amax(),
                _ => panic!("a three-step doublet with every pose observed"),
            };
            let (known, ignored) = (residual(Some(entry)), residual(None));
            assert!(known < 1e-7, "pattern {pattern}: {known} m left");
            assert!(ignored > 1e-3, "pattern {pattern}: {ignored} m left");
        }
    }

    /// The brute-force Gaussian of a doublet's stacked poses: `x = Φ·(δ₀, w₀, …, w_{L−1})`
    /// with `δ₀ ~ N(0, P₀)` and the steps' noise `Cov(wᵢ, wₖ) = ρ^|i−k|·Q`, independent of
    /// `δ₀` (row block `p`, the pose after step `p`: `Aₚ⋯A₀` on `δ₀`, `Aₚ⋯Aᵢ₊₁` on `wᵢ`,
    /// `i ≤ p`), plus the observations' `R`: `−½(rᵀS⁻¹r + ln det S)` of the residual `r`.
    fn stacked_log_density(
        model: &DoubletModel,
        view: &DoubletView,
        means: &[Pose],
        jacobians: &[Matrix3<f64>],
    ) -> f64 {
        let steps = jacobians.len();
        let mut noise = DMatrix::<f64>::zeros(3 * (steps + 1), 3 * (steps + 1));
        noise
            .view_mut((0, 0), (3, 3))
            .copy_from(&view.start.covariance);
        for i in 0..steps {
            for k in 0..steps {
                let c = model.correlation.powi(i.abs_diff(k) as i32);
                noise
                    .view_mut((3 + 3 * i, 3 + 3 * k), (3, 3))
                    .copy_from(&(model.process_covariance * c));
            }
        }
        let mut map = DMatrix::<f64>::zeros(3 * steps, 3 * (steps + 1));
        for p in 0..steps {
            // Aₚ⋯Aᵢ₊₁ for i = p, p − 1, …, 0, then Aₚ⋯A₀.
            let mut product = Matrix3::identity();
            for i in (0..=p).rev() {
                map.view_mut((3 * p, 3 + 3 * i), (3, 3)).copy_from(&product);
                product *= jacobians[i];
            }
            map.view_mut((3 * p, 0), (3, 3)).copy_from(&product);
        }
        let observed: Vec<(usize, &PoseObservation)> = if steps == 3 {
            view.three_step_observed()
        } else {
            [(0, view.middle.as_ref()), (1, view.end.as_ref())]
                .into_iter()
                .filter_map(|(i, y)| y.map(|y| (i, y)))
                .collect()
        };
        let full = &map * noise * map.transpose();
        let n = 3 * observed.len();
        let (mut covariance, mut residual) = (DMatrix::zeros(n, n), DVector::zeros(n));
        for (row, &(p, y)) in observed.iter().enumerate() {
            residual
                .rows_mut(3 * row, 3)
                .copy_from(&(y.value - means[p]));
            for (col, &(k, _)) in observed.iter().enumerate() {
                covariance
                    .view_mut((3 * row, 3 * col), (3, 3))
                    .copy_from(&full.view((3 * p, 3 * k), (3, 3)));
            }
            let mut diagonal = covariance.view_mut((3 * row, 3 * row), (3, 3));
            diagonal += y.covariance;
        }
        let factor = Cholesky::new(covariance).expect("positive definite");
        -0.5 * (factor.solve(&residual).dot(&residual) + factor.ln_determinant())
    }

    /// Under correlated motion noise every pattern's log-likelihood is the brute-force
    /// Gaussian of the stacked poses ([`stacked_log_density`]), on two- and three-step
    /// doublets of two bits on a turning segment, with a `Q` whose axes correlate, at
    /// ρ = 0, −0.4, 0.5 and 0.9, every pose observed and the middle alone: to 10⁻⁹ of the
    /// log-likelihood's scale.
    #[test]
    fn the_correlated_likelihood_is_the_stacked_gaussian() {
        let inputs = DoubletInputs {
            first: Unicycle::new(0.11, 0.4),
            second: Unicycle::new(0.09, 0.3),
        };
        let q = Matrix3::new(
            16e-6, 2e-6, 1e-6, //
            2e-6, 9e-6, -1e-6, //
            1e-6, -1e-6, 25e-6,
        );
        let observed = |x: f64, y: f64, z: f64| {
            Some(PoseObservation::new(Pose::new(x, y, z), [5e-4, 7e-4, 2e-3]))
        };
        for lag in [0.0, 0.05] {
            for rho in [0.0, -0.4, 0.5, 0.9] {
                let model = DoubletModel {
                    sample_time: T,
                    process_covariance: q,
                    correlation: rho,
                    perturbation: Perturbation::binary(
                        Unicycle::new(0.035, 0.035),
                        2,
                        settle_share(T, lag),
                    ),
                    lag,
                    rounding: None,
                };
                let three = lag > 0.0;
                let start = Pose::new(0.3, -0.1, 0.4);
                let full = DoubletView {
                    start: PoseObservation::new(start, [6e-4, 5e-4, 1e-3]),
                    middle: observed(0.32, -0.09, 0.47),
                    late: three.then(|| observed(0.335, -0.082, 0.53)).flatten(),
                    end: observed(0.351, -0.07, 0.6),
                    entry: None,
                };
                let middle_only = DoubletView {
                    late: None,
                    end: None,
                    ..full
                };
                for view in [full, middle_only] {
                    let ll = model.log_likelihoods(&inputs, &view);
                    let patterns = model.perturbation.patterns();
                    for (h, &got) in ll.iter().enumerate().take(patterns) {
                        let (means, jacobians) = if three {
                            let (m, a, _) = model.three_step_path(&inputs, &view, h);
                            (m.to_vec(), a.to_vec())
                        } else {
                            let offsets = model.step_offsets(&inputs, Some(h));
                            let [a, b, _] = inputs.applied_steps(offsets);
                            let [m1, m2, _] = inputs.propagate_steps(&start, offsets, 2, T);
                            (
                                vec![m1, m2],
                                vec![
                                    state_jacobian(start.z, a.x, T),
                                    state_jacobian(m1.z, b.x, T),
                                ],
                            )
                        };
                        let expected = stacked_log_density(&model, &view, &means, &jacobians);
                        assert!(
                            (got - expected).abs() <= 1e-9 * expected.abs().max(1.0),
                            "lag {lag} ρ {rho} pattern {h}: {got} vs {expected}"
                        );
                    }
                }
            }
        }
    }

    fn multilevel_model(levels: u8, dimensions: u8, labeling: Labeling) -> DoubletModel {
        DoubletModel {
            sample_time: T,
            process_covariance: Matrix3::from_diagonal_element(1e-10),
            correlation: 0.0,
            perturbation: Perturbation {
                delta: Unicycle::new(0.035, 0.035),
                bits_per_doublet: dimensions,
                settle: None,
                levels,
                labeling,
            },
            lag: 0.0,
            rounding: None,
        }
    }

    /// The view of pattern `h` without noise (a tiny sensor noise), on a turning segment.
    fn noise_free_view(model: &DoubletModel, inputs: &DoubletInputs, h: usize) -> DoubletView {
        let start = Pose::new(0.3, -0.1, 0.4);
        let [middle, end] = inputs.propagate(&start, model.perturbation.offset(h), T);
        let seen = |pose: Pose| PoseObservation::new(pose, [1e-6, 1e-6, 1e-6]);
        DoubletView {
            start: seen(start),
            middle: Some(seen(middle)),
            late: None,
            end: Some(seen(end)),
            entry: None,
        }
    }

    /// Without noise every symbol of every alphabet, on one and two dimensions, is decided
    /// right from the marginal LLRs, and the staged and chained LLRs agree with the truth.
    #[test]
    fn every_symbol_is_decided_right_without_noise() {
        let inputs = DoubletInputs {
            first: Unicycle::new(0.1, 0.3),
            second: Unicycle::new(0.12, 0.25),
        };
        for levels in [2_u8, 4, 8] {
            for dimensions in [1_u8, 2] {
                for labeling in [Labeling::Natural, Labeling::Gray] {
                    let model = multilevel_model(levels, dimensions, labeling);
                    for h in 0..model.perturbation.patterns() {
                        let view = noise_free_view(&model, &inputs, h);
                        let (evidence, ll) = model.evidence_and_likelihoods(&inputs, &view);
                        assert_eq!(evidence.bits(), h as u64, "{levels} {dimensions} {h}");
                        let word = h as u64;
                        let staged = staged_llrs(&ll, &model.perturbation, word);
                        let chained = model.chain_llrs(&inputs, &view, word);
                        let decided = |llrs: [f64; MAX_BITS]| {
                            BitEvidence {
                                llr: llrs,
                                separation: [0.0; MAX_BITS],
                            }
                            .bits()
                        };
                        assert_eq!(decided(staged), word);
                        assert_eq!(decided(chained), word);
                    }
                }
            }
        }
    }

    /// The separations the alphabet produces, each bit's with the other bits known (the
    /// larger over their values), in units of the lowest bit's: natural labeling 1 and 2
    /// (4 levels) and 1, 2, 4 (8 levels), Gray 1 and 3 (its top bit flips ±3 to ∓3 around
    /// the middle); on two dimensions the ω bits the same pattern again.
    #[test]
    fn each_bits_separation_is_its_labels_distance() {
        let inputs = DoubletInputs {
            first: Unicycle::new(0.1, 0.0),
            second: Unicycle::new(0.1, 0.0),
        };
        let view = noise_free_view(&multilevel_model(2, 1, Labeling::Natural), &inputs, 0);
        let view = DoubletView {
            middle: view
                .middle
                .map(|y| PoseObservation::new(y.value, [0.005; 3])),
            end: view.end.map(|y| PoseObservation::new(y.value, [0.005; 3])),
            ..view
        };
        for (levels, labeling, expected) in [
            (4, Labeling::Natural, vec![1.0, 2.0]),
            (8, Labeling::Natural, vec![1.0, 2.0, 4.0]),
            (4, Labeling::Gray, vec![1.0, 3.0]),
        ] {
            let model = multilevel_model(levels, 1, labeling);
            let d = model.separations(&inputs, &view);
            for (i, ratio) in expected.iter().enumerate() {
                let got = d[i] / d[0];
                assert!(
                    (got - ratio).abs() < 1e-6,
                    "{levels} {labeling:?} bit {i}: {got}"
                );
            }
            // The ω symbol bends the path a little: the v bits' separations barely move.
            let both = multilevel_model(levels, 2, labeling).separations(&inputs, &view);
            let m = expected.len();
            for (i, ratio) in expected.iter().enumerate() {
                assert!((both[i] - d[i]).abs() < 1e-3 * d[i], "{levels} v bit {i}");
                let got = both[m + i] / both[m];
                assert!(
                    (got - ratio).abs() < 1e-3,
                    "{levels} {labeling:?} ω bit {i}: {got}"
                );
            }
            assert!(both[2 * m..].iter().all(|&x| x == 0.0));
        }
    }
}
