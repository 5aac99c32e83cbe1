//! Tails of a weighted χ², `X = Σᵢ wᵢξᵢ²` (ξᵢ independent standard normals, `Σᵢ wᵢ = m`),
//! bounded at once for every weight vector in a box `wᵢ ∈ [lᵢ, hᵢ]` (docs/estimation.md,
//! "Per-wheel slip": the Wishart bound where slip makes the residuals' covariances unequal).
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
//! `Σwᵢ² ≥ m` give `Σw̃ᵢ² ≥ m/(1 + 2λh)²` (h = max hᵢ); with `Σw̃³ ≤ max w̃·Σw̃²`,
//! `β/σ³ ≤ κ·max w̃/(2^(3/2)·(Σw̃²)^(½))`. A probability `e^(ln_p)` is reached at
//! `q₊ = m + (Σφ_λ + ln J₊ − ln p)/λ` and `q₋ = m − (Σψ_λ + ln J₋ − ln p)/λ`, each λ giving a
//! valid quantile (the best of a fixed geometric grid of λ is taken).
//!
//! **Over the box.** φ_λ and ψ_λ are convex, so on `[lᵢ, hᵢ]` each lies below its chord:
//! `φ(wᵢ) ≤ φ(lᵢ) + sᵢ(wᵢ − lᵢ)`, `sᵢ` the chord's slope. With `Σwᵢ = m` fixed,
//! `Σᵢ sᵢ(wᵢ − lᵢ)` over the box is a fractional knapsack — the budget `m − Σlᵢ` filled with
//! the capacities `hᵢ − lᵢ` in order of falling slope — whose optimum bounds every weight
//! vector of the box (the chord is exact at the box's ends, so at equal weights, a box of
//! width 0, this is χ²_m's own exponent).
//!
//! **Dependence.** Where neighbouring terms are dependent (AR(1) motion noise within a
//! parity half) the terms are taken as `m/F` independent ones of `F` times the weight — the
//! effective count of the Gaussian path's Wishart bound, `F` its deflation: `Σφ_λ(wᵢ)`
//! becomes `Σφ_λ(F·wᵢ)/F`, and the tilted moments `σ² = 2F·Σw̃ᵢ²`, `β = κF²·Σw̃ᵢ³` (with
//! `w̃ᵢ = wᵢ/(1 ∓ 2λFwᵢ)`): the same at F = 1; a stated approximation, as there.

/// λ's grids: from the largest value down by factors `2^(1/12)`, this many points (a factor
/// `2^20` in all; near the optimum the exponent is flat, and the step costs at most 0.2 % of
/// `q − m` in the tests, 0.04 % where the tail is near-Gaussian). The grids are fixed (in
/// units of `1/F`), so a wider box never gives a smaller quantile: the upper one
/// only drops the points where `2λF·max hᵢ ≥ 1`.
const LAMBDA_POINTS: usize = 240;

/// The lower tail's largest λ (in units of `1/F`): `2^(LOWER_TOP/12)`.
const LOWER_TOP: i32 = 72;

/// The upper tail's largest λ (in units of `1/F`): `2^(UPPER_TOP/12) = ½·2^(−1/12)`, just
/// below `1/(2F)`, beyond which no box is feasible (`λ < 1/(2F·max hᵢ)`, `max hᵢ ≥ 1`).
const UPPER_TOP: i32 = -13;

/// Shevtsova's Berry–Esseen constant for sums of independent, not identically distributed
/// terms: `sup|F − Φ| ≤ C₀·Σᵢ E|Yᵢ − EYᵢ|³/σ³`.
const BERRY_ESSEEN: f64 = 0.5600;

/// `κ = E|Z² − 1|³` for a standard normal Z, rounded up: `E(Z² − 1)³ = 8`, plus twice
/// `E[(1 − Z²)³; |Z| < 1] = I₀ − 3I₂ + 3I₄ − I₆ = 0.345781…` (`Iₖ = ∫₋₁¹ zᵏφ(z) dz`,
/// `I₀ = erf(1/√2)`, `Iₖ = (k − 1)·Iₖ₋₂ − 2φ(1)`): 8.691563….
const THIRD_ABSOLUTE_MOMENT: f64 = 8.6916;

