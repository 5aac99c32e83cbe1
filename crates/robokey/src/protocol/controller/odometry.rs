//! The odometry mode's controller (docs/model.md, docs/protocol.md): tracks the reference
//! from the robot's measurements, offers command pairs, decodes the robot's choices with the
//! unknown-input observer, and decides each codeword's fate.

use super::ControllerEvent;
use super::lifecycle::ControllerLifecycle;
use super::mode::ControllerMode;
use crate::config::{Config, Feedback};
use crate::control::ReferenceTracker;
use crate::model::{Pose, Unicycle, WheelSpeeds};
use crate::observer::{Observer, ObserverParams};
use crate::protocol::assembler::CodewordAssembler;
use crate::protocol::decoder::StepDecoder;
use crate::protocol::plan::{Agreed, OdometryPlan};
use crate::protocol::{Outcome, SessionMessage};

/// The odometry mode's part of a controller endpoint.
pub(crate) struct OdometryController {
    plan: OdometryPlan,
    tracking: ReferenceTracker,
    feedback: Feedback,
    decoder: StepDecoder,
    assembler: CodewordAssembler,
    /// The decoded message of every decided codeword: key material.
    decoded: zeroize::Zeroizing<Vec<u64>>,
}

impl std::fmt::Debug for OdometryController {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Key material (decoded messages) is never printed.
        f.debug_struct("OdometryController")
            .field("next_measurement", &self.decoder.next_measurement())
            .field("decoded_codewords", &self.decoded.len())
            .finish_non_exhaustive()
    }
}

impl OdometryController {
    /// The controller of a validated configuration: `units` codewords to decide.
    pub(crate) fn new(config: &Config, agreed: &Agreed, plan: OdometryPlan, units: u32) -> Self {
        let observer = Observer::new(&observer_params(config)).expect("validated observer.m");
        Self {
            tracking: ReferenceTracker::new(config, agreed.drive, agreed.sample_time),
            feedback: config.controller.feedback,
            decoder: StepDecoder::new(agreed.drive, observer, plan.delta, agreed.enabled),
            assembler: CodewordAssembler::new(plan.code.n() as u32, units),
            decoded: zeroize::Zeroizing::new(Vec::with_capacity(units as usize)),
            plan,
        }
    }

    fn on_measurement(
        &mut self,
        agreed: &Agreed,
        life: &mut ControllerLifecycle,
        step: u32,
        y: Pose,
        applied: Option<u32>,
        cursor: u32,
    ) {
        if step > agreed.steps || step < self.decoder.next_measurement() {
            return; // past the end, stale or duplicate
        }
        if !y.iter().all(|v| v.is_finite()) {
            // Broken odometry: tracking it would poison the observer and the controller's
            // integrator, and every later command would be non-finite.
            return life.abort(format!("step {step}: the measured pose is not finite"));
        }
        let measured = match self.decoder.on_measurement(step, &y, applied) {
            Ok(Some(measured)) => measured,
            Ok(None) => return,
            Err(e) => return life.abort(format!("step {step}: {e}")),
        };
        life.robot_cursor = life.robot_cursor.max(cursor);
        if !measured.missing.is_empty() {
            for gap in measured.missing.clone() {
                self.record_step(agreed, life, gap, None);
            }
            life.emit(ControllerEvent::Missing(measured.missing));
        }
        if let Some(decision) = measured.decision {
            self.record_step(agreed, life, decision.step, decision.bit);
            life.emit(ControllerEvent::Decoded(decision));
        }
        if step < agreed.steps {
            self.send_command(agreed, life, step, &y);
        } else {
            life.send(SessionMessage::Command {
                step,
                u0: [0.0; 2],
                u1: [0.0; 2],
                fates: life.fates.window(life.robot_cursor),
            });
            let key = life.fates.accepted_key(&self.decoded, self.plan.code.k());
            life.close(agreed.confirmer.clone(), key, true, Outcome::Confirmed);
        }
    }

    fn record_step(
        &mut self,
        agreed: &Agreed,
        life: &mut ControllerLifecycle,
        step: u32,
        bit: Option<u8>,
    ) {
        if !agreed.enabled {
            return;
        }
        if let Some(received) = self.assembler.push(step, bit) {
            let decoded = self.plan.code.decode(received.word);
            let accepted = !received.erased && decoded.distance <= self.plan.accept_max_distance;
            life.fates.record(received.index, accepted);
            self.decoded.push(decoded.message);
            life.emit(ControllerEvent::CodewordDecided {
                index: received.index,
                accepted,
            });
        }
    }

    fn send_command(
        &mut self,
        agreed: &Agreed,
        life: &mut ControllerLifecycle,
        step: u32,
        y: &Pose,
    ) {
        let pose = match self.feedback {
            Feedback::Measurement => *y,
            Feedback::Estimate => self.decoder.state(),
        };
        let nominal = self.tracking.command(&pose, step);
        if !nominal.iter().all(|v| v.is_finite()) {
            // A finite but absurd pose (e.g. 1e308 m) overflows the controller's state.
            return life.abort(format!("step {step}: the tracking command is not finite"));
        }
        let (u0, u1) = command_pair(agreed, &self.plan, nominal);
        self.decoder.on_command(step, nominal, u0, u1);
        life.emit(ControllerEvent::Commanded { step, nominal });
        life.send(SessionMessage::Command {
            step,
            u0: u0.into(),
            u1: u1.into(),
            fates: life.fates.window(life.robot_cursor),
        });
    }
}

