//! A bit seen through a Gaussian observation whose covariance depends on the bit
//! (docs/secrecy.md, "Bit-dependent covariance"): per-wheel slip, whose noise grows with the
//! wheel speeds the bit sets.
//!
//! Under one value of the bit Eve's observation is `N(μ₀, Σ₀)`, under the other
//! `N(μ₁, Σ₁)`. Whitened by `Σ₀` and rotated onto the eigenvectors of `Σ₀^(−½)Σ₁Σ₀^(−½)`
//! (the caller's linear algebra), the pair is a set of independent coordinates, `N(0, 1)`
//! under the first value and `N(m_k, v_k)` under the second ([`Coordinate`]). Her
//! log-likelihood ratio `L` in favour of the true bit is a quadratic form, not Gaussian; what
//! the min-entropy bound ([`crate::view_profile`]) needs of her surprisal
//! `S = log₂(1 + e^(−L))` is its moment `E[e^(−λS)] = E[(1 + e^(−L))^(−μ)]`, `μ = λ/ln 2`.
//!
//! **The moment as one integral.** For `0 < Re s < μ`,
//! `∫₀^∞ u^(s−1)(1 + u)^(−μ) du = B(s, μ − s)`; inverted at `u = e^(−L)`,
//! `(1 + e^(−L))^(−μ) = (1/2πi)∫_(c−i∞)^(c+i∞) B(s, μ − s)·e^(sL) ds`, so
//! `E_t[(1 + e^(−L))^(−μ)] = (1/π)∫₀^∞ Re[B(c + iω, μ − c − iω)·K_t(c + iω)] dω`, where
//! `K_t(s) = E_t[e^(sL)] = ∫p_t^(1+s)·p_o^(−s)` is the pair's Chernoff coefficient at
//! `α = 1 + s` (`t` the true value, `o` the other), closed form for Gaussians: per coordinate
//! with true `(m_t, v_t)`, other `(m_o, v_o)` and `w = (1 + s)·v_o − s·v_t`,
//! `ln K = −½·[ln w − (1 + s)·ln v_o + s·ln v_t] + ½·s(1 + s)·(m_t − m_o)²/w` (the Mahalanobis
//! term under `(1 + s)Σ_o − sΣ_t` and the log-determinant ratio), analytic where `Re w > 0`.
//! Equal variances give `K = e^(s(1+s)d²/2)`: the consistent Gaussian `L ~ N(d²/2, d²)`.
//!
//! **Numerics.** `c` is the integrand's saddle on the real axis (its least there, found by a
//! golden-section search inside the strip where every `Re w > 0`), which keeps the integral
//! free of cancellation; the integrand falls as `e^(−πω)` and peaks over a width of at most
//! `c`, so it is a trapezoid sum over `ω = κ·sinh(u)` (`κ` the smaller of `c`, `μ − c` and the
//! saddle's width), to `ω = max(30, 60·width)`. Checked against the Gaussian quadrature of
//! [`crate::gaussian_llr`] and against direct integration in one and two dimensions (tests,
//! |Δ ln E| < 10⁻⁹ for λ ≤ [`LARGEST_LAMBDA`]). Each point of the sum takes two complex
//! logarithms whatever the dimension (one per ln Γ): the coordinates' `e^(−½Σ ln w)` under
//! each value is the reciprocal root of their product with its turns around 0 counted
//! (`coordinate_sum`), and the ln Γ's series and those roots stay factors.

use rayon::iter::{IntoParallelRefIterator, ParallelIterator};
use serde::{Deserialize, Serialize};

use crate::min_entropy::{MinEntropyError, check_epsilon};
use crate::special::{LANCZOS_COEFFICIENTS, LANCZOS_G};
use crate::view_profile::BitView;

/// The largest Chernoff parameter λ the moment is evaluated at (checked up to it).
pub const LARGEST_LAMBDA: f64 = 10.0;

/// The smallest Chernoff parameter λ tried.
const SMALLEST_LAMBDA: f64 = 1e-4;

/// One coordinate of a pair of Gaussian hypotheses diagonalised together: `N(0, 1)` under
/// the bit's first value, `N(shift, variance)` under its second.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Coordinate {
    /// The second value's mean, in units of the first's spread.
    pub shift: f64,
    /// The second value's variance over the first's, > 0.
    pub variance: f64,
}

/// A bit's view through a pair of Gaussian hypotheses with their own covariances: the
/// independent coordinates of the pair diagonalised together (module doc).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CovariancePair {
    coordinates: Vec<Coordinate>,
}

impl CovariancePair {
    /// The pair of its `coordinates`; those that tell nothing (shift 0, variance 1) are
    /// dropped.
    ///
    /// # Errors
    /// [`MinEntropyError::InvalidSeparation`] for a shift that is not finite,
    /// [`MinEntropyError::InvalidNoise`] for a variance that is not positive and finite.
    pub fn new(coordinates: impl IntoIterator<Item = Coordinate>) -> Result<Self, MinEntropyError> {
        let mut kept = Vec::new();
        for c in coordinates {
            if !c.shift.is_finite() {
                return Err(MinEntropyError::InvalidSeparation(c.shift));
            }
            if !(c.variance > 0.0 && c.variance.is_finite()) {
                return Err(MinEntropyError::InvalidNoise(c.variance));
            }
            if c.shift != 0.0 || c.variance != 1.0 {
                kept.push(c);
            }
        }
        Ok(Self { coordinates: kept })
    }

