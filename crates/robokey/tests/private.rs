//! Private sensing against its model (docs/private-sensing.md): the LLRs are calibrated, the
//! error rates match the linear-Gaussian references on straight segments, what the commands
//! leak is what the residual predicts, and the camera Eve's model-based min-entropy bound
//! holds against her exact joint posterior on short records.

use nalgebra::{DMatrix, DVector, Matrix3};
use robokey::Config;
use robokey::config::EveStrategy;
use robokey::model::{Pose, Unicycle, unicycle_step};
use robokey::private::{BitKind, DoubletBit, PoseObservation};
use robokey::sim::simulate;
use robokey_secrecy::calibration::check_calibration;
use robokey_secrecy::gaussian_llr::{error_rate, information, surprisal};
use robokey_secrecy::view_profile::gaussian_llr_smooth_min_entropy;

mod private_bits;
use private_bits::{bits, private};

/// The posterior probability that the decision from `llr` is wrong, and whether it was.
fn prediction(llr: f64, bit: u8) -> (f64, bool) {
    (1.0 / (1.0 + llr.abs().exp()), (llr < 0.0) != (bit == 1))
}

/// The LLR in favour of the true bit.
fn toward_truth(llr: f64, bit: u8) -> f64 {
    if bit == 0 { llr } else { -llr }
}

/// One party's LLR of a bit.
type Llr = fn(&DoubletBit) -> f64;

fn wrong(bits: &[&DoubletBit], llr: Llr) -> usize {
    bits.iter()
        .filter(|b| (llr(b) < 0.0) != (b.bit == 1))
        .count()
}

/// Seed 2023, 40 sessions, two bits per doublet (≈ 36,000 bits): the controller's, the
/// camera Eve's and the commands Eve's LLRs all pass the calibration test (10 equal-count
/// bins, exact Poisson-binomial tails, family-wise α = 10⁻³) on both kinds of bit.
#[test]
fn every_partys_llr_is_calibrated() {
    let all = bits(&private("[protocol]\nbits_per_doublet = 2\n"), 40);
    for kind in BitKind::ALL {
        let of_kind: Vec<&DoubletBit> = all.iter().filter(|b| b.kind == kind).collect();
        assert!(of_kind.len() > 15_000, "{}", of_kind.len());
        assert_every_party_calibrated(&of_kind, &format!("{kind:?}"));
    }
}

/// The controller's, the camera Eve's and the commands Eve's LLRs of `group` pass the
/// calibration test (10 equal-count bins, exact Poisson-binomial tails, α = 10⁻³).
fn assert_every_party_calibrated(group: &[&DoubletBit], what: &str) {
    let parties: [(&str, Llr); 3] = [
        ("controller", |b| b.controller),
        ("camera", |b| b.camera),
        ("commands", |b| b.llr_of(EveStrategy::Commands)),
    ];
    for (name, llr) in parties {
        let pairs: Vec<(f64, bool)> = group.iter().map(|b| prediction(llr(b), b.bit)).collect();
        let report = check_calibration(&pairs, 10, 1e-3).unwrap();
        assert!(report.passed, "{what} {name}: {report:?}");
    }
}

/// On straight segments (public turn rate < 0.05 rad/s) at the defaults, the error rates
/// match the independent linear-Gaussian estimates — controller 0.78 %, camera Eve 20.5 % —
/// within 4 standard errors of the sample, and the commands Eve is at chance.
#[test]
fn straight_segment_error_rates_match_the_references() {
    let all = bits(&private(""), 40);
    let straight: Vec<&DoubletBit> = all.iter().filter(|b| b.turn_rate < 0.05).collect();
    let n = straight.len() as f64;
    assert!(n > 3_000.0, "{n}");
    let within = |count: usize, p: f64| {
        let se = (p * (1.0 - p) / n).sqrt();
        (count as f64 / n - p).abs() < 4.0 * se
    };
    let controller = wrong(&straight, |b| b.controller);
    let camera = wrong(&straight, |b| b.camera);
    let commands = wrong(&straight, |b| b.llr_of(EveStrategy::Commands));
    assert!(within(controller, 0.0078), "controller {controller} of {n}");
    assert!(within(camera, 0.205), "camera {camera} of {n}");
    assert!(within(commands, 0.5), "commands {commands} of {n}");
    // The model's own prediction Q(d/2) agrees too.
    let predicted = straight
        .iter()
        .map(|b| error_rate(b.camera_separation))
        .sum::<f64>()
        / n;
    assert!(
        within(camera, predicted),
        "camera {camera} of {n} vs {predicted}"
    );
}

