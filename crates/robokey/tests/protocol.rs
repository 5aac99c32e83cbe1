//! End-to-end protocol properties: the endpoints driven in lockstep over an in-memory
//! channel that can drop chosen messages, on a noise-free plant.

use robokey::Config;
use robokey::model::{Pose, unicycle_step};
use robokey::protocol::{
    ControllerEndpoint, ControllerEvent, ControllerInput, ControllerOutput, Message, Outcome,
    RobotEndpoint, RobotInput, RobotOutput, SessionMessage, SessionPlan,
};
use robokey::rng::{Purpose, stream};
use robokey::sim::simulate;
use support::post_fragment;

mod support;

/// Result of a lockstep session.
struct Session {
    robot_key: Vec<u8>,
    controller_key: Vec<u8>,
    controller_fates: Vec<bool>,
    robot_outcome: Option<Outcome>,
    controller_outcome: Option<Outcome>,
}

/// Runs one session; `drop(message)` removes a message from the channel. Commands that
/// do not arrive trigger the robot's deadline.
/// Every delivered message follows a post-processing fragment, which session endpoints must
/// ignore: the tests' exact outcomes show that it changed nothing.
fn lockstep(config: &Config, drop: impl Fn(&Message) -> bool) -> Session {
    let plan = SessionPlan::from_config(config, 1);
    let drive = plan.drive;
    let steps = plan.steps;
    let mut robot = RobotEndpoint::new(plan.clone(), &mut stream(9, Purpose::Key, 0));
    let mut controller = ControllerEndpoint::new(config, plan);
    let mut pose = Pose::zeros();
    let mut fates = Vec::new();
    let (mut robot_outcome, mut controller_outcome) = (None, None);
    for k in 0..=steps {
        robot.handle_input(RobotInput::Sample { step: k, y: pose });
        let mut wheels = None;
        loop {
            let mut quiet = true;
            while let Some(out) = robot.poll_output() {
                quiet = false;
                match out {
                    RobotOutput::Transmit(m) if !drop(&m) => {
                        for m in [post_fragment(), m] {
                            controller.handle_input(ControllerInput::Frame(m));
                        }
                    }
                    RobotOutput::Apply(a) => wheels = Some(a.wheels),
                    RobotOutput::Finished(o) => robot_outcome = Some(o),
                    RobotOutput::Transmit(_) => {}
                }
            }
            while let Some(out) = controller.poll_output() {
                quiet = false;
                match out {
                    ControllerOutput::Transmit(m) if !drop(&m) => {
                        for m in [post_fragment(), m] {
                            robot.handle_input(RobotInput::Frame(m));
                        }
                    }
                    ControllerOutput::Event(ControllerEvent::CodewordDecided {
                        accepted, ..
                    }) => {
                        fates.push(accepted);
                    }
                    ControllerOutput::Event(ControllerEvent::Finished(o)) => {
                        controller_outcome = Some(o);
                    }
                    _ => {}
                }
            }
            if quiet {
                break;
            }
        }
        if wheels.is_none() && k < steps {
            robot.handle_input(RobotInput::Deadline { step: k });
            while let Some(out) = robot.poll_output() {
                if let RobotOutput::Apply(a) = out {
                    wheels = Some(a.wheels);
                }
            }
        }
        if k < steps {
            let input = drive.to_unicycle(wheels.expect("the robot always applies something"));
            pose = unicycle_step(&pose, &input, config.robot.sample_time);
        }
    }
    Session {
        robot_key: robot.key().to_vec(),
        controller_key: controller.key().to_vec(),
        controller_fates: fates,
        robot_outcome,
        controller_outcome,
    }
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
    assert_eq!(session.controller_fates.len(), 340 / 3);
    assert!(session.controller_fates.iter().all(|&a| a));
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
    let rejected: Vec<usize> = (0..session.controller_fates.len())
        .filter(|&i| !session.controller_fates[i])
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
    let rejected: Vec<usize> = (0..session.controller_fates.len())
        .filter(|&i| !session.controller_fates[i])
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
