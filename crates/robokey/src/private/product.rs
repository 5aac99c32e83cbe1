//! `C = A·B` for the Gram filter's dynamic matrices, each element rounded as `nalgebra`'s
//! `mul_to` rounds it, without its generic column-by-column path.
//!
//! `nalgebra` (0.35, `gemm` with `α = 1`, `β = 0`) takes one of two paths:
//!
//! - when a dimension is dynamic and `C`'s rows and columns and `A`'s columns all exceed
//!   [`SMALL_DIM`], `matrixmultiply`'s `dgemm`, whose kernel the CPU decides at run time
//!   (with FMA, the AVX-512 and AVX2 kernels: `c_ij = fma(a_i,k−1, b_k−1,j, … fma(a_i0, b_0j,
//!   +0))`, `k` ascending) — computed by `dgemm`'s `Accumulation`, the same chain on this
//!   CPU, where it has one (else `nalgebra`'s);
//! - otherwise column by column (`gemv`): `c_ij = a_i0·b_0j`, then `c_ij = a_ik·b_kj + c_ij`
//!   for `k = 1, 2, …`, each product and each sum rounded, no fused multiply-add (written
//!   `c_ij += a_ik·b_kj` here: a rounded sum is the same either way round).
//!
//! The second path is written here over contiguous columns, with the three-row left factor
//! (a transition's `L`, a three-dimensional state) and the three-term inner dimension (an
//! observation's `Fᵀ·R⁻¹`, a three-dimensional state) held in registers: the same operations
//! in the same order, so the same bits. The dimensions that decide the path are `nalgebra`'s.

use nalgebra::{DMatrix, Dim, Dyn, IsContiguous, Matrix, RawStorage, Storage, StorageMut};

use super::dgemm::Accumulation;

/// `nalgebra`'s threshold: products with every dimension above it go to `matrixmultiply`.
pub const SMALL_DIM: usize = 5;

/// `out = a·b` (`a` is `m × k`, `b` is `k × n`, `out` is `m × n`), bit for bit as
/// `a.mul_to(b, out)`.
///
/// # Panics
///
/// If the shapes do not match.
pub fn product_to<R1, C1, SA, R2, C2, SB, R3, C3, SC>(
    a: &Matrix<f64, R1, C1, SA>,
    b: &Matrix<f64, R2, C2, SB>,
    out: &mut Matrix<f64, R3, C3, SC>,
) where
    R1: Dim,
    C1: Dim,
    R2: Dim,
    C2: Dim,
    R3: Dim,
    C3: Dim,
    SA: Storage<f64, R1, C1> + IsContiguous,
    SB: Storage<f64, R2, C2> + IsContiguous,
    SC: StorageMut<f64, R3, C3> + IsContiguous,
    nalgebra::constraint::ShapeConstraint: nalgebra::constraint::SameNumberOfRows<R3, R1>
        + nalgebra::constraint::SameNumberOfColumns<C3, C2>
        + nalgebra::constraint::AreMultipliable<R1, C1, R2, C2>,
{
    let (m, k) = a.shape();
    let n = b.ncols();
    assert!(
        b.nrows() == k && out.shape() == (m, n),
        "product of {m}×{k} and {}×{n} into {:?}",
        b.nrows(),
        out.shape()
    );
    let dynamic = R1::is::<Dyn>()
        || C1::is::<Dyn>()
        || R2::is::<Dyn>()
        || C2::is::<Dyn>()
        || R3::is::<Dyn>()
        || C3::is::<Dyn>();
    if dynamic && m > SMALL_DIM && n > SMALL_DIM && k > SMALL_DIM {
        match Accumulation::of(k) {
            Some(accumulation) => {
                accumulation.product_to(slice(a), m, k, slice(b), out.as_mut_slice())
            }
            None => a.mul_to(b, out),
        }
        return;
    }
    column_by_column(slice(a), m, k, slice(b), n, out.as_mut_slice());
}

