//! The covariance-pair bound against Eve's exact posterior on small patterns of bits whose
//! two-dimensional observation has a covariance that depends on the bit (per-wheel slip: the
//! bit sets the wheels' travel, hence the spread and its direction).
//!
//! Bit `i = ±1` is seen through `y_i ~ N(s_i·m, Σ_{s_i})` (two observations, correlated, the
//! covariance of each value its own), independently across bits. Her exact posterior of the
//! string is the product of the bits' exact posteriors, so her surprisal of the true string
//! `−log₂ P(x|y)` is exact on every draw. The bound sizes the bits with their
//! [`CovariancePair`] views and must keep `P[−log₂ P(x|y) < t] ≤ ε` (over the draws, at a 3σ
//! binomial margin) and `P_guess ≤ 2^{−t} + ε`; the equal-covariance Gaussian view of the
//! same means (the spread's information left out) over-claims, and is caught.

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use robokey_secrecy::covariance_pair::{
    Coordinate, CovariancePair, PairedBit, paired_smooth_min_entropy,
};
use robokey_secrecy::view_profile::{BitView, ViewGroup, profile_smooth_min_entropy};

/// A symmetric 2×2 matrix `[[a, b], [b, c]]`.
#[derive(Clone, Copy)]
struct Sym {
    a: f64,
    b: f64,
    c: f64,
}

impl Sym {
    fn det(self) -> f64 {
        self.a * self.c - self.b * self.b
    }

    /// `vᵀ S⁻¹ v`.
    fn quadratic_inverse(self, v: [f64; 2]) -> f64 {
        (self.c * v[0] * v[0] - 2.0 * self.b * v[0] * v[1] + self.a * v[1] * v[1]) / self.det()
    }

    /// The lower Cholesky factor `[[l11, 0], [l21, l22]]`.
    fn cholesky(self) -> [f64; 3] {
        let l11 = self.a.sqrt();
        let l21 = self.b / l11;
        [l11, l21, (self.c - l21 * l21).sqrt()]
    }
}

/// One bit's two values: means `∓m`, covariances `minus`, `plus`.
struct BitPair {
    m: [f64; 2],
    minus: Sym,
    plus: Sym,
}

impl BitPair {
    fn log_density(&self, y: [f64; 2], value: f64) -> f64 {
        let (mean, s) = if value > 0.0 {
            (self.m, self.plus)
        } else {
            (self.m.map(|v| -v), self.minus)
        };
        let r = [y[0] - mean[0], y[1] - mean[1]];
        -0.5 * s.quadratic_inverse(r) - 0.5 * s.det().ln()
    }

    fn draw(&self, value: f64, rng: &mut ChaCha8Rng) -> [f64; 2] {
        let (mean, s) = if value > 0.0 {
            (self.m, self.plus)
        } else {
            (self.m.map(|v| -v), self.minus)
        };
        let [l11, l21, l22] = s.cholesky();
        let z: [f64; 2] = [StandardNormal.sample(rng), StandardNormal.sample(rng)];
        [mean[0] + l11 * z[0], mean[1] + l21 * z[0] + l22 * z[1]]
    }

    /// The pair diagonalised together: whitened by `minus` (`L⁻¹`), rotated onto the
    /// eigenvectors of `L⁻¹·plus·L⁻ᵀ`.
    fn covariance_pair(&self) -> CovariancePair {
        let [l11, l21, l22] = self.minus.cholesky();
        let inverse = |v: [f64; 2]| [v[0] / l11, (v[1] - l21 * v[0] / l11) / l22];
        // C = L⁻¹·plus·L⁻ᵀ, column by column.
        let p = self.plus;
        let c0 = inverse([p.a, p.b]);
        let c1 = inverse([p.b, p.c]);
        let row0 = inverse([c0[0], c1[0]]);
        let row1 = inverse([c0[1], c1[1]]);
        let c = Sym {
            a: row0[0],
            b: 0.5 * (row0[1] + row1[0]),
            c: row1[1],
        };
        let half_trace = 0.5 * (c.a + c.c);
        let root = (0.25 * (c.a - c.c).powi(2) + c.b * c.b).sqrt();
        let eigenvalues = [half_trace + root, half_trace - root];
        let angle = 0.5 * (2.0 * c.b).atan2(c.a - c.c);
        let vectors = [[angle.cos(), angle.sin()], [-angle.sin(), angle.cos()]];
        let shift = inverse([2.0 * self.m[0], 2.0 * self.m[1]]);
        CovariancePair::new((0..2).map(|k| Coordinate {
            shift: vectors[k][0] * shift[0] + vectors[k][1] * shift[1],
            variance: eigenvalues[k],
        }))
        .unwrap()
    }
}

