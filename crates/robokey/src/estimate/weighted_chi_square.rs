//! Tails of a weighted χ², `X = Σᵢ wᵢξᵢ²` (ξᵢ independent standard normals, `Σᵢ wᵢ = m`),
//! bounded at once for every weight vector `wᵢ = 1 + t·bᵀEᵢb` of a direction `b` in a cap
//! (docs/estimation.md, "Per-wheel slip": the Wishart bound where slip makes the residuals'
//! covariances unequal).
//!
//! **Tilting.** For `0 < λ < 1/(2·max wᵢ)`, `E[e^(λX)] = Πᵢ(1 − 2λwᵢ)^(−½)`, and under the
//! law tilted by `e^(λX)` the terms are again independent, `wᵢξᵢ²` with
//! `ξᵢ ~ N(0, 1/(1 − 2λwᵢ))`. Writing `1{X ≥ q}·e^(−λ(X − q)) = ∫₀^∞ λe^(−λy)·1{q ≤ X ≤ q + y} dy`,
//!
//! ```text
//! P[X ≥ q] = exp(−λ(q − m) + Σᵢ φ_λ(wᵢ)) · J₊,   φ_λ(w) = −½ ln(1 − 2λw) − λw,
//! J₊ = E_λ[e^(−λ(X − q)); X ≥ q] = ∫₀^∞ λe^(−λy)·P_λ[q ≤ X ≤ q + y] dy,
//! ```
//!
//! and with the tilt `e^(−λX)` (terms `ξᵢ ~ N(0, 1/(1 + 2λwᵢ))`) the lower tail alike:
//! `P[X ≤ q] = exp(−λ(m − q) + Σᵢ ψ_λ(wᵢ))·J₋`, `ψ_λ(w) = −½ ln(1 + 2λw) + λw`. `J ≤ 1` is
//! Chernoff's bound. **Berry–Esseen** sharpens it: the tilted X has standard deviation σ and
//! third absolute central moment sum `β = κ·Σᵢ w̃ᵢ³` (`w̃ᵢ` the tilted scales, `κ = E|Z² − 1|³`),
//! so `sup|F − Φ| ≤ C₀·β/σ³` with Shevtsova's `C₀ = 0.5600` for independent, not identically
//! distributed terms, and every interval of length y has tilted probability at most
//! `y/(σ√(2π)) + 2C₀β/σ³`; hence `J ≤ 1/(λσ√(2π)) + 2C₀β/σ³`, for every λ and q (no saddle
//! point needed). Over the weights: under `e^(λX)` the scale `w/(1 − 2λw)` is convex and
//! rising, so by Jensen `Σw̃ᵢ² ≥ m/(1 − 2λ)²`; under `e^(−λX)`, `w̃ᵢ ≥ wᵢ/(1 + 2λh)` and
//! `Σwᵢ² ≥ m` give `Σw̃ᵢ² ≥ m/(1 + 2λh)²` (h at least every weight); with `Σw̃³ ≤ max w̃·Σw̃²`,
//! `β/σ³ ≤ κ·max w̃/(2^(3/2)·(Σw̃²)^(½))`. A probability `e^(ln_p)` is reached at
//! `q₊ = m + (Σφ_λ + ln J₊ − ln p)/λ` and `q₋ = m − (Σψ_λ + ln J₋ − ln p)/λ`, each λ giving a
//! valid quantile (the best found on a fixed geometric grid of λ, descending from χ²_m's
//! best point: any λ is a bound, so the search sets only how tight).
//!
//! **Over a cap of directions.** The weights are `wᵢ = 1 + t·eᵢ(b)`, `eᵢ(b) = bᵀEᵢb` for a
//! unit direction `b` in a cap (every line within θ of a centre `c`, θ ≤ π/4) and one
//! `t ∈ [0, 1]` common to all terms, with `ΣᵢEᵢ = 0` (so `Σwᵢ = m`) and `wᵢ ≥ 0`. Let `g` be φ_λ
//! (ψ_λ) at `max(w, 0)`: convex, `g'(1)` common to all terms, and equal to φ_λ (ψ_λ) at every
//! weight allowed. Along t, `Σg(1 + t·eᵢ)` is convex with slope `g'(1)·Σeᵢ = 0` at 0, so
//! its largest value on `[0, 1]` is at t = 1. Within the cap, writing `b = cos α·c + sin α·u`
//! (`u ⊥ c`, α ≤ θ), `eᵢ(b) = eᵢ(c) + sin²α·(uᵀEᵢu − eᵢ(c)) + sin 2α·cᵀEᵢu`, so `eᵢ` lies in
//! `[αᵢ, βᵢ]`: `eᵢ(c) ± sin 2θ·|Eᵢc − eᵢ(c)c|` moved by `sin²θ` towards `Eᵢ`'s least
//! (greatest) eigenvalue, within those eigenvalues (the whole sphere: the eigenvalues
//! themselves). On it `g` lies below its chord, `g(1 + eᵢ) ≤ g(1 + αᵢ) + sᵢ·(eᵢ − αᵢ)`, and
//! the chords' sum is `K + bᵀAb`, `K = Σ(g(1 + αᵢ) − sᵢαᵢ)`, `A = ΣsᵢEᵢ`, whose largest value
//! over the cap is bounded as `eᵢ`'s (`λ_max(A)` at most): a bound for every weight vector the
//! cap and t allow, the terms tied by their one direction (at equal weights, `Eᵢ = 0`, χ²_m's
//! own exponent). The weights are at most `1 + max(0, βᵢ)` (the Berry–Esseen terms' `h`).
//!
//! **Dependence.** Where neighbouring terms are dependent (AR(1) motion noise within a
//! parity half) the terms are taken as `m/F` independent ones of `F` times the weight — the
//! effective count of the Gaussian path's Wishart bound, `F` its deflation: `Σφ_λ(wᵢ)`
//! becomes `Σφ_λ(F·wᵢ)/F`, and the tilted moments `σ² = 2F·Σw̃ᵢ²`, `β = κF²·Σw̃ᵢ³` (with
//! `w̃ᵢ = wᵢ/(1 ∓ 2λFwᵢ)`): the same at F = 1; a stated approximation, as there.

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

