//! The per-bit min-entropy bound against Eve's exact posterior on small patterns.
//!
//! Eve sees `y = Σ_i x_i·h_i + w` for uniform bits `x_i = ±1`: each bit moves some
//! observations (`h_i`: its own, and under lag the next one's), the noise `w` is AR(1) along
//! the observations (coefficient ρ) and, under slip, its spread depends on the bit
//! (`σ_j = 1 + κ·x_j`). For every draw her posterior over all `2ⁿ` strings is computed
//! exactly, hence her surprisal of the true string `−log₂ P(x|y)` and her optimal guess
//! probability `max_x P(x|y)`. The bound sizes the bits with their *genie* views (each bit's
//! view with every other bit given: `d_i = ‖W·2h_i‖`, `W` the noise's whitening), as the
//! sizing does, and must keep
//! - `P[−log₂ P(x|y) < t] ≤ ε`: the event the bound removes by smoothing, counted over the
//!   draws, at most `ε·M + 3·√(ε(1 − ε)·M)` of `M` draws (a 3σ binomial margin);
//! - `P_guess ≤ 2^{−t} + ε` (an ε-smoothed string is guessed at most ε less often), with the
//!   guess probability's mean less 3 standard errors.
//!
//! A bound that over-claims fails the first: the marginal separations of correlated bits
//! (each bit's view without its neighbours) and half the genie separations are shown to.

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use robokey_secrecy::view_profile::{BitView, ViewGroup, profile_smooth_min_entropy};

/// A small pattern of bits and the noise Eve sees them through.
struct Pattern {
    /// Each bit's effect on the observations: `(observation, amount)` pairs.
    effects: Vec<Vec<(usize, f64)>>,
    /// Observations.
    observations: usize,
    /// AR(1) coefficient of the noise along the observations.
    rho: f64,
    /// Slip: observation `j`'s noise spread is `1 + κ·x_j` (observation `j` belongs to bit
    /// `j`); 0 for none.
    slip: f64,
}

/// What the exact posterior gave over the draws.
struct Exact {
    /// Draws whose surprisal of the true string was below the bound.
    below: usize,
    /// Draws.
    draws: usize,
    /// Mean and standard error of `max_x P(x|y)`.
    guess: (f64, f64),
}

impl Pattern {
    /// `amount` on each bit's own observation, `carry` on the next one (lag), white or
    /// AR(1) noise, slip κ.
    fn new(bits: usize, amount: f64, carry: f64, rho: f64, slip: f64) -> Self {
        let observations = if carry == 0.0 { bits } else { bits + 1 };
        let effects = (0..bits)
            .map(|i| {
                let mut e = vec![(i, amount)];
                if carry != 0.0 {
                    e.push((i + 1, carry));
                }
                e
            })
            .collect();
        Self {
            effects,
            observations,
            rho,
            slip,
        }
    }

    fn bits(&self) -> usize {
        self.effects.len()
    }

    /// The AR(1) whitening of a vector along the observations.
    fn whiten(&self, v: &[f64]) -> Vec<f64> {
        let scale = (1.0 - self.rho * self.rho).sqrt();
        (0..v.len())
            .map(|j| {
                if j == 0 {
                    v[0]
                } else {
                    (v[j] - self.rho * v[j - 1]) / scale
                }
            })
            .collect()
    }

    /// The noise spread of observation `j` given the bits.
    fn spread(&self, j: usize, x: u32) -> f64 {
        if self.slip == 0.0 || j >= self.bits() {
            1.0
        } else {
            1.0 + self.slip * sign(x, j)
        }
    }

    /// `ln p(y | x)` up to a constant common to every `x`.
    fn log_likelihood(&self, y: &[f64], x: u32) -> f64 {
        let mut w = y.to_vec();
        for (i, effect) in self.effects.iter().enumerate() {
            for &(j, amount) in effect {
                w[j] -= sign(x, i) * amount;
            }
        }
        let mut log_spread = 0.0;
        for (j, wj) in w.iter_mut().enumerate() {
            let s = self.spread(j, x);
            *wj /= s;
            log_spread += s.ln();
        }
        -0.5 * self.whiten(&w).iter().map(|v| v * v).sum::<f64>() - log_spread
    }

