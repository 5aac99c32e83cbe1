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
//!
//! **Three-step doublets** (`private.prior_lag`) are sized from the lag measured: first τ̂
//! from the first steps ([`estimate_lag`]), then τ̂ and its interval at ε_est/3 from the
//! first steps, the samples after the second steps (where the pool kept them), the ends and
//! the turns over the second and third steps jointly ([`estimate_lag_jointly`]), then the
//! residuals with the bit's and the nominal inputs' lagged means through τ̂ subtracted
//! ([`DoubletResidual::three_step`]; the wheels' speed at a doublet's start recomputed from
//! the previous doublet's nominal inputs and bits through τ̂, so a doublet whose predecessor
//! was not kept is left out), a check that a first-order lag explains the doublets' ends as
//! well as their middles (the dead-time test, [`lag_shape_refusal`]), then Q and ρ (at the
//! other 2ε_est/3) from each doublet's three one-step residuals where the pool kept the
//! sample after the second step ([`DoubletResidual::three_step_split`]; from its start-to-end
//! residual otherwise), and Eve's view at the worst case over the corners and every τ of its
//! interval ([`three_step_worst_case`]).

use std::collections::BTreeMap;
use std::sync::Arc;

use robokey_secrecy::BitString;
use robokey_secrecy::covariance_pair::{ChernoffExponents, SurprisalExponent, candidate_lambdas};
use robokey_secrecy::postprocess::{
    EstimateOutcome, EstimateRefusal, EstimateRequest, KeptDoublet, KeptLate, MAX_SEPARATION_STEPS,
    SEPARATION_QUANTUM, Slicing,
};
use robokey_secrecy::view_profile::{equivalent_separation, separation_counts};
use serde::{Deserialize, Serialize};

use super::correlation::{MIN_PAIRS_PER_BATCH, SlipShare, estimate_correlation};
use super::jitter::{
    JITTER_EPSILON_SHARE, JitterEstimate, JitterRows, MAX_JITTER_FRACTION, estimate_jitter,
};
use super::lag::{
    MIN_LAG_DOUBLETS, TurnCorrection, TurnCorrections, estimate_lag_jointly, first_step_share,
    first_step_share_slope, first_turn_factor, later_turn_factor,
};
use super::motion_noise::{Corner, SlipCorners, estimate_three_step_motion_noise_timed};
use super::normal_tail::normal_upper_quantile;
use super::pairs_over_lags::PairsOverLags;
use super::slip_slices::{SlipSlices, equivalent_separation as paired_separation};
use super::worst_case::{
    below_the_region, slip_pairs, three_step_slip_pairs, three_step_steps, three_step_worst_case,
    whole_interval_corner,
};
use super::{
    DoubletResidual, JitterVariances, LagEstimate, MotionNoiseEstimate, commands_check,
    diagonal_covariance, estimate_lag, estimate_motion_noise_timed, published_separation,
    worst_case_separations,
};
use nalgebra::Vector3;
use rayon::iter::{IndexedParallelIterator, IntoParallelRefIterator, ParallelIterator};

use crate::Config;
use crate::model::{Pose, Unicycle};
use crate::private::likelihood::{DoubletView, stated_camera_view};
use crate::private::{
    DoubletInputs, DoubletModel, DoubletSamples, LateSample, Perturbation, PoseObservation,
    doublet_model,
};
use crate::world::{WorldModel, lagged};

/// The separation fed for the sessions of a refused block: Eve is taken to see every bit
/// (the largest the endpoints accept), so the block gives no key.
const REFUSED_SEPARATION: f64 = 1e6;

/// A report's JSON writes a float that is not finite (a refused block's unmeasured `Q`)
/// as `null`; read back, that is NaN again.
mod null_as_nan {
    use serde::{Deserialize, Deserializer};

    pub(super) fn scalar<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
    }

    pub(super) fn pair<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 2], D::Error> {
        Ok(<[Option<f64>; 2]>::deserialize(d)?.map(|x| x.unwrap_or(f64::NAN)))
    }

    pub(super) fn triple<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
        Ok(<[Option<f64>; 3]>::deserialize(d)?.map(|x| x.unwrap_or(f64::NAN)))
    }
}

/// What the controller measured for one block, for reports.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BlockEstimate {
    /// Doublets whose residuals were used.
    pub doublets: usize,
    /// The point estimate's standard deviations √Q̂_kk (mm, mm, mrad; robot frame).
    #[serde(deserialize_with = "null_as_nan::triple")]
    pub point_std_mm: [f64; 3],
    /// The region's lowest vertex's √Q_low,kk at the correlation's upper end (mm, mm, mrad).
    #[serde(deserialize_with = "null_as_nan::triple")]
    pub lower_std_mm: [f64; 3],
    /// The motion noise's AR(1) correlation between steps: the point estimate ρ̂.
    #[serde(deserialize_with = "null_as_nan::scalar")]
    pub correlation: f64,
    /// Its (1 − ε_est/2) interval `[ρ_lo, ρ_hi]`, over which Eve's view is sized.
    #[serde(deserialize_with = "null_as_nan::pair")]
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
    /// Three-step doublets: the lag measured, `[τ̂, τ_lo, τ_hi]` (s), whose interval Eve's
    /// view is sized over; none with two steps.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lag: Option<[f64; 3]>,
    /// Two-step doublets refused for an actuator lag: the lag measured, `[τ̂, τ_lo, τ_hi]`
    /// (s), which the refusal names as the prior to state (`robokey prior`); none otherwise.
    /// Boxed, as `jitter`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unmodelled_lag: Option<Box<[f64; 3]>>,
    /// Per-wheel slip fitted beside `Q`, `[σ̂, σ_lo, σ_hi]` as fractions of each wheel's
    /// travel: where the block measures slip (`slip_sized`), the interval at ε_est/3 its key
    /// is sized over; otherwise the fit at level ε_est, whose interval reaches 0, so up to
    /// `σ_hi` of slip may go unseen and the key is not sized for it (docs/estimation.md,
    /// "Per-wheel slip"); none where not fitted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slip: Option<[f64; 3]>,
    /// Whether Eve's view was sized with the slip measured (bits whose noise depends on
    /// them: `separation` is then one Gaussian separation that bounds no more than the
    /// bit-dependent views do, for the bits it was computed over: the block's, or a slice's).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub slip_sized: bool,
    /// Two-step doublets: the controller's sample-timing jitter measured, `[ĵ, j_lo, j_hi]`
    /// (s) at ε_est/10 — `Q`'s bound and the class tests taken with the sensor's part at
    /// `j_hi`, Eve's view of the controller's samples at `j_lo` (docs/estimation.md,
    /// "Sample-timing jitter"); none with three steps. Boxed: the estimate rides in the
    /// connection's outputs, whose variants stay of a size.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub jitter: Option<Box<[f64; 3]>>,
    /// A multilevel block sized with the slip measured: each slice's bits' exponents, kept
    /// to size each slice ([`Self::for_slice`]); not reported, and none in a slice's own.
    #[serde(skip)]
    slip_slices: Option<Arc<SlipSlices>>,
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
        self.slip_slices = None;
    }

    /// What sizes slice `slice` of a multilevel block, sized as a key of its own
    /// (docs/estimation.md, "Multilevel symbols"): this estimate — its region, worst case and
    /// any refusal — with the equivalent separation of the slice's bits' worst-case
    /// `separations` alone (each session's), `disclosed` of them taken away by the slice's own
    /// sample, at most their largest. Where the block was sized with the slip measured, the
    /// slice's bits' own bound through their pairs instead, at every point of σ²'s grid the
    /// block was sized at ([`SlipSlices::separation`]; `separations` then only counts them).
    /// The slices share the block's one estimate: the event that its region misses the plant
    /// (probability ε_est) is one event for all of them.
    #[must_use]
    pub fn for_slice(&self, slice: usize, separations: &[Vec<f64>], disclosed: u64) -> Self {
        let own = Self {
            slip_slices: None,
            ..self.clone()
        };
        if own.refused.is_some() {
            return own;
        }
        if self.slip_sized {
            let bits: usize = separations.iter().map(Vec::len).sum();
            let sized = match self.slip_slices.as_deref() {
                Some(slices) if slices.bits(slice) == bits => {
                    slices.separation(slice, disclosed, self.epsilon)
                }
                Some(slices) => Err(format!(
                    "slice {slice} holds {bits} bits where the block's sizing kept {} of it \
                     (allowed: the slice of the block sized)",
                    slices.bits(slice)
                )),
                None => Err(
                    "the block's sizing kept no slice's exponents (allowed: the \
                             estimate of a multilevel block as sized)"
                        .to_owned(),
                ),
            };
            return match sized {
                Ok(separation) => Self {
                    separation,
                    largest: separation,
                    ..own
                },
                Err(why) => {
                    let mut refused = own;
                    refused.refuse(format!("per-wheel slip: slice {slice}: {why}"));
                    refused
                }
            };
        }
        let largest = separations.iter().flatten().fold(0.0_f64, |m, &x| m.max(x));
        Self {
            separation: equivalent(separations, disclosed, self.epsilon, largest),
            largest,
            ..own
        }
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
            lag: None,
            unmodelled_lag: None,
            slip: None,
            slip_sized: false,
            jitter: None,
            slip_slices: None,
        }
    }
}

/// Each of the block's `sessions`' bits' worst-case separations (each rounded up to the
/// published grid: the estimate depends on the bits, and what is published of it — the
/// block's equivalent separation, on the same grid — is charged by the assumption), and the
/// block's estimate, for the controller's samples of every carrying doublet of each session
/// (with the robot's bits) under the parties' `config` (their stated sensor calibration and
/// camera) at ε_est = `epsilon`, the smoothing ε as well; `disclosed` bits of the block are
/// disclosed by its sample. Two-step doublets: the samples' timing jitter from their
/// one-step residuals split at the middle samples at ε_est/10 ([`estimate_jitter`]), then
/// `Q`, per-wheel slip and ρ from those residuals with the sensor's part at the jitter's
/// upper end, at the rest of ε_est ([`estimate_motion_noise_timed`]), and Eve's view of the
/// controller's samples at its lower end.
#[must_use]
pub fn block_separations(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    disclosed: u64,
    epsilon: f64,
) -> (Vec<Vec<f64>>, BlockEstimate) {
    if config.doublet_settle().is_some() {
        return three_step_block(config, sessions, disclosed, epsilon);
    }
    let doublets: usize = sessions.iter().map(|session| session.len()).sum();
    if let Err((why, lag)) = no_measured_lag(config, sessions, epsilon) {
        let (separations, estimate) = refused(sessions.len(), why, doublets, epsilon);
        return (
            separations,
            BlockEstimate {
                unmodelled_lag: lag.map(Box::new),
                ..estimate
            },
        );
    }
    let model = doublet_model(config);
    let sensor = diagonal_covariance(config.sensing.controller_std);
    let steps = two_step_split_residuals(&model, config.robot.axle_length, sessions);
    let jitter = match measured_jitter(config, &steps, epsilon, JitterRows::Both) {
        Ok(jitter) => jitter,
        Err((why, jitter)) => {
            return timed(
                refused(sessions.len(), why, doublets, epsilon),
                jitter.as_ref(),
            );
        }
    };
    let timed = |sized| timed(sized, Some(&jitter));
    let region: Vec<DoubletResidual> = steps
        .iter()
        .map(|r| r.with_jitter(jitter.upper()))
        .collect();
    let region_epsilon = epsilon * (1.0 - JITTER_EPSILON_SHARE);
    let variances = JitterVariances {
        point: jitter.point.max(0.0),
        lower: jitter.lower(),
    };
    match estimate_motion_noise_timed(&region, &sensor, region_epsilon, variances) {
        Ok(estimate) => {
            let estimate = MotionNoiseEstimate {
                doublets,
                ..estimate
            };
            // Eve's view of each doublet's start and end samples at the jitter's lower end:
            // their rates from the first step's start and the second step's end.
            let rates: Vec<[Vector3<f64>; 2]> = steps
                .chunks_exact(2)
                .map(|pair| [pair[0].sample_velocities[1], pair[1].sample_velocities[0]])
                .collect();
            let timing = SampleTiming {
                rates: &rates,
                variance: jitter.lower(),
            };
            timed(size_block(
                config,
                sessions,
                disclosed,
                &estimate,
                None,
                epsilon,
                Some(&timing),
            ))
        }
        Err(refusal) => timed(refused(
            sessions.len(),
            refusal.to_string(),
            doublets,
            epsilon,
        )),
    }
}