/// λ's grids: from the largest value down by factors `2^(1/12)`, this many points (a factor
/// `2^20` in all; near the optimum the exponent is flat, and the step costs at most 0.2 % of
/// `q − m` in the tests, 0.04 % where the tail is near-Gaussian). The upper one drops the
/// points where `2λF·max hᵢ ≥ 1`.
const LAMBDA_POINTS: usize = 240;

/// The lower tail's largest λ (in units of `1/F`): `2^(LOWER_TOP/12)`.
const LOWER_TOP: i32 = 72;

/// The upper tail's largest λ (in units of `1/F`): `2^(UPPER_TOP/12) = ½·2^(−1/12)`, just
/// below `1/(2F)`, beyond which no weights are feasible (`λ < 1/(2F·max hᵢ)`, `max hᵢ ≥ 1`).
const UPPER_TOP: i32 = -13;

/// Shevtsova's Berry–Esseen constant for sums of independent, not identically distributed
/// terms: `sup|F − Φ| ≤ C₀·Σᵢ E|Yᵢ − EYᵢ|³/σ³`.
const BERRY_ESSEEN: f64 = 0.5600;

/// `κ = E|Z² − 1|³` for a standard normal Z, rounded up: `E(Z² − 1)³ = 8`, plus twice
/// `E[(1 − Z²)³; |Z| < 1] = I₀ − 3I₂ + 3I₄ − I₆ = 0.345781…` (`Iₖ = ∫₋₁¹ zᵏφ(z) dz`,
/// `I₀ = erf(1/√2)`, `Iₖ = (k − 1)·Iₖ₋₂ − 2φ(1)`): 8.691563….
const THIRD_ABSOLUTE_MOMENT: f64 = 8.6916;

/// A cap of lines: those within θ of the unit `centre`, `sin²θ = sin_sq` (θ ≤ π/4, or
/// `sin_sq ≥ ½` for every line).
#[derive(Clone, Copy, Debug)]
pub(super) struct Cap {
    /// `c`, a unit vector.
    pub(super) centre: Vector3<f64>,
    /// `sin²θ`.
    pub(super) sin_sq: f64,
}

impl Cap {
    /// The `3k²` caps of the cube's face squares (`k ≥ 2` per side): a line meets a face
    /// `|x_a| = 1` in a square of side `2/k` and lies within `sin θ ≤ √2/k` of its centre
    /// (`wishart`'s nets), so they cover every line.
    pub(super) fn of_faces(k: u32) -> Vec<Self> {
        let side = 2.0 / f64::from(k);
        let at = |i: u32| -1.0 + side * (f64::from(i) + 0.5);
        (0..3)
            .flat_map(|axis| {
                (0..k).flat_map(move |i| {
                    (0..k).map(move |j| {
                        let mut centre = Vector3::zeros();
                        centre[axis] = 1.0;
                        centre[(axis + 1) % 3] = at(i);
                        centre[(axis + 2) % 3] = at(j);
                        Self {
                            centre: centre.normalize(),
                            sin_sq: side * side / 2.0,
                        }
                    })
                })
            })
            .collect()
    }

