//! Bounds on the extreme eigenvalues of a 3×3 Wishart matrix `W = W₃(I, m)/m`, from each
//! direction's exact χ² tail and a net of directions (docs/estimation.md, "The region").
//!
//! For a unit vector `u`, `m·uᵀWu` is exactly χ²_m. A net `N` of lines through the origin
//! (antipodal directions give the same quadratic form) whose every line lies within an angle
//! θ of one of its members bounds the whole sphere: `W ⪰ 0`, so with `v` the top eigenvector
//! and `u ∈ N` within θ of it, `uᵀWu = Σᵢ λᵢ(u·eᵢ)² ≥ λ_max·cos²θ`, and with `w` the bottom
//! one and `u` within θ of it, `uᵀWu ≤ λ_min·cos²θ + λ_max·sin²θ`. A union bound over the
//! net's `|N|` lines then gives, with `q₊` the χ²_m upper quantile and `q₋` the lower one,
//! each at `ε_side/|N|`:
//!
//! ```text
//! λ_max ≤ c₊ = q₊/(m·cos²θ)                      except with probability ε_side,
//! λ_min ≥ c₋ = (q₋/m − c₊·sin²θ)/cos²θ           except with probability ε_side
//!                                                 where λ_max ≤ c₊,
//! ```
//!
//! so both hold except with probability 2ε_side. The net: each of the cube's three face pairs
//! `{|x_a| = 1}` (a line meets one of them where its largest coordinate is ±1) cut into k×k
//! squares, their centres the net's `3k²` lines. A line through a face point `p` (`|p| ≥ 1`)
//! lies within `h/√2 = √2/k` of a centre `g` (half a square's diagonal, `h = 2/k`), so
//! `sin θ ≤ |p − g|/|p| ≤ √2/k`: `sin²θ ≤ 2/k²`. k is chosen per side on a ladder, the
//! tightest bound it gives (every k's bound holds; the choice depends on m and ε only).
//!
//! At m = 14,319 and ε_side ≈ 1.7·10⁻⁷ this gives c₊ ≈ 1.08, where Davidson–Szarek's
//! `(1 + √(3/m) + √(2 ln(1/ε_side)/m))²` is 1.126. For a non-integer m (an effective count)
//! the χ² is the Gamma distribution of that shape, the count's own approximation unchanged.

use super::chi_square::{lower_quantile, upper_quantile};

/// The net's squares per face side tried: a ladder of ratio ≈ √2 from 2 to 256 (k = 1 leaves
/// `sin²θ ≤ 2`, no bound).
const FACE_CUTS: [u32; 15] = [2, 3, 4, 6, 8, 11, 16, 23, 32, 45, 64, 91, 128, 181, 256];

/// `[c₋, c₊]`: `c₋ ≤ λ_min(W) ≤ λ_max(W) ≤ c₊` for `W = W₃(I, m)/m`, the upper side failing
/// with probability at most `epsilon/2` and the lower side at most `epsilon/2` beyond it
/// (module doc). `c₋` may be ≤ 0: too few residuals for a lower side.
pub(super) fn wishart_bounds(m: f64, epsilon: f64) -> [f64; 2] {
    net_bounds(
        m,
        epsilon,
        |ln_p| upper_quantile(m, ln_p),
        |ln_p| lower_quantile(m, ln_p),
    )
}

