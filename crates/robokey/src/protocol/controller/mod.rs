//! The controller endpoint (docs/protocol.md): tracks the reference, commands the robot,
//! decides each unit's fate and the key, and closes the session — in either sensing mode
//! (`ControllerMode`). Time is an input: it says when it must be woken
//! ([`Controller::poll_timeout`]): to retransmit its closing, to give up on a silent robot or
//! a silent sensor.

pub(crate) mod io;
pub(crate) mod lifecycle;
pub(crate) mod mode;
mod odometry;

pub use io::{ControllerEvent, ControllerInput, ControllerOutput};
pub use odometry::{command_pair, observer_params};

use self::lifecycle::ControllerLifecycle;
use self::mode::ControllerMode;
use self::odometry::OdometryController;
use super::plan::{ModePlan, SessionPlan};
use super::timing::{Time, Timing, earliest};
use super::{Closing, Message};
use crate::config::Config;
use crate::private::PrivateController;

/// The controller's timers: retransmission of its closing, silence of the robot, and
/// (private sensing) silence of its own sensor.
#[derive(Clone, Debug)]
struct Clock {
    timing: Timing,
    /// When a valid frame last came (or the session started).
    last_frame: Time,
    /// When the closing's retransmission timer last restarted: at every frame and firing.
    retransmit_from: Time,
    /// Whether the robot has been heard: the world samples when the robot does, so the
    /// sensor's silence counts only from then.
    robot_heard: bool,
    /// Whether the mode decides from the controller's own sensor (asked once, not per
    /// timer).
    uses_sensor: bool,
    /// Private sensing: when the sensor last delivered (or the robot was first heard).
    last_sample: Time,
    /// The last step the sensor delivered.
    last_step: Option<u32>,
}

/// The controller side of a session.
pub struct Controller {
    plan: SessionPlan,
    lifecycle: ControllerLifecycle,
    mode: Box<dyn ControllerMode>,
    clock: Clock,
    /// The last tags sent: the courtesy reply to a robot that repeats its closing.
    last_confirm: Option<Message>,
}

impl std::fmt::Debug for Controller {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Key material (decisions, key bits) is never printed.
        f.debug_struct("Controller")
            .field("lifecycle", &self.lifecycle)
            .field("mode", &self.mode)
            .field("clock", &self.clock)
            .finish_non_exhaustive()
    }
}

impl Controller {
    /// A controller for a validated configuration and its plan, whose session starts at
    /// `now`.
    #[must_use]
    pub fn new(config: &Config, plan: SessionPlan, timing: Timing, now: Time) -> Self {
        let units = plan.units();
        let mode: Box<dyn ControllerMode> = match &plan.mode {
            ModePlan::Odometry(o) => Box::new(OdometryController::new(
                config,
                &plan.agreed,
                o.clone(),
                units,
            )),
            ModePlan::Private(p) => {
                Box::new(PrivateController::new(config, &plan.agreed, *p, units))
            }
        };
        let uses_sensor = mode.uses_sensor();
        Self {
            lifecycle: ControllerLifecycle::new(units),
            mode,
            clock: Clock {
                timing,
                last_frame: now,
                retransmit_from: now,
                robot_heard: false,
                uses_sensor,
                last_sample: now,
                last_step: None,
            },
            last_confirm: None,
            plan,
        }
    }

    /// Feeds one input at `now`.
    pub fn handle_input(&mut self, now: Time, input: ControllerInput) {
        if self.lifecycle.is_done() {
            return;
        }
        match input {
            ControllerInput::Frame(message) => self.on_frame(now, &message),
            ControllerInput::Sensor { step, pose } => {
                self.clock.last_sample = now;
                self.clock.last_step = Some(step);
                self.mode
                    .on_sensor(&self.plan.agreed, &mut self.lifecycle, step, pose);
            }
            ControllerInput::SensorStopped(why) => {
                if self.clock.uses_sensor && !self.all_sampled() {
                    let steps = self.plan.agreed.steps;
                    self.lifecycle
                        .abort(format!("sensor stopped before step {steps}: {why}"));
                }
            }
        }
    }

