//! The robot endpoint (docs/protocol.md): owns the key bits and the clock, applies the offered
//! command its key picks (or the fallback) each step, reports each sample, and closes the
//! session — in either sensing mode (`RobotMode`). Time is an input: it says when it must be
//! woken ([`Robot::poll_timeout`]) and asks the shell for each sample ([`RobotOutput::Sense`]).

pub(crate) mod io;
pub(crate) mod lifecycle;
pub(crate) mod mode;
mod odometry;

use std::time::Duration;

use rand::CryptoRng;

pub use io::{Actuation, RobotInput, RobotOutput};

use self::lifecycle::RobotLifecycle;
use self::mode::RobotMode;
use self::odometry::OdometryRobot;
use super::plan::{ModePlan, SessionPlan};
use super::timing::{Pace, Time, Timing, earliest};
use super::{Closing, Message, Outcome};
use crate::model::Pose;
use crate::private::PrivateRobot;

/// The robot's timers: the next sample, the deadline of the command it waits for, the
/// repetition of its last report after the run, and silence.
#[derive(Clone, Copy, Debug)]
struct Clock {
    timing: Timing,
    /// `t₀`: when the session started.
    start: Time,
    /// The sample time `T`.
    period: Duration,
    /// How long after its sample a command is late in real time: `T·deadline_fraction`.
    late: Duration,
    /// The next sample to ask for, and when.
    sample: Option<(u32, Time)>,
    /// The sample asked for and not fed back yet.
    sensing: Option<u32>,
    /// The command waited for, and its deadline.
    deadline: Option<(u32, Time)>,
    /// After the run: when to repeat the last report (measurement, then tags).
    repeat: Option<Time>,
    /// When the last valid frame came.
    last_frame: Time,
}

impl Clock {
    /// The instant of sample `step` after `now`: `t₀ + k·T` (realtime), or now (lockstep).
    fn sample_at(&self, step: u32, now: Time) -> Time {
        match self.timing.pace {
            Pace::Realtime => self.start + self.period * step,
            Pace::Lockstep => now,
        }
    }

    /// The deadline of command `step`, sampled at `now`: `t_k + T·deadline_fraction`
    /// (realtime), or `step_timeout` after now (lockstep).
    fn deadline_of(&self, step: u32, now: Time) -> Time {
        match self.timing.pace {
            Pace::Realtime => self.start + self.period * step + self.late,
            Pace::Lockstep => now + self.timing.step_timeout,
        }
    }

    fn silence_at(&self) -> Time {
        self.last_frame + self.timing.silence_timeout
    }
}

/// The robot side of a session.
pub struct Robot {
    plan: SessionPlan,
    lifecycle: RobotLifecycle,
    mode: Box<dyn RobotMode>,
    clock: Clock,
    /// The report of sample N and the last tags sent: repeated after the run, and the
    /// courtesy reply to a controller that repeats its closing.
    last_report: Option<Message>,
    last_confirm: Option<Message>,
}

impl std::fmt::Debug for Robot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Key material is never printed.
        f.debug_struct("Robot")
            .field("lifecycle", &self.lifecycle)
            .field("clock", &self.clock)
            .finish_non_exhaustive()
    }
}

impl Robot {
    /// A robot whose session starts at `now` (its first sample is due then), its raw key
    /// drawn from `key_source` (a CSPRNG: the OS generator in deployment, a seeded stream in
    /// simulation).
    pub fn new<R: CryptoRng + ?Sized>(
        plan: SessionPlan,
        timing: Timing,
        key_source: &mut R,
        now: Time,
    ) -> Self {
        let units = plan.units();
        let mode: Box<dyn RobotMode> = match &plan.mode {
            ModePlan::Odometry(o) => Box::new(OdometryRobot::new(
                &plan.agreed,
                o.clone(),
                units,
                key_source,
            )),
            ModePlan::Private(p) => Box::new(PrivateRobot::new(*p, units, key_source)),
        };
        Self {
            lifecycle: RobotLifecycle::new(units),
            mode,
            clock: Clock {
                timing,
                start: now,
                period: Duration::from_secs_f64(plan.agreed.sample_time),
                late: Duration::from_secs_f64(plan.agreed.sample_time * timing.deadline_fraction),
                sample: Some((0, now)),
                sensing: None,
                deadline: None,
                repeat: None,
                last_frame: now,
            },
            last_report: None,
            last_confirm: None,
            plan,
        }
    }

