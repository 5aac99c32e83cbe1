//! Keys sized from measured motion noise in the simulator (docs/estimation.md): per block,
//! the controller's estimate from its own samples of the block's sessions and the
//! reconciled bits, and each session's bits' Eve separations at the region's worst case —
//! what the post-processing endpoints then size ℓ from, per bit (docs/secrecy.md).
//!
//! The reconciled bits are the robot's: a block whose reconciliation or confirmation fails
//! gives no key, so wherever ℓ matters the controller's corrected bits equal the robot's.

use robokey::Config;
use robokey::estimate::{
    DoubletResidual, diagonal_covariance, estimate_motion_noise, published_separation,
    worst_case_separations,
};
use robokey::private::likelihood::stated_camera_view;
use robokey::private::{DoubletSamples, doublet_model};
use robokey::sim::RunOutput;
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
    /// The region's worst-case vertex's √Q_low,kk (mm, mm, mrad): what sizes Eve's view.
    pub lower_std_mm: [f64; 3],
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
    let refuse = |why: String, doublets: usize| {
        (
            vec![vec![REFUSED_SEPARATION]; runs.len()],
            BlockEstimate {
                doublets,
                point_std_mm: [f64::NAN; 3],
                lower_std_mm: [f64::NAN; 3],
                epsilon,
                separation: REFUSED_SEPARATION,
                refused: Some(why),
            },
        )
    };
    if let Some(a) = config.doublet_settle() {
        return refuse(
            format!(
                "motion-noise estimate: it models the two-step doublet's residual, the block's \
                 doublets have three steps (private.prior_lag = {} s, a = {a:.4}; allowed: \
                 private.prior_lag = 0 with --sizing measured)",
                config.private.prior_lag
            ),
            residuals.len(),
        );
    }
    let estimate = match estimate_motion_noise(&residuals, &sensor, epsilon) {
        Ok(e) => e,
        Err(refusal) => return refuse(refusal.to_string(), residuals.len()),
    };
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
            match worst_case_separations(&model, &estimate.lower, &b.inputs, &view) {
                Some(d) => session.extend(d[..bits].iter().map(|&x| published_separation(x))),
                None => {
                    return refuse(
                        format!(
                            "motion-noise estimate: at the region's worst case (Q_low's \
                             diagonal {:?} m², m², rad²) Eve's modelled covariance is not \
                             positive definite at doublet {} (allowed: a bound exists)",
                            [0, 1, 2].map(|k| estimate.lower[(k, k)]),
                            b.doublet
                        ),
                        residuals.len(),
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
            epsilon,
            separation,
            refused: None,
        },
    )
}
