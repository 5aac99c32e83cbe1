//! Drivers shared by the fuzz targets (`fuzz/`) and the proptest drivers of the test suite:
//! arbitrary bytes become a configuration (either sensing mode) and a sequence of endpoint
//! inputs and timer firings, and every output is checked against the endpoints' invariants.
//! A violated invariant panics. Not a stable API.

use std::collections::VecDeque;
use std::time::Duration;

use crate::config::{CodeKind, Config, Feedback, SensingMode};
use crate::model::{Pose, WheelSpeeds};
use crate::protocol::controller::command_pair;
use crate::protocol::wire::{self, Frame, MAC_BYTES};
use crate::protocol::{
    Closing, Controller, ControllerEvent, ControllerInput, ControllerOutput, FateWindow, Handshake,
    Message, Outcome, Robot, RobotInput, RobotOutput, SessionMessage, SessionPlan, TAG_BYTES, Time,
    Timing,
};
use crate::world::{PlantStreams, WorldModel, WorldPlant};

/// Arbitrary bytes read front to back; reads past the end give zeros.
#[derive(Clone, Debug)]
pub struct Bytes<'a> {
    data: &'a [u8],
}

impl<'a> Bytes<'a> {
    /// Reads `data`.
    #[must_use]
    pub fn new(data: &'a [u8]) -> Self {
        Self { data }
    }

    /// Whether every byte has been read.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// Up to `n` bytes (fewer at the end).
    pub fn take(&mut self, n: usize) -> &'a [u8] {
        let (head, tail) = self.data.split_at(n.min(self.data.len()));
        self.data = tail;
        head
    }

    /// `N` bytes, zero-padded at the end.
    pub fn array<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0; N];
        let head = self.take(N);
        out[..head.len()].copy_from_slice(head);
        out
    }

    /// One byte.
    pub fn u8(&mut self) -> u8 {
        self.array::<1>()[0]
    }

    /// A boolean (the low bit of a byte).
    pub fn bool(&mut self) -> bool {
        self.u8() & 1 == 1
    }

    /// Four bytes, big-endian.
    pub fn u32(&mut self) -> u32 {
        u32::from_be_bytes(self.array())
    }

    /// Eight bytes, big-endian.
    pub fn u64(&mut self) -> u64 {
        u64::from_be_bytes(self.array())
    }

    /// A step, sequence number or count: mostly near `reference`, sometimes at the ends of
    /// the range or anywhere.
    pub fn u32_near(&mut self, reference: u32) -> u32 {
        match self.u8() % 8 {
            0 => u32::MAX,
            1 => u32::MAX - u32::from(self.u8()),
            2 => reference,
            3 => reference.saturating_add(1),
            4 => reference.saturating_sub(1),
            5 => u32::from(self.u8()),
            6 => self.u32(),
            _ => reference.wrapping_add(u32::from(self.u8())),
        }
    }

    /// An integer, often at the ends of the `i64` or `i32` range.
    pub fn i64(&mut self) -> i64 {
        match self.u8() % 8 {
            0 => i64::MAX,
            1 => i64::MIN,
            2 => i64::from(i32::MAX),
            3 => i64::from(i32::MIN),
            4 => i64::from(i32::MAX) + 1,
            5 => i64::from(self.u8() as i8),
            6 => i64::from(self.u32() as i32),
            _ => self.u64() as i64,
        }
    }

    /// A number near `typical`, or a non-finite, huge, tiny or arbitrary one.
    pub fn f64_near(&mut self, typical: f64) -> f64 {
        match self.u8() % 12 {
            0 => f64::NAN,
            1 => f64::INFINITY,
            2 => f64::NEG_INFINITY,
            3 => f64::MAX,
            4 => -f64::MAX,
            5 => 1e300,
            6 => -0.0,
            7 => f64::MIN_POSITIVE / 2.0,
            8 => f64::from_bits(self.u64()),
            _ => typical + f64::from(i16::from_be_bytes(self.array())) / 1000.0,
        }
    }
}

/// Which endpoint a run injects arbitrary inputs into; the other one is a genuine peer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Focus {
    Robot,
    Controller,
}

