//! Private sensing's controller (docs/private-sensing.md, docs/protocol.md): tracks the
//! reference from its own pose sensor, commands each doublet from the sample at its start,
//! decides each bit from a calibrated true-noise likelihood of its samples around the
//! doublet, and decides the doublets' fates.

use std::collections::VecDeque;

use super::LateSample;
use super::decision::DoubletDecision;
use super::doublet::DoubletInputs;
use super::likelihood::{
    DoubletModel, DoubletView, PoseObservation, doublet_model, stated_camera_view,
};
use super::plan::PrivatePlan;
use crate::config::Config;
use crate::control::ReferenceTracker;
use crate::model::{Pose, Unicycle, unicycle_step};
use crate::protocol::controller::io::ControllerEvent;
use crate::protocol::controller::lifecycle::ControllerLifecycle;
use crate::protocol::controller::mode::ControllerMode;
use crate::protocol::plan::Agreed;
use crate::protocol::{Outcome, SessionMessage};

/// A doublet commanded and not yet resolved.
#[derive(Clone, Copy, Debug)]
struct Pending {
    doublet: u32,
    inputs: DoubletInputs,
    /// The wheels' nominal speed at its start under the prior lag (m/s, rad/s).
    entry: Unicycle,
    carries: bool,
    /// `y_c(Lj)` … `y_c(Lj+L)` (`L` steps per doublet; the last entry unused with two).
    samples: [Option<Pose>; 4],
    /// The robot's reports on steps `Lj` … `Lj+L−1`: applied or not, if heard (the last
    /// entry unused with two steps).
    applied: [Option<bool>; 3],
}

/// Steps the robot may report beyond a doublet's end before a report of the doublet that
/// has not come counts as lost (reordering on the network).
const REORDER_SLACK: u32 = 8;

/// Private sensing's part of a controller endpoint: the model it decides with, the
/// doublets in flight, and its view of the samples and the robot's reports.
pub(crate) struct PrivateController {
    plan: PrivatePlan,
    tracking: ReferenceTracker,
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
    /// Each doublet's decided bits `v | ω << m` (0 when not decided).
    decided: Vec<u64>,
    /// The wheels' nominal speed after the inputs commanded so far, through the prior lag
    /// (m/s, rad/s; at rest before the first): what the next doublet starts from. The bits'
    /// offsets leave none under the three-step shape; with two steps it is not used.
    wheels: Unicycle,
}

impl std::fmt::Debug for PrivateController {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Its decisions are key material: never printed.
        f.debug_struct("PrivateController")
            .field("next_doublet", &self.next_doublet)
            .field("next_sample", &self.next_sample)
            .field("reported", &self.reported)
            .field("pending", &self.pending.len())
            .finish_non_exhaustive()
    }
}

impl PrivateController {
    /// The controller of a validated private-sensing configuration: `doublets` to decide.
    pub(crate) fn new(config: &Config, agreed: &Agreed, plan: PrivatePlan, doublets: u32) -> Self {
        Self {
            tracking: ReferenceTracker::new(config, agreed.drive, agreed.sample_time),
            model: doublet_model(config),
            controller_std: config.sensing.controller_std,
            camera_std: config.modelled_camera_std(),
            pending: VecDeque::new(),
            next_doublet: 0,
            next_sample: 0,
            reported: 0,
            decided: vec![0; doublets as usize],
            wheels: Unicycle::zeros(),
            plan,
        }
    }

    /// The robot's report at step k: whether it applied command `k − 1`. Reports may come
    /// out of order (a doublet's two are sent back to back); one not heard by the time the
    /// robot reported [`REORDER_SLACK`] steps further, or the end, leaves its step unapplied.
    fn handle_measurement(
        &mut self,
        agreed: &Agreed,
        life: &mut ControllerLifecycle,
        step: u32,
        applied: Option<u32>,
        cursor: u32,
    ) {
        if step > agreed.steps {
            return;
        }
        life.robot_cursor = life.robot_cursor.max(cursor);
        self.reported = self.reported.max(step + 1);
        let length = self.plan.steps_per_doublet();
        if let Some(done) = step.checked_sub(1)
            && let Some(p) = self.pending.iter_mut().find(|p| p.doublet == done / length)
        {
            p.applied[(done % length) as usize].get_or_insert(applied == Some(done));
        }
        self.resolve(agreed, life);
    }

