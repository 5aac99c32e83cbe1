//! The robot endpoint of private sensing (docs/private-sensing.md, docs/protocol.md): owns
//! the key bits and the clock, applies `u + s·Δ` then `u' − s·Δ` from each doublet's nominal
//! inputs, and reports which command it applied — never a pose.

use std::collections::VecDeque;

use rand::{CryptoRng, RngExt};

use super::doublet::DoubletInputs;
use super::plan::PrivatePlan;
use crate::model::{Unicycle, WheelSpeeds};
use crate::protocol::closing::{RobotCloser, bitmap_bit};
use crate::protocol::{
    Actuation, FateLedger, FateWindow, KeyBits, Message, Outcome, RobotInput, RobotOutput,
};

/// What the robot waits for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    ExpectCommand,
    ExpectFinish,
    ExpectConfirm,
    Done,
}

/// The robot side of a private-sensing session. It takes the odometry mode's
/// [`RobotInput`]s (the pose of a `Sample` stays on the robot) and emits [`RobotOutput`]s.
pub struct PrivateRobotEndpoint {
    plan: PrivatePlan,
    /// Each doublet's bits as `v | ω << 1`, drawn up front.
    bits: zeroize::Zeroizing<Vec<u64>>,
    /// Whether the robot applied doublet j with its bits (not gated, not erased).
    carried: Vec<bool>,
    fates: FateLedger,
    /// The input for the second step of the doublet in flight, with its step.
    second: Option<(u32, Unicycle)>,
    /// The last nominal input received: held for up to `max_hold` missing steps.
    last_nominal: Option<Unicycle>,
    missing_in_a_row: u32,
    applied_step: Option<u32>,
    next_command: u32,
    phase: Phase,
    key: KeyBits,
    commands_applied: u32,
    outputs: VecDeque<RobotOutput>,
}

impl std::fmt::Debug for PrivateRobotEndpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Key material is never printed.
        f.debug_struct("PrivateRobotEndpoint")
            .field("phase", &self.phase)
            .field("next_command", &self.next_command)
            .finish_non_exhaustive()
    }
}

impl PrivateRobotEndpoint {
    /// A robot that draws two bits per doublet (v and ω; the ω bit is used with two bits
    /// per doublet) from `key_source`, a CSPRNG: the OS generator in deployment, a seeded
    /// stream in simulation.
    pub fn new<R: CryptoRng + ?Sized>(plan: PrivatePlan, key_source: &mut R) -> Self {
        let doublets = plan.doublets();
        let bits: Vec<u64> = (0..doublets)
            .map(|_| {
                let v = key_source.random_range(0..2u8);
                let omega = key_source.random_range(0..2u8);
                u64::from(v | omega << 1)
            })
            .collect();
        Self {
            bits: bits.into(),
            carried: vec![false; doublets as usize],
            fates: FateLedger::new(doublets),
            second: None,
            last_nominal: None,
            missing_in_a_row: 0,
            applied_step: None,
            next_command: 0,
            phase: Phase::ExpectCommand,
            key: KeyBits::default(),
            commands_applied: 0,
            outputs: VecDeque::new(),
            plan,
        }
    }

    /// Feeds one input.
    pub fn handle_input(&mut self, input: RobotInput) {
        match input {
            RobotInput::Sample { step, .. } => self.handle_sample(step),
            RobotInput::Frame(message) => self.handle_message(message),
            RobotInput::Deadline { step } => self.handle_missing(step),
        }
    }

    /// The next output, if any.
    pub fn poll_output(&mut self) -> Option<RobotOutput> {
        self.outputs.pop_front()
    }

    /// The robot's raw bits of the kept doublets, `[v, ω]` each (complete once the Finish
    /// has arrived): the reference key that reconciliation corrects the controller's to.
    #[must_use]
    pub fn key(&self) -> &[u8] {
        &self.key
    }

