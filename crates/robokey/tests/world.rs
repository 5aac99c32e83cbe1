//! The world apart from the configuration (docs/world.md): no `[world]` and the `ideal`
//! world run number for number; in worlds that are not the parties', the eavesdroppers who
//! know the world stay calibrated, their window smoother converges in its width, and they
//! never decide better than their view of each bit with the rest of the block known.

use robokey::Config;
use robokey::config::EveStrategy;
use robokey::private::DoubletBit;
use robokey::sim::simulate;
use robokey_secrecy::calibration::check_calibration;
use robokey_secrecy::gaussian_llr::surprisal;

mod private_bits;
use private_bits::{bits, private};

/// The information `1 − S` a bit's LLR gives about its true value (bits).
fn information(llr: f64, bit: u8) -> f64 {
    1.0 - surprisal(if bit == 0 { llr } else { -llr })
}

/// `--world ideal` is no `[world]`: every number of whole runs, in both sensing modes.
#[test]
fn the_ideal_world_is_no_world_number_for_number() {
    for mode in ["odometry", "private"] {
        let plain = Config::from_toml(&format!("[sensing]\nmode = \"{mode}\"\n"), "t").unwrap();
        let ideal = Config::from_toml(
            &format!("[sensing]\nmode = \"{mode}\"\n[world]\npreset = \"ideal\"\n"),
            "t",
        )
        .unwrap();
        assert_eq!(ideal.to_toml(), plain.to_toml());
        for replicate in 0..2 {
            let a = simulate(&plain, replicate, true).unwrap();
            let b = simulate(&ideal, replicate, true).unwrap();
            assert_eq!(format!("{a:?}"), format!("{b:?}"), "{mode} {replicate}");
            assert_eq!(
                (a.keys.robot.as_slice(), a.keys.controller.as_slice()),
                (b.keys.robot.as_slice(), b.keys.controller.as_slice())
            );
        }
    }
}

/// An eavesdropper's log-likelihood ratio of a bit.
type Llr = fn(&DoubletBit) -> f64;

/// The `camera` and `commands` eavesdroppers' LLRs of `bits` pass the calibration test (10
/// equal-count bins, exact Poisson-binomial tails, α = 10⁻³ each); `what` names the case.
fn assert_both_calibrated<'a>(bits: impl IntoIterator<Item = &'a DoubletBit> + Clone, what: &str) {
    let adversaries: [(&str, Llr); 2] = [
        ("camera", |b| b.camera),
        ("commands", |b| b.llr_of(EveStrategy::Commands)),
    ];
    for (name, llr) in adversaries {
        let pairs: Vec<(f64, bool)> = bits
            .clone()
            .into_iter()
            .map(|b| {
                let l = llr(b);
                (1.0 / (1.0 + l.abs().exp()), (l < 0.0) != (b.bit == 1))
            })
            .collect();
        let report = check_calibration(&pairs, 10, 1e-3).unwrap();
        assert!(report.passed, "{what} {name}: {report:?}");
    }
}

/// Worlds unlike the parties' — lag, AR(1) noise, slip, delay, a camera between the
/// instants, the Khepera IV preset (continuous motion, jitter, quanta, lag, delay, slip), and
/// motion noise below the controller's sensor noise (the boundary samples' reach):
/// the `camera` and `commands` eavesdroppers' LLRs pass the calibration test (10 equal-count
/// bins, exact Poisson-binomial tails, α = 10⁻³ each), seed 2023, 12 sessions (≈ 5,000 bits)
/// per world.
#[test]
fn the_eavesdroppers_stay_calibrated_in_other_worlds() {
    let worlds = [
        "lag = 0.05\nprocess_std = [0.001, 0.001, 0.001]\n",
        "process_rho = 0.9\n",
        "slip_std = 0.05\nprocess_std = [0.002, 0.002, 0.002]\n",
        "delay = 0.02\n",
        "camera_fps = 30.0\ncamera_frame_std = [0.016, 0.016, 0.016]\n",
        "preset = \"khepera-iv\"\n",
        "process_std = [0.00015, 0.00015, 0.00015]\n",
    ];
    for world in worlds {
        let all = bits(&private(&format!("[world]\n{world}")), 12);
        assert!(all.len() > 4_500, "{world}: {}", all.len());
        assert_both_calibrated(all.iter(), world);
    }
}

/// With the prior equal to the world's lag (50 and 100 ms) and the parties' own 4 mm of
/// motion noise, the controller's LLRs pass the calibration test (10 equal-count bins, exact
/// Poisson-binomial tails, α = 10⁻³), seed 2023, 12 sessions per lag: its likelihood takes
/// the nominal inputs through the prior lag as well as the bit's offsets.
#[test]
fn the_controller_stays_calibrated_under_a_known_lag() {
    for lag in ["0.05", "0.1"] {
        let config = private(&format!(
            "[private]\nprior_lag = {lag}\n[world]\nlag = {lag}\n"
        ));
        let all = bits(&config, 12);
        assert!(all.len() > 3_000, "lag {lag}: {}", all.len());
        let pairs: Vec<(f64, bool)> = all
            .iter()
            .map(|b| {
                let l = b.controller;
                (1.0 / (1.0 + l.abs().exp()), (l < 0.0) != (b.bit == 1))
            })
            .collect();
        let report = check_calibration(&pairs, 10, 1e-3).unwrap();
        assert!(report.passed, "lag {lag}: {report:?}");
    }
}

