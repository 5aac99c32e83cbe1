//! Secrecy math for robokey: how many secret bits a run of the robot's motion yields, and the
//! tools to extract them (see docs/secrecy.md).
//!
//! Threat model: Eve is passive — she records every frame, knows the protocol, the trajectory
//! and her configured model, but never injects or alters frames. Every figure here is a
//! bound against such an Eve, and names the assumption (i.i.d. errors, per-position
//! posteriors, a confidence level) it rests on.
//!
//! The crate performs no I/O: no files, sockets, clocks, threads or global RNG; randomness
//! comes in as `&mut impl rand::Rng` (or `CryptoRng` where it must be unpredictable).
//!
//! - [`entropy`]: h(p), a ⋆ b, plug-in informations from the joint (b, b̂c, b̂a) table, bootstrap.
//! - [`interval`]: Clopper–Pearson intervals and bounds, exact binomial test.
//! - [`advantage`]: repetition advantage distillation for i.i.d. errors.
//! - [`cascade`]: Cascade reconciliation; its leak charges both sides' parities.
//! - [`ldpc`]: one-way LDPC reconciliation, belief propagation on calibrated LLRs; its leak is
//!   the syndrome.
//! - [`calibration`]: does a posterior predict the errors it claims? (a posterior feeds
//!   H_min only if it passes).
//! - [`confirm`]: 64-bit HMAC-SHA256 key-confirmation tag.
//! - [`min_entropy`]: smooth min-entropy bounds and the output length ℓ.
//! - [`toeplitz`]: Toeplitz hashing over GF(2) for privacy amplification, by Karatsuba
//!   carry-less multiplication (O(n^1.58)).
//! - [`postprocess`]: the post-processing protocol's two endpoints (pool sync, Cascade,
//!   confirmation, amplification, two-phase commit), without I/O.
//! - [`wiretap_limit`]: the secrecy margin I(X;Y_c) − I(X;Y_e) of a PAM or Gaussian alphabet
//!   through two Gaussian views, the limit a rate map sets beside each point.
//! - [`bitstring`]: packed, zeroized bit strings; [`special`]: ln Γ and incomplete beta.

pub mod advantage;
pub mod bitstring;
pub mod calibration;
pub mod cascade;
pub mod confirm;
pub mod covariance_pair;
pub mod entropy;
pub mod gaussian_llr;
mod gf2_poly;
pub mod interval;
pub mod ldpc;
pub mod min_entropy;
pub mod postprocess;
pub mod special;
pub mod toeplitz;
pub mod view_profile;
pub mod wiretap_limit;

pub use advantage::{AdvantageError, RepetitionAdvantage};
pub use bitstring::{BitString, BitStringError};
pub use calibration::{CalibrationError, CalibrationReport, check_calibration};
pub use cascade::{
    Cascade, CascadeSchedule, KeyParities, ParityOracle, ReconcileError, Reconciler, Reconciliation,
};
pub use confirm::{ConfirmationContext, ConfirmationTag};
pub use entropy::{
    BootstrapIntervals, EntropyError, JointCounts, binary_convolution, binary_entropy,
};
pub use interval::{Interval, IntervalError, binomial_test, clopper_pearson};
pub use min_entropy::{
    BinomialMinEntropy, MinEntropyError, OutputLength, PosteriorMinEntropy,
    binomial_smooth_min_entropy, output_length, posterior_smooth_min_entropy,
};
pub use toeplitz::{ToeplitzError, ToeplitzHash};