    /// The bits `[v, ω]` doublet `doublet` carries, once the robot applied it with them.
    #[must_use]
    pub fn carried_bits(&self, doublet: u32) -> Option<[u8; 2]> {
        let j = doublet as usize;
        self.carried
            .get(j)
            .copied()
            .unwrap_or(false)
            .then(|| [(self.bits[j] & 1) as u8, (self.bits[j] >> 1 & 1) as u8])
    }

    /// Whether the session is over.
    #[must_use]
    pub fn is_done(&self) -> bool {
        self.phase == Phase::Done
    }

    /// The session plan.
    #[must_use]
    pub fn plan(&self) -> &PrivatePlan {
        &self.plan
    }

    /// Steps applied from commands (fallbacks and the stop excluded).
    #[must_use]
    pub fn commands_applied(&self) -> u32 {
        self.commands_applied
    }

    /// The step whose command the robot waits for.
    #[must_use]
    pub fn next_command(&self) -> u32 {
        self.next_command
    }

    fn send(&mut self, message: Message) {
        self.outputs.push_back(RobotOutput::Transmit(message));
    }

    fn finish(&mut self, outcome: Outcome) {
        self.phase = Phase::Done;
        self.outputs.push_back(RobotOutput::Finished(outcome));
    }

    fn apply(&mut self, step: u32, input: Unicycle, bit: Option<u8>, erased: bool) {
        self.outputs.push_back(RobotOutput::Apply(Actuation {
            step,
            wheels: self.plan.drive.to_wheels(input),
            bit,
            erased,
        }));
    }

    fn stop_wheels(&mut self, step: u32) {
        self.outputs.push_back(RobotOutput::Apply(Actuation {
            step,
            wheels: WheelSpeeds::zeros(),
            bit: None,
            erased: false,
        }));
    }

    /// Sample instant `t_k`: reports which command was applied before it; applies a
    /// doublet's second input, or its fallback when the doublet's command never came; at
    /// `k = N` stops the wheels (the robot owns the clock: the stop command only carries the
    /// controller's last sample and fates).
    fn handle_sample(&mut self, step: u32) {
        let applied_step = self.applied_step.take();
        self.send(Message::PrivateMeasurement {
            step,
            applied_step,
            fate_cursor: self.fates.cursor(),
        });
        if self.phase != Phase::ExpectCommand || step != self.next_command {
            return;
        }
        if step >= self.plan.steps {
            self.stop_wheels(step);
            self.next_command = step + 1;
            self.phase = Phase::ExpectFinish;
        } else if step % 2 == 1 {
            // The second step of a doublet: its input came with the first.
            match self.second.take().filter(|(s, _)| *s == step) {
                Some((_, input)) => {
                    self.commands_applied += 1;
                    self.missing_in_a_row = 0;
                    self.applied_step = Some(step);
                    self.next_command = step + 1;
                    let bit = self.carried_bits(step / 2).map(|b| b[0]);
                    self.apply(step, input, bit, false);
                }
                None => self.handle_missing(step),
            }
        }
    }