/// The mean over `bits` of `info(b)` and its standard error.
fn mean_and_error(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// The camera eavesdropper's information per bit from `a` less from `b`, paired over the
/// same bits: its mean and standard error.
fn paired_gain(a: &[DoubletBit], b: &[DoubletBit]) -> (f64, f64) {
    assert_eq!(a.len(), b.len());
    let d: Vec<f64> = a
        .iter()
        .zip(b)
        .map(|(x, y)| {
            assert_eq!((x.step, x.bit), (y.step, y.bit));
            information(x.camera, x.bit) - information(y.camera, y.bit)
        })
        .collect();
    mean_and_error(&d)
}

/// The window smoother converges in its width. With a 50 ms lag (1 mm motion noise) a bit
/// shows at the next doublet's boundary too: two doublets each side give the camera
/// eavesdropper what three give (paired over the same bits, within 3 standard errors and
/// 0.003 bit), and clearly more than the doublet alone. In the parties' world the window
/// adds nothing to the per-doublet view.
#[test]
fn the_window_smoother_converges_in_its_width() {
    let lag = "[world]\nlag = 0.05\nprocess_std = [0.001, 0.001, 0.001]\n";
    let at = |extra: &str, width: u32| {
        bits(
            &private(&format!("[eve]\nsmoother_window = {width}\n{extra}")),
            10,
        )
    };
    let (w0, w2, w3) = (at(lag, 0), at(lag, 2), at(lag, 3));
    let (gain, se) = paired_gain(&w3, &w2);
    assert!(
        gain.abs() < 3.0 * se + 1e-9 && gain.abs() < 0.003,
        "W 3 − 2: {gain} ± {se}"
    );
    let (gain, se) = paired_gain(&w2, &w0);
    assert!(gain > 0.1 && gain > 10.0 * se, "W 2 − 0: {gain} ± {se}");
    let alone = bits(&private(""), 10);
    let window = at("", 2);
    let (gain, se) = paired_gain(&window, &alone);
    assert!(
        gain.abs() < 3.0 * se + 1e-9 && gain.abs() < 0.003,
        "ideal: {gain} ± {se}"
    );
}

/// With motion noise well below the controller's sensor noise (0.15 mm against 0.5 mm) a
/// doublet's own boundary samples no longer screen it: the neighbours' samples pin its
/// boundaries and reveal the turn residual. Her information grows with the exact window's
/// width W = 0 → 4 and converges: the default view (W = 2 and the boundary samples of
/// `WorldModel::sample_reach` doublets beyond) gives what W = 4 gives, and no less (paired
/// over the same bits, within 3 standard errors and 0.003 bit). Just above the screening line
/// (√2·σ_w ≥ σ_c: 0.36 mm) the per-doublet view misses less than 0.003 bit per bit.
#[test]
fn below_the_sensor_noise_the_neighbours_samples_are_used_and_converge() {
    let world = |sigma: f64| format!("[world]\nprocess_std = [{sigma}, {sigma}, {sigma}]\n");
    let at = |sigma: f64, width: Option<u32>| {
        let eve = width.map_or(String::new(), |w| format!("[eve]\nsmoother_window = {w}\n"));
        bits(&private(&format!("{eve}{}", world(sigma))), 10)
    };
    let low = 0.000_15;
    let (w0, w2, w4, default) = (
        at(low, Some(0)),
        at(low, Some(2)),
        at(low, Some(4)),
        at(low, None),
    );
    let (gain, se) = paired_gain(&w4, &w0);
    assert!(gain > 0.002 && gain > 3.0 * se, "W 4 − 0: {gain} ± {se}");
    let (gain, se) = paired_gain(&w4, &w2);
    assert!(gain > -se && gain < 0.003, "W 4 − 2: {gain} ± {se}");
    let (gain, se) = paired_gain(&default, &w4);
    assert!(
        gain > -3.0 * se - 1e-9 && gain.abs() < 0.003,
        "default − W 4: {gain} ± {se}"
    );
    let line = 0.000_36;
    let (gain, se) = paired_gain(&at(line, Some(4)), &at(line, None));
    assert!(
        gain.abs() < 0.003,
        "at the screening line, W 4 − alone: {gain} ± {se}"
    );
}

/// Under a 50 ms lag (1 mm motion noise) the two-step doublet's boundary residual, which
/// the next commands reveal, carries the v-bit along the heading, `τΔv(1 − e^(−T/τ))²` ≈
/// 1.686 mm per bit sign on straight doublets; the three-step doublet shaped with the same
/// prior (`private.prior_lag`) leaves none beyond the model's prediction. Both regressions of
/// `s·(r − μ)` on straight v-bits within 4 standard errors (from the bits' own spread) of
/// their theory: 1.686 mm and 0.
#[test]
fn the_three_step_doublet_hides_the_bit_from_the_commands_under_a_known_lag() {
    use robokey::estimate::commands_check::block_residuals;
    use robokey::private::doublet::sign;
    use robokey::private::{BitKind, DoubletSamples};
    let world = "[world]\nlag = 0.05\nprocess_std = [0.001, 0.001, 0.001]\n";
    let along = |config: &Config| {
        let runs: Vec<_> = (0..3)
            .map(|r| simulate(config, r, false).unwrap())
            .collect();
        let sessions: Vec<&[DoubletSamples]> = runs
            .iter()
            .map(|run| run.private.as_ref().unwrap().controller_samples.as_slice())
            .collect();
        let x: Vec<f64> = block_residuals(config, &sessions)
            .iter()
            .filter(|b| b.kind == BitKind::V && b.turn_rate < 0.05)
            .map(|b| sign(b.bit) * (b.revealed[0] - b.modelled[0]))
            .collect();
        assert!(x.len() > 300, "{} straight bits", x.len());
        mean_and_error(&x)
    };
    let (tau, t, delta_v) = (0.05_f64, 0.2, 0.035);
    let theory = tau * delta_v * (1.0 - (-t / tau).exp()).powi(2);
    let (two, two_error) = along(&private(world));
    assert!(
        (two - theory).abs() < 4.0 * two_error,
        "two steps: {two} ± {two_error} m, theory {theory}"
    );
    let shaped = private(&format!("[private]\nprior_lag = 0.05\n{world}"));
    let (three, three_error) = along(&shaped);
    assert!(
        three.abs() < 4.0 * three_error && three_error < 0.1 * theory,
        "three steps: {three} ± {three_error} m"
    );
}

/// Four levels on two dimensions (4 key bits per doublet, natural labeling) in a correlated
/// (ρ = 0.9) and a lagged world (50 ms, 1 mm of motion noise), seed 2023, 6 sessions each
/// (≈ 2,300 bits per place of bit): the window smoother's LLR of each bit given the true
/// bits before it in its doublet and the other doublets' (the chain whose sum is her
/// surprisal of the symbols, her realised bound) passes the calibration test (10
/// equal-count bins, exact Poisson-binomial tails, α = 10⁻³) for each place of bit and both
/// eavesdroppers; and her own decisions, the other symbols unknown, err no less often than
/// that view predicts: `errors ≥ Σ p_i − 3·√(Σ p_i(1 − p_i))`, `p_i = 1/(1 + e^{|L_i|})`.
#[test]
fn the_window_smoother_judges_multilevel_symbols() {
    let worlds = [
        "process_rho = 0.9\n",
        "lag = 0.05\nprocess_std = [0.001, 0.001, 0.001]\n",
    ];
    for world in worlds {
        let config = private(&format!(
            "[protocol]\nbits_per_doublet = 2\nlevels = 4\n[world]\n{world}"
        ));
        let runs: Vec<_> = (0..6)
            .map(|r| simulate(&config, r, false).unwrap())
            .collect();
        let all: Vec<&DoubletBit> = runs
            .iter()
            .flat_map(|run| &run.private.as_ref().unwrap().bits)
            .collect();
        for place in 0..4 {
            let group: Vec<&DoubletBit> = all
                .iter()
                .enumerate()
                .filter(|(i, _)| i % 4 == place)
                .map(|(_, b)| *b)
                .collect();
            assert!(group.len() > 2_000, "{world}: {}", group.len());
            assert_both_calibrated(group, &format!("{world} place {place}"));
        }
        let (mut errors, mut bits) = (0_usize, 0_usize);
        for run in &runs {
            let private = run.private.as_ref().unwrap();
            let eve = private.camera_key.as_ref().unwrap();
            let robot = &run.keys.robot;
            assert_eq!(eve.len(), robot.len(), "{world}");
            errors += eve.iter().zip(robot.iter()).filter(|(e, r)| e != r).count();
            bits += robot.len();
        }
        let p: Vec<f64> = all
            .iter()
            .map(|b| 1.0 / (1.0 + b.camera.abs().exp()))
            .collect();
        let expected: f64 = p.iter().sum::<f64>() * bits as f64 / p.len() as f64;
        let spread = p.iter().map(|p| p * (1.0 - p)).sum::<f64>().sqrt();
        println!(
            "{}: her own errors {errors} of {bits}; her view given the others predicts \
             {expected:.0} of them",
            world.replace('\n', " ")
        );
        assert!(
            errors as f64 >= expected - 3.0 * spread,
            "{world}: {errors} errors, given the others {expected:.0} ± {spread:.0}"
        );
    }
}
