//! Eve's smooth min-entropy of bits seen through views of different sharpness (docs/secrecy.md,
//! "Bits of different separations").
//!
//! Each bit `i` is seen through its own view, and Eve's surprisal of the true bit `S_i` (bits)
//! has that view's distribution; the `S_i` are independent. The lower-tail Chernoff bound of
//! one separation ([`crate::gaussian_llr`]) holds term by term:
//! `P[Σ S_i ≤ t] ≤ e^{λt}·Π_i E[e^{−λS_i}]`, so with the bits grouped by view (`n_k` bits of
//! view `k`) `ln E[e^{−λΣS}] = Σ_k n_k·ln E_k[e^{−λS}]` and
//! `H_min^ε(X|E) ≥ t = max_λ (−Σ_k n_k·ln E_k[e^{−λS}] − ln(1/ε)) / λ`. One group is the
//! one-separation bound exactly; bits sized at the largest separation of a block are the
//! special case where every group is raised to it (Blackwell-dominated, so never more).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::gaussian_llr::{expected_surprisal, grid, integral, surprisal, surprisal_table};
use crate::min_entropy::{MinEntropyError, check_epsilon, chernoff_lower_quantile};

/// How Eve sees one bit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum BitView {
    /// A consistent Gaussian log-likelihood ratio `L ~ N(d²/2, d²)` in favour of the true bit:
    /// an observation whose mean moves with the bit and whose noise does not.
    Gaussian {
        /// The Mahalanobis separation d of the two means, ≥ 0.
        separation: f64,
    },
    /// A scalar observation whose noise depends on the bit (per-wheel slip: the motion noise
    /// grows with the wheel speeds, which the bit sets): `y ~ N(+gap/2, std_one²)` for one
    /// value of the bit and `N(−gap/2, std_zero²)` for the other, in any common unit. Its
    /// log-likelihood ratio is quadratic in `y`, not Gaussian; it is integrated as it is.
    UnequalNoise {
        /// The distance between the two means, ≥ 0.
        gap: f64,
        /// The noise's standard deviation when the bit is one, > 0.
        std_one: f64,
        /// The noise's standard deviation when the bit is zero, > 0.
        std_zero: f64,
    },
}

impl BitView {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`MinEntropyError::InvalidSeparation`] for a separation or gap that is negative or
    /// not finite, [`MinEntropyError::InvalidNoise`] for a standard deviation that is not
    /// positive and finite.
    pub fn check(&self) -> Result<(), MinEntropyError> {
        match *self {
            Self::Gaussian { separation: d } | Self::UnequalNoise { gap: d, .. }
                if !(d >= 0.0 && d.is_finite()) =>
            {
                Err(MinEntropyError::InvalidSeparation(d))
            }
            Self::UnequalNoise {
                std_one, std_zero, ..
            } => [std_one, std_zero]
                .into_iter()
                .find(|s| !(*s > 0.0 && s.is_finite()))
                .map_or(Ok(()), |s| Err(MinEntropyError::InvalidNoise(s))),
            Self::Gaussian { .. } => Ok(()),
        }
    }

    /// Whether the view tells Eve nothing: `S = 1` bit for every observation.
    fn is_blind(&self) -> bool {
        match *self {
            Self::Gaussian { separation } => separation == 0.0,
            Self::UnequalNoise {
                gap,
                std_one,
                std_zero,
            } => gap == 0.0 && std_one == std_zero,
        }
    }

    /// The view's surprisals on the quadrature grid of [`crate::gaussian_llr`]: for unequal
    /// noise, `y = ±gap/2 + σ_b·z` and `L_b = ln p_b(y) − ln p_{1−b}(y)` for each value `b`
    /// of the bit, integrated separately.
    fn table(&self) -> SurprisalTable {
        match *self {
            Self::Gaussian { separation } => SurprisalTable {
                first: surprisal_table(separation),
                second: None,
            },
            Self::UnequalNoise {
                gap,
                std_one,
                std_zero,
            } => {
                let half = gap / 2.0;
                // ln p(y) up to the common constant, for mean `mean` and spread `std`.
                let log_density = |y: f64, mean: f64, std: f64| {
                    let u = (y - mean) / std;
                    -0.5 * u * u - std.ln()
                };
                let side = |mean: f64, std: f64, other_mean: f64, other_std: f64| {
                    grid()
                        .iter()
                        .map(|&(z, kernel)| {
                            let y = mean + std * z;
                            let llr =
                                -0.5 * z * z - std.ln() - log_density(y, other_mean, other_std);
                            (kernel, surprisal(llr))
                        })
                        .collect()
                };
                SurprisalTable {
                    first: side(half, std_one, -half, std_zero),
                    second: Some(side(-half, std_zero, half, std_one)),
                }
            }
        }
    }

    /// `E[S]` (bits): the view's Shannon entropy of the bit, `1 − I(B; view)`.
    #[must_use]
    pub fn expected_surprisal(&self) -> f64 {
        match *self {
            _ if self.is_blind() => 1.0,
            Self::Gaussian { separation } => expected_surprisal(separation),
            Self::UnequalNoise { .. } => self.table().expect(|s| s),
        }
    }

    /// `ln E[e^{−λS}]`, the log moment of the surprisal at `λ > 0`.
    #[must_use]
    pub fn ln_moment(&self, lambda: f64) -> f64 {
        if self.is_blind() {
            return -lambda;
        }
        self.table().ln_moment(lambda)
    }
}

