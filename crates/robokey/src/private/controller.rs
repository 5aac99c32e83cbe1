//! The controller endpoint of private sensing (docs/private-sensing.md, docs/protocol.md):
//! tracks the reference from its own pose sensor, commands each doublet from the sample at
//! its start, decides each bit from a calibrated true-noise likelihood of its samples around
//! the doublet, and sends the fates.

use std::collections::VecDeque;

use super::doublet::DoubletInputs;
use super::likelihood::{BitEvidence, DoubletModel, DoubletView, PoseObservation};
use super::plan::PrivatePlan;
use super::session::doublet_model;
use crate::config::Config;
use crate::control::{TrackingController, TrackingGains};
use crate::model::{Pose, Unicycle, unicycle_step};
use crate::protocol::closing::ControllerLifecycle;
use crate::protocol::{
    ControllerEvent, ControllerInput, ControllerOutput, FateLedger, KeyBits, Message, Outcome,
    SessionMessage,
};
use crate::trajectory::Trajectory;

/// What the controller made of one carrying doublet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DoubletDecision {
    /// Doublet index j.
    pub doublet: u32,
    /// Its first step `2j`.
    pub step: u32,
    /// Its public inputs.
    pub inputs: DoubletInputs,
    /// The controller's LLR and separation of each bit; the bit is the LLR's sign
    /// (`ln P(view|0) − ln P(view|1)`, 1 when negative).
    pub evidence: BitEvidence,
    /// Each bit's separation under the camera Eve's model as the controller can compute it
    /// — her stated camera noise around its own samples — which sizes the key.
    pub assumed_separation: [f64; 2],
}

/// A doublet commanded and not yet resolved.
#[derive(Clone, Copy, Debug)]
struct Pending {
    doublet: u32,
    inputs: DoubletInputs,
    carries: bool,
    /// `y_c(2j)`, `y_c(2j+1)`, `y_c(2j+2)`.
    samples: [Option<Pose>; 3],
    /// The robot's reports on steps `2j` and `2j+1`: applied or not, if heard.
    applied: [Option<bool>; 2],
}

/// Steps the robot may report beyond a doublet's end before a report of the doublet that
/// has not come counts as lost (reordering on the network).
const REORDER_SLACK: u32 = 8;

/// The controller side of a private-sensing session. It takes [`ControllerInput`]s — the
/// robot's frames and its own sensor's samples — and emits [`ControllerOutput`]s.
#[derive(Debug)]
pub struct PrivateControllerEndpoint {
    plan: PrivatePlan,
    trajectory: Trajectory,
    tracking: TrackingController,
    model: DoubletModel,
    controller_std: [f64; 3],
    camera_std: [f64; 3],
    pending: VecDeque<Pending>,
    /// The next doublet to command; one whose start sample never came is dropped.
    next_doublet: u32,
    /// Sensor samples before this step are stale.
    next_sample: u32,
    /// One past the latest step the robot reported on.
    reported: u32,
    fates: FateLedger,
    /// Each doublet's decided bits `v | ω << 1` (0 when not decided).
    decided: Vec<u64>,
    robot_cursor: u32,
    lifecycle: ControllerLifecycle,
    key: KeyBits,
}

impl PrivateControllerEndpoint {
    /// A controller for a validated private-sensing configuration and its plan.
    #[must_use]
    pub fn new(config: &Config, plan: PrivatePlan) -> Self {
        let c = &config.controller;
        let gains = TrackingGains {
            kp: c.kp,
            kd: c.kd,
            xi_eps: c.xi_eps,
            wheel_limit: c.wheel_limit,
        };
        Self {
            trajectory: config.trajectory(),
            tracking: TrackingController::new(gains, plan.drive, plan.sample_time),
            model: doublet_model(config),
            controller_std: config.sensing.controller_std,
            camera_std: config.eve.camera_std,
            pending: VecDeque::new(),
            next_doublet: 0,
            next_sample: 0,
            reported: 0,
            fates: FateLedger::new(plan.doublets()),
            decided: vec![0; plan.doublets() as usize],
            robot_cursor: 0,
            lifecycle: ControllerLifecycle::new(),
            key: KeyBits::default(),
            plan,
        }
    }

