//! How many of the agreed bits are secret (SECRECY.md): per grid point and adversary,
//! error rates with exact intervals, plug-in informations with bootstrap intervals, Eve on
//! the accepted bits, the acceptance-independence test, per-position error rates, and the
//! finite-key output length after Cascade reconciliation, confirmation and Toeplitz
//! privacy amplification over pooled blocks of confirmed session keys.
//!
//! Sessions are re-simulated from the sweep's `config.resolved.toml` and seeds, with the
//! adversary swapped in; sessions are added (replicates 0, 1, …) until the pooled raw key
//! fills the requested number of blocks. A learning adversary (identify, transcript) hears
//! them in that order, so what she learned from earlier sessions serves her on later ones.

use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use rayon::prelude::*;
use robokey::config::EveStrategy;
use robokey::protocol::SessionPlan;
use robokey::rng::{Purpose, stream};
use robokey::sim::{RunOutput, simulate_plan, simulate_transcript};
use robokey_secrecy::interval::clopper_pearson_lower;
use robokey_secrecy::min_entropy::{binomial_smooth_min_entropy, output_length};
use robokey_secrecy::{
    BitString, Cascade, JointCounts, Reconciler, ToeplitzHash, binomial_test, clopper_pearson,
};
use serde::Serialize;

use std::path::{Path, PathBuf};

use crate::adversary::{eavesdropper, overhear};
use crate::error::LabError;
use crate::files::write;
use crate::plot::{LineChart, Series, SeriesStyle};
use crate::sweep::{Experiment, describe};

/// Settings of the analysis.
#[derive(Clone, Debug)]
pub struct SecrecyOptions {
    /// Adversaries to evaluate.
    pub adversaries: Vec<EveStrategy>,
    /// ε of each term: smoothing ε_s, privacy amplification ε_PA and parameter
    /// estimation ε_PE; the key is then 4ε-secret (2ε_s + ε_PA + ε_PE).
    pub epsilon: f64,
    /// Pooled raw bits per privacy-amplification block.
    pub block_bits: usize,
    /// Blocks to fill per point (sessions are added until they are full).
    pub blocks: usize,
    /// Most sessions simulated per point and adversary.
    pub max_sessions: u32,
    /// Bootstrap resamples for the information intervals.
    pub bootstrap: usize,
}

impl Default for SecrecyOptions {
    fn default() -> Self {
        Self {
            adversaries: vec![EveStrategy::Mismatch, EveStrategy::Oracle],
            epsilon: 1e-6,
            block_bits: 10_000,
            blocks: 1,
            max_sessions: 2_000,
            bootstrap: 1_000,
        }
    }
}