/// The block's sample-timing jitter measured from its one-step residuals `steps` (in step
/// order, each start rate entered from the step before) at ε_est/10 ([`estimate_jitter`];
/// docs/estimation.md, "Sample-timing jitter"), or the refusal naming it, with the estimate
/// where there is one: not identified (too few consecutive pairs, or every shared sample at
/// one rate), or `j_hi` above a tenth of `robot.T` ([`MAX_JITTER_FRACTION`], the world's own
/// bound: the first-order model `t·u` assumes `t ≪ T`); `rows` the observations the fit reads.
fn measured_jitter(
    config: &Config,
    steps: &[DoubletResidual],
    epsilon: f64,
    rows: JitterRows,
) -> Result<JitterEstimate, (String, Option<JitterEstimate>)> {
    let sensor = diagonal_covariance(config.sensing.controller_std);
    let Some(jitter) = estimate_jitter(steps, &sensor, epsilon * JITTER_EPSILON_SHARE, rows) else {
        return Err((
            format!(
                "sample-timing jitter: not identified from {} one-step residuals (allowed: at \
                 least {} consecutive pairs whose shared samples' rates differ)",
                steps.len(),
                2 * MIN_PAIRS_PER_BATCH
            ),
            None,
        ));
    };
    let [point, low, high] = jitter.stds();
    let largest = MAX_JITTER_FRACTION * config.robot.sample_time;
    if high > largest {
        return Err((
            format!(
                "sample-timing jitter beyond the class: ĵ = {:.2} ms, interval [{:.2}, {:.2}] ms \
                 (allowed: at most {:.1} ms, a tenth of robot.T)",
                1e3 * point,
                1e3 * low,
                1e3 * high,
                1e3 * largest
            ),
            Some(jitter),
        ));
    }
    Ok(jitter)
}

/// A block's separations and report with the sample-timing `jitter` measured, where there is
/// one, in its record (`[ĵ, j_lo, j_hi]`, [`BlockEstimate::jitter`]).
fn timed(
    (separations, mut block): (Vec<Vec<f64>>, BlockEstimate),
    jitter: Option<&JitterEstimate>,
) -> (Vec<Vec<f64>>, BlockEstimate) {
    block.jitter = jitter.map(|j| Box::new(j.stds()));
    (separations, block)
}

/// The controller's samples' timing noise in Eve's view of two-step doublets: each
/// doublet's start and end sample rates (world frame, m/s, m/s, rad/s; in the block's order)
/// and the timing variance j² (s²) they are taken at.
struct SampleTiming<'a> {
    rates: &'a [[Vector3<f64>; 2]],
    variance: f64,
}

/// Eve's stated camera view of a two-step doublet's `samples` (start, middle, end) with the
/// controller's start and end samples' noise `R + j²uuᵀ` at their `rates` (world frame) and
/// j² = `variance` (s²): [`stated_camera_view`] itself where `variance` is 0.
fn timed_camera_view(
    config: &Config,
    samples: [Pose; 3],
    rates: [Vector3<f64>; 2],
    variance: f64,
) -> DoubletView {
    let mut view = stated_camera_view(
        samples,
        config.sensing.controller_std,
        config.modelled_camera_std(),
    );
    if variance > 0.0 {
        let sensor = diagonal_covariance(config.sensing.controller_std);
        let at = |k: usize, u: Vector3<f64>| {
            PoseObservation {
                value: samples[k],
                covariance: sensor + variance * u * u.transpose(),
            }
            .fuse(&PoseObservation::new(
                samples[k],
                config.modelled_camera_std(),
            ))
        };
        view.start = at(0, rates[0]);
        view.end = Some(at(2, rates[1]));
    }
    view
}

/// The one-step residuals of every doublet of `sessions`, split at its middle sample with
/// the steps of the symbols it carried ([`DoubletResidual::two_step_split`]): what a
/// two-step block's `Q`, slip and ρ are measured from.
fn two_step_split_residuals(
    model: &DoubletModel,
    axle: f64,
    sessions: &[&[DoubletSamples]],
) -> Vec<DoubletResidual> {
    let mut steps: Vec<DoubletResidual> = sessions
        .iter()
        .flat_map(|session| session.iter())
        .flat_map(|b| {
            let [start, middle, end] = &b.samples;
            DoubletResidual::two_step_split(
                model,
                axle,
                b.doublet,
                &b.inputs,
                [start, middle, end],
                b.pattern,
            )
        })
        .collect();
    entered(&mut steps);
    steps
}

/// Each of the one-step residuals `steps` (in step order) with its start sample's rate taken
/// from the step before it where that step is there ([`DoubletResidual::enter_from`]): the
/// rate a sample's timing error moves it along, the step before the sample's applied speed.
fn entered(steps: &mut [DoubletResidual]) {
    for k in 1..steps.len() {
        let previous = steps[k - 1];
        steps[k].enter_from(&previous);
    }
}

/// As [`block_separations`], with the simulated world's own stationary motion noise,
/// AR(1) correlation and (three-step doublets) lag in place of the estimate's region: what a pair configured with the
/// true world sizes (`robokey secrecy --sizing world`, the comparison for measured sizing;
/// no robot knows its world, so the agents refuse it).
#[must_use]
pub fn world_block_separations(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    disclosed: u64,
    epsilon: f64,
) -> (Vec<Vec<f64>>, BlockEstimate) {
    let world = WorldModel::of(config);
    let q = diagonal_covariance(world.process_std);
    // The world's slip, where it has any: Eve's view sized with it at its one value.
    let truth = if world.slip_std > 0.0 {
        MotionNoiseEstimate::known_with_slip(
            q,
            world.process_rho,
            world.slip_std * world.slip_std,
            epsilon,
        )
    } else {
        MotionNoiseEstimate::known(q, world.process_rho, epsilon)
    };
    // Three-step doublets at the world's own lag (its dead time not modelled).
    let lag = config.doublet_settle().map(|_| {
        let share = first_step_share(world.lag, config.robot.sample_time);
        LagEstimate {
            point: world.lag,
            interval: [world.lag; 2],
            share,
            share_interval: [share; 2],
            doublets: 0,
        }
    });
    size_block(
        config,
        sessions,
        disclosed,
        &truth,
        lag.as_ref(),
        epsilon,
        None,
    )
}

/// The share of ε_est the lag's interval takes in a three-step block (the motion noise's
/// region takes the rest).
const LAG_EPSILON_SHARE: f64 = 1.0 / 3.0;

/// A three-step block (the module's doc): the lag measured at ε_est/3, the residuals with
/// the lagged means through τ̂ subtracted, the dead-time test at level ε_est, Q and ρ at
/// 2ε_est/3, Eve's view at the worst case over the corners and τ's interval. Where the
/// turns are in τ's statistic, τ̂ is taken again at the correlation measured through the
/// first τ̂ and τ's interval over the region's interval of ρ (their bias under AR(1) noise,
/// [`TurnCorrection`]; both failure events are in ε_est already: ρ's interval is the
/// region's).
fn three_step_block(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    disclosed: u64,
    epsilon: f64,
) -> (Vec<Vec<f64>>, BlockEstimate) {
    let doublets: usize = sessions.iter().map(|session| session.len()).sum();
    let lag_epsilon = LAG_EPSILON_SHARE * epsilon;
    // The sample after the second step where every doublet kept it (a block holding
    // sessions pooled before it was kept is measured from the first step and the end, the
    // turns left out: their products' bias under AR(1) noise is corrected with the sample
    // after the previous doublet's second step).
    let late = sessions
        .iter()
        .all(|session| session.iter().all(|b| b.late.is_some()));
    let turns = late.then(|| heading_slopes(config, sessions)).flatten();
    let first_turns = late.then(|| first_turn_weights(config, sessions)).flatten();
    let products = |tau: f64| {
        let (turns, first_turns) = (turns.as_deref(), first_turns.as_deref());
        lag_residual_products(config, sessions, tau, late, turns, first_turns)
    };
    let corrections = turn_corrections(late, turns.is_some(), first_turns.is_some());
    let over = |correlation: [f64; 2]| TurnCorrections {
        corrections: &corrections,
        correlation,
    };
    let joint = |first: &LagEstimate, correlation: [f64; 2]| {
        estimate_lag_jointly(
            first,
            &products,
            &over(correlation),
            config.robot.sample_time,
            lag_epsilon,
        )
    };
    let (first, plain) = match measured_lag(config, sessions, lag_epsilon)
        .and_then(|first| joint(&first, [0.0, 0.0]).map(|lag| (first, lag)))
    {
        Ok(lags) => lags,
        Err(why) => return refused(sessions.len(), why, doublets, epsilon),
    };
    // Each doublet's three one-step residuals where every doublet kept the sample after
    // its second step, its start-to-end residual otherwise, with the lagged means through
    // `lag` subtracted.
    let residuals_at = |lag: f64| {
        let at_point = DoubletModel {
            lag,
            ..doublet_model(config)
        };
        if late {
            (
                split_residuals(&at_point, config.robot.axle_length, sessions),
                3,
            )
        } else {
            let whole = three_step_residuals(&at_point, config.robot.axle_length, sessions);
            (whole, 1)
        }
    };
    let sensor = diagonal_covariance(config.sensing.controller_std);
    let region = (1.0 - LAG_EPSILON_SHARE) * epsilon;
    // Where the turns are in τ's statistic their means under AR(1) noise follow ρ: τ̂ is
    // taken again at the correlation measured through the first τ̂ (a point estimate, at no
    // level), the region through that τ̂, and τ's interval over the region's interval of ρ.
    let centre = if corrections.is_empty() {
        plain.point
    } else {
        let (residuals, _) = residuals_at(plain.point);
        match estimate_correlation(&residuals, &sensor, region / 2.0, SlipShare::NONE) {
            Ok(correlation) => {
                joint(&first, [correlation.point; 2]).map_or(plain.point, |l| l.point)
            }
            Err(_) => plain.point,
        }
    };
    let (residuals, per_doublet) = residuals_at(centre);
    let used = residuals.len() / per_doublet;
    if let Some(why) = lag_shape_refusal(config, sessions, &first, epsilon) {
        return refused(sessions.len(), why, used, epsilon);
    }
    // The sample-timing jitter from the one-step residuals with the lagged means through τ̂
    // subtracted, at ε_est/10 of the region's share: not measured from start-to-end
    // residuals, so a block without the sample after the second step is refused for it.
    if !late {
        return refused(
            sessions.len(),
            "sample-timing jitter: not measured: a session of the block was pooled without \
             the sample after each doublet's second step, and its start-to-end residuals share \
             no consecutive one-step pair (allowed: every doublet keeps that sample)"
                .to_owned(),
            used,
            epsilon,
        );
    }
    let jitter = match measured_jitter(config, &residuals, epsilon, JitterRows::Products) {
        Ok(jitter) => jitter,
        Err((why, jitter)) => {
            return timed(refused(sessions.len(), why, used, epsilon), jitter.as_ref());
        }
    };
    let timed = |sized| timed(sized, Some(&jitter));
    let steps: Vec<DoubletResidual> = residuals
        .iter()
        .map(|r| r.with_jitter(jitter.upper()))
        .collect();
    let variances = JitterVariances {
        point: jitter.point.max(0.0),
        lower: jitter.lower(),
    };
    let region = region - JITTER_EPSILON_SHARE * epsilon;
    match estimate_three_step_motion_noise_timed(&steps, &sensor, region, variances) {
        Ok(estimate) => {
            let estimate = MotionNoiseEstimate {
                doublets: used,
                ..estimate
            };
            let lag = if corrections.is_empty() {
                plain
            } else {
                match joint(&first, estimate.correlation.interval) {
                    Ok(lag) => lag,
                    Err(why) => return timed(refused(sessions.len(), why, used, epsilon)),
                }
            };
            // Eve's view of the controller's samples with the sensor's `R` alone: below the
            // jitter's lower end (j² = 0 sharpens her view most).
            timed(size_block(
                config,
                sessions,
                disclosed,
                &estimate,
                Some(&lag),
                epsilon,
                None,
            ))
        }
        Err(refusal) => timed(refused(
            sessions.len(),
            format!(
                "{refusal} (three-step doublets, the lag measured {centre:.4} s [{:.4}, {:.4}])",
                plain.interval[0], plain.interval[1]
            ),
            used,
            epsilon,
        )),
    }
}

/// The corrections of the turns' products in τ's statistic (`lag_residual_products`'s order:
/// the v-bit's products, then the turn over the second and third steps where `later`, the
/// first step's turn where `first`, then their straddle products in the same order): none
/// without `late` (the turns are left out there).
fn turn_corrections(late: bool, later: bool, first: bool) -> Vec<TurnCorrection> {
    if !late {
        return Vec::new();
    }
    let along = 3;
    let kinds = [
        (later, later_turn_factor as fn(f64) -> f64),
        (first, first_turn_factor),
    ];
    let kept: Vec<fn(f64) -> f64> = kinds
        .iter()
        .filter(|(on, _)| *on)
        .map(|(_, f)| *f)
        .collect();
    kept.iter()
        .enumerate()
        .map(|(k, &factor)| TurnCorrection {
            component: along + k,
            straddle: along + kept.len() + k,
            factor,
        })
        .collect()
}

/// The wheels' speed at the start of each of `session`'s three-step doublets through
/// `model`'s lag τ (m/s, rad/s): the previous doublet's nominal inputs (from its first, the
/// speed before it taken as settled there: the error decays by `e^(−3T/τ)` over its three
/// steps) plus its bits' offsets from rest (what a lag other than the prior leaves of
/// them); none for a doublet whose predecessor is not kept.
fn entry_speeds(model: &DoubletModel, session: &[DoubletSamples]) -> Vec<Option<Unicycle>> {
    let t = model.sample_time;
    let mut out = vec![None; session.len()];
    for (i, pair) in session.windows(2).enumerate() {
        let [previous, this] = [&pair[0], &pair[1]];
        if this.doublet != previous.doublet + 1 {
            continue;
        }
        let inputs = &previous.inputs;
        let (_, nominal) = inputs.nominal_transient(inputs.first, 3, model.lag, t);
        let offsets = model.step_offsets(inputs, Some(previous.pattern));
        let bit = offsets.iter().fold(Unicycle::zeros(), |speed, &c| {
            lagged(c, speed, t, model.lag).1
        });
        out[i + 1] = Some(nominal + bit);
    }
    out
}

