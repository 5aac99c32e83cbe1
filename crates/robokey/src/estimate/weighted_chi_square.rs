//! Tails of a weighted χ², `X = Σᵢ wᵢξᵢ²` (ξᵢ independent standard normals, `Σᵢ wᵢ = m`),
//! bounded at once for every weight vector in a box `wᵢ ∈ [lᵢ, hᵢ]` (docs/estimation.md,
//! "Per-wheel slip": the Wishart bound where slip makes the residuals' covariances unequal).
//!
//! **Chernoff.** For `0 < λ < 1/(2·max wᵢ)`, `E[e^(λX)] = Πᵢ(1 − 2λwᵢ)^(−½)`, so
//!
//! ```text
//! P[X ≥ q] ≤ exp(−λ(q − m) + Σᵢ φ_λ(wᵢ)),   φ_λ(w) = −½ ln(1 − 2λw) − λw,
//! P[X ≤ q] ≤ exp(−λ(m − q) + Σᵢ ψ_λ(wᵢ)),   ψ_λ(w) = −½ ln(1 + 2λw) + λw   (λ > 0),
//! ```
//!
//! exact bounds for known weights; a probability `e^(ln_p)` is reached at
//! `q₊ = m + (Σφ_λ + ln(1/p))/λ` and `q₋ = m − (Σψ_λ + ln(1/p))/λ`, each λ giving a valid
//! quantile (the best of a geometric grid of λ is taken; its choice depends on the box only).
//!
//! **Over the box.** φ_λ and ψ_λ are convex, so on `[lᵢ, hᵢ]` each lies below its chord:
//! `φ(wᵢ) ≤ φ(lᵢ) + sᵢ(wᵢ − lᵢ)`, `sᵢ` the chord's slope. With `Σwᵢ = m` fixed,
//! `Σᵢ sᵢ(wᵢ − lᵢ)` over the box is a fractional knapsack — the budget `m − Σlᵢ` filled with
//! the capacities `hᵢ − lᵢ` in order of falling slope — whose optimum bounds every weight
//! vector of the box (the chord is exact at the box's ends, so at equal weights, a box of
//! width 0, this is χ²_m's own Chernoff bound).
//!
//! **Dependence.** Where neighbouring terms are dependent (AR(1) motion noise within a
//! parity half) the terms are taken as `m/F` independent ones of `F` times the weight — the
//! effective count of the Gaussian path's Wishart bound, `F` its deflation: `Σφ_λ(wᵢ)`
//! becomes `Σφ_λ(F·wᵢ)/F` (the same at F = 1; a stated approximation, as there).

/// λ's grids: from the largest value down by factors `2^(1/12)`, this many points (a factor
/// `2^20` in all; near the optimum the exponent is flat, and the step costs at most 0.2 % of
/// `q − m` in the tests, 0.04 % where the tail is near-Gaussian).
const LAMBDA_POINTS: usize = 240;

/// The lower tail's largest λ (in units of `1/F`): `2^(LOWER_TOP/12)`.
const LOWER_TOP: i32 = 72;

/// A box of weights and the Chernoff exponents over it on a grid of λ.
#[derive(Clone, Debug)]
pub(super) struct WeightedChiSquare {
    /// `m = Σwᵢ`.
    count: f64,
    /// `(λ, max over the box of Σφ_λ(wᵢ))` for the upper tail.
    upper: Vec<[f64; 2]>,
    /// `(λ, max over the box of Σψ_λ(wᵢ))` for the lower tail.
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

impl WeightedChiSquare {
    /// The tails' exponents over the box `boxes` (each `[lᵢ, hᵢ]`, `0 ≤ lᵢ ≤ 1 ≤ hᵢ`, the
    /// weights' mean 1) for terms of effective dependence `dependence` (F ≥ 1, module doc).
    /// An infinite `hᵢ` leaves the upper tail unbounded.
    pub(super) fn new(boxes: &[[f64; 2]], dependence: f64) -> Self {
        let f = dependence;
        let count = boxes.len() as f64;
        let widest = boxes.iter().map(|b| b[1]).fold(1.0, f64::max);
        let step = 2f64.powf(-1.0 / 12.0);
        let top = 0.5 / (f * widest);
        let upper = if top > 0.0 {
            (1..=LAMBDA_POINTS)
                .map(|j| {
                    let lambda = top * step.powi(j as i32);
                    let phi =
                        |w: f64| (-0.5 * (-2.0 * lambda * f * w).ln_1p() - lambda * f * w) / f;
                    [lambda, chord_maximum(boxes, phi)]
                })
                .collect()
        } else {
            Vec::new()
        };
        let lower = (0..LAMBDA_POINTS)
            .map(|j| {
                let lambda = 2f64.powf(f64::from(LOWER_TOP - j as i32) / 12.0) / f;
                let psi = |w: f64| (-0.5 * (2.0 * lambda * f * w).ln_1p() + lambda * f * w) / f;
                [lambda, chord_maximum(boxes, psi)]
            })
            .collect();
        Self {
            count,
            upper,
            lower,
        }
    }

