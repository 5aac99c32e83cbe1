//! The LU factorisation with partial pivoting of a square matrix in kept storage, each
//! number rounded as `nalgebra`'s `LU` (0.35) rounds it: the Gram filter's conditioning
//! factors `I + P·J` once per batch of observations, and `nalgebra`'s generic views cost more
//! than the arithmetic at its sizes (3 to 15).
//!
//! The operations, in `nalgebra`'s order: for each column `i`, the pivot is the first row
//! `r ≥ i` of largest `|a_ri|`; a zero pivot leaves the column as it is; otherwise the rows
//! `i` and `r` swap in every column, the multipliers below it are `a_ri · (1 / a_ii)`, and each
//! later column `k` gains `(−a_ik)·m_r + a_rk` row by row. Solving `A·X = B` swaps `B`'s rows
//! in the same order, then forward substitution with the unit lower factor (`b_r` gains
//! `(−b_i)·l_ri + b_r`) and back substitution with the upper one (`b_i ← b_i / u_ii`, then
//! `b_r` gains `(−b_i)·u_ri + b_r` for `r < i`); the determinant is
//! `((1·u_00)·u_11)·…`, negated for an odd number of swaps.

use nalgebra::DMatrix;

/// A square matrix's LU factors and its row swaps, overwritten by each [`Lu::factor`].
#[derive(Clone, Debug, Default)]
pub struct Lu {
    /// The matrix to factor, then its factors: `L` below the diagonal (unit diagonal
    /// implied), `U` on and above it.
    matrix: DMatrix<f64>,
    /// The row swaps `(i, r)` in the order they were made.
    swaps: Vec<(usize, usize)>,
}

impl Lu {
    /// The matrix to factor, `dim × dim`, its elements unspecified: to be written before
    /// [`Self::factor`].
    pub fn matrix(&mut self, dim: usize) -> &mut DMatrix<f64> {
        if self.matrix.shape() != (dim, dim) {
            self.matrix = DMatrix::zeros(dim, dim);
        }
        &mut self.matrix
    }

    /// Factors the matrix in place.
    pub fn factor(&mut self) {
        let n = self.matrix.nrows();
        let a = self.matrix.as_mut_slice();
        self.swaps.clear();
        for i in 0..n {
            let column = &a[i * n..(i + 1) * n];
            let mut pivot = i;
            let mut largest = column[i].abs();
            for (r, value) in column.iter().enumerate().skip(i + 1) {
                if value.abs() > largest {
                    largest = value.abs();
                    pivot = r;
                }
            }
            let diag = column[pivot];
            if diag == 0.0 {
                continue;
            }
            if pivot != i {
                self.swaps.push((i, pivot));
                for k in 0..n {
                    a.swap(i + k * n, pivot + k * n);
                }
            }
            let inverse = 1.0 / diag;
            let (done, later) = a.split_at_mut((i + 1) * n);
            let multipliers = &mut done[i * n + i + 1..];
            for m in multipliers.iter_mut() {
                *m *= inverse;
            }
            for column in later.chunks_exact_mut(n) {
                let (top, below) = column.split_at_mut(i + 1);
                let scale = -top[i];
                for (y, &m) in below.iter_mut().zip(&*multipliers) {
                    *y += scale * m;
                }
            }
        }
    }

    /// Overwrites `b` (`dim × columns`) with `A⁻¹·b`; false if `U` has a zero on its
    /// diagonal (`A` singular), `b` then partly solved.
    pub fn solve_mut(&self, b: &mut DMatrix<f64>) -> bool {
        let n = self.matrix.nrows();
        assert_eq!(b.nrows(), n, "LU solve of {n} rows against {}", b.nrows());
        let a = self.matrix.as_slice();
        for &(i, r) in &self.swaps {
            b.swap_rows(i, r);
        }
        for column in b.as_mut_slice().chunks_exact_mut(n) {
            for (i, factor) in a.chunks_exact(n).enumerate().take(n.saturating_sub(1)) {
                let (top, below) = column.split_at_mut(i + 1);
                let scale = -top[i];
                for (y, &l) in below.iter_mut().zip(&factor[i + 1..]) {
                    *y += scale * l;
                }
            }
        }
        for column in b.as_mut_slice().chunks_exact_mut(n) {
            for (i, factor) in a.chunks_exact(n).enumerate().rev() {
                let diag = factor[i];
                if diag == 0.0 {
                    return false;
                }
                let (above, rest) = column.split_at_mut(i);
                let value = rest[0] / diag;
                rest[0] = value;
                let scale = -value;
                for (y, &u) in above.iter_mut().zip(&factor[..i]) {
                    *y += scale * u;
                }
            }
        }
        true
    }

    /// The determinant of the factored matrix.
    #[must_use]
    pub fn determinant(&self) -> f64 {
        let n = self.matrix.nrows();
        let a = self.matrix.as_slice();
        let sign = if self.swaps.len().is_multiple_of(2) {
            1.0
        } else {
            -1.0
        };
        (0..n).fold(1.0, |product, i| product * a[i + i * n]) * sign
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    fn same(x: &[f64], y: &[f64]) -> bool {
        x.len() == y.len() && x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits())
    }

    /// Against `nalgebra`'s `LU` bit for bit — solutions, determinants, and whether it
    /// solved — on random matrices of every size from 1 to 12, with ties, zero columns and
    /// singular ones among them.
    #[test]
    fn factors_solutions_and_determinants_are_nalgebras_bit_for_bit() {
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(13);
        let mut lu = Lu::default();
        for n in 1..=12 {
            for trial in 0..200 {
                let mut value = || match rng.random_range(0..10) {
                    0 => 0.0,
                    1 => -0.0,
                    2 => 1.0,
                    3 => -1.0,
                    _ => (rng.random::<f64>() - 0.5) * 2f64.powi(rng.random_range(-20..20)),
                };
                let mut a = DMatrix::from_fn(n, n, |_, _| value());
                if trial % 10 == 0 && n > 1 {
                    a.column_mut(trial % n).fill(0.0);
                }
                let b = DMatrix::from_fn(n, 1 + trial % 4, |_, _| value());
                let expected = a.clone().lu();
                let mut solved = b.clone();
                let ok = expected.solve_mut(&mut solved);
                lu.matrix(n).copy_from(&a);
                lu.factor();
                let mut got = b.clone();
                assert_eq!(lu.solve_mut(&mut got), ok, "{n}: {a}");
                if ok {
                    assert!(same(solved.as_slice(), got.as_slice()), "{n}: {a}");
                }
                let (d, e) = (expected.determinant(), lu.determinant());
                assert_eq!(d.to_bits(), e.to_bits(), "{n}: {a}: {d} vs {e}");
            }
        }
    }
}
