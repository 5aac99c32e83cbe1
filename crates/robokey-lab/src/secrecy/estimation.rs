//! Keys sized from measured motion noise in the simulator (docs/estimation.md): per block,
//! the controller's estimate from its own samples of the block's sessions and the
//! reconciled bits, and each session's bits' Eve separations at the region's worst case —
//! what the post-processing endpoints then size ℓ from, per bit (docs/secrecy.md).
//!
//! The reconciled bits are the robot's: a block whose reconciliation or confirmation fails
//! gives no key, so wherever ℓ matters the controller's corrected bits equal the robot's.

use robokey::Config;
use robokey::estimate::{
    DoubletResidual, MotionNoiseEstimate, diagonal_covariance, estimate_motion_noise,
    published_separation, worst_case_separations,
};
use robokey::private::likelihood::stated_camera_view;
use robokey::private::{DoubletSamples, doublet_model};
use robokey::sim::RunOutput;
use robokey::world::WorldModel;
use robokey_secrecy::postprocess::Assumption;
use serde::{Deserialize, Serialize};

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
    /// The largest separation of Eve's view over the block's bits at the worst case, rounded
    /// up to the published grid (2⁻⁸).
    pub separation: f64,
    /// Why the block was refused, naming the test and the value.
    pub refused: Option<String>,
}

/// The controller's samples of every carrying doublet of `run`.
fn controller_samples(run: &RunOutput) -> &[DoubletSamples] {
    run.private
        .as_ref()
        .map_or(&[][..], |p| &p.controller_samples)
}

/// Each of `runs`' sessions' bits' worst-case separations (each rounded up to the published
/// grid: the estimate depends on the bits, and what is published of it — the block's
/// equivalent separation, on the same grid — is charged by the assumption), and the block's
/// estimate, for
/// the sessions of one block under the parties' `config` (their stated sensor calibration
/// and camera) at ε_est = `epsilon`.
#[must_use]
pub fn block_separations(
    config: &Config,
    runs: &[&RunOutput],
    epsilon: f64,
) -> (Vec<Vec<f64>>, BlockEstimate) {
    let model = doublet_model(config);
    let residuals: Vec<DoubletResidual> = runs
        .iter()
        .flat_map(|run| controller_samples(run))
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
    let sensor = diagonal_covariance(config.sensing.controller_std);
    if let Err(why) = two_step_doublets(config) {
        return refused(runs.len(), why, residuals.len(), epsilon);
    }
    match estimate_motion_noise(&residuals, &sensor, epsilon) {
        Ok(estimate) => size_block(config, runs, &estimate),
        Err(refusal) => refused(runs.len(), refusal.to_string(), residuals.len(), epsilon),
    }
}

/// The estimate and Eve's modelled view model the two-step doublet's residual: a block of
/// three-step doublets (`private.prior_lag` > 0) is refused, naming the setting.
fn two_step_doublets(config: &Config) -> Result<(), String> {
    match config.doublet_settle() {
        None => Ok(()),
        Some(a) => Err(format!(
            "motion-noise estimate: it models the two-step doublet's residual, the block's \
             doublets have three steps (private.prior_lag = {} s, a = {a:.4}; allowed: \
             private.prior_lag = 0 with --sizing measured or world)",
            config.private.prior_lag
        )),
    }
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
        BlockEstimate {
            doublets,
            point_std_mm: [f64::NAN; 3],
            lower_std_mm: [f64::NAN; 3],
            correlation: f64::NAN,
            correlation_interval: [f64::NAN; 2],
            epsilon,
            separation: REFUSED_SEPARATION,
            refused: Some(why),
        },
    )
}

/// As [`block_separations`], with the simulated world's own stationary motion noise and
/// AR(1) correlation in place of the estimate's region: what a pair configured with the
/// true world sizes (`--sizing world`, the comparison for measured sizing).
#[must_use]
pub fn world_block_separations(
    config: &Config,
    runs: &[&RunOutput],
    epsilon: f64,
) -> (Vec<Vec<f64>>, BlockEstimate) {
    if let Err(why) = two_step_doublets(config) {
        let doublets = runs.iter().flat_map(|run| controller_samples(run)).count();
        return refused(runs.len(), why, doublets, epsilon);
    }
    let world = WorldModel::of(config);
    let truth = MotionNoiseEstimate::known(
        diagonal_covariance(world.process_std),
        world.process_rho,
        epsilon,
    );
    size_block(config, runs, &truth)
}

/// The measured sizing's `assumption` restated for `--sizing world`: the motion noise and
/// correlation are the simulated world's, known, not measured.
#[must_use]
pub fn world_known(assumption: Assumption) -> Assumption {
    match assumption {
        Assumption::MeasuredViews {
            separation,
            statement,
            estimation_epsilon,
            estimate_leak,
        } => Assumption::MeasuredViews {
            separation,
            statement: statement.replacen(
                "motion noise measured by the controller per block",
                "motion noise and its correlation those of the simulated world, known to the \
                 parties (--sizing world: a pair configured with the true world)",
                1,
            ),
            estimation_epsilon,
            estimate_leak,
        },
        other => other,
    }
}

/// Each of `runs`' sessions' bits' separations of Eve's view at the worst case of
/// `estimate`'s region (each rounded up to the published grid), and the block's report.
fn size_block(
    config: &Config,
    runs: &[&RunOutput],
    estimate: &MotionNoiseEstimate,
) -> (Vec<Vec<f64>>, BlockEstimate) {
    let model = doublet_model(config);
    let epsilon = estimate.epsilon;
    let refuse = |why: String, doublets: usize| refused(runs.len(), why, doublets, epsilon);
    let bits = usize::from(config.protocol.bits_per_doublet);
    let mut separations = Vec::with_capacity(runs.len());
    for run in runs {
        let mut session = Vec::new();
        for b in controller_samples(run) {
            let view = stated_camera_view(
                b.samples,
                config.sensing.controller_std,
                config.eve.camera_std,
            );
            match worst_case_separations(&model, estimate, &b.inputs, &view) {
                Some(d) => session.extend(d[..bits].iter().map(|&x| published_separation(x))),
                None => {
                    return refuse(
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
                    );
                }
            }
        }
        separations.push(session);
    }
    let [point, lower] = estimate.stds();
    let mm = |s: [f64; 3]| s.map(|x| 1e3 * x);
    let separation = separations.iter().flatten().fold(0.0_f64, |m, &x| m.max(x));
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
            refused: None,
        },
    )
}
