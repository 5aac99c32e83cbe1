//! Bounds on the extreme eigenvalues of a 3×3 Wishart matrix `W = W₃(I, m)/m`, from each
//! direction's exact χ² tail and a net of directions (docs/estimation.md, "The region").
//!
//! For a unit vector `u`, `m·uᵀWu` is exactly χ²_m. A net `N` of lines through the origin
//! (antipodal directions give the same quadratic form) whose every line lies within an angle
//! θ of one of its members bounds the whole sphere. With `v` the top eigenvector and `u ∈ N`
//! within θ of it, `u = cos θ·v + sin θ·e` (`e ⊥ v`), so `uᵀWu = λ_max·cos²θ + eᵀWe·sin²θ ≥
//! λ_max·(1 − s) + λ_min·s` for `s ≥ sin²θ`; with `w` the bottom eigenvector and `u` within
//! θ of it, `uᵀWu ≤ λ_min·(1 − s) + λ_max·s` alike. Two nets, `N₁` (every line within
//! `sin²θ ≤ s₁`) for the upper side and `N₂` (`s₂`) for the lower, each with a union bound at
//! the χ²_m quantiles `q₊` of `ε/(2|N₁|)` and `q₋` of `ε/(2|N₂|)`: except with probability
//! ε, every line of `N₁` has `m·uᵀWu ≤ q₊` and every line of `N₂` has `m·uᵀWu ≥ q₋`, and
//! then, with `a = q₊/m` and `b = q₋/m`,
//!
//! ```text
//! λ_max·(1 − s₁) + λ_min·s₁ ≤ a,    λ_min·(1 − s₂) + λ_max·s₂ ≥ b,    λ_min ≥ 0.
//! ```
//!
//! The largest `λ_max` and the least `λ_min` these allow (a two-variable linear programme,
//! `s₁ + s₂ < 1`) are
//!
//! ```text
//! c₊ = min(a/(1 − s₁), (a·(1 − s₂) − b·s₁)/(1 − s₁ − s₂)),   c₋ = (b − c₊·s₂)/(1 − s₂):
//! ```
//!
//! the first term of `c₊` where the lower side leaves `λ_min` at 0 (`b·(1 − s₁) ≤ a·s₂`), the
//! second where both constraints meet. Both bounds hold on the one event, so
//! `c₋ ≤ λ_min(W) ≤ λ_max(W) ≤ c₊` except with probability ε. Where only `W ⪰ 0` is used
//! (`λ_min ≥ 0`), `c₊ = a/(1 − s₁)`: the lower side's net tightens the upper bound by
//! `(b·(1 − s₁) − a·s₂)·s₁/((1 − s₁)(1 − s₁ − s₂))`, the covering's cost falling from
//! `c₊·s₁` to about `(c₊ − c₋)·s₁`.
//!
//! The nets: each of the cube's three face pairs `{|x_a| = 1}` (a line meets one of them
//! where its largest coordinate is ±1) cut into k×k squares, their centres the net's `3k²`
//! lines. A line through a face point `p` (`|p| ≥ 1`) lies within `h/√2 = √2/k` of a centre
//! `g` (half a square's diagonal, `h = 2/k`), so `sin θ ≤ |p − g|/|p| ≤ √2/k`: `s = 2/k²`. The
//! pair `(k₁, k₂)` is the ladder's pair that gives χ²_m's tightest `c₊`; it depends on m
//! and ε only, never on the data, so its event is one fixed event.
//!
//! At m = 14,319 and ε ≈ 1.7·10⁻⁷ (a three-step block's share per half at ε_est = 10⁻⁶) this
//! gives c₊ ≈ 1.078 (1.080 from the upper side alone at the whole ε with `λ_min ≥ 0`), where
//! Davidson–Szarek's `(1 + √(3/m) + √(2 ln(2/ε)/m))²` is 1.128. For a non-integer m (an
//! effective count) the χ² is the Gamma distribution of that shape, the count's own
//! approximation unchanged.

use super::chi_square::{lower_quantile, upper_quantile};

/// The net's squares per face side tried: a ladder of ratio ≈ √2 from 2 to 256 (k = 1 leaves
/// `sin²θ ≤ 2`, no bound). A finer ladder (every k from 2 to 256) moves `c₊` by 10⁻⁴.
const FACE_CUTS: [u32; 15] = [2, 3, 4, 6, 8, 11, 16, 23, 32, 45, 64, 91, 128, 181, 256];

