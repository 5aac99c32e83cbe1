//! A bit seen through a consistent Gaussian log-likelihood ratio (docs/secrecy.md, "Private
//! sensing").
//!
//! A party whose observation of a uniform bit `B` is Gaussian, with means a Mahalanobis
//! distance `d` apart under its noise, holds the log-likelihood ratio in favour of the true
//! bit `L ~ N(d²/2, d²)` (natural log). Its error rate is `Q(d/2)`, its surprisal of the true
//! bit is `S = log₂(1 + e^{−L})` bits, and its information is `I(B; view) = 1 − E[S]`. A
//! larger `d` is a more informative (Blackwell-dominating) view, so every bound below is
//! monotone in `d`: a bound at the largest separation holds for every smaller one.

use serde::{Deserialize, Serialize};

use crate::min_entropy::{MinEntropyError, check_epsilon};
use crate::view_profile::{BitView, ViewGroup, profile_smooth_min_entropy};

/// Grid of the standard normal variable for the expectations: `z ∈ [−Z, Z]`.
const Z: f64 = 12.0;
/// Trapezoid steps over the grid (spectrally accurate for smooth integrands).
const STEPS: usize = 2_400;

/// The grid's points `z` and their trapezoid weights times the Gaussian kernel `e^{−z²/2}`,
/// which do not depend on the separation: computed once.
pub(crate) fn grid() -> &'static [(f64, f64)] {
    static GRID: std::sync::OnceLock<Vec<(f64, f64)>> = std::sync::OnceLock::new();
    GRID.get_or_init(|| {
        let h = 2.0 * Z / STEPS as f64;
        (0..=STEPS)
            .map(|i| {
                let z = -Z + h * i as f64;
                let weight = if i == 0 || i == STEPS { 0.5 } else { 1.0 };
                (z, weight * (-0.5 * z * z).exp())
            })
            .collect()
    })
}

/// The trapezoid terms of `E[g(S)]` for the surprisal `S` of a view with separation `d`,
/// over the grid in order: `(z, L, w·e^{−z²/2}·g(S(L)))` with `L = d²/2 + d·z`.
fn terms(separation: f64, g: impl Fn(f64) -> f64) -> impl Iterator<Item = (f64, f64, f64)> {
    let (mean, std) = (separation * separation / 2.0, separation);
    grid().iter().map(move |&(z, kernel)| {
        let llr = mean + std * z;
        (z, llr, kernel * g(surprisal(llr)))
    })
}

/// A sum of the terms times the trapezoid step and the Gaussian density's constant.
pub(crate) fn integral(sum: f64) -> f64 {
    let h = 2.0 * Z / STEPS as f64;
    sum * h / (2.0 * std::f64::consts::PI).sqrt()
}

/// `(kernel weight, S)` at each grid point for a view with separation `d`: the terms of
/// `E[g(S)]` before `g`, `L = d²/2 + d·z` (the same operations as [`terms`], so a sum over
/// them is the same bit for bit).
pub(crate) fn surprisal_table(separation: f64) -> Vec<(f64, f64)> {
    let (mean, std) = (separation * separation / 2.0, separation);
    grid()
        .iter()
        .map(|&(z, kernel)| (kernel, surprisal(mean + std * z)))
        .collect()
}

/// A term below this fraction of a positive sum is below a quarter of the sum's last-place
/// unit, which is more than `2^−53` of it.
const NEGLIGIBLE: f64 = f64::EPSILON / 8.0;

/// `E[S]`, the trapezoid sum over [`surprisal_table`], bit for bit, without its negligible
/// tail. Past the mean (`z > 0` and `L > 0`) every term is smaller than the one before (the
/// kernel falls with `z`, `S` with `L`); once a term is below a quarter of the last-place
/// unit of the sum, each later one is below half of it (rounding errors of a few units in
/// the last place cannot double a term), so adding it leaves the sum as it is (round to
/// nearest): the tail is not computed. It is a sixth to a third of the grid for the
/// separations of private sensing; every eighth term is checked, so that the check costs
/// less than it saves.
pub(crate) fn expected_surprisal(separation: f64) -> f64 {
    let mut sum = 0.0;
    let mut terms = terms(separation, |s| s);
    for (z, llr, term) in terms.by_ref() {
        sum += term;
        if z > 0.0 && llr > 0.0 {
            break;
        }
    }
    // Past the mean: a term, checked every eighth, that is negligible ends the sum.
    let mut i = 0_u32;
    for (_, _, term) in terms {
        sum += term;
        i += 1;
        if i.is_multiple_of(8) && term < sum * NEGLIGIBLE {
            break;
        }
    }
    integral(sum)
}

