//! A bit seen through covariance pairs at each lag of a grid over τ's interval, its moment
//! bounded between the grid's lags (docs/estimation.md, "Per-wheel slip": three-step
//! doublets under slip).
//!
//! Under per-wheel slip Eve's view of a bit is a pair of Gaussians per value of its doublet's
//! other bits ([`PairedBit`]); under a measured lag each pair depends on the plant's τ, which
//! is known only to lie in `[τ_lo, τ_hi]`. What the block's bound needs of the bit at a
//! Chernoff parameter λ is a lower bound, over every τ of the interval, on her surprisal's
//! exponent `e_k(τ) = −ln E[e^(−λS)]` under each value `k` of the other bits (the least over
//! `k` then taken, as for one lag). Each `e_k` is a smooth function of τ (the pair's means and
//! covariances are, and the moment is a smooth function of them). On a grid of spacing `h`,
//! between neighbours a function with `e'' ≤ M` lies above its chord less `M·h²/8`, so above
//! the smaller end less `M·h²/8`; with `M = 2·max(0, max_j Δ²e_j)/h²` — twice the most
//! positive second difference `Δ²e_j = e_j−1 − 2e_j + e_j+1` along the grid (each is `h²·e''`
//! somewhere between its points) — the exponent is at least
//!
//! `min_j e_k(τ_j) − max(0, max_j Δ²e_k,j)/4`
//!
//! for every τ of the interval: the concavity slack the Gaussian path took before its cells
//! were bounded (estimate/lag_cell.rs), mirrored — there the separation was bounded above,
//! here the exponent below. It rests on a stated curvature assumption (convexity between
//! points at most twice what the grid shows): an exponent that bends faster than the grid
//! resolves is not covered (the Gaussian path's cell bound is not carried over to the
//! exponent: docs/estimation.md, "What is not done yet"). The
//! slack is taken at every λ the bound tries, from the same moments the least over the grid
//! takes (no further evaluation); a grid of one lag (a point interval, or two-step doublets)
//! takes none.

use robokey_secrecy::covariance_pair::{CovariancePair, PairedBit, SurprisalExponent};

/// A bit's pairs at each lag of an evenly spaced grid over τ's interval (one lag: the
/// interval is a point, or the doublet has no lag), each lag's pairs one per value of the
/// doublet's other bits in the same order.
#[derive(Clone, Debug)]
pub struct PairsOverLags {
    lags: Vec<PairedBit>,
}

impl PairsOverLags {
    /// The bit's `pairs` at one lag (no slack).
    #[must_use]
    pub fn at_one_lag(pairs: PairedBit) -> Self {
        Self { lags: vec![pairs] }
    }

    /// The bit's pairs at each lag of an evenly spaced grid, in the grid's order; `None`
    /// where the lags hold different counts of pairs (the same values of the other bits at
    /// every lag are needed) or there is no lag.
    #[must_use]
    pub fn over_grid(lags: Vec<PairedBit>) -> Option<Self> {
        let count = lags.first()?.len();
        lags.iter()
            .all(|pairs| pairs.len() == count)
            .then_some(Self { lags })
    }

    /// The first pair at the grid's first lag (the other bits' first value), if any.
    #[must_use]
    pub fn first_pair(&self) -> Option<&CovariancePair> {
        self.lags.first()?.first()
    }
}

impl SurprisalExponent for PairsOverLags {
    /// The least over the other bits' values of each value's least over the grid less its
    /// convexity slack (the module's doc), at most λ; no slack with one lag. A moment that is
    /// not finite at some lag leaves that value no bound (−∞).
    fn surprisal_exponent(&self, lambda: f64) -> f64 {
        let exponents: Vec<Vec<f64>> = self
            .lags
            .iter()
            .map(|pairs| pairs.iter().map(|p| -p.ln_moment(lambda)).collect())
            .collect();
        let values = self.lags.first().map_or(0, Vec::len);
        (0..values)
            .map(|k| {
                let least = exponents
                    .iter()
                    .map(|at| at[k])
                    .fold(f64::INFINITY, f64::min);
                if exponents.len() < 3 {
                    return least;
                }
                let slack = exponents
                    .windows(3)
                    .map(|w| {
                        let bend = w[0][k] - 2.0 * w[1][k] + w[2][k];
                        if bend.is_finite() {
                            bend.max(0.0) / 4.0
                        } else {
                            f64::INFINITY
                        }
                    })
                    .fold(0.0, f64::max);
                least - slack
            })
            .fold(f64::INFINITY, f64::min)
            .min(lambda)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robokey_secrecy::covariance_pair::Coordinate;

    /// A pair of one coordinate: shift `d`, variance `v`.
    fn pair(d: f64, v: f64) -> CovariancePair {
        CovariancePair::new([Coordinate {
            shift: d,
            variance: v,
        }])
        .unwrap()
    }

    /// One lag: the bound is the plain bit's, number for number.
    #[test]
    fn one_lag_is_the_plain_bit() {
        let pairs = vec![pair(1.2, 1.3), pair(0.7, 0.8)];
        let one = PairsOverLags::at_one_lag(pairs.clone());
        for lambda in [0.05, 0.5, 2.0] {
            assert_eq!(
                one.surprisal_exponent(lambda),
                pairs.surprisal_exponent(lambda)
            );
        }
    }

    /// A view whose separation peaks between grid points (a bump in τ narrower than the
    /// grid's spacing but resolved by its curvature), under a bit-dependent variance: the
    /// exponent with its slack lies below the exponent at each of 400 lags over the
    /// interval, at every λ tried, and below the grid's least (the slack is taken); where the
    /// separation falls along the interval the bound lies below the sampled least as well.
    #[test]
    fn the_slack_covers_the_exponent_between_grid_points() {
        let [low, high] = [0.04, 0.06];
        let grid = |points: usize| -> Vec<f64> {
            (0..points)
                .map(|i| low + (high - low) * i as f64 / (points - 1) as f64)
                .collect()
        };
        let peaked = |tau: f64| 1.0 + 0.6 * (-((tau - 0.0535) / 0.006).powi(2)).exp();
        let falling = |tau: f64| 1.5 - 8.0 * (tau - low);
        for (case, separation) in [
            ("peaked", &peaked as &dyn Fn(f64) -> f64),
            ("falling", &falling),
        ] {
            let view = |tau: f64| vec![pair(separation(tau), 1.0 + 0.3 * separation(tau))];
            let bit = PairsOverLags::over_grid(grid(5).into_iter().map(view).collect()).unwrap();
            for lambda in [0.05, 0.2, 0.5, 1.0, 3.0] {
                let bound = bit.surprisal_exponent(lambda);
                let sampled = grid(400)
                    .into_iter()
                    .map(|tau| view(tau).surprisal_exponent(lambda))
                    .fold(f64::INFINITY, f64::min);
                let on_grid = grid(5)
                    .into_iter()
                    .map(|tau| view(tau).surprisal_exponent(lambda))
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    bound <= sampled,
                    "{case} λ {lambda}: {bound} above {sampled}"
                );
                if case == "peaked" {
                    assert!(
                        sampled < on_grid,
                        "{case} λ {lambda}: the grid sees the peak"
                    );
                    assert!(bound < on_grid, "{case} λ {lambda}: no slack taken");
                }
            }
        }
    }

    /// Lags holding different counts of pairs are not a grid of one bit.
    #[test]
    fn lags_of_differing_pairs_are_refused() {
        assert!(PairsOverLags::over_grid(vec![vec![pair(1.0, 1.0)], vec![]]).is_none());
        assert!(PairsOverLags::over_grid(Vec::new()).is_none());
    }
}