/// `[c₋, c₊]`: `c₋ ≤ λ_min(W) ≤ λ_max(W) ≤ c₊` for `W = W₃(I, m)/m` except with probability
/// at most `epsilon`, both on one event (module doc). `c₋` may be ≤ 0: too few residuals for a
/// lower side.
pub(super) fn wishart_bounds(m: f64, epsilon: f64) -> [f64; 2] {
    net_bounds(
        m,
        epsilon,
        |ln_p| upper_quantile(m, ln_p),
        |ln_p| lower_quantile(m, ln_p),
    )
}

/// `[c₋, c₊]` where `c₊` alone must hold except with probability `epsilon`: the joint nets'
/// bound at `epsilon` (`wishart_bounds`, `c₋` on the same event) or, where it is tighter, the
/// upper side alone at `epsilon` with only `λ_min ≥ 0` (`c₊ = a/(1 − s₁)`, the best k of the
/// ladder) and `c₋` from a lower net at `epsilon` more, holding where both do. The upper side
/// alone wins with few residuals, where the lower side's net gains less than halving each
/// side's probability costs: below about 1,000 at ε = 2.5·10⁻⁷. The choice is by m and ε
/// alone.
pub(super) fn wishart_upper_bounds(m: f64, epsilon: f64) -> [f64; 2] {
    let joint = wishart_bounds(m, epsilon);
    let ln_p = |k: u32| epsilon.ln() - net(k).1;
    let most = FACE_CUTS
        .iter()
        .map(|&k| upper_quantile(m, ln_p(k)) / (m * (1.0 - net(k).0)))
        .fold(f64::INFINITY, f64::min);
    if joint[1] <= most {
        return joint;
    }
    let least = FACE_CUTS
        .iter()
        .map(|&k| {
            let s = net(k).0;
            (lower_quantile(m, ln_p(k)) / m - most * s) / (1.0 - s)
        })
        .fold(f64::NEG_INFINITY, f64::max);
    [least, most]
}

/// `sin²θ`'s bound for the net of `k` squares per face side, `s = 2/k²`, and the log of its
/// line count, `ln 3k²`.
fn net(k: u32) -> (f64, f64) {
    let k = f64::from(k);
    (2.0 / (k * k), (3.0 * k * k).ln())
}

/// `[c₋, c₊]` (module doc) from `a = q₊/m` on the upper net of `sin²θ ≤ s₁` and `b = q₋/m` on
/// the lower one of `sin²θ ≤ s₂` (`s₁ + s₂ < 1`).
fn covered([a, b]: [f64; 2], [s1, s2]: [f64; 2]) -> [f64; 2] {
    let most = (a / (1.0 - s1)).min((a * (1.0 - s2) - b * s1) / (1.0 - s1 - s2));
    [(b - most * s2) / (1.0 - s2), most]
}

/// The ladder's pair `(k₁, k₂)` with χ²_m's tightest `c₊` at `epsilon` (its greatest `c₋`
/// breaks ties): a function of m and ε alone (module doc).
fn chosen_nets(m: f64, epsilon: f64) -> [u32; 2] {
    let ln_side = (0.5 * epsilon).ln();
    let quantiles: Vec<[f64; 2]> = FACE_CUTS
        .iter()
        .map(|&k| {
            let ln_p = ln_side - net(k).1;
            [upper_quantile(m, ln_p) / m, lower_quantile(m, ln_p) / m]
        })
        .collect();
    let mut best = ([FACE_CUTS[0]; 2], [f64::INFINITY; 2]);
    for (i, &k1) in FACE_CUTS.iter().enumerate() {
        for (j, &k2) in FACE_CUTS.iter().enumerate() {
            let s = [net(k1).0, net(k2).0];
            if s[0] + s[1] >= 1.0 {
                continue;
            }
            let [least, most] = covered([quantiles[i][0], quantiles[j][1]], s);
            if (most, -least) < (best.1[1], -best.1[0]) {
                best = ([k1, k2], [least, most]);
            }
        }
    }
    best.0
}

