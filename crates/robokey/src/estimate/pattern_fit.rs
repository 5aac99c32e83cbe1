//! The motion noise's fit at block time over the bit patterns a doublet's known bits leave
//! open (docs/estimation.md, "Causality"): what the LLRs recomputed before reconciliation
//! use, for a binary block (the doublets its sample discloses a bit of, whole with one bit per
//! doublet, in part with two) and for a multilevel slice (`slice_llrs`). It fits the motion
//! noise's covariance `Q̂` and its AR(1) correlation ρ̂ between steps, which the likelihood
//! then models (`DoubletModel::correlation`); beside it, the model the `world` basis
//! recomputes with instead (`world_llr_model`).
//!
//! **Moments.** A doublet's one-step residuals under pattern `h`,
//! `zₖ = H(θₖ)ᵀ(y(Lj+k+1) − f(y(Lj+k), uₖ(h)))` (robot frame at the step's start sample `θₖ`;
//! [`DoubletResidual::two_step_split`], [`DoubletResidual::three_step_split`]), hold one
//! step's motion noise each: `E[zₖzₖᵀ] = Q + Sₖ`, `Sₖ = C₀RC₀ᵀ + C₁RC₁ᵀ`, whatever ρ. Two
//! consecutive ones share the sample between them: `E[zₖzₖ₊₁ᵀ] = ρQ − Eₖ`,
//! `Eₖ = C₀,ₖRC₁,ₖ₊₁ᵀ` (the shared sample ends step k and starts step k + 1). So `Q̂` is the
//! mean of `zₖzₖᵀ − Sₖ`, and given it ρ is affine in the cross moment: per axis
//! `ρ̂ₐ = mean(zₖzₖ₊₁ᵀ + Eₖ)ₐₐ / Q̂ₐₐ`, the axes pooled with weights `(Q̂ₐₐ/(Q̂ₐₐ + S̄ₐₐ))²` (an
//! axis buried under the sensor's noise says little, as `estimate_correlation` pools them),
//! clamped to the estimate's class `[−½, 0.999]`. Only the steps within a doublet are paired:
//! its samples are all the fit reads.
//!
//! **EM.** Each doublet's residuals are formed under every pattern its known bits leave open,
//! weighted by the pattern's posterior probability given the doublet's samples under the
//! current `Q̂` and ρ̂ — the likelihood the LLRs are recomputed with
//! ([`DoubletModel::log_likelihoods`], the patterns uniform), so the middle sample, which
//! carries the v-bit, weighs the patterns as the end does — and the moments taken with the
//! weights; from the prior's `Q` and ρ = 0, at most [`EM_ITERATIONS`] iterations. At the true
//! `Q` and ρ the weights are the patterns' true conditional probabilities given the samples,
//! so by the tower rule each weighted moment has the expectation of its true pattern's: the
//! fit is unbiased to first order (its ratio leaves an O(1/n) bias). A doublet known whole has
//! one open pattern of weight 1: on whole doublets alone the fit is the moments, at once.

use nalgebra::Matrix3;

use super::block::own_view;
use super::correlation::{HIGHEST_CORRELATION, LOWEST_CORRELATION};
use super::diagonal_covariance;
use super::motion_noise::{EstimationRefusal, MIN_DOUBLETS_PER_PARITY};
use super::residual::{DoubletResidual, rotation};
use crate::Config;
use crate::private::{DoubletModel, DoubletSamples, doublet_model_with};
use crate::world::WorldModel;

/// Most EM iterations of a fit.
pub const EM_ITERATIONS: usize = 50;

/// The fit stops once no diagonal entry of `Q̂` moves by more than this share, and ρ̂ by no
/// more than this, in an iteration.
pub const EM_TOLERANCE: f64 = 1e-4;

/// A pattern weight below which its residuals leave the fit (their share of the moments is
/// below the fit's own rounding).
const NEGLIGIBLE_WEIGHT: f64 = 1e-12;

/// A kept doublet with what is known of its bits: those of `mask` (bit `i` at `1 << i`),
/// valued as in `word`.
#[derive(Clone, Copy)]
pub(crate) struct PartlyKnown {
    pub samples: DoubletSamples,
    pub mask: usize,
    pub word: usize,
}