    /// Feeds one input at `now`.
    pub fn handle_input(&mut self, now: Time, input: RobotInput) {
        match input {
            RobotInput::Sample { step, y } => self.on_sample(now, step, &y),
            RobotInput::Frame(message) => self.on_frame(now, &message),
        }
        self.after(now);
    }

    /// Feeds a message from the controller at `now`, by reference: what
    /// [`RobotInput::Frame`] does without moving the message (the simulator's link).
    pub fn handle_frame(&mut self, now: Time, message: &Message) {
        self.on_frame(now, message);
        self.after(now);
    }

    /// Handles every timer due at `now`.
    pub fn handle_timeout(&mut self, now: Time) {
        if self.lifecycle.is_done() {
            return;
        }
        if now >= self.clock.silence_at() {
            let reason = format!(
                "silence: no valid frame from the controller for {:.1} s",
                self.clock.timing.silence_timeout.as_secs_f64()
            );
            self.lifecycle.send(Closing::Abort {
                reason: reason.clone(),
            });
            self.lifecycle.abort(reason);
            return;
        }
        if let Some((step, at)) = self.clock.sample
            && now >= at
        {
            self.clock.sample = None;
            self.clock.sensing = Some(step);
            self.lifecycle.sense(step);
        }
        if let Some((step, at)) = self.clock.deadline
            && now >= at
        {
            self.clock.deadline = None;
            self.mode
                .on_missing(&self.plan.agreed, &mut self.lifecycle, step);
        }
        if let Some(at) = self.clock.repeat
            && now >= at
        {
            self.clock.repeat = Some(now + self.clock.timing.retransmit_interval());
            if let Some(repeat) = self
                .last_confirm
                .clone()
                .or_else(|| self.last_report.clone())
            {
                self.lifecycle.send(repeat);
            }
        }
        self.after(now);
    }

    /// When the endpoint must next be woken (`None` once the session is over).
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Time> {
        if self.lifecycle.is_done() {
            return None;
        }
        let c = &self.clock;
        [
            c.sample.map(|(_, at)| at),
            c.deadline.map(|(_, at)| at),
            c.repeat,
        ]
        .into_iter()
        .fold(Some(c.silence_at()), earliest)
    }

    /// The next output, if any.
    pub fn poll_output(&mut self) -> Option<RobotOutput> {
        self.lifecycle.poll()
    }

    /// The robot's key `K_r` (complete once the Finish has arrived): in private sensing its
    /// raw bits of the kept doublets, `[v, ω]` each, the reference reconciliation corrects
    /// the controller's to.
    #[must_use]
    pub fn key(&self) -> &[u8] {
        self.lifecycle.key()
    }

