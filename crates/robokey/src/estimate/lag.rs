//! The actuator's first-order lag τ measured from the bits' mid-doublet amplitude
//! (docs/estimation.md, "The lag").
//!
//! Through a lag τ a step offset `s·Δv` begun from wheels that carry no offset moves the
//! robot `s·Δv·T·g(τ)` along its heading (`s = ±1` binary, a multilevel symbol's amplitude
//! `(L − 1 − 2i)/√E` with `protocol.levels > 2`), `g(τ) = 1 − (τ/T)·(1 − e^(−T/τ))` (`g(0) = 1`,
//! decreasing toward 0). The controller's residual after a doublet's first step along its
//! start heading, `z = e(θ₀)·(y(Lj+1) − f(y(Lj), u))`, is that plus what does not depend on
//! the doublet's v-bit: the motion and sensor noise, the ω-bit (the Euler map moves the
//! position along the start heading), and the nominal input's own transient through the lag
//! (the wheels' speed at the doublet's start is not kept). With the reconciled amplitudes
//! `s`, which are uniform over the alphabet and independent of all of it,
//!
//! `ĝ = Σ sᵢzᵢ / (Δv·T·Σ sᵢ²)`
//!
//! (binary: `mean(s·z)/(Δv·T)`) is unbiased for `g(τ)`, and `ĝ ± z(ε_est/2)·σ̂/(Δv·T·√Σsᵢ²)`
//! (`σ̂` the deviation of what remains, `zᵢ − ĝ·sᵢ·Δv·T`; the products' covariances vanish
//! between doublets, `E[sᵢsⱼ] = 0`) covers it with
//! probability about 1 − ε_est — the normal approximation of the mean, the quantile taken
//! from the normal tail's bound, wider than the exact one. `g` is monotone, so the interval
//! maps to `[τ_lo, τ_hi]` through its inverse. A dead time `D` shortens the first step's
//! travel as a lag does (`g = 1 − D/T` for a pure delay): the estimate is the lag that
//! explains the amplitude, not the lag and the dead time apart.

use super::normal_tail::normal_upper_quantile;
use crate::model::unicycle_step;
use crate::private::DoubletSamples;
use crate::private::doublet::Perturbation;

/// The largest lag the class covers (s): `private.prior_lag`'s range.
pub const MAX_LAG: f64 = 1.0;

/// The fewest doublets the estimate is made from.
pub const MIN_LAG_DOUBLETS: usize = 100;

/// What the controller measured of the lag for one block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LagEstimate {
    /// The point estimate τ̂ (s).
    pub point: f64,
    /// Its (1 − ε_est) interval `[τ_lo, τ_hi]` (s).
    pub interval: [f64; 2],
    /// The first step's share of the v-bit's travel, `ĝ` (1 without lag).
    pub share: f64,
    /// Its (1 − ε_est) interval.
    pub share_interval: [f64; 2],
    /// Doublets it was measured from.
    pub doublets: usize,
}

/// `g(τ) = 1 − (τ/T)·(1 − e^(−T/τ))`: the share of a step offset's travel a first-order
/// lag `lag` τ (s) leaves in a step of `sample_time` T (s) begun without offset.
#[must_use]
pub fn first_step_share(lag: f64, sample_time: f64) -> f64 {
    if lag <= 0.0 {
        return 1.0;
    }
    1.0 - lag / sample_time * (1.0 - (-sample_time / lag).exp())
}

/// The lag in `[0, MAX_LAG]` whose [`first_step_share`] is `share`, by bisection (`g` is
/// decreasing): 0 for a share of 1 or more, [`MAX_LAG`] for one at or below `g(MAX_LAG)`.
fn lag_of_share(share: f64, sample_time: f64) -> f64 {
    if share >= 1.0 {
        return 0.0;
    }
    if share <= first_step_share(MAX_LAG, sample_time) {
        return MAX_LAG;
    }
    let (mut low, mut high) = (0.0, MAX_LAG);
    for _ in 0..64 {
        let middle = 0.5 * (low + high);
        if first_step_share(middle, sample_time) > share {
            low = middle;
        } else {
            high = middle;
        }
    }
    0.5 * (low + high)
}

