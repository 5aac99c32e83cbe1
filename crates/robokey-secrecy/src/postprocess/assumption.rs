//! What the operator states about Eve. The final key length follows from this statement and
//! from what was published — never from Eve's realised view, which no deployed party has.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::confirm::TAG_BITS;
use crate::gaussian_llr;
use crate::min_entropy::{OutputLength, binomial_smooth_min_entropy, output_length};
use crate::view_profile::gaussian_llr_smooth_min_entropy;

/// An adversary assumption.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Assumption {
    /// Eve can know everything the controller knows (the paper's odometry mode, where she
    /// learns the model from the traffic): her min-entropy is zero, and so is ℓ.
    NoSecrecy {
        /// Why, for reports.
        reason: String,
    },
    /// Eve's guesses of the pooled bits err independently, each with probability at least
    /// `error_rate` (a binary-symmetric view). Stated by the operator, not measured.
    IndependentErrors {
        /// Her least error probability, in (0, ½].
        error_rate: f64,
    },
    /// Under a stated physical model (private sensing: Eve's camera noise, the motion noise,
    /// the exact model), Eve's view of each pooled bit is at most as informative as a
    /// consistent Gaussian log-likelihood ratio of its own Mahalanobis separation,
    /// independently across bits (`gaussian_llr`); a block is sized with the equivalent
    /// separation of its bits' separations (`view_profile`).
    GaussianViews {
        /// The separation every bit is sized with at least (the block's equivalent is raised
        /// to it), ≥ 0.
        separation: f64,
        /// The physical model, for people: e.g. "Eve's camera noise ≥ 8 mm, 8 mrad".
        statement: String,
    },
    /// [`Self::GaussianViews`] with the plant measured rather than configured: the bits'
    /// separations are taken at the worst case of a (1 − ε_est) confidence region of the motion noise the controller estimated from its own samples
    /// (docs/estimation.md). The region's failure probability ε_est is a term of the key's ε.
    MeasuredViews {
        /// The separation every bit is sized with at least, ≥ 0.
        separation: f64,
        /// The camera statement and the measured plant, for people.
        statement: String,
        /// ε_est: the probability that the true motion noise lies outside the region.
        estimation_epsilon: f64,
        /// log₂ of the number of values the published outcome of the estimate can take
        /// (the quantised separation, or a refusal): the estimate depends on the bits, so
        /// what is carried of it is charged, `H_min(X | E, F) ≥ H_min(X | E) − log₂|F|`.
        estimate_leak: f64,
    },
}

/// What each bit's view is under [`Assumption::MeasuredViews`], as its text states it: the
/// block's estimate decides which (its `slip_sized`, in the controller's report and the lab's
/// block estimates), and the separation published bounds either (docs/estimation.md,
/// "Per-wheel slip").
const MEASURED_VIEWS: &str = "each a Gaussian likelihood ratio of its own separation or, in a \
    block whose estimate measured per-wheel slip and was sized with it, the likelihood ratio of \
    two Gaussians with covariances of their own (the slip's noise depends on the bit)";

/// An assumption out of range.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, Error)]
pub enum AssumptionError {
    /// An error rate outside (0, ½].
    #[error("assumed Eve error rate {0} is out of range (allowed: (0, 0.5])")]
    ErrorRate(f64),
    /// A separation that is negative or not finite.
    #[error("assumed separation {0} of Eve's view is out of range (allowed: ≥ 0, finite)")]
    Separation(f64),
    /// An ε_est outside (0, 1).
    #[error("ε_est {0} of the measured plant's region is out of range (allowed: (0, 1))")]
    EstimationEpsilon(f64),
    /// A charge for the published estimate that is negative or not finite.
    #[error(
        "the charge {0} bits for the published estimate is out of range (allowed: ≥ 0, finite)"
    )]
    EstimateLeak(f64),
}

