//! What private sensing adds to the secrecy analysis (docs/private-sensing.md): the
//! assumption that sizes the key, both parties' calibration, the adversary's information
//! binned by the public turn rate against what the model predicts, the turn gate and the
//! tracking cost.

use rayon::prelude::*;
use std::collections::HashMap;

use robokey::Config;
use robokey::config::{EveConfig, EveStrategy};
use robokey::estimate::commands_check::TURN_EDGES;
use robokey::private::DoubletBit;
use robokey::sim::{RunOutput, simulate};
use robokey_secrecy::calibration::check_calibration;
use robokey_secrecy::gaussian_llr::{information_interpolated, surprisal};
use serde::{Deserialize, Serialize};

use super::Rate;
use crate::error::LabError;

/// The outcome of a calibration test of one party's LLRs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// Bits tested.
    pub bits: u64,
    /// Every bin within its Bonferroni-corrected level (family-wise α = 10⁻³).
    pub passed: bool,
    /// The smallest per-bin p-value (NaN when the test could not run).
    #[serde(deserialize_with = "crate::reals::nan_if_null")]
    pub worst_p: f64,
    /// The errors of the bin with that p-value against its prediction (`None` when the test
    /// could not run, or in a folder written before it was recorded).
    #[serde(default)]
    pub worst_bin: Option<BinErrors>,
}

/// One calibration bin's errors: what occurred against `Σ qᵢ`, what the LLRs predicted.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BinErrors {
    /// Errors that occurred.
    pub observed: u64,
    /// Errors the LLRs predicted, `Σ 1/(1 + e^|Lᵢ|)`.
    pub predicted: f64,
}

impl BinErrors {
    /// Fewer errors than predicted: the LLRs are timid (under-confident). For the controller
    /// that is conservative (a longer syndrome); for an eavesdropper it would understate
    /// what she learns.
    #[must_use]
    pub fn under_confident(&self) -> bool {
        (self.observed as f64) < self.predicted
    }
}

impl std::fmt::Display for BinErrors {
    /// "1 error where 42.6 predicted, under-confident".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} error{} where {:.1} predicted, {}-confident",
            self.observed,
            if self.observed == 1 { "" } else { "s" },
            self.predicted,
            if self.under_confident() {
                "under"
            } else {
                "over"
            }
        )
    }
}

/// The adversary's information on the bits of one turn-rate bin.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TurnBin {
    /// Lower edge (rad/s).
    pub from: f64,
    /// Upper edge (rad/s; infinite for the last).
    #[serde(deserialize_with = "crate::reals::infinity_if_null")]
    pub to: f64,
    /// Bits in the bin.
    pub bits: u64,
    /// Her error rate with a 95 % Clopper–Pearson interval.
    pub error: Option<Rate>,
    /// Measured information `1 − mean S` (bits per bit) with a 95 % normal interval.
    #[serde(deserialize_with = "crate::reals::nans_if_null")]
    pub information: [f64; 3],
    /// What the model predicts: `mean I(d)` over the bin's separations (`I(d)` interpolated,
    /// within 10⁻¹² bit).
    pub predicted: f64,
}

/// The private-sensing figures of one point and adversary.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PrivateFigures {
    /// Doublets commanded over the sessions simulated.
    pub doublets: u64,
    /// Fraction of them the turn gate left without a bit.
    pub gated_fraction: f64,
    /// Key bits per doublet (`protocol.bits_per_doublet · log₂ protocol.levels`).
    pub bits_per_doublet: usize,
    /// The controller's error rate over the bits carried.
    pub controller_error: Option<Rate>,
    /// The adversary's error rate over the bits carried.
    pub eve_error: Option<Rate>,
    /// The controller's LLRs.
    pub controller_calibration: Calibration,
    /// The adversary's LLRs.
    pub eve_calibration: Calibration,
    /// Her measured information per bit `1 − mean S`, with a 95 % interval (NaN without
    /// bits).
    #[serde(deserialize_with = "crate::reals::nans_if_null")]
    pub eve_information: [f64; 3],
    /// The model's prediction of it (the same interpolated `I(d)`).
    pub eve_information_predicted: f64,
    /// The same binned by the public turn rate.
    pub turn_bins: Vec<TurnBin>,
    /// The largest separation the camera assumption gives her over the bits: what sizes
    /// the key.
    pub assumed_separation: f64,
    /// Mean tracking error J_x (mm) over the sessions.
    pub jx_mm: f64,
    /// J_x (mm) with the protocol off (same seeds).
    pub jx_off_mm: f64,
}