    /// The coordinates kept.
    #[must_use]
    pub fn coordinates(&self) -> &[Coordinate] {
        &self.coordinates
    }

    /// `ln E[e^(−λS)]` over the uniform bit (both values true in turn), `0 < λ ≤`
    /// [`LARGEST_LAMBDA`]: the Bromwich integral of the module doc. A pair of equal
    /// variances is the consistent Gaussian view, computed as
    /// [`crate::view_profile::BitView::Gaussian`] computes it.
    #[must_use]
    pub fn ln_moment(&self, lambda: f64) -> f64 {
        if self.coordinates.is_empty() {
            return -lambda;
        }
        if self.coordinates.iter().all(|c| c.variance == 1.0) {
            let d2: f64 = self.coordinates.iter().map(|c| c.shift * c.shift).sum();
            return BitView::Gaussian {
                separation: d2.sqrt(),
            }
            .ln_moment(lambda);
        }
        let mu = lambda / std::f64::consts::LN_2;
        // The strip where every coordinate's `Re w > 0` under either value true.
        let strip = self
            .coordinates
            .iter()
            .map(|c| {
                let v = c.variance;
                if v < 1.0 {
                    v / (1.0 - v)
                } else if v > 1.0 {
                    1.0 / (v - 1.0)
                } else {
                    f64::INFINITY
                }
            })
            .fold(mu, f64::min);
        // What every evaluation of the integrand shares, computed once per moment.
        let shared = Shared {
            ln_gamma_mu: ln_gamma(mu),
            sum_ln_variances: self.coordinates.iter().map(|c| c.variance.ln()).sum(),
        };
        // ln(½(e^first + e^second)) of the integrand's two terms, the larger factored out.
        let on_axis = |c: f64| {
            let [first, second] = self.terms(c, mu, &shared).map(|t| t.ln + t.factor.ln());
            let (high, low) = (first.max(second), first.min(second));
            high + (low - high).exp().ln_1p() - std::f64::consts::LN_2
        };
        // Golden-section search for the least on the axis, each step reusing the inner point
        // it keeps.
        let ratio = (5f64.sqrt() - 1.0) / 2.0;
        let (mut a, mut b) = (1e-9 * strip, (1.0 - 1e-9) * strip);
        let (mut x1, mut x2) = (b - ratio * (b - a), a + ratio * (b - a));
        let (mut f1, mut f2) = (on_axis(x1), on_axis(x2));
        for _ in 0..40 {
            if f1 < f2 {
                (b, x2, f2) = (x2, x1, f1);
                x1 = b - ratio * (b - a);
                f1 = on_axis(x1);
            } else {
                (a, x1, f1) = (x1, x2, f2);
                x2 = a + ratio * (b - a);
                f2 = on_axis(x2);
            }
        }
        let c = 0.5 * (a + b);
        let e = 1e-4 * c.min(strip - c);
        let curvature = (on_axis(c + e) - 2.0 * on_axis(c) + on_axis(c - e)) / (e * e);
        let width = if curvature > 0.0 {
            curvature.sqrt().recip()
        } else {
            c
        };
        let scale = c.min(mu - c).min(width);
        let reach = 30f64.max(60.0 * width);
        let end = (reach / scale).asinh();
        let steps = (end / TRAPEZOID_STEP).ceil().max(1.0);
        let h = end / steps;
        let steps = steps as usize;
        let sum: f64 = (0..=steps)
            .map(|k| {
                let u = h * k as f64;
                let omega = scale * u.sinh();
                let weight = if k == 0 || k == steps { 0.5 } else { 1.0 };
                let terms = self.terms(Complex::new(c, omega), mu, &shared);
                let value: f64 = terms.iter().map(Term::value).sum();
                weight * scale * u.cosh() * 0.5 * value
            })
            .sum();
        (sum * h / std::f64::consts::PI).ln()
    }

    /// `B(s, μ − s)·K_b(s)` for each value `b` true (module doc; the integrand is the two
    /// terms' mean), with ln Γ(μ) and `Σ ln v` from `shared`:
    /// `ln K₀ = Σₖ[gₖ/wₖ − ½ ln wₖ] + ½(1 + s)·Σ ln v`, `wₖ = (1 + s)vₖ − s`, and
    /// `ln K₁ = Σₖ[gₖ/wₖ − ½ ln wₖ] − ½s·Σ ln v`, `wₖ = 1 + s − s·vₖ`, with
    /// `gₖ = ½s(1 + s)·shiftₖ²` ([`Self::coordinate_sum`]), and the ln Γ's series a factor
    /// ([`lanczos`]). On the real axis (the saddle's search) in real arithmetic, off it in
    /// complex.
    fn terms<S: Scalar>(&self, s: S, mu: f64, shared: &Shared) -> [Term<S>; 2] {
        let (gamma_s, series_s) = lanczos(s);
        let (gamma_rest, series_rest) = lanczos(S::real(mu) - s);
        let beta = Term {
            ln: gamma_s + gamma_rest - S::real(shared.ln_gamma_mu),
            factor: series_s * series_rest,
        };
        let one = S::real(1.0);
        let first = self.coordinate_sum(s, |v| (s + one) * v - s);
        let second = self.coordinate_sum(s, |v| (s + one) - s * v);
        [
            Term {
                ln: beta.ln + first.ln + (s + one) * (0.5 * shared.sum_ln_variances),
                factor: beta.factor * first.factor,
            },
            Term {
                ln: beta.ln + second.ln - s * (0.5 * shared.sum_ln_variances),
                factor: beta.factor * second.factor,
            },
        ]
    }

