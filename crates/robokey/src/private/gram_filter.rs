//! A Kalman filter with one covariance and many means (docs/world.md, "The window
//! smoother"): each column is an observation sequence — the residual of what Eve saw, the
//! effect of a bit — run through the same gains, and the Gram matrix of their whitened
//! innovations is `cᵀ·Σ⁻¹·c'`, with `Σ` the covariance of all the observations. Then
//! `ln p(y | s) = −½·(r − G·s)ᵀΣ⁻¹(r − G·s) − ½·ln det Σ + const` for every bit pattern `s`
//! from one pass.
//!
//! Observations of a step come as a batch conditioned at once in information form: with
//! `J = Σ FᵀR⁻¹F`, `u_c = Σ FᵀR⁻¹y_c`, `S_cc' = Σ y_cᵀR⁻¹y_c'` and the prior `N(m_c, P)`,
//! the posterior is `P⁺ = (I + P·J)⁻¹P`, `m_c⁺ = m_c + P⁺(u_c − J·m_c)`, and the Gram matrix
//! gains `S̃_cc' − ũ_cᵀP⁺ũ_c'` (`ũ_c = u_c − J·m_c`, `S̃` the same quadratic about the
//! means); `ln det Σ` gains `ln det(I + P·J) − Σ ln det R⁻¹`.

use nalgebra::{DMatrix, DVector, Matrix3, Matrix3xX, MatrixXx3, Vector3};

use super::lu::Lu;
use super::product::{product_to, transposed_product_to};

/// The filter's state between observations.
#[derive(Clone, Debug)]
pub struct GramFilter {
    cov: DMatrix<f64>,
    /// One mean per column, `dim × columns`.
    means: DMatrix<f64>,
    gram: DMatrix<f64>,
    log_det: f64,
    batch: Batch,
    /// The batch of the other dimension the state alternates with (augmented within a
    /// step, reduced at its end), kept empty for its return.
    set_aside: Option<Batch>,
    work: Conditioning,
}

/// Work space of [`GramFilter::condition`] and [`GramFilter::transition`], overwritten by
/// each: the same products as allocating ones (`product_to` rounds as `nalgebra`'s `*`), into
/// kept storage, reallocated only when a shape changes.
#[derive(Clone, Debug, Default)]
struct Conditioning {
    /// `J·m` (`dim × columns`), then `ũ = u − J·m`.
    about: DMatrix<f64>,
    /// `uᵀ`, `mᵀ` or `ũᵀ` (`columns × dim`), materialised where a product of them goes to
    /// `matrixmultiply` (`transposed_product_to`).
    transposed: DMatrix<f64>,
    /// `mᵀJ` (`columns × dim`).
    means_information: DMatrix<f64>,
    /// `uᵀm`, `mᵀJm` and `ũᵀ·gain` (`columns × columns`).
    cross: DMatrix<f64>,
    quadratic: DMatrix<f64>,
    reduction: DMatrix<f64>,
    /// `I + P·J`, then its LU factors.
    growth: Lu,
    /// `P⁺` before its symmetrisation (`dim × dim`).
    posterior: DMatrix<f64>,
    /// `P⁺ũ` (`dim × columns`).
    gain: DMatrix<f64>,
    /// `Lᵀ` (`dim × new_dim`) and `L·P` (`new_dim × dim`) of a transition.
    map_transposed: DMatrix<f64>,
    mapped: DMatrix<f64>,
    /// The covariance and means of the previous dimension, the storage the next change of
    /// dimension writes into (then swapped with the state's).
    spare_cov: DMatrix<f64>,
    spare_means: DMatrix<f64>,
}

/// `m` as a `rows × columns` matrix of unspecified values: kept when it has that shape.
fn shaped(m: &mut DMatrix<f64>, rows: usize, columns: usize) -> &mut DMatrix<f64> {
    if m.shape() != (rows, columns) {
        *m = DMatrix::zeros(rows, columns);
    }
    m
}

