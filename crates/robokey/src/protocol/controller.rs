//! The controller endpoint (docs/model.md, docs/protocol.md): tracks the reference, offers command pairs,
//! decodes the robot's choices, acks codewords and confirms the key.

use super::assembler::CodewordAssembler;
use super::closing::ControllerLifecycle;
use super::decoder::StepDecoder;
use super::endpoint_io::{ControllerEvent, ControllerInput, ControllerOutput};
use super::fates::FateLedger;
use super::message::{Closing, Message, SessionMessage};
use super::plan::SessionPlan;
use super::{KeyBits, Outcome};
use crate::config::{Config, Feedback};
use crate::control::{TrackingController, TrackingGains};
use crate::model::{Pose, Unicycle, WheelSpeeds};
use crate::observer::{Observer, ObserverParams};
use crate::trajectory::Trajectory;

/// The controller side of a session.
pub struct ControllerEndpoint {
    plan: SessionPlan,
    trajectory: Trajectory,
    tracking: TrackingController,
    feedback: Feedback,
    decoder: StepDecoder,
    assembler: CodewordAssembler,
    fates: FateLedger,
    /// The decoded message of every decided codeword: key material.
    decoded: zeroize::Zeroizing<Vec<u64>>,
    robot_cursor: u32,
    lifecycle: ControllerLifecycle,
    key: KeyBits,
}

impl std::fmt::Debug for ControllerEndpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Key material (decoded messages, key bits) is never printed.
        f.debug_struct("ControllerEndpoint")
            .field("lifecycle", &self.lifecycle)
            .field("next_measurement", &self.decoder.next_measurement())
            .field("decoded_codewords", &self.decoded.len())
            .field("key_bits", &self.key.len())
            .finish_non_exhaustive()
    }
}

impl ControllerEndpoint {
    /// A controller for a validated configuration and its plan.
    #[must_use]
    pub fn new(config: &Config, plan: SessionPlan) -> Self {
        let c = &config.controller;
        let gains = TrackingGains {
            kp: c.kp,
            kd: c.kd,
            xi_eps: c.xi_eps,
            wheel_limit: c.wheel_limit,
        };
        let observer = Observer::new(&observer_params(config)).expect("validated observer.m");
        Self {
            trajectory: config.trajectory(),
            tracking: TrackingController::new(gains, plan.drive, plan.sample_time),
            feedback: c.feedback,
            decoder: StepDecoder::new(plan.drive, observer, plan.delta, plan.enabled),
            assembler: CodewordAssembler::new(plan.code.n() as u32, plan.codewords()),
            fates: FateLedger::new(plan.codewords()),
            decoded: zeroize::Zeroizing::new(Vec::with_capacity(plan.codewords() as usize)),
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
            ControllerInput::Sensor { .. } => {}
            ControllerInput::Timeout => self.lifecycle.on_timeout(),
        }
    }

    /// The next output, if any.
    pub fn poll_output(&mut self) -> Option<ControllerOutput> {
        self.lifecycle.poll()
    }

    /// The controller's key `K_c` (complete once the session has finished).
    #[must_use]
    pub fn key(&self) -> &[u8] {
        &self.key
    }

    /// The session plan.
    #[must_use]
    pub fn plan(&self) -> &SessionPlan {
        &self.plan
    }

    /// Whether the session is over.
    #[must_use]
    pub fn is_done(&self) -> bool {
        self.lifecycle.is_done()
    }

    fn handle_message(&mut self, message: Message) {
        match message {
            Message::Session(SessionMessage::Measurement {
                step,
                y,
                applied_step,
                fate_cursor,
            }) if self.lifecycle.running() => {
                self.handle_measurement(step, Pose::from(y), applied_step, fate_cursor);
            }
            Message::Closing(message) => self.lifecycle.on_message(message),
            // Handshake and post-processing messages are not the endpoint's; a session
            // message after the run is a late duplicate.
            _ => {}
        }
    }

    /// Ends the session and tells the robot why.
    fn abort(&mut self, reason: String) {
        self.lifecycle.send(
            Closing::Abort {
                reason: reason.clone(),
            }
            .into(),
        );
        self.lifecycle.finish(Outcome::Aborted(reason));
    }