/// Most messages in flight per direction (the rest are dropped, as a full buffer would).
const QUEUE: usize = 32;
/// Most outputs one robot input or timer may cause (stop, FinishAck and Confirm after a
/// Finish; abort, stop and the end on silence).
const ROBOT_OUTPUTS: usize = 4;

/// A small configuration of either sensing mode (a few steps, so a run reaches the end of
/// the session), or the default one.
fn config(bytes: &mut Bytes<'_>) -> Config {
    let mut config = Config::default();
    let choice = bytes.u8();
    match choice % 6 {
        0 => config.code.key_bits = 1 + u32::from(bytes.u8() % 6),
        1 => {
            config.code.kind = CodeKind::Hamming74;
            config.code.accept_max_distance = u32::from(bytes.u8() % 2);
            config.code.key_bits = 4 * (1 + u32::from(bytes.u8() % 3));
        }
        2 => {
            config.protocol.enabled = false;
            config.trajectory.laps = 1;
            config.trajectory.side_time = 0.2 * f64::from(1 + bytes.u8() % 5);
        }
        3 => {}
        private => {
            config.sensing.mode = SensingMode::Private;
            config.trajectory.laps = 1;
            config.trajectory.side_time = 0.2 * f64::from(1 + bytes.u8() % 10);
            if private == 5 {
                config.protocol.bits_per_doublet = 2;
                config.protocol.max_turn_rate = 1000.0;
            }
        }
    }
    // Private sensing decides from measurements only (an estimate would carry the bit on).
    if choice & 0x10 != 0 && config.sensing.mode == SensingMode::Odometry {
        config.controller.feedback = Feedback::Estimate;
    }
    if choice & 0x20 != 0 {
        config.observer.m = 1;
    }
    config
        .validate()
        .expect("the fuzzing configurations are valid");
    config
}

/// Checks every robot output.
#[derive(Default)]
struct RobotCheck {
    last_applied: Option<u32>,
    finished: Option<Outcome>,
}

/// Checks every controller output.
#[derive(Default)]
struct ControllerCheck {
    /// Codewords decided (odometry: in order).
    decided: u32,
    /// Doublets resolved, decided or erased (each once).
    resolved: Vec<bool>,
    finished: Option<Outcome>,
}

impl ControllerCheck {
    /// Doublet `doublet` was decided or erased: once only.
    fn resolve(&mut self, doublet: u32) {
        let slot = self
            .resolved
            .get_mut(doublet as usize)
            .expect("a doublet of the session");
        assert!(!*slot, "doublet {doublet} resolved twice");
        *slot = true;
    }
}

/// Both endpoints, the messages between them, a clock and a noise-free plant.
struct Harness {
    focus: Focus,
    plan: SessionPlan,
    robot: Robot,
    controller: Controller,
    to_robot: VecDeque<Message>,
    to_controller: VecDeque<Message>,
    plant: WorldPlant,
    /// The plant's pose is `x(sensed)`.
    sensed: u32,
    now: Time,
    robot_check: RobotCheck,
    controller_check: ControllerCheck,
}

impl Harness {
    fn new(bytes: &mut Bytes<'_>, focus: Focus) -> Self {
        use rand::SeedableRng;
        let config = config(bytes);
        let session = bytes.u32();
        let plan = SessionPlan::from_config(&config, session);
        let mut key_source = rand::rngs::ChaCha20Rng::seed_from_u64(bytes.u64());
        let timing = Timing::default();
        let mut still = WorldModel::ideal(&config);
        still.process_std = [0.0; 3];
        let streams = PlantStreams {
            process: rand::rngs::ChaCha8Rng::seed_from_u64(0),
            slip: rand::rngs::ChaCha8Rng::seed_from_u64(0),
        };
        let agreed = &plan.agreed;
        Self {
            focus,
            robot: Robot::new(plan.clone(), timing, &mut key_source, Time::ZERO),
            controller: Controller::new(&config, plan.clone(), timing, Time::ZERO),
            plant: WorldPlant::new(
                &still,
                agreed.drive,
                agreed.wheel_limit,
                agreed.sample_time,
                streams,
                false,
            ),
            controller_check: ControllerCheck {
                resolved: vec![false; plan.units() as usize],
                ..ControllerCheck::default()
            },
            plan,
            to_robot: VecDeque::new(),
            to_controller: VecDeque::new(),
            sensed: 0,
            now: Time::ZERO,
            robot_check: RobotCheck::default(),
        }
    }

