//! The motion noise's white fit at block time over the bit patterns a doublet's known bits
//! leave open (docs/estimation.md, "Causality"): what the LLRs recomputed before
//! reconciliation use, for a binary block whose sample discloses a doublet's bits only in
//! part (two bits per doublet) and for a multilevel slice (`slice_llrs`).
//!
//! `Q̂` is the fixed point of an EM iteration on the white moment fit
//! ([`weighted_white_motion_noise`]): each doublet's residual is formed under every bit
//! pattern its known bits leave open, weighted by the pattern's posterior probability given
//! the residual under the current `Q̂` (Gaussian, covariance `S_R + M(Q̂)`, the patterns
//! uniform), and the moment equation solved with the weighted `zzᵀ`; from the prior's `Q`,
//! at most [`EM_ITERATIONS`] iterations. At the true white `Q` the weights are the patterns'
//! true conditional probabilities, so by the tower rule the weighted equation has the
//! complete-data one's expectation, zero: the fit is unbiased to first order, as the fit on
//! whole doublets is. A doublet known whole has one open pattern of weight 1, so on whole
//! doublets alone the first iteration is the plain white fit ([`white_motion_noise`]'s
//! arithmetic) and the second repeats it exactly.
//!
//! [`white_motion_noise`]: super::motion_noise::white_motion_noise

use nalgebra::Matrix3;

use super::diagonal_covariance;
use super::motion_noise::weighted_white_motion_noise;
use super::residual::{DoubletResidual, rotation};
use crate::Config;
use crate::private::{DoubletModel, DoubletSamples};

/// Most EM iterations of a fit.
pub const EM_ITERATIONS: usize = 50;

/// The fit stops once no diagonal entry of `Q̂` moves by more than this share in an
/// iteration.
pub const EM_TOLERANCE: f64 = 1e-4;

/// A pattern weight below which its residual leaves the fit (its share of the moment is
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

/// `Q̂` (robot frame) fitted to `doublets` under the parties' `config` with the prior's
/// doublet model `prior`: the EM fixed point of the module's doc, each doublet's residual
/// under pattern `h` its start-to-end one ([`pattern_residual`]). `what` names the data in
/// a refusal.
///
/// # Errors
/// The weighted fit's refusal (a value not finite, fewer than
/// [`MIN_DOUBLETS_PER_PARITY`](super::motion_noise::MIN_DOUBLETS_PER_PARITY) doublets of a
/// parity, singular) or a `Q̂` not positive definite, naming `what` and the value.
pub(crate) fn open_pattern_motion_noise(
    config: &Config,
    prior: &DoubletModel,
    doublets: &[PartlyKnown],
    what: &str,
) -> Result<Matrix3<f64>, String> {
    let patterns = prior.perturbation.patterns();
    let axle = config.robot.axle_length;
    // Each doublet's residuals under its open patterns; they do not depend on Q.
    let mut residuals = Vec::new();
    let mut open = Vec::with_capacity(doublets.len());
    for d in doublets {
        let before = residuals.len();
        residuals.extend(
            (0..patterns)
                .filter(|h| h & d.mask == d.word & d.mask)
                .map(|h| pattern_residual(prior, axle, &d.samples, h)),
        );
        open.push(before..residuals.len());
    }
    let sensor = diagonal_covariance(config.sensing.controller_std);
    let mut q = prior.process_covariance;
    let mut weights = vec![0.0; residuals.len()];
    for _ in 0..EM_ITERATIONS {
        for range in &open {
            let ll: Vec<f64> = residuals[range.clone()]
                .iter()
                .map(|r| gaussian_log_density(r, &q, &sensor))
                .collect();
            let top = ll.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let total: f64 = ll.iter().map(|l| (l - top).exp()).sum();
            for (w, l) in weights[range.clone()].iter_mut().zip(&ll) {
                let p = (l - top).exp() / total;
                *w = if p < NEGLIGIBLE_WEIGHT { 0.0 } else { p };
            }
        }
        let next = weighted_white_motion_noise(&residuals, &weights, &sensor)
            .map_err(|refusal| format!("{what}'s fit: {refusal}"))?;
        if next.symmetric_eigenvalues().iter().any(|&e| e <= 0.0) {
            return Err(format!(
                "{what}'s white fit Q̂ is not positive definite (diagonal {:.3e}, {:.3e}, \
                 {:.3e})",
                next[(0, 0)],
                next[(1, 1)],
                next[(2, 2)]
            ));
        }
        let moved = (0..3)
            .map(|i| ((next[(i, i)] - q[(i, i)]) / next[(i, i)]).abs())
            .fold(0.0, f64::max);
        q = next;
        if moved < EM_TOLERANCE {
            break;
        }
    }
    Ok(q)
}