/// Draws below the bound that still hold at ε, at a 3σ binomial margin.
fn allowed(epsilon: f64, draws: usize) -> f64 {
    let m = draws as f64;
    epsilon * m + 3.0 * (epsilon * (1.0 - epsilon) * m).sqrt()
}

/// Over `draws` seeded draws of the bits: how many had a surprisal below `t`, and the mean
/// and standard error of her guess probability.
fn exact(bits: &[BitPair], t: f64, draws: usize) -> (usize, f64, f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(2023);
    let (mut below, mut sum, mut sum_sq) = (0, 0.0, 0.0);
    for _ in 0..draws {
        let (mut surprisal, mut ln_guess) = (0.0, 0.0);
        for bit in bits {
            let value = if rng.random_range(0..2_u32) == 1 {
                1.0
            } else {
                -1.0
            };
            let y = bit.draw(value, &mut rng);
            let (own, other) = (bit.log_density(y, value), bit.log_density(y, -value));
            let top = own.max(other);
            let normaliser = top + ((own - top).exp() + (other - top).exp()).ln();
            surprisal += (normaliser - own) / std::f64::consts::LN_2;
            ln_guess += top - normaliser;
        }
        below += usize::from(surprisal < t);
        let guess = ln_guess.exp();
        sum += guess;
        sum_sq += guess * guess;
    }
    let m = draws as f64;
    let mean = sum / m;
    (
        below,
        mean,
        ((sum_sq / m - mean * mean) / m).max(0.0).sqrt(),
    )
}

/// λ log-spaced over [10⁻³, 10]: the bound at its best among them.
fn lambdas() -> Vec<f64> {
    (0..60)
        .map(|i| 10f64.powf(-3.0 + 4.0 * f64::from(i) / 59.0))
        .collect()
}

/// Twelve bits, the spread growing with the bit's travel along its direction and turning;
/// three shapes of pair.
fn pattern(shift: f64, spread: f64) -> Vec<BitPair> {
    (0..12)
        .map(|i| {
            let turn = 0.3 * f64::from(i % 3);
            let grow = 1.0 + spread * (1.0 + 0.5 * f64::from(i % 2));
            BitPair {
                m: [shift * turn.cos(), shift * turn.sin()],
                minus: Sym {
                    a: 1.0,
                    b: 0.2,
                    c: 1.0,
                },
                plus: Sym {
                    a: grow * grow,
                    b: 0.2 * grow + 0.3 * spread,
                    c: 1.0 + spread,
                },
            }
        })
        .collect()
}

#[test]
fn the_covariance_pair_bound_holds_against_the_exact_posterior() {
    for (shift, spread) in [(0.3, 0.6), (0.5, 1.5), (0.2, 3.0)] {
        let bits = pattern(shift, spread);
        let views: Vec<PairedBit> = bits.iter().map(|b| vec![b.covariance_pair()]).collect();
        for epsilon in [0.05, 0.2] {
            let t = paired_smooth_min_entropy(&views, 0, epsilon, &lambdas())
                .unwrap()
                .h_min;
            assert!(t > 0.0, "{shift} {spread}: the bound claims nothing");
            let draws = 4_000;
            let (below, guess, se) = exact(&bits, t, draws);
            assert!(
                below as f64 <= allowed(epsilon, draws),
                "shift {shift} spread {spread} ε {epsilon}: {below} of {draws} below t = {t:.3}"
            );
            assert!(
                guess - 3.0 * se <= (-t).exp2() + epsilon,
                "shift {shift} spread {spread}: P_guess {guess:.4} ± {se:.4} > 2^−t + ε"
            );
        }
    }
}

/// The Gaussian view of the means alone (the first value's covariance, as an
/// equal-covariance sizing would take it) leaves out what the spread tells her: caught.
#[test]
fn the_equal_covariance_view_over_claims_and_is_caught() {
    let bits = pattern(0.2, 3.0);
    let groups: Vec<ViewGroup> = bits
        .iter()
        .map(|b| ViewGroup {
            view: BitView::Gaussian {
                separation: b
                    .minus
                    .quadratic_inverse([2.0 * b.m[0], 2.0 * b.m[1]])
                    .sqrt(),
            },
            bits: 1,
        })
        .collect();
    let t = profile_smooth_min_entropy(&groups, 0.05).unwrap().h_min;
    let draws = 3_000;
    let (below, _, _) = exact(&bits, t, draws);
    assert!(
        below as f64 > allowed(0.05, draws),
        "the over-claim t = {t:.3} was not caught ({below} of {draws} below)"
    );
}