    /// `exp(Σₖ [gₖ/wₖ − ½ ln wₖ])`, `gₖ = ½s(1 + s)·shiftₖ²`, `wₖ = w(vₖ)`, with no logarithm:
    /// inside the strip every `Re wₖ > 0`, so each `Arg wₖ` lies in (−π/2, π/2) and the
    /// product `p = Πₖ wₖ` turns by less than π/2 at each factor: it crosses the negative real
    /// axis exactly where its principal argument jumps by ∓2π, and counting those crossings
    /// (`n`) gives `Σₖ ln wₖ = Ln p + 2πin` exactly, so `exp(−½Σₖ ln wₖ) = (−1)ⁿ/√p` (the
    /// principal root). The product's modulus is folded into the logarithm wherever it leaves
    /// [10⁻¹⁵⁰, 10¹⁵⁰], so it neither overflows nor underflows.
    fn coordinate_sum<S: Scalar>(&self, s: S, w: impl Fn(f64) -> S) -> Term<S> {
        let half_gap = s * (s + S::real(1.0)) * 0.5;
        let (mut gaps, mut product) = (S::real(0.0), S::real(1.0));
        let (mut ln_modulus, mut turns) = (0.0, 0i32);
        for c in &self.coordinates {
            let w = w(c.variance);
            gaps = gaps + half_gap * w.recip() * (c.shift * c.shift);
            let next = product * w;
            turns += S::turn(product, next);
            product = next;
            let size = product.norm_squared();
            if !(1e-300..=1e300).contains(&size) {
                let modulus = size.sqrt();
                ln_modulus += modulus.ln();
                product = product * modulus.recip();
            }
        }
        let sign = if turns % 2 == 0 { 1.0 } else { -1.0 };
        Term {
            ln: gaps - S::real(0.5 * ln_modulus),
            factor: product.inverse_sqrt() * sign,
        }
    }
}

/// A number kept as `e^ln·factor`: the integrand's terms, whose factors (the ln Γ's series,
/// the coordinates' roots) need no logarithm off the real axis.
#[derive(Clone, Copy)]
struct Term<S> {
    ln: S,
    factor: S,
}

impl Term<Complex> {
    /// `Re(e^ln·factor)`.
    fn value(&self) -> f64 {
        let (sin, cos) = self.ln.im.sin_cos();
        self.ln.re.exp() * (cos * self.factor.re - sin * self.factor.im)
    }
}

/// What the integrand of one moment (`CovariancePair::ln_moment` at one μ) takes the same at
/// every point `s`: ln Γ(μ) and `Σ ln v` over the coordinates.
struct Shared {
    ln_gamma_mu: f64,
    sum_ln_variances: f64,
}

/// Step of the trapezoid sum in `u` (`ω = κ·sinh(u)`).
const TRAPEZOID_STEP: f64 = 0.06;

/// A bit of a block seen through covariance pairs: one per value of its doublet's other bits
/// (given to Eve), the most informative of them at each λ.
pub type PairedBit = Vec<CovariancePair>;

/// What the bound of [`paired_smooth_min_entropy`] needs of a bit's view: a lower bound on
/// `−ln E[e^(−λS)]` of Eve's surprisal `S` (bits) at Chernoff parameter λ.
pub trait SurprisalExponent {
    /// `−ln E[e^(−λS)]` at `lambda`, or a lower bound on it (at most λ: `S ≤ 1` bit).
    fn surprisal_exponent(&self, lambda: f64) -> f64;
}

impl SurprisalExponent for PairedBit {
    /// The least over the bit's pairs (no pair: Eve sees nothing, `λ`).
    fn surprisal_exponent(&self, lambda: f64) -> f64 {
        self.iter()
            .map(|pair| -pair.ln_moment(lambda))
            .fold(f64::INFINITY, f64::min)
            .min(lambda)
    }
}

/// The bound of [`paired_smooth_min_entropy`] and where it was reached.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PairedMinEntropy {
    /// Bits kept (those of the block less the removed ones).
    pub positions: u64,
    /// The Chernoff parameter λ that attains the bound.
    pub lambda: f64,
    /// `H_min^ε ≥ t` (bits), `[0, positions]`.
    pub h_min: f64,
}

/// `H_min^ε(X|E) ≥ t` for `bits` seen through covariance pairs (their surprisals
/// independent, as under the genie view), `removed` of them taken away — at each λ the ones
/// whose `−ln E[e^(−λS)]` is largest, the worst choice: `t = max_λ (Σ_kept −ln E_i[e^(−λS)] −
/// ln(1/ε))/λ` over the `lambdas` given (each in (0, [`LARGEST_LAMBDA`]]; every λ gives a
/// bound, the choice only sharpens it: [`candidate_lambdas`]). Each bit's exponent is its
/// [`SurprisalExponent`] (a lower bound keeps the bound a bound).
///
/// # Errors
/// [`MinEntropyError::InvalidEpsilon`] for ε outside (0, 1).
pub fn paired_smooth_min_entropy<B: SurprisalExponent + Sync>(
    bits: &[B],
    removed: u64,
    epsilon: f64,
    lambdas: &[f64],
) -> Result<PairedMinEntropy, MinEntropyError> {
    check_epsilon(epsilon)?;
    ChernoffExponents::of(bits, lambdas).smooth_min_entropy(removed, epsilon)
}