/// What the commands leak, binned by the public turn rate: the measured information
/// `1 − E[S]` (its standard error from the sample) contains the model's prediction
/// `mean I(d)`, which grows with the turn; overall it is far below the camera Eve's.
#[test]
fn the_commands_leak_is_the_predicted_residual() {
    let all = bits(&private(""), 40);
    let info = |b: &DoubletBit, llr: f64| 1.0 - surprisal(toward_truth(llr, b.bit));
    let mut predicted_by_bin = Vec::new();
    for (low, high) in [(0.0, 0.1), (0.1, 0.3), (0.3, 0.5)] {
        let bin: Vec<&DoubletBit> = all
            .iter()
            .filter(|b| b.turn_rate >= low && b.turn_rate < high)
            .collect();
        let n = bin.len() as f64;
        assert!(n > 1_000.0, "[{low}, {high}): {n}");
        let values: Vec<f64> = bin
            .iter()
            .map(|b| info(b, b.llr_of(EveStrategy::Commands)))
            .collect();
        let mean = values.iter().sum::<f64>() / n;
        let se = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
        let predicted = bin
            .iter()
            .map(|b| information(b.separation_of(EveStrategy::Commands)))
            .sum::<f64>()
            / n;
        assert!(
            (mean - predicted).abs() < 4.0 * se,
            "[{low}, {high}): measured {mean} ± {se}, predicted {predicted}"
        );
        predicted_by_bin.push(predicted);
    }
    assert!(
        predicted_by_bin.windows(2).all(|w| w[0] < w[1]),
        "{predicted_by_bin:?}"
    );
    let mean_info = |llr: fn(&DoubletBit) -> f64| {
        all.iter().map(|b| info(b, llr(b))).sum::<f64>() / all.len() as f64
    };
    let (commands, camera) = (
        mean_info(|b| b.llr_of(EveStrategy::Commands)),
        mean_info(|b| b.camera),
    );
    assert!(
        commands < camera / 20.0,
        "commands {commands}, camera {camera}"
    );
}

/// Doublets per record of the exact-posterior test: 2¹⁰ bit patterns.
const RECORD: usize = 10;