    /// Sample `y_c(k)`: recorded for the doublets around it; a doublet's first sample
    /// commands it (its second input from the open-loop prediction, never from the
    /// mid-doublet sample, which carries the bit); `y_c(N)` goes with the stop command.
    fn handle_sample(
        &mut self,
        agreed: &Agreed,
        life: &mut ControllerLifecycle,
        step: u32,
        pose: Pose,
    ) {
        let fresh = step >= self.next_sample && step <= agreed.steps;
        if !life.running() || !fresh || !pose.iter().all(|v| v.is_finite()) {
            return;
        }
        self.next_sample = step + 1;
        let length = self.plan.steps_per_doublet();
        for p in &mut self.pending {
            if let Some(slot) = step
                .checked_sub(length * p.doublet)
                .filter(|&i| i <= length)
                .and_then(|i| p.samples.get_mut(i as usize))
            {
                *slot = Some(pose);
            }
        }
        // Doublets whose first sample never came were never commanded.
        let doublets = agreed.steps / length;
        while self.next_doublet < doublets && length * self.next_doublet < step {
            life.fates.record(self.next_doublet, false);
            life.emit(ControllerEvent::DoubletErased {
                doublet: self.next_doublet,
            });
            self.next_doublet += 1;
        }
        self.command(agreed, life, step, pose);
        self.resolve(agreed, life);
    }

    fn command(&mut self, agreed: &Agreed, life: &mut ControllerLifecycle, step: u32, pose: Pose) {
        let t = agreed.sample_time;
        let length = self.plan.steps_per_doublet();
        let (first, second) = if step >= agreed.steps {
            (Unicycle::zeros(), None)
        } else if self.plan.is_later_step(step, agreed.steps) {
            return; // mid-doublet: its input went with the first
        } else {
            let first = self.tracking.command(&pose, step);
            let finite = |u: &Unicycle| u.iter().all(|v| v.is_finite());
            if !finite(&first) {
                // A finite but absurd pose (e.g. 1e308 m) overflows the controller's state.
                return life.abort(format!("step {step}: the tracking command is not finite"));
            }
            if step + length <= agreed.steps {
                let predicted = unicycle_step(&pose, &first, t);
                let second = self.tracking.command(&predicted, step + 1);
                if !finite(&second) {
                    return life.abort(format!("step {step}: the tracking command is not finite"));
                }
                let inputs = DoubletInputs { first, second };
                let carries = self.plan.carries(agreed.enabled, &inputs);
                let entry = self.wheels;
                (_, self.wheels) = inputs.nominal_transient(entry, length, self.model.lag, t);
                self.pending.push_back(Pending {
                    doublet: step / length,
                    inputs,
                    entry,
                    carries,
                    samples: [Some(pose), None, None, None],
                    applied: [None; 3],
                });
                self.next_doublet = step / length + 1;
                life.emit(ControllerEvent::DoubletCommanded {
                    step,
                    inputs,
                    carries,
                });
                (first, Some(second))
            } else {
                life.emit(ControllerEvent::Commanded {
                    step,
                    nominal: first,
                });
                (first, None)
            }
        };
        life.send(SessionMessage::DoubletCommand {
            step,
            sample: pose.into(),
            first: first.into(),
            second: second.map(Into::into),
            fates: life.fates.window(life.robot_cursor),
        });
    }