    /// The bit word (`v | ω << m`, `m` bits per symbol label) doublet `doublet` carries,
    /// once the robot applied it with them (private sensing).
    #[must_use]
    pub fn carried_word(&self, doublet: u32) -> Option<u64> {
        self.mode.carried_word(doublet)
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

    /// What a robot that needs nothing more answers a controller still repeating its
    /// closing with: `FinishAck` and its tags, once it sent them in a session it did not
    /// abort.
    #[must_use]
    pub fn courtesy_reply(&self) -> Option<Vec<Message>> {
        let confirm = self.last_confirm.clone()?;
        let aborted = matches!(self.lifecycle.outcome(), Some(Outcome::Aborted(_)));
        (!aborted).then(|| vec![Closing::FinishAck.into(), confirm])
    }

    fn on_sample(&mut self, now: Time, step: u32, y: &Pose) {
        if self.clock.sensing != Some(step) {
            return; // not asked for, or asked and answered already
        }
        self.clock.sensing = None;
        self.mode
            .on_sample(&self.plan.agreed, &mut self.lifecycle, step, y);
        if step >= self.plan.agreed.steps {
            // Only the report of sample N is ever repeated: the controller finishes on it,
            // and it has no successor to stand in for it if lost.
            if let Some(report @ Message::Session(message)) = self.lifecycle.last_queued_message()
                && message.step() >= self.plan.agreed.steps
            {
                self.last_report = Some(report.clone());
            }
        }
        if self.lifecycle.awaits(step) {
            let at = self.clock.deadline_of(step, now);
            self.clock.deadline = Some((step, at));
        }
    }

    fn on_frame(&mut self, now: Time, message: &Message) {
        if self.lifecycle.is_done() {
            return;
        }
        self.clock.last_frame = now;
        match message {
            Message::Session(message) => {
                self.mode
                    .on_message(&self.plan.agreed, &mut self.lifecycle, message);
            }
            Message::Closing(message) => {
                let confirmer = self.plan.agreed.confirmer.clone();
                self.lifecycle
                    .on_message(message, &confirmer, self.mode.as_ref());
                if let Some(confirm @ Message::Closing(Closing::Confirm { .. })) =
                    self.lifecycle.last_queued_message()
                {
                    self.last_confirm = Some(confirm.clone());
                }
            }
            // A repeated Ready (the controller has not heard the robot yet) needs nothing;
            // post-processing is not the session's.
            Message::Handshake(_) | Message::Post(_) => {}
        }
    }

    /// Moves the clock on after an input or a timer: once command `k` is settled (applied,
    /// or its fallback), sample `k + 1` is due; once the run is over (the stop step passed, or
    /// a `Finish` ended it early), the last report repeats until the session ends.
    fn after(&mut self, now: Time) {
        let clock = &mut self.clock;
        if self.lifecycle.is_done() {
            (clock.sample, clock.deadline, clock.repeat) = (None, None, None);
            return;
        }
        if clock.sensing.is_some() || clock.sample.is_some() {
            return;
        }
        if let Some((step, _)) = clock.deadline {
            if self.lifecycle.awaits(step) {
                return; // still waiting for the command
            }
            clock.deadline = None;
        }
        let next = self.lifecycle.next_command;
        if self.lifecycle.expects_command() && next <= self.plan.agreed.steps {
            let at = clock.sample_at(next, now);
            clock.sample = Some((next, at));
        } else if clock.repeat.is_none() {
            clock.repeat = Some(now + clock.timing.retransmit_interval());
        }
    }
}

/// Drives a robot by hand in unit tests.
#[cfg(test)]
pub(crate) mod testing {
    use super::{Robot, RobotInput, RobotOutput};
    use crate::model::Pose;
    use crate::protocol::Time;

    /// Wakes `robot` at its next timer, answering a sample request with the origin; returns
    /// the time and every output.
    pub(crate) fn wake(robot: &mut Robot) -> (Time, Vec<RobotOutput>) {
        let now = robot.poll_timeout().expect("a running robot has a timer");
        robot.handle_timeout(now);
        (now, drain(robot, now))
    }

    /// Every output of `robot`, answering a sample request with the origin at `now`.
    pub(crate) fn drain(robot: &mut Robot, now: Time) -> Vec<RobotOutput> {
        let mut outputs = Vec::new();
        while let Some(output) = robot.poll_output() {
            if let RobotOutput::Sense { step } = output {
                robot.handle_input(
                    now,
                    RobotInput::Sample {
                        step,
                        y: Pose::zeros(),
                    },
                );
            }
            outputs.push(output);
        }
        outputs
    }

    /// Wakes `robot` until it asks for a sample; returns that step and the time.
    pub(crate) fn next_sample(robot: &mut Robot) -> (u32, Time) {
        loop {
            let (now, outputs) = wake(robot);
            if let Some(step) = outputs.iter().find_map(|o| match o {
                RobotOutput::Sense { step } => Some(*step),
                _ => None,
            }) {
                return (step, now);
            }
        }
    }
}