/// The camera Eve's exact joint posterior over the `levels`ⁿ symbol patterns of a record of
/// n = `labels.len()` consecutive doublets (one dimension, on v), from everything she holds
/// over it: her camera at every step, the controller's boundary samples, the commands.
/// Linear-Gaussian model of the whole record (the means are exactly linear in the v-offsets;
/// the covariance is propagated along the nominal path): no factorisation across doublets.
/// Returns the surprisal (bits) of the true labels `labels`.
fn joint_surprisal(config: &Config, rows: &[robokey::sim::TraceRow], labels: &[usize]) -> f64 {
    let record = labels.len();
    let alphabet = robokey::private::Perturbation::of(config);
    let levels = usize::from(alphabet.levels);
    let t = config.robot.sample_time;
    let steps = 2 * record;
    let q = Matrix3::from_diagonal(&config.noise.process_std.map(|s| s * s).into());
    let start =
        PoseObservation::new(rows[0].measurement.into(), config.sensing.controller_std).fuse(
            &PoseObservation::new(rows[0].camera.unwrap().into(), config.eve.camera_std),
        );
    let nominal: Vec<Unicycle> = rows[..steps]
        .iter()
        .map(|r| r.nominal.unwrap().into())
        .collect();
    let delta = config.protocol.delta_v;
    // Means for the all-zero offsets and each bit's unit effect.
    let path = |offsets: &dyn Fn(usize) -> f64| {
        let mut poses = vec![start.value];
        for k in 0..steps {
            let u = nominal[k] + Unicycle::new(offsets(k), 0.0);
            poses.push(unicycle_step(&poses[k], &u, t));
        }
        poses
    };
    let base = path(&|_| 0.0);
    let effect: Vec<Vec<Pose>> = (0..record)
        .map(|j| {
            let shifted = path(&|k| match k {
                _ if k == 2 * j => delta,
                _ if k == 2 * j + 1 => -delta,
                _ => 0.0,
            });
            shifted.iter().zip(&base).map(|(a, b)| a - b).collect()
        })
        .collect();
    // Error sensitivities: x_k − m_k = T_k·z, z = [x₀ − m₀; w₀; …; w_{2n−1}].
    let dim = 3 * (steps + 1);
    let mut sens = vec![DMatrix::<f64>::zeros(3, dim)];
    sens[0]
        .view_mut((0, 0), (3, 3))
        .copy_from(&Matrix3::identity());
    for k in 0..steps {
        let (sin, cos) = base[k].z.sin_cos();
        let v = nominal[k].x;
        let a = Matrix3::new(1.0, 0.0, -t * v * sin, 0.0, 1.0, t * v * cos, 0.0, 0.0, 1.0);
        let mut next = DMatrix::from_fn(3, dim, |r, c| {
            (0..3).map(|i| a[(r, i)] * sens[k][(i, c)]).sum()
        });
        for i in 0..3 {
            next[(i, 3 * (k + 1) + i)] += 1.0;
        }
        sens.push(next);
    }
    let mut z_cov = DMatrix::<f64>::zeros(dim, dim);
    z_cov.view_mut((0, 0), (3, 3)).copy_from(&start.covariance);
    for k in 0..steps {
        z_cov
            .view_mut((3 * (k + 1), 3 * (k + 1)), (3, 3))
            .copy_from(&q);
    }
    // Observations: the camera at steps 1..=2n, the controller's samples at the boundaries.
    let mut observed: Vec<(usize, Pose, [f64; 3])> = (1..=steps)
        .map(|k| (k, rows[k].camera.unwrap().into(), config.eve.camera_std))
        .collect();
    observed.extend((1..=record).map(|j| {
        (
            2 * j,
            rows[2 * j].measurement.into(),
            config.sensing.controller_std,
        )
    }));
    let m = 3 * observed.len();
    let mut h = DMatrix::<f64>::zeros(m, dim);
    let mut noise = DMatrix::<f64>::zeros(m, m);
    let mut residual = DVector::<f64>::zeros(m);
    let mut g = DMatrix::<f64>::zeros(m, record);
    for (row, (k, y, std)) in observed.iter().enumerate() {
        h.view_mut((3 * row, 0), (3, dim)).copy_from(&sens[*k]);
        for i in 0..3 {
            noise[(3 * row + i, 3 * row + i)] = std[i] * std[i];
            residual[3 * row + i] = y[i] - base[*k][i];
            for j in 0..record {
                g[(3 * row + i, j)] = effect[j][*k][i];
            }
        }
    }
    let cov = &h * z_cov * h.transpose() + noise;
    let chol = cov.cholesky().expect("positive definite");
    let field = g.transpose() * chol.solve(&residual);
    let coupling = g.transpose() * chol.solve(&g);
    // ln p(y | s) = const + sᵀ·field − ½·sᵀ·coupling·s, s_j the amplitude of doublet j's
    // label (±1 binary); pattern p holds label j as its j-th base-`levels` digit.
    let amplitudes = |pattern: usize| {
        DVector::from_fn(record, |j, _| {
            alphabet.amplitude(pattern / levels.pow(j as u32) % levels)
        })
    };
    let ln_p: Vec<f64> = (0..levels.pow(record as u32))
        .map(|p| {
            let s = amplitudes(p);
            s.dot(&field) - 0.5 * s.dot(&(&coupling * &s))
        })
        .collect();
    let max = ln_p.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let ln_total = max + ln_p.iter().map(|v| (v - max).exp()).sum::<f64>().ln();
    let truth = labels
        .iter()
        .rev()
        .fold(0, |acc, &label| acc * levels + label);
    (ln_total - ln_p[truth]) / std::f64::consts::LN_2
}

