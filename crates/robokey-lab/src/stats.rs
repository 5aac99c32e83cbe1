//! Descriptive statistics and trend tests used by summaries and reports (no I/O).

use rand::RngExt;
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Count, median, quartiles, extremes and mean of a sample.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Number of values.
    pub count: usize,
    /// Median (= `quantile(0.5)`).
    pub median: f64,
    /// First quartile.
    pub q1: f64,
    /// Third quartile.
    pub q3: f64,
    /// Smallest value.
    pub min: f64,
    /// Largest value.
    pub max: f64,
    /// Arithmetic mean.
    pub mean: f64,
}

impl Summary {
    /// Summarizes `values` (NaNs skipped); `None` when nothing is left.
    #[must_use]
    pub fn of(values: &[f64]) -> Option<Self> {
        let mut sorted: Vec<f64> = values.iter().copied().filter(|x| !x.is_nan()).collect();
        if sorted.is_empty() {
            return None;
        }
        sorted.sort_by(f64::total_cmp);
        Some(Self {
            count: sorted.len(),
            median: quantile(&sorted, 0.5),
            q1: quantile(&sorted, 0.25),
            q3: quantile(&sorted, 0.75),
            min: sorted[0],
            max: sorted[sorted.len() - 1],
            mean: sorted.iter().sum::<f64>() / sorted.len() as f64,
        })
    }
}

/// The `p`-quantile of sorted values by linear interpolation between order statistics
/// (R type 7, numpy's default): position `p·(n − 1)`.
///
/// # Panics
/// If `sorted` is empty.
#[must_use]
pub fn quantile(sorted: &[f64], p: f64) -> f64 {
    let position = p.clamp(0.0, 1.0) * (sorted.len() - 1) as f64;
    let (lower, fraction) = (position.floor() as usize, position.fract());
    match sorted.get(lower + 1) {
        Some(&upper) if fraction > 0.0 => sorted[lower] + fraction * (upper - sorted[lower]),
        _ => sorted[lower],
    }
}

/// Ranks with ties given their average rank (1-based).
fn ranks(values: &[f64]) -> Vec<f64> {
    let mut order: Vec<usize> = (0..values.len()).collect();
    order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
    let mut ranks = vec![0.0; values.len()];
    let mut start = 0;
    while start < order.len() {
        let mut end = start;
        while end + 1 < order.len() && values[order[end + 1]] == values[order[start]] {
            end += 1;
        }
        let average = (start + end) as f64 / 2.0 + 1.0;
        for &i in &order[start..=end] {
            ranks[i] = average;
        }
        start = end + 1;
    }
    ranks
}

fn pearson(x: &[f64], y: &[f64]) -> Option<f64> {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx) * (a - mx);
        syy += (b - my) * (b - my);
    }
    (sxx > 0.0 && syy > 0.0).then(|| sxy / (sxx * syy).sqrt())
}

/// Spearman's rank correlation with average ranks for ties; `None` when the lengths
/// differ, fewer than 2 pairs are given, or either series is constant.
#[must_use]
pub fn spearman(x: &[f64], y: &[f64]) -> Option<f64> {
    (x.len() == y.len() && x.len() >= 2).then(|| pearson(&ranks(x), &ranks(y)))?
}

/// The result of a permutation trend test.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrendTest {
    /// Spearman's ρ, `None` when undefined (a constant series).
    pub rho: Option<f64>,
    /// Two-sided permutation p-value, `(1 + #{|ρ_perm| ≥ |ρ|}) / (1 + permutations)`;
    /// 1 when ρ is undefined.
    pub p_value: f64,
    /// Number of permutations.
    pub permutations: usize,
}

/// Spearman's ρ with a two-sided permutation p-value: `y` is shuffled (Fisher–Yates,
/// ChaCha8 seeded by `seed`) `permutations` times.
#[must_use]
pub fn spearman_permutation_test(
    x: &[f64],
    y: &[f64],
    permutations: usize,
    seed: u64,
) -> TrendTest {
    let Some(rho) = spearman(x, y) else {
        return TrendTest {
            rho: None,
            p_value: 1.0,
            permutations,
        };
    };
    let (rx, mut ry) = (ranks(x), ranks(y));
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut extreme = 0usize;
    for _ in 0..permutations {
        for i in (1..ry.len()).rev() {
            ry.swap(i, rng.random_range(0..=i));
        }
        if pearson(&rx, &ry).is_some_and(|r| r.abs() >= rho.abs() - 1e-12) {
            extreme += 1;
        }
    }
    TrendTest {
        rho: Some(rho),
        p_value: (1 + extreme) as f64 / (1 + permutations) as f64,
        permutations,
    }
}

/// Wilson score interval for a binomial proportion at two-sided `confidence` (e.g. 0.95).
#[must_use]
pub fn wilson_interval(successes: u64, trials: u64, confidence: f64) -> (f64, f64) {
    if trials == 0 {
        return (0.0, 1.0);
    }
    let z = normal_quantile(0.5 + confidence / 2.0);
    let (n, p) = (trials as f64, successes as f64 / trials as f64);
    let denominator = 1.0 + z * z / n;
    let centre = (p + z * z / (2.0 * n)) / denominator;
    let half = z * (p * (1.0 - p) / n + z * z / (4.0 * n * n)).sqrt() / denominator;
    ((centre - half).max(0.0), (centre + half).min(1.0))
}