/// `source` as the top left corner of `target`, zeros elsewhere (`target` has at least as
/// many rows and columns).
fn embed(source: &DMatrix<f64>, target: &mut DMatrix<f64>) {
    let (rows, target_rows) = (source.nrows(), target.nrows());
    if rows == 0 {
        target.fill(0.0);
        return;
    }
    let mut columns = target.as_mut_slice().chunks_exact_mut(target_rows);
    // The source first: `zip` stops on it without taking a column of the target.
    for (from, to) in source.as_slice().chunks_exact(rows).zip(columns.by_ref()) {
        let (top, below) = to.split_at_mut(rows);
        top.copy_from_slice(from);
        below.fill(0.0);
    }
    columns.for_each(|to| to.fill(0.0));
}

/// `(A + Aᵀ)/2` of the `n × n` column-major `a` into `out`: element `(i, j)` is
/// `(a_ij + a_ji)·0.5`, `a_ji` read along row `j`.
fn symmetrised(a: &[f64], n: usize, out: &mut [f64]) {
    let n = n.max(1); // an empty matrix has no columns
    for (j, (out, column)) in out.chunks_exact_mut(n).zip(a.chunks_exact(n)).enumerate() {
        for ((y, &x), &x_t) in out.iter_mut().zip(column).zip(a[j..].iter().step_by(n)) {
            *y = (x + x_t) * 0.5;
        }
    }
}

/// `source`ᵀ into `target`, reshaped as needed.
fn transpose_into(source: &DMatrix<f64>, target: &mut DMatrix<f64>) {
    source.transpose_to(shaped(target, source.ncols(), source.nrows()));
}

/// The observations gathered since the last conditioning: zero when `empty`, and sized for
/// the state by the first observation after a change of its dimension.
#[derive(Clone, Debug)]
struct Batch {
    info: DMatrix<f64>,
    projected: DMatrix<f64>,
    direct: DMatrix<f64>,
    log_det_noise: f64,
    empty: bool,
    /// Work space of one observation, overwritten by each: `Fᵀ`, `FᵀR⁻¹`, `FᵀR⁻¹F`, the
    /// columns' values `y_c` side by side (`3 × columns`), every column's `FᵀR⁻¹y_c` at once
    /// (`dim × columns`) and each column's `R⁻¹y_c` (the same products as allocating ones,
    /// into kept storage).
    transposed: DMatrix<f64>,
    weighted: MatrixXx3<f64>,
    information: DMatrix<f64>,
    values: Matrix3xX<f64>,
    projection: DMatrix<f64>,
    scaled: Vec<Vector3<f64>>,
}

impl Batch {
    fn new(dim: usize, columns: usize) -> Self {
        Self {
            info: DMatrix::zeros(dim, dim),
            projected: DMatrix::zeros(dim, columns),
            direct: DMatrix::zeros(columns, columns),
            log_det_noise: 0.0,
            empty: true,
            transposed: DMatrix::zeros(dim, 3),
            weighted: MatrixXx3::zeros(dim),
            information: DMatrix::zeros(dim, dim),
            values: Matrix3xX::zeros(columns),
            projection: DMatrix::zeros(dim, columns),
            scaled: Vec::with_capacity(columns),
        }
    }

    /// Empties the batch in place after its conditioning.
    fn clear(&mut self) {
        self.info.fill(0.0);
        self.projected.fill(0.0);
        self.direct.fill(0.0);
        self.log_det_noise = 0.0;
        self.empty = true;
    }
}

impl GramFilter {
    /// A filter over a state of prior covariance `cov` (every column's mean zero) with
    /// `columns` observation sequences.
    #[must_use]
    pub fn new(cov: DMatrix<f64>, columns: usize) -> Self {
        let dim = cov.nrows();
        Self {
            means: DMatrix::zeros(dim, columns),
            gram: DMatrix::zeros(columns, columns),
            log_det: 0.0,
            batch: Batch::new(dim, columns),
            set_aside: None,
            work: Conditioning::default(),
            cov,
        }
    }

    /// The state's dimension.
    #[must_use]
    pub fn dim(&self) -> usize {
        self.cov.nrows()
    }