/// A view's `(kernel weight, surprisal)` at each point of the quadrature grid, computed once:
/// `ln E[e^{−λS}]` at the many λ of the Chernoff search then costs one exponential a point.
/// `second`: the other value of the bit, for a view whose two values are integrated apart.
struct SurprisalTable {
    first: Vec<(f64, f64)>,
    second: Option<Vec<(f64, f64)>>,
}

impl SurprisalTable {
    /// `E[g(S)]`, the bit uniform: the trapezoid sum of each side, halved over two sides.
    fn expect(&self, g: impl Fn(f64) -> f64) -> f64 {
        let side = |terms: &[(f64, f64)]| {
            terms
                .iter()
                .fold(0.0, |sum, &(kernel, s)| sum + kernel * g(s))
        };
        match &self.second {
            None => integral(side(&self.first)),
            Some(second) => 0.5 * integral(side(&self.first) + side(second)),
        }
    }

    /// `ln E[e^{−λS}]`.
    fn ln_moment(&self, lambda: f64) -> f64 {
        self.expect(|s| (-lambda * s).exp()).ln()
    }
}

/// `bits` bits, each seen through `view`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ViewGroup {
    /// How Eve sees each of them.
    pub view: BitView,
    /// How many bits.
    pub bits: u64,
}

impl ViewGroup {
    /// Gaussian views grouped by separation (equal values, bit for bit, share a group), in
    /// increasing separation: what a block's per-bit separations, rounded up to their
    /// published grid, size the key with.
    #[must_use]
    pub fn gaussian(separations: impl IntoIterator<Item = f64>) -> Vec<Self> {
        let mut counts: BTreeMap<u64, u64> = BTreeMap::new();
        for d in separations {
            *counts.entry(d.to_bits()).or_default() += 1;
        }
        let mut groups: Vec<Self> = counts
            .into_iter()
            .map(|(d, bits)| Self {
                view: BitView::Gaussian {
                    separation: f64::from_bits(d),
                },
                bits,
            })
            .collect();
        groups.sort_by(|a, b| a.largest_separation().total_cmp(&b.largest_separation()));
        groups
    }

    /// The group's Gaussian separation (for unequal noise, `gap` over the smaller spread:
    /// for people only, the bound integrates the view itself).
    #[must_use]
    pub fn largest_separation(&self) -> f64 {
        match self.view {
            BitView::Gaussian { separation } => separation,
            BitView::UnequalNoise {
                gap,
                std_one,
                std_zero,
            } => gap / std_one.min(std_zero),
        }
    }
}

/// The smooth min-entropy bound for bits of several views.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ProfileMinEntropy {
    /// Bits n, over every group.
    pub positions: u64,
    /// Smoothing ε.
    pub epsilon: f64,
    /// Shannon entropy `Σ_k n_k·E_k[S]` (bits).
    pub shannon: f64,
    /// The Chernoff parameter λ that attains the bound.
    pub lambda: f64,
    /// `H_min^ε ≥ t` with `P[Σ S_i < t] ≤ ε` (bits).
    pub h_min: f64,
}