/// The three-step residuals of every doublet of `sessions` whose entry speed is known, with
/// the lagged means through `model`'s lag ([`DoubletResidual::three_step`]), on wheels
/// `axle` D (m) apart.
fn three_step_residuals(
    model: &DoubletModel,
    axle: f64,
    sessions: &[&[DoubletSamples]],
) -> Vec<DoubletResidual> {
    three_step_doublets(model, axle, sessions)
        .into_iter()
        .map(|(residual, _)| residual)
        .collect()
}

/// The one-step residuals of every doublet of `sessions` whose entry speed is known
/// ([`DoubletResidual::three_step_split`]: from each kept sample to the next, the sample
/// after the second step included), with the lagged means through `model`'s lag, on wheels
/// `axle` D (m) apart; every doublet has kept its sample after the second step. Each start
/// sample's rate is the step before it's mean speed through τ where that step is there
/// ([`entered`]; the speed the simulator's Euler world moves a jittered sample along).
fn split_residuals(
    model: &DoubletModel,
    axle: f64,
    sessions: &[&[DoubletSamples]],
) -> Vec<DoubletResidual> {
    let mut steps: Vec<DoubletResidual> = with_entry_speed(model, sessions, |b, entry| {
        let [start, middle, end] = &b.samples;
        Some(DoubletResidual::three_step_split(
            model,
            axle,
            b.doublet,
            &b.inputs,
            [start, middle, &b.late?.sample, end],
            b.pattern,
            entry,
        ))
    })
    .into_iter()
    .flatten()
    .collect();
    entered(&mut steps);
    steps
}

/// `per_doublet` of every doublet of `sessions` whose entry speed is known (its predecessor
/// kept: [`entry_speeds`] through `model`'s lag), given that speed; `None` leaves it out.
/// The doublets are a map on rayon's current pool (each result depends on its doublet and
/// entry speed alone), collected in the block's order.
fn with_entry_speed<T: Send>(
    model: &DoubletModel,
    sessions: &[&[DoubletSamples]],
    per_doublet: impl Fn(&DoubletSamples, Unicycle) -> Option<T> + Sync,
) -> Vec<T> {
    let entered: Vec<(&DoubletSamples, Unicycle)> = sessions
        .iter()
        .flat_map(|session| {
            entry_speeds(model, session)
                .into_iter()
                .zip(session.iter())
                .filter_map(|(entry, b)| Some((b, entry?)))
                .collect::<Vec<_>>()
        })
        .collect();
    let results: Vec<Option<T>> = entered
        .par_iter()
        .map(|&(b, entry)| per_doublet(b, entry))
        .collect();
    results.into_iter().flatten().collect()
}

/// Each three-step doublet's residuals along its start heading after its first step, after
/// its second (with `late`: the kept sample `y(3j+2)`) and at its end, with the lagged means
/// through `lag` (s) subtracted ([`DoubletResidual::three_step_means`]), times its
/// v-amplitude (m); with `turns` (`heading_slopes`, one per doublet measured) also its
/// heading residual over its second and third steps, `θ(3j+3) − θ(3j+1)` less the lagged
/// means' turn, times that slope (rad²/s); with `first_turns` (`first_turn_weights`) its heading
/// residual over its first step, `θ(3j+1) − θ(3j)` less the lagged means' turn, times that
/// weight `a`, plus the weight's correction `R_θ·∂a/∂θ̂` (rad²/s); after them, with `late`,
/// each turn's weight times the doublet's straddle residual (`straddle_turns`), whose
/// product measures the turn's bias under AR(1) noise ([`TurnCorrection`]; a doublet whose
/// straddle is not known carries 0 in its turns' products and straddles): what
/// [`estimate_lag_jointly`] measures τ from. A doublet whose predecessor is not kept is left
/// out (its entry speed is not known), and with `late` one that did not keep the sample
/// after its second step.
fn lag_residual_products(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    lag: f64,
    late: bool,
    turns: Option<&[f64]>,
    first_turns: Option<&[[f64; 2]]>,
) -> Vec<Vec<f64>> {
    let model = DoubletModel {
        lag,
        ..doublet_model(config)
    };
    let measured = lag_doublets(&model, sessions, late, |b, means| {
        let [start, middle, end] = &b.samples;
        let (sin, cos) = start.z.sin_cos();
        let amplitude = model.perturbation.amplitude(b.pattern);
        let along = |sample: &Pose, mean: &Pose| {
            amplitude * ((sample.x - mean.x) * cos + (sample.y - mean.y) * sin)
        };
        let second = b
            .late
            .filter(|_| late)
            .map(|kept| along(&kept.sample, &means[1]));
        let products: Vec<f64> = std::iter::once(along(middle, &means[0]))
            .chain(second)
            .chain(std::iter::once(along(end, &means[2])))
            .collect();
        let first = middle.z - means[0].z;
        (
            products,
            end.z - middle.z - (means[2].z - means[0].z),
            first,
        )
    });
    let straddles = (late && (turns.is_some() || first_turns.is_some()))
        .then(|| straddle_turns(&model, sessions));
    measured
        .into_iter()
        .enumerate()
        .map(|(i, (mut products, turn, first))| {
            // A doublet whose straddle is not known carries no turn products (0, as their
            // straddles: still of mean 0).
            let straddle = straddles.as_ref().map(|s| s[i]);
            let kept = if straddle == Some(None) { 0.0 } else { 1.0 };
            let mut after = Vec::new();
            if let Some(turns) = turns {
                products.push(kept * turns[i] * turn);
                after.extend(straddle.map(|s| s.map_or(0.0, |s| turns[i] * s)));
            }
            if let Some(weights) = first_turns {
                let [weight, correction] = weights[i];
                products.push(kept * (weight * first + correction));
                after.extend(straddle.map(|s| s.map_or(0.0, |s| weight * s)));
            }
            products.extend(after);
            products
        })
        .collect()
}