    fn handle_measurement(&mut self, step: u32, y: Pose, applied: Option<u32>, cursor: u32) {
        if step > self.plan.steps || step < self.decoder.next_measurement() {
            return; // past the end, stale or duplicate
        }
        if !y.iter().all(|v| v.is_finite()) {
            // Broken odometry: tracking it would poison the observer and the controller's
            // integrator, and every later command would be non-finite.
            return self.abort(format!("step {step}: the measured pose is not finite"));
        }
        let measured = match self.decoder.on_measurement(step, &y, applied) {
            Ok(Some(measured)) => measured,
            Ok(None) => return,
            Err(e) => return self.abort(format!("step {step}: {e}")),
        };
        self.robot_cursor = self.robot_cursor.max(cursor);
        if !measured.missing.is_empty() {
            for gap in measured.missing.clone() {
                self.record_step(gap, None);
            }
            self.lifecycle
                .emit(ControllerEvent::Missing(measured.missing));
        }
        if let Some(decision) = measured.decision {
            self.record_step(decision.step, decision.bit);
            self.lifecycle.emit(ControllerEvent::Decoded(decision));
        }
        if step < self.plan.steps {
            self.send_command(step, &y);
        } else {
            self.lifecycle.send(
                SessionMessage::Command {
                    step,
                    u0: [0.0; 2],
                    u1: [0.0; 2],
                    fates: self.fates.window(self.robot_cursor),
                }
                .into(),
            );
            self.key = self.fates.accepted_key(&self.decoded, self.plan.code.k());
            self.lifecycle.close(
                self.plan.confirmer.clone(),
                &self.fates,
                &self.key,
                Outcome::Confirmed,
            );
        }
    }

    fn record_step(&mut self, step: u32, bit: Option<u8>) {
        if !self.plan.enabled {
            return;
        }
        if let Some(received) = self.assembler.push(step, bit) {
            let decoded = self.plan.code.decode(received.word);
            let accepted = !received.erased && decoded.distance <= self.plan.accept_max_distance;
            self.fates.record(received.index, accepted);
            self.decoded.push(decoded.message);
            self.lifecycle.emit(ControllerEvent::CodewordDecided {
                index: received.index,
                accepted,
            });
        }
    }

    fn send_command(&mut self, step: u32, y: &Pose) {
        let pose = match self.feedback {
            Feedback::Measurement => *y,
            Feedback::Estimate => self.decoder.state(),
        };
        let reference = self.trajectory.at(f64::from(step) * self.plan.sample_time);
        let nominal = self.tracking.command(&pose, &reference);
        if !nominal.iter().all(|v| v.is_finite()) {
            // A finite but absurd pose (e.g. 1e308 m) overflows the controller's state.
            return self.abort(format!("step {step}: the tracking command is not finite"));
        }
        let (u0, u1) = command_pair(&self.plan, nominal);
        self.decoder.on_command(step, nominal, u0, u1);
        self.lifecycle
            .emit(ControllerEvent::Commanded { step, nominal });
        self.lifecycle.send(
            SessionMessage::Command {
                step,
                u0: u0.into(),
                u1: u1.into(),
                fates: self.fates.window(self.robot_cursor),
            }
            .into(),
        );
    }
}

/// The pair `u0D = H⁻¹(uU + Δ)`, `u1D = H⁻¹(uU − Δ)` (protocol off: both `H⁻¹uU`).
#[must_use]
pub fn command_pair(plan: &SessionPlan, nominal: Unicycle) -> (WheelSpeeds, WheelSpeeds) {
    if plan.enabled {
        (
            plan.drive.to_wheels(nominal + plan.delta),
            plan.drive.to_wheels(nominal - plan.delta),
        )
    } else {
        let wheels = plan.drive.to_wheels(nominal);
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

    fn controller() -> ControllerEndpoint {
        let config = Config::default();
        ControllerEndpoint::new(&config, SessionPlan::from_config(&config, 1))
    }

    fn measure(
        controller: &mut ControllerEndpoint,
        step: u32,
        y: [f64; 3],
    ) -> Vec<ControllerOutput> {
        controller.handle_input(ControllerInput::Frame(Message::Session(
            SessionMessage::Measurement {
                step,
                y,
                applied_step: step.checked_sub(1),
                fate_cursor: 0,
            },
        )));
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
        assert!(!controller.decoded.is_empty());
        let text = format!("{controller:?}");
        assert!(text.starts_with("ControllerEndpoint {"), "{text}");
        assert!(text.contains("decoded_codewords: 9"), "{text}");
        assert!(!text.contains('['), "{text}");
        assert_eq!(
            format!("{:?}", KeyBits::from(vec![1, 0, 1])),
            "KeyBits(3 bits)"
        );
    }
}