/// `[c₋, c₊]` over the nets (module doc) for any law of `m·uᵀWu` along each line:
/// `upper(ln_p)` a `q₊` with `P[m·uᵀWu > q₊] ≤ e^ln_p` and `lower(ln_p)` a `q₋` with
/// `P[m·uᵀWu < q₋] ≤ e^ln_p`, for every line of the nets; both sides hold except with
/// probability at most `epsilon`. The nets are the pair χ²_m chooses at `epsilon`
/// (`chosen_nets`), whatever `upper` and `lower` are, so that the event is fixed by m and ε.
/// `wishart_bounds` with χ²_m's quantiles; the slip path's weighted χ²
/// (`weighted_chi_square`) with its tilted-tail ones (Chernoff's sharpened by Berry–Esseen).
/// The two sides are independent: `rayon::join` evaluates them on the current pool (the slip
/// path's quantiles, each over every cap of directions, are the largest part of a slip
/// block's region).
pub(super) fn net_bounds(
    m: f64,
    epsilon: f64,
    upper: impl Fn(f64) -> f64 + Sync,
    lower: impl Fn(f64) -> f64 + Sync,
) -> [f64; 2] {
    let ln_side = (0.5 * epsilon).ln();
    let [k1, k2] = chosen_nets(m, epsilon);
    let (s1, lines1) = net(k1);
    let (s2, lines2) = net(k2);
    let (q_upper, q_lower) = rayon::join(|| upper(ln_side - lines1), || lower(ln_side - lines2));
    covered([q_upper / m, q_lower / m], [s1, s2])
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
    /// largest eigenvalue exceeds `c₊` or the smallest falls below `c₋` in at most ε of them —
    /// within 4 binomial standard deviations of 400, `√(20000·0.02·0.98) ≈ 20`: at most 480.
    /// At m = 40 the nets are coarse (`s₁`, `s₂` of 0.06–0.13), where the lower side's share
    /// in `c₊` is largest.
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
        eprintln!(
            "m {m}: nets {:?}, c₋ {lower:.4} c₊ {upper:.4}; {below} below, {above} above of \
             {draws}",
            chosen_nets(f64::from(m), epsilon)
        );
        let limit = f64::from(draws) * epsilon
            + 4.0 * (f64::from(draws) * epsilon * (1.0 - epsilon)).sqrt();
        assert!(
            f64::from(above + below) <= limit,
            "{above} above c₊ {upper}, {below} below c₋ {lower}"
        );
    }

    /// Where only `c₊` must hold, the choice is never looser than either form: from 30 to 10⁶
    /// residuals at ε = 2.5·10⁻⁷, `c₊` is the joint nets' at ε or the upper side's alone at ε,
    /// whichever is smaller — the upper side alone below 1,000 residuals, the joint nets from
    /// 2,000 on.
    #[test]
    fn where_only_the_upper_side_counts_the_tighter_form_is_taken() {
        let epsilon = 2.5e-7;
        for m in [30.0, 100.0, 500.0, 2_000.0, 14_319.0, 1e6] {
            let [_, chosen] = wishart_upper_bounds(m, epsilon);
            let [_, joint] = wishart_bounds(m, epsilon);
            let alone = FACE_CUTS
                .iter()
                .map(|&k| upper_quantile(m, epsilon.ln() - net(k).1) / (m * (1.0 - net(k).0)))
                .fold(f64::INFINITY, f64::min);
            eprintln!("m {m}: chosen {chosen:.5}, joint {joint:.5}, upper side alone {alone:.5}");
            assert_eq!(chosen, joint.min(alone), "m {m}");
            assert_eq!(chosen == alone, m < 1_000.0, "m {m}");
        }
    }

    /// `covered` is the linear programme's optimum: over a 400×400 grid of `(λ_min, λ_max)`
    /// (`0 ≤ λ_min ≤ λ_max ≤ 3`), every pair meeting the two nets' constraints lies within
    /// `[c₋, c₊]`, and some meet them within a grid step of `c₊` and of `c₋` — at coarse and
    /// at fine nets, and where the lower side leaves `λ_min` at 0.
    #[test]
    fn the_covering_is_the_linear_programmes_optimum() {
        for (a, b, s) in [
            (1.3, 0.75, [0.125, 0.0555]),
            (1.08, 0.93, [0.0165, 0.0078]),
            (1.5, 0.05, [0.2, 0.2]),
        ] {
            let [least, most] = covered([a, b], s);
            let step = 3.0 / 400.0;
            let (mut top, mut bottom) = (f64::NEG_INFINITY, f64::INFINITY);
            for i in 0..=400 {
                for j in i..=400 {
                    let (low, high) = (f64::from(i) * step, f64::from(j) * step);
                    if high * (1.0 - s[0]) + low * s[0] <= a
                        && low * (1.0 - s[1]) + high * s[1] >= b
                    {
                        top = top.max(high);
                        bottom = bottom.min(low);
                    }
                }
            }
            eprintln!("a {a} b {b} s {s:?}: [{least:.4}, {most:.4}], grid [{bottom:.4}, {top:.4}]");
            assert!(
                top <= most && most - top < 2.0 * step,
                "{top} against {most}"
            );
            assert!(bottom >= least.max(0.0) - 1e-12 && bottom - least.max(0.0) < 2.0 * step);
            assert!(most < a / (1.0 - s[0]) || b * (1.0 - s[0]) <= a * s[1]);
        }
    }
}