/// Each three-step doublet's straddle residual, per doublet `lag_residual_products` measures
/// (every doublet kept its sample after the second step): the heading from the previous
/// doublet's sample after its second step to this doublet's sample after its first,
/// `θ̂(3j+1) − θ̂(3j−1)`, less the lagged means' turn over those two steps through `model`'s
/// lag (rad). Its noise is the heading noise of steps `3j−1` and `3j` and the sensor's at
/// two samples the controller did not read; none where the previous doublet's own entry
/// speed is not known (its predecessor not kept).
fn straddle_turns(model: &DoubletModel, sessions: &[&[DoubletSamples]]) -> Vec<Option<f64>> {
    sessions
        .iter()
        .flat_map(|session| {
            let entries = entry_speeds(model, session);
            let means = |i: usize| {
                let b: &DoubletSamples = &session[i];
                entries[i].map(|entry| {
                    DoubletResidual::three_step_means(
                        model,
                        &b.inputs,
                        &b.samples[0],
                        b.pattern,
                        entry,
                    )
                    .1
                })
            };
            (0..session.len())
                .filter(|&i| entries[i].is_some() && session[i].late.is_some())
                .map(|i| {
                    let (b, previous) = (&session[i], &session[i - 1]);
                    let own = means(i)?;
                    let before = means(i - 1)?;
                    let late = previous.late?.sample;
                    let turn = (before[2].z - before[1].z) + (own[0].z - b.samples[0].z);
                    Some(b.samples[1].z - late.z - turn)
                })
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Each doublet's weight on its first step's turn and that weight's correction, `[a, R_θ·∂a/∂θ̂]`
/// (rad/s, rad²/s), per doublet `lag_residual_products` measures: `a = −T·g′(τ_p)·(ω_e − ω₁)`
/// the slope in τ of the first step's lagged turn `T·(ω₁ + (ω_e − ω₁)·(1 − g(τ)))` at the
/// prior `private.prior_lag` τ_p ([`first_step_share_slope`]; ω₁ the first nominal input, ω_e
/// the wheels' entry speed through τ_p, rad/s). The controller set ω₁ from its sample at the
/// doublet's start, whose heading noise `η₀` (variance `R_θ`, `sensing.controller_std`) the
/// turn's residual carries as `−η₀`: `E[a·(−η₀)] = −R_θ·E[∂a/∂η₀]` (Stein's identity: Gaussian
/// `η₀`, `a` differentiable in it), so `a·r₁ + R_θ·∂a/∂θ̂` has mean 0 at the true τ, with
/// `∂a/∂θ̂ = T·g′(τ_p)·∂ω₁/∂θ̂` the controller's own gain
/// ([`crate::control::TrackingGains::heading_gain`], from ω₁'s command and the predecessor's
/// second, whose speed is the integrator ξ the law held). The rest of the residual, the first
/// step's motion noise and the heading sample after it, is independent of `a` under white
/// noise. Under AR(1) motion noise of correlation ρ the step's noise also correlates with the
/// heading the controller read, through the step before: the product's mean is then
/// `ρ·E[a·w(3j−1)]`, corrected over ρ's interval with the straddle residual
/// (`straddle_turns`, [`TurnCorrection`]). None where the block's path carries no turns or where any doublet's command or
/// its predecessor's lies at the wheel limit or at the controller's guard (the gain is not
/// the law's there).
fn first_turn_weights(config: &Config, sessions: &[&[DoubletSamples]]) -> Option<Vec<[f64; 2]>> {
    let model = doublet_model(config);
    let t = model.sample_time;
    let gains = crate::control::TrackingGains::of(&config.controller);
    let drive = config.robot.drive();
    let noise = config.sensing.controller_std[2].powi(2);
    let slope = -t * first_step_share_slope(model.lag, t);
    let weights = sessions
        .iter()
        .flat_map(|session| {
            let entries = entry_speeds(&model, session);
            session
                .iter()
                .zip(entries)
                .enumerate()
                .filter_map(|(i, (b, entry))| {
                    let entry = entry?;
                    let previous = session[i - 1].inputs.second;
                    let gain = gains.heading_gain(&drive, previous, b.inputs.first, t);
                    Some(gain.map(|gain| {
                        let weight = slope * (entry.y - b.inputs.first.y);
                        [weight, -noise * slope * gain]
                    }))
                })
                .collect::<Vec<_>>()
        })
        .collect::<Option<Vec<_>>>()?;
    let mean_square = weights.iter().map(|[a, _]| a * a).sum::<f64>() / weights.len().max(1) as f64;
    (mean_square.sqrt() > MIN_TURN_SLOPE).then_some(weights)
}

/// The lag step (s) of the heading's numerical slope in τ.
const TURN_SLOPE_STEP: f64 = 1e-3;

/// The least root-mean-square heading slope (rad/s per s of lag) `heading_slopes` reads as
/// nominal turns, far above the numerical difference's rounding (≈ 10⁻¹³) and far below
/// what a path that turns carries (0.13 in the grid's square).
const MIN_TURN_SLOPE: f64 = 1e-9;

/// Each doublet's turn over its second and third steps through the lag at `private.prior_lag`
/// `τ_p`: its slope in τ there, `a = ∂(θ̄₃ − θ̄₁)/∂τ` (rad/s; a central difference, the entry
/// speed recomputed at each τ), per doublet `lag_residual_products` measures. The nominal
/// inputs change between and within doublets (the path turns; the controller corrects), and
/// through τ each change leaves a transient in the turn that τ scales: `a·(θ(3j+3) − θ(3j+1)
/// − (θ̄₃ − θ̄₁)(τ))` has mean 0 at the true τ, as the v-bit's products do, and moves with τ.
/// The inputs come from the controller's sample at the doublet's start and the slope from the
/// prior, so under white noise `a` is independent of that residual's noise (the motion noise
/// of the second and third steps, the heading samples after the first step and at the end):
/// the products are martingale differences (under AR(1) noise the second and third steps'
/// noise follows the step before the start sample, which the controller read, by ρ² and ρ³:
/// the product's mean is `ρ²·(1 + ρ)·E[a·w(3j−1)]`, corrected over ρ's interval with the
/// straddle residual, [`TurnCorrection`]). None where the block's path carries no turns.
fn heading_slopes(config: &Config, sessions: &[&[DoubletSamples]]) -> Option<Vec<f64>> {
    let prior = config.private.prior_lag;
    let [below, above] = [(prior - TURN_SLOPE_STEP).max(0.0), prior + TURN_SLOPE_STEP];
    let [low, high] = [below, above].map(|lag| {
        let model = DoubletModel {
            lag,
            ..doublet_model(config)
        };
        lag_doublets(&model, sessions, true, |_, means| means[2].z - means[0].z)
    });
    let slopes: Vec<f64> = low
        .iter()
        .zip(&high)
        .map(|(l, h)| (h - l) / (above - below))
        .collect();
    let mean_square = slopes.iter().map(|a| a * a).sum::<f64>() / slopes.len().max(1) as f64;
    (mean_square.sqrt() > MIN_TURN_SLOPE).then_some(slopes)
}

/// `per_doublet` of each three-step doublet of `sessions` the lag is measured from, given
/// the lagged means of its poses after each step through `model`'s lag
/// ([`DoubletResidual::three_step_means`], the entry speed from its kept predecessor): every
/// doublet whose predecessor is kept, with `late` only those that kept the sample after
/// their second step.
fn lag_doublets<T: Send>(
    model: &DoubletModel,
    sessions: &[&[DoubletSamples]],
    late: bool,
    per_doublet: impl Fn(&DoubletSamples, &[Pose; 3]) -> T + Sync,
) -> Vec<T> {
    with_entry_speed(model, sessions, |b, entry| {
        if late && b.late.is_none() {
            return None;
        }
        let (_, means) =
            DoubletResidual::three_step_means(model, &b.inputs, &b.samples[0], b.pattern, entry);
        Some(per_doublet(b, &means))
    })
}

/// [`three_step_residuals`] with the pattern each doublet carried.
fn three_step_doublets(
    model: &DoubletModel,
    axle: f64,
    sessions: &[&[DoubletSamples]],
) -> Vec<(DoubletResidual, usize)> {
    with_entry_speed(model, sessions, |b, entry| {
        let residual = DoubletResidual::three_step(
            model,
            axle,
            b.doublet,
            &b.inputs,
            [&b.samples[0], &b.samples[2]],
            b.pattern,
            entry,
        );
        Some((residual, b.pattern))
    })
}

/// Lags the dead-time test tries over the lag's interval.
const SHAPE_GRID: usize = 9;

/// The dead-time test of a three-step block: a first-order lag whose first steps carry the
/// share measured (`lag`'s interval) also fixes what the v-bit leaves at the doublet's end.
/// The end residual along the start heading, with the lagged means through τ subtracted,
/// regressed on the v-bit's sign (a multilevel v-symbol's amplitude), `β(τ) = mean sᵢzᵢ`, is 0 under the class at the true τ;
/// the block is refused when at every τ of a grid over the interval `|β(τ)|` stands more
/// than `z(ε_est/2)` standard errors from 0, naming the values. A pure dead time `D ≪ T`
/// leaves, at the sample instants, what a lag `τ = D` leaves up to terms in `e^(−T/D)`: the
/// test sees (and Eve's per-instant view suffers) the difference only where it shows.
pub fn lag_shape_refusal(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    lag: &LagEstimate,
    epsilon: f64,
) -> Option<String> {
    let limit = normal_upper_quantile(epsilon / 2.0);
    let [low, high] = lag.interval;
    let grid: Vec<f64> = if high > low {
        (0..SHAPE_GRID)
            .map(|i| low + (high - low) * i as f64 / (SHAPE_GRID - 1) as f64)
            .collect()
    } else {
        vec![low]
    };
    let fits = grid.iter().map(|&tau| {
        let model = DoubletModel {
            lag: tau,
            ..doublet_model(config)
        };
        let x: Vec<f64> = three_step_doublets(&model, config.robot.axle_length, sessions)
            .iter()
            .map(|(r, pattern)| model.perturbation.amplitude(*pattern) * r.value[0])
            .collect();
        let n = x.len().max(2) as f64;
        let mean = x.iter().sum::<f64>() / n;
        let variance = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (tau, mean, (variance / n).sqrt())
    });
    let (tau, beta, error) = fits.min_by(|a, b| (a.1.abs() / a.2).total_cmp(&(b.1.abs() / b.2)))?;
    let statistic = beta.abs() / error;
    (statistic > limit).then(|| {
        format!(
            "lag shape: the doublets' ends along the heading regress on the v-bit by {:.3} mm \
             (standard error {:.3} mm, {statistic:.1} of them) at the lag of [{low:.4}, \
             {high:.4}] s that explains them best ({tau:.4} s), where a first-order lag leaves \
             none (allowed: within {limit:.1} at level ε_est): a dead time, or a plant outside \
             the first-order lag class",
            1e3 * beta,
            1e3 * error
        )
    })
}

/// The lag measured from the block's `sessions` at ε_est = `epsilon` ([`estimate_lag`]).
fn measured_lag(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    epsilon: f64,
) -> Result<LagEstimate, String> {
    estimate_lag(
        sessions.iter().flat_map(|session| session.iter()),
        &Perturbation::of(config),
        config.robot.sample_time,
        epsilon,
    )
}

/// The two-step doublet's estimate models no actuator lag or dead time: a block of two-step
/// doublets whose first steps carry less of the v-bit's travel than all of it at level
/// ε_est (the share's interval below 1), or a share beyond the class, is refused, naming the
/// share and the lag that explains it (`[τ̂, τ_lo, τ_hi]`, s, with the reason, where it was
/// measured). Too few doublets to tell are left to the motion-noise estimate, which needs
/// more.
fn no_measured_lag(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    epsilon: f64,
) -> Result<(), (String, Option<[f64; 3]>)> {
    let doublets: usize = sessions.iter().map(|session| session.len()).sum();
    if config.doublet_settle().is_some() || doublets < MIN_LAG_DOUBLETS {
        return Ok(());
    }
    let lag = measured_lag(config, sessions, epsilon).map_err(|why| (why, None))?;
    if lag.interval[0] > 0.0 {
        let [low, high] = lag.share_interval;
        let why = format!(
            "actuator lag: the doublets' first steps carry {:.4} [{low:.4}, {high:.4}] of the \
             v-bit's travel over {} doublets, what a lag (or dead time) of {:.4} s [{:.4}, \
             {:.4}] leaves; the two-step doublet's estimate models none (allowed: a share \
             whose interval reaches 1; to key under this lag, state it as the prior on both \
             agents, `--set private.prior_lag={:.4}`, which shapes three-step doublets)",
            lag.share, lag.doublets, lag.point, lag.interval[0], lag.interval[1], lag.point
        );
        return Err((why, Some([lag.point, lag.interval[0], lag.interval[1]])));
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
/// equivalent separation at the block's ε_est = `epsilon` (the smoothing ε as well),
/// `disclosed` of its bits disclosed by the sample; three-step doublets over the `lag`
/// measured's interval too.
fn size_block(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    disclosed: u64,
    estimate: &MotionNoiseEstimate,
    lag: Option<&LagEstimate>,
    epsilon: f64,
    timing: Option<&SampleTiming<'_>>,
) -> (Vec<Vec<f64>>, BlockEstimate) {
    if let Some(points) = &estimate.slip_corners {
        return size_slip_block(points, config, sessions, disclosed, estimate, lag, epsilon);
    }
    let lags = lag.map(|lag| (lag.interval, three_step_steps(estimate)));
    let model = doublet_model(config);
    let bits = model.perturbation.key_bits();
    // Each doublet's worst case, the doublets on rayon's pool (`kept` its place in the
    // block), kept in the block's order.
    let mut worst = block_doublets(sessions)
        .par_iter()
        .enumerate()
        .map(|(kept, &(session, i))| {
            let b = &session[i];
            // The camera as stated: per instant, or her frames' worth per instant; the
            // controller's samples with their timing noise where it is measured.
            match &lags {
                None => {
                    let view = match timing {
                        Some(t) => timed_camera_view(config, b.samples, t.rates[kept], t.variance),
                        None => stated_camera_view(
                            b.samples,
                            config.sensing.controller_std,
                            config.modelled_camera_std(),
                        ),
                    };
                    worst_case_separations(&model, estimate, &b.inputs, &view)
                }
                Some((lags, steps)) => {
                    let (view, next) = three_step_views(config, session, i);
                    three_step_worst_case(
                        &model,
                        steps,
                        *lags,
                        &b.inputs,
                        &view,
                        Some((&next.0, &next.1)),
                    )
                }
            }
        })
        .collect::<Vec<_>>()
        .into_iter();
    let mut separations = Vec::with_capacity(sessions.len());
    for session in sessions {
        let mut session_separations = Vec::with_capacity(session.len() * bits);
        for (b, worst) in session.iter().zip(worst.by_ref()) {
            match worst {
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
    let largest = separations.iter().flatten().fold(0.0_f64, |m, &x| m.max(x));
    let separation = equivalent(&separations, disclosed, epsilon, largest);
    let lag = lag.map(|lag| [lag.point, lag.interval[0], lag.interval[1]]);
    (
        separations,
        sized_report(estimate, epsilon, [separation, largest], lag, false),
    )
}

/// Every doublet of the block's `sessions`, in order: its session and its place there.
fn block_doublets<'a>(sessions: &[&'a [DoubletSamples]]) -> Vec<(&'a [DoubletSamples], usize)> {
    sessions
        .iter()
        .flat_map(|session| (0..session.len()).map(move |i| (*session, i)))
        .collect()
}

/// Eve's stated camera view of `session`'s three-step doublet `i` (its four instants; the
/// late sample is not kept, and its value does not enter her separations) and of the next
/// doublet's entry: the kept successor's inputs and view, or where none is kept (she still
/// sees the robot move on) this doublet's own inputs and view from its end.
fn three_step_views(
    config: &Config,
    session: &[DoubletSamples],
    i: usize,
) -> (DoubletView, (DoubletInputs, DoubletView)) {
    let of = |b: &DoubletSamples| {
        let [start, middle, end] = b.samples;
        stated_camera_view(
            [start, middle, middle, end],
            config.sensing.controller_std,
            config.modelled_camera_std(),
        )
    };
    let b = &session[i];
    let view = of(b);
    let next = match session.get(i + 1).filter(|n| n.doublet == b.doublet + 1) {
        Some(next) => (next.inputs, of(next)),
        None => (
            b.inputs,
            DoubletView {
                start: view.end.unwrap_or(view.start),
                ..view
            },
        ),
    };
    (view, next)
}

/// The report of a block sized from `estimate` at ε_est = `epsilon`: its published
/// `[separation, largest]`, the lag measured (three-step doublets), whether the slip
/// measured sized it.
fn sized_report(
    estimate: &MotionNoiseEstimate,
    epsilon: f64,
    [separation, largest]: [f64; 2],
    lag: Option<[f64; 3]>,
    slip_sized: bool,
) -> BlockEstimate {
    let [point, lower] = estimate.stds();
    let mm = |s: [f64; 3]| s.map(|x| 1e3 * x);
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
        lag,
        unmodelled_lag: None,
        slip: estimate.slip.map(|slip| slip.stds()),
        slip_sized,
        jitter: None,
        slip_slices: None,
    }
}

/// A block whose estimate measured per-wheel slip (its `points` of the slip's interval,
/// `estimate.slip_corners`), sized with
/// each bit's view through the pair of Gaussians of its two values, each with its own
/// covariance (docs/estimation.md, "Per-wheel slip"): at each point of the slip's interval
/// the corner below the whole correlation interval (every cell's `Q_cell` and step weights
/// at once, [`whole_interval_corner`]), each bit's pairs ([`slip_pairs`]) at whichever of
/// the matrices below the region ([`below_the_region`]: shares of the corner, raised by
/// the region's upper bound) tells her least about the doublet, the bound of
/// `covariance_pair::paired_smooth_min_entropy` with `disclosed` bits removed; the least over
/// the points, published as the smallest Gaussian separation whose bound is no larger
/// (`slip_slices::equivalent_separation`). Every bit's entry is that separation. Three-step
/// doublets (the `lag` measured) are seen through their four instants and the next
/// doublet's entry, over the lag's interval ([`three_step_slip_pairs`]). A multilevel block
/// keeps each slice's bits' exponents at every point (evaluated once, for the block's bound:
/// [`ChernoffExponents::split`]), from which each slice is sized ([`BlockEstimate::for_slice`]).
fn size_slip_block(
    points: &[SlipCorners],
    config: &Config,
    sessions: &[&[DoubletSamples]],
    disclosed: u64,
    estimate: &MotionNoiseEstimate,
    lag: Option<&LagEstimate>,
    epsilon: f64,
) -> (Vec<Vec<f64>>, BlockEstimate) {
    let slip = estimate.slip.map(|s| s.stds());
    let named = |why: String| {
        let (separations, mut block) = refused(sessions.len(), why, estimate.doublets, epsilon);
        block.slip = slip;
        (separations, block)
    };
    let model = doublet_model(config);
    let axle = config.robot.axle_length;
    let bits: usize =
        sessions.iter().map(|s| s.len()).sum::<usize>() * model.perturbation.key_bits();
    // Multilevel symbols: each slice's bits (every session holds whole doublets, so a bit's
    // place in the block is its place in its session modulo the doublet's key bits).
    let slicing = (model.perturbation.bits_per_symbol() > 1)
        .then(|| {
            Slicing::new(
                model.perturbation.key_bits(),
                model.perturbation.bits_per_symbol(),
            )
            .ok()
        })
        .flatten();
    let parts = slicing.map_or(1, |s| usize::from(s.slices));
    let doublets = block_doublets(sessions);
    let mut slip_slices = SlipSlices::default();
    let mut least = f64::INFINITY;
    for (i, point) in points.iter().enumerate() {
        if i > 0 && points[i - 1] == *point {
            continue; // a known world's one point, repeated
        }
        let corner = whole_interval_corner(&point.corners);
        // Every member Q of the region lies above the corner and above 0, and below its
        // upper bound, hence above each of `below_the_region`'s matrices: each doublet is
        // sized at whichever of those views leaves her less (the corner's heading entry,
        // below 0 where the slip's uncertain share swamps a small Q along the heading, can
        // leave her covariance near singular or without a bound at the corner itself).
        let views: Vec<Corner> = below_the_region(&corner.motion, point.upper.as_ref())
            .into_iter()
            .map(|motion| Corner { motion, ..corner })
            .collect();
        // Each doublet's bits' pairs, the doublets on rayon's pool, kept in the block's order.
        let sized: Vec<Option<Vec<PairsOverLags>>> = doublets
            .par_iter()
            .map(|&(session, i)| {
                let b = &session[i];
                // Her view of the doublet: two steps' three instants, or (the lag measured)
                // three steps' four and the next doublet's entry.
                let view = stated_camera_view(
                    b.samples,
                    config.sensing.controller_std,
                    config.modelled_camera_std(),
                );
                let three_step =
                    lag.map(|lag| (lag.interval, three_step_views(config, session, i)));
                let pairs_at = |share: &Corner| match &three_step {
                    None => slip_pairs(&model, share, point.variance, axle, &b.inputs, &view)
                        .map(|bits| bits.into_iter().map(PairsOverLags::at_one_lag).collect()),
                    Some((interval, (view, (next_inputs, next_view)))) => three_step_slip_pairs(
                        &model,
                        share,
                        (point.variance, axle),
                        *interval,
                        &b.inputs,
                        view,
                        Some((next_inputs, next_view)),
                    ),
                };
                views
                    .iter()
                    .fold(None, |kept, share| blunter(kept, pairs_at(share)))
                    .map(|(_, pairs)| pairs)
            })
            .collect();
        let mut paired: Vec<PairsOverLags> = Vec::with_capacity(bits);
        for (&(session, i), pairs) in doublets.iter().zip(sized) {
            let b = &session[i];
            match pairs {
                Some(pairs) => paired.extend(pairs),
                None => {
                    return named(format!(
                        "per-wheel slip: at σ² = {:.3e} and the region's corner Eve's modelled \
                         covariance is not positive definite at doublet {} (allowed: a bound \
                         exists)",
                        point.variance, b.doublet
                    ));
                }
            }
        }
        let kept = (paired.len() as u64).saturating_sub(disclosed);
        let proxy = (paired
            .iter()
            .filter_map(PairsOverLags::first_pair)
            .map(|pair| {
                pair.coordinates()
                    .iter()
                    .map(|c| c.shift * c.shift)
                    .sum::<f64>()
            })
            .sum::<f64>()
            / paired.len().max(1) as f64)
            .sqrt();
        // Each bit's exponents at the block's λ, evaluated once and kept by slice; the
        // block's bound is their union's.
        let slices = match candidate_lambdas(kept.max(1), proxy, epsilon) {
            Ok(lambdas) => ChernoffExponents::split(&paired, &lambdas, parts, |i| {
                slicing.map_or(0, |s| s.slice_of(i))
            }),
            Err(why) => return named(format!("per-wheel slip: {why}")),
        };
        let bound = ChernoffExponents::joined(&slices)
            .unwrap_or_default()
            .smooth_min_entropy(disclosed, epsilon);
        match bound {
            Ok(bound) => least = least.min(bound.h_min),
            Err(why) => return named(format!("per-wheel slip: {why}")),
        }
        if slicing.is_some() {
            slip_slices.push(slices);
        }
    }
    let kept = (bits as u64).saturating_sub(disclosed);
    let separation = match paired_separation(kept, least, epsilon) {
        Ok(separation) => separation,
        Err(why) => return named(format!("per-wheel slip: {why}")),
    };
    let mut report = sized_report(
        estimate,
        epsilon,
        [separation; 2],
        lag.map(|lag| [lag.point, lag.interval[0], lag.interval[1]]),
        true,
    );
    report.slip_slices = slicing.map(|_| Arc::new(slip_slices));
    (
        sessions
            .iter()
            .map(|session| vec![separation; session.len() * model.perturbation.key_bits()])
            .collect(),
        report,
    )
}

/// Of the view of one doublet's bits `kept` so far (with its exponent) and an `other`, each
/// from a matrix below every `Q` of the region (so each bounds what she sees), the one that
/// tells her less, with its exponent: the larger sum over its bits of `−ln E[e^(−S/2)]` (the
/// Bhattacharyya exponent, each bit's [`SurprisalExponent`] at λ = ½), `kept` where they tie;
/// the one that exists where the other has no bound. Sizing each doublet at either keeps the
/// block's bound, since each bit's surprisal enters it on its own (docs/estimation.md,
/// "Per-wheel slip").
fn blunter<B: SurprisalExponent>(
    kept: Option<(f64, Vec<B>)>,
    other: Option<Vec<B>>,
) -> Option<(f64, Vec<B>)> {
    let other = other.map(|bits| {
        let exponent = bits.iter().map(|bit| bit.surprisal_exponent(0.5)).sum();
        (exponent, bits)
    });
    match (kept, other) {
        (Some(kept), Some(other)) => Some(if kept.0 >= other.0 { kept } else { other }),
        (kept, other) => kept.or(other),
    }
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
/// index, public inputs, the controller's three samples and, for a three-step doublet, its
/// sample after the second step and entry speed (`late`).
#[must_use]
pub fn kept_doublet(
    doublet: u32,
    inputs: &DoubletInputs,
    samples: &[Pose; 3],
    late: Option<&LateSample>,
) -> KeptDoublet {
    let unicycle = |u: Unicycle| [u.x, u.y];
    let pose = |p: &Pose| [p.x, p.y, p.z];
    KeptDoublet {
        doublet,
        inputs: [unicycle(inputs.first), unicycle(inputs.second)],
        samples: samples.each_ref().map(pose),
        late: late.map(|l| KeptLate {
            sample: pose(&l.sample),
            entry: unicycle(l.entry),
        }),
    }
}

/// One session's kept doublets with the robot's `bits` of it (`key_bits` per doublet, in
/// order: the v-symbol's label, then the ω-symbol's) as the estimate reads them.
///
/// # Errors
/// The numbers do not match, or a kept value is not finite (a store that kept the wrong
/// thing), naming the session and the values.
fn with_bits(
    id: u32,
    kept: &[KeptDoublet],
    bits: &BitString,
    key_bits: usize,
) -> Result<Vec<DoubletSamples>, String> {
    if kept.len() * key_bits != bits.len() {
        return Err(format!(
            "session {id:08x}: the pool kept {} doublets for its {} raw bits (allowed: one per \
             {key_bits} bits; sessions pooled without their samples cannot be measured)",
            kept.len(),
            bits.len()
        ));
    }
    kept.iter()
        .enumerate()
        .map(|(i, k)| {
            let late = k.late.iter().flat_map(|l| l.sample.iter().chain(&l.entry));
            let finite = k.inputs.iter().flatten().chain(k.samples.iter().flatten());
            if !finite.chain(late).all(|x| x.is_finite()) {
                return Err(format!(
                    "session {id:08x}: doublet {}'s kept samples are not finite",
                    k.doublet
                ));
            }
            let pattern = (0..key_bits).fold(0, |pattern, j| {
                pattern | usize::from(bits.get(i * key_bits + j) == Some(true)) << j
            });
            Ok(doublet_samples(k, pattern))
        })
        .collect()
}

/// A kept doublet as the estimate reads it, with the bit `pattern` it carried.
pub(crate) fn doublet_samples(k: &KeptDoublet, pattern: usize) -> DoubletSamples {
    DoubletSamples {
        doublet: k.doublet,
        inputs: DoubletInputs {
            first: Unicycle::new(k.inputs[0][0], k.inputs[0][1]),
            second: Unicycle::new(k.inputs[1][0], k.inputs[1][1]),
        },
        samples: k.samples.map(|p| Pose::new(p[0], p[1], p[2])),
        pattern,
        late: k.late.map(|l| LateSample {
            sample: Pose::new(l.sample[0], l.sample[1], l.sample[2]),
            entry: Unicycle::new(l.entry[0], l.entry[1]),
        }),
    }
}

/// A doublet as the controller saw it: its kept samples (a three-step doublet's late one and
/// entry speed too), each with the stated sensor noise `sensing.controller_std`.
pub(crate) fn own_view(config: &Config, d: &DoubletSamples) -> DoubletView {
    let own = |pose| PoseObservation::new(pose, config.sensing.controller_std);
    DoubletView {
        start: own(d.samples[0]),
        middle: Some(own(d.samples[1])),
        late: d.late.map(|l| own(l.sample)),
        end: Some(own(d.samples[2])),
        entry: d.late.map(|l| l.entry),
    }
}

/// The agents' controller's estimate of the plant for its endpoint's `request` (the kept
/// samples and the robot's bits of each session) under `config` at ε_est = `epsilon`: the
/// same computation as the simulator's [`block_separations`], then the commands check at
/// level ε_est ([`commands_check::block_refusal`]), whose refusal is added to the block's.
#[must_use]
pub fn estimate_request(config: &Config, request: &EstimateRequest, epsilon: f64) -> BlockEstimate {
    request_separations(config, request, epsilon).1
}

/// [`estimate_request`] with each session's bits' worst-case separations (as
/// [`block_separations`] gives them; none when the request does not match its samples):
/// what sizes each slice of a multilevel block ([`BlockEstimate::for_slice`]).
#[must_use]
pub fn request_separations(
    config: &Config,
    request: &EstimateRequest,
    epsilon: f64,
) -> (Vec<Vec<f64>>, BlockEstimate) {
    match request_sessions(config, request) {
        Ok(sessions) => {
            let views: Vec<&[DoubletSamples]> = sessions.iter().map(Vec::as_slice).collect();
            let (separations, mut estimate) =
                block_separations(config, &views, request.disclosed, epsilon);
            if let Some(why) =
                commands_check::sized_block_refusal(config, &views, epsilon, Some(&estimate))
            {
                estimate.refuse(why);
            }
            (separations, estimate)
        }
        Err(why) => (
            Vec::new(),
            BlockEstimate::refused(format!("motion-noise estimate: {why}"), 0, epsilon),
        ),
    }
}

/// The commands check alone for a configured block's `request` (the agents' controller
/// under `postprocess.sizing = "configured"`): the simulator's
/// [`commands_check::sized_block_refusal`] with no estimate, at level ε_est = `epsilon`, on
/// the kept samples and the robot's bits. `Ok(0)`: accepted (the block is sized from the
/// configured assumption); otherwise the refusal, naming the check.
///
/// # Errors
/// The check's refusal, or the kept samples not matching the robot's bits.
pub fn check_request(config: &Config, request: &EstimateRequest, epsilon: f64) -> EstimateOutcome {
    let sessions = request_sessions(config, request)
        .map_err(|why| EstimateRefusal(format!("commands check: {why}")))?;
    let views: Vec<&[DoubletSamples]> = sessions.iter().map(Vec::as_slice).collect();
    match commands_check::sized_block_refusal(config, &views, epsilon, None) {
        Some(why) => Err(EstimateRefusal(why)),
        None => Ok(0),
    }
}

/// Each session of `request` as the estimate and the check read it ([`with_bits`]).
fn request_sessions(
    config: &Config,
    request: &EstimateRequest,
) -> Result<Vec<Vec<DoubletSamples>>, String> {
    let key_bits = config.protocol.key_bits_per_doublet();
    request
        .sessions
        .iter()
        .map(|(id, kept, bits)| with_bits(*id, kept, bits, key_bits))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::lag::tests::doublets;
    use crate::estimate::{
        MAX_PUBLISHED_SEPARATION, estimate_motion_noise, estimate_motion_noise_split,
    };

    /// Of two views of a doublet the one that tells Eve less is kept: a pair further apart
    /// (a larger shift, or a variance further from the other value's) loses to a closer one
    /// whichever comes first, and a view without a bound gives way to one with it.
    #[test]
    fn the_blunter_view_of_a_doublet_is_kept() {
        use robokey_secrecy::covariance_pair::{Coordinate, CovariancePair, PairedBit};
        let bits = |shift: f64, variance: f64| {
            vec![vec![
                CovariancePair::new([Coordinate { shift, variance }]).unwrap(),
            ]]
        };
        // Two views folded in turn from none, as the sizing folds a doublet's.
        let kept = |a: Option<&Vec<PairedBit>>, b: Option<&Vec<PairedBit>>| {
            let first = blunter(None, a.cloned());
            blunter(first, b.cloned()).map(|(_, bits)| bits)
        };
        let (sharp, blunt) = (bits(2.0, 1.0), bits(1.0, 1.0));
        for (a, b) in [(&sharp, &blunt), (&blunt, &sharp)] {
            assert_eq!(kept(Some(a), Some(b)), Some(blunt.clone()));
        }
        let (spread, close) = (bits(1.0, 9.0), bits(1.0, 1.5));
        assert_eq!(kept(Some(&spread), Some(&close)), Some(close));
        assert_eq!(kept(None, Some(&sharp)), Some(sharp.clone()));
        assert_eq!(kept(Some(&sharp), None), Some(sharp));
        assert_eq!(kept(None, None), None);
    }

    /// Every share of the corner bounds what every member of the region shows Eve, and so
    /// does the doublet's blunter view over the shares. At a corner whose heading entry is
    /// below 0 as slip leaves it (5 % slip at 4 mm: `Q_c` ≈ diag(12, 12.5, −26)·10⁻⁶, σ² at
    /// its interval's upper end 2.85·10⁻³), on a turning doublet of two bits, white and over
    /// a correlation cell [0.3, 0.5]: 300 seeded members `Q ⪰ 0, Q ⪰ Q_c` — each minimal
    /// member `Q_c + xxᵀ` (`xᵀQ_c⁻¹x = −1`: along-track and lateral noise correlated with the
    /// heading's, up to ten times `Q_c`'s own, where every Loewner vertex above 0 fails),
    /// half of them with a random positive part added, ρ anywhere in the cell — give her on
    /// every bit no larger moment `E[e^(−λS)]` (λ = ¼, ½, 1; each bit's least exponent over
    /// its pairs) than each share's view does, to 10⁻⁹ of it; and some of them give her more
    /// than the corner's positive part (diag(12, 12.5, 0)·10⁻⁶, a member but no bound) does,
    /// so the members reach where a vertex above 0 would over-claim.
    #[test]
    fn every_share_of_the_corner_bounds_the_members_of_the_region() {
        use crate::estimate::motion_noise::tests::weights_of;
        use crate::estimate::worst_case::slip_pairs;
        use crate::estimate::worst_case::tests::{
            assert_blunter, exponents, member, turning_two_bit_doublet,
        };
        use crate::rng::{Purpose, stream};
        use nalgebra::{Matrix3, Vector3};
        use rand::RngExt;
        use robokey_secrecy::covariance_pair::PairedBit;
        let (config, model, inputs, view) = turning_two_bit_doublet();
        let (slip, axle) = (2.85e-3, config.robot.axle_length);
        let [a1, a2, c] = [12e-6, 12.5e-6, 26e-6];
        let corner_motion = Matrix3::from_diagonal(&Vector3::new(a1, a2, -c));
        let mut rng = stream(41, Purpose::Process, 0);
        for cell in [[0.0, 0.0], [0.3, 0.5]] {
            let corner = Corner {
                correlation: cell,
                motion: corner_motion,
                step_weights: weights_of(cell),
            };
            let shares: Vec<Vec<PairedBit>> = crate::estimate::worst_case::VERTEX_SHARES
                .iter()
                .filter_map(|&share| {
                    let view_at = Corner {
                        motion: corner_motion * share,
                        ..corner
                    };
                    slip_pairs(&model, &view_at, slip, axle, &inputs, &view)
                })
                .collect();
            assert!(
                shares.len() >= 2,
                "too few shares with a bound: {}",
                shares.len()
            );
            let kept = shares
                .iter()
                .cloned()
                .fold(None, |kept, bits| blunter(kept, Some(bits)))
                .unwrap()
                .1;
            // Not a bound: the corner's positive part, which the members below defeat.
            let positive = Corner {
                motion: Matrix3::from_diagonal(&Vector3::new(a1, a2, 0.0)),
                ..corner
            };
            let positive = slip_pairs(&model, &positive, slip, axle, &inputs, &view).unwrap();
            let mut defeated = 0;
            for trial in 0..150 {
                let scale = 10f64.powf(rng.random_range(-3.0..1.0));
                let [t1, t2]: [f64; 2] =
                    [a1, a2].map(|a| (scale * a).sqrt() * rng.random_range(-1.0..1.0));
                let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                let s = sign * (c * (1.0 + t1 * t1 / a1 + t2 * t2 / a2)).sqrt();
                let x = Vector3::new(t1, t2, s);
                let mut motion = corner_motion + x * x.transpose();
                if trial % 2 == 1 {
                    let y = Vector3::from_fn(|k, _| {
                        [a1, a2, c][k].sqrt() * rng.random_range(-0.5..0.5)
                    });
                    motion += y * y.transpose();
                }
                let min_eigenvalue = motion.symmetric_eigenvalues().min();
                assert!(
                    min_eigenvalue > -1e-12 * c,
                    "not a member: {min_eigenvalue}"
                );
                let rho = rng.random_range(cell[0]..=cell[1]);
                let seen =
                    slip_pairs(&model, &member(motion, rho), slip, axle, &inputs, &view).unwrap();
                for lambda in [0.25, 0.5, 1.0] {
                    let truth = exponents(&seen, lambda);
                    let above = exponents(&positive, lambda);
                    defeated += usize::from(above.iter().zip(&truth).any(|(p, t)| p > t));
                    for bound in shares.iter().chain([&kept]) {
                        let case = format!("cell {cell:?} trial {trial}");
                        assert_blunter(bound, &truth, lambda, &case);
                    }
                }
            }
            assert!(
                defeated > 0,
                "cell {cell:?}: no member below the positive part's view"
            );
        }
    }

    /// A two-step block whose first steps show a 50 ms lag is refused by name (before the
    /// motion-noise estimate, which models none), its estimate carrying the lag it names;
    /// one without lag is not refused for it.
    #[test]
    fn a_two_step_block_that_shows_a_lag_is_refused_naming_it() {
        let config = Config::from_toml("[sensing]\nmode = \"private\"\n", "t").unwrap();
        let estimate = |tau: f64| {
            let block = doublets(2000, tau, 7);
            block_separations(&config, &[&block], 0, 1e-6).1
        };
        let refusal = |tau: f64| estimate(tau).refused;
        let refused = estimate(0.05);
        let lagging = refused.refused.clone().expect("refused");
        assert!(lagging.starts_with("actuator lag"), "{lagging}");
        // It names the prior to state, a value the configuration accepts.
        let (_, prior) = lagging
            .split_once("--set private.prior_lag=")
            .expect("names the prior");
        let prior = prior.split('`').next().unwrap();
        let shaped = Config::from_toml(
            &format!("[sensing]\nmode = \"private\"\n[private]\nprior_lag = {prior}\n"),
            "t",
        )
        .unwrap();
        assert!(
            shaped.doublet_settle().is_some(),
            "three-step doublets: {prior}"
        );
        let [tau, low, high] = *refused.unmodelled_lag.expect("the lag it names");
        assert_eq!(format!("{tau:.4}"), prior);
        assert!(low < tau && tau < high && low > 0.0, "{low} {tau} {high}");
        assert_eq!(refused.lag, None, "no three-step lag");
        let still = refusal(0.0).unwrap_or_default();
        assert!(!still.contains("actuator lag"), "{still}");
    }

    /// 16 simulated sessions of a robot with 1 mm of white motion noise per axis and a lag
    /// `tau` (s), the parties' doublets shaped for `prior` (s).
    fn lagging_block(tau: f64, prior: f64) -> (Config, Vec<Vec<DoubletSamples>>) {
        delayed_block(0.0, tau, prior)
    }

    /// [`lagging_block`] with a dead time `delay` (s) before the lag.
    fn delayed_block(delay: f64, tau: f64, prior: f64) -> (Config, Vec<Vec<DoubletSamples>>) {
        simulated_block(&format!(
            "[sensing]\nmode = \"private\"\n[private]\nprior_lag = {prior}\n[world]\n\
             process_std = [0.001, 0.001, 0.001]\nlag = {tau}\ndelay = {delay}\n"
        ))
    }

    /// The controller's samples of 16 simulated sessions of the configuration `toml`.
    fn simulated_block(toml: &str) -> (Config, Vec<Vec<DoubletSamples>>) {
        simulated_sessions(toml, 0..16)
    }

    /// The controller's samples of the simulated sessions `replicates` of the configuration
    /// `toml`.
    fn simulated_sessions(
        toml: &str,
        replicates: std::ops::Range<u32>,
    ) -> (Config, Vec<Vec<DoubletSamples>>) {
        let config = Config::from_toml(toml, "t").unwrap();
        let sessions = replicates
            .map(|r| {
                crate::sim::simulate(&config, r, false)
                    .unwrap()
                    .private
                    .unwrap()
                    .controller_samples
            })
            .collect();
        (config, sessions)
    }

    /// Q̂'s diagonal (m², m², rad²) from the three-step residuals through `lag` (s) (with
    /// `split`, the one-step ones), and the residuals' count and mean square per axis.
    fn q_hat(
        config: &Config,
        sessions: &[&[DoubletSamples]],
        lag: f64,
        split: bool,
    ) -> (Result<[f64; 3], String>, usize, [f64; 3]) {
        let model = DoubletModel {
            lag,
            ..doublet_model(config)
        };
        let axle = config.robot.axle_length;
        let residuals = if split {
            split_residuals(&model, axle, sessions)
        } else {
            three_step_residuals(&model, axle, sessions)
        };
        let n = residuals.len();
        let square =
            [0, 1, 2].map(|k| residuals.iter().map(|r| r.value[k].powi(2)).sum::<f64>() / n as f64);
        let sensor = diagonal_covariance(config.sensing.controller_std);
        let estimate = estimate_motion_noise(&residuals, &sensor, 1e-3)
            .map(|e| [0, 1, 2].map(|k| e.point[(k, k)]))
            .map_err(|e| e.to_string());
        (estimate, n, square)
    }

    /// With the lagged means through τ̂ subtracted, Q̂ is the world's 1 mm² (1 mrad²) per
    /// axis at 20, 50 and 100 ms, within 4 of its relative standard errors
    /// `√(2F/n)·(3Q + 2R)/(3Q)` (F = 1.5 for the neighbours' shared sample), and the
    /// three-step block is sized, not refused. Without (the nominal inputs and the bit taken
    /// to act at once) the residuals hold the nominal turn's transient: their mean square in
    /// heading grows (by more than the tolerance: 1.4×, 3.8×, 14× at 20, 50, 100 ms) and the
    /// estimate is refused (the speed classes differ, or the innovations are not white) or
    /// Q̂ inflated.
    #[test]
    fn three_step_q_is_unbiased_with_the_lag_subtracted() {
        for tau in [0.02, 0.05, 0.1] {
            let (config, sessions) = lagging_block(tau, tau);
            let views: Vec<&[DoubletSamples]> = sessions.iter().map(Vec::as_slice).collect();
            let lag = measured_lag(&config, &views, 1e-3).unwrap();
            let (with, n, square_with) = q_hat(&config, &views, lag.point, false);
            let (without, _, square_without) = q_hat(&config, &views, 0.0, false);
            let tolerance = 4.0 * (3.0 / n as f64).sqrt() * (3.0 + 0.5) / 3.0;
            eprintln!(
                "τ {tau}: τ̂ {:.4} [{:.4}, {:.4}], {n} residuals, Q̂ with {with:?} without \
                 {without:?}; mean squares with {square_with:?} without {square_without:?}; \
                 tolerance {tolerance:.3}",
                lag.point, lag.interval[0], lag.interval[1]
            );
            let with = with.expect("in the class");
            for k in 0..3 {
                assert!(
                    (with[k] / 1e-6 - 1.0).abs() < tolerance,
                    "τ {tau} axis {k}: {with:?}"
                );
            }
            assert!(
                square_without[2] / square_with[2] - 1.0 > tolerance,
                "τ {tau}"
            );
            match without {
                Ok(q) => assert!(q[2] / 1e-6 - 1.0 > tolerance, "τ {tau}: {q:?}"),
                // Refused by a class test (homogeneity or whiteness), naming it.
                Err(why) => assert!(why.starts_with("motion-noise estimate"), "{why}"),
            }
            let (_, estimate) = block_separations(&config, &views, 0, 1e-6);
            assert_eq!(estimate.refused, None, "τ {tau}");
            assert!(
                estimate.separation > 0.0 && estimate.separation < 10.0,
                "{estimate:?}"
            );
            assert!(estimate.lag.is_some());
        }
    }

    /// The one-step residuals ([`split_residuals`]) through τ̂ give the world's 1 mm²
    /// (1 mrad²) per axis at 20, 50 and 100 ms too, within 4 of their relative standard
    /// errors `√(2F/n)·(Q + 2R)/Q` (n one-step residuals, three per doublet; F = 1.5 bounds
    /// the neighbours' shared sample's inflation), and from three times as many residuals.
    #[test]
    fn one_step_q_is_unbiased_with_the_lag_subtracted() {
        for tau in [0.02, 0.05, 0.1] {
            let (config, sessions) = lagging_block(tau, tau);
            let views: Vec<&[DoubletSamples]> = sessions.iter().map(Vec::as_slice).collect();
            let lag = measured_lag(&config, &views, 1e-3).unwrap();
            let (whole, doublets, _) = q_hat(&config, &views, lag.point, false);
            let (split, n, _) = q_hat(&config, &views, lag.point, true);
            assert_eq!(n, 3 * doublets, "τ {tau}");
            let tolerance = 4.0 * (3.0 / n as f64).sqrt() * (1.0 + 0.5);
            eprintln!("τ {tau}: {n} one-step residuals, Q̂ {split:?} (whole doublets {whole:?})");
            let split = split.expect("in the class");
            for k in 0..3 {
                assert!(
                    (split[k] / 1e-6 - 1.0).abs() < tolerance,
                    "τ {tau} axis {k}: {split:?}"
                );
            }
        }
    }

    /// σ² from three-step doublets' one-step residuals (the lag subtracted through τ̂, each
    /// step's slip map at its mean wheel travel through τ̂): over 10 seeded blocks of 16
    /// simulated sessions each (≈ 4,900 doublets; a 50 ms lag, the parties' prior, 5 %
    /// per-wheel slip and 1 mm of white motion noise) the interval at ε = 0.1 misses the
    /// world's σ² = 2.5·10⁻³ in at most 4 (Binomial(10, 0.1): 5 or more with probability
    /// 0.0016), and the blocks' mean σ̂² lies within 4 of its standard errors (their spread
    /// over √10) of it. The first block is sized with the slip over the lag measured (not
    /// refused), its interval at ε_est = 10⁻⁶ holding the world's slip and lag.
    #[test]
    fn slip_is_measured_from_three_step_doublets_at_its_level() {
        use crate::estimate::slip::estimate_slip;
        let (world, blocks) = (2.5e-3, 10);
        let toml = "[sensing]\nmode = \"private\"\n[private]\nprior_lag = 0.05\n[world]\n\
                    process_std = [0.001, 0.001, 0.001]\nlag = 0.05\nslip_std = 0.05\n";
        let mut points = Vec::with_capacity(blocks);
        let mut misses = 0;
        for block in 0..blocks as u32 {
            let (config, sessions) = simulated_sessions(toml, 16 * block..16 * (block + 1));
            let views: Vec<&[DoubletSamples]> = sessions.iter().map(Vec::as_slice).collect();
            let lag = measured_lag(&config, &views, 1e-3).unwrap();
            let model = DoubletModel {
                lag: lag.point,
                ..doublet_model(&config)
            };
            let residuals = split_residuals(&model, config.robot.axle_length, &views);
            let sensor = diagonal_covariance(config.sensing.controller_std);
            let fit = estimate_slip(&residuals, &sensor, 0.0, 0.1).expect("identified");
            let [low, high] = fit.interval;
            eprintln!(
                "block {block}: τ̂ {:.4}, {} residuals, σ̂² {:.4e} [{low:.4e}, {high:.4e}]",
                lag.point,
                residuals.len(),
                fit.point
            );
            misses += usize::from(!(low <= world && world <= high));
            points.push(fit.point);
            if block == 0 {
                let (_, estimate) = block_separations(&config, &views, 0, 1e-6);
                assert_eq!(estimate.refused, None, "{estimate:?}");
                assert!(estimate.slip_sized, "{estimate:?}");
                let [_, low, high] = estimate.slip.expect("the slip measured");
                assert!(low <= 0.05 && 0.05 <= high, "{estimate:?}");
                let [_, low, high] = estimate.lag.expect("three-step doublets");
                assert!(low <= 0.05 && 0.05 <= high, "{estimate:?}");
            }
        }
        let n = blocks as f64;
        let mean = points.iter().sum::<f64>() / n;
        let spread = (points.iter().map(|p| (p - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        assert!(misses <= 4, "{misses} of {blocks} intervals miss σ² at 0.1");
        assert!(
            (mean - world).abs() < 4.0 * spread / n.sqrt(),
            "mean σ̂² {mean:.4e}, spread {spread:.4e}"
        );
    }

    /// 16 simulated sessions of a robot with 1 mm of white motion noise, a `lag` and a dead
    /// time `delay` (s), the doublets shaped for `prior` (s): the block's lag and dead-time
    /// test at ε_est = 10⁻⁶.
    fn shape_test(delay: f64, lag: f64, prior: f64) -> Option<String> {
        let (config, sessions) = delayed_block(delay, lag, prior);
        let views: Vec<&[DoubletSamples]> = sessions.iter().map(Vec::as_slice).collect();
        let measured = measured_lag(&config, &views, 1e-6 * LAG_EPSILON_SHARE).unwrap();
        lag_shape_refusal(&config, &views, &measured, 1e-6)
    }

    /// The dead-time test over ≈ 4,900 doublets: a 20 ms dead time reads as a 20 ms lag at
    /// the sample instants (`e^(−T/D)` ≈ 5·10⁻⁵) and passes, as does a lag alone; a 100 ms
    /// dead time (z ≈ 18: the ends regress on the bit by −0.52 mm, standard error 0.028) and
    /// 40 ms of dead time behind a 50 ms lag (z ≈ 9.7) are refused, naming the test.
    #[test]
    fn a_dead_time_no_lag_explains_is_refused_by_the_shape_test() {
        assert_eq!(shape_test(0.02, 0.0, 0.02), None);
        assert_eq!(shape_test(0.0, 0.05, 0.05), None);
        for (delay, lag) in [(0.1, 0.0), (0.04, 0.05)] {
            let why = shape_test(delay, lag, 0.05).expect("refused");
            assert!(why.starts_with("lag shape"), "{why}");
        }
    }

    /// The commands check of a wrong prior (50 ms shaped, 100 ms in the world): against the
    /// prior the boundary residual reveals more than the model predicts and the block is
    /// refused; against the lag measured (its interval, as the block's estimate sized Eve's
    /// view over it) the residual is predicted and the block passes.
    #[test]
    fn the_commands_check_predicts_the_prior_error_over_the_lag_measured() {
        let (config, sessions) = lagging_block(0.1, 0.05);
        let views: Vec<&[DoubletSamples]> = sessions.iter().map(Vec::as_slice).collect();
        let (_, estimate) = block_separations(&config, &views, 0, 1e-6);
        assert_eq!(estimate.refused, None);
        let against_prior = commands_check::block_refusal(&config, &views, 1e-6);
        assert!(against_prior.is_some(), "{against_prior:?}");
        let sized = commands_check::sized_block_refusal(&config, &views, 1e-6, Some(&estimate));
        assert_eq!(sized, None);
    }

    /// The commands check's prediction over the lag measured is its largest over the whole
    /// interval: at 40 lags spread over `[τ_lo, τ_hi]` (a 100 ms world, 50 ms prior) no
    /// regression's prediction exceeds it.
    #[test]
    fn the_commands_check_predicts_its_largest_over_the_whole_interval() {
        let (config, sessions) = lagging_block(0.1, 0.05);
        let views: Vec<&[DoubletSamples]> = sessions.iter().map(Vec::as_slice).collect();
        let (_, estimate) = block_separations(&config, &views, 0, 1e-6);
        let [_, low, high] = estimate.lag.expect("three-step");
        assert!(high > low, "{:?}", estimate.lag);
        let bound = commands_check::regressions_over_lags(&config, &views, [low, high]);
        assert!(!bound.is_empty());
        for i in 0..40 {
            let tau = low + (high - low) * f64::from(i) / 39.0;
            let model = DoubletModel {
                lag: tau,
                ..doublet_model(&config)
            };
            let bits: Vec<commands_check::BoundaryResidual> = views
                .iter()
                .flat_map(|session| session.iter())
                .flat_map(|samples| commands_check::doublet_residuals(&model, samples))
                .collect();
            for (at, largest) in commands_check::regressions(&bits).iter().zip(&bound) {
                assert!(
                    at.predicted.abs() <= largest.predicted + 1e-15,
                    "τ {tau}: {at:?} above {largest:?}"
                );
            }
        }
    }

    /// A wrong prior (50 ms shaped, 20 ms in the world): with τ̂ subtracted Q̂ is the world's;
    /// at the prior the residuals' mean square along the track and in heading is larger.
    #[test]
    fn a_wrong_prior_is_measured_through_the_lag() {
        let (config, sessions) = lagging_block(0.02, 0.05);
        let views: Vec<&[DoubletSamples]> = sessions.iter().map(Vec::as_slice).collect();
        let lag = measured_lag(&config, &views, 1e-3).unwrap();
        let (with, n, square_with) = q_hat(&config, &views, lag.point, false);
        let (prior, _, square_prior) = q_hat(&config, &views, 0.05, false);
        let tolerance = 4.0 * (3.0 / n as f64).sqrt() * (3.0 + 0.5) / 3.0;
        eprintln!(
            "wrong prior: τ̂ {:.4}; Q̂ with τ̂ {with:?}, at the prior {prior:?}; mean squares \
             {square_with:?} against {square_prior:?}",
            lag.point
        );
        let with = with.expect("in the class");
        for k in 0..3 {
            assert!((with[k] / 1e-6 - 1.0).abs() < tolerance, "{with:?}");
        }
        assert!(square_prior[2] > square_with[2], "{square_prior:?}");
    }

    /// The parties' configuration with three-step doublets shaped for a 50 ms prior lag.
    fn lagging_parties() -> Config {
        Config::from_toml(
            "[sensing]\nmode = \"private\"\n[private]\nprior_lag = 0.05\n",
            "t",
        )
        .unwrap()
    }

    /// One session of `n` three-step doublets of `config`'s shape on a robot whose wheels
    /// follow their commands through a lag `lag` (s), over [`varied_inputs`] (speeds
    /// 0.01–0.16 m/s, turns ±0.4 rad/s, changing between doublets), each step moved by its
    /// mean speed through the lag (the Euler world's map) plus `motion` (m, m, rad) of white
    /// noise per axis in the robot's frame, each sample by the sensor's stated noise and by a
    /// timing error of std `jitter` (s) along the pose's rate over the step before it (that
    /// step's mean speed at the sample's heading, as the Euler world's plant moves one);
    /// random bits, every doublet keeping its sample after the second step.
    fn jittered_lagging_session(
        config: &Config,
        n: u32,
        lag: f64,
        motion: f64,
        jitter: f64,
        seed: u64,
    ) -> Vec<DoubletSamples> {
        use crate::estimate::homogeneity::tests::varied_inputs;
        use crate::estimate::residual::rotation;
        use crate::model::unicycle_step;
        use crate::rng::{Purpose, stream};
        use rand_distr::{Distribution, StandardNormal};
        let model = doublet_model(config);
        let t = model.sample_time;
        let sensor = config.sensing.controller_std;
        let mut rng = stream(seed, Purpose::Process, 0);
        let mut normal =
            || <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut rng);
        let mut x = Pose::new(0.0, 0.0, 0.3);
        let mut speed = varied_inputs(0).first;
        let mut rate = Vector3::new(speed.x * x.z.cos(), speed.x * x.z.sin(), speed.y);
        let sample = |x: &Pose, rate: &Vector3<f64>, normal: &mut dyn FnMut() -> f64| {
            x + Pose::from_fn(|k, _| sensor[k] * normal()) + rate * (jitter * normal())
        };
        let mut start = sample(&x, &rate, &mut normal);
        (0..n)
            .map(|j| {
                let inputs = varied_inputs(j);
                let pattern = (0..model.perturbation.key_bits())
                    .fold(0, |p, i| p | usize::from(normal() > 0.0) << i);
                let commands = inputs.applied_steps(model.step_offsets(&inputs, Some(pattern)));
                let mut samples = [start; 4];
                for (k, command) in commands.into_iter().enumerate() {
                    let (mean, end) = lagged(command, speed, t, lag);
                    speed = end;
                    let noise = Pose::from_fn(|_, _| motion * normal());
                    x = unicycle_step(&x, &mean, t) + rotation(x.z) * noise;
                    rate = Vector3::new(mean.x * x.z.cos(), mean.x * x.z.sin(), mean.y);
                    samples[k + 1] = sample(&x, &rate, &mut normal);
                }
                start = samples[3];
                DoubletSamples {
                    doublet: j,
                    inputs,
                    samples: [samples[0], samples[1], samples[3]],
                    pattern,
                    late: Some(LateSample {
                        sample: samples[2],
                        entry: Unicycle::zeros(),
                    }),
                }
            })
            .collect()
    }

    /// Three-step blocks measure the sample-timing jitter from their one-step residuals
    /// with the lagged means through τ̂ subtracted (τ̂ from the first steps alone, the
    /// coarser estimate), and j²'s interval covers at its level: over 100 seeded blocks of
    /// 1,000 doublets (3,000 one-step residuals) of a 50 ms robot at 1 mm (mrad) of white
    /// motion noise, at ε = 0.05, the interval misses j² in at most 11 blocks with no jitter
    /// and with 5 ms (5 expected were it exact; 11 is 3 binomial standard deviations
    /// `√(100·0.05·0.95)` above).
    #[test]
    fn the_jitter_interval_covers_in_three_step_blocks() {
        let config = lagging_parties();
        let sensor = diagonal_covariance(config.sensing.controller_std);
        let (blocks, level, allowed) = (100_u64, 0.05, 11);
        for (name, jitter) in [("none", 0.0), ("5 ms", 5e-3)] {
            let mut misses = 0;
            let mut widths = 0.0;
            for block in 0..blocks {
                let session = jittered_lagging_session(&config, 1_000, 0.05, 1e-3, jitter, block);
                let views = [session.as_slice()];
                let tau = measured_lag(&config, &views, level).unwrap().point;
                let model = DoubletModel {
                    lag: tau,
                    ..doublet_model(&config)
                };
                let steps = split_residuals(&model, config.robot.axle_length, &views);
                let estimate = estimate_jitter(&steps, &sensor, level, JitterRows::Products)
                    .expect("identified");
                let [low, high] = estimate.interval;
                misses += usize::from(jitter * jitter < low || jitter * jitter > high);
                let [_, lo, hi] = estimate.stds();
                widths += hi - lo;
            }
            eprintln!(
                "jitter {name}: {misses} of {blocks} missed, [j_lo, j_hi] {:.2} ms wide on average",
                1e3 * widths / blocks as f64
            );
            assert!(
                misses <= allowed,
                "jitter {name}: {misses} of {blocks} missed"
            );
        }
    }

    /// A three-step block records the jitter it measured and is sized (5 ms at the parties'
    /// 4 mm and 50 ms, 1,500 doublets); a jitter whose interval reaches above a tenth of `robot.T`
    /// (30 ms on the default 0.2 s) is refused by name, the reason naming the test, ĵ, its
    /// interval and the bound, the record keeping the estimate.
    #[test]
    fn three_step_blocks_record_the_jitter_and_refuse_it_beyond_a_tenth_of_t() {
        let config = lagging_parties();
        let sized = jittered_lagging_session(&config, 1_500, 0.05, 4e-3, 5e-3, 11);
        let (_, block) = block_separations(&config, &[sized.as_slice()], 0, 1e-6);
        assert_eq!(block.refused, None, "{block:?}");
        let [point, low, high] = *block.jitter.expect("measured");
        assert!(
            low <= 5e-3 && 5e-3 <= high && point > 0.0,
            "{:?}",
            [point, low, high]
        );
        let beyond = jittered_lagging_session(&config, 1_500, 0.05, 1e-3, 0.03, 12);
        let (separations, block) = block_separations(&config, &[beyond.as_slice()], 0, 1e-6);
        let why = block.refused.expect("refused");
        assert!(
            why.starts_with("sample-timing jitter beyond the class: ĵ = ")
                && why.contains("(allowed: at most 20.0 ms, a tenth of robot.T)"),
            "{why}"
        );
        let [_, _, high] = *block.jitter.expect("recorded");
        assert!(high > 0.02, "{high}");
        assert_eq!(separations, vec![vec![REFUSED_SEPARATION]]);
    }

    /// 16 simulated sessions of a robot with 1 mm (1 mrad) of white motion noise per axis,
    /// the parties at their defaults with two dimensions of a `levels`-level alphabet.
    fn multilevel_block(levels: u8) -> (Config, Vec<Vec<DoubletSamples>>) {
        simulated_block(&format!(
            "[sensing]\nmode = \"private\"\n[protocol]\nbits_per_doublet = 2\n\
             levels = {levels}\n[world]\nprocess_std = [0.001, 0.001, 0.001]\n"
        ))
    }

    /// Multilevel symbols under measured slip (two dimensions of 4 levels, 10 % per-wheel slip
    /// on 1 mm of white motion noise, the first 200 doublets of a seeded session of two laps —
    /// the simulation is causal, so they are the default three laps' first 200, at two thirds
    /// of the simulating: the sizing's cost grows with the doublets. At 20 % the jitter's
    /// interval, whose standard error comes from few batches and takes Student's quantile,
    /// reaches above its class on 300 doublets (21.3 ms) and passes from 400, at twice this
    /// test's CPU), the block is sized with the slip,
    /// and each slice from its own bits' pairs, not refused. The slices' bits partition the
    /// block's (each slice's count the bits at its place of every label); the block's bound is
    /// the union's of its slices' exponents at every point of σ²'s grid, number for number
    /// (its published separation recomputed from them); the fine slice is sized below the
    /// coarse one. What is outside holds the slices refused by name: an estimate without the
    /// slices' exponents (one read back from a report), a slice of another size, a refused
    /// block.
    #[test]
    fn multilevel_slices_under_slip_are_sized_from_their_own_bits() {
        let (config, sessions) = simulated_sessions(
            "[sensing]\nmode = \"private\"\n[protocol]\nbits_per_doublet = 2\nlevels = 4\n\
             [world]\nprocess_std = [0.001, 0.001, 0.001]\nslip_std = 0.1\n\
             [trajectory]\nlaps = 2\n",
            0..1,
        );
        let views: Vec<&[DoubletSamples]> = sessions.iter().map(|s| &s[..200]).collect();
        let model = doublet_model(&config);
        let slicing = Slicing::new(
            model.perturbation.key_bits(),
            model.perturbation.bits_per_symbol(),
        )
        .unwrap();
        let bits: usize = views.iter().map(|s| s.len()).sum::<usize>() * 4;
        let disclosed = (bits / 10) as u64;
        let (separations, block) = block_separations(&config, &views, disclosed, 1e-6);
        assert_eq!(block.refused, None, "{block:?}");
        assert!(block.slip_sized, "{block:?}");
        let kept = block.slip_slices.as_deref().expect("the slices' exponents");
        // The partition: every bit in one slice, each slice its place's bits.
        let picked: Vec<Vec<Vec<f64>>> = (0..2)
            .map(|slice| separations.iter().map(|s| slicing.pick(s, slice)).collect())
            .collect();
        assert_eq!(kept.slices(), 2);
        for (slice, own) in picked.iter().enumerate() {
            let count: usize = own.iter().map(Vec::len).sum();
            assert_eq!(kept.bits(slice), count);
            assert_eq!(count, bits / 2);
        }
        // The block's bound from its slices' exponents joined, at each point.
        let least = kept
            .points()
            .iter()
            .map(|slices| {
                let joined = ChernoffExponents::joined(slices).unwrap();
                assert_eq!(joined.bits(), bits);
                joined.smooth_min_entropy(disclosed, 1e-6).unwrap().h_min
            })
            .fold(f64::INFINITY, f64::min);
        let union = paired_separation(bits as u64 - disclosed, least, 1e-6).unwrap();
        assert_eq!(union, block.separation);
        // Each slice sized, from its own bits.
        let own: Vec<BlockEstimate> = picked
            .iter()
            .enumerate()
            .map(|(slice, own)| block.for_slice(slice, own, disclosed / 2))
            .collect();
        eprintln!(
            "slip {:?}: block {} (H_min^ε at least {least:.1} of {bits} bits), slices {} and {}",
            block.slip, block.separation, own[0].separation, own[1].separation
        );
        for slice in &own {
            assert_eq!(slice.refused, None, "{slice:?}");
            assert!(slice.slip_sized && slice.slip_slices.is_none());
            assert!(slice.separation > 0.0 && slice.separation < MAX_PUBLISHED_SEPARATION);
            assert_eq!(slice.largest, slice.separation);
            assert_eq!(
                slice.outcome().unwrap() as f64 * SEPARATION_QUANTUM,
                slice.separation
            );
        }
        assert!(own[0].separation < own[1].separation, "{own:?}");
        // Outside what was sized: refused, naming it.
        let read: BlockEstimate = toml::from_str(&toml::to_string(&block).unwrap()).unwrap();
        let why = read.for_slice(0, &picked[0], 0).refused.unwrap();
        assert!(why.contains("kept no slice's exponents"), "{why}");
        let fewer = [picked[0][0][..1].to_vec()];
        let why = block.for_slice(1, &fewer, 0).refused.unwrap();
        assert!(
            why.starts_with("per-wheel slip: slice 1: slice 1 holds"),
            "{why}"
        );
        let why = block.for_slice(2, &[], 0).refused.unwrap();
        assert!(why.contains("slice 2 of 2"), "{why}");
        let mut refused = block.clone();
        refused.refuse("a test's reason".to_owned());
        let slice = refused.for_slice(0, &picked[0], 0);
        assert_eq!(slice.refused.as_deref(), Some("a test's reason"));
        assert!(slice.outcome().is_err());
    }

    /// The sizing is the same number for number on one thread and on two (each doublet's
    /// worst case and each bit's moments are computed on rayon's pool and placed in the
    /// block's order): seeded sessions of two laps on 1 mm of white motion noise — one under
    /// 10 % per-wheel slip (319 doublets, sized by the slip's pairs and moments), one without
    /// (322, by the worst case over the corners), three under a 50 ms lag stated as the prior
    /// (597 three-step doublets, over the lag's interval) — each sized in a pool of one thread
    /// and in one of two: the same separations (bit patterns) and the same report.
    #[test]
    fn a_block_is_sized_alike_on_one_thread_and_on_two() {
        let white = "[world]\nprocess_std = [0.001, 0.001, 0.001]\n";
        for (slip, toml, sessions) in [
            (true, format!("{white}slip_std = 0.1\n"), 1),
            (false, white.to_owned(), 1),
            (
                false,
                format!("[private]\nprior_lag = 0.05\n{white}lag = 0.05\n"),
                3,
            ),
        ] {
            let (config, sessions) = simulated_sessions(
                &format!("[sensing]\nmode = \"private\"\n[trajectory]\nlaps = 2\n{toml}"),
                0..sessions,
            );
            let views: Vec<&[DoubletSamples]> = sessions.iter().map(Vec::as_slice).collect();
            let on = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let (separations, block) =
                    pool.install(|| block_separations(&config, &views, 20, 1e-6));
                let bits: Vec<Vec<u64>> = separations
                    .iter()
                    .map(|s| s.iter().map(|x| x.to_bits()).collect())
                    .collect();
                (bits, format!("{block:?}"), block)
            };
            let (one, two) = (on(1), on(2));
            assert_eq!(one.2.refused, None, "{:?}", one.2);
            assert_eq!(one.2.slip_sized, slip, "{:?}", one.2);
            assert_eq!(one.0, two.0);
            assert_eq!(one.1, two.1);
        }
    }

    /// The lag's per-doublet work is the same number for number on one thread and on two
    /// (`with_entry_speed` maps the doublets on rayon's pool and collects them in the block's
    /// order): three seeded sessions of two laps under a 50 ms lag stated as the prior, 1 mm
    /// of white motion noise — the turns' slopes and weights, τ's statistic's products at
    /// three lags, the one-step residuals and the dead-time test, each computed in a pool of
    /// one thread and in one of two.
    #[test]
    fn the_lag_residuals_are_alike_on_one_thread_and_on_two() {
        let (config, sessions) = simulated_sessions(
            "[sensing]\nmode = \"private\"\n[trajectory]\nlaps = 2\n[private]\nprior_lag = 0.05\n\
             [world]\nprocess_std = [0.001, 0.001, 0.001]\nlag = 0.05\n",
            0..3,
        );
        let views: Vec<&[DoubletSamples]> = sessions.iter().map(Vec::as_slice).collect();
        let lag = measured_lag(&config, &views, 1e-6).expect("the first step's lag");
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let turns = heading_slopes(&config, &views);
                let first_turns = first_turn_weights(&config, &views);
                let products: Vec<Vec<Vec<u64>>> = [0.03, 0.05, 0.08]
                    .iter()
                    .map(|&tau| {
                        let (turns, first_turns) = (turns.as_deref(), first_turns.as_deref());
                        lag_residual_products(&config, &views, tau, true, turns, first_turns)
                            .iter()
                            .map(|u| u.iter().map(|x| x.to_bits()).collect())
                            .collect()
                    })
                    .collect();
                let model = doublet_model(&config);
                let steps = split_residuals(&model, config.robot.axle_length, &views);
                let shape = lag_shape_refusal(&config, &views, &lag, 1e-6);
                (
                    format!("{turns:?} {first_turns:?}"),
                    products,
                    format!("{steps:?}"),
                    shape,
                    steps.len(),
                )
            })
        };
        let (one, two) = (on(1), on(2));
        assert!(
            one.1.iter().all(|p| p.len() >= MIN_LAG_DOUBLETS),
            "{}",
            one.1[0].len()
        );
        assert!(
            one.4 >= 3 * MIN_LAG_DOUBLETS,
            "{} one-step residuals",
            one.4
        );
        assert!(one.0.starts_with("Some("), "the path turns: {}", one.0);
        assert_eq!(one, two);
    }

    /// Multilevel symbols: with each symbol's mean subtracted Q̂ (from the n one-step
    /// residuals) is the world's 1 mm² (1 mrad²) per axis at 4 and 8 levels, within 4 of its
    /// relative standard errors `√(2F/n)·(Q + 2R)/Q` (F = 1.5 for the neighbours' shared
    /// sample), and the block is
    /// sized, not refused, with a separation for every key bit; the slip fitted beside `Q`
    /// shows none (its interval reaches 0, its upper end below 2 % of the wheels' travel).
    #[test]
    fn multilevel_q_is_unbiased_with_the_symbols_mean_subtracted() {
        for levels in [4_u8, 8] {
            let (config, sessions) = multilevel_block(levels);
            let views: Vec<&[DoubletSamples]> = sessions.iter().map(Vec::as_slice).collect();
            let model = doublet_model(&config);
            let with = two_step_split_residuals(&model, config.robot.axle_length, &views);
            let sensor = diagonal_covariance(config.sensing.controller_std);
            let n = with.len();
            let q_hat = estimate_motion_noise_split(&with, &sensor, 1e-3).expect("in the class");
            for (k, std) in config.sensing.controller_std.into_iter().enumerate() {
                let tolerance = 4.0 * (3.0 / n as f64).sqrt() * (1e-6 + 2.0 * std * std) / 1e-6;
                let got = q_hat.point[(k, k)] / 1e-6;
                eprintln!("{levels} levels, axis {k}: Q̂/Q {got:.4} (tolerance {tolerance:.3})");
                assert!(
                    (got - 1.0).abs() < tolerance,
                    "{levels} levels axis {k}: {got}"
                );
            }
            let (separations, estimate) = block_separations(&config, &views, 0, 1e-6);
            assert_eq!(estimate.refused, None, "{levels} levels");
            let [_, low, high] = estimate.slip.expect("the slip fitted beside Q");
            assert!(
                low == 0.0 && high < 0.02,
                "{levels} levels: {:?}",
                estimate.slip
            );
            let key_bits = model.perturbation.key_bits();
            for (session, d) in views.iter().zip(&separations) {
                assert_eq!(d.len(), session.len() * key_bits);
                assert!(d.iter().all(|&d| d > 0.0 && d < MAX_PUBLISHED_SEPARATION));
            }
        }
    }
}
