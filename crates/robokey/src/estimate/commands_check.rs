//! The commands check (docs/private-sensing.md, "The commands check"), one implementation
//! for the simulator and the agents: after reconciliation, what the public commands reveal —
//! the controller's boundary residuals, which the next commands carry — is regressed on the
//! reconciled bits, model-free, per bit kind, turn-rate class and axis, and compared with the
//! model's prediction of the same regression. A block where the commands reveal more than
//! the model predicts is refused, naming the class, the axis and the statistic.
//!
//! It reads the controller's samples of each carrying doublet with the robot's bits
//! ([`DoubletSamples`]): the simulator's runs hold them, the agents' controller keeps them in
//! its pool for the block's estimate ([`super::block::estimate_request`] runs the check).

use robokey_secrecy::gaussian_llr::erfc;

use super::BlockEstimate;
use super::quantum_check::quantum_refusal;
use super::worst_case::largest_of_each_over_lags;
use crate::Config;
use crate::private::doublet::{in_doublet_frame, sign};
use crate::private::{BitKind, DoubletModel, DoubletSamples, doublet_model};

/// Upper edges of the turn-rate classes (rad/s); the last class is open. The lab's
/// `private-leak` figure bins by them too.
pub const TURN_EDGES: [f64; 6] = [0.05, 0.1, 0.2, 0.3, 0.5, 1.0];

/// Classes with fewer bits are not tested: the normal approximation of the regression's
/// error needs a sample (a class that small carries at most this many of the block's bits).
pub const MIN_CLASS_BITS: usize = 100;

/// The axes of the doublet frame ([`in_doublet_frame`]), with the unit and scale each is
/// reported in.
const AXES: [(&str, &str, f64); 3] = [
    ("along the heading", "mm", 1e3),
    ("across, toward the turn", "mm", 1e3),
    ("in heading", "mrad", 1e3),
];

/// What the next commands reveal of one bit's doublet, and what the model predicts of it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundaryResidual {
    /// Which input the bit rides on.
    pub kind: BitKind,
    /// The robot's (reconciled) bit.
    pub bit: u8,
    /// The doublet's public nominal turn rate (rad/s).
    pub turn_rate: f64,
    /// The controller's boundary residual `y_c(Lj+L) − f(… f(y_c(Lj), u) …)` over the
    /// doublet's `L` nominal inputs, in the doublet's frame (m, m, rad): what the next
    /// commands reveal.
    pub revealed: [f64; 3],
    /// The model's part of it for `s = +1`: half the difference of the predicted ends of the
    /// bit's two values, the doublet's other bit as reconciled (m, m, rad, same frame). The
    /// residual's regression on `s` is this under the model.
    pub modelled: [f64; 3],
}

/// The boundary residuals of every key bit of one carrying doublet under `model` (each
/// bit's kind its symbol's dimension), from the controller's samples and the robot's bits
/// `samples.pattern`.
#[must_use]
pub fn doublet_residuals(model: &DoubletModel, samples: &DoubletSamples) -> Vec<BoundaryResidual> {
    let start = &samples.samples[0];
    let frame =
        |delta: &crate::model::Pose| in_doublet_frame(delta, start.z, samples.inputs.first.y);
    let end = |pattern: Option<usize>| model.end_of(&samples.inputs, start, pattern);
    let revealed = frame(&(samples.samples[2] - end(None)));
    let bits = samples.pattern;
    let perturbation = &model.perturbation;
    (0..perturbation.key_bits())
        .map(|index| {
            let with = |value: usize| {
                let pattern = (bits & !(1 << index)) | (value << index);
                perturbation.pattern(pattern as u64)
            };
            let [plus, minus] = [with(0), with(1)].map(|h| end(Some(h)));
            BoundaryResidual {
                kind: BitKind::ALL[perturbation.dimension_of(index)],
                bit: (bits >> index & 1) as u8,
                turn_rate: samples.inputs.turn_rate(),
                revealed,
                modelled: frame(&(0.5 * (plus - minus))),
            }
        })
        .collect()
}