/// The lag measured from `doublets` (the controller's samples and the reconciled bits) with
/// the v-symbol's offsets of `perturbation` (its Δv, m/s, and alphabet), sample time
/// `sample_time` (s), at ε_est = `epsilon`.
///
/// # Errors
/// Fewer than [`MIN_LAG_DOUBLETS`] doublets, a non-positive Δv, or an interval that leaves
/// the class (its upper end beyond [`MAX_LAG`]), naming the value.
pub fn estimate_lag<'a>(
    doublets: impl IntoIterator<Item = &'a DoubletSamples>,
    perturbation: &Perturbation,
    sample_time: f64,
    epsilon: f64,
) -> Result<LagEstimate, String> {
    let delta_v = perturbation.delta.x;
    let scale = delta_v * sample_time;
    if scale <= 0.0 {
        return Err(format!(
            "lag estimate: protocol.delta_v = {delta_v} m/s (allowed: above 0)"
        ));
    }
    // Each doublet's v-symbol amplitude `s` (its label: the pattern's low bits), `s·z/(Δv·T)`.
    let products: Vec<(f64, f64)> = doublets
        .into_iter()
        .map(|b| {
            let [start, middle, _] = b.samples;
            let predicted = unicycle_step(&start, &b.inputs.first, sample_time);
            let (sin, cos) = start.z.sin_cos();
            let along = (middle.x - predicted.x) * cos + (middle.y - predicted.y) * sin;
            let amplitude = perturbation.amplitude(b.pattern);
            (amplitude, amplitude * along / scale)
        })
        .collect();
    let n = products.len();
    if n < MIN_LAG_DOUBLETS {
        return Err(format!(
            "lag estimate: {n} doublets (allowed: at least {MIN_LAG_DOUBLETS})"
        ));
    }
    let count = n as f64;
    // Σ s² (binary: n).
    let weight = products.iter().map(|(s, _)| s * s).sum::<f64>();
    let share = products.iter().map(|(_, p)| p).sum::<f64>() / weight;
    // What remains of each, `(z/(Δv·T) − ĝ·s)² = s²·(p/s² − ĝ)²` (binary: `(p − ĝ)²`).
    let variance = products
        .iter()
        .map(|(s, p)| s * s * (p / (s * s) - share).powi(2))
        .sum::<f64>()
        / (count - 1.0);
    let half_width = normal_upper_quantile(epsilon / 2.0) * (variance / weight).sqrt();
    let [low, high] = [share - half_width, share + half_width];
    let floor = first_step_share(MAX_LAG, sample_time);
    if low <= floor {
        return Err(format!(
            "lag estimate: the first step's share of the bit's travel is {share:.4} \
             [{low:.4}, {high:.4}] over {n} doublets, which allows a lag beyond the class \
             (allowed: the interval's lower end above {floor:.4}, the share at τ = {MAX_LAG} s)"
        ));
    }
    Ok(LagEstimate {
        point: lag_of_share(share, sample_time),
        interval: [
            lag_of_share(high, sample_time),
            lag_of_share(low, sample_time),
        ],
        share,
        share_interval: [low, high],
        doublets: n,
    })
}

#[cfg(test)]
pub(in crate::estimate) mod tests {
    use super::*;
    use crate::model::{Pose, Unicycle};
    use crate::private::DoubletInputs;
    use crate::rng::{Purpose, stream};
    use rand_distr::{Distribution, StandardNormal};

    const T: f64 = 0.2;
    const DELTA_V: f64 = 0.035;

    #[test]
    fn the_share_is_one_without_lag_and_inverts() {
        assert_eq!(first_step_share(0.0, T), 1.0);
        for tau in [0.01, 0.02, 0.05, 0.1, 0.3, 0.9] {
            let share = first_step_share(tau, T);
            assert!(share < 1.0 && share > first_step_share(MAX_LAG, T));
            assert!((lag_of_share(share, T) - tau).abs() < 1e-12, "{tau}");
        }
        assert_eq!(lag_of_share(1.2, T), 0.0);
    }

    /// The binary doublet of the tests, two bits.
    fn binary() -> Perturbation {
        Perturbation::binary(Unicycle::new(DELTA_V, 0.0), 2, None)
    }

    /// `n` doublets of a world with lag `tau`: the mid sample carries the v-bit's lagged
    /// travel, 1 mm of motion noise and 0.5 mm of sensor noise per sample, a bit-free
    /// nominal transient of up to 3 mm and the ω-bit's heading (two bits per doublet).
    pub(in crate::estimate) fn doublets(n: u32, tau: f64, seed: u64) -> Vec<DoubletSamples> {
        doublets_of(&binary(), n, tau, seed)
    }