/// `H_min^ε(X|E) ≥ t` for bits whose surprisals are independent, `groups[k].bits` of them
/// distributed as for `groups[k].view`: `t = max_λ (−Σ_k n_k·ln E_k[e^{−λS}] − ln(1/ε)) / λ`
/// (λ searched over [10⁻⁴, 10³]), clamped to `[0, n]`. Bits whose views tell nothing give
/// `n` outright.
///
/// # Errors
/// [`MinEntropyError`] for ε outside (0, 1) or a view out of range ([`BitView::check`]).
pub fn profile_smooth_min_entropy(
    groups: &[ViewGroup],
    epsilon: f64,
) -> Result<ProfileMinEntropy, MinEntropyError> {
    check_epsilon(epsilon)?;
    for group in groups {
        group.view.check()?;
    }
    let positions: u64 = groups.iter().map(|g| g.bits).sum();
    let nf = positions as f64;
    let informative: Vec<&ViewGroup> = groups
        .iter()
        .filter(|g| g.bits > 0 && !g.view.is_blind())
        .collect();
    if informative.is_empty() {
        return Ok(ProfileMinEntropy {
            positions,
            epsilon,
            shannon: nf,
            lambda: 0.0,
            h_min: nf,
        });
    }
    let tables: Vec<(f64, SurprisalTable)> = informative
        .iter()
        .map(|g| (g.bits as f64, g.view.table()))
        .collect();
    let blind: f64 = groups
        .iter()
        .filter(|g| g.bits > 0 && g.view.is_blind())
        .map(|g| g.bits as f64)
        .sum();
    // Blind bits' surprisal is 1 bit: `ln E[e^{−λ}] = −λ` each.
    let (t, lambda) = chernoff_lower_quantile(
        |lambda| {
            tables
                .iter()
                .map(|(bits, table)| bits * table.ln_moment(lambda))
                .sum::<f64>()
                - blind * lambda
        },
        epsilon,
    );
    Ok(ProfileMinEntropy {
        positions,
        epsilon,
        shannon: groups
            .iter()
            .filter(|g| g.bits > 0)
            .map(|g| g.bits as f64 * g.view.expected_surprisal())
            .sum(),
        lambda,
        h_min: t.clamp(0.0, nf),
    })
}

/// The smooth min-entropy bound for `n` bits each seen through an independent view of
/// separation at most `d` (one group of [`profile_smooth_min_entropy`]).
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

/// The grid a bit's separation is grouped on, rounded up: 2⁻⁶ (15,625 millionths, the finest
/// power of two that is a whole number of millionths), a multiple of the published 2⁻⁸ grid,
/// so a block's bits fall in at most 64 groups per unit of separation and its bound costs a
/// few integrals per group.
pub const GROUP_QUANTUM_MICROS: u64 = 15_625;

/// The grid an equivalent separation is found on: 2⁻⁸ (3,906.25 millionths).
const EQUIVALENT_STEPS_PER_UNIT: f64 = 256.0;

/// A bit's separation rounded up to the group grid ([`GROUP_QUANTUM_MICROS`]), in millionths.
#[must_use]
pub fn grouped_micros(separation: f64) -> u64 {
    (separation * 1e6 / GROUP_QUANTUM_MICROS as f64)
        .ceil()
        .max(0.0) as u64
        * GROUP_QUANTUM_MICROS
}

/// A session's per-bit separations on the group grid, millionths → bits, for `bits` bits:
/// the largest `bits` of `separations` (a list of more — every decided doublet's — errs
/// safe), the bits a shorter list lacks at its largest.
#[must_use]
pub fn separation_counts(separations: &[f64], bits: usize) -> BTreeMap<u64, u64> {
    let mut sorted = separations.to_vec();
    sorted.sort_by(|a, b| b.total_cmp(a));
    let largest = sorted.first().copied().unwrap_or(0.0);
    let mut counts = BTreeMap::new();
    for i in 0..bits {
        let d = sorted.get(i).copied().unwrap_or(largest);
        *counts.entry(grouped_micros(d)).or_default() += 1;
    }
    counts
}