    /// Resolves, in order, every doublet whose samples and measurements are all in or
    /// known lost; once every step is, closes the session.
    fn resolve(&mut self, agreed: &Agreed, life: &mut ControllerLifecycle) {
        let length = self.plan.steps_per_doublet();
        while let Some(&p) = self.pending.front() {
            let end = length * p.doublet + length;
            let reports = &p.applied[..length as usize];
            let reports_settled = reports.iter().all(Option::is_some)
                || self.reported > (end + REORDER_SLACK).min(agreed.steps);
            if self.next_sample <= end || !reports_settled {
                break;
            }
            self.pending.pop_front();
            let all_applied = reports.iter().all(|r| *r == Some(true));
            let samples = &p.samples[..=length as usize];
            let complete = if all_applied && samples.iter().all(Option::is_some) {
                let mut all = [Pose::zeros(); 4];
                for (slot, sample) in all.iter_mut().zip(samples.iter().flatten()) {
                    *slot = *sample;
                }
                Some(all)
            } else {
                None
            };
            match (p.carries, complete) {
                (false, _) => life.fates.record(p.doublet, false),
                (true, Some(samples)) => self.decide(life, &p, samples),
                (true, None) => {
                    life.fates.record(p.doublet, false);
                    life.emit(ControllerEvent::DoubletErased { doublet: p.doublet });
                }
            }
        }
        let over = self.next_sample > agreed.steps && self.reported > agreed.steps;
        if life.running() && over && self.pending.is_empty() {
            let key = life
                .fates
                .accepted_key(&self.decided, self.plan.perturbation.key_bits());
            life.close(agreed.confirmer.clone(), key, false, Outcome::Kept);
        }
    }

    /// Decides doublet `p` from its samples `y_c(Lj) … y_c(Lj+L)` (the first `L + 1` of
    /// `samples`).
    fn decide(&mut self, life: &mut ControllerLifecycle, p: &Pending, samples: [Pose; 4]) {
        let length = self.plan.steps_per_doublet() as usize;
        let own = |k: usize| PoseObservation::new(samples[k], self.controller_std);
        let view = DoubletView {
            start: own(0),
            middle: Some(own(1)),
            late: (length == 3).then(|| own(2)),
            end: Some(own(length)),
            entry: Some(p.entry),
        };
        let taken = &samples[..=length];
        let assumed = stated_camera_view(taken, self.controller_std, self.camera_std);
        let (evidence, log_likelihoods) = self.model.evidence_and_likelihoods(&p.inputs, &view);
        let decision = DoubletDecision {
            doublet: p.doublet,
            step: self.plan.steps_per_doublet() * p.doublet,
            inputs: p.inputs,
            evidence,
            log_likelihoods: if self.model.perturbation.levels > 2 {
                log_likelihoods[..self.model.perturbation.patterns()].to_vec()
            } else {
                Vec::new()
            },
            assumed_separation: self.model.sizing_separations(&p.inputs, &assumed),
            samples: [samples[0], samples[1], samples[length]],
            late: (length == 3).then(|| LateSample {
                sample: samples[2],
                entry: p.entry,
            }),
        };
        self.decided[p.doublet as usize] = decision.evidence.bits();
        life.fates.record(p.doublet, true);
        life.emit(ControllerEvent::DoubletDecided(Box::new(decision)));
    }
}

impl ControllerMode for PrivateController {
    fn on_message(
        &mut self,
        agreed: &Agreed,
        life: &mut ControllerLifecycle,
        message: &SessionMessage,
    ) {
        if let &SessionMessage::PrivateMeasurement {
            step,
            applied_step,
            fate_cursor,
        } = message
            && life.running()
        {
            self.handle_measurement(agreed, life, step, applied_step, fate_cursor);
        }
    }

    fn on_sensor(
        &mut self,
        agreed: &Agreed,
        life: &mut ControllerLifecycle,
        step: u32,
        pose: Pose,
    ) {
        self.handle_sample(agreed, life, step, pose);
    }

    fn uses_sensor(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::{
        Controller, ControllerInput, ControllerOutput, SessionPlan, Time, Timing,
    };

    #[test]
    fn a_doublets_reports_may_come_in_either_order() {
        let config = Config::from_toml(
            "[sensing]\nmode = \"private\"\n[protocol]\nmax_turn_rate = 1000.0\n",
            "test",
        )
        .unwrap();
        let plan = SessionPlan::from_config(&config, 1);
        let mut controller = Controller::new(&config, plan, Timing::default(), Time::ZERO);
        let report = |step, applied_step| {
            ControllerInput::Frame(
                SessionMessage::PrivateMeasurement {
                    step,
                    applied_step,
                    fate_cursor: 0,
                }
                .into(),
            )
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
            controller.handle_input(Time::ZERO, input);
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