/// `[c₋, c₊]` over the net (module doc) for any law of `m·uᵀWu` along each line: `upper(ln_p)`
/// a `q₊` with `P[m·uᵀWu > q₊] ≤ e^ln_p` and `lower(ln_p)` a `q₋` with
/// `P[m·uᵀWu < q₋] ≤ e^ln_p`, for every line of the net; each side fails with probability at
/// most `epsilon/2` (the lower one where the upper holds). `wishart_bounds` with χ²_m's
/// quantiles; the slip path's weighted χ² (`weighted_chi_square`) with its tilted-tail ones
/// (Chernoff's sharpened by Berry–Esseen).
pub(super) fn net_bounds(
    m: f64,
    epsilon: f64,
    upper: impl Fn(f64) -> f64,
    lower: impl Fn(f64) -> f64,
) -> [f64; 2] {
    let ln_side = (0.5 * epsilon).ln();
    let lines = |k: u32| (3.0 * f64::from(k) * f64::from(k)).ln();
    let sin2 = |k: u32| 2.0 / f64::from(k * k);
    let most = FACE_CUTS
        .iter()
        .map(|&k| upper(ln_side - lines(k)) / (m * (1.0 - sin2(k))))
        .fold(f64::INFINITY, f64::min);
    let least = FACE_CUTS
        .iter()
        .map(|&k| (lower(ln_side - lines(k)) / m - most * sin2(k)) / (1.0 - sin2(k)))
        .fold(f64::NEG_INFINITY, f64::max);
    [least, most]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{Purpose, stream};
    use nalgebra::{Matrix3, SymmetricEigen, Vector3};
    use rand_distr::{Distribution, StandardNormal};

    /// Davidson–Szarek's `(1 ± √(3/m) ± √(2 ln(2/ε)/m))²`, each side at ε/2.
    fn davidson_szarek(m: f64, epsilon: f64, sign: f64) -> f64 {
        (1.0 + sign * ((3.0 / m).sqrt() + (2.0 * (2.0 / epsilon).ln() / m).sqrt())).powi(2)
    }

    /// Never looser than Davidson–Szarek at the same level, from 30 residuals to 10⁶ and from
    /// ε = 0.1 to 10⁻¹².
    #[test]
    fn the_bound_is_never_looser_than_davidson_szarek() {
        for m in [30.0, 100.0, 333.3, 1_000.0, 5_226.0, 14_319.0, 1e5, 1e6] {
            for epsilon in [0.1, 1e-3, 1e-6, 1e-9, 1e-12] {
                let [lower, upper] = wishart_bounds(m, epsilon);
                let (ds_lower, ds_upper) = (
                    davidson_szarek(m, epsilon, -1.0),
                    davidson_szarek(m, epsilon, 1.0),
                );
                eprintln!(
                    "m {m} ε {epsilon}: [{lower:.4}, {upper:.4}] against [{ds_lower:.4}, {ds_upper:.4}]"
                );
                assert!(upper <= ds_upper, "m {m} ε {epsilon}: {upper} > {ds_upper}");
                // Davidson–Szarek's lower side is only a bound while its root is positive.
                if (3.0 / m).sqrt() + (2.0 * (2.0 / epsilon).ln() / m).sqrt() < 1.0 {
                    assert!(lower >= ds_lower, "m {m} ε {epsilon}: {lower} < {ds_lower}");
                }
                assert!(1.0 < upper && lower < 1.0, "m {m} ε {epsilon}");
            }
        }
    }

    /// The bound holds: over 20,000 seeded draws of `W₃(I, m)/m` at m = 40 and ε = 0.02, the
    /// largest eigenvalue exceeds `c₊` in at most ε/2 of them, and the smallest falls below
    /// `c₋` (with the largest below `c₊`) in at most ε/2 — each count within 4 binomial
    /// standard deviations of 200, `√(20000·0.01·0.99) ≈ 14`: at most 256.
    #[test]
    fn the_bound_misses_at_most_its_level() {
        let (m, epsilon, draws) = (40, 0.02, 20_000);
        let [lower, upper] = wishart_bounds(f64::from(m), epsilon);
        let mut rng = stream(21, Purpose::Process, 0);
        let mut normal =
            || <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut rng);
        let (mut above, mut below) = (0, 0);
        for _ in 0..draws {
            let mut w = Matrix3::zeros();
            for _ in 0..m {
                let x = Vector3::new(normal(), normal(), normal());
                w += x * x.transpose();
            }
            let eigenvalues = SymmetricEigen::new(w / f64::from(m)).eigenvalues;
            let (least, most) = (eigenvalues.min(), eigenvalues.max());
            above += u32::from(most > upper);
            below += u32::from(most <= upper && least < lower);
        }
        eprintln!("m {m}: c₋ {lower:.4} c₊ {upper:.4}; {below} below, {above} above of {draws}");
        let limit = f64::from(draws) * epsilon / 2.0
            + 4.0 * (f64::from(draws) * epsilon / 2.0 * (1.0 - epsilon / 2.0)).sqrt();
        assert!(f64::from(above) <= limit, "{above} above c₊ {upper}");
        assert!(f64::from(below) <= limit, "{below} below c₋ {lower}");
    }
}