/// One separation that sizes a block of per-bit separations no larger than the per-bit bound
/// does: the smallest `d` on the 2⁻⁸ grid (in millionths, rounded up) with
/// `H(n', d) ≤ H(kept)`, where `H` is the Chernoff bound of [`profile_smooth_min_entropy`],
/// `counts` maps each separation (millionths) to its bits, and `kept` is what remains after
/// `removed` bits are taken away — the `removed` bits of the smallest separations, the worst
/// choice at every λ (a smaller separation's `−ln E[e^{−λS}]` is larger), so the result holds
/// whichever bits a public sample removes. One separation over every kept bit is returned
/// as it is; none kept, or none above 0, gives 0. Found by bisection: `H(n', ·)` falls with
/// `d`, and at the largest separation it is below `H(kept)` (every bit raised to it).
///
/// # Errors
/// [`MinEntropyError::InvalidEpsilon`] for ε outside (0, 1).
pub fn equivalent_separation(
    counts: &BTreeMap<u64, u64>,
    removed: u64,
    epsilon: f64,
) -> Result<u64, MinEntropyError> {
    check_epsilon(epsilon)?;
    let mut to_remove = removed;
    let mut kept: Vec<(u64, u64)> = Vec::new();
    for (&micros, &bits) in counts {
        let gone = to_remove.min(bits);
        to_remove -= gone;
        if bits > gone {
            kept.push((micros, bits - gone));
        }
    }
    let n: u64 = kept.iter().map(|k| k.1).sum();
    let largest = kept.last().map_or(0, |k| k.0);
    if largest == 0 || kept.len() == 1 {
        return Ok(largest);
    }
    let groups: Vec<ViewGroup> = kept
        .iter()
        .map(|&(micros, bits)| ViewGroup {
            view: BitView::Gaussian {
                separation: micros as f64 * 1e-6,
            },
            bits,
        })
        .collect();
    let target = profile_smooth_min_entropy(&groups, epsilon)?.h_min;
    gaussian_separation_within(n, target, largest, epsilon)
}

