//! The results of an analysis: the secrecy of one grid point against one adversary, with
//! every figure a report shows (serialised to `secrecy.json` and read back from it).

use robokey::config::EveStrategy;
use robokey_secrecy::clopper_pearson;
use serde::{Deserialize, Serialize};

use super::pipeline::{Block, Pooling};
use super::private::PrivateFigures;

/// What an adversary is, for the secrecy it is credited against.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AdversaryClass {
    /// The best modelled adversary for the configuration: reports lead with it.
    Strongest,
    /// Starts with a wrong model and learns it from the traffic.
    Learning,
    /// Never learns the model: a figure against it holds only if nobody can.
    Restricted,
}

impl AdversaryClass {
    /// The class of an eavesdropping strategy (odometry mode: the oracle decides exactly as
    /// the controller does; identify and transcript learn r and D; mismatch and soft keep
    /// their wrong model forever).
    #[must_use]
    pub fn of(strategy: EveStrategy) -> Self {
        match strategy {
            EveStrategy::Oracle | EveStrategy::Camera => Self::Strongest,
            EveStrategy::Identify | EveStrategy::Transcript => Self::Learning,
            EveStrategy::Mismatch | EveStrategy::Soft | EveStrategy::Commands => Self::Restricted,
        }
    }

    /// The name in reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Strongest => "strongest",
            Self::Learning => "learning",
            Self::Restricted => "restricted",
        }
    }

    /// Against whom a figure for this class holds.
    #[must_use]
    pub fn holds_against(self) -> &'static str {
        match self {
            Self::Strongest => "the strongest modelled eavesdropper (exact model, every frame)",
            Self::Learning => "an eavesdropper who learns r and D from the traffic",
            Self::Restricted => "only an eavesdropper who never learns r and D",
        }
    }
}

/// Against whom a figure against `strategy` holds.
#[must_use]
pub fn holds_against(strategy: EveStrategy) -> &'static str {
    match strategy {
        EveStrategy::Camera => {
            "the strongest modelled eavesdropper of private sensing (exact model, her camera at \
             every sample instant, the controller's boundary samples the commands reveal)"
        }
        EveStrategy::Commands => "only an eavesdropper without a camera (what the commands leak)",
        other => AdversaryClass::of(other).holds_against(),
    }
}

/// A rate with a two-sided 95 % Clopper–Pearson interval.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Rate {
    /// Events.
    pub count: u64,
    /// Trials.
    pub trials: u64,
    /// count / trials.
    pub rate: f64,
    /// 95 % interval.
    pub low: f64,
    /// 95 % interval.
    pub high: f64,
}

impl Rate {
    pub(crate) fn new(count: u64, trials: u64) -> Option<Self> {
        let ci = clopper_pearson(count, trials, 0.95).ok()?;
        Some(Self {
            count,
            trials,
            rate: count as f64 / trials as f64,
            low: ci.lower,
            high: ci.upper,
        })
    }
}

/// The secrecy of one grid point against one adversary.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PointSecrecy {
    /// The point's index in the experiment's grid.
    pub point_index: usize,
    /// The point's parameters, `field = value, …`.
    pub point: String,
    /// The adversary.
    pub adversary: String,
    /// Its class: strongest, learning or restricted.
    pub adversary_class: AdversaryClass,
    /// Against whom the figures of this row hold.
    pub holds_against: String,
    /// Which sessions were pooled.
    pub pooling: Pooling,
    /// Why the configuration yields no secret key whatever this adversary gives, if it does
    /// not by structure.
    pub structural_zero: Option<String>,
    /// Why ℓ = 0 here (None when ℓ > 0).
    pub zero_reason: Option<String>,
    /// The stated assumption that sizes the key.
    pub assumption: String,
    /// ℓ that this adversary's realised view would support (the diagnostic).
    pub realised_secret_bits: u64,
    /// The assumption credits more than this adversary's realised view supports: the
    /// assumption is violated by this adversary.
    pub assumption_exceeds_realised: bool,
    /// The world's parameters that differ from what the parties believe, their stated
    /// `private.prior_lag` included (`world.FIELD = VALUE (parties: VALUE)`,
    /// [`robokey::world::WorldModel::differences`]), when the point's world is not theirs: the
    /// realised view is then the eavesdroppers' who know the world (docs/world.md).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub world_differences: Vec<String>,
    /// The first block's error-rate estimate for reconciliation.
    pub q_estimate: Option<f64>,
    /// Where it comes from.
    pub q_source: Option<String>,
    /// Sessions simulated.
    pub sessions: u32,
    /// Sessions pooled into the blocks.
    pub sessions_pooled: u32,
    /// Robot steps over those sessions.
    pub steps: u64,
    /// Robot steps of the sessions simulated until the last one pooled, dropped ones
    /// included: the denominator of the per-step rates (0 in files written before it).
    #[serde(default)]
    pub used_steps: u64,
    /// Sample time T (s).
    pub sample_time: f64,
    /// Controller's bit error rate over applied bits.
    pub p_c: Option<Rate>,
    /// Eve's bit error rate over applied bits.
    pub p_e: Option<Rate>,
    /// Plug-in I(B;B̂c) − I(B;B̂a) (bits per step) with a 95 % bootstrap interval.
    pub information_advantage: Option<[f64; 3]>,
    /// Plug-in I(B;B̂c|B̂a) with a 95 % bootstrap interval.
    pub information_conditional: Option<[f64; 3]>,
    /// Accepted (raw) key bits.
    pub raw_bits: u64,
    /// Raw agreed bits per robot step.
    pub raw_bits_per_step: f64,
    /// Eve's error rate on accepted bits (her ŝa against K_c).
    pub eve_error_accepted: Option<Rate>,
    /// p-value of the exact binomial test of P(s = 1 | accepted) = ½.
    pub acceptance_independence_p: Option<f64>,
    /// The privacy-amplification blocks.
    pub blocks: Vec<Block>,
    /// Total secret bits over the blocks, under the stated assumption.
    pub secret_bits: u64,
    /// Secret bits per robot step (over every session simulated until the last one pooled,
    /// dropped sessions included: they cost robot time too).
    pub secret_bits_per_step: f64,
    /// Secret bits per second.
    pub secret_bits_per_second: f64,
    /// Controller and Eve error rates per position along the lap (20 bins).
    pub positions: Vec<PositionErrors>,
    /// Private sensing: calibration, the leak by turn rate, the gate, J_x.
    pub private: Option<PrivateFigures>,
}

/// Error rates in one bin of lap position.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PositionErrors {
    /// Bin start as a fraction of the lap.
    pub from: f64,
    /// Applied bits in the bin.
    pub bits: u64,
    /// Controller error rate.
    pub controller: f64,
    /// Eve error rate.
    pub eve: f64,
}