/// Doublet `d`'s start-to-end residual under bit pattern `pattern` and `prior`'s model, on
/// wheels `axle` D (m) apart: a three-step doublet's (kept with its sample after the second
/// step) through the prior lag from the wheels' entry speed the online decision used
/// ([`DoubletResidual::three_step`]), a two-step one's by the Euler map
/// ([`DoubletResidual::new`]).
pub(crate) fn pattern_residual(
    prior: &DoubletModel,
    axle: f64,
    d: &DoubletSamples,
    pattern: usize,
) -> DoubletResidual {
    let [start, _, end] = &d.samples;
    match d.late {
        Some(late) => DoubletResidual::three_step(
            prior,
            axle,
            d.doublet,
            &d.inputs,
            [start, end],
            pattern,
            late.entry,
        ),
        None => DoubletResidual::new(prior, axle, d.doublet, &d.inputs, start, end, pattern),
    }
}

/// The prior's doublet model with motion noise `q` (robot frame) turned to `d`'s start
/// heading: the model a doublet's LLRs are recomputed with from a fitted `Q̂`.
pub(crate) fn turned(prior: &DoubletModel, q: &Matrix3<f64>, d: &DoubletSamples) -> DoubletModel {
    let h = rotation(d.samples[0].z);
    DoubletModel {
        process_covariance: h * q * h.transpose(),
        ..*prior
    }
}

/// `ln N(z; 0, S_R + M(q))` of a residual under white motion noise `q` (robot frame) and
/// the sensor's `sensor` (world frame), up to the constant `−(3/2)·ln 2π`; −∞ where the
/// covariance is not positive definite.
fn gaussian_log_density(r: &DoubletResidual, q: &Matrix3<f64>, sensor: &Matrix3<f64>) -> f64 {
    let covariance = r.motion_part(q, 0.0) + r.sensor_part(sensor);
    covariance.cholesky().map_or(f64::NEG_INFINITY, |c| {
        let solved = c.solve(&r.value);
        let log_det: f64 = c.l().diagonal().iter().map(|d| d.ln()).sum();
        -0.5 * r.value.dot(&solved) - log_det
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::block::two_step_residuals;
    use crate::estimate::motion_noise::white_motion_noise;
    use crate::private::doublet_model;

    /// On doublets known whole the fit is the white fit on their residuals, to the bit; with
    /// one bit of each two-bit doublet open it still finds the world's `Q` (1 mm, the prior
    /// 4 mm): each diagonal entry within 15 % of the world's 10⁻⁶ — the two sessions' ≈ 1,000
    /// doublets give a variance's relative standard error `√(2/n)` ≈ 4.5 % before the
    /// sensor's share, so 15 % is over three of them.
    #[test]
    fn whole_doublets_give_the_white_fit_and_open_bits_the_worlds_q() {
        let config = Config::from_toml(
            "[sensing]\nmode = \"private\"\n[protocol]\nbits_per_doublet = 2\n[world]\n\
             process_std = [0.001, 0.001, 0.001]\n",
            "t",
        )
        .unwrap();
        let prior = doublet_model(&config);
        // Each carrying its robot's pattern, as reconciliation gives it.
        let doublets: Vec<DoubletSamples> = (0..2)
            .flat_map(|r| {
                let run = crate::sim::simulate(&config, r, false).unwrap();
                run.private.unwrap().controller_samples
            })
            .collect();
        let whole: Vec<PartlyKnown> = doublets
            .iter()
            .map(|&samples| PartlyKnown {
                samples,
                mask: 0b11,
                word: samples.pattern,
            })
            .collect();
        let fitted = open_pattern_motion_noise(&config, &prior, &whole, "t").unwrap();
        let sensor = diagonal_covariance(config.sensing.controller_std);
        let white = white_motion_noise(
            &two_step_residuals(&prior, config.robot.axle_length, &[&doublets]),
            &sensor,
        )
        .unwrap();
        assert_eq!(fitted, white);
        let half: Vec<PartlyKnown> = whole
            .iter()
            .enumerate()
            .map(|(j, d)| PartlyKnown {
                mask: 1 << (j % 2),
                ..*d
            })
            .collect();
        let fitted = open_pattern_motion_noise(&config, &prior, &half, "t").unwrap();
        for i in 0..3 {
            assert!(
                (fitted[(i, i)] / 1e-6 - 1.0).abs() < 0.15,
                "axis {i}: {:.3e}",
                fitted[(i, i)]
            );
        }
    }
}