    fn feed_robot(&mut self, input: RobotInput) {
        self.robot.handle_input(self.now, input);
        self.drain_robot();
    }

    /// Takes the robot's outputs; answers a sample request from the plant (and, in private
    /// sensing, gives the controller's sensor the same pose).
    fn drain_robot(&mut self) {
        let mut count = 0;
        let mut sense = None;
        while let Some(output) = self.robot.poll_output() {
            count += 1;
            assert!(
                count <= ROBOT_OUTPUTS,
                "more than {ROBOT_OUTPUTS} robot outputs"
            );
            self.check_robot(&output);
            match output {
                RobotOutput::Transmit(m) if self.to_controller.len() < QUEUE => {
                    self.to_controller.push_back(m);
                }
                RobotOutput::Apply(a) => self.plant.apply(a.wheels),
                RobotOutput::Sense { step } => sense = Some(step),
                _ => {}
            }
        }
        if let Some(step) = sense {
            while self.sensed < step {
                self.plant.step();
                self.sensed += 1;
            }
            let pose = self.plant.pose();
            self.feed_robot(RobotInput::Sample { step, y: pose });
            if self.plan.private().is_some() {
                self.feed_controller(ControllerInput::Sensor { step, pose });
            }
        }
    }

    fn feed_controller(&mut self, input: ControllerInput) {
        self.controller.handle_input(self.now, input);
        self.drain_controller();
    }

    fn drain_controller(&mut self) {
        let bound = 8 + self.plan.units() as usize;
        let mut count = 0;
        while let Some(output) = self.controller.poll_output() {
            count += 1;
            assert!(count <= bound, "more than {bound} controller outputs");
            self.check_controller(&output);
            if let ControllerOutput::Transmit(m) = output
                && self.to_robot.len() < QUEUE
            {
                self.to_robot.push_back(m);
            }
        }
    }

    fn check_robot(&mut self, output: &RobotOutput) {
        let check = &mut self.robot_check;
        let agreed = &self.plan.agreed;
        match output {
            RobotOutput::Apply(a) => {
                assert!(check.finished.is_none(), "actuation after the end: {a:?}");
                assert!(
                    a.wheels
                        .iter()
                        .all(|w| w.is_finite() && w.abs() <= agreed.wheel_limit),
                    "wheel speeds beyond the agreed limit: {a:?}"
                );
                assert!(
                    check.last_applied.is_none_or(|last| a.step >= last),
                    "actuation for an earlier step: {a:?} after {:?}",
                    check.last_applied
                );
                check.last_applied = Some(a.step);
                if a.step >= agreed.steps {
                    assert_eq!(a.wheels, WheelSpeeds::zeros(), "moving after the last step");
                }
                if a.bit.is_some() {
                    assert!(
                        agreed.enabled && !a.erased && a.step < agreed.steps,
                        "{a:?}"
                    );
                }
            }
            RobotOutput::Sense { step } => {
                assert!(check.finished.is_none(), "a sample after the end");
                assert!(*step <= agreed.steps, "a sample past the last step");
            }
            RobotOutput::Finished(outcome) => {
                assert!(
                    check.finished.is_none(),
                    "the robot finished twice: {outcome:?}"
                );
                check.finished = Some(outcome.clone());
            }
            RobotOutput::Transmit(_) => {}
        }
        self.check_key(self.robot.key());
        assert!(self.robot.commands_applied() <= agreed.steps);
    }

    /// A key holds whole units, at most one per unit of the session.
    fn check_key(&self, key: &[u8]) {
        let bits = self.plan.bits_per_unit();
        assert!(
            key.len().is_multiple_of(bits) && key.len() <= self.plan.units() as usize * bits,
            "a key of {} bits",
            key.len()
        );
    }

