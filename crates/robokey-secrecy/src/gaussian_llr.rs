//! A bit seen through a consistent Gaussian log-likelihood ratio (docs/secrecy.md, "Private
//! sensing").
//!
//! A party whose observation of a uniform bit `B` is Gaussian, with means a Mahalanobis
//! distance `d` apart under its noise, holds the log-likelihood ratio in favour of the true
//! bit `L ~ N(d²/2, d²)` (natural log). Its error rate is `Q(d/2)`, its surprisal of the true
//! bit is `S = log₂(1 + e^{−L})` bits, and its information is `I(B; view) = 1 − E[S]`. A
//! larger `d` is a more informative (Blackwell-dominating) view, so every bound below is
//! monotone in `d`: a bound at the largest separation holds for every smaller one.

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

/// Width of the cells of the interpolated `I(d)` (separation units).
const CELL_WIDTH: f64 = 0.25;
/// Cells of the interpolated `I(d)`, covering `0 ≤ d < 20` (above, the integral is
/// computed: `I` is 1 to the last bit there).
const CELLS: usize = 80;
/// Chebyshev nodes, and coefficients, per cell.
const NODES: usize = 12;

/// The Chebyshev coefficients of `I(d)` on each cell, from [`information`] at the cell's
/// `NODES` Chebyshev nodes: computed once (960 integrals).
fn information_cells() -> &'static [[f64; NODES]] {
    static CELLS_TABLE: std::sync::OnceLock<Vec<[f64; NODES]>> = std::sync::OnceLock::new();
    CELLS_TABLE.get_or_init(|| {
        let angle =
            |j: usize, k: usize| std::f64::consts::PI * j as f64 * (k as f64 + 0.5) / NODES as f64;
        (0..CELLS)
            .map(|cell| {
                let values: Vec<f64> = (0..NODES)
                    .map(|k| {
                        let t = angle(1, k).cos();
                        information(CELL_WIDTH * (cell as f64 + 0.5 * (t + 1.0)))
                    })
                    .collect();
                std::array::from_fn(|j| {
                    let sum: f64 = (0..NODES).map(|k| values[k] * angle(j, k).cos()).sum();
                    let scale = if j == 0 { 1.0 } else { 2.0 };
                    scale * sum / NODES as f64
                })
            })
            .collect()
    })
}

/// `I(d)` interpolated: on cells of width 0.25 over `0 ≤ d < 20`, the degree-11 Chebyshev
/// interpolant of [`information`] at the cell's 12 Chebyshev nodes,
/// `p(t) = Σ_j c_j·T_j(t)` with `t = 2(d − a)/0.25 − 1` (Clenshaw's recurrence), clamped to
/// `[0, 1]`; [`information`] itself elsewhere. Its error is the interpolation remainder
/// `|I⁽¹²⁾(ξ)|·(w/2)¹²/(2¹¹·12!) ≈ 1.5·10⁻²³·|I⁽¹²⁾(ξ)|` (`w = 0.25`), measured at most
/// 5.1·10⁻¹⁵ over 20,480 points of the domain (a test holds it to `|ΔI| ≤ 10⁻¹²` on every
/// cell); it costs 12 multiply-adds instead of a 2,401-point sum with an `exp` and a `log1p`
/// per point. Not bit for bit [`information`]: for the lab's predictions only, never for a
/// bound that sizes a key.
#[must_use]
pub fn information_interpolated(separation: f64) -> f64 {
    if separation.is_nan() || separation <= 0.0 {
        return 0.0;
    }
    let position = separation / CELL_WIDTH;
    if position >= CELLS as f64 {
        return information(separation);
    }
    let cell = position as usize;
    let t = 2.0 * (position - cell as f64) - 1.0;
    let coefficients = &information_cells()[cell];
    // Clenshaw: b_j = c_j + 2t·b_{j+1} − b_{j+2}; p = c_0 + t·b_1 − b_2.
    let (mut next, mut after) = (0.0, 0.0);
    for &c in coefficients[1..].iter().rev() {
        (next, after) = (c + 2.0 * t * next - after, next);
    }
    (coefficients[0] + t * next - after).clamp(0.0, 1.0)
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

    /// The interpolated `I(d)` is within 10⁻¹² of the integral on every cell: 64 points a
    /// cell, the ends included, over `0 < d < 20`, and the integral itself above.
    #[test]
    fn the_interpolated_information_is_the_integral_within_a_picobit() {
        let mut worst = (0.0_f64, 0.0_f64);
        for i in 1..(CELLS * 64) {
            let d = CELL_WIDTH * i as f64 / 64.0;
            let error = (information_interpolated(d) - information(d)).abs();
            if error > worst.0 {
                worst = (error, d);
            }
        }
        assert!(worst.0 <= 1e-12, "|ΔI| = {:e} at d = {}", worst.0, worst.1);
        for d in [20.0, 25.0, 50.0] {
            assert_eq!(information_interpolated(d), information(d));
        }
        assert_eq!(information_interpolated(0.0), 0.0);
        assert_eq!(information_interpolated(-1.0), 0.0);
        assert_eq!(information_interpolated(f64::NAN), 0.0);
        println!("worst |ΔI| = {:e} at d = {}", worst.0, worst.1);
    }
}