/// A set of bits' exponents `−ln E[e^(−λS)]` ([`SurprisalExponent`]) at each of a few
/// Chernoff parameters λ, each λ's sorted ascending: all that the bound of
/// [`paired_smooth_min_entropy`] reads of the bits. Kept, it gives the bound with any number
/// of them removed without evaluating a moment again; [`Self::split`] evaluates each bit's
/// moments once and partitions them (a multilevel block's slices), [`Self::joined`] puts
/// parts back together (the sorted union: the same bound as the whole, number for number).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ChernoffExponents {
    /// Bits held.
    bits: usize,
    /// Each λ in (0, [`LARGEST_LAMBDA`]] with the bits' exponents there, ascending.
    at: Vec<(f64, Vec<f64>)>,
}

impl ChernoffExponents {
    /// `bits`' exponents at each of `lambdas` in (0, [`LARGEST_LAMBDA`]] (the others give no
    /// bound and are dropped).
    #[must_use]
    pub fn of<B: SurprisalExponent + Sync>(bits: &[B], lambdas: &[f64]) -> Self {
        Self::split(bits, lambdas, 1, |_| 0)
            .pop()
            .unwrap_or_default()
    }

    /// `bits`' exponents at each of `lambdas` (as [`Self::of`]), each bit's evaluated once,
    /// in `parts` parts: bit `i` in part `part_of(i)` (values from `parts` on are dropped).
    ///
    /// The bits are evaluated on rayon's current pool (the global one outside `install`),
    /// each bit's exponents on one thread and placed in the bits' order before the sort: the
    /// result is the sequential one, number for number, on any number of threads.
    #[must_use]
    pub fn split<B: SurprisalExponent + Sync>(
        bits: &[B],
        lambdas: &[f64],
        parts: usize,
        part_of: impl Fn(usize) -> usize,
    ) -> Vec<Self> {
        let lambdas: Vec<f64> = lambdas
            .iter()
            .copied()
            .filter(|&l| l > 0.0 && l <= LARGEST_LAMBDA)
            .collect();
        let mut out: Vec<Self> = (0..parts)
            .map(|_| Self {
                bits: 0,
                at: lambdas.iter().map(|&l| (l, Vec::new())).collect(),
            })
            .collect();
        let placed: Vec<(&B, usize)> = bits
            .iter()
            .enumerate()
            .map(|(i, bit)| (bit, part_of(i)))
            .filter(|&(_, part)| part < parts)
            .collect();
        let evaluated: Vec<Vec<f64>> = placed
            .par_iter()
            .map(|(bit, _)| lambdas.iter().map(|&l| bit.surprisal_exponent(l)).collect())
            .collect();
        for ((_, part), exponents) in placed.into_iter().zip(evaluated) {
            let part = &mut out[part];
            part.bits += 1;
            for ((_, at), exponent) in part.at.iter_mut().zip(exponents) {
                at.push(exponent);
            }
        }
        for part in &mut out {
            for (_, exponents) in &mut part.at {
                exponents.sort_by(f64::total_cmp);
            }
        }
        out
    }

    /// The bits of every one of `parts` together (each taken at the first part's λ; parts at
    /// other λ are not joined: none).
    #[must_use]
    pub fn joined(parts: &[Self]) -> Option<Self> {
        let first = parts.first()?;
        let same = |p: &Self| {
            p.at.len() == first.at.len() && p.at.iter().zip(&first.at).all(|(a, b)| a.0 == b.0)
        };
        if !parts.iter().all(same) {
            return None;
        }
        let at = (0..first.at.len())
            .map(|k| {
                let mut exponents: Vec<f64> = parts
                    .iter()
                    .flat_map(|p| p.at[k].1.iter().copied())
                    .collect();
                exponents.sort_by(f64::total_cmp);
                (first.at[k].0, exponents)
            })
            .collect();
        Some(Self {
            bits: parts.iter().map(|p| p.bits).sum(),
            at,
        })
    }

    /// Bits held.
    #[must_use]
    pub fn bits(&self) -> usize {
        self.bits
    }

    /// The bound of [`paired_smooth_min_entropy`] on the bits held, `removed` of them taken
    /// away (at each λ the ones whose exponent is largest, the worst choice).
    ///
    /// # Errors
    /// [`MinEntropyError::InvalidEpsilon`] for ε outside (0, 1).
    pub fn smooth_min_entropy(
        &self,
        removed: u64,
        epsilon: f64,
    ) -> Result<PairedMinEntropy, MinEntropyError> {
        check_epsilon(epsilon)?;
        let removed = usize::try_from(removed)
            .unwrap_or(usize::MAX)
            .min(self.bits);
        let positions = (self.bits - removed) as u64;
        let ln_inv_eps = -epsilon.ln();
        let (lambda, t) = self
            .at
            .iter()
            .map(|(lambda, exponents)| {
                let kept: f64 = exponents[..exponents.len() - removed].iter().sum();
                let t = (kept - ln_inv_eps) / lambda;
                (*lambda, if t.is_finite() { t } else { f64::NEG_INFINITY })
            })
            .fold((0.0, f64::NEG_INFINITY), |best, x| {
                if x.1 > best.1 { x } else { best }
            });
        Ok(PairedMinEntropy {
            positions,
            lambda,
            h_min: t.clamp(0.0, positions as f64),
        })
    }
}