/// The boundary residuals of every bit of a block's `sessions` under the parties' `config`.
#[must_use]
pub fn block_residuals(config: &Config, sessions: &[&[DoubletSamples]]) -> Vec<BoundaryResidual> {
    let model = doublet_model(config);
    sessions
        .iter()
        .flat_map(|session| session.iter())
        .flat_map(|samples| doublet_residuals(&model, samples))
        .collect()
}

/// One regression of the boundary residual on the bits' signs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Regression {
    /// The bits' kind.
    pub kind: BitKind,
    /// The class's turn rates `[from, to)` (rad/s).
    pub turn_rate: [f64; 2],
    /// The axis, an index into the doublet frame.
    pub axis: usize,
    /// Bits in the class.
    pub bits: usize,
    /// `β̂ = mean sᵢ·rᵢ`: what the residual reveals per bit sign (m or rad).
    pub measured: f64,
    /// `mean μᵢ`: the model's prediction of it (a three-step block sized over τ's interval:
    /// its largest magnitude there).
    pub predicted: f64,
    /// β̂'s standard error, `sd(sᵢ·rᵢ)/√n`.
    pub std_error: f64,
}

impl Regression {
    /// The statistic `z = (|β̂| − |mean μ|) / SE`: standard errors by which the commands
    /// reveal more than the model predicts.
    #[must_use]
    pub fn statistic(&self) -> f64 {
        (self.measured.abs() - self.predicted.abs()) / self.std_error
    }

    /// One-sided p-value of `|β| ≤ |mean μ|` (the commands reveal no more than the model
    /// predicts): `½·erfc(z/√2)`.
    #[must_use]
    pub fn p_value(&self) -> f64 {
        let z = self.statistic();
        if z.is_nan() {
            return 1.0;
        }
        0.5 * erfc(z / std::f64::consts::SQRT_2)
    }

    /// The regression in words, for a refusal.
    #[must_use]
    pub fn describe(&self) -> String {
        let (axis, unit, scale) = AXES[self.axis];
        let kind = match self.kind {
            BitKind::V => "v-bits",
            BitKind::Omega => "ω-bits",
        };
        let to = if self.turn_rate[1].is_finite() {
            format!("{:.2}", self.turn_rate[1])
        } else {
            "∞".to_owned()
        };
        format!(
            "{kind} at turn rates {:.2}–{to} rad/s ({} bits): the boundary residual {axis} \
             reveals {:.3} {unit} per bit sign where the model predicts {:.3} {unit} (standard \
             error {:.3} {unit})",
            self.turn_rate[0],
            self.bits,
            scale * self.measured,
            scale * self.predicted,
            scale * self.std_error,
        )
    }
}

/// Every regression of `bits` (a block's, each with its reconciled value) with at least
/// [`MIN_CLASS_BITS`] bits: per kind, turn-rate class and axis.
#[must_use]
pub fn regressions(bits: &[BoundaryResidual]) -> Vec<Regression> {
    let mut out = Vec::new();
    for kind in BitKind::ALL {
        let mut from = 0.0;
        for &to in TURN_EDGES.iter().chain([f64::INFINITY].iter()) {
            let class: Vec<&BoundaryResidual> = bits
                .iter()
                .filter(|b| b.kind == kind && b.turn_rate >= from && b.turn_rate < to)
                .collect();
            let n = class.len();
            if n >= MIN_CLASS_BITS {
                for axis in 0..AXES.len() {
                    let x: Vec<f64> = class
                        .iter()
                        .map(|b| sign(b.bit) * b.revealed[axis])
                        .collect();
                    let mean = x.iter().sum::<f64>() / n as f64;
                    let variance =
                        x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
                    out.push(Regression {
                        kind,
                        turn_rate: [from, to],
                        axis,
                        bits: n,
                        measured: mean,
                        predicted: class.iter().map(|b| b.modelled[axis]).sum::<f64>() / n as f64,
                        std_error: (variance / n as f64).sqrt(),
                    });
                }
            }
            from = to;
        }
    }
    out
}

