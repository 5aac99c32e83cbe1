//! The odometry mode's robot (docs/protocol.md): applies one of the two offered commands per
//! step — the one its key bit picks — or the fallback, and reports odometry.

use rand::{CryptoRng, RngExt};

use super::io::Actuation;
use super::lifecycle::{ClosingRules, RobotLifecycle};
use super::mode::RobotMode;
use crate::code::low_mask;
use crate::model::{Pose, Unicycle, WheelSpeeds};
use crate::protocol::plan::{Agreed, OdometryPlan};
use crate::protocol::{FateLedger, KeyBits, Outcome, SessionMessage};

/// The odometry mode's part of a robot endpoint: the key's messages and codewords, which
/// codewords it saw erased, and the last pair (held through a short gap).
pub(crate) struct OdometryRobot {
    plan: OdometryPlan,
    messages: zeroize::Zeroizing<Vec<u64>>,
    codewords: zeroize::Zeroizing<Vec<u64>>,
    /// Whether the robot saw codeword j erased (a command missing): it is never accepted.
    erased: Vec<bool>,
    last_pair: Option<(WheelSpeeds, WheelSpeeds)>,
}

impl OdometryRobot {
    /// Draws the raw key from `key_source` (a CSPRNG: the OS generator in deployment, a
    /// seeded stream in simulation): one message per codeword of the session, `units` of
    /// them complete.
    pub(crate) fn new<R: CryptoRng + ?Sized>(
        agreed: &Agreed,
        plan: OdometryPlan,
        units: u32,
        key_source: &mut R,
    ) -> Self {
        let n = plan.code.n() as u32;
        // Enough messages for every step, including a trailing partial codeword.
        let count = if agreed.enabled {
            agreed.steps.div_ceil(n)
        } else {
            0
        };
        let mask = low_mask(plan.code.k());
        let messages: Vec<u64> = (0..count)
            .map(|_| key_source.random::<u64>() & mask)
            .collect();
        let codewords = messages.iter().map(|&m| plan.code.encode(m)).collect();
        Self {
            erased: vec![false; units as usize],
            messages: messages.into(),
            codewords: zeroize::Zeroizing::new(codewords),
            last_pair: None,
            plan,
        }
    }

    fn command(
        &mut self,
        agreed: &Agreed,
        life: &mut RobotLifecycle,
        step: u32,
        u0: WheelSpeeds,
        u1: WheelSpeeds,
    ) {
        if step < agreed.steps && !self.is_agreed_pair(agreed, &u0, &u1) {
            // Treated as a lost command: the step is erased.
            return self.on_missing(agreed, life, step);
        }
        life.command_arrived(step);
        if step >= agreed.steps {
            life.stop_wheels(step);
            life.end_run();
            return;
        }
        self.last_pair = Some((u0, u1));
        life.commands_applied += 1;
        let bit = agreed.enabled.then(|| self.bit(step));
        let wheels = if bit == Some(1) { u1 } else { u0 };
        life.apply(Actuation {
            step,
            wheels,
            bit,
            erased: false,
        });
    }

    /// Whether `(u0D, u1D)` is a pair the agreed plan allows: finite, within the wheel
    /// limit, and `H·u0D − H·u1D = 2Δ` (protocol on) or `u0D = u1D` (off), so an
    /// impersonated or buggy controller cannot offer a pair that reveals the bit.
    fn is_agreed_pair(&self, agreed: &Agreed, u0: &WheelSpeeds, u1: &WheelSpeeds) -> bool {
        let within = |w: &WheelSpeeds| w.iter().all(|v| v.abs() <= agreed.wheel_limit);
        if !(within(u0) && within(u1)) {
            return false; // also rejects NaN
        }
        let spread = agreed.drive.to_unicycle(*u0) - agreed.drive.to_unicycle(*u1);
        let expected = if agreed.enabled {
            self.plan.delta * 2.0
        } else {
            Unicycle::zeros()
        };
        (spread - expected).amax() <= 1e-9 * (1.0 + expected.amax())
    }