/// Chernoff parameters worth trying for `n` bits of views near separation `d`: the λ that
/// attains [`crate::view_profile::gaussian_llr_smooth_min_entropy`]'s bound there, and that λ
/// times 2^(±½), 2^(±1) (within `[10⁻⁴, LARGEST_LAMBDA]`).
///
/// # Errors
/// [`MinEntropyError`] for ε outside (0, 1) or a separation that is negative or not finite.
pub fn candidate_lambdas(n: u64, d: f64, epsilon: f64) -> Result<Vec<f64>, MinEntropyError> {
    let centre = crate::view_profile::gaussian_llr_smooth_min_entropy(n, d, epsilon)?.lambda;
    Ok([-1.0, -0.5, 0.0, 0.5, 1.0]
        .iter()
        .map(|&e| (centre * 2f64.powf(e)).clamp(SMALLEST_LAMBDA, LARGEST_LAMBDA))
        .collect())
}

/// What the integrand is computed in: `f64` on the real axis, [`Complex`] off it.
trait Scalar:
    Copy
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Mul<f64, Output = Self>
{
    /// `x` on the real axis.
    fn real(x: f64) -> Self;
    /// The real part.
    fn re(self) -> f64;
    /// `|z|²`.
    fn norm_squared(self) -> f64;
    /// `1/z`.
    fn recip(self) -> Self;
    /// The principal logarithm, its modulus as `½ ln |z|²`: every `z` it is taken of here
    /// has `|z|²` within the floating-point range (`coordinate_sum` folds its product's).
    fn ln(self) -> Self;
    /// `z^(−½)`, the principal root's reciprocal (for `f64`, `z > 0`).
    fn inverse_sqrt(self) -> Self;
    /// The turns the principal argument misses from `before` to `after` (`|Arg(after/before)|
    /// < π/2`): ±1 where it crosses the negative real axis, where the sign of the imaginary
    /// part flips (atan2 takes that sign: +0 → π, −0 → −π), else 0.
    fn turn(before: Self, after: Self) -> i32;
}

impl Scalar for f64 {
    fn real(x: f64) -> Self {
        x
    }

    fn re(self) -> f64 {
        self
    }

    fn norm_squared(self) -> f64 {
        self * self
    }

    fn recip(self) -> Self {
        f64::recip(self)
    }

    fn ln(self) -> Self {
        f64::ln(self)
    }

    fn inverse_sqrt(self) -> Self {
        self.sqrt().recip()
    }

    fn turn(_: Self, _: Self) -> i32 {
        0
    }
}

/// A complex number, for the Bromwich integral.
#[derive(Debug, Clone, Copy)]
struct Complex {
    re: f64,
    im: f64,
}

impl Complex {
    fn new(re: f64, im: f64) -> Self {
        Self { re, im }
    }
}

impl Scalar for Complex {
    fn real(re: f64) -> Self {
        Self { re, im: 0.0 }
    }

    fn re(self) -> f64 {
        self.re
    }

    fn norm_squared(self) -> f64 {
        self.re * self.re + self.im * self.im
    }

    fn recip(self) -> Self {
        let n = self.norm_squared().recip();
        Self::new(self.re * n, -self.im * n)
    }

    fn ln(self) -> Self {
        Self::new(0.5 * self.norm_squared().ln(), self.im.atan2(self.re))
    }

    /// `√z = (r, im/2r)`, `r = √((|z| + re)/2)`, where `re ≥ 0`; `(|im|/2t, ±t)`,
    /// `t = √((|z| − re)/2)` with the sign of `im`, where `re < 0` (no cancellation either
    /// way; on the cut the sign of a zero `im` picks the side, as atan2 does); `1/√z =
    /// conj(√z)/|z|`.
    fn inverse_sqrt(self) -> Self {
        let modulus = self.norm_squared().sqrt();
        let root = if self.re >= 0.0 {
            let r = (0.5 * (modulus + self.re)).sqrt();
            Self::new(r, 0.5 * self.im / r)
        } else {
            let t = (0.5 * (modulus - self.re)).sqrt();
            Self::new(0.5 * self.im.abs() / t, t.copysign(self.im))
        };
        Self::new(root.re / modulus, -root.im / modulus)
    }

    fn turn(before: Self, after: Self) -> i32 {
        if after.re < 0.0 && before.im.is_sign_negative() != after.im.is_sign_negative() {
            if after.im.is_sign_negative() { 1 } else { -1 }
        } else {
            0
        }
    }
}

impl std::ops::Add for Complex {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self::new(self.re + o.re, self.im + o.im)
    }
}

impl std::ops::Sub for Complex {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        Self::new(self.re - o.re, self.im - o.im)
    }
}

impl std::ops::Mul for Complex {
    type Output = Self;
    fn mul(self, o: Self) -> Self {
        Self::new(
            self.re * o.re - self.im * o.im,
            self.re * o.im + self.im * o.re,
        )
    }
}

impl std::ops::Mul<f64> for Complex {
    type Output = Self;
    fn mul(self, k: f64) -> Self {
        Self::new(self.re * k, self.im * k)
    }
}

/// ln Γ(z) for `Re z > 0` ([`lanczos`]), up to a multiple of 2πi (the integrand is
/// exponentiated).
fn ln_gamma<S: Scalar>(z: S) -> S {
    let (principal, factor) = lanczos(z);
    principal + factor.ln()
}