/// The largest separation the camera assumption gives her over every bit of `runs`,
/// computed as the controller can (docs/private-sensing.md, "Secrecy accounting").
#[must_use]
pub fn largest_separation(runs: &[RunOutput]) -> f64 {
    bits(runs).fold(0.0, |m, b| m.max(b.assumed_separation))
}

/// Each bit's separation under the camera assumption in `run`, as the controller computes
/// them: what sizes its keys per bit.
#[must_use]
pub fn assumed_separations(run: &RunOutput) -> Vec<f64> {
    bits(std::slice::from_ref(run))
        .map(|b| b.assumed_separation)
        .collect()
}

fn bits(runs: &[RunOutput]) -> impl Iterator<Item = &DoubletBit> {
    runs.iter()
        .flat_map(|r| r.private.as_ref().map_or(&[][..], |p| p.bits.as_slice()))
}

fn toward_truth(llr: f64, bit: u8) -> f64 {
    if bit == 0 { llr } else { -llr }
}

/// The model's prediction of the information per bit: the mean of `I(d)` over bits whose
/// `I(d)` (computed once per bit) are `informations`.
fn predicted_information(informations: impl ExactSizeIterator<Item = f64>) -> f64 {
    let count = informations.len();
    informations.sum::<f64>() / count.max(1) as f64
}

/// `I(d)` of each of `separations`, in order, interpolated
/// ([`information_interpolated`]: within 10⁻¹² bit of the integral).
fn informations(separations: impl Iterator<Item = f64>) -> Vec<f64> {
    separations.map(information_interpolated).collect()
}

/// The error rate of deciding each bit by the sign of `llr`.
fn error_rate(bits: &[&DoubletBit], llr: impl Fn(&DoubletBit) -> f64) -> Option<Rate> {
    let wrong = bits
        .iter()
        .filter(|b| (llr(b) < 0.0) != (b.bit == 1))
        .count();
    Rate::new(wrong as u64, bits.len() as u64)
}

fn calibration(bits: &[&DoubletBit], llr: impl Fn(&DoubletBit) -> f64) -> Calibration {
    let pairs: Vec<(f64, bool)> = bits
        .iter()
        .map(|b| {
            let l = llr(b);
            (1.0 / (1.0 + l.abs().exp()), (l < 0.0) != (b.bit == 1))
        })
        .collect();
    let report = check_calibration(&pairs, 10, 1e-3).ok();
    let worst = report
        .as_ref()
        .and_then(|r| r.bins.iter().min_by(|a, b| a.p_value.total_cmp(&b.p_value)));
    Calibration {
        bits: pairs.len() as u64,
        passed: report.as_ref().is_some_and(|r| r.passed),
        worst_p: worst.map_or(f64::NAN, |b| b.p_value.min(1.0)),
        worst_bin: worst.map(|b| BinErrors {
            observed: b.observed_errors,
            predicted: b.predicted_errors,
        }),
    }
}

/// Mean of `1 − S` with a 95 % normal interval (the sample is ≥ 10³ bits per bin in use).
fn mean_information(values: &[f64]) -> [f64; 3] {
    let n = values.len() as f64;
    if values.is_empty() {
        return [f64::NAN; 3];
    }
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    let half = 1.96 * (var / n).sqrt();
    [mean, mean - half, mean + half]
}

/// Protocol-off runs J_x is compared with: replicates 0 … n − 1 for `n` sessions, at most 10.
#[must_use]
pub fn off_replicates(sessions: usize) -> usize {
    sessions.min(10)
}