impl ControllerMode for OdometryController {
    fn on_message(
        &mut self,
        agreed: &Agreed,
        life: &mut ControllerLifecycle,
        message: SessionMessage,
    ) {
        if let SessionMessage::Measurement {
            step,
            y,
            applied_step,
            fate_cursor,
        } = message
            && life.running()
        {
            self.on_measurement(agreed, life, step, Pose::from(y), applied_step, fate_cursor);
        }
    }

    fn on_sensor(&mut self, _: &Agreed, _: &mut ControllerLifecycle, _: u32, _: Pose) {}

    fn uses_sensor(&self) -> bool {
        false
    }
}

/// The pair `u0D = H⁻¹(uU + Δ)`, `u1D = H⁻¹(uU − Δ)` (protocol off: both `H⁻¹uU`).
#[must_use]
pub fn command_pair(
    agreed: &Agreed,
    plan: &OdometryPlan,
    nominal: Unicycle,
) -> (WheelSpeeds, WheelSpeeds) {
    if agreed.enabled {
        (
            agreed.drive.to_wheels(nominal + plan.delta),
            agreed.drive.to_wheels(nominal - plan.delta),
        )
    } else {
        let wheels = agreed.drive.to_wheels(nominal);
        (wheels, wheels)
    }
}

/// The observer design of a configuration.
#[must_use]
pub fn observer_params(config: &Config) -> ObserverParams {
    ObserverParams {
        sample_time: config.robot.sample_time,
        w_var: config.observer.w_var,
        v_var: config.observer.v_var,
        variant: config.observer.variant,
        channels: config.observer.m,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::{
        Controller, ControllerInput, ControllerOutput, KeyBits, Message, SessionPlan, Time, Timing,
    };

    fn controller() -> Controller {
        let config = Config::default();
        let plan = SessionPlan::from_config(&config, 1);
        Controller::new(&config, plan, Timing::default(), Time::ZERO)
    }

    fn measure(controller: &mut Controller, step: u32, y: [f64; 3]) -> Vec<ControllerOutput> {
        controller.handle_input(
            Time::ZERO,
            ControllerInput::Frame(
                SessionMessage::Measurement {
                    step,
                    y,
                    applied_step: step.checked_sub(1),
                    fate_cursor: 0,
                }
                .into(),
            ),
        );
        std::iter::from_fn(|| controller.poll_output()).collect()
    }

    fn commands(outputs: &[ControllerOutput]) -> Vec<[f64; 4]> {
        outputs
            .iter()
            .filter_map(|o| match o {
                ControllerOutput::Transmit(Message::Session(SessionMessage::Command {
                    u0,
                    u1,
                    ..
                })) => Some([u0[0], u0[1], u1[0], u1[1]]),
                _ => None,
            })
            .collect()
    }

    /// Found by the `robot_endpoint` driver: a NaN pose made every later command NaN
    /// (the integrator ξ stayed NaN). A non-finite measurement now aborts the session.
    #[test]
    fn a_non_finite_measurement_aborts_without_a_command() {
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut controller = controller();
            assert_eq!(commands(&measure(&mut controller, 0, [0.0; 3])).len(), 1);
            let outputs = measure(&mut controller, 1, [0.0, bad, 0.0]);
            assert!(commands(&outputs).is_empty(), "{outputs:?}");
            assert!(matches!(
                outputs.last(),
                Some(ControllerOutput::Event(ControllerEvent::Finished(Outcome::Aborted(r))))
                    if r.contains("not finite")
            ));
            assert!(controller.is_done());
        }
    }

    /// Found by the `controller_endpoint` driver: a finite but absurd pose (`f64::MAX` m)
    /// overflowed the tracking controller into a NaN command. Every command sent stays
    /// finite; a pose that overflows the controller aborts the session.
    #[test]
    fn an_absurd_measurement_never_yields_a_non_finite_command() {
        for huge in [1e300, f64::MAX, -f64::MAX] {
            let mut controller = controller();
            let mut sent = Vec::new();
            for step in 0..4 {
                sent.extend(commands(&measure(&mut controller, step, [huge, huge, 0.0])));
            }
            assert!(sent.iter().flatten().all(|w| w.is_finite()), "{sent:?}");
            assert_eq!(controller.is_done(), huge.abs() == f64::MAX, "{huge}");
        }
    }

    #[test]
    fn debug_prints_no_key_material() {
        let mut controller = controller();
        for step in 0..30 {
            measure(&mut controller, step, [0.0; 3]);
        }
        let text = format!("{controller:?}");
        assert!(text.starts_with("Controller {"), "{text}");
        assert!(text.contains("decoded_codewords: 9"), "{text}");
        assert!(!text.contains('['), "{text}");
        assert_eq!(
            format!("{:?}", KeyBits::from(vec![1, 0, 1])),
            "KeyBits(3 bits)"
        );
    }
}
