//! How far Eve's three-step view of a bit can move over a cell `[τ₀, τ₁]` of the lag's
//! interval (docs/estimation.md, "The lag", item 5): a bound on the separation at every τ
//! of the cell from its value at the cell's centre τ_c, with no assumption on how it bends.
//!
//! **The speeds.** Through a first-order lag a step of command `c` from speed `e` has mean
//! speed `c + (e − c)·b` and ends at `c + (e − c)·a`, `a = e^(−T/τ)`, `b = (τ/T)(1 − a)`.
//! Every step's applied mean speed in Eve's view (the bit's offsets, the nominal inputs'
//! transient from the entry speed, the next doublet's decay of what the bit left) is
//! therefore a polynomial `Σ_m (c_m + c′_m·b)·a^m` with fixed coefficients
//! ([`LagPolynomial`]). `a` and `b` are positive and increase with τ (`b = (1 − e^(−x))/x`,
//! `x = T/τ`, falls with x), so every monomial `a^m`, `a^m·b` does, and each term's range
//! over the cell is between its values at `τ₀` and `τ₁`: the speed's range is within their
//! sum, and `r_u = max(u_hi − u(τ_c), u(τ_c) − u_lo)` bounds `|u(τ) − u(τ_c)|`.
//!
//! **The path.** The Euler map moves a pose by `T·(v cos θ, v sin θ, ω)` at the step's
//! start heading, and `|v sin θ − v_c sin θ_c| ≤ |v − v_c| + |v_c|·|θ − θ_c|` (likewise
//! cos), so from an exactly known start the poses' radii follow
//! `r_θ,k+1 = r_θ,k + T·r_ω,k`, `r_xy,k+1 = r_xy,k + T·(r_v,k + |v_c,k|·r_θ,k)`, and the
//! Jacobians `A_k`' two τ-dependent entries `∓T·v·(sin θ, cos θ)` move by at most
//! `T·(r_v,k + |v_c,k|·r_θ,k)` ([`path_radius`]). Her covariance
//! `S = F·P₀·Fᵀ + G·K·Gᵀ + R` (`F`, `G` products of the `A_k`, `P₀`, `K`, `R` free of τ)
//! is enclosed entrywise by midpoint-radius products: `X ∈ ⟨X_c, r_X⟩`, `Y ∈ ⟨Y_c, r_Y⟩`
//! give `XY ∈ ⟨X_cY_c, |X_c|·r_Y + r_X·|Y_c| + r_X·r_Y⟩` ([`covariance_radius`]).
//!
//! **The means.** The poses move with the speeds by the Euler map's derivative `J` at the
//! centre's path plus a remainder of at most `T·(r_v·r_θ + |v_c|·r_θ²/2)` per step on the
//! positions (none on the heading, linear in the turn rates), and the speeds by
//! `Σᵢ Δfᵢ·Cᵢ` exactly (`Δfᵢ` monomial `i`'s move, `Cᵢ` its coefficients): a bit's
//! difference of two patterns' means is `δ = δ_c + Σᵢ Δfᵢ·wᵢ + e`, `wᵢ = J_a·C_a,i −
//! J_b·C_b,i` ([`monomial_moves`]), every `Δfᵢ` of τ − τ_c's sign ([`monomial_spans`]).
//!
//! **The separation** ([`separation_bound`]). With `|S(τ) − S_c| ≤ r_S` entrywise on the
//! cell, `D = diag(S_c)^(−½)` and `η = λ_max(D·r̄_S·D)/λ_min(D·S_c·D)` (`r̄_S` the larger
//! of `r_S` and its transpose; both bounded by row sums): `xᵀ(S − S_c)x ≥ −|x|ᵀr̄_S|x| ≥
//! −η·xᵀS_c x`, so `S ⪰ (1 − η)·S_c`, and expanding `‖S_c^(−½)δ‖²` (`z = S_c^(−½)δ_c`,
//! `pᵢ = zᵀS_c^(−½)wᵢ`, `r_e = √(ρᵀ|S_c⁻¹|ρ)` with `ρ ≥ |e|`), where `η < 1`,
//!
//! `d(τ)²·(1 − η) ≤ ‖z‖² + 2·(max(Σᵢ upᵢ·pᵢ⁺, Σᵢ downᵢ·pᵢ⁻) + ‖z‖·r_e) + (Σᵢ sᵢ·‖S_c^(−½)wᵢ‖ + r_e)²`
//!
//! (`upᵢ`, `downᵢ` the monomial's span above and below the centre, `sᵢ` the larger);
//! where `η ≥ 1` the cell has no bound (∞: it is split). It also shows `S` positive
//! definite over the whole cell where `S_c` is. The cross term is exact to first order, so
//! the bound exceeds `d`'s largest on the cell only at second order in its width; the cells
//! are split until it lies within a stated slack of what the centres and the interval's
//! ends show (`worst_case`'s `largest_over_lags`). Floating-point rounding is not enclosed
//! (it is 10⁻¹⁶ relative, far below that slack).

