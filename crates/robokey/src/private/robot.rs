//! Private sensing's robot (docs/private-sensing.md, docs/protocol.md): applies `u + s·Δ`
//! then `u' − s·Δ` (with a prior lag, `u + s·Δ`, `u' − (1 + a)·s·Δ`, `u' + a·s·Δ`) from each
//! doublet's nominal inputs, and reports which command it applied — never a pose.

use rand::{CryptoRng, RngExt};

use super::doublet::DoubletInputs;
use super::plan::PrivatePlan;
use crate::model::{Pose, Unicycle};
use crate::protocol::plan::Agreed;
use crate::protocol::robot::io::Actuation;
use crate::protocol::robot::lifecycle::{ClosingRules, RobotLifecycle};
use crate::protocol::robot::mode::RobotMode;
use crate::protocol::{FateLedger, FateWindow, KeyBits, Outcome, SessionMessage};

/// Private sensing's part of a robot endpoint: each doublet's bits, which doublets it
/// carried, the doublet in flight and the input it holds through a short gap.
pub(crate) struct PrivateRobot {
    plan: PrivatePlan,
    /// Each doublet's bits as `v | ω << m` (`m = log₂ levels` bits per symbol label), drawn
    /// up front.
    bits: zeroize::Zeroizing<Vec<u64>>,
    /// Whether the robot applied doublet j with its bits (not gated, not erased).
    carried: Vec<bool>,
    /// The inputs for the later steps of the doublet in flight, with their steps, in order.
    later: Vec<(u32, Unicycle)>,
    /// The last nominal input received: held for up to `max_hold` missing steps.
    last_nominal: Option<Unicycle>,
}

impl PrivateRobot {
    /// Draws two symbol labels per doublet, each uniform over the alphabet's `levels` (v
    /// and ω; the ω label is used with two dimensions) for `doublets` doublets from
    /// `key_source`, a CSPRNG: the OS generator in deployment, a seeded stream in
    /// simulation.
    pub(crate) fn new<R: CryptoRng + ?Sized>(
        plan: PrivatePlan,
        doublets: u32,
        key_source: &mut R,
    ) -> Self {
        let levels = plan.perturbation.levels;
        let m = plan.perturbation.bits_per_symbol();
        let bits: Vec<u64> = (0..doublets)
            .map(|_| {
                let v = key_source.random_range(0..levels);
                let omega = key_source.random_range(0..levels);
                u64::from(v) | u64::from(omega) << m
            })
            .collect();
        Self {
            bits: bits.into(),
            carried: vec![false; doublets as usize],
            later: Vec::new(),
            last_nominal: None,
            plan,
        }
    }

    fn apply(
        agreed: &Agreed,
        life: &mut RobotLifecycle,
        step: u32,
        input: Unicycle,
        bit: Option<u8>,
        erased: bool,
    ) {
        life.apply(Actuation {
            step,
            wheels: agreed.drive.to_wheels(input),
            bit,
            erased,
        });
    }

    /// The doublet (or lone last step) starting at `step`: applies `u + s·Δ` now and keeps
    /// the later steps' inputs (`u' − s·Δ`, or `u' − (1 + a)·s·Δ` and `u' + a·s·Δ`) for the
    /// next steps. A command whose shape does not fit the step, or any of whose derivable
    /// inputs is not finite or beyond the wheel limit, is treated as lost.
    fn command(
        &mut self,
        agreed: &Agreed,
        life: &mut RobotLifecycle,
        step: u32,
        first: Unicycle,
        second: Option<Unicycle>,
    ) {
        let length = self.plan.steps_per_doublet();
        let starts_doublet = step.is_multiple_of(length) && step + length <= agreed.steps;
        let inputs = match second {
            Some(second) if starts_doublet => Some(DoubletInputs { first, second }),
            None if !starts_doublet => None,
            _ => return self.on_missing(agreed, life, step),
        };
        if !self.is_allowed(agreed, first, inputs.as_ref()) {
            return self.on_missing(agreed, life, step);
        }
        life.commands_applied += 1;
        life.command_arrived(step);
        let Some(inputs) = inputs else {
            self.last_nominal = Some(first);
            return Self::apply(agreed, life, step, first, None, false);
        };
        let j = (step / length) as usize;
        let carries = self.plan.carries(agreed.enabled, &inputs);
        let offset = if carries {
            let pattern = self.plan.perturbation.pattern(self.bits[j]);
            self.plan.perturbation.offset(pattern)
        } else {
            Unicycle::zeros()
        };
        self.carried[j] = carries;
        let applied = inputs.applied_steps(self.plan.perturbation.step_offsets(offset));
        self.later = (1..length)
            .map(|i| (step + i, applied[i as usize]))
            .collect();
        self.last_nominal = Some(inputs.second);
        let bit = self
            .carried_word(step / length)
            .map(|word| (word & 1) as u8);
        Self::apply(agreed, life, step, applied[0], bit, false);
    }

