//! The world of one simulated session: the plant and its sensors around the robot and the
//! controller on an ideal virtual link, and the eavesdropper listening — in either sensing
//! mode. It answers the robot's sample requests, drives the plant with what the robot
//! applies, and records what every party decided.

use std::collections::{BTreeMap, VecDeque};

use super::StepBits;
use super::trace::TraceRows;
use crate::config::{Config, EveStrategy};
use crate::eve::Eavesdropper;
use crate::pair::{Side, Surroundings};
use crate::private::{
    BitKind, DoubletBit, DoubletDecision, DoubletEavesdropper, DoubletSamples, EveDoublet,
    Perturbation, PrivateRun, likelihood::staged_llrs,
};
use crate::protocol::{
    Controller, ControllerEvent, ControllerInput, ControllerOutput, Message, Outcome, Robot,
    RobotInput, RobotOutput, SessionMessage, Time,
};
use crate::trajectory::Trajectory;
use crate::world::Scene;

/// What the sensors of a sensing mode observe, and who listens.
pub(super) enum Senses<'a> {
    /// The robot's odometry; the eavesdropper (if any) hears the messages.
    Odometry {
        /// The eavesdropper, when the run has one.
        eve: Option<Box<dyn Eavesdropper>>,
        /// Every message in the order a tap hears it, when asked for.
        transcript: Option<&'a mut Vec<Message>>,
    },
    /// The controller's own sensor and Eve's camera; both private-sensing eavesdroppers.
    Private(Box<PrivateSenses>),
}

/// Private sensing's sensors, eavesdroppers and bookkeeping.
pub(super) struct PrivateSenses {
    /// The `camera` and `commands` eavesdroppers.
    pub(super) eve: DoubletEavesdropper,
    /// The controller's decisions, waiting for the eavesdroppers' on the same doublet.
    pub(super) decided: VecDeque<DoubletDecision>,
    /// The eavesdroppers' decisions, by doublet.
    pub(super) heard: BTreeMap<u32, EveDoublet>,
    /// What the session carried.
    pub(super) run: PrivateRun,
}

/// The world of one simulated session.
pub(super) struct World<'a> {
    pub(super) config: &'a Config,
    pub(super) trajectory: Trajectory,
    pub(super) sample_time: f64,
    /// The plant and its sensors.
    pub(super) scene: Scene,
    pub(super) senses: Senses<'a>,
    /// `Σ_k ‖p(k) − r(k)‖` over `k = 1…N` (m).
    pub(super) tracking_error: f64,
    /// The applied bit and both decisions of every step `k ≤ N`.
    pub(super) log: Vec<StepBits>,
    pub(super) trace: TraceRows<'a>,
    pub(super) robot_outcome: Option<Outcome>,
    pub(super) controller_outcome: Option<Outcome>,
    /// Odometry: why the controller aborted (the run fails).
    pub(super) abort: Option<String>,
}

impl World<'_> {
    /// Sample instant `t_k`: the plant moves one period (from `k = 1`), the sensors observe
    /// it, and the robot — and in private sensing the controller — get their samples.
    fn sense(&mut self, now: Time, step: u32, robot: &mut Robot, controller: &mut Controller) {
        self.record_private(robot);
        if step > 0 {
            self.scene.step();
        }
        // No later step writes the rows before this one (in private sensing, the row before
        // it: a doublet's decision lands on its last step's row — or, while an eavesdropper
        // who smooths over later doublets has not decided one the controller has, that row).
        let settled = match &self.senses {
            Senses::Odometry { .. } => step,
            Senses::Private(p) => {
                let last = robot.plan().steps_per_doublet() - 1;
                let undecided_by_eve = p.decided.front().map_or(u32::MAX, |d| d.step + last);
                step.saturating_sub(1).min(undecided_by_eve)
            }
        };
        self.trace.complete_before(settled as usize);
        let observed = self.scene.observe();
        let (pose, measured, filmed) = (observed.pose, observed.measured, observed.filmed);
        let t = f64::from(step) * self.sample_time;
        let reference = self.trajectory.at(t).position;
        if step > 0 {
            self.tracking_error += (pose.xy() - reference).norm();
        }
        if let Some(row) = self.trace.row(step as usize) {
            row.k = step;
            row.t = t;
            row.reference = reference.into();
            row.pose = pose.into();
            row.measurement = measured.into();
            row.camera = filmed.map(Into::into);
        }
        match &mut self.senses {
            Senses::Odometry { .. } => {
                robot.handle_input(now, RobotInput::Sample { step, y: measured });
            }
            Senses::Private(p) => {
                if let Some(filmed) = filmed {
                    p.eve.film(step, filmed);
                }
                for frame in &observed.frames {
                    p.eve.film_frame(*frame);
                }
                p.collect();
                // The simulated robot has no odometry of its own: it would send none anyway.
                robot.handle_input(now, RobotInput::Sample { step, y: pose });
                controller.handle_input(
                    now,
                    ControllerInput::Sensor {
                        step,
                        pose: measured,
                    },
                );
            }
        }
    }

    /// Records, in the controller's order, every doublet both it and the eavesdroppers have
    /// decided (private sensing).
    pub(super) fn record_private(&mut self, robot: &Robot) {
        let Senses::Private(p) = &mut self.senses else {
            return;
        };
        while let Some(e) = p.decided.front().and_then(|d| p.heard.remove(&d.doublet)) {
            let d = p
                .decided
                .pop_front()
                .expect("paired with the front decision");
            let word = robot
                .carried_word(d.doublet)
                .expect("the robot carried every doublet the simulated controller decides");
            record(
                self.config,
                &d,
                &e,
                word,
                &mut p.run,
                &mut self.log,
                &mut self.trace,
            );
        }
    }
}