/// The standard normal quantile Φ⁻¹(p) (Wichura's AS 241, ~1e-16 relative accuracy).
#[must_use]
pub fn normal_quantile(p: f64) -> f64 {
    if p <= 0.0 {
        return f64::NEG_INFINITY;
    }
    if p >= 1.0 {
        return f64::INFINITY;
    }
    let q = p - 0.5;
    if q.abs() <= 0.425 {
        let r = 0.180625 - q * q;
        return q * poly(&A, r) / poly(&B, r);
    }
    let r = if q < 0.0 { p } else { 1.0 - p };
    let r = (-r.ln()).sqrt();
    let value = if r <= 5.0 {
        let r = r - 1.6;
        poly(&C, r) / poly(&D, r)
    } else {
        let r = r - 5.0;
        poly(&E, r) / poly(&F, r)
    };
    if q < 0.0 { -value } else { value }
}

fn poly(coefficients: &[f64; 8], x: f64) -> f64 {
    coefficients.iter().rev().fold(0.0, |acc, c| acc * x + c)
}

const A: [f64; 8] = [
    3.387_132_872_796_366_5,
    133.141_667_891_784_38,
    1_971.590_950_306_551_3,
    13_731.693_765_509_46,
    45_921.953_931_549_87,
    67_265.770_927_008_7,
    33_430.575_583_588_13,
    2_509.080_928_730_122_7,
];
const B: [f64; 8] = [
    1.0,
    42.313_330_701_600_91,
    687.187_007_492_057_9,
    5_394.196_021_424_751,
    21_213.794_301_586_597,
    39_307.895_800_092_71,
    28_729.085_735_721_943,
    5_226.495_278_852_545,
];
const C: [f64; 8] = [
    1.423_437_110_749_683_5,
    4.630_337_846_156_546,
    5.769_497_221_460_691,
    3.647_848_324_763_204_5,
    1.270_458_252_452_368_4,
    0.241_780_725_177_450_6,
    0.022_723_844_989_269_184,
    0.000_774_545_014_278_341_4,
];
const D: [f64; 8] = [
    1.0,
    2.053_191_626_637_759,
    1.676_384_830_183_803_8,
    0.689_767_334_985_1,
    0.148_103_976_427_480_08,
    0.015_198_666_563_616_457,
    0.000_547_593_808_499_534_5,
    1.050_750_071_644_416_9e-9,
];
const E: [f64; 8] = [
    6.657_904_643_501_103,
    5.463_784_911_164_114,
    1.784_826_539_917_291_3,
    0.296_560_571_828_504_9,
    0.026_532_189_526_576_124,
    0.001_242_660_947_388_078_4,
    2.711_555_568_743_487_6e-5,
    2.010_334_399_292_288_1e-7,
];
const F: [f64; 8] = [
    1.0,
    0.599_832_206_555_888,
    0.136_929_880_922_735_8,
    0.014_875_361_290_850_615,
    0.000_786_869_131_145_613_3,
    1.846_318_317_510_054_8e-5,
    1.421_511_758_316_446e-7,
    2.044_263_103_389_939_7e-15,
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quartiles_match_hand_computed_values() {
        let s = Summary::of(&[4.0, 1.0, 3.0, 2.0]).unwrap();
        assert_eq!((s.q1, s.median, s.q3), (1.75, 2.5, 3.25));
        assert_eq!((s.min, s.max, s.mean, s.count), (1.0, 4.0, 2.5, 4));
        let s = Summary::of(&[7.0, 1.0, 3.0, 5.0, 9.0]).unwrap();
        assert_eq!((s.q1, s.median, s.q3), (3.0, 5.0, 7.0));
        let s = Summary::of(&[2.0, 10.0, 4.0]).unwrap();
        assert_eq!((s.q1, s.median, s.q3), (3.0, 4.0, 7.0));
        let s = Summary::of(&[5.0]).unwrap();
        assert_eq!(
            (s.q1, s.median, s.q3, s.min, s.max),
            (5.0, 5.0, 5.0, 5.0, 5.0)
        );
        assert!(Summary::of(&[]).is_none());
        assert!(Summary::of(&[f64::NAN]).is_none());
    }

    #[test]
    fn spearman_handles_monotone_data_ties_and_constants() {
        let x = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0];
        let y = [2.0, 4.0, 5.0, 9.0, 10.0, 20.0, 21.0, 30.0];
        let test = spearman_permutation_test(&x, &y, 999, 1);
        assert_eq!(test.rho, Some(1.0));
        assert!(test.p_value < 0.01, "{test:?}");
        assert_eq!(test, spearman_permutation_test(&x, &y, 999, 1));
        // Ties: x = [1, 2, 2, 3], y = [1, 3, 2, 4] → ranks x [1, 2.5, 2.5, 4], y [1, 3, 2, 4];
        // ρ = Σdxdy / √(Σdx² Σdy²) = 4.5 / √(4.5 · 5) = 0.948683…
        let rho = spearman(&[1.0, 2.0, 2.0, 3.0], &[1.0, 3.0, 2.0, 4.0]).unwrap();
        assert!((rho - 4.5 / (4.5f64 * 5.0).sqrt()).abs() < 1e-12);
        let flat = spearman_permutation_test(&x, &[1.0; 8], 99, 1);
        assert_eq!((flat.rho, flat.p_value), (None, 1.0));
    }

    #[test]
    fn normal_quantile_and_wilson_interval() {
        assert!((normal_quantile(0.975) - 1.959_963_984_540_054).abs() < 1e-14);
        assert!((normal_quantile(0.5)).abs() < 1e-16);
        assert!((normal_quantile(1e-10) + 6.361_340_902_404_056).abs() < 1e-12);
        // Wilson 95 % for 5/10: [0.2366, 0.7634].
        let (lo, hi) = wilson_interval(5, 10, 0.95);
        assert!(
            (lo - 0.236_593).abs() < 1e-6 && (hi - 0.763_407).abs() < 1e-6,
            "{lo} {hi}"
        );
    }
}