    /// Whether every input the robot could derive from a command is finite and within its
    /// wheel limit: for every bit pattern, gated or not, so that whether a step is erased
    /// never depends on the bit.
    fn is_allowed(&self, agreed: &Agreed, first: Unicycle, inputs: Option<&DoubletInputs>) -> bool {
        let within = |u: Unicycle| {
            agreed
                .drive
                .to_wheels(u)
                .iter()
                .all(|w| w.abs() <= agreed.wheel_limit) // also rejects NaN
        };
        let Some(inputs) = inputs else {
            return within(first);
        };
        let perturbation = &self.plan.perturbation;
        let steps = perturbation.steps() as usize;
        (0..perturbation.patterns())
            .map(|h| perturbation.offset(h))
            .chain([Unicycle::zeros()])
            .all(|offset| {
                inputs.applied_steps(perturbation.step_offsets(offset))[..steps]
                    .iter()
                    .all(|&u| within(u))
            })
    }

    /// Records the fates of a window; a doublet the robot did not carry is never kept.
    fn record(&self, life: &mut RobotLifecycle, fates: FateWindow) {
        for (index, kept) in fates.iter() {
            life.fates.record(index, kept && self.keepable(index));
        }
    }
}

impl ClosingRules for PrivateRobot {
    /// One beyond the session was not carried.
    fn keepable(&self, index: u32) -> bool {
        self.carried.get(index as usize).copied().unwrap_or(false)
    }

    fn key(&self, fates: &FateLedger) -> KeyBits {
        fates.accepted_key(&self.bits, self.plan.perturbation.key_bits())
    }

    /// Raw bits are confirmed per post-processing block, never per session.
    fn tags_cover_key(&self) -> bool {
        false
    }

    fn verified(&self) -> Outcome {
        Outcome::Kept
    }

    fn count_mismatch(&self, codewords: u32, len: u32) -> String {
        format!("Finish covers {codewords} doublets, the session has {len}")
    }
}

impl RobotMode for PrivateRobot {
    /// Reports which command was applied before `t_k`; applies a doublet's later inputs,
    /// or its fallback when the doublet's command never came; at `k = N` stops the wheels
    /// (the robot owns the clock: the stop command only carries the controller's last
    /// sample and fates).
    fn on_sample(&mut self, agreed: &Agreed, life: &mut RobotLifecycle, step: u32, _y: &Pose) {
        let applied_step = life.applied_step.take();
        let fate_cursor = life.fates.cursor();
        life.send(SessionMessage::PrivateMeasurement {
            step,
            applied_step,
            fate_cursor,
        });
        if !life.awaits(step) {
            return;
        }
        if step >= agreed.steps {
            life.stop_wheels(step);
            life.next_command = step + 1;
            life.end_run();
        } else if self.plan.is_later_step(step, agreed.steps) {
            // A later step of a doublet: its input came with the first.
            let next = (!self.later.is_empty()).then(|| self.later.remove(0));
            match next.filter(|(s, _)| *s == step) {
                Some((_, input)) => {
                    life.commands_applied += 1;
                    life.command_arrived(step);
                    let doublet = step / self.plan.steps_per_doublet();
                    let bit = self.carried_word(doublet).map(|word| (word & 1) as u8);
                    Self::apply(agreed, life, step, input, bit, false);
                }
                None => self.on_missing(agreed, life, step),
            }
        }
    }