    fn check_controller(&mut self, output: &ControllerOutput) {
        let check = &mut self.controller_check;
        let agreed = &self.plan.agreed;
        let finite_within = |w: &[f64]| {
            w.iter()
                .all(|w| w.is_finite() && w.abs() <= agreed.wheel_limit)
        };
        match output {
            ControllerOutput::Transmit(m) => {
                assert!(check.finished.is_none(), "a message after the end: {m:?}");
                match m {
                    Message::Session(SessionMessage::Command { step, u0, u1, .. }) => {
                        assert!(
                            *step <= agreed.steps,
                            "a command past the stop command: {m:?}"
                        );
                        assert!(
                            finite_within(u0) && finite_within(u1),
                            "a command the robot must refuse: {m:?}"
                        );
                        if *step == agreed.steps {
                            assert_eq!((*u0, *u1), ([0.0; 2], [0.0; 2]), "the stop command");
                        }
                    }
                    Message::Session(SessionMessage::DoubletCommand {
                        step,
                        sample,
                        first,
                        second,
                        ..
                    }) => {
                        assert!(
                            *step <= agreed.steps,
                            "a command past the stop command: {m:?}"
                        );
                        let finite = |u: &[f64]| u.iter().all(|x| x.is_finite());
                        assert!(
                            finite(sample) && finite(first) && second.is_none_or(|s| finite(&s)),
                            "a command that is not finite: {m:?}"
                        );
                        if *step == agreed.steps {
                            assert_eq!((*first, *second), ([0.0; 2], None), "the stop command");
                        }
                    }
                    _ => {}
                }
            }
            ControllerOutput::Event(ControllerEvent::CodewordDecided { index, .. }) => {
                assert_eq!(
                    *index, check.decided,
                    "codewords are decided once, in order"
                );
                check.decided += 1;
                assert!(check.decided <= self.plan.units());
            }
            ControllerOutput::Event(ControllerEvent::DoubletErased { doublet }) => {
                check.resolve(*doublet);
            }
            ControllerOutput::Event(ControllerEvent::DoubletDecided(decision)) => {
                check.resolve(decision.doublet);
            }
            ControllerOutput::Event(ControllerEvent::Decoded(decision)) => {
                assert!(decision.bit.is_none_or(|b| b <= 1));
                assert!(decision.step < agreed.steps);
            }
            ControllerOutput::Event(ControllerEvent::Finished(outcome)) => {
                assert!(check.finished.is_none(), "the controller finished twice");
                check.finished = Some(outcome.clone());
            }
            ControllerOutput::Event(_) => {}
        }
        self.check_key(self.controller.key());
    }

    /// Moves the clock to the next timer of either side (if any) and fires what is due.
    fn advance(&mut self) {
        let next = [self.robot.poll_timeout(), self.controller.poll_timeout()]
            .into_iter()
            .flatten()
            .min();
        if let Some(next) = next {
            self.now = self.now.max(next);
        }
        self.fire();
    }

    /// Fires both sides' timers due now.
    fn fire(&mut self) {
        if self.robot.poll_timeout().is_some_and(|t| t <= self.now) {
            self.robot.handle_timeout(self.now);
            self.drain_robot();
        }
        if self
            .controller
            .poll_timeout()
            .is_some_and(|t| t <= self.now)
        {
            self.controller.handle_timeout(self.now);
            self.drain_controller();
        }
    }

    fn deliver_to_robot(&mut self) {
        if let Some(m) = self.to_robot.pop_front() {
            self.feed_robot(RobotInput::Frame(m));
        }
    }

    fn deliver_to_controller(&mut self) {
        if let Some(m) = self.to_controller.pop_front() {
            self.feed_controller(ControllerInput::Frame(m));
        }
    }

    /// Delivers everything in flight until both sides are quiet.
    fn settle(&mut self) {
        for _ in 0..64 {
            if self.to_robot.is_empty() && self.to_controller.is_empty() {
                break;
            }
            self.deliver_to_controller();
            self.deliver_to_robot();
        }
    }