    /// `[least, greatest]` of `bᵀEb` over the cap's lines, for `E` with extreme eigenvalues
    /// `[μ₁, μ₃]` (module doc): `e(c) ∓ sin²θ·(e(c) − μ₁ | μ₃ − e(c)) ∓ sin 2θ·|Ec − e(c)c|`.
    fn range(&self, e: &Matrix3<f64>, [least, greatest]: [f64; 2]) -> [f64; 2] {
        if self.sin_sq >= 0.5 {
            return [least, greatest];
        }
        let image = e * self.centre;
        let at = self.centre.dot(&image);
        let across = (image - at * self.centre).norm();
        let sin_double = 2.0 * (self.sin_sq * (1.0 - self.sin_sq)).sqrt();
        [
            (at - self.sin_sq * (at - least) - sin_double * across).max(least),
            (at + self.sin_sq * (greatest - at) + sin_double * across).min(greatest),
        ]
    }
}

/// The weights `wᵢ = 1 + t·bᵀEᵢb` (`ΣEᵢ = 0`, t ∈ [0, 1], `b` a unit direction) and their
/// tails' quantiles over a cap of directions (module doc).
#[derive(Clone, Debug)]
pub(super) struct DirectionalChiSquare {
    /// `Eᵢ`.
    spreads: Vec<Matrix3<f64>>,
    /// Each `Eᵢ`'s least and greatest eigenvalue.
    extremes: Vec<[f64; 2]>,
    /// `F ≥ 1` (module doc).
    dependence: f64,
}

/// The tail: its grid of λ and its exponent's sign.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Tail {
    Upper,
    Lower,
}

impl Tail {
    /// +1 for the upper tail, −1 for the lower.
    fn sign(self) -> f64 {
        match self {
            Self::Upper => 1.0,
            Self::Lower => -1.0,
        }
    }
}

/// `ln J` (module doc): `ln min(1, 1/(λσ√(2π)) + 2C₀·ratio)`, for tilted standard deviation
/// at least `sigma` and `β/σ³` at most `ratio`.
fn ln_berry_esseen_factor(lambda: f64, sigma: f64, ratio: f64) -> f64 {
    let density = 1.0 / (lambda * sigma * (2.0 * std::f64::consts::PI).sqrt());
    (density + 2.0 * BERRY_ESSEEN * ratio).min(1.0).ln()
}

/// A grid point (within `0..LAMBDA_POINTS`) where `value` is locally least: from `start`
/// (first up the grid while `value` is infinite, towards the upper tail's smaller λ), then
/// walking each way while a neighbour is smaller: `(value, index)`.
fn descend(start: usize, value: impl Fn(usize) -> f64) -> (f64, usize) {
    let mut best = (value(start), start);
    while best.0.is_infinite() && best.1 + 1 < LAMBDA_POINTS {
        best = (value(best.1 + 1), best.1 + 1);
    }
    for step in [1isize, -1] {
        while let Some(next) = best
            .1
            .checked_add_signed(step)
            .filter(|&j| j < LAMBDA_POINTS)
        {
            let v = value(next);
            if v >= best.0 {
                break;
            }
            best = (v, next);
        }
    }
    best
}

impl DirectionalChiSquare {
    /// The weights of spreads `spreads` (`Eᵢ`, summing to 0) for terms of effective
    /// dependence `dependence` (F ≥ 1, module doc).
    pub(super) fn new(spreads: Vec<Matrix3<f64>>, dependence: f64) -> Self {
        let extremes = spreads
            .iter()
            .map(|e| {
                let values = SymmetricEigen::new(*e).eigenvalues;
                [values.min(), values.max()]
            })
            .collect();
        Self {
            spreads,
            extremes,
            dependence,
        }
    }

    /// λ at grid point `j` of `tail`.
    fn lambda(&self, tail: Tail, j: usize) -> f64 {
        let top = match tail {
            Tail::Upper => UPPER_TOP,
            Tail::Lower => LOWER_TOP,
        };
        2f64.powf(f64::from(top - j as i32) / 12.0) / self.dependence
    }