/// `log₂(1 + e^{−L})` (bits): the surprisal of the true bit given LLR `L` in its favour.
#[must_use]
pub fn surprisal(llr: f64) -> f64 {
    let softplus = if llr > 0.0 {
        (-llr).exp().ln_1p()
    } else {
        -llr + llr.exp().ln_1p()
    };
    softplus / std::f64::consts::LN_2
}

/// The probability of deciding wrongly, `Q(d/2) = ½·erfc(d/(2√2))`.
#[must_use]
pub fn error_rate(separation: f64) -> f64 {
    0.5 * erfc(separation / (2.0 * std::f64::consts::SQRT_2))
}

/// `I(B; view) = 1 − E[S]` (bits per bit).
#[must_use]
pub fn information(separation: f64) -> f64 {
    if separation <= 0.0 {
        return 0.0;
    }
    (1.0 - expected_surprisal(separation)).max(0.0)
}

/// `erfc(x)` with fractional error below 1.2·10⁻⁷ (Chebyshev fit, Numerical Recipes §6.2).
#[must_use]
pub fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 { r } else { 2.0 - r }
}

/// The smooth min-entropy bound for `n` bits each seen through an independent view of
/// separation at most `d` (one group of [`crate::view_profile`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GaussianMinEntropy {
    /// Bits n.
    pub positions: u64,
    /// The separation d.
    pub separation: f64,
    /// Smoothing ε.
    pub epsilon: f64,
    /// Shannon entropy `n·E[S]` (bits): what the bound approaches per bit as n grows.
    pub shannon: f64,
    /// The Chernoff parameter λ that attains the bound.
    pub lambda: f64,
    /// `H_min^ε ≥ t` with `P[Σ S_i < t] ≤ ε` (bits).
    pub h_min: f64,
}