/// The bound that sizes the key — n independent views of the largest separation — against
/// the camera Eve's exact joint posterior on records of 10 doublets (seed 2023, every
/// all-carrying record of 80 sessions): at ε = 0.05 the bound may not exceed the empirical
/// ε-quantile of her exact surprisal, taken at its lower 3σ order statistic.
#[test]
fn the_model_bound_holds_against_the_exact_joint_posterior() {
    let config = private("");
    let (mut joint, mut factorised, mut largest) = (Vec::new(), Vec::new(), 0.0_f64);
    for replicate in 0..80 {
        let run = simulate(&config, replicate, true).unwrap();
        let private = run.private.unwrap();
        let by_step: std::collections::HashMap<u32, &DoubletBit> =
            private.bits.iter().map(|b| (b.step, b)).collect();
        let mut k = 0;
        while k + 2 * RECORD < run.trace.len() {
            let record: Vec<&DoubletBit> = (0..RECORD)
                .filter_map(|j| by_step.get(&((k + 2 * j) as u32)).copied())
                .collect();
            if record.len() == RECORD {
                let labels: Vec<usize> = record.iter().map(|b| usize::from(b.bit)).collect();
                joint.push(joint_surprisal(
                    &config,
                    &run.trace[k..=k + 2 * RECORD],
                    &labels,
                ));
                factorised.push(
                    record
                        .iter()
                        .map(|b| surprisal(toward_truth(b.camera, b.bit)))
                        .sum::<f64>(),
                );
                largest = record
                    .iter()
                    .fold(largest, |m, b| m.max(b.assumed_separation));
            }
            k += 2 * RECORD;
        }
    }
    let count = joint.len();
    assert!(count > 1_000, "{count}");
    let epsilon = 0.05;
    let bound = gaussian_llr_smooth_min_entropy(RECORD as u64, largest, epsilon)
        .unwrap()
        .h_min;
    joint.sort_by(f64::total_cmp);
    let m = count as f64;
    let low = (m * epsilon - 3.0 * (m * epsilon * (1.0 - epsilon)).sqrt()).floor() as usize;
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    println!(
        "{count} records: bound {bound:.3} bits; exact joint surprisal quantile {:.3} \
         (lower order statistic {:.3}); mean joint {:.3}, mean factorised {:.3}",
        joint[(m * epsilon) as usize],
        joint[low],
        mean(&joint),
        mean(&factorised)
    );
    assert!(bound <= joint[low], "{bound} > {}", joint[low]);
}

/// Four levels per dimension (seed 2023, 20 sessions, two dimensions, ≈ 36,000 bits): the
/// controller's LLRs given the lower slice (multistage), the camera and commands Eve's given
/// the bits before (her chain, whose sum is her surprisal of the symbols) pass the
/// calibration test on each kind and place of bit.
#[test]
fn multilevel_llrs_are_calibrated() {
    let all = bits(
        &private("[protocol]\nbits_per_doublet = 2\nlevels = 4\n"),
        20,
    );
    for kind in BitKind::ALL {
        for place in 0..2 {
            // Four bits per doublet: v's label then ω's, lowest place first.
            let group: Vec<&DoubletBit> = all
                .iter()
                .enumerate()
                .filter(|(i, b)| b.kind == kind && i % 2 == place)
                .map(|(_, b)| b)
                .collect();
            assert!(group.len() > 5_000, "{}", group.len());
            assert_every_party_calibrated(&group, &format!("{kind:?} place {place}"));
        }
    }
}