    /// Records a fate; a codeword the robot saw erased is never accepted.
    fn record_fate(&mut self, life: &mut RobotLifecycle, index: u32, accepted: bool) {
        let erased = !self.keepable(index);
        life.fates.record(index, accepted && !erased);
    }

    fn bit(&self, step: u32) -> u8 {
        let (index, position) = self.plan.position(step);
        (self.codewords[index as usize] >> position & 1) as u8
    }
}

impl ClosingRules for OdometryRobot {
    /// One beyond the session counts as erased.
    fn keepable(&self, index: u32) -> bool {
        !self.erased.get(index as usize).copied().unwrap_or(true)
    }

    fn key(&self, fates: &FateLedger) -> KeyBits {
        fates.accepted_key(&self.messages, self.plan.code.k())
    }

    fn tags_cover_key(&self) -> bool {
        true
    }

    fn verified(&self) -> Outcome {
        Outcome::Confirmed
    }

    fn count_mismatch(&self, codewords: u32, len: u32) -> String {
        format!("Finish covers {codewords} codewords, the robot sent {len}")
    }
}

impl RobotMode for OdometryRobot {
    fn on_sample(&mut self, _agreed: &Agreed, life: &mut RobotLifecycle, step: u32, y: &Pose) {
        let applied_step = life.applied_step.take();
        let fate_cursor = life.fates.cursor();
        life.send(SessionMessage::Measurement {
            step,
            y: (*y).into(),
            applied_step,
            fate_cursor,
        });
    }

    fn on_message(&mut self, agreed: &Agreed, life: &mut RobotLifecycle, message: &SessionMessage) {
        if let &SessionMessage::Command {
            step,
            u0,
            u1,
            fates,
        } = message
            // Otherwise stale, duplicate, from the future, or after the run.
            && life.expects_command()
            && step == life.next_command
        {
            for (index, accepted) in fates.iter() {
                self.record_fate(life, index, accepted);
            }
            self.command(agreed, life, step, u0.into(), u1.into());
        }
    }

    fn on_missing(&mut self, agreed: &Agreed, life: &mut RobotLifecycle, step: u32) {
        let Some(missing_in_a_row) = life.command_missing(step) else {
            return;
        };
        let (index, _) = self.plan.position(step);
        if let Some(erased) = self.erased.get_mut(index as usize) {
            *erased = true;
        }
        // Hold the last pair's midpoint through a short gap; a missing stop command (step
        // ≥ N) stops the wheels, as the stop command would have.
        let wheels = match self.last_pair {
            Some((u0, u1)) if step < agreed.steps && missing_in_a_row <= agreed.max_hold => {
                (u0 + u1) / 2.0
            }
            _ => WheelSpeeds::zeros(),
        };
        life.apply(Actuation {
            step,
            wheels,
            bit: None,
            erased: true,
        });
    }

