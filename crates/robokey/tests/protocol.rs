//! End-to-end protocol properties: the endpoints on the virtual network, with chosen
//! messages dropped, on a noise-free plant; and whole simulated runs.

use robokey::Config;
use robokey::protocol::{Message, Outcome, SessionMessage};
use robokey::sim::simulate;
use support::{Network, session};

mod support;

/// Runs one session on an ideal link, dropping the messages `drop` picks.
fn lockstep(config: &Config, drop: impl Fn(&Message) -> bool) -> support::Session {
    session(config, Network::default(), |_, m| drop(m), |_| false)
}

/// A short, noise-free session with a large Δ: every clean codeword must be accepted.
fn clean_config() -> Config {
    let mut config = Config::default();
    config.noise.process_std = [0.0; 3];
    config.noise.measurement_std = [0.0; 3];
    config.protocol.delta_v = 0.05;
    config.trajectory.laps = 1;
    config
}

#[test]
fn large_delta_without_noise_accepts_everything_and_confirms() {
    let config = clean_config();
    let session = lockstep(&config, |_| false);
    assert_eq!(session.fates.len(), 340 / 3);
    assert!(session.fates.iter().all(|&a| a));
    assert_eq!(session.robot_key.len(), 340 / 3);
    assert_eq!(session.robot_key, session.controller_key);
    assert_eq!(session.robot_outcome, Some(Outcome::Confirmed));
    assert_eq!(session.controller_outcome, Some(Outcome::Confirmed));
}

#[test]
fn a_lost_command_erases_exactly_its_codeword_on_both_sides() {
    let config = clean_config();
    // Command 31 is step 31 = codeword 10, position 1.
    let session = lockstep(&config, |m| {
        matches!(
            m,
            Message::Session(SessionMessage::Command { step: 31, .. })
        )
    });
    let rejected: Vec<usize> = (0..session.fates.len())
        .filter(|&i| !session.fates[i])
        .collect();
    assert_eq!(rejected, vec![10]);
    assert_eq!(session.robot_key.len(), 340 / 3 - 1);
    assert_eq!(session.robot_key, session.controller_key);
    assert_eq!(session.controller_outcome, Some(Outcome::Confirmed));
}

#[test]
fn a_lost_measurement_erases_exactly_its_codeword_on_both_sides() {
    let config = clean_config();
    // y(46) decides step 45 = codeword 15, position 0; command 46 is never sent, so
    // step 46 (same codeword) is erased as well.
    let session = lockstep(&config, |m| {
        matches!(
            m,
            Message::Session(SessionMessage::Measurement { step: 46, .. })
        )
    });
    let rejected: Vec<usize> = (0..session.fates.len())
        .filter(|&i| !session.fates[i])
        .collect();
    assert_eq!(rejected, vec![15]);
    assert_eq!(session.robot_key, session.controller_key);
    assert_eq!(session.robot_outcome, Some(Outcome::Confirmed));
}

#[test]
fn a_tiny_delta_makes_bits_coin_flips() {
    // With Δv = 1e-5 m/s the noise swamps the bit: the error rate is 50 % within a
    // binomial interval. 20 runs × 1020 bits, per-run errors are independent across runs;
    // bound at 4.5 standard errors of a fair coin.
    let mut config = Config::default();
    config.protocol.delta_v = 1e-5;
    let runs = 20;
    let mut wrong = 0.0;
    let mut bits = 0.0;
    for replicate in 0..runs {
        let m = simulate(&config, replicate, false).unwrap().metrics;
        wrong += m.ber_controller.unwrap() * 1020.0;
        bits += 1020.0;
    }
    let rate = wrong / bits;
    let se = (0.25 / bits).sqrt();
    assert!(
        (rate - 0.5).abs() < 4.5 * se,
        "bit error rate {rate} (se {se})"
    );
}

#[test]
fn keys_stay_aligned_through_rejections() {
    // Defaults reject ≈ 12 % of codewords; the keys must still line up position by
    // position. Wrong accepted bits are rare (≈ 0.03 per run, docs/experiments.md), so over 20 runs
    // the count is ≈ Poisson(0.6) and P(> 8) < 1e-8; a shift would mismatch ≈ 50 %.
    let config = Config::default();
    let mut differing = 0;
    let mut total = 0;
    for replicate in 0..20 {
        let m = simulate(&config, replicate, false).unwrap().metrics;
        assert!(
            m.accepted.unwrap() < m.codewords_sent.unwrap(),
            "some rejections"
        );
        let accepted = m.accepted.unwrap() as usize;
        differing += ((100.0 - m.correct_pct.unwrap()) / 100.0 * accepted as f64).round() as usize;
        total += accepted;
    }
    assert!(differing <= 8, "{differing} wrong positions of {total}");
}

#[test]
fn protocol_off_defines_only_the_tracking_error() {
    let mut config = Config::default();
    config.protocol.enabled = false;
    let m = simulate(&config, 0, false).unwrap().metrics;
    assert!(m.jx > 0.0);
    assert_eq!(
        robokey::Metrics {
            jx: m.jx,
            ..Default::default()
        },
        m
    );
}

#[test]
fn same_seed_same_run_and_replicates_differ() {
    let config = Config::default();
    let a = simulate(&config, 3, true).unwrap();
    let b = simulate(&config, 3, true).unwrap();
    assert_eq!(a.metrics, b.metrics);
    assert_eq!(a.trace, b.trace);
    assert_ne!(a.metrics, simulate(&config, 4, false).unwrap().metrics);
}

#[test]
fn the_oracle_eve_decides_exactly_as_the_controller() {
    let mut config = Config::default();
    config.eve.strategy = Some(robokey::config::EveStrategy::Oracle);
    for replicate in 0..5 {
        let run = simulate(&config, replicate, false).unwrap();
        assert!(
            run.steps
                .iter()
                .all(|s| s.bhat == s.bhat_eve && s.bhat.is_some())
        );
        assert_eq!(
            run.keys.eve.as_ref().map(|k| k.as_slice()),
            Some(run.keys.controller.as_slice())
        );
        assert_eq!(run.metrics.eve_disagreement_pct, Some(0.0));
    }
}