    /// Feeds one input.
    pub fn handle_input(&mut self, input: ControllerInput) {
        match input {
            ControllerInput::Frame(message) => self.handle_message(message),
            ControllerInput::Sensor { step, pose } => self.handle_sample(step, pose),
            ControllerInput::Timeout => self.lifecycle.on_timeout(),
        }
    }

    /// The next output, if any.
    pub fn poll_output(&mut self) -> Option<ControllerOutput> {
        self.lifecycle.poll()
    }

    /// The controller's decisions on the kept doublets, `[v, ω]` each (complete once the
    /// session has finished): the raw bits reconciliation corrects.
    #[must_use]
    pub fn key(&self) -> &[u8] {
        &self.key
    }

    /// The session plan.
    #[must_use]
    pub fn plan(&self) -> &PrivatePlan {
        &self.plan
    }

    /// Whether the session is over.
    #[must_use]
    pub fn is_done(&self) -> bool {
        self.lifecycle.is_done()
    }

    fn handle_message(&mut self, message: Message) {
        match message {
            Message::Session(SessionMessage::PrivateMeasurement {
                step,
                applied_step,
                fate_cursor,
            }) if self.lifecycle.running() => {
                self.handle_measurement(step, applied_step, fate_cursor);
            }
            Message::Closing(message) => self.lifecycle.on_message(message),
            // Handshake and post-processing messages are not the endpoint's; a session
            // message after the run is a late duplicate.
            _ => {}
        }
    }

    /// The robot's report at step k: whether it applied command `k − 1`. Reports may come
    /// out of order (a doublet's two are sent back to back); one not heard by the time the
    /// robot reported [`REORDER_SLACK`] steps further, or the end, leaves its step unapplied.
    fn handle_measurement(&mut self, step: u32, applied: Option<u32>, cursor: u32) {
        if step > self.plan.steps {
            return;
        }
        self.robot_cursor = self.robot_cursor.max(cursor);
        self.reported = self.reported.max(step + 1);
        if let Some(done) = step.checked_sub(1)
            && let Some(p) = self.pending.iter_mut().find(|p| p.doublet == done / 2)
        {
            p.applied[(done % 2) as usize].get_or_insert(applied == Some(done));
        }
        self.resolve();
    }

    /// Sample `y_c(k)`: recorded for the doublets around it; a doublet's first sample
    /// commands it (its second input from the open-loop prediction, never from the
    /// mid-doublet sample, which carries the bit); `y_c(N)` goes with the stop command.
    fn handle_sample(&mut self, step: u32, pose: Pose) {
        let fresh = step >= self.next_sample && step <= self.plan.steps;
        if !self.lifecycle.running() || !fresh || !pose.iter().all(|v| v.is_finite()) {
            return;
        }
        self.next_sample = step + 1;
        for p in &mut self.pending {
            if let Some(slot) = step
                .checked_sub(2 * p.doublet)
                .and_then(|i| p.samples.get_mut(i as usize))
            {
                *slot = Some(pose);
            }
        }
        // Doublets whose first sample never came were never commanded.
        while self.next_doublet < self.plan.doublets() && 2 * self.next_doublet < step {
            self.fates.record(self.next_doublet, false);
            self.lifecycle.emit(ControllerEvent::DoubletErased {
                doublet: self.next_doublet,
            });
            self.next_doublet += 1;
        }
        self.command(step, pose);
        self.resolve();
    }

    fn command(&mut self, step: u32, pose: Pose) {
        let t = self.plan.sample_time;
        let reference = |k: u32| self.trajectory.at(f64::from(k) * t);
        let (first, second) = if step >= self.plan.steps {
            (Unicycle::zeros(), None)
        } else if step % 2 == 1 {
            return; // mid-doublet: its input went with the first
        } else {
            let first = self.tracking.command(&pose, &reference(step));
            if self.plan.starts_doublet(step) {
                let predicted = unicycle_step(&pose, &first, t);
                let second = self.tracking.command(&predicted, &reference(step + 1));
                let inputs = DoubletInputs { first, second };
                let carries = self.plan.carries(&inputs);
                self.pending.push_back(Pending {
                    doublet: step / 2,
                    inputs,
                    carries,
                    samples: [Some(pose), None, None],
                    applied: [None; 2],
                });
                self.next_doublet = step / 2 + 1;
                self.lifecycle.emit(ControllerEvent::DoubletCommanded {
                    step,
                    inputs,
                    carries,
                });
                (first, Some(second))
            } else {
                self.lifecycle.emit(ControllerEvent::Commanded {
                    step,
                    nominal: first,
                });
                (first, None)
            }
        };
        self.lifecycle.send(
            SessionMessage::DoubletCommand {
                step,
                sample: pose.into(),
                first: first.into(),
                second: second.map(Into::into),
                fates: self.fates.window(self.robot_cursor),
            }
            .into(),
        );
    }