impl Assumption {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`AssumptionError`] naming the value.
    pub fn check(&self) -> Result<(), AssumptionError> {
        match *self {
            Self::IndependentErrors { error_rate } if !(error_rate > 0.0 && error_rate <= 0.5) => {
                Err(AssumptionError::ErrorRate(error_rate))
            }
            Self::GaussianViews { separation, .. } | Self::MeasuredViews { separation, .. }
                if !(separation >= 0.0 && separation.is_finite()) =>
            {
                Err(AssumptionError::Separation(separation))
            }
            Self::MeasuredViews {
                estimation_epsilon, ..
            } if !(estimation_epsilon > 0.0 && estimation_epsilon < 1.0) => {
                Err(AssumptionError::EstimationEpsilon(estimation_epsilon))
            }
            Self::MeasuredViews { estimate_leak, .. }
                if !(estimate_leak >= 0.0 && estimate_leak.is_finite()) =>
            {
                Err(AssumptionError::EstimateLeak(estimate_leak))
            }
            _ => Ok(()),
        }
    }

    /// Whether the assumption is restricted: stated by the operator about an Eve who never
    /// learns the model, rather than derived from a physical statement. Keys made under it
    /// are labelled so, and the agents make them only when told to.
    #[must_use]
    pub fn is_restricted(&self) -> bool {
        matches!(self, Self::IndependentErrors { .. })
    }

    /// The assumption for one block whose bits' Eve separations have the equivalent
    /// separation `separation_micros` millionths (`view_profile::equivalent_separation`): a
    /// Gaussian-views separation is raised to it; the other assumptions have none.
    #[must_use]
    pub fn for_block(&self, separation_micros: u64) -> Self {
        match self {
            Self::GaussianViews {
                separation,
                statement,
            } => Self::GaussianViews {
                separation: separation.max(separation_micros as f64 * 1e-6),
                statement: statement.clone(),
            },
            Self::MeasuredViews {
                separation,
                statement,
                estimation_epsilon,
                estimate_leak,
            } => Self::MeasuredViews {
                separation: separation.max(separation_micros as f64 * 1e-6),
                statement: statement.clone(),
                estimation_epsilon: *estimation_epsilon,
                estimate_leak: *estimate_leak,
            },
            Self::NoSecrecy { .. } | Self::IndependentErrors { .. } => self.clone(),
        }
    }

    /// Whether the plant is measured: the block's separation is then the estimate's, carried
    /// in `Confirm` ([`Self::with_estimate`]).
    #[must_use]
    pub fn is_measured(&self) -> bool {
        matches!(self, Self::MeasuredViews { .. })
    }

    /// The assumption for one block whose estimate of the plant published `steps` grid
    /// steps: a measured separation becomes `steps · 2⁻⁸` (what the robot recomputes ℓ
    /// from); the other assumptions are unchanged.
    #[must_use]
    pub fn with_estimate(&self, steps: u32) -> Self {
        match self {
            Self::MeasuredViews {
                statement,
                estimation_epsilon,
                estimate_leak,
                ..
            } => Self::MeasuredViews {
                separation: f64::from(steps) * super::SEPARATION_QUANTUM,
                statement: statement.clone(),
                estimation_epsilon: *estimation_epsilon,
                estimate_leak: *estimate_leak,
            },
            Self::NoSecrecy { .. }
            | Self::IndependentErrors { .. }
            | Self::GaussianViews { .. } => self.clone(),
        }
    }

    /// The named ε terms a key made under this assumption is secret except with, for ε per
    /// term `epsilon`: 2ε_s + ε_PA + ε_PE, and ε_est when the plant was measured.
    #[must_use]
    pub fn epsilon_terms(&self, epsilon: f64) -> Vec<(&'static str, f64)> {
        let mut terms = vec![
            ("ε_s", epsilon),
            ("ε_s", epsilon),
            ("ε_PA", epsilon),
            ("ε_PE", epsilon),
        ];
        if let Self::MeasuredViews {
            estimation_epsilon, ..
        } = self
        {
            terms.push(("ε_est", *estimation_epsilon));
        }
        terms
    }

    /// The total ε of [`Self::epsilon_terms`].
    #[must_use]
    pub fn total_epsilon(&self, epsilon: f64) -> f64 {
        self.epsilon_terms(epsilon).iter().map(|t| t.1).sum()
    }

    /// For people: what is assumed.
    #[must_use]
    pub fn describe(&self) -> String {
        match self {
            Self::NoSecrecy { reason } => format!("no secrecy: {reason}"),
            Self::IndependentErrors { error_rate } => format!(
                "Eve's guesses err independently with probability ≥ {error_rate} \
                 (stated by the operator)"
            ),
            Self::GaussianViews {
                separation,
                statement,
            } => format!(
                "{statement}: Eve's views of the bits, each a Gaussian likelihood ratio of its \
                 own separation, independent across bits, give her no more than views of \
                 separation {separation:.3} each would (her error rate ≥ {:.4}, information ≤ \
                 {:.4} bit per bit)",
                gaussian_llr::error_rate(*separation),
                gaussian_llr::information(*separation),
            ),
            Self::MeasuredViews {
                separation,
                statement,
                estimation_epsilon,
                estimate_leak,
            } => format!(
                "{statement}: at the worst case of the motion noise's (1 − {estimation_epsilon:e}) \
                 region, Eve's views of the bits, {MEASURED_VIEWS}, independent across bits, give \
                 her no more than Gaussian views of separation {separation:.3} each would (her \
                 error rate ≥ {:.4}, information ≤ {:.4} bit per bit); ε_est = \
                 {estimation_epsilon:e} is a term of the key's ε; the published estimate is \
                 charged {estimate_leak:.1} bits",
                gaussian_llr::error_rate(*separation),
                gaussian_llr::information(*separation),
            ),
        }
    }

    /// A lower bound on Eve's smooth min-entropy (bits) of `n` reconciled bits at smoothing
    /// ε: 0; or the binomial bound w*·log₂(1/p) + (n − w*)·log₂(1/(1 − p)) with
    /// w* = min{w : P[Bin(n, p) ≤ w] > ε}, exact for a binary-symmetric view; or the
    /// Chernoff bound on the Gaussian views' total surprisal.
    #[must_use]
    pub fn h_min(&self, n: u64, epsilon: f64) -> f64 {
        match *self {
            Self::NoSecrecy { .. } => 0.0,
            Self::IndependentErrors { error_rate } => {
                binomial_smooth_min_entropy(n, error_rate, epsilon).map_or(0.0, |b| b.h_min)
            }
            Self::GaussianViews { separation, .. } => {
                gaussian_llr_smooth_min_entropy(n, separation, epsilon).map_or(0.0, |b| b.h_min)
            }
            Self::MeasuredViews {
                separation,
                estimate_leak,
                ..
            } => (gaussian_llr_smooth_min_entropy(n, separation, epsilon).map_or(0.0, |b| b.h_min)
                - estimate_leak)
                .max(0.0),
        }
    }

    /// ℓ for `n` reconciled bits after `leak_ec` reconciliation bits and two 64-bit tags.
    #[must_use]
    pub fn output_length(&self, n: u64, leak_ec: u64, epsilon: f64) -> (f64, OutputLength) {
        let h_min = self.h_min(n, epsilon);
        let length = output_length(h_min, leak_ec, 2 * TAG_BITS, epsilon).unwrap_or(OutputLength {
            bits: 0,
            raw: f64::NEG_INFINITY,
            reason: Some("the bound could not be evaluated".into()),
        });
        let length = match self {
            Self::NoSecrecy { reason } => OutputLength {
                reason: Some(format!("no secret bits: {reason}")),
                ..length
            },
            Self::IndependentErrors { .. }
            | Self::GaussianViews { .. }
            | Self::MeasuredViews { .. } => length,
        };
        (h_min, length)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn measured(separation: f64, estimation_epsilon: f64, estimate_leak: f64) -> Assumption {
        Assumption::MeasuredViews {
            separation,
            statement: "test".into(),
            estimation_epsilon,
            estimate_leak,
        }
    }

    /// Measured views are the Gaussian views less the published estimate's charge, with
    /// ε_est a fifth named term; a configured statement keeps its four.
    #[test]
    fn a_measured_plant_charges_its_estimate_and_names_epsilon_est() {
        let configured = Assumption::GaussianViews {
            separation: 1.7,
            statement: "test".into(),
        };
        let m = measured(1.7, 1e-6, 16.5);
        assert!((configured.h_min(10_000, 1e-6) - m.h_min(10_000, 1e-6) - 16.5).abs() < 1e-9);
        assert_eq!(configured.epsilon_terms(1e-6).len(), 4);
        let terms = m.epsilon_terms(1e-6);
        assert_eq!(terms.last(), Some(&("ε_est", 1e-6)));
        assert!((m.total_epsilon(1e-6) - 5e-6).abs() < 1e-18);
        assert!(m.describe().contains("ε_est = 1e-6"));
        // A block sized under per-wheel slip is bounded through pairs of covariances, not
        // Gaussian likelihood ratios: the text names both views the estimate sizes with.
        assert!(
            m.describe().contains(
                "in a block whose estimate measured per-wheel slip and was sized with it, the \
                 likelihood ratio of two Gaussians with covariances of their own"
            ),
            "{}",
            m.describe()
        );
        assert!(
            m.describe()
                .contains("no more than Gaussian views of separation 1.700")
        );
        assert_eq!(m.for_block(2_000_000), measured(2.0, 1e-6, 16.5));
        // The carried estimate replaces the separation; a configured one ignores it.
        assert!(m.is_measured() && !configured.is_measured());
        assert_eq!(m.with_estimate(436), measured(436.0 / 256.0, 1e-6, 16.5));
        assert_eq!(configured.with_estimate(436), configured);
        assert!(m.check().is_ok());
        assert_eq!(
            measured(1.7, 0.0, 16.5).check(),
            Err(AssumptionError::EstimationEpsilon(0.0))
        );
        assert_eq!(
            measured(1.7, 1e-6, -1.0).check(),
            Err(AssumptionError::EstimateLeak(-1.0))
        );
        assert_eq!(measured(1e6, 1e-6, 16.5).h_min(10_000, 1e-6), 0.0);
    }
}