/// A box of weights and the tails' exponents over it on a grid of λ.
#[derive(Clone, Debug)]
pub(super) struct WeightedChiSquare {
    /// `m = Σwᵢ`.
    count: f64,
    /// `(λ, max over the weights of Σφ_λ(wᵢ) + ln J₊)` for the upper tail.
    upper: Vec<[f64; 2]>,
    /// `(λ, max over the weights of Σψ_λ(wᵢ) + ln J₋)` for the lower tail.
    lower: Vec<[f64; 2]>,
}

/// `max Σᵢ g(wᵢ)` over `wᵢ ∈ [lᵢ, hᵢ]`, `Σwᵢ = Σᵢ 1`, bounded by the chords (module doc):
/// `g` convex, `boxes` each `[lᵢ, hᵢ]` with `lᵢ ≤ 1 ≤ hᵢ`.
fn chord_maximum(boxes: &[[f64; 2]], g: impl Fn(f64) -> f64) -> f64 {
    let mut base = 0.0;
    let mut budget = boxes.len() as f64;
    let mut chords = Vec::with_capacity(boxes.len());
    for &[l, h] in boxes {
        let at_low = g(l);
        base += at_low;
        budget -= l;
        if h > l {
            chords.push([(g(h) - at_low) / (h - l), h - l]);
        }
    }
    chords.sort_unstable_by(|a, b| b[0].total_cmp(&a[0]));
    for [slope, capacity] in chords {
        if budget <= 0.0 {
            break;
        }
        let take = capacity.min(budget);
        base += slope * take;
        budget -= take;
    }
    base
}

/// `ln J` (module doc): `ln min(1, 1/(λσ√(2π)) + 2C₀·ratio)`, for tilted standard deviation
/// at least `sigma` and `β/σ³` at most `ratio`.
fn ln_berry_esseen_factor(lambda: f64, sigma: f64, ratio: f64) -> f64 {
    let density = 1.0 / (lambda * sigma * (2.0 * std::f64::consts::PI).sqrt());
    (density + 2.0 * BERRY_ESSEEN * ratio).min(1.0).ln()
}

impl WeightedChiSquare {
    /// The tails' exponents over the box `boxes` (each `[lᵢ, hᵢ]`, `0 ≤ lᵢ ≤ 1 ≤ hᵢ`, the
    /// weights' mean 1) for terms of effective dependence `dependence` (F ≥ 1, module doc).
    /// An infinite `hᵢ` leaves the upper tail unbounded.
    pub(super) fn new(boxes: &[[f64; 2]], dependence: f64) -> Self {
        let f = dependence;
        let count = boxes.len() as f64;
        let widest = boxes.iter().map(|b| b[1]).fold(1.0, f64::max);
        // `κ·√F/(2^(3/2)·√m)`: `β/σ³` per unit of `max w̃/√(Σw̃²/m)` (module doc).
        let skew = THIRD_ABSOLUTE_MOMENT * f.sqrt() / (8f64.sqrt() * count.sqrt());
        let upper = (0..LAMBDA_POINTS)
            .map(|j| 2f64.powf(f64::from(UPPER_TOP - j as i32) / 12.0) / f)
            .filter(|lambda| 2.0 * lambda * f * widest < 1.0)
            .map(|lambda| {
                let phi = |w: f64| (-0.5 * (-2.0 * lambda * f * w).ln_1p() - lambda * f * w) / f;
                let exponent = chord_maximum(boxes, phi);
                let at_mean = 1.0 - 2.0 * lambda * f;
                let sigma = (2.0 * f * count).sqrt() / at_mean;
                let ratio = skew * widest / (1.0 - 2.0 * lambda * f * widest) * at_mean;
                [
                    lambda,
                    exponent + ln_berry_esseen_factor(lambda, sigma, ratio),
                ]
            })
            .collect();
        let lower = (0..LAMBDA_POINTS)
            .map(|j| {
                let lambda = 2f64.powf(f64::from(LOWER_TOP - j as i32) / 12.0) / f;
                let psi = |w: f64| (-0.5 * (2.0 * lambda * f * w).ln_1p() + lambda * f * w) / f;
                let exponent = chord_maximum(boxes, psi);
                // An infinite `widest` bounds neither σ below nor β/σ³ above: Chernoff's J ≤ 1.
                let ln_factor = if widest.is_finite() {
                    let at_widest = 1.0 + 2.0 * lambda * f * widest;
                    let sigma = (2.0 * f * count).sqrt() / at_widest;
                    ln_berry_esseen_factor(lambda, sigma, skew * widest)
                } else {
                    0.0
                };
                [lambda, exponent + ln_factor]
            })
            .collect();
        Self {
            count,
            upper,
            lower,
        }
    }