/// The motion noise fitted at block time: `Q̂` in the robot's frame and ρ̂.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct MotionFit {
    /// `Q̂` (m², m², rad² per step; robot frame).
    pub q: Matrix3<f64>,
    /// ρ̂, the lag-one correlation between steps, within `[−½, 0.999]`.
    pub correlation: f64,
}

/// One open pattern's moments over a doublet's one-step residuals, which do not depend on
/// the fit: `Σₖ (zₖzₖᵀ − Sₖ)`, `Σₖ Sₖ` and `Σₖ (zₖzₖ₊₁ᵀ + Eₖ)`.
struct PatternMoments {
    pattern: usize,
    square: Matrix3<f64>,
    sensor: Matrix3<f64>,
    cross: Matrix3<f64>,
}

impl PatternMoments {
    fn of(steps: &[DoubletResidual], sensor: &Matrix3<f64>, pattern: usize) -> Self {
        let mut moments = Self {
            pattern,
            square: Matrix3::zeros(),
            sensor: Matrix3::zeros(),
            cross: Matrix3::zeros(),
        };
        for (k, z) in steps.iter().enumerate() {
            let s = z.sensor_part(sensor);
            moments.square += z.value * z.value.transpose() - s;
            moments.sensor += s;
            if let Some(next) = steps.get(k + 1) {
                moments.cross += z.value * next.value.transpose()
                    + z.sensor_maps[0] * sensor * next.sensor_maps[1].transpose();
            }
        }
        moments
    }
}

/// `Q̂` (robot frame) and ρ̂ fitted to `doublets` under the parties' `config` with the prior's
/// doublet model `prior`: the EM fixed point of the module's doc. `what` names the data in a
/// refusal.
///
/// # Errors
/// A residual not finite, fewer than
/// [`MIN_DOUBLETS_PER_PARITY`](super::motion_noise::MIN_DOUBLETS_PER_PARITY) doublets of a
/// parity, or a `Q̂` not positive definite, naming `what` and the value.
pub(crate) fn open_pattern_fit(
    config: &Config,
    prior: &DoubletModel,
    doublets: &[PartlyKnown],
    what: &str,
) -> Result<MotionFit, String> {
    let refused = |refusal: EstimationRefusal| format!("{what}'s fit: {refusal}");
    let parity = |p: u32| {
        doublets
            .iter()
            .filter(|d| d.samples.doublet % 2 == p)
            .count()
    };
    let fewest = parity(0).min(parity(1));
    if fewest < MIN_DOUBLETS_PER_PARITY {
        return Err(refused(EstimationRefusal::TooFewDoublets { have: fewest }));
    }
    let patterns = prior.perturbation.patterns();
    let axle = config.robot.axle_length;
    let sensor = diagonal_covariance(config.sensing.controller_std);
    // Each doublet's open patterns' moments; they do not depend on the fit.
    let mut open = Vec::with_capacity(doublets.len());
    let (mut steps, mut pairs) = (0_usize, 0_usize);
    for d in doublets {
        let mut moments = Vec::new();
        for h in (0..patterns).filter(|h| h & d.mask == d.word & d.mask) {
            let split = one_step_residuals(prior, axle, &d.samples, h);
            if split.iter().any(|z| !z.value.iter().all(|v| v.is_finite())) {
                return Err(refused(EstimationRefusal::NotFinite {
                    doublet: d.samples.doublet,
                }));
            }
            moments.push(PatternMoments::of(&split, &sensor, h));
        }
        let length = if d.samples.late.is_some() { 3 } else { 2 };
        steps += length;
        pairs += length - 1;
        open.push(moments);
    }
    let partly = open.iter().any(|m| m.len() > 1);
    let mut fit = MotionFit {
        q: prior.process_covariance,
        correlation: 0.0,
    };
    let mut weights: Vec<Vec<f64>> = open.iter().map(|m| vec![1.0; m.len()]).collect();
    for _ in 0..EM_ITERATIONS {
        for ((d, moments), w) in doublets.iter().zip(&open).zip(&mut weights) {
            if moments.len() > 1 {
                *w = posterior(config, prior, &fit, &d.samples, moments);
            }
        }
        let weighted = |part: &dyn Fn(&PatternMoments) -> Matrix3<f64>| -> Matrix3<f64> {
            open.iter()
                .zip(&weights)
                .flat_map(|(m, w)| m.iter().zip(w))
                .map(|(m, &w)| part(m) * w)
                .sum()
        };
        let q = weighted(&|m| m.square) / steps as f64;
        let q = (q + q.transpose()) / 2.0;
        if q.symmetric_eigenvalues().iter().any(|&e| e <= 0.0) {
            return Err(format!(
                "{what}'s fit Q̂ is not positive definite (diagonal {:.3e}, {:.3e}, {:.3e})",
                q[(0, 0)],
                q[(1, 1)],
                q[(2, 2)]
            ));
        }
        let cross = weighted(&|m| m.cross) / pairs as f64;
        let sensor_mean = weighted(&|m| m.sensor) / steps as f64;
        let (mut pooled, mut total) = (0.0, 0.0);
        for a in 0..3 {
            let share = (q[(a, a)] / (q[(a, a)] + sensor_mean[(a, a)])).powi(2);
            pooled += share * cross[(a, a)] / q[(a, a)];
            total += share;
        }
        let next = MotionFit {
            q,
            correlation: (pooled / total).clamp(LOWEST_CORRELATION, HIGHEST_CORRELATION),
        };
        let moved = (0..3)
            .map(|i| ((next.q[(i, i)] - fit.q[(i, i)]) / next.q[(i, i)]).abs())
            .fold((next.correlation - fit.correlation).abs(), f64::max);
        fit = next;
        if !partly || moved < EM_TOLERANCE {
            break;
        }
    }
    Ok(fit)
}

