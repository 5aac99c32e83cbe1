//! A block's estimate of the plant, one implementation for the simulator and the agents
//! (docs/estimation.md): per block, the controller's estimate from its own samples of the
//! block's sessions and the reconciled bits, each bit's Eve separation at the region's
//! worst case, and the block's equivalent separation of them (the per-bit bound,
//! docs/secrecy.md) — what the post-processing endpoints size ℓ from. The agents' controller
//! keeps each pooled session's samples ([`kept_doublet`]) and answers its endpoint's request
//! at block time ([`estimate_request`]); the simulator reads them from its runs.
//!
//! The reconciled bits are the robot's: a block whose reconciliation or confirmation fails
//! gives no key, so wherever ℓ matters the controller's corrected bits equal the robot's.

use std::collections::BTreeMap;

use robokey_secrecy::BitString;
use robokey_secrecy::postprocess::{
    EstimateOutcome, EstimateRefusal, EstimateRequest, KeptDoublet, MAX_SEPARATION_STEPS,
    SEPARATION_QUANTUM,
};
use robokey_secrecy::view_profile::{equivalent_separation, separation_counts};
use serde::{Deserialize, Serialize};

use super::lag::MIN_LAG_DOUBLETS;
use super::{
    DoubletResidual, LagEstimate, MotionNoiseEstimate, commands_check, diagonal_covariance,
    estimate_lag, estimate_motion_noise, published_separation, worst_case_separations,
};
use crate::Config;
use crate::model::{Pose, Unicycle};
use crate::private::likelihood::stated_camera_view;
use crate::private::{DoubletInputs, DoubletSamples, doublet_model};
use crate::world::WorldModel;

/// The separation fed for the sessions of a refused block: Eve is taken to see every bit
/// (the largest the endpoints accept), so the block gives no key.
const REFUSED_SEPARATION: f64 = 1e6;

/// What the controller measured for one block, for reports.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BlockEstimate {
    /// Doublets whose residuals were used.
    pub doublets: usize,
    /// The point estimate's standard deviations √Q̂_kk (mm, mm, mrad; robot frame).
    pub point_std_mm: [f64; 3],
    /// The region's lowest vertex's √Q_low,kk at the correlation's upper end (mm, mm, mrad).
    pub lower_std_mm: [f64; 3],
    /// The motion noise's AR(1) correlation between steps: the point estimate ρ̂.
    pub correlation: f64,
    /// Its (1 − ε_est/2) interval `[ρ_lo, ρ_hi]`, over which Eve's view is sized.
    pub correlation_interval: [f64; 2],
    /// ε_est.
    pub epsilon: f64,
    /// What sizes the block, published: the equivalent separation of its bits' worst-case
    /// separations under the per-bit bound, whichever bits its sample discloses, on the
    /// published grid (2⁻⁸), at most `largest`.
    pub separation: f64,
    /// The largest of its bits' worst-case separations (on the grid), for people.
    pub largest: f64,
    /// Why the block was refused, naming the test and the value.
    pub refused: Option<String>,
}

impl BlockEstimate {
    /// What the controller publishes of it: the separation in grid steps of 2⁻⁸ (it is on
    /// the grid already), or the refusal.
    pub fn outcome(&self) -> EstimateOutcome {
        match &self.refused {
            Some(why) => Err(EstimateRefusal(why.clone())),
            None => {
                Ok(((self.separation / SEPARATION_QUANTUM).round() as u32)
                    .min(MAX_SEPARATION_STEPS))
            }
        }
    }

    /// Refuses the block for `why` as well (after any earlier reason): it gives no key.
    pub fn refuse(&mut self, why: String) {
        self.refused = Some(match self.refused.take() {
            Some(earlier) => format!("{earlier}; {why}"),
            None => why,
        });
        self.separation = REFUSED_SEPARATION;
        self.largest = REFUSED_SEPARATION;
    }

    /// A block refused before any estimate, naming why.
    fn refused(why: String, doublets: usize, epsilon: f64) -> Self {
        Self {
            doublets,
            point_std_mm: [f64::NAN; 3],
            lower_std_mm: [f64::NAN; 3],
            correlation: f64::NAN,
            correlation_interval: [f64::NAN; 2],
            epsilon,
            separation: REFUSED_SEPARATION,
            largest: REFUSED_SEPARATION,
            refused: Some(why),
        }
    }
}