/// The smallest separation `d` on the 2⁻⁸ grid (in millionths, rounded up) at which `n` bits
/// of one Gaussian view have a bound [`profile_smooth_min_entropy`] no larger than `target`,
/// at most `largest` (millionths; returned where even it bounds more than `target`): one
/// separation that sizes `n` bits no larger than a bound `target` on their min-entropy does.
/// By bisection: the bound falls with `d`.
///
/// # Errors
/// [`MinEntropyError::InvalidEpsilon`] for ε outside (0, 1).
pub fn gaussian_separation_within(
    n: u64,
    target: f64,
    largest: u64,
    epsilon: f64,
) -> Result<u64, MinEntropyError> {
    let single = |step: u64| -> Result<f64, MinEntropyError> {
        let separation = step as f64 / EQUIVALENT_STEPS_PER_UNIT;
        let group = ViewGroup {
            view: BitView::Gaussian { separation },
            bits: n,
        };
        Ok(profile_smooth_min_entropy(&[group], epsilon)?.h_min)
    };
    let (mut low, mut high) = (
        0_u64,
        (largest as f64 * 1e-6 * EQUIVALENT_STEPS_PER_UNIT).ceil() as u64,
    );
    if single(high)? > target {
        return Ok(largest);
    }
    while high - low > 1 {
        let middle = low + (high - low) / 2;
        if single(middle)? <= target {
            high = middle;
        } else {
            low = middle;
        }
    }
    let micros = (high as f64 * 1e6 / EQUIVALENT_STEPS_PER_UNIT).ceil() as u64;
    Ok(micros.min(largest))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gaussian(separation: f64, bits: u64) -> ViewGroup {
        ViewGroup {
            view: BitView::Gaussian { separation },
            bits,
        }
    }

    /// Equal spreads make the unequal-noise view the consistent Gaussian one of separation
    /// `gap / σ`; the single-separation bound is the one-group profile bit for bit.
    #[test]
    fn the_special_cases_agree() {
        for &d in &[0.3, 1.65, 3.0] {
            let unequal = BitView::UnequalNoise {
                gap: 2.0 * d,
                std_one: 2.0,
                std_zero: 2.0,
            };
            let consistent = BitView::Gaussian { separation: d };
            assert!(
                (unequal.expected_surprisal() - consistent.expected_surprisal()).abs() < 1e-9,
                "d {d}"
            );
            assert!((unequal.ln_moment(0.7) - consistent.ln_moment(0.7)).abs() < 1e-9);
            let one = gaussian_llr_smooth_min_entropy(5_000, d, 1e-6).unwrap();
            let profile = profile_smooth_min_entropy(&[gaussian(d, 5_000)], 1e-6).unwrap();
            assert_eq!(one.h_min.to_bits(), profile.h_min.to_bits());
            assert_eq!(one.shannon.to_bits(), profile.shannon.to_bits());
        }
    }

    /// Bits of smaller separations add entropy: a block with half its bits at the largest
    /// separation lies strictly between all bits at the smaller and all at the larger one,
    /// and splitting a group in two changes nothing.
    #[test]
    fn mixing_separations_lies_between_the_extremes() {
        let at = |groups: &[ViewGroup]| profile_smooth_min_entropy(groups, 1e-6).unwrap().h_min;
        let (low, high) = (at(&[gaussian(1.2, 10_000)]), at(&[gaussian(2.0, 10_000)]));
        let mixed = at(&[gaussian(1.2, 5_000), gaussian(2.0, 5_000)]);
        assert!(high < mixed && mixed < low, "{high} {mixed} {low}");
        let split = at(&[
            gaussian(1.2, 2_500),
            gaussian(2.0, 5_000),
            gaussian(1.2, 2_500),
        ]);
        assert!((split - mixed).abs() < 1e-9 * mixed);
        // Blind bits count in full.
        let blind = at(&[
            gaussian(0.0, 1_000),
            gaussian(1.2, 5_000),
            gaussian(2.0, 5_000),
        ]);
        assert!(blind > mixed + 999.0, "{blind} {mixed}");
        assert_eq!(at(&[gaussian(0.0, 700)]), 700.0);
    }

    #[test]
    fn grouping_counts_equal_separations() {
        let groups = ViewGroup::gaussian([2.0, 1.0, 2.0, 0.5, 1.0, 2.0]);
        let flat: Vec<(f64, u64)> = groups
            .iter()
            .map(|g| (g.largest_separation(), g.bits))
            .collect();
        assert_eq!(flat, vec![(0.5, 1), (1.0, 2), (2.0, 3)]);
    }

    /// The equivalent separation lies between the smallest and the largest, sizes no more
    /// than the per-bit bound of what the sample leaves, and is the separation itself when
    /// there is one.
    #[test]
    fn the_equivalent_separation_never_claims_more() {
        let counts: BTreeMap<u64, u64> =
            [(1_000_000, 6_000), (1_500_000, 3_000), (2_500_000, 1_000)]
                .into_iter()
                .collect();
        let d = equivalent_separation(&counts, 1_000, 1e-6).unwrap();
        assert!(1_000_000 < d && d < 2_500_000, "{d}");
        let worst_kept = [
            gaussian(1.0, 5_000),
            gaussian(1.5, 3_000),
            gaussian(2.5, 1_000),
        ];
        let per_bit = profile_smooth_min_entropy(&worst_kept, 1e-6).unwrap().h_min;
        let sized = gaussian_llr_smooth_min_entropy(9_000, d as f64 * 1e-6, 1e-6)
            .unwrap()
            .h_min;
        assert!(sized <= per_bit, "{sized} > {per_bit}");
        // Within one step of the grid: a step less would claim more.
        let step_less = gaussian_llr_smooth_min_entropy(9_000, d as f64 * 1e-6 - 0.004, 1e-6)
            .unwrap()
            .h_min;
        assert!(step_less > per_bit, "{step_less} ≤ {per_bit}");
        let one: BTreeMap<u64, u64> = [(1_234_567, 500)].into_iter().collect();
        assert_eq!(equivalent_separation(&one, 50, 1e-6), Ok(1_234_567));
        assert_eq!(equivalent_separation(&BTreeMap::new(), 0, 1e-6), Ok(0));
        assert_eq!(grouped_micros(1.0), 1_000_000);
        assert_eq!(grouped_micros(1.000_001), 1_015_625);
        assert_eq!(grouped_micros(0.0), 0);
        let counts: Vec<(u64, u64)> = separation_counts(&[0.5, 2.0, 1.0], 2).into_iter().collect();
        assert_eq!(counts, vec![(1_000_000, 1), (2_000_000, 1)]);
        let counts: Vec<(u64, u64)> = separation_counts(&[0.5, 1.0], 4).into_iter().collect();
        assert_eq!(counts, vec![(500_000, 1), (1_000_000, 3)]);
    }

    #[test]
    fn views_out_of_range_are_named() {
        let bad = ViewGroup {
            view: BitView::UnequalNoise {
                gap: 1.0,
                std_one: 0.0,
                std_zero: 1.0,
            },
            bits: 3,
        };
        assert_eq!(
            profile_smooth_min_entropy(&[bad], 1e-6),
            Err(MinEntropyError::InvalidNoise(0.0))
        );
        assert_eq!(
            profile_smooth_min_entropy(&[gaussian(f64::NAN, 3)], 1e-6)
                .unwrap_err()
                .to_string(),
            "separation NaN must be finite and non-negative"
        );
        assert!(profile_smooth_min_entropy(&[gaussian(1.0, 3)], 1.0).is_err());
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
