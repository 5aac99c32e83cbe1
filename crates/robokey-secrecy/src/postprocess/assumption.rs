//! What the operator states about Eve. The final key length follows from this statement and
//! from what was published — never from Eve's realised view, which no deployed party has.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::confirm::TAG_BITS;
use crate::min_entropy::{OutputLength, binomial_smooth_min_entropy, output_length};

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
}

/// An assumption out of range.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, Error)]
pub enum AssumptionError {
    /// An error rate outside (0, ½].
    #[error("assumed Eve error rate {0} is out of range (allowed: (0, 0.5])")]
    ErrorRate(f64),
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
            _ => Ok(()),
        }
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
        }
    }

    /// A lower bound on Eve's smooth min-entropy (bits) of `n` reconciled bits at smoothing
    /// ε: 0, or the binomial bound w*·log₂(1/p) + (n − w*)·log₂(1/(1 − p)) with
    /// w* = min{w : P[Bin(n, p) ≤ w] > ε}, exact for a binary-symmetric view.
    #[must_use]
    pub fn h_min(&self, n: u64, epsilon: f64) -> f64 {
        match *self {
            Self::NoSecrecy { .. } => 0.0,
            Self::IndependentErrors { error_rate } => {
                binomial_smooth_min_entropy(n, error_rate, epsilon).map_or(0.0, |b| b.h_min)
            }
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
            Self::IndependentErrors { .. } => length,
        };
        (h_min, length)
    }
}