impl PrivateSenses {
    /// Takes the eavesdroppers' decisions.
    pub(super) fn collect(&mut self) {
        while let Some(doublet) = self.eve.poll() {
            self.heard.insert(doublet.doublet, doublet);
        }
    }
}

impl Surroundings<Robot, Controller> for World<'_> {
    fn robot_output(
        &mut self,
        now: Time,
        output: RobotOutput,
        robot: &mut Robot,
        controller: &mut Controller,
    ) {
        match output {
            RobotOutput::Sense { step } => self.sense(now, step, robot, controller),
            RobotOutput::Apply(actuation) => {
                self.scene.apply(actuation.wheels);
                let doublet = actuation.step / robot.plan().steps_per_doublet();
                if let Senses::Private(p) = &mut self.senses
                    && actuation.bit.is_some()
                    && let Some(word) = robot.carried_word(doublet)
                {
                    p.eve.reveal(doublet, word);
                }
                if let Some(row) = self.trace.row(actuation.step as usize) {
                    row.bit = actuation.bit;
                    if self.config.protocol.bits_per_doublet == 2
                        && matches!(self.senses, Senses::Private(_))
                    {
                        let m = Perturbation::of(self.config).bits_per_symbol();
                        row.bit_omega = actuation
                            .bit
                            .and(robot.carried_word(doublet))
                            .map(|word| (word >> m & 1) as u8);
                    }
                }
                if let Senses::Odometry { .. } = self.senses
                    && let Some(logged) = self.log.get_mut(actuation.step as usize)
                {
                    logged.bit = actuation.bit;
                }
            }
            RobotOutput::Finished(outcome) => self.robot_outcome = Some(outcome),
            RobotOutput::Transmit(_) => {}
        }
    }

    fn controller_output(
        &mut self,
        _now: Time,
        output: ControllerOutput,
        robot: &mut Robot,
        _controller: &mut Controller,
    ) {
        let ControllerOutput::Event(event) = output else {
            return;
        };
        match event {
            ControllerEvent::Decoded(d) => {
                if let Some(logged) = self.log.get_mut(d.step as usize) {
                    logged.bhat = d.bit;
                }
                if let Some(row) = self.trace.row(d.step as usize + 1) {
                    row.bhat = d.bit;
                    row.dhat = Some(d.estimate.deviation.into());
                    row.xhat = Some(d.estimate.state.into());
                }
            }
            ControllerEvent::Commanded { step, nominal } => {
                if let Some(row) = self.trace.row(step as usize) {
                    row.nominal = Some(nominal.into());
                }
            }
            ControllerEvent::DoubletCommanded {
                step,
                inputs,
                carries,
            } => {
                if let Senses::Private(p) = &mut self.senses {
                    p.run.doublets += 1;
                    p.run.gated += u32::from(self.config.protocol.enabled && !carries);
                }
                // The second nominal input holds over a three-step doublet's last two steps.
                for k in step..step + robot.plan().steps_per_doublet() {
                    let nominal = if k == step {
                        inputs.first
                    } else {
                        inputs.second
                    };
                    if let Some(row) = self.trace.row(k as usize) {
                        row.nominal = Some(nominal.into());
                    }
                }
            }
            ControllerEvent::DoubletDecided(decision) => {
                if let Senses::Private(p) = &mut self.senses {
                    p.decided.push_back(*decision);
                }
                self.record_private(robot);
            }
            ControllerEvent::Finished(outcome) => {
                if let (Senses::Odometry { .. }, Outcome::Aborted(reason)) =
                    (&self.senses, &outcome)
                {
                    self.abort = Some(reason.clone());
                }
                self.controller_outcome = Some(outcome);
            }
            ControllerEvent::Missing(_)
            | ControllerEvent::CodewordDecided { .. }
            | ControllerEvent::DoubletErased { .. } => {}
        }
    }

    fn heard(&mut self, from: Side, message: &Message) {
        match &mut self.senses {
            Senses::Odometry {
                eve, transcript, ..
            } => {
                if let Some(transcript) = transcript.as_deref_mut() {
                    transcript.push(message.clone());
                }
                let decision = eve.as_mut().and_then(|eve| eve.observe(message));
                if let (Side::Robot, Some(d)) = (from, decision) {
                    if let Some(logged) = self.log.get_mut(d.step as usize) {
                        logged.bhat_eve = d.bit;
                    }
                    if let Some(row) = self.trace.row(d.step as usize + 1) {
                        row.bhat_eve = d.bit;
                    }
                }
                if let Message::Session(SessionMessage::Command { step, u0, u1, .. }) = message
                    && let Some(row) = self.trace.row(*step as usize)
                {
                    row.u0 = Some(*u0);
                    row.u1 = Some(*u1);
                }
            }
            Senses::Private(p) => {
                p.eve.observe(message);
                p.collect();
            }
        }
    }

    fn done(&self) -> bool {
        self.abort.is_some() || (self.robot_outcome.is_some() && self.controller_outcome.is_some())
    }
}