use nalgebra::{Cholesky, DMatrix, DVector, Dyn, Matrix3, SMatrix, Vector3};

use crate::model::Unicycle;
use crate::private::DoubletInputs;
use crate::private::likelihood::DoubletModel;

/// Powers of `a` a polynomial holds: `a⁰ … a⁵` (the next doublet's decay of the end speed).
const POWERS: usize = 6;

/// A speed (m/s, rad/s) through a first-order lag τ as a polynomial in `a = e^(−T/τ)` and
/// `b = (τ/T)(1 − a)`: `Σ_m (c_m + c′_m·b)·a^m`, `terms[m] = [c_m, c′_m]`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LagPolynomial {
    terms: [[Unicycle; 2]; POWERS],
}

impl LagPolynomial {
    /// The constant `c`.
    fn constant(c: Unicycle) -> Self {
        let mut terms = [[Unicycle::zeros(); 2]; POWERS];
        terms[0][0] = c;
        Self { terms }
    }

    /// `self + sign·other`. Inlined: left out of line (as the crate's codegen units may
    /// place it) its calls took 6 % of a lagged block's CPU.
    #[inline]
    fn plus(self, other: Self, sign: f64) -> Self {
        Self {
            terms: std::array::from_fn(|m| {
                [0, 1].map(|n| self.terms[m][n] + sign * other.terms[m][n])
            }),
        }
    }

    /// `self·a` (its highest power must be below [`POWERS`] − 1).
    fn times_a(self) -> Self {
        debug_assert!(
            self.terms[POWERS - 1]
                .iter()
                .all(|c| *c == Unicycle::zeros())
        );
        Self {
            terms: std::array::from_fn(|m| {
                if m == 0 {
                    [Unicycle::zeros(); 2]
                } else {
                    self.terms[m - 1]
                }
            }),
        }
    }

    /// `self·b` (`self` must be free of `b`).
    fn times_b(self) -> Self {
        debug_assert!(self.terms.iter().all(|t| t[1] == Unicycle::zeros()));
        Self {
            terms: self.terms.map(|t| [Unicycle::zeros(), t[0]]),
        }
    }

    /// One step of command `command` from speed `start` through the lag: its mean speed
    /// `c + (e − c)·b` and its end speed `c + (e − c)·a` (`start` free of `b`).
    fn lagged(command: Self, start: Self) -> (Self, Self) {
        let gap = start.plus(command, -1.0);
        (
            command.plus(gap.times_b(), 1.0),
            command.plus(gap.times_a(), 1.0),
        )
    }

    /// Each monomial's coefficient, `a^m·b^n` at index `2m + n`.
    pub(crate) fn coefficients(&self) -> [Unicycle; MONOMIALS] {
        std::array::from_fn(|i| self.terms[i / 2][i % 2])
    }