    /// Appends `extra` independent unit-variance variables to the state (zero mean in every
    /// column). Conditions pending observations first.
    pub fn augment(&mut self, extra: usize) {
        self.condition();
        let (dim, columns) = (self.dim(), self.means.ncols());
        let w = &mut self.work;
        let cov = shaped(&mut w.spare_cov, dim + extra, dim + extra);
        embed(&self.cov, cov);
        for i in dim..dim + extra {
            cov[(i, i)] = 1.0;
        }
        std::mem::swap(&mut self.cov, &mut w.spare_cov);
        embed(
            &self.means,
            shaped(&mut w.spare_means, dim + extra, columns),
        );
        std::mem::swap(&mut self.means, &mut w.spare_means);
    }

    /// A three-dimensional observation `y_c = F·x + ε`, `ε ~ N(0, R)`, given by `F`
    /// (`3 × dim`), `R⁻¹` and its value in each column. Kept until [`Self::condition`].
    pub fn observe(
        &mut self,
        f: &Matrix3xX<f64>,
        noise_inverse: &Matrix3<f64>,
        values: &[Vector3<f64>],
    ) {
        let (dim, columns) = (self.dim(), self.means.ncols());
        if self.batch.info.nrows() != dim {
            // Empty (a change of dimension conditions first): set aside for its return.
            let kept = self
                .set_aside
                .take()
                .filter(|b| b.info.nrows() == dim)
                .unwrap_or_else(|| Batch::new(dim, columns));
            self.set_aside = Some(std::mem::replace(&mut self.batch, kept));
        }
        let b = &mut self.batch;
        f.transpose_to(&mut b.transposed);
        product_to(&b.transposed, noise_inverse, &mut b.weighted); // dim × 3
        product_to(&b.weighted, f, &mut b.information);
        b.info += &b.information;
        // `FᵀR⁻¹y_c` of every column in one product: on `nalgebra`'s `gemv` path (an inner
        // dimension of 3) each element is the one the column's own product gives.
        for (mut column, value) in b.values.column_iter_mut().zip(values) {
            column.copy_from(value);
        }
        product_to(&b.weighted, &b.values, &mut b.projection);
        b.projected += &b.projection;
        // `S_cc' += (R⁻¹y_c)·y_c'`, column `c'` of `S` at a time.
        b.scaled.clear();
        b.scaled
            .extend(values.iter().map(|value| noise_inverse * value));
        // Each term `(s₀y₀ + s₁y₁) + s₂y₂`, as `nalgebra`'s three-element `dot` sums it.
        for (other, direct) in values
            .iter()
            .zip(b.direct.as_mut_slice().chunks_exact_mut(columns.max(1)))
        {
            for (entry, scaled) in direct.iter_mut().zip(&b.scaled) {
                *entry += scaled.x * other.x + scaled.y * other.y + scaled.z * other.z;
            }
        }
        b.log_det_noise += noise_inverse.determinant().ln();
        b.empty = false;
    }