    /// [`doublets`] carrying `perturbation`'s symbols (uniform labels on both dimensions).
    fn doublets_of(
        perturbation: &Perturbation,
        n: u32,
        tau: f64,
        seed: u64,
    ) -> Vec<DoubletSamples> {
        let mut rng = stream(seed, Purpose::Process, 0);
        let mut normal =
            || <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut rng);
        let share = first_step_share(tau, T);
        (0..n)
            .map(|j| {
                let start = Pose::new(0.3 * f64::from(j), 0.1, 0.1 * f64::from(j % 60));
                let inputs = DoubletInputs {
                    first: Unicycle::new(0.1, 0.3 * f64::from(j % 3) - 0.3),
                    second: Unicycle::new(0.1, 0.0),
                };
                let pattern = (0..perturbation.key_bits())
                    .fold(0, |pattern, i| pattern | usize::from(normal() > 0.0) << i);
                let transient = 3e-3 * (f64::from(j % 5) - 2.0) / 2.0;
                let along = perturbation.amplitude(pattern) * DELTA_V * T * share
                    + transient
                    + 1e-3 * normal();
                let sensor = |k: f64| 5e-4 * k;
                let predicted = unicycle_step(&start, &inputs.first, T);
                let middle = predicted
                    + Pose::new(
                        along * start.z.cos() + sensor(normal()),
                        along * start.z.sin() + sensor(normal()),
                        0.01 * normal(),
                    );
                let sensed_start = start + Pose::new(sensor(normal()), sensor(normal()), 0.0);
                DoubletSamples {
                    doublet: j,
                    inputs,
                    samples: [sensed_start, middle, middle],
                    pattern,
                }
            })
            .collect()
    }

    /// Seeded recovery: over 200 blocks of 1,000 doublets per lag at ε_est = 0.05, the
    /// interval misses the truth at most 5 % of the time plus 3 binomial deviations
    /// (√(200·0.05·0.95) ≈ 3.1: at most 19 misses), and the point estimates' mean lies
    /// within 4 of its standard errors of the truth (the share's deviation ≈ 1.12 mm /
    /// (Δv·T·√1000) ≈ 0.005 per block, mapped through g's slope).
    #[test]
    fn the_lag_is_recovered_and_its_interval_covers_it() {
        for (i, tau) in [0.0, 0.02, 0.05, 0.1].into_iter().enumerate() {
            let mut misses = 0;
            let mut shares = Vec::new();
            for block in 0..200 {
                let seed = 1000 * i as u64 + block;
                let estimate = estimate_lag(&doublets(1000, tau, seed), &binary(), T, 0.05)
                    .expect("inside the class");
                let [low, high] = estimate.interval;
                if tau < low || tau > high {
                    misses += 1;
                }
                shares.push(estimate.share);
            }
            assert!(misses <= 19, "τ = {tau}: {misses} of 200 missed");
            let mean = shares.iter().sum::<f64>() / 200.0;
            let deviation = (shares.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / 199.0).sqrt()
                / 200_f64.sqrt();
            let truth = first_step_share(tau, T);
            assert!(
                (mean - truth).abs() < 4.0 * deviation,
                "τ = {tau}: share {mean} ± {deviation} against {truth}"
            );
        }
    }

    #[test]
    fn too_few_doublets_or_a_lag_beyond_the_class_is_refused() {
        let few = estimate_lag(&doublets(99, 0.05, 1), &binary(), T, 1e-6).unwrap_err();
        assert!(few.contains("99 doublets"), "{few}");
        let beyond = estimate_lag(&doublets(400, 3.0, 2), &binary(), T, 1e-6).unwrap_err();
        assert!(beyond.contains("beyond the class"), "{beyond}");
    }

    /// Multilevel symbols (4 and 8 levels, two dimensions, natural labeling): over 50 blocks
    /// of 1,000 doublets at ε_est = 0.05 the interval misses a 50 ms lag at most 5 % of the
    /// time plus 3 binomial deviations (√(50·0.05·0.95) ≈ 1.5: at most 7 misses), and the
    /// shares' mean lies within 4 of its standard errors of the truth — where regressing on
    /// the label's low bit alone (the binary sign) reads `E[sign·s] = 1/√5` of it at 4 levels.
    #[test]
    fn the_lag_is_recovered_from_multilevel_symbols() {
        for levels in [4_u8, 8] {
            let perturbation = Perturbation { levels, ..binary() };
            let tau = 0.05;
            let truth = first_step_share(tau, T);
            let mut misses = 0;
            let mut shares = Vec::new();
            for block in 0..50 {
                let doublets = doublets_of(&perturbation, 1000, tau, 7000 + block);
                let estimate = estimate_lag(&doublets, &perturbation, T, 0.05).expect("in class");
                let [low, high] = estimate.interval;
                misses += usize::from(tau < low || tau > high);
                shares.push(estimate.share);
            }
            let mean = shares.iter().sum::<f64>() / 50.0;
            let deviation = (shares.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / 49.0).sqrt()
                / 50_f64.sqrt();
            assert!(misses <= 7, "{levels} levels: {misses} of 50 missed");
            assert!(
                (mean - truth).abs() < 4.0 * deviation,
                "{levels} levels: share {mean} ± {deviation} against {truth}"
            );
        }
    }
}