    /// Each component's least and greatest over `[τ₀, τ₁]` (s) with steps of `sample_time`
    /// T (s): each term between its values at the ends (every monomial increases with τ).
    pub(crate) fn range(&self, [low, high]: [f64; 2], sample_time: f64) -> [Unicycle; 2] {
        let ends = [low, high].map(|tau| monomials(tau, sample_time));
        let mut bounds = [Unicycle::zeros(); 2];
        for (i, c) in self.coefficients().iter().enumerate() {
            for axis in 0..2 {
                let [x, y] = ends.map(|f| c[axis] * f[i]);
                bounds[0][axis] += x.min(y);
                bounds[1][axis] += x.max(y);
            }
        }
        bounds
    }
}

/// The monomials of a [`LagPolynomial`]: `a^m·b^n`, `m < POWERS`, `n ∈ {0, 1}`.
pub(crate) const MONOMIALS: usize = 2 * POWERS;

/// Each monomial's value at lag τ (s) with steps of `sample_time` T (s): `a = e^(−T/τ)`,
/// `b = (τ/T)(1 − a)`, both 0 at τ = 0 (no lag).
fn monomials(tau: f64, sample_time: f64) -> [f64; MONOMIALS] {
    let a = if tau > 0.0 {
        (-sample_time / tau).exp()
    } else {
        0.0
    };
    let b = tau / sample_time * (1.0 - a);
    let mut power = 1.0;
    let mut values = [0.0; MONOMIALS];
    for m in 0..POWERS {
        values[2 * m] = power;
        values[2 * m + 1] = power * b;
        power *= a;
    }
    values
}

/// Each monomial's largest move from the centre of `cell` (s) up to its upper end and down
/// to its lower end: `[f(τ₁) − f(τ_c), f(τ_c) − f(τ₀)]`, both ≥ 0 (each increases with τ).
pub(crate) fn monomial_spans([low, high]: [f64; 2], sample_time: f64) -> [[f64; MONOMIALS]; 2] {
    let [f0, fc, f1] = [low, 0.5 * (low + high), high].map(|tau| monomials(tau, sample_time));
    [
        std::array::from_fn(|i| (f1[i] - fc[i]).max(0.0)),
        std::array::from_fn(|i| (fc[i] - f0[i]).max(0.0)),
    ]
}

/// How the poses after a three-step path's steps move with the steps' applied speeds, each
/// monomial's coefficients in `speeds` carried through the Euler map's derivative at the
/// path (`headings` at each step's start, `applied` its speeds, steps of `sample_time` T):
/// column `i` is `J·C_i` (9 rows: the three poses), `J = ∂(poses)/∂(v₀, ω₀, v₁, ω₁, v₂, ω₂)`:
/// `∂(x, y)ₖ/∂vⱼ = T·(cos θⱼ, sin θⱼ)`, `∂(x, y)ₖ/∂ωⱼ = Σ_{j<l<k} T²·vₗ·(−sin θₗ, cos θₗ)`,
/// `∂θₖ/∂ωⱼ = T` (`j < k`, poses after step `k`).
pub(crate) fn monomial_moves(
    headings: [f64; 3],
    applied: &[Unicycle; 3],
    speeds: &[LagPolynomial; 3],
    sample_time: f64,
) -> SMatrix<f64, 9, MONOMIALS> {
    let t = sample_time;
    let mut jacobian = SMatrix::<f64, 9, 6>::zeros();
    for k in 0..3 {
        for j in 0..=k {
            let (sin, cos) = headings[j].sin_cos();
            jacobian[(3 * k, 2 * j)] = t * cos;
            jacobian[(3 * k + 1, 2 * j)] = t * sin;
            jacobian[(3 * k + 2, 2 * j + 1)] = t;
            for l in j + 1..=k {
                let (sin, cos) = headings[l].sin_cos();
                jacobian[(3 * k, 2 * j + 1)] -= t * t * applied[l].x * sin;
                jacobian[(3 * k + 1, 2 * j + 1)] += t * t * applied[l].x * cos;
            }
        }
    }
    let mut coefficients = SMatrix::<f64, 6, MONOMIALS>::zeros();
    for (j, speed) in speeds.iter().enumerate() {
        for (i, c) in speed.coefficients().iter().enumerate() {
            coefficients[(2 * j, i)] = c.x;
            coefficients[(2 * j + 1, i)] = c.y;
        }
    }
    jacobian * coefficients
}