    /// `g` (module doc) of `tail` at λ, scaled for dependence `F`: `(−½ln(1 ∓ 2λFw⁺) ∓ λFw⁺)/F`.
    fn exponent_term(&self, tail: Tail, lambda: f64) -> impl Fn(f64) -> f64 {
        let (f, sign) = (self.dependence, tail.sign());
        move |w: f64| {
            let x = lambda * f * w.max(0.0);
            (-0.5 * (-2.0 * sign * x).ln_1p() - sign * x) / f
        }
    }

    /// `m ± (exponent + ln J − ln p)/λ` for `tail` at grid point `j`, weights at most
    /// `widest` (module doc); ∞ (−∞ for the lower tail) where λ is too large for them.
    fn quantile_of(&self, tail: Tail, j: usize, exponent: f64, widest: f64, ln_p: f64) -> f64 {
        let f = self.dependence;
        let count = self.spreads.len() as f64;
        let lambda = self.lambda(tail, j);
        // `κ·√F/(2^(3/2)·√m)`: `β/σ³` per unit of `max w̃/√(Σw̃²/m)` (module doc).
        let skew = THIRD_ABSOLUTE_MOMENT * f.sqrt() / (8f64.sqrt() * count.sqrt());
        let ln_factor = match tail {
            Tail::Upper => {
                if 2.0 * lambda * f * widest >= 1.0 {
                    return f64::INFINITY;
                }
                let at_mean = 1.0 - 2.0 * lambda * f;
                let sigma = (2.0 * f * count).sqrt() / at_mean;
                let ratio = skew * widest / (1.0 - 2.0 * lambda * f * widest) * at_mean;
                ln_berry_esseen_factor(lambda, sigma, ratio)
            }
            Tail::Lower => {
                let sigma = (2.0 * f * count).sqrt() / (1.0 + 2.0 * lambda * f * widest);
                ln_berry_esseen_factor(lambda, sigma, skew * widest)
            }
        };
        count + tail.sign() * (exponent + ln_factor - ln_p) / lambda
    }

    /// The quantile of `tail` at `e^ln_p` at grid point `j` over the cap `cap`, whose ranges
    /// of `eᵢ` are `ranges` (each `[αᵢ, βᵢ]`): the exponent `K + max bᵀAb` (module doc).
    fn quantile_at(&self, tail: Tail, cap: &Cap, ranges: &[[f64; 2]], ln_p: f64, j: usize) -> f64 {
        let widest = ranges.iter().map(|r| 1.0 + r[1]).fold(1.0, f64::max);
        if tail == Tail::Upper && 2.0 * self.lambda(tail, j) * self.dependence * widest >= 1.0 {
            return f64::INFINITY;
        }
        let g = self.exponent_term(tail, self.lambda(tail, j));
        let (mut base, mut a) = (0.0, Matrix3::zeros());
        for (e, &[low, high]) in self.spreads.iter().zip(ranges) {
            let at_low = g(1.0 + low);
            let slope = if high > low {
                (g(1.0 + high) - at_low) / (high - low)
            } else {
                0.0
            };
            base += at_low - slope * low;
            a += slope * e;
        }
        let values = SymmetricEigen::new(a).eigenvalues;
        let exponent = base + cap.range(&a, [values.min(), values.max()])[1];
        self.quantile_of(tail, j, exponent, widest, ln_p)
    }

    /// The most extreme over `caps` (covering the lines that count) of `tail`'s quantile at
    /// `e^ln_p` (upper: the largest; lower: the least), each cap's found by [`descend`] from
    /// the previous cap's grid point, the first from equal weights' best.
    fn over(&self, tail: Tail, caps: &[Cap], ln_p: f64) -> f64 {
        let sign = tail.sign();
        let count = self.spreads.len() as f64;
        let mut start = (0..LAMBDA_POINTS)
            .map(|j| {
                let exponent = count * self.exponent_term(tail, self.lambda(tail, j))(1.0);
                (sign * self.quantile_of(tail, j, exponent, 1.0, ln_p), j)
            })
            .fold((f64::INFINITY, 0), |a, b| if b.0 < a.0 { b } else { a })
            .1;
        let mut most = f64::NEG_INFINITY;
        for cap in caps {
            let ranges: Vec<[f64; 2]> = self
                .spreads
                .iter()
                .zip(&self.extremes)
                .map(|(e, &extremes)| cap.range(e, extremes))
                .collect();
            let (value, at) = descend(start, |j| {
                sign * self.quantile_at(tail, cap, &ranges, ln_p, j)
            });
            start = at;
            most = most.max(value);
        }
        sign * most
    }