    /// A `q` with `P[X ≥ q] ≤ e^ln_p` for every weight vector allowed (∞ where none).
    pub(super) fn upper_quantile(&self, ln_p: f64) -> f64 {
        self.upper
            .iter()
            .map(|[lambda, exponent]| self.count + (exponent - ln_p) / lambda)
            .fold(f64::INFINITY, f64::min)
    }

    /// A `q` with `P[X ≤ q] ≤ e^ln_p` for every weight vector allowed (may be ≤ 0: no
    /// lower side).
    pub(super) fn lower_quantile(&self, ln_p: f64) -> f64 {
        self.lower
            .iter()
            .map(|[lambda, exponent]| self.count - (exponent - ln_p) / lambda)
            .fold(f64::NEG_INFINITY, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::super::chi_square::{lower_quantile, upper_quantile};
    use super::*;
    use crate::rng::{Purpose, stream};
    use rand_distr::{Distribution, StandardNormal};

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

    /// At equal weights (a box of width 0) the bound is never inside χ²_m's exact
    /// quantile — from 3 terms, where the Berry–Esseen term is large, to 5,000 — and, from
    /// 40 terms, never outside its Chernoff quantile (beyond λ's grid step, 0.2 % of
    /// `|q − m|`; below 40 the lower tail's optimum λ can lie above the grid, which only
    /// widens it); at m = 5,000 and p = 10⁻⁸ it recovers at least 60 % of Chernoff's slack
    /// on each side.
    #[test]
    fn equal_weights_lie_between_the_exact_and_the_chernoff_quantiles() {
        for m in [3usize, 10, 40, 1_000, 5_000] {
            let tails = WeightedChiSquare::new(&vec![[1.0, 1.0]; m], 1.0);
            let n = m as f64;
            for ln_p in [0.01f64.ln(), 1e-8f64.ln(), 1e-12f64.ln()] {
                let (exact_up, exact_down) = (upper_quantile(n, ln_p), lower_quantile(n, ln_p));
                let (up, down) = (tails.upper_quantile(ln_p), tails.lower_quantile(ln_p));
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

    /// The bound over a box holds for weight vectors in it, where a Gaussian tail does not:
    /// over 40,000 seeded draws of `Σwᵢξᵢ²` with 200 weights, one in ten at 5.5 and the rest
    /// at 0.5 (mean 1), the quantiles at p = 10⁻³ of the box `[0.5, 5.5]` are exceeded at
    /// most 40 + 4·√40 ≈ 65 times on each side, while the normal approximation's upper
    /// quantile (`m + z·√(2Σwᵢ²)`) is exceeded more often than that — the count catches a
    /// tail that under-covers; a wider box (`[0, 8]`) gives quantiles further out.
    #[test]
    fn the_bound_over_a_box_holds_for_its_members() {
        let weights: Vec<f64> = (0..200)
            .map(|i| if i % 10 == 0 { 5.5 } else { 0.5 })
            .collect();
        let tight = WeightedChiSquare::new(&vec![[0.5, 5.5]; 200], 1.0);
        let wide = WeightedChiSquare::new(&vec![[0.0, 8.0]; 200], 1.0);
        let ln_p = 1e-3f64.ln();
        let (up, down) = (tight.upper_quantile(ln_p), tight.lower_quantile(ln_p));
        assert!(wide.upper_quantile(ln_p) > up && wide.lower_quantile(ln_p) < down);
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
            "[{down:.1}, {up:.1}]: {below} below, {above} above of {draws}; above the \
             normal approximation's {gaussian:.1}: {beyond_gaussian}"
        );
        let limit = f64::from(draws) * 1e-3 + 4.0 * (f64::from(draws) * 1e-3).sqrt();
        assert!(f64::from(above) <= limit && f64::from(below) <= limit);
        assert!(f64::from(beyond_gaussian) > limit);
    }
}