/// The posterior probabilities of a doublet's open patterns (`moments`, uniform a priori)
/// given its samples `d` under `fit`; a pattern below [`NEGLIGIBLE_WEIGHT`] gets 0, and where
/// no pattern's covariance is positive definite (every likelihood 0) they stay uniform.
fn posterior(
    config: &Config,
    prior: &DoubletModel,
    fit: &MotionFit,
    d: &DoubletSamples,
    moments: &[PatternMoments],
) -> Vec<f64> {
    let ll = turned(prior, fit, d).log_likelihoods(&d.inputs, &own_view(config, d));
    let top = moments
        .iter()
        .map(|m| ll[m.pattern])
        .fold(f64::NEG_INFINITY, f64::max);
    if top == f64::NEG_INFINITY {
        return vec![1.0 / moments.len() as f64; moments.len()];
    }
    let total: f64 = moments.iter().map(|m| (ll[m.pattern] - top).exp()).sum();
    moments
        .iter()
        .map(|m| {
            let p = (ll[m.pattern] - top).exp() / total;
            if p < NEGLIGIBLE_WEIGHT { 0.0 } else { p }
        })
        .collect()
}

/// Doublet `d`'s one-step residuals under bit pattern `pattern` and `prior`'s model, on
/// wheels `axle` D (m) apart: a three-step doublet's (kept with its sample after the second
/// step) at the steps' mean speeds through the prior lag from the wheels' entry speed the
/// online decision used ([`DoubletResidual::three_step_split`]), a two-step one's at its
/// applied speeds ([`DoubletResidual::two_step_split`]).
fn one_step_residuals(
    prior: &DoubletModel,
    axle: f64,
    d: &DoubletSamples,
    pattern: usize,
) -> Vec<DoubletResidual> {
    let [start, middle, end] = &d.samples;
    match d.late {
        Some(late) => DoubletResidual::three_step_split(
            prior,
            axle,
            d.doublet,
            &d.inputs,
            [start, middle, &late.sample, end],
            pattern,
            late.entry,
        )
        .to_vec(),
        None => DoubletResidual::two_step_split(
            prior,
            axle,
            d.doublet,
            &d.inputs,
            [start, middle, end],
            pattern,
        )
        .to_vec(),
    }
}

/// The prior's doublet model with `fit`'s motion noise (`Q̂` turned from the robot's frame to
/// `d`'s start heading, and ρ̂): the model a doublet's LLRs are recomputed with.
pub(crate) fn turned(prior: &DoubletModel, fit: &MotionFit, d: &DoubletSamples) -> DoubletModel {
    let h = rotation(d.samples[0].z);
    DoubletModel {
        process_covariance: h * fit.q * h.transpose(),
        correlation: fit.correlation,
        ..*prior
    }
}