/// ln Γ(z) for `Re z > 0` as `(p, f)` with `ln Γ(z) = p + ln f` up to a multiple of 2πi:
/// Lanczos (g = 7, the coefficients of [`crate::special`]), `p = ½ ln 2π + (x + ½)·ln t − t`
/// (`x = z − 1`, `t = x + g + ½`, the principal logarithm: it is multiplied) and `f` the
/// series; below `Re z = ½` through Γ(z) = Γ(z + 1)/z, `f` divided by `z`. Kept apart, the
/// series needs no logarithm off the real axis (the integrand's terms keep it a factor).
fn lanczos<S: Scalar>(z: S) -> (S, S) {
    if z.re() < 0.5 {
        let (principal, factor) = lanczos(z + S::real(1.0));
        return (principal, factor * z.recip());
    }
    let x = z - S::real(1.0);
    let mut series = S::real(LANCZOS_COEFFICIENTS[0]);
    for (i, &c) in LANCZOS_COEFFICIENTS.iter().enumerate().skip(1) {
        series = series + (x + S::real(i as f64)).recip() * c;
    }
    let t = x + S::real(LANCZOS_G + 0.5);
    (
        S::real(0.5 * (2.0 * std::f64::consts::PI).ln()) + (x + S::real(0.5)) * t.ln() - t,
        series,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pair(coordinates: &[(f64, f64)]) -> CovariancePair {
        CovariancePair::new(
            coordinates
                .iter()
                .map(|&(shift, variance)| Coordinate { shift, variance }),
        )
        .unwrap()
    }

    /// The complex ln Γ agrees with the real one on the axis and with Γ(z + 1) = z·Γ(z).
    #[test]
    fn complex_ln_gamma_is_gamma() {
        for x in [0.01, 0.3, 1.0, 2.5, 17.0] {
            let real = crate::special::ln_gamma(x).unwrap();
            assert!((ln_gamma(x) - real).abs() < 1e-12, "{x}");
            assert!((ln_gamma(Complex::real(x)).re - real).abs() < 1e-12, "{x}");
        }
        for (re, im) in [(0.2, 0.7), (1.3, -4.0), (0.01, 25.0)] {
            let z = Complex::new(re, im);
            let step = ln_gamma(z + Complex::real(1.0)) - ln_gamma(z) - z.ln();
            let wrapped = step.im.rem_euclid(2.0 * std::f64::consts::PI);
            assert!(step.re.abs() < 1e-11, "{re} {im}: {step:?}");
            assert!(
                wrapped.min(2.0 * std::f64::consts::PI - wrapped) < 1e-10,
                "{re} {im}: {step:?}"
            );
        }
    }

    /// The Bromwich integral of a pair whose variances are equal but handled as unequal (a
    /// coordinate of variance 1 beside one of variance 1 + 10⁻⁹) is the Gaussian view's
    /// quadrature; one unequal coordinate is [`BitView::UnequalNoise`]'s quadrature.
    #[test]
    fn the_integral_matches_the_one_dimensional_quadratures() {
        for d in [0.05, 0.3, 1.0, 2.0, 4.0, 8.0] {
            for lambda in [1e-4, 0.01, 0.05, 0.5, 3.0, LARGEST_LAMBDA] {
                let integral = pair(&[(d, 1.0), (0.0, 1.0 + 1e-9)]).ln_moment(lambda);
                let gaussian = BitView::Gaussian { separation: d }.ln_moment(lambda);
                assert!(
                    (integral - gaussian).abs() < 1e-9,
                    "d {d} λ {lambda}: {integral} vs {gaussian}"
                );
            }
        }
        for (gap, variance) in [(1.0, 2.0), (0.5, 0.3), (2.5, 4.0), (0.0, 6.0), (3.0, 0.2)] {
            for lambda in [1e-3, 0.05, 0.5, 3.0] {
                let integral = pair(&[(gap, variance)]).ln_moment(lambda);
                // UnequalNoise: y ~ N(±gap/2, σ²) — the same pair, translated.
                let quadrature = BitView::UnequalNoise {
                    gap,
                    std_one: variance.sqrt(),
                    std_zero: 1.0,
                }
                .ln_moment(lambda);
                assert!(
                    (integral - quadrature).abs() < 1e-9,
                    "gap {gap} v {variance} λ {lambda}: {integral} vs {quadrature}"
                );
            }
        }
    }

    /// Two coordinates, integrated directly on a 2-D grid: `E[(1 + e^(−L))^(−μ)]` =
    /// `½∫(p₀^(1+μ) + p₁^(1+μ))/(p₀ + p₁)^μ`.
    #[test]
    fn the_integral_matches_a_two_dimensional_quadrature() {
        let cases = [
            [(1.5, 1.0), (0.2, 3.0)],
            [(0.8, 0.5), (0.0, 2.5)],
            [(2.0, 0.25), (1.0, 4.0)],
        ];
        for coordinates in cases {
            for lambda in [0.01, 0.2, 1.0] {
                let mu = lambda / std::f64::consts::LN_2;
                let points = 601;
                let axis = |m: f64, v: f64| {
                    let (lo, hi) = (
                        (-12.0_f64).min(m - 12.0 * v.sqrt()),
                        12.0_f64.max(m + 12.0 * v.sqrt()),
                    );
                    (0..points)
                        .map(move |i| lo + (hi - lo) * i as f64 / (points - 1) as f64)
                        .collect::<Vec<f64>>()
                };
                let [(m0, v0), (m1, v1)] = coordinates;
                let (xs, ys) = (axis(m0, v0), axis(m1, v1));
                let (hx, hy) = (xs[1] - xs[0], ys[1] - ys[0]);
                let mut sum = 0.0;
                for &x in &xs {
                    for &y in &ys {
                        let p0 = (-0.5 * (x * x + y * y)).exp();
                        let p1 = (-0.5 * ((x - m0).powi(2) / v0 + (y - m1).powi(2) / v1)).exp()
                            / (v0 * v1).sqrt();
                        if p0 + p1 > 0.0 {
                            sum +=
                                0.5 * (p0.powf(1.0 + mu) + p1.powf(1.0 + mu)) / (p0 + p1).powf(mu);
                        }
                    }
                }
                let direct = (sum * hx * hy / (2.0 * std::f64::consts::PI)).ln();
                let integral = pair(&coordinates).ln_moment(lambda);
                assert!(
                    (integral - direct).abs() < 1e-9,
                    "{coordinates:?} λ {lambda}: {integral} vs {direct}"
                );
            }
        }
    }

    /// The coordinates' sum without a logarithm is the sum of each coordinate's principal
    /// logarithms up to a multiple of 2πi (the same exponential), where the product of 24
    /// coordinates' `w` winds around 0 (their arguments add beyond π) and where that of 400
    /// leaves the floating-point range (its modulus folded).
    #[test]
    fn one_root_for_all_coordinates_is_the_sum_of_their_logarithms() {
        let one = Complex::real(1.0);
        let mut wound = false;
        for dimension in [1, 3, 24, 400] {
            let p = pair(
                &(0..dimension)
                    .map(|k| {
                        let x = f64::from(k) / f64::from(dimension);
                        (2.0 * x - 0.7, (4.0 * (x * 5.0).fract() - 2.0).exp())
                    })
                    .collect::<Vec<_>>(),
            );
            let strip = p
                .coordinates()
                .iter()
                .map(|c| 1.0 / (c.variance - 1.0).abs().max(1e-300) * c.variance.min(1.0))
                .fold(5.0, f64::min);
            for c in [1e-3 * strip, 0.5 * strip, 0.999 * strip] {
                for omega in [0.0, 0.3, 4.0, 60.0, 2_000.0] {
                    let s = Complex::new(c, omega);
                    let forms: [&dyn Fn(f64) -> Complex; 2] =
                        [&|v| (s + one) * v - s, &|v| (s + one) - s * v];
                    for w in forms {
                        let gap = s * (s + one) * 0.5;
                        let (mut direct, mut arguments) = (Complex::real(0.0), 0.0);
                        for c in p.coordinates() {
                            let w = w(c.variance);
                            assert!(w.re > 0.0, "outside the strip");
                            direct = direct + gap * (c.shift * c.shift) * w.recip() - w.ln() * 0.5;
                            arguments += w.im.atan2(w.re);
                        }
                        wound |= arguments.abs() > std::f64::consts::PI;
                        let term = p.coordinate_sum(s, w);
                        let fast = term.ln + term.factor.ln();
                        let scale = 1.0 + direct.re.abs() + direct.im.abs();
                        let turns = (fast.im - direct.im) / (2.0 * std::f64::consts::PI);
                        assert!(
                            (fast.re - direct.re).abs() < 1e-12 * scale
                                && (turns - turns.round()).abs() < 1e-12 * scale,
                            "{dimension} at {s:?}: {fast:?} vs {direct:?}"
                        );
                    }
                }
            }
        }
        assert!(wound, "no case winds around 0");
    }

    /// A pair with no information is the blind view; invalid coordinates are refused.
    #[test]
    fn blind_and_invalid_pairs() {
        assert_eq!(pair(&[(0.0, 1.0)]).ln_moment(0.3), -0.3);
        assert!(
            CovariancePair::new([Coordinate {
                shift: f64::NAN,
                variance: 1.0
            }])
            .is_err()
        );
        assert!(
            CovariancePair::new([Coordinate {
                shift: 0.0,
                variance: 0.0
            }])
            .is_err()
        );
    }

    /// Equal-variance pairs give the Gaussian profile's bound (to the search's resolution);
    /// more information (larger shifts, a spread that moves more with the bit) never raises
    /// it; removing bits removes at least their Shannon share.
    #[test]
    fn the_paired_bound_is_the_profile_bound_for_equal_variances_and_monotone() {
        use crate::view_profile::{ViewGroup, profile_smooth_min_entropy};
        let bits: Vec<PairedBit> = (0..2_000)
            .map(|i| vec![pair(&[(if i % 2 == 0 { 0.8 } else { 1.6 }, 1.0)])])
            .collect();
        let lambdas = candidate_lambdas(2_000, 1.2, 1e-6).unwrap();
        let paired = paired_smooth_min_entropy(&bits, 0, 1e-6, &lambdas).unwrap();
        let profile = profile_smooth_min_entropy(
            &[
                ViewGroup {
                    view: BitView::Gaussian { separation: 0.8 },
                    bits: 1_000,
                },
                ViewGroup {
                    view: BitView::Gaussian { separation: 1.6 },
                    bits: 1_000,
                },
            ],
            1e-6,
        )
        .unwrap();
        assert!(
            paired.h_min <= profile.h_min + 1e-6,
            "{paired:?} {profile:?}"
        );
        assert!(paired.h_min > profile.h_min - 2.0, "{paired:?} {profile:?}");
        let spread: Vec<PairedBit> = (0..2_000)
            .map(|i| {
                vec![pair(&[
                    (if i % 2 == 0 { 0.8 } else { 1.6 }, 1.0),
                    (0.0, 3.0),
                ])]
            })
            .collect();
        let with_spread = paired_smooth_min_entropy(&spread, 0, 1e-6, &lambdas).unwrap();
        assert!(with_spread.h_min < paired.h_min, "{with_spread:?}");
        let fewer = paired_smooth_min_entropy(&bits, 100, 1e-6, &lambdas).unwrap();
        assert_eq!(fewer.positions, 1_900);
        assert!(fewer.h_min < paired.h_min - 100.0 * 0.3, "{fewer:?}");
        // A bit with two pairs is sized at the more informative.
        let two: Vec<PairedBit> = (0..2_000)
            .map(|_| vec![pair(&[(0.8, 1.0)]), pair(&[(1.6, 1.0)])])
            .collect();
        let sharp: Vec<PairedBit> = (0..2_000).map(|_| vec![pair(&[(1.6, 1.0)])]).collect();
        let (two, sharp) = (
            paired_smooth_min_entropy(&two, 0, 1e-6, &lambdas).unwrap(),
            paired_smooth_min_entropy(&sharp, 0, 1e-6, &lambdas).unwrap(),
        );
        assert!((two.h_min - sharp.h_min).abs() < 1e-9, "{two:?} {sharp:?}");
    }

    /// Each bit's exponents evaluated once and kept: the bound of one part is
    /// [`paired_smooth_min_entropy`]'s number for number, with any count removed; parts joined
    /// are the whole (the same bound); each part's bound is the function's on its own bits at
    /// the same λ; λ outside (0, LARGEST_LAMBDA] are dropped; parts at other λ do not join.
    #[test]
    fn exponents_kept_and_split_give_the_same_bounds() {
        let bits: Vec<PairedBit> = (0..600)
            .map(|i| {
                let d = 0.3 + 0.002 * f64::from(i % 97);
                vec![
                    pair(&[(d, 1.0 + 0.001 * f64::from(i % 13))]),
                    pair(&[(0.8 * d, 1.2)]),
                ]
            })
            .collect();
        let lambdas = [0.0, 0.05, 0.2, 0.7, 11.0];
        let whole = ChernoffExponents::of(&bits, &lambdas);
        assert_eq!(whole.bits(), 600);
        assert_eq!(whole.at.len(), 3);
        for removed in [0, 1, 60, 600, 700] {
            assert_eq!(
                whole.smooth_min_entropy(removed, 1e-6).unwrap(),
                paired_smooth_min_entropy(&bits, removed, 1e-6, &lambdas).unwrap()
            );
        }
        let parts = ChernoffExponents::split(&bits, &lambdas, 3, |i| i % 3);
        assert_eq!(ChernoffExponents::joined(&parts).unwrap(), whole);
        for (k, part) in parts.iter().enumerate() {
            let own: Vec<PairedBit> = bits.iter().skip(k).step_by(3).cloned().collect();
            assert_eq!(part.bits(), 200);
            assert_eq!(
                part.smooth_min_entropy(20, 1e-6).unwrap(),
                paired_smooth_min_entropy(&own, 20, 1e-6, &lambdas).unwrap()
            );
        }
        let other = ChernoffExponents::of(&bits, &[0.3]);
        assert_eq!(ChernoffExponents::joined(&[whole, other]), None);
        assert!(
            ChernoffExponents::of(&bits, &lambdas)
                .smooth_min_entropy(0, 1.5)
                .is_err()
        );
    }

    /// [`ChernoffExponents::split`] evaluates the bits on rayon's pool: in a pool of one
    /// thread and in one of two, each part's exponents at each λ are bit for bit each of its
    /// bits' exponent evaluated in turn and sorted (a bit whose part is beyond `parts` is
    /// dropped).
    #[test]
    fn split_is_the_sequential_evaluation_on_any_number_of_threads() {
        let bits: Vec<PairedBit> = (0..400)
            .map(|i| {
                let d = 0.3 + 0.003 * f64::from(i % 89);
                vec![pair(&[
                    (d, 1.0 + 0.002 * f64::from(i % 11)),
                    (0.5 * d, 0.9),
                ])]
            })
            .collect();
        let lambdas = [0.05, 0.2, 0.7];
        let sequential: Vec<Vec<Vec<u64>>> = (0..3)
            .map(|part| {
                lambdas
                    .iter()
                    .map(|&l| {
                        let mut at: Vec<f64> = (part..bits.len())
                            .step_by(4)
                            .map(|i| bits[i].surprisal_exponent(l))
                            .collect();
                        at.sort_by(f64::total_cmp);
                        at.iter().map(|x| x.to_bits()).collect()
                    })
                    .collect()
            })
            .collect();
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let parts = pool.install(|| ChernoffExponents::split(&bits, &lambdas, 3, |i| i % 4));
            let evaluated: Vec<Vec<Vec<u64>>> = parts
                .iter()
                .map(|part| {
                    part.at
                        .iter()
                        .map(|(_, at)| at.iter().map(|x| x.to_bits()).collect())
                        .collect()
                })
                .collect();
            assert_eq!(evaluated, sequential, "{threads} threads");
            assert!(parts.iter().all(|part| part.bits() == 100));
        }
    }
}