/// The applied mean speeds of a three-step doublet's steps under `pattern` as polynomials
/// of the lag (`DoubletModel::three_step_path`'s): the nominal inputs `[u, u′, u′]` plus the
/// bit's rounded offsets, through the lag from the wheels' `entry` speed where Eve's view
/// knows it; without it the nominal inputs as commanded and the offsets from wheels that
/// carried none.
pub(crate) fn three_step_speeds(
    model: &DoubletModel,
    inputs: &DoubletInputs,
    entry: Option<Unicycle>,
    pattern: usize,
) -> [LagPolynomial; 3] {
    let offsets = model.step_offsets(inputs, Some(pattern));
    let nominal = [inputs.first, inputs.second, inputs.second];
    let constant = LagPolynomial::constant;
    match entry {
        Some(entry) => {
            let mut speed = constant(entry);
            std::array::from_fn(|k| {
                let (mean, end) = LagPolynomial::lagged(constant(nominal[k] + offsets[k]), speed);
                speed = end;
                mean
            })
        }
        None => {
            let mut speed = constant(Unicycle::zeros());
            std::array::from_fn(|k| {
                let (mean, end) = LagPolynomial::lagged(constant(offsets[k]), speed);
                speed = end;
                constant(nominal[k]).plus(mean, 1.0)
            })
        }
    }
}

/// The applied mean speeds of the next doublet's steps (`next_inputs`) under this doublet's
/// (`inputs`) `pattern` as polynomials of the lag (`worst_case`'s `entry_path`): the speed
/// the bit's offsets leave at this doublet's end, decaying through the next three steps,
/// on the next doublet's nominal inputs.
pub(crate) fn entry_speeds(
    model: &DoubletModel,
    inputs: &DoubletInputs,
    next_inputs: &DoubletInputs,
    pattern: usize,
) -> [LagPolynomial; 3] {
    let zero = LagPolynomial::constant(Unicycle::zeros());
    let mut speed = model
        .step_offsets(inputs, Some(pattern))
        .iter()
        .fold(zero, |speed, &c| {
            LagPolynomial::lagged(LagPolynomial::constant(c), speed).1
        });
    let nominal = [next_inputs.first, next_inputs.second, next_inputs.second];
    std::array::from_fn(|k| {
        let (mean, end) = LagPolynomial::lagged(zero, speed);
        speed = end;
        LagPolynomial::constant(nominal[k]).plus(mean, 1.0)
    })
}

/// How far a three-step path from an exactly known start can move over a cell: each pose's
/// radius after each step (m, m, rad) and each step Jacobian's entrywise radius.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PathRadius {
    /// `r` of the poses after steps 1, 2, 3.
    pub poses: [Vector3<f64>; 3],
    /// `r` of `A₀, A₁, A₂`.
    pub jacobians: [Matrix3<f64>; 3],
    /// How far the poses after steps 1, 2, 3 can lie from their first-order move in the
    /// speeds ([`monomial_moves`]): `ρₖ₊₁ = ρₖ + T·(r_v,k·r_θ,k + |v_c,k|·r_θ,k²/2)` on
    /// the positions (`|cos(θ_c + e) − cos θ_c + sin θ_c·e| ≤ e²/2`), 0 on the heading
    /// (linear in the turn rates).
    pub remainders: [Vector3<f64>; 3],
}

/// The radii of a path whose applied speeds at the cell's centre are `applied` and over the
/// cell `cell` (s) are `speeds`, with steps of `sample_time` T (s) (the module's doc).
pub(crate) fn path_radius(
    applied: &[Unicycle; 3],
    speeds: &[LagPolynomial; 3],
    cell: [f64; 2],
    sample_time: f64,
) -> PathRadius {
    let mut pose = Vector3::zeros();
    let mut radius = PathRadius {
        poses: [Vector3::zeros(); 3],
        jacobians: [Matrix3::zeros(); 3],
        remainders: [Vector3::zeros(); 3],
    };
    let mut remainder = Vector3::zeros();
    for k in 0..3 {
        let [low, high] = speeds[k].range(cell, sample_time);
        let c = applied[k];
        let r_u = (high - c).sup(&(c - low)).sup(&Unicycle::zeros());
        let r_move = r_u.x + c.x.abs() * pose.z;
        let bend = sample_time * (r_u.x * pose.z + 0.5 * c.x.abs() * pose.z * pose.z);
        remainder += Vector3::new(bend, bend, 0.0);
        radius.remainders[k] = remainder;
        radius.jacobians[k][(0, 2)] = sample_time * r_move;
        radius.jacobians[k][(1, 2)] = sample_time * r_move;
        pose += sample_time * Vector3::new(r_move, r_move, r_u.y);
        radius.poses[k] = pose;
    }
    radius
}

