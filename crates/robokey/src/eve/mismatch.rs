//! The paper's model mismatch (docs/protocol.md): Eve knows `r, D, W, V` up to relative errors.

use rand::{Rng, RngExt};

use crate::config::Draw;

/// Eve's relative model errors (fractions: 0.1 = 10 %).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ModelErrors {
    /// Error on the wheel radius `r`.
    pub r: f64,
    /// Error on the axle length `D`.
    pub d: f64,
    /// Error on the process covariance `W`.
    pub w: f64,
    /// Error on the measurement covariance `V`.
    pub v: f64,
}

impl ModelErrors {
    /// Draws `e = α·u`, `u ~ U[−1, 1]`, in the order r, D, W, V (one draw for all with
    /// [`Draw::Common`]).
    pub fn draw<R: Rng + ?Sized>(alpha: f64, draw: Draw, rng: &mut R) -> Self {
        let mut next = || alpha * rng.random_range(-1.0..=1.0);
        match draw {
            Draw::Independent => Self {
                r: next(),
                d: next(),
                w: next(),
                v: next(),
            },
            Draw::Common => {
                let e = next();
                Self {
                    r: e,
                    d: e,
                    w: e,
                    v: e,
                }
            }
        }
    }
}