    /// Conditions the state on the observations gathered since the last call.
    ///
    /// Each element is computed by the same operations, in the same order, as the
    /// expressions of the module's documentation written with allocating products:
    /// `ũ = u − J·m`, `S̃ = S − uᵀm − (uᵀm)ᵀ + (mᵀJ)m`, `P⁺ = (I + P·J)⁻¹P` symmetrised as
    /// `(P⁺ + P⁺ᵀ)/2`, `gram += S̃ − ũᵀ(P⁺ũ)`, `m += P⁺ũ`.
    pub fn condition(&mut self) {
        if self.batch.empty {
            return;
        }
        let (dim, columns) = (self.dim(), self.means.ncols());
        let (b, w) = (&self.batch, &mut self.work);
        // ũ = u − J·m and S̃ = S − uᵀm − mᵀu + mᵀJm: the batch about the prior means.
        product_to(&b.info, &self.means, shaped(&mut w.about, dim, columns));
        w.about
            .zip_apply(&b.projected, |product, u| *product = u - *product);
        transposed_product_to(
            &b.projected,
            &self.means,
            shaped(&mut w.cross, columns, columns),
            &mut w.transposed,
        );
        transposed_product_to(
            &self.means,
            &b.info,
            shaped(&mut w.means_information, columns, dim),
            &mut w.transposed,
        );
        product_to(
            &w.means_information,
            &self.means,
            shaped(&mut w.quadratic, columns, columns),
        );
        // I + P·J: every element gains `δ_ij`, zeros included, as in the sum of the identity
        // and the product (a rounded sum is the same either way round).
        let growth = w.growth.matrix(dim);
        product_to(&self.cov, &b.info, growth);
        for (j, column) in growth
            .as_mut_slice()
            .chunks_exact_mut(dim.max(1))
            .enumerate()
        {
            for (i, element) in column.iter_mut().enumerate() {
                *element += f64::from(u8::from(i == j));
            }
        }
        w.growth.factor();
        let posterior = shaped(&mut w.posterior, dim, dim);
        posterior.copy_from(&self.cov);
        assert!(
            w.growth.solve_mut(posterior),
            "I + P·J is invertible for P, J positive semi-definite"
        );
        symmetrised(posterior.as_slice(), dim, self.cov.as_mut_slice());
        product_to(&self.cov, &w.about, shaped(&mut w.gain, dim, columns));
        transposed_product_to(
            &w.about,
            &w.gain,
            shaped(&mut w.reduction, columns, columns),
            &mut w.transposed,
        );
        // Element (i, j) gains `((S_ij − X_ij) − X_ji + Q_ij) − R_ij` (`X = uᵀm`, `Q = mᵀJm`,
        // `R = ũᵀP⁺ũ`), column by column, `X_ji` read along row `j`.
        let (cross, stride) = (w.cross.as_slice(), columns.max(1));
        for (j, ((((gram, direct), cross_j), quadratic), reduction)) in self
            .gram
            .as_mut_slice()
            .chunks_exact_mut(stride)
            .zip(b.direct.as_slice().chunks_exact(stride))
            .zip(cross.chunks_exact(stride))
            .zip(w.quadratic.as_slice().chunks_exact(stride))
            .zip(w.reduction.as_slice().chunks_exact(stride))
            .enumerate()
        {
            let row_j = cross[j..].iter().step_by(stride);
            for (((((g, &s), &x), &x_t), &q), &r) in gram
                .iter_mut()
                .zip(direct)
                .zip(cross_j)
                .zip(row_j)
                .zip(quadratic)
                .zip(reduction)
            {
                *g += s - x - x_t + q - r;
            }
        }
        self.means += &w.gain;
        self.log_det += w.growth.determinant().abs().ln() - b.log_det_noise;
        self.batch.clear();
    }

    /// Maps the state through `x ← L·x` (`L` is `new_dim × dim`), conditioning pending
    /// observations first.
    pub fn transition(&mut self, l: &DMatrix<f64>) {
        self.condition();
        let w = &mut self.work;
        let (new_dim, dim) = l.shape();
        let columns = self.means.ncols();
        transpose_into(l, &mut w.map_transposed);
        product_to(l, &self.cov, shaped(&mut w.mapped, new_dim, dim));
        product_to(
            &w.mapped,
            &w.map_transposed,
            shaped(&mut w.spare_cov, new_dim, new_dim),
        );
        std::mem::swap(&mut self.cov, &mut w.spare_cov);
        product_to(l, &self.means, shaped(&mut w.spare_means, new_dim, columns));
        std::mem::swap(&mut self.means, &mut w.spare_means);
    }

    /// Adds a known offset to the state's mean in each column (`offsets` is `dim × columns`):
    /// a deterministic input, e.g. where the path the state deviates from restarts.
    /// Conditions pending observations first.
    pub fn shift(&mut self, offsets: &DMatrix<f64>) {
        self.condition();
        self.means += offsets;
    }

    /// The Gram matrix `cᵀΣ⁻¹c'` of the columns and `ln det Σ` (up to a constant common to
    /// every run with the same observation noises), after conditioning what is pending.
    pub fn finish(mut self) -> (DMatrix<f64>, f64) {
        self.condition();
        (self.gram, self.log_det)
    }
}