/// A matrix known to lie within `radius` of `centre`, entry by entry.
type Enclosed<const R: usize, const C: usize> = (SMatrix<f64, R, C>, SMatrix<f64, R, C>);

/// `XY`'s enclosure from `X`'s and `Y`'s: `⟨X_cY_c, |X_c|·r_Y + r_X·|Y_c| + r_X·r_Y⟩`.
fn product<const R: usize, const M: usize, const C: usize>(
    (x, rx): &Enclosed<R, M>,
    (y, ry): &Enclosed<M, C>,
) -> Enclosed<R, C> {
    (x * y, x.abs() * ry + rx * y.abs() + rx * ry)
}

/// The entrywise radius of `F·P₀·Fᵀ + G·K·Gᵀ` (9×9, the three poses after the steps) over
/// a cell, from the steps' Jacobians at its centre `jacobians` and their radii `radius`,
/// the start's covariance `start_covariance` and the steps' `k` (both free of τ): `F`
/// stacks `A₀, A₁A₀, A₂A₁A₀`, `G`'s block `(i, j < i)` is `Aᵢ ⋯ Aⱼ₊₁`, `Gᵢᵢ = I`.
pub(crate) fn covariance_radius(
    jacobians: &[Matrix3<f64>; 3],
    radius: &[Matrix3<f64>; 3],
    start_covariance: &Matrix3<f64>,
    k: &SMatrix<f64, 9, 9>,
) -> SMatrix<f64, 9, 9> {
    let mut f: Enclosed<9, 3> = (SMatrix::zeros(), SMatrix::zeros());
    let mut g: Enclosed<9, 9> = (SMatrix::identity(), SMatrix::zeros());
    let mut through: Enclosed<3, 3> = (Matrix3::identity(), Matrix3::zeros());
    for i in 0..3 {
        through = product(&(jacobians[i], radius[i]), &through);
        f.0.fixed_view_mut::<3, 3>(3 * i, 0).copy_from(&through.0);
        f.1.fixed_view_mut::<3, 3>(3 * i, 0).copy_from(&through.1);
        let mut carried: Enclosed<3, 3> = (Matrix3::identity(), Matrix3::zeros());
        for j in (0..i).rev() {
            carried = product(&carried, &(jacobians[j + 1], radius[j + 1]));
            g.0.fixed_view_mut::<3, 3>(3 * i, 3 * j)
                .copy_from(&carried.0);
            g.1.fixed_view_mut::<3, 3>(3 * i, 3 * j)
                .copy_from(&carried.1);
        }
    }
    let transpose = |(c, r): &Enclosed<9, 3>| -> Enclosed<3, 9> { (c.transpose(), r.transpose()) };
    let start = product(
        &product(&f, &(*start_covariance, Matrix3::zeros())),
        &transpose(&f),
    );
    let steps = product(
        &product(&g, &(*k, SMatrix::zeros())),
        &(g.0.transpose(), g.1.transpose()),
    );
    start.1 + steps.1
}

/// One pattern's view at a cell's centre, with what bounds it over the cell: its
/// covariance `S_c` factored, `|S_c⁻¹|`, `η` (`S ⪰ (1 − η)·S_c` on the cell), each
/// monomial's move of its mean per unit (`moves`, n × [`MONOMIALS`]) and its remainders.
pub(crate) struct CentredView {
    factor: Cholesky<f64, Dyn>,
    inverse: DMatrix<f64>,
    eta: f64,
    moves: DMatrix<f64>,
    remainder: DVector<f64>,
}