/// `H_min^ε(X|E) ≥ t` for `n` bits whose surprisals `S_i` are independent, each distributed
/// as for separation `d`: removing the outcomes with total surprisal below `t` (mass ≤ ε)
/// leaves none likelier than `2^{−t}`. `t` is the largest value the lower-tail Chernoff bound
/// `P[Σ S_i ≤ t] ≤ min_λ e^{λt}·E[e^{−λS}]ⁿ ≤ ε` allows
/// (`t = max_λ (n·(−ln E[e^{−λS}]) − ln(1/ε)) / λ`), clamped to `[0, n]`.
///
/// # Errors
/// [`MinEntropyError`] for ε outside (0, 1) or a separation that is negative or not finite.
pub fn gaussian_llr_smooth_min_entropy(
    n: u64,
    separation: f64,
    epsilon: f64,
) -> Result<GaussianMinEntropy, MinEntropyError> {
    check_epsilon(epsilon)?;
    if !(separation >= 0.0 && separation.is_finite()) {
        return Err(MinEntropyError::InvalidSeparation(separation));
    }
    let nf = n as f64;
    if separation == 0.0 || n == 0 {
        return Ok(GaussianMinEntropy {
            positions: n,
            separation,
            epsilon,
            shannon: nf,
            lambda: 0.0,
            h_min: nf,
        });
    }
    let profile = profile_smooth_min_entropy(
        &[ViewGroup {
            view: BitView::Gaussian { separation },
            bits: n,
        }],
        epsilon,
    )?;
    Ok(GaussianMinEntropy {
        positions: n,
        separation,
        epsilon,
        shannon: profile.shannon,
        lambda: profile.lambda,
        h_min: profile.h_min,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn erfc_and_error_rate_match_tables() {
        assert!((erfc(0.0) - 1.0).abs() < 1e-7);
        assert!((erfc(1.0) - 0.157_299_207).abs() < 1e-7);
        assert!((erfc(-1.0) - 1.842_700_793).abs() < 1e-7);
        // Q(1.96) = 0.025.
        assert!((error_rate(2.0 * 1.959_964) - 0.025).abs() < 1e-6);
    }

    #[test]
    fn information_is_monotone_and_bounded() {
        assert_eq!(information(0.0), 0.0);
        let mut last = 0.0;
        for i in 1..40 {
            let info = information(f64::from(i) * 0.25);
            assert!(info > last && info <= 1.0, "{i}: {info}");
            last = info;
        }
        assert!(last > 0.999);
        // Small d: I ≈ d²/(8 ln 2) (Fisher information of a Gaussian shift).
        let d: f64 = 0.1;
        let approx = d * d / (8.0 * std::f64::consts::LN_2);
        assert!(
            (information(d) - approx).abs() < 0.01 * approx,
            "{}",
            information(d)
        );
    }

    /// Leaving out the negligible tail changes no bit of `E[S]`: 4,000 separations from 10⁻⁵
    /// to 50, log-spaced, and the private-sensing map's range densely.
    #[test]
    fn the_expected_surprisal_is_the_whole_sum_bit_for_bit() {
        let whole = |d: f64| {
            integral(
                surprisal_table(d)
                    .iter()
                    .fold(0.0, |sum, &(kernel, s)| sum + kernel * s),
            )
        };
        let logspaced = (0..2_000).map(|i| 10f64.powf(-5.0 + 6.7 * f64::from(i) / 2_000.0));
        let dense = (0..2_000).map(|i| 0.8 + 4.2 * f64::from(i) / 2_000.0);
        for d in logspaced.chain(dense) {
            assert_eq!(
                expected_surprisal(d).to_bits(),
                whole(d).to_bits(),
                "d = {d}"
            );
        }
    }

    /// The bound is at most the Shannon entropy, grows towards it per bit with n, and falls
    /// as the view sharpens; a fair-coin view gives n.
    #[test]
    fn bound_behaves() {
        let at = |n, d| gaussian_llr_smooth_min_entropy(n, d, 1e-6).unwrap();
        let b = at(100_000, 1.65);
        assert!(b.h_min < b.shannon, "{b:?}");
        assert!(b.h_min / b.shannon > 0.95, "{b:?}");
        assert!(at(10_000, 1.65).h_min / 10_000.0 < b.h_min / 100_000.0);
        assert!(at(10_000, 2.0).h_min < at(10_000, 1.5).h_min);
        assert_eq!(at(500, 0.0).h_min, 500.0);
        assert!(gaussian_llr_smooth_min_entropy(10, -1.0, 1e-6).is_err());
        assert!(gaussian_llr_smooth_min_entropy(10, 1.0, 0.0).is_err());
    }

    /// Against the exact smooth min-entropy of a product of independent Gaussian views,
    /// estimated from the empirical ε-quantile of the total surprisal over 20,000 seeded
    /// draws of 16 bits: the bound may not exceed the quantile's lower 3σ order statistic.
    #[test]
    fn bound_is_below_the_empirical_surprisal_quantile() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(7);
        let (n, draws) = (16, 20_000);
        for &(d, eps) in &[(1.65, 0.05), (3.0, 0.1), (0.8, 0.01)] {
            let mut totals: Vec<f64> = (0..draws)
                .map(|_| {
                    (0..n)
                        .map(|_| {
                            let z: f64 = StandardNormal.sample(&mut rng);
                            surprisal(d * d / 2.0 + d * z)
                        })
                        .sum()
                })
                .collect();
            totals.sort_by(f64::total_cmp);
            let m = draws as f64;
            let low = (m * eps - 3.0 * (m * eps * (1.0 - eps)).sqrt()).floor() as usize;
            let bound = gaussian_llr_smooth_min_entropy(n as u64, d, eps)
                .unwrap()
                .h_min;
            assert!(
                bound <= totals[low],
                "d {d}, ε {eps}: {bound} > {}",
                totals[low]
            );
        }
    }
}