    fn on_message(&mut self, agreed: &Agreed, life: &mut RobotLifecycle, message: &SessionMessage) {
        let &SessionMessage::DoubletCommand {
            step,
            first,
            second,
            fates,
            ..
        } = message
        else {
            return;
        };
        if life.expects_command() {
            // Otherwise stale, duplicate, from the future, or not a command step.
            let commanded = !self.plan.is_later_step(step, agreed.steps);
            if step == life.next_command && step < agreed.steps && commanded {
                self.record(life, fates);
                self.command(agreed, life, step, first.into(), second.map(Unicycle::from));
            }
        } else if life.expects_finish() {
            // The stop command: its fates.
            self.record(life, fates);
        }
    }

    /// The robot holds the last nominal input for up to `max_hold` steps, then stops; a
    /// doublet with a missing step carries no bit.
    fn on_missing(&mut self, agreed: &Agreed, life: &mut RobotLifecycle, step: u32) {
        let Some(missing_in_a_row) = life.command_missing(step) else {
            return;
        };
        let doublet = step / self.plan.steps_per_doublet();
        if let Some(carried) = self.carried.get_mut(doublet as usize) {
            *carried = false;
        }
        self.later.clear();
        let input = match self.last_nominal {
            Some(u) if missing_in_a_row <= agreed.max_hold => u,
            _ => Unicycle::zeros(),
        };
        Self::apply(agreed, life, step, input, None, true);
    }

    fn carried_word(&self, doublet: u32) -> Option<u64> {
        self.keepable(doublet).then(|| self.bits[doublet as usize])
    }
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;

    use crate::config::Config;
    use crate::protocol::robot::testing::{drain, next_sample};
    use crate::protocol::{
        Actuation, FateWindow, Robot, RobotInput, RobotOutput, SessionMessage, SessionPlan, Timing,
    };

    fn robot(seed: u64) -> Robot {
        robot_with(seed, "")
    }

    fn robot_with(seed: u64, extra: &str) -> Robot {
        let config =
            Config::from_toml(&format!("[sensing]\nmode = \"private\"\n{extra}"), "test").unwrap();
        let plan = SessionPlan::from_config(&config, 1);
        let mut key_source = rand::rngs::ChaCha20Rng::seed_from_u64(seed);
        Robot::new(
            plan,
            Timing::default(),
            &mut key_source,
            crate::protocol::Time::ZERO,
        )
    }

    /// Offers the doublet that starts at the robot's next even sample; returns what it
    /// applied first (its second step is applied at the next sample).
    fn offer(robot: &mut Robot, first: [f64; 2], second: [f64; 2]) -> Actuation {
        let (step, now) = std::iter::repeat_with(|| next_sample(robot))
            .find(|(step, _)| step % 2 == 0)
            .expect("a doublet's first step");
        robot.handle_input(
            now,
            RobotInput::Frame(
                SessionMessage::DoubletCommand {
                    step,
                    sample: [0.0; 3],
                    first,
                    second: Some(second),
                    fates: FateWindow::default(),
                }
                .into(),
            ),
        );
        drain(robot, now)
            .into_iter()
            .find_map(|o| match o {
                RobotOutput::Apply(a) => Some(a),
                _ => None,
            })
            .expect("an actuation")
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
                let held = robot.plan().agreed.drive.to_wheels([0.1, 0.2].into());
                assert_eq!(erased.wheels, held);
                let _ = offer(&mut robot, [0.1, 0.2], [0.1, 0.2]);
            }
        }
    }

    /// With four levels the outermost symbol `±3/√5·Δv` must fit too: v = 0.755 m/s fits
    /// `v + Δv` (37.6 rad/s) but not `v + 1.342·Δv` (38.2 rad/s), so a binary robot applies
    /// the doublet and a 4-level one erases it whatever its symbol.
    #[test]
    fn every_symbol_of_the_alphabet_is_within_the_wheel_limit() {
        for seed in 0..8 {
            let binary = offer(&mut robot(seed), [0.755, 0.0], [0.755, 0.0]);
            assert!(!binary.erased);
            let mut four = robot_with(seed, "[protocol]\nlevels = 4\n");
            let erased = offer(&mut four, [0.755, 0.0], [0.755, 0.0]);
            assert!(erased.erased && erased.bit.is_none(), "seed {seed}");
            assert!(!offer(&mut four, [0.1, 0.2], [0.1, 0.2]).erased);
        }
    }
}