impl CentredView {
    /// The view of covariance `covariance` at the centre, within `covariance_radius`
    /// entrywise over the cell, its mean moving by `moves` per unit of each monomial within
    /// `remainder`; `None` where `S_c` is not positive definite. `η` from norms that bound
    /// the eigenvalues (`D = diag(S_c)^(−½)`, `r̄` the larger of the radius and its
    /// transpose): `λ_max(D·r̄·D) ≤ ‖D·r̄·D‖_∞` (row sums, entries ≥ 0) and
    /// `1/λ_min(D·S_c·D) ≤ ‖D⁻¹·S_c⁻¹·D⁻¹‖_∞` (symmetric).
    pub(crate) fn new(
        covariance: &DMatrix<f64>,
        covariance_radius: &DMatrix<f64>,
        moves: DMatrix<f64>,
        remainder: DVector<f64>,
    ) -> Option<Self> {
        let factor = Cholesky::new(covariance.clone())?;
        let inverse = factor.inverse().abs();
        let scale = covariance.diagonal().map(f64::sqrt);
        let row_sums = |m: &DMatrix<f64>, by: &dyn Fn(usize, usize) -> f64| {
            (0..m.nrows())
                .map(|i| (0..m.ncols()).map(|j| m[(i, j)] * by(i, j)).sum::<f64>())
                .fold(0.0, f64::max)
        };
        let radius = covariance_radius.sup(&covariance_radius.transpose());
        let spread = row_sums(&radius, &|i, j| 1.0 / (scale[i] * scale[j]));
        let precision = row_sums(&inverse, &|i, j| scale[i] * scale[j]);
        Some(Self {
            factor,
            inverse,
            eta: spread * precision,
            moves,
            remainder,
        })
    }

    /// The view of covariance `covariance` at a point (a cell of no width: nothing moves);
    /// `None` where it is not positive definite.
    pub(crate) fn point(covariance: &DMatrix<f64>) -> Option<Self> {
        Some(Self {
            factor: Cholesky::new(covariance.clone())?,
            inverse: DMatrix::zeros(0, 0),
            eta: 0.0,
            moves: DMatrix::zeros(covariance.nrows(), 0),
            remainder: DVector::zeros(0),
        })
    }
}

/// The separation of pattern `b`'s mean from `a`'s in `a`'s view at the cell's centre,
/// `d_c = ‖z‖`, `z = S_c^(−½)δ_c` (`difference` = `δ_c`), and its bound over the cell:
/// with `δ = δ_c + Σᵢ Δfᵢ·wᵢ + e` (`wᵢ` the difference of the two patterns' `moves`,
/// `Δfᵢ` monomial `i`'s move, all of τ − τ_c's sign, within `spans`' up and down, `|e|` at
/// most the remainders' sum `ρ`),
///
/// `d(τ)²·(1 − η) ≤ d_c² + 2·(c + d_c·r_e) + (Σᵢ sᵢ·‖S_c^(−½)wᵢ‖ + r_e)²`,
///
/// `c = max(Σᵢ upᵢ·max(pᵢ, 0), Σᵢ downᵢ·max(−pᵢ, 0))`, `pᵢ = zᵀS_c^(−½)wᵢ`, `sᵢ` the larger
/// span, `r_e = √(ρᵀ|S_c⁻¹|ρ)` (expanding `‖S_c^(−½)δ‖²`, Cauchy–Schwarz on the cross
/// term's remainder and the triangle inequality on the square): the cross term is exact
/// to first order, so the bound exceeds `d`'s largest over the cell only at second order
/// in its width. ∞ where `η ≥ 1`.
pub(crate) fn separation_bound(
    a: &CentredView,
    b: &CentredView,
    difference: &DVector<f64>,
    [up, down]: &[[f64; MONOMIALS]; 2],
) -> [f64; 2] {
    let centre = a.factor.solve(difference).dot(difference).sqrt();
    if a.moves.ncols() == 0 || b.moves.ncols() == 0 {
        return [centre; 2];
    }
    let Some(z) = a.factor.l().solve_lower_triangular(difference) else {
        return [centre, f64::INFINITY];
    };
    let Some(whitened) = a.factor.l().solve_lower_triangular(&(&a.moves - &b.moves)) else {
        return [centre, f64::INFINITY];
    };
    let remainder = &a.remainder + &b.remainder;
    let bent = (remainder.transpose() * &a.inverse * &remainder)[(0, 0)].sqrt();
    let (mut rising, mut falling, mut linear) = (0.0, 0.0, 0.0);
    for i in 0..MONOMIALS {
        if up[i] == 0.0 && down[i] == 0.0 {
            continue;
        }
        let w = whitened.column(i);
        let p = z.dot(&w);
        rising += up[i] * p.max(0.0);
        falling += down[i] * (-p).max(0.0);
        linear += up[i].max(down[i]) * w.norm();
    }
    let square = centre * centre
        + 2.0 * (rising.max(falling) + centre * bent)
        + (linear + bent) * (linear + bent);
    let bound = if (0.0..1.0).contains(&a.eta) {
        (square / (1.0 - a.eta)).sqrt()
    } else {
        f64::INFINITY
    };
    [centre, bound.max(centre)]
}