/// Each of the block's `sessions`' bits' worst-case separations (each rounded up to the
/// published grid: the estimate depends on the bits, and what is published of it — the
/// block's equivalent separation, on the same grid — is charged by the assumption), and the
/// block's estimate, for the controller's samples of every carrying doublet of each session
/// (with the robot's bits) under the parties' `config` (their stated sensor calibration and
/// camera) at ε_est = `epsilon`, the smoothing ε as well; `disclosed` bits of the block are
/// disclosed by its sample.
#[must_use]
pub fn block_separations(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    disclosed: u64,
    epsilon: f64,
) -> (Vec<Vec<f64>>, BlockEstimate) {
    let model = doublet_model(config);
    let residuals: Vec<DoubletResidual> = sessions
        .iter()
        .flat_map(|session| session.iter())
        .map(|b| {
            DoubletResidual::new(
                &model,
                b.doublet,
                &b.inputs,
                &b.samples[0],
                &b.samples[2],
                b.pattern,
            )
        })
        .collect();
    if let Err(why) = two_step_doublets(config, sessions, epsilon)
        .and_then(|()| no_measured_lag(config, sessions, epsilon))
    {
        return refused(sessions.len(), why, residuals.len(), epsilon);
    }
    let sensor = diagonal_covariance(config.sensing.controller_std);
    match estimate_motion_noise(&residuals, &sensor, epsilon) {
        Ok(estimate) => size_block(config, sessions, disclosed, &estimate),
        Err(refusal) => refused(
            sessions.len(),
            refusal.to_string(),
            residuals.len(),
            epsilon,
        ),
    }
}

/// As [`block_separations`], with the simulated world's own stationary motion noise and
/// AR(1) correlation in place of the estimate's region: what a pair configured with the
/// true world sizes (`robokey secrecy --sizing world`, the comparison for measured sizing;
/// no robot knows its world, so the agents refuse it).
#[must_use]
pub fn world_block_separations(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    disclosed: u64,
    epsilon: f64,
) -> (Vec<Vec<f64>>, BlockEstimate) {
    if let Err(why) = two_step_doublets(config, sessions, epsilon) {
        let doublets = sessions.iter().map(|session| session.len()).sum();
        return refused(sessions.len(), why, doublets, epsilon);
    }
    let world = WorldModel::of(config);
    let truth = MotionNoiseEstimate::known(
        diagonal_covariance(world.process_std),
        world.process_rho,
        epsilon,
    );
    size_block(config, sessions, disclosed, &truth)
}

/// The estimate and Eve's modelled view model the two-step doublet's residual: a block of
/// three-step doublets (`private.prior_lag` > 0) is refused, naming the setting and the lag
/// measured from the block's `sessions` at ε_est = `epsilon` ([`estimate_lag`]).
fn two_step_doublets(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    epsilon: f64,
) -> Result<(), String> {
    let Some(a) = config.doublet_settle() else {
        return Ok(());
    };
    let measured = match measured_lag(config, sessions, epsilon) {
        Ok(lag) => format!(
            "the lag measured {:.4} s [{:.4}, {:.4}] from {} doublets",
            lag.point, lag.interval[0], lag.interval[1], lag.doublets
        ),
        Err(why) => why,
    };
    Err(format!(
        "motion-noise estimate: it models the two-step doublet's residual, the block's \
         doublets have three steps (private.prior_lag = {} s, a = {a:.4}; {measured}; \
         allowed: private.prior_lag = 0 with measured sizing, or --sizing world)",
        config.private.prior_lag
    ))
}

/// The lag measured from the block's `sessions` at ε_est = `epsilon` ([`estimate_lag`]).
fn measured_lag(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    epsilon: f64,
) -> Result<LagEstimate, String> {
    estimate_lag(
        sessions.iter().flat_map(|session| session.iter()),
        config.protocol.delta_v,
        config.robot.sample_time,
        epsilon,
    )
}