/// The plant of a point: its configuration with the protocol off and without Eve's
/// settings. She only films, from her own random stream, and never acts, so the robot's
/// path with the protocol off — J_x — does not depend on her: the points of a camera map
/// share their protocol-off runs.
fn plant(config: &Config) -> Config {
    let mut off = config.clone();
    off.protocol.enabled = false;
    off.eve = EveConfig::default();
    off
}

/// J_x (m) of each plant's protocol-off runs, replicates 0, 1, …: simulated once per plant,
/// however many points and adversaries compare with it.
#[derive(Debug, Default)]
pub struct OffRuns(HashMap<String, Vec<f64>>);

impl OffRuns {
    /// Simulates, in parallel, replicates `0 … n − 1` of the plant of each `(config, n)`
    /// (the largest `n` of a plant).
    ///
    /// # Errors
    /// Never in practice: private sessions do not abort.
    pub fn simulate<'a>(
        wanted: impl IntoIterator<Item = (&'a Config, usize)>,
    ) -> Result<Self, LabError> {
        let mut plants: Vec<(String, Config, usize)> = Vec::new();
        for (config, n) in wanted {
            let plant = plant(config);
            let key = plant.to_toml();
            match plants.iter_mut().find(|p| p.0 == key) {
                Some(p) => p.2 = p.2.max(n),
                None => plants.push((key, plant, n)),
            }
        }
        let runs: Vec<(usize, u32)> = plants
            .iter()
            .enumerate()
            .flat_map(|(i, p)| (0..p.2 as u32).map(move |r| (i, r)))
            .collect();
        let jx: Vec<f64> = runs
            .par_iter()
            .map(|&(i, r)| simulate(&plants[i].1, r, false).map(|o| o.metrics.jx))
            .collect::<Result<_, _>>()?;
        let mut by_plant: HashMap<String, Vec<f64>> = HashMap::new();
        for (&(i, _), jx) in runs.iter().zip(jx) {
            by_plant.entry(plants[i].0.clone()).or_default().push(jx);
        }
        Ok(Self(by_plant))
    }

    /// J_x of the first `n` protocol-off runs of `config`'s plant (fewer if fewer were
    /// simulated).
    #[must_use]
    pub fn jx(&self, config: &Config, n: usize) -> &[f64] {
        self.0
            .get(&plant(config).to_toml())
            .map_or(&[], |jx| &jx[..n.min(jx.len())])
    }
}

/// The figures of `runs` against `adversary`; J_x with the protocol off from `off`.
///
/// # Errors
/// Never in practice: private sessions do not abort.
pub fn figures(
    config: &Config,
    runs: &[RunOutput],
    adversary: EveStrategy,
    off: &OffRuns,
) -> Result<PrivateFigures, LabError> {
    let all: Vec<&DoubletBit> = bits(runs).collect();
    let doublets: u64 = runs
        .iter()
        .filter_map(|r| r.private.as_ref())
        .map(|p| u64::from(p.doublets))
        .sum();
    let gated: u64 = runs
        .iter()
        .filter_map(|r| r.private.as_ref())
        .map(|p| u64::from(p.gated))
        .sum();
    let info_of = |b: &DoubletBit| 1.0 - surprisal(toward_truth(b.llr_of(adversary), b.bit));
    let predicted = informations(all.iter().map(|b| b.separation_of(adversary)));
    let mut turn_bins = Vec::new();
    let mut from = 0.0;
    for &to in TURN_EDGES.iter().chain([f64::INFINITY].iter()) {
        let in_bin = |b: &&DoubletBit| b.turn_rate >= from && b.turn_rate < to;
        let bin: Vec<&DoubletBit> = all.iter().copied().filter(in_bin).collect();
        if !bin.is_empty() {
            let bin_predicted: Vec<f64> = all
                .iter()
                .zip(&predicted)
                .filter(|(b, _)| in_bin(b))
                .map(|(_, &p)| p)
                .collect();
            let values: Vec<f64> = bin.iter().map(|b| info_of(b)).collect();
            turn_bins.push(TurnBin {
                from,
                to,
                bits: bin.len() as u64,
                error: error_rate(&bin, |b| b.llr_of(adversary)),
                information: mean_information(&values),
                predicted: predicted_information(bin_predicted.into_iter()),
            });
        }
        from = to;
    }
    let values: Vec<f64> = all.iter().map(|b| info_of(b)).collect();
    let jx_off = off.jx(config, off_replicates(runs.len()));
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let jx: Vec<f64> = runs.iter().map(|r| r.metrics.jx).collect();
    Ok(PrivateFigures {
        doublets,
        gated_fraction: gated as f64 / doublets.max(1) as f64,
        bits_per_doublet: config.protocol.key_bits_per_doublet(),
        controller_error: error_rate(&all, |b| b.controller),
        eve_error: error_rate(&all, |b| b.llr_of(adversary)),
        controller_calibration: calibration(&all, |b| b.controller),
        eve_calibration: calibration(&all, |b| b.llr_of(adversary)),
        eve_information: mean_information(&values),
        eve_information_predicted: predicted_information(predicted.into_iter()),
        turn_bins,
        assumed_separation: largest_separation(runs),
        jx_mm: 1e3 * mean(&jx),
        jx_off_mm: 1e3 * mean(jx_off),
    })
}