/// A rate with a two-sided 95 % Clopper–Pearson interval.
#[derive(Clone, Copy, Debug, Serialize)]
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
    fn new(count: u64, trials: u64) -> Option<Self> {
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

/// One privacy-amplification block.
#[derive(Clone, Debug, Serialize)]
pub struct Block {
    /// Raw bits pooled.
    pub bits: usize,
    /// Disagreements between K_c and K_r before reconciliation.
    pub errors_before: usize,
    /// Parities revealed by Cascade (leak_EC).
    pub leak: u64,
    /// Whether Bob's corrected key equals Alice's (else confirmation discards the block).
    pub confirmed: bool,
    /// Eve's errors against K_c in this block.
    pub eve_errors: usize,
    /// Lower confidence bound (level 1 − ε_PE) of Eve's error rate.
    pub eve_error_lower: f64,
    /// Smooth min-entropy lower bound (bits).
    pub h_min: f64,
    /// w* of the binomial bound.
    pub w_star: u64,
    /// Secret bits ℓ.
    pub secret_bits: u64,
    /// Why ℓ = 0, when it is.
    pub reason: Option<String>,
}

/// The secrecy of one grid point against one adversary.
#[derive(Clone, Debug, Serialize)]
pub struct PointSecrecy {
    /// The point's parameters, `field = value, …`.
    pub point: String,
    /// The grid point's x value for figures (the first swept field), if numeric.
    pub x: Option<f64>,
    /// The adversary.
    pub adversary: String,
    /// Sessions simulated.
    pub sessions: u32,
    /// Robot steps over those sessions.
    pub steps: u64,
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
    /// Total secret bits over the blocks.
    pub secret_bits: u64,
    /// Secret bits per robot step (over the sessions that filled the blocks).
    pub secret_bits_per_step: f64,
    /// Secret bits per second.
    pub secret_bits_per_second: f64,
    /// Controller and Eve error rates per position along the lap (20 bins).
    pub positions: Vec<PositionErrors>,
}

/// Error rates in one bin of lap position.
#[derive(Clone, Copy, Debug, Serialize)]
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

/// Lap-position bins.
const POSITION_BINS: usize = 20;

/// Sessions of one point against one adversary, added in chunks until the pooled raw key
/// fills the blocks.
fn sessions(
    experiment: &Experiment,
    point: usize,
    adversary: EveStrategy,
    options: &SecrecyOptions,
) -> Result<Vec<RunOutput>, LabError> {
    let mut config = experiment.points[point].config.clone();
    config.eve.enabled = true;
    config.eve.strategy = adversary;
    let plan = SessionPlan::from_config(&config, 0);
    let needed = options.block_bits * options.blocks;
    let mut runs: Vec<RunOutput> = Vec::new();
    let minimum = experiment.replicates();
    let mut learner = matches!(adversary, EveStrategy::Identify | EveStrategy::Transcript)
        .then(|| eavesdropper(&config, adversary, 0));
    while (runs.len() as u32) < options.max_sessions {
        let bits: usize = runs.iter().map(|r| r.keys.controller.len()).sum();
        if bits >= needed && runs.len() as u32 >= minimum {
            break;
        }
        let start = runs.len() as u32;
        let chunk = 32.min(options.max_sessions - start);
        let more: Vec<RunOutput> = match learner.as_mut() {
            None => (start..start + chunk)
                .into_par_iter()
                .map(|replicate| {
                    let mut plan = plan.clone();
                    plan.session = replicate;
                    simulate_plan(&config, plan, replicate, false)
                })
                .collect::<Result<_, _>>()?,
            // What a learning Eve learns carries over: she hears the sessions in order.
            Some(eve) => {
                let heard = (start..start + chunk)
                    .into_par_iter()
                    .map(|replicate| simulate_transcript(&config, replicate))
                    .collect::<Result<Vec<_>, _>>()?;
                heard
                    .into_iter()
                    .zip(start..)
                    .map(|((mut run, transcript), replicate)| {
                        let steps = &mut run.steps;
                        let key = overhear(eve, &config, replicate, &transcript, |_, step, bit| {
                            if let Some(logged) = steps.get_mut(step as usize) {
                                logged.bhat_eve = bit;
                            }
                        });
                        run.keys.eve = Some(key);
                        run
                    })
                    .collect()
            }
        };
        if more.iter().all(|r| r.keys.controller.is_empty()) && runs.is_empty() {
            runs.extend(more);
            break; // nothing is ever accepted here
        }
        runs.extend(more);
    }
    Ok(runs)
}

fn bits(key: &[u8]) -> BitString {
    let bools: zeroize::Zeroizing<Vec<bool>> =
        zeroize::Zeroizing::new(key.iter().map(|&b| b == 1).collect());
    BitString::from_bools(&bools)
}

/// Reconciles, confirms and amplifies one pooled block; `public` supplies the public
/// randomness (Cascade permutations, the Toeplitz seed).
fn block(
    alice: &[u8],
    bob: &[u8],
    eve: &[u8],
    options: &SecrecyOptions,
    public: &mut ChaCha8Rng,
) -> Block {
    let n = alice.len();
    let errors_before = alice.iter().zip(bob).filter(|(a, b)| a != b).count();
    let eve_errors = alice.iter().zip(eve).filter(|(a, b)| a != b).count();
    // Cascade needs an error-rate estimate: the realised rate, floored so that k1 ≤ n.
    let q = (errors_before as f64 / n as f64).clamp(1.0 / n as f64, 0.25);
    let (a, b) = (bits(alice), bits(bob));
    let reconciled = Cascade::biconf(q).and_then(|c| c.reconcile(&a, &b, public));
    let (leak, confirmed) = match &reconciled {
        Ok(r) => (r.leak, r.corrected == a),
        Err(_) => (n as u64, false),
    };
    let eps = options.epsilon;
    let eve_error_lower = clopper_pearson_lower(eve_errors as u64, n as u64, eps)
        .unwrap_or(0.0)
        .min(0.5);
    let entropy = binomial_smooth_min_entropy(n as u64, eve_error_lower, eps).ok();
    let h_min = entropy.as_ref().map_or(0.0, |e| e.h_min);
    let length = output_length(h_min, leak, robokey_secrecy::confirm::TAG_BITS, eps).ok();
    let (mut secret_bits, mut reason) = length
        .map_or((0, Some("the bound could not be evaluated".into())), |l| {
            (l.bits, l.reason)
        });
    if !confirmed {
        secret_bits = 0;
        reason = Some("reconciliation left errors: the confirmation tag discards the block".into());
    } else if secret_bits > 0 {
        // Amplify for real: both sides' outputs must agree.
        let hash = ToeplitzHash::random(n, secret_bits as usize, public);
        let agree = hash.as_ref().ok().and_then(|h| {
            Some(h.hash(&a).ok()? == h.hash(&reconciled.as_ref().ok()?.corrected).ok()?)
        });
        if agree != Some(true) {
            secret_bits = 0;
            reason = Some("Toeplitz outputs differ".into());
        }
    }
    Block {
        bits: n,
        errors_before,
        leak,
        confirmed,
        eve_errors,
        eve_error_lower,
        h_min,
        w_star: entropy.map_or(0, |e| e.w_star),
        secret_bits,
        reason,
    }
}

/// Analyzes one point against one adversary.
fn analyze_point(
    experiment: &Experiment,
    point: usize,
    adversary: EveStrategy,
    options: &SecrecyOptions,
) -> Result<PointSecrecy, LabError> {
    let runs = sessions(experiment, point, adversary, options)?;
    let config = &experiment.points[point].config;
    let lap_steps = (config.trajectory.waypoints.len().saturating_sub(1) as f64
        * config.trajectory.side_time
        / config.robot.sample_time)
        .round()
        .max(1.0) as usize;
    let mut joint = JointCounts::default();
    let mut positions = vec![(0u64, 0u64, 0u64); POSITION_BINS];
    let mut steps = 0u64;
    for run in &runs {
        steps += run.steps.len() as u64;
        for (k, s) in run.steps.iter().enumerate() {
            if let (Some(b), Some(c), Some(a)) = (s.bit, s.bhat, s.bhat_eve) {
                joint.record(b == 1, c == 1, a == 1);
                let bin = (k % lap_steps) * POSITION_BINS / lap_steps;
                positions[bin].0 += 1;
                positions[bin].1 += u64::from(c != b);
                positions[bin].2 += u64::from(a != b);
            }
        }
    }
    let n = joint.total();
    let rate = |f: fn(&JointCounts) -> Result<f64, robokey_secrecy::EntropyError>| {
        f(&joint)
            .ok()
            .and_then(|r| Rate::new((r * n as f64).round() as u64, n))
    };
    let mut rng = stream(config.run.seed, Purpose::Public, point as u64);
    let intervals =
        robokey_secrecy::entropy::bootstrap(&joint, options.bootstrap, 0.95, &mut rng).ok();
    // Pool the keys in session order.
    let (mut alice, mut bob, mut eve) = (
        zeroize::Zeroizing::new(Vec::new()),
        zeroize::Zeroizing::new(Vec::new()),
        zeroize::Zeroizing::new(Vec::new()),
    );
    for run in &runs {
        alice.extend_from_slice(&run.keys.controller);
        bob.extend_from_slice(&run.keys.robot);
        eve.extend_from_slice(run.keys.eve.as_deref().map_or(&[][..], |k| k.as_slice()));
    }
    let raw_bits = alice.len() as u64;
    let eve_wrong = alice.iter().zip(eve.iter()).filter(|(a, b)| a != b).count() as u64;
    let ones = bob.iter().filter(|&&b| b == 1).count() as u64;
    let mut public = ChaCha8Rng::seed_from_u64(config.run.seed ^ (point as u64) << 32);
    let blocks: Vec<Block> = alice
        .chunks_exact(options.block_bits)
        .zip(bob.chunks_exact(options.block_bits))
        .zip(eve.chunks_exact(options.block_bits))
        .take(options.blocks)
        .map(|((a, b), e)| block(a, b, e, options, &mut public))
        .collect();
    // Steps of the sessions whose keys filled the blocks.
    let used_bits = blocks.len() * options.block_bits;
    let mut used_steps = 0u64;
    let mut seen = 0usize;
    for run in &runs {
        if seen >= used_bits {
            break;
        }
        seen += run.keys.controller.len();
        used_steps += run.steps.len() as u64;
    }
    let secret_bits: u64 = blocks.iter().map(|b| b.secret_bits).sum();
    let per_step = if used_steps > 0 {
        secret_bits as f64 / used_steps as f64
    } else {
        0.0
    };
    let params = &experiment.points[point].params;
    Ok(PointSecrecy {
        point: describe(params),
        x: params
            .first()
            .and_then(|(_, v)| v.as_float().or_else(|| v.as_integer().map(|i| i as f64))),
        adversary: adversary.name().to_owned(),
        sessions: runs.len() as u32,
        steps,
        sample_time: config.robot.sample_time,
        p_c: rate(JointCounts::controller_error_rate),
        p_e: rate(JointCounts::eve_error_rate),
        information_advantage: intervals.as_ref().map(|i| {
            [
                i.advantage,
                i.advantage_interval.lower,
                i.advantage_interval.upper,
            ]
        }),
        information_conditional: intervals.as_ref().map(|i| {
            [
                i.conditional,
                i.conditional_interval.lower,
                i.conditional_interval.upper,
            ]
        }),
        raw_bits,
        raw_bits_per_step: if steps > 0 {
            raw_bits as f64 / steps as f64
        } else {
            0.0
        },
        eve_error_accepted: Rate::new(eve_wrong, raw_bits),
        acceptance_independence_p: binomial_test(ones, bob.len() as u64, 0.5).ok(),
        blocks,
        secret_bits,
        secret_bits_per_step: per_step,
        secret_bits_per_second: per_step / config.robot.sample_time,
        positions: positions
            .iter()
            .enumerate()
            .map(|(i, &(bits, c, e))| PositionErrors {
                from: i as f64 / POSITION_BINS as f64,
                bits,
                controller: c as f64 / bits.max(1) as f64,
                eve: e as f64 / bits.max(1) as f64,
            })
            .collect(),
    })
}

/// Analyzes every point of an experiment against every adversary (on the current rayon
/// pool). Deterministic: a pure function of the experiment and the options.
///
/// # Errors
/// A session aborts.
pub fn analyze(
    experiment: &Experiment,
    options: &SecrecyOptions,
) -> Result<Vec<PointSecrecy>, LabError> {
    let jobs: Vec<(usize, EveStrategy)> = (0..experiment.points.len())
        .flat_map(|p| options.adversaries.iter().map(move |&a| (p, a)))
        .collect();
    jobs.iter()
        .map(|&(p, a)| analyze_point(experiment, p, a, options))
        .collect()
}

/// `secrecy.csv`: one row per point and adversary.
#[must_use]
pub fn secrecy_csv(results: &[PointSecrecy]) -> String {
    let mut out = String::from(
        "point,adversary,sessions,steps,p_c,p_c_low,p_c_high,p_e,p_e_low,p_e_high,info_advantage,info_advantage_low,info_advantage_high,info_conditional,raw_bits,raw_bits_per_step,eve_error_accepted,eve_error_accepted_high,acceptance_p,blocks,leak,secret_bits,secret_bits_per_step,secret_bits_per_second,zero_reason\n",
    );
    for r in results {
        let rate = |x: &Option<Rate>| {
            x.map_or(",,".to_owned(), |x| {
                format!("{},{},{}", x.rate, x.low, x.high)
            })
        };
        let info = |x: &Option<[f64; 3]>| {
            x.map_or(",,".to_owned(), |x| format!("{},{},{}", x[0], x[1], x[2]))
        };
        let leak: u64 = r.blocks.iter().map(|b| b.leak).sum();
        let reason = r
            .blocks
            .iter()
            .find_map(|b| b.reason.clone())
            .unwrap_or_else(|| {
                if r.blocks.is_empty() {
                    "not enough raw bits for one block".into()
                } else {
                    String::new()
                }
            });
        out.push_str(&format!(
            "\"{}\",{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},\"{}\"\n",
            r.point,
            r.adversary,
            r.sessions,
            r.steps,
            rate(&r.p_c),
            rate(&r.p_e),
            info(&r.information_advantage),
            r.information_conditional
                .map_or(String::new(), |x| x[0].to_string()),
            r.raw_bits,
            r.raw_bits_per_step,
            r.eve_error_accepted
                .map_or(",".to_owned(), |x| format!("{},{}", x.rate, x.high)),
            r.acceptance_independence_p
                .map_or(String::new(), |p| p.to_string()),
            r.blocks.len(),
            leak,
            r.secret_bits,
            r.secret_bits_per_step,
            r.secret_bits_per_second,
            reason.replace('"', "'"),
        ));
    }
    out
}

/// A markdown section for `report.md`.
#[must_use]
pub fn secrecy_markdown(results: &[PointSecrecy], options: &SecrecyOptions) -> String {
    let mut md = String::from(
        "| point | adversary | p_c % | p_e % | raw bits/step | Eve wrong on accepted % | leak_EC | secret bits/step | why zero |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in results {
        let pct = |x: &Option<Rate>| {
            x.map_or("–".into(), |x| {
                format!(
                    "{:.2} [{:.2}, {:.2}]",
                    100.0 * x.rate,
                    100.0 * x.low,
                    100.0 * x.high
                )
            })
        };
        let leak: u64 = r.blocks.iter().map(|b| b.leak).sum();
        let why = r
            .blocks
            .iter()
            .find_map(|b| b.reason.clone())
            .unwrap_or_else(|| {
                if r.blocks.is_empty() {
                    format!("fewer than {} raw bits", options.block_bits)
                } else {
                    String::new()
                }
            });
        md.push_str(&format!(
            "| {} | {} | {} | {} | {:.4} | {} | {} | {:.5} | {} |\n",
            r.point,
            r.adversary,
            pct(&r.p_c),
            pct(&r.p_e),
            r.raw_bits_per_step,
            pct(&r.eve_error_accepted),
            leak,
            r.secret_bits_per_step,
            why
        ));
    }
    md.push_str(&format!(
        "\nFinite-key bound (SECRECY §5): blocks of {} pooled raw bits, Cascade (biconf) reconciliation with its realised leak, a 64-bit confirmation tag, ε_s = ε_PA = ε_PE = {:e} (the key is {:e}-secret), and Eve's error p taken as the one-sided Clopper–Pearson lower bound at level 1 − ε_PE of her error on the block. p_c, p_e: 95 % Clopper–Pearson intervals over applied bits.\n",
        options.block_bits,
        options.epsilon,
        4.0 * options.epsilon
    ));
    md
}

/// Writes `secrecy.csv`, `secrecy.json`, `secrecy.md` and the figure
/// `secrecy-bits-per-step.{svg,png}` into `dir`; returns the files.
///
/// # Errors
/// A file cannot be written.
pub fn write_secrecy(
    dir: &Path,
    experiment: &Experiment,
    results: &[PointSecrecy],
    options: &SecrecyOptions,
) -> Result<Vec<PathBuf>, LabError> {
    std::fs::create_dir_all(dir).map_err(crate::error::io_at(dir))?;
    let json = serde_json::json!({
        "epsilon": options.epsilon,
        "epsilon_total": 4.0 * options.epsilon,
        "block_bits": options.block_bits,
        "results": results,
    });
    let mut files = vec![
        write(&dir.join("secrecy.csv"), secrecy_csv(results))?,
        write(
            &dir.join("secrecy.json"),
            serde_json::to_string_pretty(&json).expect("JSON serializes") + "\n",
        )?,
        write(&dir.join("secrecy.md"), secrecy_markdown(results, options))?,
    ];
    let axis = experiment
        .axes
        .first()
        .map_or_else(|| "point".to_owned(), |a| a.field.clone());
    let mut series: Vec<Series> = options
        .adversaries
        .iter()
        .map(|&a| {
            let name = a.name();
            Series {
                label: format!("secret bits/step vs {name} Eve"),
                points: results
                    .iter()
                    .filter(|r| r.adversary == name)
                    .filter_map(|r| Some((r.x?, r.secret_bits_per_step)))
                    .collect(),
                style: SeriesStyle::Line,
            }
        })
        .collect();
    if let Some(&first) = options.adversaries.first() {
        let name = first.name();
        series.push(Series {
            label: "raw agreed bits/step".into(),
            points: results
                .iter()
                .filter(|r| r.adversary == name)
                .filter_map(|r| Some((r.x?, r.raw_bits_per_step)))
                .collect(),
            style: SeriesStyle::Dashed,
        });
    }
    if series.iter().any(|s| !s.points.is_empty()) {
        let chart = LineChart {
            title: format!(
                "Secret bits per robot step (ε = {:e}, blocks of {} bits)",
                4.0 * options.epsilon,
                options.block_bits
            ),
            x_label: axis,
            y_label: "bits per step".into(),
            series,
            equal_aspect: false,
            log_y: false,
        };
        let base = dir.join("secrecy-bits-per-step");
        files.extend(chart.save(&base).map_err(|e| LabError::Plot {
            path: base.clone(),
            message: e.to_string(),
        })?);
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn experiment(text: &str) -> Experiment {
        Experiment::from_table("t", text.parse().unwrap(), "test.toml").unwrap()
    }

    #[test]
    fn an_oracle_eve_leaves_zero_secret_bits() {
        let options = SecrecyOptions {
            adversaries: vec![EveStrategy::Oracle],
            block_bits: 2_000,
            bootstrap: 50,
            ..SecrecyOptions::default()
        };
        let results = analyze(&experiment("[run]\nreplicates = 2\n"), &options).unwrap();
        let r = &results[0];
        assert_eq!(r.blocks.len(), 1);
        assert_eq!(r.eve_error_accepted.unwrap().count, 0);
        assert_eq!(r.secret_bits, 0);
        assert!(
            r.blocks[0]
                .reason
                .as_deref()
                .unwrap()
                .contains("no secret bits"),
            "{:?}",
            r.blocks[0].reason
        );
        assert!(r.raw_bits_per_step > 0.25);
    }

    #[test]
    fn acceptance_does_not_depend_on_the_key_bit() {
        let options = SecrecyOptions {
            adversaries: vec![EveStrategy::Mismatch],
            block_bits: 3_000,
            bootstrap: 50,
            ..SecrecyOptions::default()
        };
        let r = &analyze(&experiment("[run]\nreplicates = 2\n"), &options).unwrap()[0];
        // Under independence the p-value is uniform: failing at 1e-3 has probability 1e-3.
        assert!(r.acceptance_independence_p.unwrap() > 1e-3, "{r:?}");
        let p_c = r.p_c.unwrap();
        assert!(
            p_c.low < 0.0431 + 0.01 && p_c.high > 0.0431 - 0.01,
            "{p_c:?}"
        );
    }
}