    /// Resolves, in order, every doublet whose samples and measurements are all in or
    /// known lost; once every step is, closes the session.
    fn resolve(&mut self) {
        while let Some(&p) = self.pending.front() {
            let end = 2 * p.doublet + 2;
            let reports_settled = p.applied.iter().all(Option::is_some)
                || self.reported > (end + REORDER_SLACK).min(self.plan.steps);
            if self.next_sample <= end || !reports_settled {
                break;
            }
            self.pending.pop_front();
            let complete = match p.samples {
                [Some(start), Some(middle), Some(end)] if p.applied == [Some(true); 2] => {
                    Some([start, middle, end])
                }
                _ => None,
            };
            match (p.carries, complete) {
                (false, _) => self.fates.record(p.doublet, false),
                (true, Some(samples)) => self.decide(&p, samples),
                (true, None) => {
                    self.fates.record(p.doublet, false);
                    self.lifecycle
                        .emit(ControllerEvent::DoubletErased { doublet: p.doublet });
                }
            }
        }
        let over = self.next_sample > self.plan.steps && self.reported > self.plan.steps;
        if self.lifecycle.running() && over && self.pending.is_empty() {
            self.key = self.fates.accepted_key(
                &self.decided,
                usize::from(self.plan.perturbation.bits_per_doublet),
            );
            self.lifecycle
                .close(self.plan.confirmer.clone(), &self.fates, &[], Outcome::Kept);
        }
    }

    fn decide(&mut self, p: &Pending, samples: [Pose; 3]) {
        let own = |k: usize| PoseObservation::new(samples[k], self.controller_std);
        let stated_camera = |k: usize| PoseObservation::new(samples[k], self.camera_std);
        let view = DoubletView {
            start: own(0),
            middle: Some(own(1)),
            end: Some(own(2)),
        };
        // The camera Eve's view as the controller can model it: her stated noise around
        // its own samples, fused with the boundary samples the commands reveal.
        let assumed = DoubletView {
            start: own(0).fuse(&stated_camera(0)),
            middle: Some(stated_camera(1)),
            end: Some(own(2).fuse(&stated_camera(2))),
        };
        let decision = DoubletDecision {
            doublet: p.doublet,
            step: 2 * p.doublet,
            inputs: p.inputs,
            evidence: self.model.evidence(&p.inputs, &view),
            assumed_separation: self.model.separations(&p.inputs, &assumed),
        };
        self.decided[p.doublet as usize] = decision.evidence.bits();
        self.fates.record(p.doublet, true);
        self.lifecycle
            .emit(ControllerEvent::DoubletDecided(decision));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_doublets_reports_may_come_in_either_order() {
        let config = Config::from_toml(
            "[sensing]\nmode = \"private\"\n[protocol]\nmax_turn_rate = 1000.0\n",
            "test",
        )
        .unwrap();
        let mut controller =
            PrivateControllerEndpoint::new(&config, PrivatePlan::from_config(&config, 1));
        let report = |step, applied_step| {
            ControllerInput::Frame(Message::Session(SessionMessage::PrivateMeasurement {
                step,
                applied_step,
                fate_cursor: 0,
            }))
        };
        for input in [
            ControllerInput::Sensor {
                step: 0,
                pose: Pose::zeros(),
            },
            report(0, None),
            ControllerInput::Sensor {
                step: 1,
                pose: Pose::new(0.001, 0.0, 0.0),
            },
            ControllerInput::Sensor {
                step: 2,
                pose: Pose::new(0.002, 0.0, 0.0),
            },
            report(2, Some(1)),
            report(1, Some(0)),
        ] {
            controller.handle_input(input);
        }
        let decided: Vec<u32> = std::iter::from_fn(|| controller.poll_output())
            .filter_map(|o| match o {
                ControllerOutput::Event(ControllerEvent::DoubletDecided(d)) => Some(d.doublet),
                _ => None,
            })
            .collect();
        assert_eq!(decided, [0]);
    }
}