    /// Feeds a message from the robot at `now`, by reference: what
    /// [`ControllerInput::Frame`] does without moving the message (the simulator's link).
    pub fn handle_frame(&mut self, now: Time, message: &Message) {
        if !self.lifecycle.is_done() {
            self.on_frame(now, message);
        }
    }

    fn on_frame(&mut self, now: Time, message: &Message) {
        let clock = &mut self.clock;
        clock.last_frame = now;
        clock.retransmit_from = now;
        if !clock.robot_heard {
            clock.robot_heard = true;
            clock.last_sample = clock.last_sample.max(now);
        }
        match message {
            Message::Session(message) => {
                self.mode
                    .on_message(&self.plan.agreed, &mut self.lifecycle, message);
            }
            Message::Closing(message) => self.lifecycle.on_message(message),
            // The channel's and post-processing's layers are not the session's.
            Message::Handshake(_) | Message::Post(_) => {}
        }
    }

    /// Handles every timer due at `now`.
    pub fn handle_timeout(&mut self, now: Time) {
        if self.lifecycle.is_done() {
            return;
        }
        let timing = self.clock.timing;
        if now >= self.clock.last_frame + timing.silence_timeout {
            return self.lifecycle.abort(format!(
                "silence: no valid frame from the robot for {:.1} s",
                timing.silence_timeout.as_secs_f64()
            ));
        }
        if let Some(at) = self.sensor_silence_at()
            && now >= at
        {
            let last = self
                .clock
                .last_step
                .map_or_else(|| "none".to_owned(), |k| k.to_string());
            return self.lifecycle.abort(format!(
                "sensor: no sample for {:.1} s (last step {last})",
                timing.silence_timeout.as_secs_f64()
            ));
        }
        if now >= self.clock.retransmit_from + timing.retransmit_interval() {
            self.clock.retransmit_from = now;
            self.lifecycle.on_timeout();
        }
    }

    /// When the endpoint must next be woken (`None` once the session is over).
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Time> {
        if self.lifecycle.is_done() {
            return None;
        }
        let timing = &self.clock.timing;
        let retransmit = self
            .lifecycle
            .closing()
            .then(|| self.clock.retransmit_from + timing.retransmit_interval());
        [retransmit, self.sensor_silence_at()].into_iter().fold(
            Some(self.clock.last_frame + timing.silence_timeout),
            earliest,
        )
    }

    /// The next output, if any.
    pub fn poll_output(&mut self) -> Option<ControllerOutput> {
        // Looked at in the queue, so that the output itself is handed over without a copy.
        if let Some(ControllerOutput::Transmit(
            message @ Message::Closing(Closing::Confirm { .. }),
        )) = self.lifecycle.next_output()
        {
            self.last_confirm = Some(message.clone());
        }
        self.lifecycle.poll()
    }

    /// The controller's key `K_c` (complete once the session has finished): in private
    /// sensing its decisions on the kept doublets, `[v, ω]` each, the raw bits
    /// reconciliation corrects.
    #[must_use]
    pub fn key(&self) -> &[u8] {
        &self.lifecycle.key
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

    /// Whether a frame of the robot has arrived in this session.
    #[must_use]
    pub fn robot_heard(&self) -> bool {
        self.clock.robot_heard
    }

    /// What a controller that needs nothing more answers a robot still repeating its
    /// closing with: its tags, once it sent them.
    #[must_use]
    pub fn courtesy_reply(&self) -> Option<Vec<Message>> {
        self.last_confirm.clone().map(|confirm| vec![confirm])
    }

    /// Whether the sensor delivered the last step `N`.
    fn all_sampled(&self) -> bool {
        self.clock
            .last_step
            .is_some_and(|k| k >= self.plan.agreed.steps)
    }

    /// Private sensing: when the sensor counts as silent, once the robot has been heard and
    /// until the sensor delivered step `N`.
    fn sensor_silence_at(&self) -> Option<Time> {
        let watched = self.clock.uses_sensor && self.clock.robot_heard && !self.all_sampled();
        watched.then(|| self.clock.last_sample + self.clock.timing.silence_timeout)
    }
}
