//! The private-sensing endpoints on the virtual network, with chosen messages dropped and
//! chosen sensor samples missing, on a noise-free plant with a perfect sensor: losses cost
//! doublets, never agreement.

use robokey::Config;
use robokey::model::Pose;
use robokey::protocol::{
    Closing, Controller, ControllerInput, Message, Outcome, Robot, RobotInput, SessionMessage,
    SessionPlan, Time, Timing,
};
use robokey::rng::{Purpose, stream};
use support::{Network, session};

mod support;

/// Runs one session on an ideal link, dropping the messages `drop` picks and the sensor
/// samples `blind` picks.
fn lockstep(
    config: &Config,
    drop: impl Fn(&Message) -> bool,
    blind: impl Fn(u32) -> bool,
) -> support::Session {
    session(config, Network::default(), |_, m| drop(m), blind)
}

/// One lap, no motion noise, a perfect sensor, two bits per doublet, no turn gate.
fn clean_config() -> Config {
    let mut config = Config::from_toml(
        "[sensing]\nmode = \"private\"\ncontroller_std = [1e-9, 1e-9, 1e-9]\n\
         [noise]\nprocess_std = [1e-9, 1e-9, 1e-9]\n\
         [protocol]\nbits_per_doublet = 2\nmax_turn_rate = 1000.0\n",
        "test",
    )
    .unwrap();
    config.trajectory.laps = 1;
    config
}

#[test]
fn a_clean_session_keeps_every_doublet_with_equal_bits() {
    let config = clean_config();
    let s = lockstep(&config, |_| false, |_| false);
    let plan = SessionPlan::from_config(&config, 1);
    assert!(s.erased.is_empty(), "{:?}", s.erased);
    assert_eq!(s.decided, (0..plan.units()).collect::<Vec<_>>());
    assert_eq!(s.robot_key.len(), 2 * s.decided.len());
    assert_eq!(s.robot_key, s.controller_key);
    assert_eq!(s.robot_outcome, Some(Outcome::Kept));
    assert_eq!(s.controller_outcome, Some(Outcome::Kept));
}

#[test]
fn lost_commands_measurements_and_samples_drop_their_doublets_on_both_sides() {
    let config = clean_config();
    let clean = lockstep(&config, |_| false, |_| false);
    let lossy = lockstep(
        &config,
        |m| match m {
            Message::Session(SessionMessage::DoubletCommand { step, .. }) => {
                [10, 40].contains(step)
            }
            Message::Session(SessionMessage::PrivateMeasurement { step, .. }) => {
                [21, 52, 60].contains(step)
            }
            _ => false,
        },
        |k| [31, 70].contains(&k),
    );
    // Commands 10 and 40 lost (doublets 5 and 20); the reports of steps 20, 51 and 59 lost
    // (measurements 21, 52, 60: doublets 10, 25, 29); samples 31 (doublet 15's middle) and
    // 70 (doublet 34's end, and 35's start: never commanded) missing.
    let dropped = [5, 10, 15, 20, 25, 29, 34, 35];
    let expected: Vec<u32> = clean
        .decided
        .iter()
        .copied()
        .filter(|j| !dropped.contains(j))
        .collect();
    assert_eq!(lossy.decided, expected);
    let mut erased = lossy.erased.clone();
    erased.sort_unstable();
    assert_eq!(erased, dropped);
    assert_eq!(lossy.robot_key.len(), 2 * expected.len());
    assert_eq!(lossy.robot_key, lossy.controller_key);
    assert_eq!(lossy.robot_outcome, Some(Outcome::Kept));
    assert_eq!(lossy.controller_outcome, Some(Outcome::Kept));
}

#[test]
fn a_lost_stop_command_changes_nothing() {
    // The robot stops at N on its own clock; the Finish carries every fate.
    let config = clean_config();
    let steps = SessionPlan::from_config(&config, 1).agreed.steps;
    let s = lockstep(
        &config,
        |m| matches!(m, Message::Session(SessionMessage::DoubletCommand { step, .. }) if *step == steps),
        |_| false,
    );
    assert_eq!(s.robot_outcome, Some(Outcome::Kept));
    assert_eq!(s.controller_outcome, Some(Outcome::Kept));
    assert_eq!(s.robot_key, s.controller_key);
}

mod arbitrary_inputs {
    use super::*;
    use proptest::prelude::*;
    use robokey::protocol::FateWindow;

    /// Authenticated but arbitrary frames and sensor samples (a buggy or compromised peer, a
    /// broken sensor): steps near the session's, any floats, any fates.
    fn message() -> impl Strategy<Value = Message> {
        let f = proptest::num::f64::ANY;
        let step = prop_oneof![0u32..12, 0u32..400, any::<u32>()];
        prop_oneof![
            (
                step.clone(),
                proptest::option::of(any::<u32>()),
                any::<u32>()
            )
                .prop_map(|(step, applied_step, fate_cursor)| {
                    Message::from(SessionMessage::PrivateMeasurement {
                        step,
                        applied_step,
                        fate_cursor,
                    })
                }),
            (
                step,
                [f, f, f],
                [f, f],
                proptest::option::of([f, f]),
                (any::<u32>(), 0u8..=64, any::<u64>())
            )
                .prop_map(
                    |(step, sample, first, second, (first_fate, count, accepted))| {
                        Message::from(SessionMessage::DoubletCommand {
                            step,
                            sample,
                            first,
                            second,
                            fates: FateWindow {
                                first: first_fate,
                                count,
                                accepted,
                            },
                        })
                    }
                ),
            (0u32..300, proptest::collection::vec(any::<u64>(), 0..6))
                .prop_map(|(codewords, bitmap)| Closing::Finish { codewords, bitmap }.into()),
            Just(Closing::FinishAck.into()),
            (any::<[u8; 16]>(), any::<[u8; 16]>()).prop_map(|(session_tag, key_tag)| {
                Closing::Confirm {
                    session_tag,
                    key_tag,
                }
                .into()
            }),
        ]
    }

    proptest! {
        #[test]
        fn the_private_endpoints_never_panic_on_arbitrary_frames_and_samples(
            inputs in proptest::collection::vec(
                (message(), 0u32..400, [proptest::num::f64::ANY; 3]),
                0..60
            )
        ) {
            let mut config = clean_config();
            config.trajectory.side_time = 5.0;
            let plan = SessionPlan::from_config(&config, 1);
            let timing = Timing::default();
            let mut robot =
                Robot::new(plan.clone(), timing, &mut stream(1, Purpose::Key, 0), Time::ZERO);
            let mut controller = Controller::new(&config, plan, timing, Time::ZERO);
            for (i, (message, step, pose)) in inputs.into_iter().enumerate() {
                // Time runs on by 100 ms an input: every timer fires at some point.
                let now = Time::ZERO + std::time::Duration::from_millis(100 * i as u64);
                robot.handle_input(now, RobotInput::Sample { step, y: Pose::zeros() });
                robot.handle_input(now, RobotInput::Frame(message.clone()));
                robot.handle_timeout(now);
                controller.handle_input(now, ControllerInput::Sensor { step, pose: pose.into() });
                controller.handle_input(now, ControllerInput::Frame(message));
                controller.handle_timeout(now);
                while robot.poll_output().is_some() {}
                while controller.poll_output().is_some() {}
            }
        }
    }
}