/// `ln Σ exp(v)` of a vector, 0-safe for −∞ entries.
#[must_use]
pub fn ln_sum_exp(values: &DVector<f64>) -> f64 {
    let max = values.max();
    if max == f64::NEG_INFINITY {
        return max;
    }
    max + values.iter().map(|v| (v - max).exp()).sum::<f64>().ln()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against the batch formula: the Gram matrix is `Cᵀ(H·P₀·Hᵀ + R)⁻¹C` and the log
    /// determinant `ln det(H·P₀·Hᵀ + R)` for a random linear-Gaussian chain.
    #[test]
    fn the_gram_matrix_and_log_determinant_are_the_batch_ones() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(5);
        let mut normal = || -> f64 { StandardNormal.sample(&mut rng) };
        let (dim, columns, steps) = (4, 3, 3);
        let p0 = {
            let a = DMatrix::from_fn(dim, dim, |_, _| normal());
            &a * a.transpose() + DMatrix::identity(dim, dim) * 0.1
        };
        // x₁ = L·[x₀; e] with one extra unit variable per step; observations of x each step.
        let mut filter = GramFilter::new(p0.clone(), columns);
        // Batch: latent z = [x₀; e₁; e₂; e₃], x_k = M_k z.
        let total = dim + steps;
        let mut m = DMatrix::zeros(dim, total);
        m.view_mut((0, 0), (dim, dim))
            .copy_from(&DMatrix::identity(dim, dim));
        let mut h_rows: Vec<Matrix3xX<f64>> = Vec::new();
        let mut r_blocks: Vec<Matrix3<f64>> = Vec::new();
        let mut values: Vec<Vec<Vector3<f64>>> = Vec::new();
        for k in 0..steps {
            for _ in 0..2 {
                let f = Matrix3xX::from_fn(dim, |_, _| normal());
                let a = Matrix3::from_fn(|_, _| normal());
                let r = a * a.transpose() + Matrix3::identity() * 0.5;
                let vals: Vec<Vector3<f64>> = (0..columns)
                    .map(|_| Vector3::from_fn(|_, _| normal()))
                    .collect();
                filter.observe(&f, &r.try_inverse().unwrap(), &vals);
                h_rows.push(&f * &m);
                r_blocks.push(r);
                values.push(vals);
            }
            filter.augment(1);
            let l = DMatrix::from_fn(dim, dim + 1, |_, _| normal() * 0.5);
            filter.transition(&l);
            let mut stacked = DMatrix::zeros(dim + 1, total);
            stacked.view_mut((0, 0), (dim, total)).copy_from(&m);
            stacked[(dim, dim + k)] = 1.0;
            m = &l * stacked;
        }
        let (gram, log_det) = filter.finish();
        let n = 3 * h_rows.len();
        let mut h = DMatrix::zeros(n, total);
        let mut r = DMatrix::zeros(n, n);
        let mut c = DMatrix::zeros(n, columns);
        for (i, (row, block)) in h_rows.iter().zip(&r_blocks).enumerate() {
            h.view_mut((3 * i, 0), (3, total)).copy_from(row);
            r.view_mut((3 * i, 3 * i), (3, 3)).copy_from(block);
            for (col, value) in values[i].iter().enumerate().take(columns) {
                c.view_mut((3 * i, col), (3, 1)).copy_from(value);
            }
        }
        let mut prior = DMatrix::identity(total, total);
        prior.view_mut((0, 0), (dim, dim)).copy_from(&p0);
        let sigma = &h * prior * h.transpose() + r;
        let expected = c.transpose() * sigma.clone().lu().solve(&c).unwrap();
        assert!(
            (&gram - &expected).amax() < 1e-8 * expected.amax(),
            "{gram} vs {expected}"
        );
        let expected_log_det = sigma.lu().determinant().ln();
        assert!(
            (log_det - expected_log_det).abs() < 1e-8,
            "{log_det} vs {expected_log_det}"
        );
    }
}