/// The commands check of a block's `bits` at family-wise level `level`: the reason for
/// refusing the block when some regression reveals more than the model predicts with a
/// p-value below `level / tests` (Bonferroni over the block's regressions); none when every
/// one passes.
#[must_use]
pub fn refusal(bits: &[BoundaryResidual], level: f64) -> Option<String> {
    refusal_of(&regressions(bits), level)
}

/// [`refusal`] of a block's regressions `tests`.
fn refusal_of(tests: &[Regression], level: f64) -> Option<String> {
    let threshold = level / tests.len().max(1) as f64;
    let worst = tests
        .iter()
        .map(|r| (r, r.p_value()))
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    (worst.1 < threshold).then(|| {
        format!(
            "the commands check refused the block: {}; p = {:.1e} below {level:.0e} / {} \
             regressions (the commands reveal more than the model predicts)",
            worst.0.describe(),
            worst.1,
            tests.len()
        )
    })
}

/// The commands check of a block of `sessions` (the controller's samples of each with the
/// robot's bits) under the parties' `config` at level `level` ([`refusal`]).
#[must_use]
pub fn block_refusal(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    level: f64,
) -> Option<String> {
    refusal(&block_residuals(config, sessions), level)
}

/// The largest slack of the model's prediction over τ's interval before its grid is
/// refined, in standard errors of the regression it predicts.
const PREDICTION_SLACK: f64 = 0.1;

/// The regressions of a block of `sessions` against the model's largest prediction over the
/// lag's whole `interval` `[τ_lo, τ_hi]` (s), per regression: its magnitude on the grid Eve's
/// view is sized on, refined while a concavity slack exceeds `PREDICTION_SLACK` standard
/// errors, plus that slack (`largest_of_each_over_lags`). The measured side is the
/// regression's at `τ_lo` (what the next commands reveal does not depend on τ). A
/// prediction that bends faster than the grid resolves is under-predicted there, which
/// only refuses more blocks: this check need not bound it as Eve's view does.
#[must_use]
pub fn regressions_over_lags(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    [low, high]: [f64; 2],
) -> Vec<Regression> {
    let prior = doublet_model(config);
    let tests_at = |tau: f64| {
        let model = DoubletModel { lag: tau, ..prior };
        let bits: Vec<BoundaryResidual> = sessions
            .iter()
            .flat_map(|session| session.iter())
            .flat_map(|samples| doublet_residuals(&model, samples))
            .collect();
        regressions(&bits)
    };
    let mut tests = tests_at(low);
    let slack_limit: Vec<f64> = tests
        .iter()
        .map(|r| PREDICTION_SLACK * r.std_error)
        .collect();
    if let Some(largest) = largest_of_each_over_lags([low, high], &slack_limit, |tau| {
        Some(tests_at(tau).iter().map(|r| r.predicted.abs()).collect())
    }) {
        for (test, predicted) in tests.iter_mut().zip(largest) {
            test.predicted = predicted;
        }
    }
    tests
}