/// The two-step doublet's estimate models no actuator lag or dead time: a block of two-step
/// doublets whose first steps carry less of the v-bit's travel than all of it at level
/// ε_est (the share's interval below 1), or a share beyond the class, is refused, naming the
/// share and the lag that explains it. Too few doublets to tell are left to the
/// motion-noise estimate, which needs more.
fn no_measured_lag(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    epsilon: f64,
) -> Result<(), String> {
    let doublets: usize = sessions.iter().map(|session| session.len()).sum();
    if config.doublet_settle().is_some() || doublets < MIN_LAG_DOUBLETS {
        return Ok(());
    }
    let lag = measured_lag(config, sessions, epsilon)?;
    if lag.interval[0] > 0.0 {
        let [low, high] = lag.share_interval;
        return Err(format!(
            "actuator lag: the doublets' first steps carry {:.4} [{low:.4}, {high:.4}] of the \
             v-bit's travel over {} doublets, what a lag (or dead time) of {:.4} s [{:.4}, \
             {:.4}] leaves; the two-step doublet's estimate models none (allowed: a share \
             whose interval reaches 1; private.prior_lag shapes three-step doublets for a lag)",
            lag.share, lag.doublets, lag.point, lag.interval[0], lag.interval[1]
        ));
    }
    Ok(())
}

/// The separations and report of a refused block of `sessions` sessions.
fn refused(
    sessions: usize,
    why: String,
    doublets: usize,
    epsilon: f64,
) -> (Vec<Vec<f64>>, BlockEstimate) {
    (
        vec![vec![REFUSED_SEPARATION]; sessions],
        BlockEstimate::refused(why, doublets, epsilon),
    )
}

/// Each of `sessions`' bits' separations of Eve's view at the worst case of `estimate`'s
/// region (each rounded up to the published grid), and the block's report with its
/// equivalent separation, `disclosed` of its bits disclosed by the sample.
fn size_block(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    disclosed: u64,
    estimate: &MotionNoiseEstimate,
) -> (Vec<Vec<f64>>, BlockEstimate) {
    let model = doublet_model(config);
    let epsilon = estimate.epsilon;
    let bits = usize::from(config.protocol.bits_per_doublet);
    let mut separations = Vec::with_capacity(sessions.len());
    for session in sessions {
        let mut session_separations = Vec::with_capacity(session.len() * bits);
        for b in session.iter() {
            // The camera as stated: per instant, or her frames' worth per instant.
            let view = stated_camera_view(
                b.samples,
                config.sensing.controller_std,
                config.modelled_camera_std(),
            );
            match worst_case_separations(&model, estimate, &b.inputs, &view) {
                Some(d) => {
                    session_separations.extend(d[..bits].iter().map(|&x| published_separation(x)))
                }
                None => {
                    return refused(
                        sessions.len(),
                        format!(
                            "motion-noise estimate: at the region's worst case (Q_low's \
                             diagonal {:?} m², m², rad², ρ in [{:.3}, {:.3}]) Eve's modelled \
                             covariance is not positive definite at doublet {} (allowed: a \
                             bound exists)",
                            [0, 1, 2].map(|k| estimate.lower[(k, k)]),
                            estimate.correlation.interval[0],
                            estimate.correlation.interval[1],
                            b.doublet
                        ),
                        estimate.doublets,
                        epsilon,
                    );
                }
            }
        }
        separations.push(session_separations);
    }
    let [point, lower] = estimate.stds();
    let mm = |s: [f64; 3]| s.map(|x| 1e3 * x);
    let largest = separations.iter().flatten().fold(0.0_f64, |m, &x| m.max(x));
    let separation = equivalent(&separations, disclosed, epsilon, largest);
    (
        separations,
        BlockEstimate {
            doublets: estimate.doublets,
            point_std_mm: mm(point),
            lower_std_mm: mm(lower),
            correlation: estimate.correlation.point,
            correlation_interval: estimate.correlation.interval,
            epsilon,
            separation,
            largest,
            refused: None,
        },
    )
}

/// The block's equivalent separation (the per-bit bound, `view_profile`) of its sessions'
/// bits' `separations`, `disclosed` of them taken away (the worst choice), on the published
/// grid and at most their `largest`; the largest itself where the bound has no answer.
fn equivalent(separations: &[Vec<f64>], disclosed: u64, epsilon: f64, largest: f64) -> f64 {
    let mut counts: BTreeMap<u64, u64> = BTreeMap::new();
    for session in separations {
        for (d, n) in separation_counts(session, session.len()) {
            *counts.entry(d).or_default() += n;
        }
    }
    match equivalent_separation(&counts, disclosed, epsilon) {
        // A grid point rounded up to whole millionths (or a multiple of the 2⁻⁶ group grid):
        // the whole steps of 2⁻⁸ below it are that grid point.
        Ok(micros) => ((micros * 256 / 1_000_000) as f64 * SEPARATION_QUANTUM).min(largest),
        Err(_) => largest,
    }
}