/// Four levels on v (seed 2023, every all-carrying record of 5 doublets, 4⁵ symbol patterns,
/// of 25 sessions): the key's sizing — the bits' assumed separations folded into one
/// equivalent separation, as a block's is — may not exceed the empirical ε-quantile of the
/// camera Eve's exact surprisal of the symbols (ε = 0.05, at its lower 3σ order statistic).
#[test]
fn the_multilevel_bound_holds_against_the_exact_joint_posterior() {
    use robokey_secrecy::view_profile::{equivalent_separation, separation_counts};
    const SYMBOLS: usize = 5;
    let config = private("[protocol]\nlevels = 4\n");
    let epsilon = 0.05;
    let (mut joint, mut bounds) = (Vec::new(), Vec::new());
    for replicate in 0..25 {
        let run = simulate(&config, replicate, true).unwrap();
        let private = run.private.unwrap();
        let mut by_step: std::collections::HashMap<u32, Vec<&DoubletBit>> =
            std::collections::HashMap::new();
        for b in &private.bits {
            by_step.entry(b.step).or_default().push(b);
        }
        let mut k = 0;
        while k + 2 * SYMBOLS < run.trace.len() {
            let record: Vec<&Vec<&DoubletBit>> = (0..SYMBOLS)
                .filter_map(|j| by_step.get(&((k + 2 * j) as u32)))
                .collect();
            if record.len() == SYMBOLS {
                let labels: Vec<usize> = record
                    .iter()
                    .map(|bits| usize::from(bits[0].bit) | usize::from(bits[1].bit) << 1)
                    .collect();
                joint.push(joint_surprisal(
                    &config,
                    &run.trace[k..=k + 2 * SYMBOLS],
                    &labels,
                ));
                let separations: Vec<f64> = record
                    .iter()
                    .flat_map(|bits| bits.iter().map(|b| b.assumed_separation))
                    .collect();
                let counts = separation_counts(&separations, separations.len());
                let micros = equivalent_separation(&counts, 0, epsilon).unwrap();
                bounds.push(
                    gaussian_llr_smooth_min_entropy(
                        separations.len() as u64,
                        micros as f64 * 1e-6,
                        epsilon,
                    )
                    .unwrap()
                    .h_min,
                );
            }
            k += 2 * SYMBOLS;
        }
    }
    let count = joint.len();
    assert!(count > 1_000, "{count}");
    let bound = bounds.iter().copied().fold(0.0_f64, f64::max);
    joint.sort_by(f64::total_cmp);
    let m = count as f64;
    let low = (m * epsilon - 3.0 * (m * epsilon * (1.0 - epsilon)).sqrt()).floor() as usize;
    println!(
        "{count} records: largest bound {bound:.3} bits; exact joint surprisal quantile {:.3} \
         (lower order statistic {:.3})",
        joint[(m * epsilon) as usize],
        joint[low]
    );
    assert!(bound <= joint[low], "{bound} > {}", joint[low]);
}

/// SHA-256 (first 8 bytes, hex) of everything `replicates` private runs of `config` produce:
/// every trace row, step log, key, metric and bit record, reals as their exact `Debug` text.
fn private_fingerprint(config: &Config, replicates: u32) -> String {
    use sha2::{Digest, Sha256};
    let mut hash = Sha256::new();
    for replicate in 0..replicates {
        let out = simulate(config, replicate, true).unwrap();
        hash.update(format!(
            "{:?}{:?}{:?}{:?}{:?}{:?}{:?}{:?}",
            out.trace,
            out.steps,
            // The bits themselves: a key's `Debug` prints only its length.
            *out.keys.robot,
            *out.keys.controller,
            out.keys.eve.as_deref(),
            out.metrics,
            out.private,
            out.trace.len()
        ));
    }
    hash.finalize()[..8]
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Private runs keep every number they produce (pinned before the simulator was rewritten
/// to drive the private-mode endpoints, so that agents and simulator share one
/// implementation; re-pinned once, unchanged otherwise, when the keys' bits entered the hash,
/// which had seen only their redacted `Debug` text; each bit's record held the commands
/// check's boundary residual and its modelled part for a while, which the check now
/// recomputes from the controller's kept samples, and the pins are again those from before
/// those two fields; re-pinned when the commands eavesdropper's LLR and separation became
/// optional — the same numbers, their `Debug` text now `Some(…)`: with those wrappers taken
/// out of the hashed text the runs gave the previous pins): one and two bits per doublet, protocol off, no eavesdropper, the
/// commands eavesdropper, every doublet gated, and an odd number of steps (a lone last step).
#[test]
fn pinned_private_runs_keep_every_number() {
    let configs = [
        ("default", ""),
        ("two bits", "[protocol]\nbits_per_doublet = 2\n"),
        ("off", "[protocol]\nenabled = false\n"),
        ("no eve", "[eve]\nenabled = false\n"),
        ("commands", "[eve]\nstrategy = \"commands\"\n"),
        ("all gated", "[protocol]\nmax_turn_rate = 0.0\n"),
        ("odd", "[trajectory]\nside_time = 17.05\nlaps = 1\n"),
    ];
    let got: Vec<String> = configs
        .iter()
        .map(|(name, extra)| format!("{name} {}", private_fingerprint(&private(extra), 2)))
        .collect();
    assert_eq!(got.join("\n"), PINNED_PRIVATE.trim());
}

const PINNED_PRIVATE: &str = "
default 579a6a48d8b36f4c
two bits bcfd92a423364b52
off 7f11f24176836d41
no eve a203bdc078f49a5b
commands 61eacc646218dcdc
all gated 5b02859dca978155
odd 35be065f9be80498
";