/// Over the observed poses (`observed`: their indices among the three), stacked: each
/// monomial's move (`moves`' rows), the remainders ([`PathRadius::remainders`]), and her
/// covariance's radius from the 9×9 one (her observation noises are free of τ).
pub(crate) fn observed_radius(
    moves: &SMatrix<f64, 9, MONOMIALS>,
    radius: &PathRadius,
    covariance: &SMatrix<f64, 9, 9>,
    observed: &[usize],
) -> (DMatrix<f64>, DVector<f64>, DMatrix<f64>) {
    let n = 3 * observed.len();
    let mut moved = DMatrix::zeros(n, MONOMIALS);
    let mut remainder = DVector::zeros(n);
    let mut s = DMatrix::zeros(n, n);
    for (row, &i) in observed.iter().enumerate() {
        moved
            .fixed_view_mut::<3, MONOMIALS>(3 * row, 0)
            .copy_from(&moves.fixed_view::<3, MONOMIALS>(3 * i, 0));
        remainder
            .fixed_rows_mut::<3>(3 * row)
            .copy_from(&radius.remainders[i]);
        for (col, &j) in observed.iter().enumerate() {
            s.fixed_view_mut::<3, 3>(3 * row, 3 * col)
                .copy_from(&covariance.fixed_view::<3, 3>(3 * i, 3 * j));
        }
    }
    (moved, remainder, s)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A speed's range over a cell holds it at each of 201 lags of the cell: three steps'
    /// mean speeds from an entry speed and three more decaying after them, on cells near 0,
    /// around 50 ms and wide.
    #[test]
    fn a_speeds_range_holds_it_over_the_cell() {
        let constant = |v: f64, w: f64| LagPolynomial::constant(Unicycle::new(v, w));
        let mut speed = constant(0.09, 0.5);
        let mut means = Vec::new();
        for command in [
            constant(0.12, 0.3),
            constant(0.05, 0.6),
            constant(0.1, 0.2),
            constant(0.0, 0.0),
            constant(0.0, 0.0),
            constant(0.0, 0.0),
        ] {
            let (mean, end) = LagPolynomial::lagged(command, speed);
            means.push(mean);
            speed = end;
        }
        for [low, high] in [[0.0, 0.03], [0.045, 0.055], [0.1, 0.4]] {
            for mean in &means {
                let [least, greatest] = mean.range([low, high], 0.2);
                for i in 0..=200 {
                    let tau = low + (high - low) * f64::from(i) / 200.0;
                    let [at, _] = mean.range([tau; 2], 0.2);
                    for axis in 0..2 {
                        assert!(
                            least[axis] - 1e-15 <= at[axis] && at[axis] <= greatest[axis] + 1e-15,
                            "τ {tau}: {at} outside [{least}, {greatest}]"
                        );
                    }
                }
            }
        }
    }
}