    /// Each bit's genie view: every other bit given.
    fn genie_views(&self) -> Vec<ViewGroup> {
        (0..self.bits())
            .map(|i| {
                let mut v = vec![0.0; self.observations];
                for &(j, amount) in &self.effects[i] {
                    v[j] = 2.0 * amount;
                }
                let view = if self.slip == 0.0 {
                    BitView::Gaussian {
                        separation: self.whiten(&v).iter().map(|a| a * a).sum::<f64>().sqrt(),
                    }
                } else {
                    assert!(self.rho == 0.0 && self.effects[i].len() == 1);
                    BitView::UnequalNoise {
                        gap: v[i],
                        std_one: 1.0 + self.slip,
                        std_zero: 1.0 - self.slip,
                    }
                };
                ViewGroup { view, bits: 1 }
            })
            .collect()
    }

    /// Each bit's view alone (its own observation, neighbours unknown, noise white): what
    /// ignoring the neighbours would claim.
    fn marginal_views(&self) -> Vec<ViewGroup> {
        self.effects
            .iter()
            .map(|e| ViewGroup {
                view: BitView::Gaussian {
                    separation: 2.0 * e[0].1,
                },
                bits: 1,
            })
            .collect()
    }

    /// One draw of the bits and Eve's observations.
    fn draw(&self, rng: &mut ChaCha8Rng) -> (u32, Vec<f64>) {
        let x = rng.random_range(0..1_u32 << self.bits());
        let scale = (1.0 - self.rho * self.rho).sqrt();
        let mut ar = 0.0;
        let mut y = vec![0.0; self.observations];
        for (j, yj) in y.iter_mut().enumerate() {
            let e: f64 = StandardNormal.sample(rng);
            ar = if j == 0 { e } else { self.rho * ar + scale * e };
            *yj = self.spread(j, x) * ar;
        }
        for (i, effect) in self.effects.iter().enumerate() {
            for &(j, amount) in effect {
                y[j] += sign(x, i) * amount;
            }
        }
        (x, y)
    }

    /// Eve's exact posterior over `draws` seeded draws, against the bound `t` (bits).
    fn exact(&self, t: f64, draws: usize, seed: u64) -> Exact {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let strings = 1_u32 << self.bits();
        let (mut below, mut sum, mut sum_sq) = (0, 0.0, 0.0);
        let mut logs = vec![0.0; strings as usize];
        for _ in 0..draws {
            let (x, y) = self.draw(&mut rng);
            for (s, l) in logs.iter_mut().enumerate() {
                *l = self.log_likelihood(&y, s as u32);
            }
            let top = logs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let normaliser = top + logs.iter().map(|l| (l - top).exp()).sum::<f64>().ln();
            let surprisal = (normaliser - logs[x as usize]) / std::f64::consts::LN_2;
            below += usize::from(surprisal < t);
            let guess = (top - normaliser).exp();
            sum += guess;
            sum_sq += guess * guess;
        }
        let m = draws as f64;
        let mean = sum / m;
        Exact {
            below,
            draws,
            guess: (mean, ((sum_sq / m - mean * mean) / m).max(0.0).sqrt()),
        }
    }
}

/// Bit `i` of `x` as ±1.
fn sign(x: u32, i: usize) -> f64 {
    if x >> i & 1 == 1 { 1.0 } else { -1.0 }
}

/// The most draws below a bound that holds, at a 3σ binomial margin.
fn allowed(epsilon: f64, draws: usize) -> f64 {
    let m = draws as f64;
    epsilon * m + 3.0 * (epsilon * (1.0 - epsilon) * m).sqrt()
}

fn bound(views: &[ViewGroup], epsilon: f64) -> f64 {
    profile_smooth_min_entropy(views, epsilon).unwrap().h_min
}

/// Asserts both inequalities for the genie bound of `pattern`; returns it.
fn genie_holds(name: &str, pattern: &Pattern, epsilon: f64, draws: usize) -> f64 {
    let t = bound(&pattern.genie_views(), epsilon);
    assert!(
        t > 0.0,
        "{name}: the bound claims nothing, the check is void"
    );
    let exact = pattern.exact(t, draws, 2023);
    assert!(
        exact.below as f64 <= allowed(epsilon, exact.draws),
        "{name}: {} of {} draws below t = {t:.3} (ε = {epsilon})",
        exact.below,
        exact.draws
    );
    let (mean, se) = exact.guess;
    assert!(
        mean - 3.0 * se <= (-t).exp2() + epsilon,
        "{name}: P_guess {mean:.4} ± {se:.4} > 2^−t + ε = {:.4}",
        (-t).exp2() + epsilon
    );
    t
}

