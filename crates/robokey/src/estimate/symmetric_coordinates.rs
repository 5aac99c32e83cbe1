//! A symmetric 3×3 matrix as its six coordinates (the diagonal, then the upper triangle):
//! the parameters the motion-noise and slip fits solve for.

use nalgebra::{Matrix3, Vector6};

/// The entries `(i, j)` of a symmetric 3×3 matrix, in the order of its six coordinates.
pub(super) const ENTRIES: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];

/// The six coordinates of `m`'s symmetric part.
pub(super) fn coordinates(m: &Matrix3<f64>) -> Vector6<f64> {
    Vector6::from_iterator(ENTRIES.iter().map(|&(i, j)| 0.5 * (m[(i, j)] + m[(j, i)])))
}

/// The symmetric matrix with coordinates `q`.
pub(super) fn symmetric(q: &Vector6<f64>) -> Matrix3<f64> {
    let mut m = Matrix3::zeros();
    for (&(i, j), &v) in ENTRIES.iter().zip(q.iter()) {
        m[(i, j)] = v;
        m[(j, i)] = v;
    }
    m
}