    /// Sends arbitrary input to the side under test.
    fn inject(&mut self, message: Message) {
        match self.focus {
            Focus::Robot => self.feed_robot(RobotInput::Frame(message)),
            Focus::Controller => self.feed_controller(ControllerInput::Frame(message)),
        }
    }

    /// An arbitrary pose near the plant's.
    fn pose(&self, bytes: &mut Bytes<'_>) -> Pose {
        let pose = self.plant.pose();
        Pose::new(
            bytes.f64_near(pose.x),
            bytes.f64_near(pose.y),
            bytes.f64_near(pose.z),
        )
    }

    /// An arbitrary message of the session's mode, built around its current state.
    fn message(&self, bytes: &mut Bytes<'_>) -> Message {
        let units = self.plan.units();
        let private = self.plan.private().is_some();
        let fates = |bytes: &mut Bytes<'_>| FateWindow {
            first: bytes.u32_near(0),
            count: bytes.u8(),
            accepted: bytes.u64(),
        };
        match bytes.u8() % 8 {
            0 if private => {
                let mut input = || [bytes.f64_near(0.1), bytes.f64_near(0.0)];
                let (first, second) = (input(), input());
                SessionMessage::DoubletCommand {
                    step: bytes.u32_near(self.robot.next_command()),
                    sample: self.pose(bytes).into(),
                    first,
                    second: bytes.bool().then_some(second),
                    fates: fates(bytes),
                }
                .into()
            }
            0 => {
                let step = bytes.u32_near(self.robot.next_command());
                let odometry = self.plan.odometry().expect("odometry");
                let (u0, u1) = if bytes.bool() {
                    let nominal = [bytes.f64_near(0.1), bytes.f64_near(0.0)].into();
                    let (u0, u1) = command_pair(&self.plan.agreed, odometry, nominal);
                    (u0.into(), u1.into())
                } else {
                    let mut wheel = || bytes.f64_near(4.0);
                    ([wheel(), wheel()], [wheel(), wheel()])
                };
                SessionMessage::Command {
                    step,
                    u0,
                    u1,
                    fates: fates(bytes),
                }
                .into()
            }
            1 if private => SessionMessage::PrivateMeasurement {
                step: bytes.u32_near(self.sensed),
                applied_step: bytes
                    .bool()
                    .then(|| bytes.u32_near(self.sensed.saturating_sub(1))),
                fate_cursor: bytes.u32_near(units),
            }
            .into(),
            1 => SessionMessage::Measurement {
                step: bytes.u32_near(self.sensed),
                y: self.pose(bytes).into(),
                applied_step: bytes
                    .bool()
                    .then(|| bytes.u32_near(self.sensed.saturating_sub(1))),
                fate_cursor: bytes.u32_near(units),
            }
            .into(),
            2 => Closing::Finish {
                codewords: bytes.u32_near(units),
                bitmap: (0..bytes.u8() % 4).map(|_| bytes.u64()).collect(),
            }
            .into(),
            3 => Closing::FinishAck.into(),
            4 => Closing::Confirm {
                session_tag: bytes.array::<TAG_BYTES>(),
                key_tag: bytes.array::<TAG_BYTES>(),
            }
            .into(),
            5 => Closing::Abort {
                reason: String::from_utf8_lossy(bytes.take(8)).into_owned(),
            }
            .into(),
            6 => {
                if bytes.bool() {
                    Handshake::Ready.into()
                } else {
                    Closing::Done.into()
                }
            }
            _ => {
                // Arbitrary bytes through the wire decoder, with a MAC trailer.
                let len = usize::from(bytes.u8());
                let mut frame = bytes.take(len).to_vec();
                frame.extend_from_slice(&[0; MAC_BYTES]);
                wire::decode(&frame).map_or(Closing::FinishAck.into(), |f| f.message)
            }
        }
    }

    /// The next genuine message toward the side under test, with one byte of its wire
    /// encoding changed; `None` when none is in flight or the result does not decode.
    fn mutated(&mut self, bytes: &mut Bytes<'_>) -> Option<Message> {
        let queue = match self.focus {
            Focus::Robot => &mut self.to_robot,
            Focus::Controller => &mut self.to_controller,
        };
        let message = queue.pop_front()?;
        let frame = Frame {
            session: self.plan.agreed.session,
            seq: 0,
            message,
        };
        let mut encoded = wire::encode(&frame);
        let at = usize::from(u16::from_be_bytes(bytes.array())) % encoded.len();
        encoded[at] ^= bytes.u8().max(1);
        encoded.extend_from_slice(&[0; MAC_BYTES]);
        wire::decode(&encoded).ok().map(|f| f.message)
    }

    /// What the side under test's own senses deliver, arbitrary: the robot's odometry, the
    /// controller's sensor (or its failure).
    fn sense(&mut self, bytes: &mut Bytes<'_>) {
        match self.focus {
            Focus::Robot => {
                let step = bytes.u32_near(self.sensed);
                let y = self.pose(bytes);
                self.feed_robot(RobotInput::Sample { step, y });
            }
            Focus::Controller if bytes.u8().is_multiple_of(16) => {
                let why = String::from_utf8_lossy(bytes.take(8)).into_owned();
                self.feed_controller(ControllerInput::SensorStopped(why));
            }
            Focus::Controller => {
                let step = bytes.u32_near(self.sensed);
                let pose = self.pose(bytes);
                self.feed_controller(ControllerInput::Sensor { step, pose });
            }
        }
    }

    fn run(&mut self, bytes: &mut Bytes<'_>) {
        while !bytes.is_empty() {
            match bytes.u8() % 12 {
                0..=2 => {
                    self.advance();
                    self.settle();
                }
                3 => self.advance(),
                4 => self.deliver_to_robot(),
                5 => self.deliver_to_controller(),
                6 => {
                    // Loss.
                    let _ = if bytes.bool() {
                        self.to_robot.pop_front()
                    } else {
                        self.to_controller.pop_front()
                    };
                }
                7 => {
                    // Time jumps by up to 2.55 s: any timer may fire.
                    self.now = self.now + Duration::from_millis(10 * u64::from(bytes.u8()));
                    self.fire();
                }
                8 => self.sense(bytes),
                9 | 10 => {
                    let message = self.message(bytes);
                    self.inject(message);
                }
                _ => {
                    if let Some(message) = self.mutated(bytes) {
                        self.inject(message);
                    }
                }
            }
        }
        self.check_end();
    }

    /// A confirmed key is the peer's key: arbitrary input cannot forge a confirmation.
    fn check_end(&self) {
        let confirmed = |o: &Option<Outcome>| matches!(o, Some(Outcome::Confirmed));
        if confirmed(&self.robot_check.finished) || confirmed(&self.controller_check.finished) {
            assert!(
                self.robot.key() == self.controller.key(),
                "a confirmed session with different keys"
            );
        }
    }
}