/// Asserts that `views` over-claim on `pattern`: the check catches them.
fn over_claim_is_caught(name: &str, pattern: &Pattern, views: &[ViewGroup], epsilon: f64) {
    let t = bound(views, epsilon);
    let exact = pattern.exact(t, 3_000, 2023);
    assert!(
        exact.below as f64 > allowed(epsilon, exact.draws),
        "{name}: an over-claiming t = {t:.3} was not caught ({} of {} below)",
        exact.below,
        exact.draws
    );
}

/// Half of every bit's genie separation: an over-claim.
fn halved(pattern: &Pattern) -> Vec<ViewGroup> {
    pattern
        .genie_views()
        .iter()
        .map(|g| ViewGroup {
            view: BitView::Gaussian {
                separation: 0.5 * g.largest_separation(),
            },
            bits: 1,
        })
        .collect()
}

/// Independent bits of four different separations (the turn classes of a block).
#[test]
fn independent_bits_of_different_separations() {
    let mut p = Pattern::new(12, 0.0, 0.0, 0.0, 0.0);
    for (i, e) in p.effects.iter_mut().enumerate() {
        e[0].1 = [0.3, 0.55, 0.8, 1.0][i % 4];
    }
    for &epsilon in &[0.05, 0.2] {
        genie_holds("independent", &p, epsilon, 4_000);
    }
    over_claim_is_caught("half the separations", &p, &halved(&p), 0.05);
}

/// AR(1) noise along the observations: the genie separation (neighbours given) holds where
/// each bit's own, marginal view over-claims.
#[test]
fn correlated_neighbours() {
    for &rho in &[0.5, 0.9] {
        let p = Pattern::new(12, 0.45, 0.0, rho, 0.0);
        genie_holds(&format!("AR(1) ρ = {rho}"), &p, 0.05, 4_000);
    }
    let p = Pattern::new(12, 0.45, 0.0, 0.9, 0.0);
    over_claim_is_caught("marginal views at ρ = 0.9", &p, &p.marginal_views(), 0.05);
}

/// Lag: each bit's effect carried into the next observation, with white and correlated
/// noise; 16 bits once.
#[test]
fn lagged_bits() {
    genie_holds("lag", &Pattern::new(12, 0.4, 0.25, 0.0, 0.0), 0.05, 4_000);
    genie_holds(
        "lag, ρ = 0.5",
        &Pattern::new(12, 0.4, -0.3, 0.5, 0.0),
        0.05,
        4_000,
    );
    genie_holds(
        "lag, 16 bits",
        &Pattern::new(16, 0.35, 0.2, 0.0, 0.0),
        0.1,
        400,
    );
}

/// Slip: the noise's spread depends on the bit; the unequal-noise view integrates it.
#[test]
fn bit_dependent_noise() {
    for &slip in &[0.2, 0.5] {
        let p = Pattern::new(12, 0.45, 0.0, 0.0, slip);
        genie_holds(&format!("slip κ = {slip}"), &p, 0.05, 4_000);
    }
}

/// Multilevel symbols (natural labeling): a 2^m-level amplitude `Σ_b 2^b·s_b·a` on one
/// observation is m bits of amounts `a, 2a, …` on the same observation, so each bit's genie
/// separation (the symbol's other bits given) is `2^b` times the lowest's — the separations
/// a 4- or 8-level doublet produces. Six 4-level and four 8-level symbols (12 bits); half
/// those separations over-claim and are caught.
#[test]
fn multilevel_symbols() {
    for (levels, a) in [(4_u32, 0.3), (8, 0.15)] {
        let per_symbol = levels.trailing_zeros() as usize;
        let symbols = 12 / per_symbol;
        let effects = (0..symbols * per_symbol)
            .map(|i| vec![(i / per_symbol, a * f64::from(1_u32 << (i % per_symbol)))])
            .collect();
        let p = Pattern {
            effects,
            observations: symbols,
            rho: 0.0,
            slip: 0.0,
        };
        for &epsilon in &[0.05, 0.2] {
            genie_holds(&format!("{levels} levels"), &p, epsilon, 4_000);
        }
        over_claim_is_caught(&format!("{levels} levels, halved"), &p, &halved(&p), 0.05);
    }
}