    fn handle_message(&mut self, message: Message) {
        match (self.phase, message) {
            (
                Phase::ExpectCommand,
                Message::DoubletCommand {
                    step,
                    first,
                    second,
                    fates,
                    ..
                },
            ) => {
                if step != self.next_command || step >= self.plan.steps || step % 2 == 1 {
                    return; // stale, duplicate, from the future, or not a command step
                }
                self.record(fates);
                self.handle_command(step, first.into(), second.map(Unicycle::from));
            }
            (Phase::ExpectFinish, Message::DoubletCommand { fates, .. }) => self.record(fates),
            (
                phase @ (Phase::ExpectCommand | Phase::ExpectFinish | Phase::ExpectConfirm),
                Message::Finish { codewords, bitmap },
            ) => {
                if phase == Phase::ExpectCommand {
                    // The Finish ends the run wherever the robot is.
                    self.stop_wheels(self.next_command);
                }
                if codewords != self.fates.len() {
                    let reason = format!(
                        "Finish covers {codewords} doublets, the session has {}",
                        self.fates.len()
                    );
                    self.send(Message::Abort {
                        reason: reason.clone(),
                    });
                    self.finish(Outcome::Aborted(reason));
                    return;
                }
                for index in 0..codewords {
                    self.record_fate(index, bitmap_bit(&bitmap, index));
                }
                self.key = self.fates.accepted_key(
                    &self.bits,
                    usize::from(self.plan.perturbation.bits_per_doublet),
                );
                self.phase = Phase::ExpectConfirm;
                for message in self.closer(&self.fates.bitmap()).answer() {
                    self.send(message);
                }
            }
            (
                Phase::ExpectConfirm,
                Message::Confirm {
                    session_tag,
                    key_tag,
                },
            ) => {
                let outcome =
                    self.closer(&self.fates.bitmap())
                        .verdict(session_tag, key_tag, Outcome::Kept);
                self.finish(outcome);
            }
            (Phase::Done, _) => {}
            (_, Message::Abort { reason }) => {
                self.stop_wheels(self.next_command);
                self.finish(Outcome::Aborted(format!("controller aborted: {reason}")));
            }
            _ => {}
        }
    }

    /// The doublet (or lone last step) starting at `step`: applies `u + s·Δ` now and keeps
    /// `u' − s·Δ` for the next step. A command whose shape does not fit the step, or any of
    /// whose derivable inputs is not finite or beyond the wheel limit, is treated as lost.
    fn handle_command(&mut self, step: u32, first: Unicycle, second: Option<Unicycle>) {
        let inputs = match second {
            Some(second) if self.plan.starts_doublet(step) => Some(DoubletInputs { first, second }),
            None if !self.plan.starts_doublet(step) => None,
            _ => return self.handle_missing(step),
        };
        if !self.is_allowed(first, inputs.as_ref()) {
            return self.handle_missing(step);
        }
        self.commands_applied += 1;
        self.missing_in_a_row = 0;
        self.applied_step = Some(step);
        self.next_command = step + 1;
        let Some(inputs) = inputs else {
            self.last_nominal = Some(first);
            return self.apply(step, first, None, false);
        };
        let j = (step / 2) as usize;
        let carries = self.plan.carries(&inputs);
        let offset = if carries {
            let pattern = self
                .plan
                .perturbation
                .pattern([(self.bits[j] & 1) as u8, (self.bits[j] >> 1 & 1) as u8]);
            self.plan.perturbation.offset(pattern)
        } else {
            Unicycle::zeros()
        };
        self.carried[j] = carries;
        let [a, b] = inputs.applied(offset);
        self.second = Some((step + 1, b));
        self.last_nominal = Some(inputs.second);
        let bit = self.carried_bits(step / 2).map(|bits| bits[0]);
        self.apply(step, a, bit, false);
    }

    /// Whether every input the robot could derive from a command is finite and within its
    /// wheel limit: for every bit pattern, gated or not, so that whether a step is erased
    /// never depends on the bit.
    fn is_allowed(&self, first: Unicycle, inputs: Option<&DoubletInputs>) -> bool {
        let within = |u: Unicycle| {
            self.plan
                .drive
                .to_wheels(u)
                .iter()
                .all(|w| w.abs() <= self.plan.wheel_limit) // also rejects NaN
        };
        let Some(inputs) = inputs else {
            return within(first);
        };
        let perturbation = &self.plan.perturbation;
        (0..perturbation.patterns())
            .map(|h| perturbation.offset(h))
            .chain([Unicycle::zeros()])
            .all(|offset| inputs.applied(offset).into_iter().all(within))
    }