/// `robokey eve` in private sensing: simulates `sessions` replicates of `config` and measures
/// each of `strategies` on them (every strategy hears the same sessions).
///
/// # Errors
/// A strategy that does not apply in private sensing.
pub fn eavesdroppers(
    config: &Config,
    strategies: &[EveStrategy],
    sessions: u32,
) -> Result<Vec<(EveStrategy, PrivateFigures)>, LabError> {
    if let Some(s) = strategies
        .iter()
        .find(|s| s.mode() != robokey::config::SensingMode::Private)
    {
        return Err(LabError::SensingMode(format!(
            "the {} eavesdropper does not apply in private sensing (allowed: camera, commands)",
            s.name()
        )));
    }
    let runs: Vec<RunOutput> = (0..sessions)
        .into_par_iter()
        .map(|r| simulate(config, r, false))
        .collect::<Result<_, _>>()?;
    let off = OffRuns::simulate([(config, off_replicates(runs.len()))])?;
    strategies
        .iter()
        .map(|&s| Ok((s, figures(config, &runs, s, &off)?)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use robokey::private::BitKind;

    fn bit(bit: u8, controller: f64) -> DoubletBit {
        DoubletBit {
            step: 0,
            kind: BitKind::V,
            bit,
            turn_rate: 0.0,
            controller,
            camera: 0.0,
            commands: None,
            camera_separation: 0.0,
            assumed_separation: 0.0,
            commands_separation: None,
        }
    }

    /// LLRs of magnitude 2 (q = 0.119 each) that are never wrong fail the test as
    /// under-confident, naming the worst bin's errors against its prediction; the same
    /// magnitudes wrong half the time fail as over-confident; wrong at q's rate, they pass.
    #[test]
    fn a_failed_calibration_names_its_worst_bin_and_direction() {
        let q = 1.0 / (1.0 + 2f64.exp());
        let check = |wrong_every: usize| {
            let bits: Vec<DoubletBit> = (0..2_000)
                .map(|i| {
                    let wrong = wrong_every > 0 && i % wrong_every == 0;
                    bit(u8::from(wrong), 2.0)
                })
                .collect();
            calibration(&bits.iter().collect::<Vec<_>>(), |b| b.controller)
        };
        let timid = check(0);
        let worst = timid.worst_bin.unwrap();
        assert!(!timid.passed && worst.under_confident());
        assert_eq!(worst.observed, 0);
        assert!((worst.predicted - 200.0 * q).abs() < 1e-9, "{worst:?}");
        let bold = check(2);
        assert!(!bold.passed && !bold.worst_bin.unwrap().under_confident());
        // Every 8th wrong: 25 of 200 per bin against 23.8 predicted.
        assert!(check(8).passed);
    }
}