/// The robot endpoint, in either sensing mode, under arbitrary samples, timers and messages
/// (structured, mutated genuine ones, and arbitrary bytes through the wire decoder), with a
/// genuine controller as its peer.
///
/// # Panics
/// When the robot (or its peer) breaks an invariant: an actuation beyond the agreed wheel
/// limit, non-finite, out of step order or after the end; a sample request past the end;
/// too many outputs for one input; a key longer than the session allows; a confirmed
/// session with different keys.
pub fn robot_endpoint(data: &[u8]) {
    let mut bytes = Bytes::new(data);
    Harness::new(&mut bytes, Focus::Robot).run(&mut bytes);
}

/// The controller endpoint, in either sensing mode, under arbitrary measurements and sensor
/// samples (non-finite, huge, out of order, duplicated, past the end), a failing sensor,
/// timers and messages, with a genuine robot as its peer.
///
/// # Panics
/// When the controller (or its peer) breaks an invariant: a command that is not finite (or,
/// in odometry mode, beyond the robot's wheel limit), a command past the stop command, units
/// decided out of order or twice, too many outputs for one input, output after the end, a
/// confirmed session with different keys.
pub fn controller_endpoint(data: &[u8]) {
    let mut bytes = Bytes::new(data);
    Harness::new(&mut bytes, Focus::Controller).run(&mut bytes);
}
