//! The robot endpoint (docs/protocol.md): owns the key bits and the clock, applies one of the
//! two offered commands per step (or the fallback), reports odometry.

use super::Outcome;
use super::closing::{RobotClosing, RobotLifecycle};
use super::endpoint_io::{Actuation, RobotInput, RobotOutput};
use super::fates::FateLedger;
use super::message::{Message, SessionMessage};
use super::plan::SessionPlan;
use crate::code::low_mask;
use crate::model::{Pose, Unicycle, WheelSpeeds};
use rand::{CryptoRng, RngExt};

/// The robot side of a session.
pub struct RobotEndpoint {
    plan: SessionPlan,
    messages: zeroize::Zeroizing<Vec<u64>>,
    codewords: zeroize::Zeroizing<Vec<u64>>,
    /// Whether the robot saw codeword j erased (a command missing): it is never accepted.
    erased: Vec<bool>,
    last_pair: Option<(WheelSpeeds, WheelSpeeds)>,
    lifecycle: RobotLifecycle,
}

impl std::fmt::Debug for RobotEndpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Key material is never printed.
        f.debug_struct("RobotEndpoint")
            .field("lifecycle", &self.lifecycle)
            .finish_non_exhaustive()
    }
}

impl RobotEndpoint {
    /// A robot that draws its raw key from `key_source` (a CSPRNG: the OS generator in
    /// deployment, a seeded stream in simulation).
    pub fn new<R: CryptoRng + ?Sized>(plan: SessionPlan, key_source: &mut R) -> Self {
        let n = plan.code.n() as u32;
        // Enough messages for every step, including a trailing partial codeword.
        let count = if plan.enabled {
            plan.steps.div_ceil(n)
        } else {
            0
        };
        let mask = low_mask(plan.code.k());
        let messages: Vec<u64> = (0..count)
            .map(|_| key_source.random::<u64>() & mask)
            .collect();
        let codewords = messages.iter().map(|&m| plan.code.encode(m)).collect();
        Self {
            lifecycle: RobotLifecycle::new(plan.codewords()),
            erased: vec![false; plan.codewords() as usize],
            messages: messages.into(),
            codewords: zeroize::Zeroizing::new(codewords),
            last_pair: None,
            plan,
        }
    }

    /// Feeds one input.
    pub fn handle_input(&mut self, input: RobotInput) {
        match input {
            RobotInput::Sample { step, y } => self.handle_sample(step, &y),
            RobotInput::Frame(message) => self.handle_message(message),
            RobotInput::Deadline { step } => self.handle_deadline(step),
        }
    }

    /// The next output, if any.
    pub fn poll_output(&mut self) -> Option<RobotOutput> {
        self.lifecycle.poll()
    }

    /// The robot's key `K_r` (complete once the Finish has arrived).
    #[must_use]
    pub fn key(&self) -> &[u8] {
        self.lifecycle.key()
    }

    /// Whether the session is over.
    #[must_use]
    pub fn is_done(&self) -> bool {
        self.lifecycle.is_done()
    }

    /// The session plan.
    #[must_use]
    pub fn plan(&self) -> &SessionPlan {
        &self.plan
    }

    /// Commands applied to the wheels (stop commands and fallbacks excluded).
    #[must_use]
    pub fn commands_applied(&self) -> u32 {
        self.lifecycle.commands_applied
    }

    /// The step whose command the robot waits for.
    #[must_use]
    pub fn next_command(&self) -> u32 {
        self.lifecycle.next_command
    }

    fn handle_sample(&mut self, step: u32, y: &Pose) {
        let applied_step = self.lifecycle.applied_step.take();
        let fate_cursor = self.lifecycle.fates.cursor();
        self.lifecycle.send(
            SessionMessage::Measurement {
                step,
                y: (*y).into(),
                applied_step,
                fate_cursor,
            }
            .into(),
        );
    }

    fn handle_message(&mut self, message: Message) {
        match message {
            Message::Session(SessionMessage::Command {
                step,
                u0,
                u1,
                fates,
            }) if self.lifecycle.expects_command() => {
                if step != self.lifecycle.next_command {
                    return; // stale, duplicate or from the future
                }
                for (index, accepted) in fates.iter() {
                    self.record_fate(index, accepted);
                }
                self.handle_command(step, u0.into(), u1.into());
            }
            Message::Closing(message) => {
                let erased = &self.erased;
                let messages = &self.messages;
                let k = self.plan.code.k();
                let closing = RobotClosing {
                    confirmer: &self.plan.confirmer,
                    keepable: &|index| !was_erased(erased, index),
                    key: &|fates: &FateLedger| fates.accepted_key(messages, k),
                    tags_cover_key: true,
                    verified: Outcome::Confirmed,
                    count_mismatch: |codewords, len| {
                        format!("Finish covers {codewords} codewords, the robot sent {len}")
                    },
                };
                self.lifecycle.on_message(message, &closing);
            }
            // Handshake and post-processing messages are not the endpoint's; a session
            // message after the run is a late duplicate.
            _ => {}
        }
    }

    fn handle_command(&mut self, step: u32, u0: WheelSpeeds, u1: WheelSpeeds) {
        if step < self.plan.steps && !self.is_agreed_pair(&u0, &u1) {
            // Treated as a lost command: the step is erased.
            return self.handle_deadline(step);
        }
        self.lifecycle.command_arrived(step);
        if step >= self.plan.steps {
            self.lifecycle.stop_wheels(step);
            self.lifecycle.end_run();
            return;
        }
        self.last_pair = Some((u0, u1));
        self.lifecycle.commands_applied += 1;
        let bit = self.plan.enabled.then(|| self.bit(step));
        let wheels = if bit == Some(1) { u1 } else { u0 };
        self.lifecycle.apply(Actuation {
            step,
            wheels,
            bit,
            erased: false,
        });
    }