/// The commands check of a block of `sessions` as its estimate sized it, then the
/// command-quantum check ([`quantum_refusal`]) at the same level: a block of three-step
/// doublets whose `estimate` measured the lag is checked against the model's largest
/// prediction over τ's whole interval ([`regressions_over_lags`]: what the prior's error
/// leaves at the doublet's end is modelled, and in Eve's view over the same interval, on
/// the same grid), and its quantum at τ̂; any other block against the parties' prior
/// ([`block_refusal`]).
#[must_use]
pub fn sized_block_refusal(
    config: &Config,
    sessions: &[&[DoubletSamples]],
    level: f64,
    estimate: Option<&BlockEstimate>,
) -> Option<String> {
    let Some([point, low, high]) = estimate.and_then(|e| e.lag) else {
        return block_refusal(config, sessions, level)
            .or_else(|| quantum_refusal(config, sessions, doublet_model(config).lag, level));
    };
    refusal_of(&regressions_over_lags(config, sessions, [low, high]), level)
        .or_else(|| quantum_refusal(config, sessions, point, level))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{Purpose, stream};
    use rand_distr::{Distribution, Normal};

    /// `n` v-bits on a straight segment with residual noise `noise` (m) per axis, and a
    /// residual `leak` (m) along the heading per bit sign that the model does not predict.
    fn block(n: usize, noise: f64, leak: f64, seed: u64) -> Vec<BoundaryResidual> {
        let mut rng = stream(seed, Purpose::Public, 0);
        let normal = Normal::new(0.0, noise).unwrap();
        (0..n)
            .map(|i| {
                let bit = (i % 2) as u8;
                let mut revealed = [0.0; 3].map(|_| normal.sample(&mut rng));
                revealed[0] += sign(bit) * leak;
                BoundaryResidual {
                    kind: BitKind::V,
                    bit,
                    turn_rate: 0.0,
                    revealed,
                    modelled: [0.0; 3],
                }
            })
            .collect()
    }

    /// A leak the model does not predict is refused when it stands above the regression's
    /// error (≈ 0.016 mm at 10⁴ bits with 1.6 mm of residual noise), naming the class, the
    /// axis and the values; white residuals pass at ε = 10⁻⁶.
    /// With a 4-level alphabet on v and ω every key bit is checked under its symbol's
    /// dimension: v's two bits as v-bits, ω's two as ω-bits.
    #[test]
    fn every_key_bit_of_a_multilevel_doublet_is_checked_under_its_dimension() {
        let mut config = Config::default();
        config.sensing.mode = crate::config::SensingMode::Private;
        config.protocol.bits_per_doublet = 2;
        config.protocol.levels = 4;
        let model = doublet_model(&config);
        let samples = DoubletSamples {
            doublet: 0,
            inputs: crate::private::DoubletInputs {
                first: crate::model::Unicycle::new(0.1, 0.0),
                second: crate::model::Unicycle::new(0.1, 0.0),
            },
            samples: [crate::model::Pose::zeros(); 3],
            pattern: 0b1001,
            late: None,
        };
        let residuals = doublet_residuals(&model, &samples);
        let kinds: Vec<BitKind> = residuals.iter().map(|r| r.kind).collect();
        assert_eq!(
            kinds,
            [BitKind::V, BitKind::V, BitKind::Omega, BitKind::Omega]
        );
        let bits: Vec<u8> = residuals.iter().map(|r| r.bit).collect();
        assert_eq!(bits, [1, 0, 0, 1]);
    }

    #[test]
    fn a_residual_the_model_does_not_predict_refuses_the_block() {
        let bits = block(10_000, 0.0016, 0.0017, 1);
        let why = refusal(&bits, 1e-6).expect("refused");
        assert!(
            why.contains("v-bits at turn rates 0.00–0.05 rad/s"),
            "{why}"
        );
        assert!(why.contains("along the heading"), "{why}");
        assert!(why.contains("reveals 1.7"), "{why}");
        // The statistic: ≈ 1.7 / 0.016 ≈ 106 standard errors along the heading.
        let along = regressions(&bits)[0];
        assert!((90.0..125.0).contains(&along.statistic()), "{along:?}");
        for seed in 2..6 {
            assert_eq!(refusal(&block(10_000, 0.0016, 0.0, seed), 1e-6), None);
        }
        // Below the regression's power at this size: 0.02 mm is ≈ 1.25 standard errors.
        assert_eq!(refusal(&block(10_000, 0.0016, 0.000_02, 7), 1e-6), None);
    }

    /// What the model predicts is not an excess: a residual equal to its prediction passes.
    #[test]
    fn a_predicted_residual_passes() {
        let mut bits = block(10_000, 0.0016, 0.0017, 8);
        for b in &mut bits {
            b.modelled[0] = 0.0017;
        }
        assert_eq!(refusal(&bits, 1e-6), None);
    }

    /// Classes below [`MIN_CLASS_BITS`] are not tested: a small block passes however much
    /// its residuals reveal, and says nothing.
    #[test]
    fn classes_too_small_to_test_are_not_tested() {
        let bits = block(MIN_CLASS_BITS - 1, 0.0016, 0.0017, 9);
        assert!(regressions(&bits).is_empty());
        assert_eq!(refusal(&bits, 1e-6), None);
    }
}