/// What the agents' controller keeps of a decided doublet for the block's estimate: its
/// index, public inputs and the controller's three samples.
#[must_use]
pub fn kept_doublet(doublet: u32, inputs: &DoubletInputs, samples: &[Pose; 3]) -> KeptDoublet {
    let unicycle = |u: Unicycle| [u.x, u.y];
    KeptDoublet {
        doublet,
        inputs: [unicycle(inputs.first), unicycle(inputs.second)],
        samples: samples.map(|p| [p.x, p.y, p.z]),
    }
}

/// One session's kept doublets with the robot's `bits` of it (`bits_per_doublet` per
/// doublet, in order) as the estimate reads them.
///
/// # Errors
/// The numbers do not match, or a kept value is not finite (a store that kept the wrong
/// thing), naming the session and the values.
fn with_bits(
    id: u32,
    kept: &[KeptDoublet],
    bits: &BitString,
    bits_per_doublet: usize,
) -> Result<Vec<DoubletSamples>, String> {
    if kept.len() * bits_per_doublet != bits.len() {
        return Err(format!(
            "session {id:08x}: the pool kept {} doublets for its {} raw bits (allowed: one per \
             {bits_per_doublet} bits; sessions pooled without their samples cannot be measured)",
            kept.len(),
            bits.len()
        ));
    }
    kept.iter()
        .enumerate()
        .map(|(i, k)| {
            let finite = k.inputs.iter().flatten().chain(k.samples.iter().flatten());
            if !finite.into_iter().all(|x| x.is_finite()) {
                return Err(format!(
                    "session {id:08x}: doublet {}'s kept samples are not finite",
                    k.doublet
                ));
            }
            let bit = |j: usize| {
                usize::from(
                    j < bits_per_doublet && bits.get(i * bits_per_doublet + j) == Some(true),
                )
            };
            Ok(DoubletSamples {
                doublet: k.doublet,
                inputs: DoubletInputs {
                    first: Unicycle::new(k.inputs[0][0], k.inputs[0][1]),
                    second: Unicycle::new(k.inputs[1][0], k.inputs[1][1]),
                },
                samples: k.samples.map(|p| Pose::new(p[0], p[1], p[2])),
                pattern: bit(0) | bit(1) << 1,
            })
        })
        .collect()
}

/// The agents' controller's estimate of the plant for its endpoint's `request` (the kept
/// samples and the robot's bits of each session) under `config` at ε_est = `epsilon`: the
/// same computation as the simulator's [`block_separations`], then the commands check at
/// level ε_est ([`commands_check::block_refusal`]), whose refusal is added to the block's.
#[must_use]
pub fn estimate_request(config: &Config, request: &EstimateRequest, epsilon: f64) -> BlockEstimate {
    let bits_per_doublet = usize::from(config.protocol.bits_per_doublet);
    let sessions: Result<Vec<Vec<DoubletSamples>>, String> = request
        .sessions
        .iter()
        .map(|(id, kept, bits)| with_bits(*id, kept, bits, bits_per_doublet))
        .collect();
    match sessions {
        Ok(sessions) => {
            let views: Vec<&[DoubletSamples]> = sessions.iter().map(Vec::as_slice).collect();
            let mut estimate = block_separations(config, &views, request.disclosed, epsilon).1;
            if let Some(why) = commands_check::block_refusal(config, &views, epsilon) {
                estimate.refuse(why);
            }
            estimate
        }
        Err(why) => BlockEstimate::refused(format!("motion-noise estimate: {why}"), 0, epsilon),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::lag::tests::doublets;

    /// A two-step block whose first steps show a 50 ms lag is refused by name (before the
    /// motion-noise estimate, which models none); one without lag is not refused for it.
    #[test]
    fn a_two_step_block_that_shows_a_lag_is_refused_naming_it() {
        let config = Config::from_toml("[sensing]\nmode = \"private\"\n", "t").unwrap();
        let refusal = |tau: f64| {
            let block = doublets(2000, tau, 7);
            block_separations(&config, &[&block], 0, 1e-6).1.refused
        };
        let lagging = refusal(0.05).expect("refused");
        assert!(lagging.starts_with("actuator lag"), "{lagging}");
        let still = refusal(0.0).unwrap_or_default();
        assert!(!still.contains("actuator lag"), "{still}");
    }
}