/// The doublet model of LLRs recomputed with the world's own motion noise (`"world"`, an
/// oracle): its `Q` (world frame) and its correlation between steps; the parties' lag and
/// rounding.
pub(crate) fn world_llr_model(config: &Config) -> DoubletModel {
    let world = WorldModel::of(config);
    DoubletModel {
        correlation: world.process_rho,
        ..doublet_model_with(config, world.process_std)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::private::doublet_model;

    /// Every doublet of `sessions` simulated sessions of `config`, each with its robot's
    /// pattern (as reconciliation gives it).
    fn simulated(config: &Config, sessions: u32) -> Vec<DoubletSamples> {
        (0..sessions)
            .flat_map(|r| {
                let run = crate::sim::simulate(config, r, false).unwrap();
                run.private.unwrap().controller_samples
            })
            .collect()
    }

    /// On seeded simulated blocks (8 sessions, 4 mm of motion noise, the sensor's 0.5 mm)
    /// the fit finds the world's `Q` and ρ: white and at ρ = 0.5 and 0.9, on doublets known whole
    /// (one bit each) and with one of two bits open (the EM weights at work). Tolerances are
    /// four standard errors from the `n` doublets: one-step residuals form the AR(1) series
    /// itself, so a diagonal entry of `Q̂` (a mean of `2n` squares) has relative standard error
    /// `√(2/(2n)·(1 + ρ²)/(1 − ρ²))·(1 + s)`, `s = 2R/Q` the sensor's share; the cross moment
    /// (`n` products of consecutive steps, which correlate `2ρ^(4d)/(1 + ρ²)` `d` doublets
    /// apart) `√((1 + ρ²)·F/n)·(1 + s)` of `Q`, `F = 1 + 4ρ⁴/((1 − ρ⁴)(1 + ρ²))`, and ρ̂ that
    /// plus `|ρ|` times `Q̂`'s (their ratio; the axes pooled, no worse than one axis).
    #[test]
    fn the_fit_finds_the_worlds_q_and_correlation() {
        let (std, sensor) = (0.004_f64, 0.0005_f64);
        for (rho, bits) in [(0.0_f64, 1_usize), (0.5, 1), (0.5, 2), (0.9, 2)] {
            let config = Config::from_toml(
                &format!(
                    "[sensing]\nmode = \"private\"\n[protocol]\nbits_per_doublet = {bits}\n\
                     [world]\nprocess_std = [{std}, {std}, {std}]\nprocess_rho = {rho}\n"
                ),
                "t",
            )
            .unwrap();
            let doublets: Vec<PartlyKnown> = simulated(&config, 8)
                .into_iter()
                .enumerate()
                .map(|(j, samples)| PartlyKnown {
                    samples,
                    mask: if bits == 1 { 1 } else { 1 << (j % 2) },
                    word: samples.pattern,
                })
                .collect();
            let fit = open_pattern_fit(&config, &doublet_model(&config), &doublets, "t").unwrap();
            let n = doublets.len() as f64;
            let share = 1.0 + 2.0 * (sensor / std).powi(2);
            let r2 = rho * rho;
            let se_q = (1.0 / n * (1.0 + r2) / (1.0 - r2)).sqrt() * share;
            let f = 1.0 + 4.0 * r2 * r2 / ((1.0 - r2 * r2) * (1.0 + r2));
            let se_rho = ((1.0 + r2) * f / n).sqrt() * share + rho.abs() * se_q;
            for a in 0..3 {
                let ratio = fit.q[(a, a)] / (std * std);
                assert!(
                    (ratio - 1.0).abs() < 4.0 * se_q,
                    "ρ {rho}, {bits} bits, axis {a}: Q̂/Q = {ratio:.4} (4 s.e. {:.4}, n {n})",
                    4.0 * se_q
                );
            }
            assert!(
                (fit.correlation - rho).abs() < 4.0 * se_rho,
                "ρ {rho}, {bits} bits: ρ̂ = {:.4} (4 s.e. {:.4}, n {n})",
                fit.correlation,
                4.0 * se_rho
            );
        }
    }
}