    /// A `q` with `P[X ≥ q] ≤ e^ln_p` for every direction in `caps` and every t (∞ where
    /// none).
    pub(super) fn upper_quantile(&self, caps: &[Cap], ln_p: f64) -> f64 {
        self.over(Tail::Upper, caps, ln_p)
    }

    /// A `q` with `P[X ≤ q] ≤ e^ln_p` for every direction in `caps` and every t (may be ≤ 0:
    /// no lower side).
    pub(super) fn lower_quantile(&self, caps: &[Cap], ln_p: f64) -> f64 {
        self.over(Tail::Lower, caps, ln_p)
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::super::chi_square::{lower_quantile, upper_quantile};
    use super::*;
    use crate::rng::{Purpose, stream};
    use rand_distr::{Distribution, StandardNormal};

    /// The four unit directions of a regular tetrahedron, `(±1, ±1, ±1)/√3` with an even
    /// number of minus signs: `Σₖ uₖuₖᵀ = (4/3)·I`.
    pub(in crate::estimate) fn tetrahedron_directions() -> [Vector3<f64>; 4] {
        [
            [1.0, 1.0, 1.0],
            [1.0, -1.0, -1.0],
            [-1.0, 1.0, -1.0],
            [-1.0, -1.0, 1.0],
        ]
        .map(|u| Vector3::from(u) / 3f64.sqrt())
    }

    /// χ²_m's Chernoff quantile, `m(x − 1 − ln x)/2 = ln(1/p)`, solved by bisection.
    fn chernoff(m: f64, ln_p: f64, above: bool) -> f64 {
        let (mut a, mut b): (f64, f64) = if above { (1.0, 100.0) } else { (1e-9, 1.0) };
        for _ in 0..200 {
            let x = 0.5 * (a + b);
            let rate = 0.5 * m * (x - 1.0 - x.ln());
            if (rate < -ln_p) == above {
                a = x;
            } else {
                b = x;
            }
        }
        m * 0.5 * (a + b)
    }

    /// Every line: one cap of `sin²θ = 1`.
    const WHOLE: Cap = Cap {
        centre: Vector3::new(1.0, 0.0, 0.0),
        sin_sq: 1.0,
    };

    /// At equal weights (`Eᵢ = 0`) the bound is never inside χ²_m's exact
    /// quantile — from 3 terms, where the Berry–Esseen term is large, to 5,000 — and, from
    /// 40 terms, never outside its Chernoff quantile (beyond λ's grid step, 0.2 % of
    /// `|q − m|`; below 40 the lower tail's optimum λ can lie above the grid, which only
    /// widens it); at m = 5,000 and p = 10⁻⁸ it recovers at least 60 % of Chernoff's slack
    /// on each side.
    #[test]
    fn equal_weights_lie_between_the_exact_and_the_chernoff_quantiles() {
        for m in [3usize, 10, 40, 1_000, 5_000] {
            let tails = DirectionalChiSquare::new(vec![Matrix3::zeros(); m], 1.0);
            let n = m as f64;
            for ln_p in [0.01f64.ln(), 1e-8f64.ln(), 1e-12f64.ln()] {
                let (exact_up, exact_down) = (upper_quantile(n, ln_p), lower_quantile(n, ln_p));
                let (up, down) = (
                    tails.upper_quantile(&[WHOLE], ln_p),
                    tails.lower_quantile(&[WHOLE], ln_p),
                );
                let (chernoff_up, chernoff_down) =
                    (chernoff(n, ln_p, true), chernoff(n, ln_p, false));
                eprintln!(
                    "m {m} ln p {ln_p:.1}: up {up:.2} (exact {exact_up:.2}, Chernoff \
                     {chernoff_up:.2}), down {down:.2} (exact {exact_down:.2}, Chernoff \
                     {chernoff_down:.2})"
                );
                assert!(up >= exact_up && down <= exact_down, "m {m} ln p {ln_p}");
                if m >= 40 {
                    assert!(up <= chernoff_up + 2e-3 * (up - n), "m {m} ln p {ln_p}");
                    assert!(
                        down >= chernoff_down - 2e-3 * (n - down),
                        "m {m} ln p {ln_p}"
                    );
                }
                if m == 5_000 && ln_p < -18.0 && ln_p > -19.0 {
                    assert!(chernoff_up - up > 0.6 * (chernoff_up - exact_up));
                    assert!(down - chernoff_down > 0.6 * (exact_down - chernoff_down));
                }
            }
        }
    }

    /// `THIRD_ABSOLUTE_MOMENT` bounds `E|Z² − 1|³` (midpoint rule on [0, 12], 2·10⁶ steps).
    #[test]
    fn the_third_absolute_moment_is_rounded_up() {
        let steps = 2_000_000;
        let h = 12.0 / f64::from(steps);
        let moment: f64 = (0..steps)
            .map(|i| {
                let z = (f64::from(i) + 0.5) * h;
                2.0 * (z * z - 1.0).abs().powi(3) * (-0.5 * z * z).exp()
                    / (2.0 * std::f64::consts::PI).sqrt()
                    * h
            })
            .sum();
        eprintln!("E|Z² − 1|³ ≈ {moment:.7}");
        assert!(moment < THIRD_ABSOLUTE_MOMENT && THIRD_ABSOLUTE_MOMENT - moment < 1e-4);
    }

    /// The bound over the caps holds for the weights of a direction in them, where a
    /// Gaussian tail does not: 200 terms whose spreads point along a tetrahedron's four
    /// directions `uₖ` in turn, `Eᵢ = 3·(uₖuₖᵀ − I/3)` (summing to 0), so that along `u₀`
    /// the weights are 3 for one in four and ⅓ for the rest (mean 1). Over 40,000 seeded
    /// draws of `Σwᵢξᵢ²` at those weights, the quantiles at p = 10⁻³ over the faces' caps
    /// (k = 4) are exceeded at most 40 + 4·√40 ≈ 65 times on each side, while the normal
    /// approximation's upper quantile (`m + z·√(2Σwᵢ²)`) is exceeded more often than that —
    /// the count catches a tail that under-covers. The whole sphere's bound (each `eᵢ` over
    /// all its eigenvalues, every term's in another direction) lies further out than the
    /// caps', and the caps' lies beyond the one direction's own (a cap of θ = 0, where the
    /// chords are exact).
    #[test]
    fn the_bound_over_caps_holds_for_their_directions() {
        let directions = tetrahedron_directions();
        let spreads = (0..200)
            .map(|i| {
                let u = directions[i % 4];
                3.0 * (u * u.transpose()) - Matrix3::identity()
            })
            .collect();
        let tails = DirectionalChiSquare::new(spreads, 1.0);
        let ln_p = 1e-3f64.ln();
        let caps = Cap::of_faces(4);
        let (up, down) = (
            tails.upper_quantile(&caps, ln_p),
            tails.lower_quantile(&caps, ln_p),
        );
        let whole = [
            tails.upper_quantile(&[WHOLE], ln_p),
            tails.lower_quantile(&[WHOLE], ln_p),
        ];
        let along = Cap {
            centre: directions[0],
            sin_sq: 0.0,
        };
        let own = [
            tails.upper_quantile(&[along], ln_p),
            tails.lower_quantile(&[along], ln_p),
        ];
        let weights: Vec<f64> = (0..200)
            .map(|i| if i % 4 == 0 { 3.0 } else { 1.0 / 3.0 })
            .collect();
        let gaussian = 200.0 + 3.0902 * (2.0 * weights.iter().map(|w| w * w).sum::<f64>()).sqrt();
        let mut rng = stream(33, Purpose::Process, 0);
        let mut normal =
            || <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut rng);
        let draws = 40_000;
        let (mut above, mut below, mut beyond_gaussian) = (0, 0, 0);
        for _ in 0..draws {
            let x: f64 = weights.iter().map(|w| w * normal().powi(2)).sum();
            above += u32::from(x > up);
            below += u32::from(x < down);
            beyond_gaussian += u32::from(x > gaussian);
        }
        eprintln!(
            "caps [{down:.1}, {up:.1}], whole sphere {whole:.1?}, the direction's own \
             {own:.1?}: {below} below, {above} above of {draws}; above the normal \
             approximation's {gaussian:.1}: {beyond_gaussian}"
        );
        let limit = f64::from(draws) * 1e-3 + 4.0 * (f64::from(draws) * 1e-3).sqrt();
        assert!(f64::from(above) <= limit && f64::from(below) <= limit);
        assert!(f64::from(beyond_gaussian) > limit);
        assert!(whole[0] > up && whole[1] < down);
        assert!(own[0] <= up && own[1] >= down);
    }
}