    /// Step `step`'s command is missing: the robot holds the last nominal input for up to
    /// `max_hold` steps, then stops; a doublet with a missing step carries no bit.
    fn handle_missing(&mut self, step: u32) {
        if self.phase != Phase::ExpectCommand || step != self.next_command {
            return;
        }
        self.next_command = step + 1;
        self.missing_in_a_row += 1;
        self.applied_step = None;
        if let Some(carried) = self.carried.get_mut((step / 2) as usize) {
            *carried = false;
        }
        self.second = None;
        let input = match self.last_nominal {
            Some(u) if self.missing_in_a_row <= self.plan.max_hold => u,
            _ => Unicycle::zeros(),
        };
        self.apply(step, input, None, true);
    }

    /// Records the fates of a window.
    fn record(&mut self, fates: FateWindow) {
        for (index, kept) in fates.iter() {
            self.record_fate(index, kept);
        }
    }

    /// Records a fate; a doublet the robot did not carry is never kept.
    fn record_fate(&mut self, index: u32, kept: bool) {
        let carried = self.carried.get(index as usize).copied().unwrap_or(false);
        self.fates.record(index, kept && carried);
    }

    /// The closing handshake: tags over the fates and the empty key (raw bits are
    /// confirmed per post-processing block, never per session).
    fn closer<'a>(&'a self, bitmap: &'a [u64]) -> RobotCloser<'a> {
        RobotCloser {
            confirmer: &self.plan.confirmer,
            bitmap,
            tagged_key: &[],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use rand::SeedableRng;

    fn robot(seed: u64) -> PrivateRobotEndpoint {
        let config = Config::from_toml("[sensing]\nmode = \"private\"\n", "test").unwrap();
        let plan = PrivatePlan::from_config(&config, 1);
        PrivateRobotEndpoint::new(plan, &mut rand::rngs::ChaCha20Rng::seed_from_u64(seed))
    }

    /// Offers the doublet at the robot's next command step; returns what it applied.
    fn offer(robot: &mut PrivateRobotEndpoint, first: [f64; 2], second: [f64; 2]) -> Actuation {
        let step = robot.next_command();
        robot.handle_input(RobotInput::Sample {
            step,
            y: crate::model::Pose::zeros(),
        });
        robot.handle_input(RobotInput::Frame(Message::DoubletCommand {
            step,
            sample: [0.0; 3],
            first,
            second: Some(second),
            fates: FateWindow::default(),
        }));
        let applied = std::iter::from_fn(|| robot.poll_output())
            .find_map(|o| match o {
                RobotOutput::Apply(a) => Some(a),
                _ => None,
            })
            .expect("an actuation");
        // The doublet's second step.
        robot.handle_input(RobotInput::Sample {
            step: step + 1,
            y: crate::model::Pose::zeros(),
        });
        while robot.poll_output().is_some() {}
        applied
    }

    #[test]
    fn only_finite_inputs_whose_every_pattern_is_within_the_wheel_limit_are_applied() {
        // r = 0.021 m, limit 38 rad/s: v = 0.79 m/s is 37.6 rad/s, within the limit, but
        // v + Δv (0.825 m/s, 39.3 rad/s) is not — whatever the bit, the doublet is erased.
        for seed in 0..8 {
            let mut robot = robot(seed);
            let good = offer(&mut robot, [0.1, 0.2], [0.1, 0.2]);
            assert!(!good.erased);
            for (first, second) in [
                ([0.79, 0.0], [0.1, 0.0]),
                ([0.1, 0.0], [f64::NAN, 0.0]),
                ([f64::INFINITY, 0.0], [0.1, 0.0]),
            ] {
                let erased = offer(&mut robot, first, second);
                assert!(
                    erased.erased && erased.bit.is_none(),
                    "{first:?} {second:?}"
                );
                assert_eq!(erased.wheels, robot.plan.drive.to_wheels([0.1, 0.2].into()));
                let _ = offer(&mut robot, [0.1, 0.2], [0.1, 0.2]);
            }
        }
    }
}