/// `out = aᵀ·b` (`a` is `k × m`, `b` is `k × n`, `out` is `m × n`), bit for bit as `aᵀ`
/// materialised and multiplied by [`product_to`]: on `nalgebra`'s `gemv` path each element is
/// `a_0i·b_0j`, then `a_pi·b_pj +` it for `p = 1, 2, …` — a chain down two contiguous columns,
/// with no transpose; on its `dgemm` path `aᵀ` is written into `spare` first.
///
/// # Panics
///
/// If the shapes do not match.
pub fn transposed_product_to(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    out: &mut DMatrix<f64>,
    spare: &mut DMatrix<f64>,
) {
    let (k, m) = a.shape();
    let n = b.ncols();
    assert!(
        b.nrows() == k && out.shape() == (m, n),
        "product of ({k}×{m})ᵀ and {}×{n} into {:?}",
        b.nrows(),
        out.shape()
    );
    if m > SMALL_DIM && n > SMALL_DIM && k > SMALL_DIM {
        if spare.shape() != (m, k) {
            *spare = DMatrix::zeros(m, k);
        }
        a.transpose_to(spare);
        product_to(spare, b, out);
        return;
    }
    if m == 0 || n == 0 {
        return;
    }
    if k == 0 {
        out.fill(0.0);
        return;
    }
    let (a, b) = (a.as_slice(), b.as_slice());
    if k == 3 {
        for (c, bc) in out
            .as_mut_slice()
            .chunks_exact_mut(m)
            .zip(b.chunks_exact(3))
        {
            for (y, ac) in c.iter_mut().zip(a.chunks_exact(3)) {
                *y = ac[2] * bc[2] + (ac[1] * bc[1] + ac[0] * bc[0]);
            }
        }
        return;
    }
    for (c, bc) in out
        .as_mut_slice()
        .chunks_exact_mut(m)
        .zip(b.chunks_exact(k))
    {
        for (y, ac) in c.iter_mut().zip(a.chunks_exact(k)) {
            let mut sum = ac[0] * bc[0];
            for (&p, &q) in ac.iter().zip(bc).skip(1) {
                sum += p * q;
            }
            *y = sum;
        }
    }
}

/// A contiguous matrix's elements, column after column.
fn slice<R: Dim, C: Dim, S: RawStorage<f64, R, C> + IsContiguous>(
    m: &Matrix<f64, R, C, S>,
) -> &[f64] {
    m.as_slice()
}