    /// Whether `(u0D, u1D)` is a pair the agreed plan allows: finite, within the wheel
    /// limit, and `H·u0D − H·u1D = 2Δ` (protocol on) or `u0D = u1D` (off), so an
    /// impersonated or buggy controller cannot offer a pair that reveals the bit.
    fn is_agreed_pair(&self, u0: &WheelSpeeds, u1: &WheelSpeeds) -> bool {
        let within = |w: &WheelSpeeds| w.iter().all(|v| v.abs() <= self.plan.wheel_limit);
        if !(within(u0) && within(u1)) {
            return false; // also rejects NaN
        }
        let spread = self.plan.drive.to_unicycle(*u0) - self.plan.drive.to_unicycle(*u1);
        let expected = if self.plan.enabled {
            self.plan.delta * 2.0
        } else {
            Unicycle::zeros()
        };
        (spread - expected).amax() <= 1e-9 * (1.0 + expected.amax())
    }

    fn handle_deadline(&mut self, step: u32) {
        let Some(missing_in_a_row) = self.lifecycle.command_missing(step) else {
            return;
        };
        let (index, _) = self.plan.position(step);
        if let Some(erased) = self.erased.get_mut(index as usize) {
            *erased = true;
        }
        // Hold the last pair's midpoint through a short gap; a missing stop command (step
        // ≥ N) stops the wheels, as the stop command would have.
        let wheels = match self.last_pair {
            Some((u0, u1)) if step < self.plan.steps && missing_in_a_row <= self.plan.max_hold => {
                (u0 + u1) / 2.0
            }
            _ => WheelSpeeds::zeros(),
        };
        self.lifecycle.apply(Actuation {
            step,
            wheels,
            bit: None,
            erased: true,
        });
    }

    /// Records a fate; a codeword the robot saw erased is never accepted.
    fn record_fate(&mut self, index: u32, accepted: bool) {
        let erased = was_erased(&self.erased, index);
        self.lifecycle.fates.record(index, accepted && !erased);
    }

    fn bit(&self, step: u32) -> u8 {
        let (index, position) = self.plan.position(step);
        (self.codewords[index as usize] >> position & 1) as u8
    }
}

/// Whether the robot saw codeword `index` erased (one beyond the session counts as erased).
fn was_erased(erased: &[bool], index: u32) -> bool {
    erased.get(index as usize).copied().unwrap_or(true)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use crate::protocol::FateWindow;
    use crate::protocol::controller::command_pair;
    use rand::SeedableRng;

    fn robot() -> RobotEndpoint {
        let plan = SessionPlan::from_config(&Config::default(), 1);
        RobotEndpoint::new(plan, &mut rand::rngs::ChaCha20Rng::seed_from_u64(1))
    }

    fn command(robot: &mut RobotEndpoint, u0: [f64; 2], u1: [f64; 2]) -> Actuation {
        robot.handle_input(RobotInput::Frame(Message::Session(
            SessionMessage::Command {
                step: robot.next_command(),
                u0,
                u1,
                fates: FateWindow::default(),
            },
        )));
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
        let (u0, u1) = command_pair(robot.plan(), Unicycle::new(0.1, 0.0));
        for _ in 0..robot.plan().steps {
            assert!(!command(&mut robot, u0.into(), u1.into()).erased);
        }
        let steps = robot.plan().steps;
        robot.handle_input(RobotInput::Deadline { step: steps });
        match robot.poll_output() {
            Some(RobotOutput::Apply(a)) => {
                assert_eq!(
                    (a.step, a.wheels, a.erased),
                    (steps, WheelSpeeds::zeros(), true)
                );
            }
            other => panic!("expected an actuation, got {other:?}"),
        }
    }

    /// Found by the `robot_endpoint` fuzz target: a window starting near `u32::MAX`
    /// overflowed `first + j` (a panic with overflow checks).
    #[test]
    fn a_fate_window_at_the_end_of_the_index_range_is_ignored() {
        let mut robot = robot();
        let (u0, u1) = command_pair(robot.plan(), Unicycle::new(0.1, 0.0));
        robot.handle_input(RobotInput::Frame(Message::Session(
            SessionMessage::Command {
                step: 0,
                u0: u0.into(),
                u1: u1.into(),
                fates: FateWindow {
                    first: u32::MAX - 3,
                    count: 64,
                    accepted: u64::MAX,
                },
            },
        )));
        assert!(matches!(robot.poll_output(), Some(RobotOutput::Apply(a)) if !a.erased));
        assert_eq!(robot.lifecycle.fates.cursor(), 0);
    }

    #[test]
    fn only_pairs_of_the_agreed_delta_within_the_wheel_limit_are_applied() {
        let mut robot = robot();
        let (u0, u1) = command_pair(robot.plan(), Unicycle::new(0.1, 0.2));
        let applied = command(&mut robot, u0.into(), u1.into());
        assert!(!applied.erased && applied.bit.is_some());
        // Offers that reveal the bit in the motion, a spread other than 2Δ, a non-finite or
        // too fast wheel: each is erased as if lost, and the wheels hold the last good pair.
        let (w0, w1) = command_pair(robot.plan(), Unicycle::new(0.1, 0.25));
        let wide = command_pair(robot.plan(), Unicycle::new(0.1, 0.2)).0 * 2.0;
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