    fn carried_word(&self, _doublet: u32) -> Option<u64> {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use crate::protocol::controller::command_pair;
    use crate::protocol::robot::testing::wake;
    use crate::protocol::{
        FateWindow, Pace, Robot, RobotInput, RobotOutput, SessionPlan, Time, Timing,
    };
    use rand::SeedableRng;

    /// A robot that never gives up on a silent controller: the tests feed commands at time
    /// zero and then let its clock run.
    fn robot() -> Robot {
        let plan = SessionPlan::from_config(&Config::default(), 1);
        let mut key_source = rand::rngs::ChaCha20Rng::seed_from_u64(1);
        let patient = Timing::new(Pace::Realtime, std::time::Duration::from_secs(3600));
        Robot::new(plan, patient, &mut key_source, Time::ZERO)
    }

    /// The pair the controller offers for `nominal`.
    fn pair(robot: &Robot, nominal: Unicycle) -> (WheelSpeeds, WheelSpeeds) {
        let plan = robot.plan();
        command_pair(&plan.agreed, plan.odometry().expect("odometry"), nominal)
    }

    fn command(robot: &mut Robot, u0: [f64; 2], u1: [f64; 2]) -> Actuation {
        robot.handle_input(
            Time::ZERO,
            RobotInput::Frame(
                SessionMessage::Command {
                    step: robot.next_command(),
                    u0,
                    u1,
                    fates: FateWindow::default(),
                }
                .into(),
            ),
        );
        match robot.poll_output() {
            Some(RobotOutput::Apply(actuation)) => actuation,
            other => panic!("expected an actuation, got {other:?}"),
        }
    }

    /// Found by the `robot_endpoint` driver: with the stop command (step N) lost, the
    /// deadline held the last pair's midpoint, moving the robot past the end of the run.
    #[test]
    fn a_missing_stop_command_stops_the_wheels() {
        let mut robot = robot();
        let (u0, u1) = pair(&robot, Unicycle::new(0.1, 0.0));
        for _ in 0..robot.plan().agreed.steps {
            assert!(!command(&mut robot, u0.into(), u1.into()).erased);
        }
        let steps = robot.plan().agreed.steps;
        // The robot samples step N, then its deadline passes without the stop command.
        let applied = loop {
            let (_, outputs) = wake(&mut robot);
            if let Some(a) = outputs.iter().find_map(|o| match o {
                RobotOutput::Apply(a) => Some(*a),
                _ => None,
            }) {
                break a;
            }
        };
        assert_eq!(
            (applied.step, applied.wheels, applied.erased),
            (steps, WheelSpeeds::zeros(), true)
        );
    }

    /// Found by the `robot_endpoint` fuzz target: a window starting near `u32::MAX`
    /// overflowed `first + j` (a panic with overflow checks).
    #[test]
    fn a_fate_window_at_the_end_of_the_index_range_is_ignored() {
        let mut robot = robot();
        let (u0, u1) = pair(&robot, Unicycle::new(0.1, 0.0));
        robot.handle_input(
            Time::ZERO,
            RobotInput::Frame(
                SessionMessage::Command {
                    step: 0,
                    u0: u0.into(),
                    u1: u1.into(),
                    fates: FateWindow {
                        first: u32::MAX - 3,
                        count: 64,
                        accepted: u64::MAX,
                    },
                }
                .into(),
            ),
        );
        assert!(matches!(robot.poll_output(), Some(RobotOutput::Apply(a)) if !a.erased));
        assert_eq!(robot.lifecycle.fates.cursor(), 0);
    }

    #[test]
    fn only_pairs_of_the_agreed_delta_within_the_wheel_limit_are_applied() {
        let mut robot = robot();
        let (u0, u1) = pair(&robot, Unicycle::new(0.1, 0.2));
        let applied = command(&mut robot, u0.into(), u1.into());
        assert!(!applied.erased && applied.bit.is_some());
        // Offers that reveal the bit in the motion, a spread other than 2Δ, a non-finite or
        // too fast wheel: each is erased as if lost, and the wheels hold the last good pair.
        let (w0, w1) = pair(&robot, Unicycle::new(0.1, 0.25));
        let wide = pair(&robot, Unicycle::new(0.1, 0.2)).0 * 2.0;
        let mut held = (u0 + u1) / 2.0;
        for (a, b) in [
            ([5.0, 5.0], [-5.0, -5.0]),
            (w0.into(), u1.into()),
            ([f64::NAN, 0.0], w1.into()),
            ([39.0, 39.0], [39.0 - 1e-3, 39.0 - 1e-3]),
            (wide.into(), w1.into()),
        ] {
            let erased = command(&mut robot, a, b);
            assert!(erased.erased && erased.bit.is_none(), "{a:?} {b:?}");
            assert_eq!(erased.wheels, held);
            let _ = command(&mut robot, w0.into(), w1.into());
            held = (w0 + w1) / 2.0;
        }
        assert_eq!(robot.commands_applied(), 1 + 5);
    }
}