/// Records a decided doublet's bits — the robot's, and every party's evidence — in the run,
/// the step log and the trace.
fn record(
    config: &Config,
    d: &DoubletDecision,
    e: &EveDoublet,
    word: u64,
    run: &mut PrivateRun,
    log: &mut [StepBits],
    trace: &mut TraceRows<'_>,
) {
    let perturbation = Perturbation::of(config);
    // Multilevel: each slice's LLR given the lower slices, as multistage reconciliation
    // leaves the controller them; binary: the marginal LLRs.
    let controller = if perturbation.levels > 2 {
        staged_llrs(&d.log_likelihoods, &perturbation, word)
    } else {
        d.evidence.llr
    };
    for (i, &controller) in controller.iter().enumerate().take(perturbation.key_bits()) {
        run.bits.push(DoubletBit {
            step: d.step,
            kind: BitKind::ALL[perturbation.dimension_of(i)],
            bit: (word >> i & 1) as u8,
            turn_rate: d.inputs.turn_rate(),
            controller,
            camera: e.camera_given_others.unwrap_or(e.camera).llr[i],
            commands: e
                .commands
                .map(|own| e.commands_given_others.unwrap_or(own).llr[i]),
            camera_separation: e.camera.separation[i],
            assumed_separation: d.assumed_separation[i],
            commands_separation: e.commands.map(|own| own.separation[i]),
        });
    }
    run.controller_samples.push(DoubletSamples {
        doublet: d.doublet,
        inputs: d.inputs,
        samples: d.samples,
        late: d.late,
        // Both dimensions' labels, whether or not the ω one rides.
        pattern: (word & ((1 << (2 * perturbation.bits_per_symbol())) - 1)) as usize,
    });
    let decide = |llr: f64| u8::from(llr < 0.0);
    let eve_llr = match config.eve_strategy() {
        EveStrategy::Commands => e.commands.map(|own| own.llr[0]),
        _ => Some(e.camera.llr[0]),
    };
    let logged = StepBits {
        bit: Some((word & 1) as u8),
        bhat: Some(decide(d.evidence.llr[0])),
        bhat_eve: eve_llr.filter(|_| config.eve.enabled).map(decide),
    };
    log[d.step as usize] = logged;
    if let Some(row) = trace.row((d.step + perturbation.steps() - 1) as usize) {
        row.bhat = logged.bhat;
        row.bhat_eve = logged.bhat_eve;
    }
}
