//! The robot endpoint of private sensing (docs/private-sensing.md, docs/protocol.md): owns
//! the key bits and the clock, applies `u + s·Δ` then `u' − s·Δ` from each doublet's nominal
//! inputs, and reports which command it applied — never a pose.

use rand::{CryptoRng, RngExt};

use super::doublet::DoubletInputs;
use super::plan::PrivatePlan;
use crate::model::Unicycle;
use crate::protocol::closing::{RobotClosing, RobotLifecycle};
use crate::protocol::{
    Actuation, FateLedger, FateWindow, Message, Outcome, RobotInput, RobotOutput, SessionMessage,
};

/// The robot side of a private-sensing session. It takes the odometry mode's
/// [`RobotInput`]s (the pose of a `Sample` stays on the robot) and emits [`RobotOutput`]s.
pub struct PrivateRobotEndpoint {
    plan: PrivatePlan,
    /// Each doublet's bits as `v | ω << 1`, drawn up front.
    bits: zeroize::Zeroizing<Vec<u64>>,
    /// Whether the robot applied doublet j with its bits (not gated, not erased).
    carried: Vec<bool>,
    /// The input for the second step of the doublet in flight, with its step.
    second: Option<(u32, Unicycle)>,
    /// The last nominal input received: held for up to `max_hold` missing steps.
    last_nominal: Option<Unicycle>,
    lifecycle: RobotLifecycle,
}

impl std::fmt::Debug for PrivateRobotEndpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Key material is never printed.
        f.debug_struct("PrivateRobotEndpoint")
            .field("lifecycle", &self.lifecycle)
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
            second: None,
            last_nominal: None,
            lifecycle: RobotLifecycle::new(doublets),
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
        self.lifecycle.poll()
    }

    /// The robot's raw bits of the kept doublets, `[v, ω]` each (complete once the Finish
    /// has arrived): the reference key that reconciliation corrects the controller's to.
    #[must_use]
    pub fn key(&self) -> &[u8] {
        self.lifecycle.key()
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
        self.lifecycle.is_done()
    }

    /// The session plan.
    #[must_use]
    pub fn plan(&self) -> &PrivatePlan {
        &self.plan
    }

    /// Steps applied from commands (fallbacks and the stop excluded).
    #[must_use]
    pub fn commands_applied(&self) -> u32 {
        self.lifecycle.commands_applied
    }

    /// The step whose command the robot waits for.
    #[must_use]
    pub fn next_command(&self) -> u32 {
        self.lifecycle.next_command
    }

    fn apply(&mut self, step: u32, input: Unicycle, bit: Option<u8>, erased: bool) {
        self.lifecycle.apply(Actuation {
            step,
            wheels: self.plan.drive.to_wheels(input),
            bit,
            erased,
        });
    }

    /// Sample instant `t_k`: reports which command was applied before it; applies a
    /// doublet's second input, or its fallback when the doublet's command never came; at
    /// `k = N` stops the wheels (the robot owns the clock: the stop command only carries the
    /// controller's last sample and fates).
    fn handle_sample(&mut self, step: u32) {
        let applied_step = self.lifecycle.applied_step.take();
        let fate_cursor = self.lifecycle.fates.cursor();
        self.lifecycle.send(
            SessionMessage::PrivateMeasurement {
                step,
                applied_step,
                fate_cursor,
            }
            .into(),
        );
        if !self.lifecycle.awaits(step) {
            return;
        }
        if step >= self.plan.steps {
            self.lifecycle.stop_wheels(step);
            self.lifecycle.next_command = step + 1;
            self.lifecycle.end_run();
        } else if step % 2 == 1 {
            // The second step of a doublet: its input came with the first.
            match self.second.take().filter(|(s, _)| *s == step) {
                Some((_, input)) => {
                    self.lifecycle.commands_applied += 1;
                    self.lifecycle.command_arrived(step);
                    let bit = self.carried_bits(step / 2).map(|b| b[0]);
                    self.apply(step, input, bit, false);
                }
                None => self.handle_missing(step),
            }
        }
    }

    fn handle_message(&mut self, message: Message) {
        match message {
            Message::Session(SessionMessage::DoubletCommand {
                step,
                first,
                second,
                fates,
                ..
            }) if self.lifecycle.expects_command() => {
                if step != self.lifecycle.next_command || step >= self.plan.steps || step % 2 == 1 {
                    return; // stale, duplicate, from the future, or not a command step
                }
                self.record(fates);
                self.handle_command(step, first.into(), second.map(Unicycle::from));
            }
            Message::Session(SessionMessage::DoubletCommand { fates, .. })
                if self.lifecycle.expects_finish() =>
            {
                self.record(fates);
            }
            Message::Closing(message) => {
                let carried = &self.carried;
                let bits = &self.bits;
                let bits_per_doublet = usize::from(self.plan.perturbation.bits_per_doublet);
                let closing = RobotClosing {
                    confirmer: &self.plan.confirmer,
                    keepable: &|index| was_carried(carried, index),
                    key: &|fates: &FateLedger| fates.accepted_key(bits, bits_per_doublet),
                    // Raw bits are confirmed per post-processing block, never per session.
                    tags_cover_key: false,
                    verified: Outcome::Kept,
                    count_mismatch: |codewords, len| {
                        format!("Finish covers {codewords} doublets, the session has {len}")
                    },
                };
                self.lifecycle.on_message(message, &closing);
            }
            // Handshake and post-processing messages are not the endpoint's; a session
            // message after the run is a late duplicate.
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
        self.lifecycle.commands_applied += 1;
        self.lifecycle.command_arrived(step);
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
        let Some(missing_in_a_row) = self.lifecycle.command_missing(step) else {
            return;
        };
        if let Some(carried) = self.carried.get_mut((step / 2) as usize) {
            *carried = false;
        }
        self.second = None;
        let input = match self.last_nominal {
            Some(u) if missing_in_a_row <= self.plan.max_hold => u,
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
        let carried = was_carried(&self.carried, index);
        self.lifecycle.fates.record(index, kept && carried);
    }
}

/// Whether the robot applied doublet `index` with its bits (one beyond the session was not).
fn was_carried(carried: &[bool], index: u32) -> bool {
    carried.get(index as usize).copied().unwrap_or(false)
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
        robot.handle_input(RobotInput::Frame(Message::Session(
            SessionMessage::DoubletCommand {
                step,
                sample: [0.0; 3],
                first,
                second: Some(second),
                fates: FateWindow::default(),
            },
        )));
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
