//! The private-sensing endpoints driven in lockstep over an in-memory channel that can drop
//! chosen messages and sensor samples, on a noise-free plant with a perfect sensor: losses
//! cost doublets, never agreement.

use robokey::Config;
use robokey::model::{Pose, unicycle_step};
use robokey::private::{PrivateControllerEndpoint, PrivatePlan, PrivateRobotEndpoint};
use robokey::protocol::{
    ControllerEvent, ControllerInput, ControllerOutput, Message, Outcome, RobotInput, RobotOutput,
};
use robokey::rng::{Purpose, stream};

/// Result of a lockstep session.
struct Session {
    robot_key: Vec<u8>,
    controller_key: Vec<u8>,
    decided: Vec<u32>,
    erased: Vec<u32>,
    robot_outcome: Option<Outcome>,
    controller_outcome: Option<Outcome>,
}

/// Runs one session; `drop(message)` removes a message from the channel, `blind(k)` the
/// controller's sensor sample k. Commands that do not arrive trigger the robot's deadline.
fn lockstep(
    config: &Config,
    drop: impl Fn(&Message) -> bool,
    blind: impl Fn(u32) -> bool,
) -> Session {
    let plan = PrivatePlan::from_config(config, 1);
    let (drive, steps) = (plan.drive, plan.steps);
    let mut robot = PrivateRobotEndpoint::new(plan.clone(), &mut stream(9, Purpose::Key, 0));
    let mut controller = PrivateControllerEndpoint::new(config, plan);
    let mut pose = Pose::zeros();
    let (mut decided, mut erased) = (Vec::new(), Vec::new());
    let (mut robot_outcome, mut controller_outcome) = (None, None);
    for k in 0..=steps {
        robot.handle_input(RobotInput::Sample { step: k, y: pose });
        if !blind(k) {
            controller.handle_input(ControllerInput::Sensor { step: k, pose });
        }
        let mut wheels = None;
        let mut deadline_passed = false;
        loop {
            let mut quiet = true;
            while let Some(out) = robot.poll_output() {
                quiet = false;
                match out {
                    RobotOutput::Transmit(m) if !drop(&m) => {
                        controller.handle_input(ControllerInput::Frame(m));
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
                        robot.handle_input(RobotInput::Frame(m));
                    }
                    ControllerOutput::Event(ControllerEvent::DoubletDecided(d)) => {
                        decided.push(d.doublet);
                    }
                    ControllerOutput::Event(ControllerEvent::DoubletErased { doublet }) => {
                        erased.push(doublet);
                    }
                    ControllerOutput::Event(ControllerEvent::Finished(o)) => {
                        controller_outcome = Some(o);
                    }
                    _ => {}
                }
            }
            if quiet && wheels.is_none() && k < steps && !deadline_passed {
                deadline_passed = true;
                robot.handle_input(RobotInput::Deadline { step: k });
                continue;
            }
            if quiet {
                break;
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
        decided,
        erased,
        robot_outcome,
        controller_outcome,
    }
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
    let plan = PrivatePlan::from_config(&config, 1);
    assert!(s.erased.is_empty(), "{:?}", s.erased);
    assert_eq!(s.decided, (0..plan.doublets()).collect::<Vec<_>>());
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
            Message::DoubletCommand { step, .. } => [10, 40].contains(step),
            Message::PrivateMeasurement { step, .. } => [21, 52, 60].contains(step),
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
    let steps = PrivatePlan::from_config(&config, 1).steps;
    let s = lockstep(
        &config,
        |m| matches!(m, Message::DoubletCommand { step, .. } if *step == steps),
        |_| false,
    );
    assert_eq!(s.robot_outcome, Some(Outcome::Kept));
    assert_eq!(s.controller_outcome, Some(Outcome::Kept));
    assert_eq!(s.robot_key, s.controller_key);
}