    /// A `q` with `P[X ≥ q] ≤ e^ln_p` for every weight vector in the box (∞ where none).
    pub(super) fn upper_quantile(&self, ln_p: f64) -> f64 {
        self.upper
            .iter()
            .map(|[lambda, exponent]| self.count + (exponent - ln_p) / lambda)
            .fold(f64::INFINITY, f64::min)
    }

    /// A `q` with `P[X ≤ q] ≤ e^ln_p` for every weight vector in the box (may be ≤ 0: no
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

    /// At equal weights (a box of width 0) the bound is χ²_m's Chernoff bound: never inside
    /// the exact quantile, and within 0.2 % of `|q − m|` of the Chernoff quantile solved
    /// exactly (λ's grid step).
    #[test]
    fn equal_weights_give_the_chi_square_chernoff_bound() {
        for m in [40usize, 1_000, 5_000] {
            let tails = WeightedChiSquare::new(&vec![[1.0, 1.0]; m], 1.0);
            let n = m as f64;
            for ln_p in [0.01f64.ln(), 1e-8f64.ln(), 1e-12f64.ln()] {
                let (exact_up, exact_down) = (upper_quantile(n, ln_p), lower_quantile(n, ln_p));
                let (up, down) = (tails.upper_quantile(ln_p), tails.lower_quantile(ln_p));
                // The exact Chernoff quantile: m(x − 1 − ln x)/2 = ln(1/p), solved by bisection.
                let chernoff = |above: bool| {
                    let (mut a, mut b): (f64, f64) = if above { (1.0, 10.0) } else { (1e-9, 1.0) };
                    for _ in 0..200 {
                        let x = 0.5 * (a + b);
                        let rate = 0.5 * n * (x - 1.0 - x.ln());
                        if (rate < -ln_p) == above {
                            a = x;
                        } else {
                            b = x;
                        }
                    }
                    n * 0.5 * (a + b)
                };
                eprintln!(
                    "m {m} ln p {ln_p:.1}: up {up:.2} (exact {exact_up:.2}, Chernoff {:.2}), \
                     down {down:.2} (exact {exact_down:.2}, Chernoff {:.2})",
                    chernoff(true),
                    chernoff(false)
                );
                assert!(up >= exact_up && down <= exact_down, "m {m} ln p {ln_p}");
                assert!(
                    (up - chernoff(true)).abs() < 2e-3 * (up - n),
                    "m {m} ln p {ln_p}"
                );
                assert!(
                    (down - chernoff(false)).abs() < 2e-3 * (n - down),
                    "m {m} ln p {ln_p}"
                );
            }
        }
    }

    /// The bound over a box holds for weight vectors in it: over 40,000 seeded draws of
    /// `Σwᵢξᵢ²` with 200 weights, one in ten at 5.5 and the rest at 0.5 (mean 1), the upper
    /// quantile at p = 10⁻³ of the box `[0.5, 5.5]` is exceeded at most 40 + 4·√40 ≈ 65
    /// times and the lower one undershot as often at most; a box that admits the vector
    /// but is wider (`[0, 8]`) gives quantiles further out.
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
        let mut rng = stream(33, Purpose::Process, 0);
        let mut normal =
            || <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut rng);
        let draws = 40_000;
        let (mut above, mut below) = (0, 0);
        for _ in 0..draws {
            let x: f64 = weights.iter().map(|w| w * normal().powi(2)).sum();
            above += u32::from(x > up);
            below += u32::from(x < down);
        }
        eprintln!("[{down:.1}, {up:.1}]: {below} below, {above} above of {draws}");
        let limit = f64::from(draws) * 1e-3 + 4.0 * (f64::from(draws) * 1e-3).sqrt();
        assert!(f64::from(above) <= limit && f64::from(below) <= limit);
    }
}