/// `nalgebra`'s `gemv` path of `out = a·b` over column-major slices: each element
/// `a_i0·b_0j`, then `a_ik·b_kj +` it for `k = 1, 2, …` (all zero when `k = 0`).
fn column_by_column(a: &[f64], m: usize, k: usize, b: &[f64], n: usize, out: &mut [f64]) {
    if m == 0 || n == 0 {
        return;
    }
    if k == 0 {
        out.fill(0.0);
        return;
    }
    let columns = out.chunks_exact_mut(m).zip(b.chunks_exact(k));
    if m == 3 {
        for (c, bc) in columns {
            let first = bc[0];
            let (mut y0, mut y1, mut y2) = (a[0] * first, a[1] * first, a[2] * first);
            for (ac, &x) in a.chunks_exact(3).zip(bc).skip(1) {
                y0 += ac[0] * x;
                y1 += ac[1] * x;
                y2 += ac[2] * x;
            }
            c.copy_from_slice(&[y0, y1, y2]);
        }
    } else if k == 3 {
        let (a0, rest) = a.split_at(m);
        let (a1, a2) = rest.split_at(m);
        for (c, bc) in columns {
            let (x0, x1, x2) = (bc[0], bc[1], bc[2]);
            for (((y, &p), &q), &r) in c.iter_mut().zip(a0).zip(a1).zip(a2) {
                *y = r * x2 + (q * x1 + p * x0);
            }
        }
    } else {
        for (c, bc) in columns {
            let first = bc[0];
            for (y, &p) in c.iter_mut().zip(&a[..m]) {
                *y = p * first;
            }
            for (ac, &x) in a.chunks_exact(m).zip(bc).skip(1) {
                for (y, &p) in c.iter_mut().zip(ac) {
                    *y += p * x;
                }
            }
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use nalgebra::{DVector, Matrix3, Matrix3xX, MatrixXx3, Vector3};
    use rand::{RngExt, SeedableRng};

    /// Values that exercise the rounding: wide exponents, exact zeros of both signs.
    pub(crate) fn value(rng: &mut rand::rngs::ChaCha8Rng) -> f64 {
        match rng.random_range(0..8) {
            0 => 0.0,
            1 => -0.0,
            _ => (rng.random::<f64>() - 0.5) * 2f64.powi(rng.random_range(-30..30)),
        }
    }

    fn same(x: &[f64], y: &[f64]) -> bool {
        x.len() == y.len() && x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits())
    }

    /// Four products of random factors `a` (`m × k`, or `k × m` where `transposed`) and `b`
    /// (`k × n`) for every `m`, `k`, `n` up to 9: `expected` by `nalgebra`'s `mul_to` of `a`
    /// (transposed first where `transposed`) and `b`, `got` by `product`, compared bit for bit
    /// (signed zeros included).
    fn every_shape_bit_for_bit(
        seed: u64,
        transposed: bool,
        mut product: impl FnMut(&DMatrix<f64>, &DMatrix<f64>, &mut DMatrix<f64>),
    ) {
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(seed);
        for m in 0..=9 {
            for k in 0..=9 {
                for n in 0..=9 {
                    for _ in 0..4 {
                        let (rows, columns) = if transposed { (k, m) } else { (m, k) };
                        let a = DMatrix::from_fn(rows, columns, |_, _| value(&mut rng));
                        let b = DMatrix::from_fn(k, n, |_, _| value(&mut rng));
                        let mut expected = DMatrix::from_element(m, n, f64::NAN);
                        if transposed {
                            a.transpose().mul_to(&b, &mut expected);
                        } else {
                            a.mul_to(&b, &mut expected);
                        }
                        let mut got = DMatrix::from_element(m, n, f64::NAN);
                        product(&a, &b, &mut got);
                        assert!(
                            same(expected.as_slice(), got.as_slice()),
                            "{m}×{k}×{n} (a transposed: {transposed}): {expected} vs {got}"
                        );
                    }
                }
            }
        }
    }

    /// Every shape up to 9 × 9 × 9, on both of `nalgebra`'s paths.
    #[test]
    fn every_element_is_nalgebras_bit_for_bit() {
        every_shape_bit_for_bit(11, false, product_to);
    }

    /// `aᵀ·b` against `a.transpose()` multiplied by `mul_to`, every shape up to 9 × 9 × 9.
    #[test]
    fn a_transposed_product_is_the_transpose_multiplied_bit_for_bit() {
        let mut spare = DMatrix::zeros(0, 0);
        every_shape_bit_for_bit(14, true, |a, b, got| {
            transposed_product_to(a, b, got, &mut spare);
        });
    }

    /// The mixed static and dynamic shapes the filter multiplies.
    #[test]
    fn the_filters_mixed_shapes_are_nalgebras_bit_for_bit() {
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(12);
        for dim in [3, 6, 9, 13] {
            let f = Matrix3xX::from_fn(dim, |_, _| value(&mut rng));
            let noise = Matrix3::from_fn(|_, _| value(&mut rng));
            let v = Vector3::from_fn(|_, _| value(&mut rng));
            let ft = f.transpose();
            let mut w_expected = MatrixXx3::zeros(dim);
            ft.mul_to(&noise, &mut w_expected);
            let mut w = MatrixXx3::zeros(dim);
            product_to(&ft, &noise, &mut w);
            assert!(same(w_expected.as_slice(), w.as_slice()));
            let (mut expected, mut got) = (DMatrix::zeros(dim, dim), DMatrix::zeros(dim, dim));
            w.mul_to(&f, &mut expected);
            product_to(&w, &f, &mut got);
            assert!(same(expected.as_slice(), got.as_slice()));
            let (mut expected, mut got) = (DVector::zeros(dim), DVector::zeros(dim));
            w.mul_to(&v, &mut expected);
            product_to(&w, &v, &mut got);
            assert!(same(expected.as_slice(), got.as_slice()));
        }
    }
}
