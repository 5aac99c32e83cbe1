//! Estimating the plant from the controller's own samples (docs/estimation.md): after
//! reconciliation, with the reconciled bits, the controller measures the motion noise its
//! key rests on, bounds it over a (1 − ε_est) confidence region, and sizes Eve's modelled
//! view — hence ℓ — from the region's worst case. Pure: no clocks, files or randomness.
//!
//! The model class covered here is Gaussian motion noise with a constant 3×3 stationary
//! covariance `Q` in the robot's frame and AR(1) correlation `ρ ∈ [−½, 1)` between steps
//! (white at ρ = 0), and a controller sensor of stated covariance `R` (its calibration);
//! with three-step doublets (`private.prior_lag`) a first-order actuator lag τ as well,
//! measured first (`lag`) and subtracted before `Q` and ρ (`block`). Per-wheel slip is
//! measured jointly with `Q` (`slip`), and where the block shows it Eve's view of each bit is
//! a pair of Gaussians whose covariances depend on the bit (`worst_case::slip_pairs`), sized
//! at points of the slip's interval (`motion_noise`, `block`). Two-step blocks measure the
//! controller's sample-timing jitter first (`jitter`): each sample's noise `R + j²·uuᵀ`, its
//! rate `u` public, with j²'s interval's upper end under `Q` and its lower end in Eve's view.

pub mod block;
pub mod block_llrs;
mod chi_square;
pub mod commands_check;
pub mod correlation;
mod half_away;
pub mod homogeneity;
pub mod jitter;
pub mod lag;
mod lag_cell;
pub mod motion_noise;
mod normal_tail;
pub mod pairs_over_lags;
mod pattern_fit;
pub mod prior;
pub mod quantum_check;
pub mod residual;
pub mod slice_llrs;
pub mod slip;
pub mod slip_slices;
mod symmetric_coordinates;
mod weighted_chi_square;
mod wishart;
pub mod worst_case;

pub use block::{
    BlockEstimate, block_separations, check_request, estimate_request, kept_doublet,
    request_separations, world_block_separations,
};
pub use block_llrs::{doublet_llrs, llr_answer, recomputed_llrs, recomputes_llrs};
pub use correlation::Correlation;
pub use homogeneity::{ClassDeparture, speed_class_departure};
pub use jitter::{JitterEstimate, JitterRows, estimate_jitter};
pub use lag::{LagEstimate, estimate_lag};
pub use motion_noise::{
    Corner, EstimationRefusal, JitterVariances, MotionNoiseEstimate, diagonal_covariance,
    estimate_motion_noise, estimate_motion_noise_split, estimate_motion_noise_timed,
};
pub use residual::DoubletResidual;
pub use slice_llrs::{SliceSession, recomputed_slice_llrs};
pub use slip::{SlipEstimate, estimate_slip};
pub use worst_case::{
    ESTIMATE_LEAK_BITS, MAX_PUBLISHED_SEPARATION, SEPARATION_QUANTUM, published_separation,
    worst_case_separations,
};
