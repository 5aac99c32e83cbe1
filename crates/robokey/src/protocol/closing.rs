//! How a session ends once every fate is known (docs/protocol.md), in either sensing mode:
//! the controller sends `Finish` until the robot's `FinishAck`, then its confirmation tags
//! until the robot's verify, each at most [`FINISH_TRIES`] times; the robot answers a
//! `Finish` with `FinishAck` and its tags.

use std::collections::VecDeque;

use super::endpoint_io::{Actuation, ControllerEvent, ControllerOutput, RobotOutput};
use super::fates::FateLedger;
use super::message::{Closing, Message};
use super::{ConfirmTags, Confirmer, Direction, KeyBits, Outcome, TAG_BYTES};
use crate::model::WheelSpeeds;

/// The direction the controller sends in.
const DIRECTION: Direction = Direction::ToRobot;

/// Largest number of Finish (and Confirm) transmissions before the session ends
/// unconfirmed.
pub(crate) const FINISH_TRIES: u32 = 10;

/// Where a controller endpoint's session is.
#[derive(Clone, Debug)]
enum Phase {
    /// Measurements (or reports) drive it.
    Running,
    Closing(Box<Closer>),
    Done,
}

/// What both controller endpoints (odometry and private sensing) share: their outputs, in
/// order, and where the session is — running, closing (every fate known: [`Closer`]) or done.
#[derive(Clone)]
pub(crate) struct ControllerLifecycle {
    phase: Phase,
    outputs: VecDeque<ControllerOutput>,
}

impl std::fmt::Debug for ControllerLifecycle {
    /// The phase and how many outputs wait (they may carry decisions: not printed).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ControllerLifecycle")
            .field("phase", &self.phase)
            .field("outputs", &self.outputs.len())
            .finish()
    }
}

impl ControllerLifecycle {
    /// A running session with no output yet.
    pub(crate) fn new() -> Self {
        Self {
            phase: Phase::Running,
            outputs: VecDeque::new(),
        }
    }

    /// Whether measurements still drive the session.
    pub(crate) fn running(&self) -> bool {
        matches!(self.phase, Phase::Running)
    }

    /// Whether the session is over.
    pub(crate) fn is_done(&self) -> bool {
        matches!(self.phase, Phase::Done)
    }

    /// The next output, if any.
    pub(crate) fn poll(&mut self) -> Option<ControllerOutput> {
        self.outputs.pop_front()
    }

    /// Reports an event.
    pub(crate) fn emit(&mut self, event: ControllerEvent) {
        self.outputs.push_back(ControllerOutput::Event(event));
    }

    /// Sends a message to the robot.
    pub(crate) fn send(&mut self, message: Message) {
        self.outputs.push_back(ControllerOutput::Transmit(message));
    }

    /// Ends the session with `outcome`.
    pub(crate) fn finish(&mut self, outcome: Outcome) {
        self.phase = Phase::Done;
        self.emit(ControllerEvent::Finished(outcome));
    }

    /// Starts closing ([`Closer::start`]).
    pub(crate) fn close(
        &mut self,
        confirmer: Confirmer,
        fates: &FateLedger,
        tagged_key: &[u8],
        verified: Outcome,
    ) {
        let closer = Closer::start(confirmer, fates, tagged_key, verified, &mut self.outputs);
        self.phase = Phase::Closing(Box::new(closer));
    }

    /// The retransmission timer fired.
    pub(crate) fn on_timeout(&mut self) {
        if let Phase::Closing(closer) = &mut self.phase
            && let Some(outcome) = closer.on_timeout(&mut self.outputs)
        {
            self.finish(outcome);
        }
    }

    /// A closing-layer message from the robot: ignored once done, an `Abort` ends the
    /// session, a closing session hands it to its [`Closer`]; anything else (a duplicate, a
    /// message that does not fit the phase) is ignored.
    pub(crate) fn on_message(&mut self, message: Closing) {
        match (&mut self.phase, message) {
            (Phase::Done, _) => {}
            (_, Closing::Abort { reason }) => {
                self.finish(Outcome::Aborted(format!("robot aborted: {reason}")));
            }
            (Phase::Closing(closer), message) => {
                if let Some(outcome) = closer.on_message(message, &mut self.outputs) {
                    self.finish(outcome);
                }
            }
            (Phase::Running, _) => {}
        }
    }
}

/// What the closing controller waits for, and how often it has sent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Waiting {
    FinishAck { tries: u32 },
    Confirm { tries: u32 },
}

/// The closing controller: the final fates and the key its tags cover.
#[derive(Clone, Debug)]
pub(crate) struct Closer {
    confirmer: Confirmer,
    codewords: u32,
    bitmap: Vec<u64>,
    /// The key the tags cover: the raw key in odometry mode, empty in private sensing.
    tagged_key: KeyBits,
    /// The outcome once the robot's tags verify.
    verified: Outcome,
    waiting: Waiting,
}

impl Closer {
    /// Starts closing with the final `fates` (sends the first `Finish`); the tags cover
    /// `tagged_key`, and a verified robot ends the session as `verified`.
    pub(crate) fn start(
        confirmer: Confirmer,
        fates: &FateLedger,
        tagged_key: &[u8],
        verified: Outcome,
        out: &mut VecDeque<ControllerOutput>,
    ) -> Self {
        let closer = Self {
            confirmer,
            codewords: fates.len(),
            bitmap: fates.bitmap(),
            tagged_key: tagged_key.to_vec().into(),
            verified,
            waiting: Waiting::FinishAck { tries: 1 },
        };
        closer.send_finish(out);
        closer
    }

    /// A message from the robot; the outcome when it ends the session.
    pub(crate) fn on_message(
        &mut self,
        message: Closing,
        out: &mut VecDeque<ControllerOutput>,
    ) -> Option<Outcome> {
        match (self.waiting, message) {
            (Waiting::FinishAck { .. }, Closing::FinishAck) => {
                self.send_confirm(out);
                self.waiting = Waiting::Confirm { tries: 1 };
                None
            }
            (
                Waiting::FinishAck { .. },
                Closing::Confirm {
                    session_tag,
                    key_tag,
                },
            ) => {
                // The FinishAck was lost; the robot's tag proves it had the Finish.
                self.send_confirm(out);
                Some(self.verify(session_tag, key_tag))
            }
            (
                Waiting::Confirm { .. },
                Closing::Confirm {
                    session_tag,
                    key_tag,
                },
            ) => Some(self.verify(session_tag, key_tag)),
            // Duplicates and messages that do not fit are ignored.
            _ => None,
        }
    }

    /// The retransmission timer fired; the outcome when the tries are spent.
    pub(crate) fn on_timeout(&mut self, out: &mut VecDeque<ControllerOutput>) -> Option<Outcome> {
        match self.waiting {
            Waiting::FinishAck { tries } | Waiting::Confirm { tries } if tries >= FINISH_TRIES => {
                let waited = match self.waiting {
                    Waiting::FinishAck { .. } => "FinishAck",
                    Waiting::Confirm { .. } => "confirmation tag",
                };
                Some(Outcome::Unconfirmed(format!(
                    "no {waited} from the robot after {tries} transmissions"
                )))
            }
            Waiting::FinishAck { tries } => {
                self.waiting = Waiting::FinishAck { tries: tries + 1 };
                self.send_finish(out);
                None
            }
            // Our tag or the robot's was lost: repeating ours makes the robot repeat its own.
            Waiting::Confirm { tries } => {
                self.waiting = Waiting::Confirm { tries: tries + 1 };
                self.send_confirm(out);
                None
            }
        }
    }

    fn send_finish(&self, out: &mut VecDeque<ControllerOutput>) {
        out.push_back(ControllerOutput::Transmit(
            Closing::Finish {
                codewords: self.codewords,
                bitmap: self.bitmap.clone(),
            }
            .into(),
        ));
    }

    fn send_confirm(&self, out: &mut VecDeque<ControllerOutput>) {
        let ours = self
            .confirmer
            .tags(DIRECTION, &self.bitmap, &self.tagged_key);
        out.push_back(ControllerOutput::Transmit(
            Closing::Confirm {
                session_tag: ours.session,
                key_tag: ours.key,
            }
            .into(),
        ));
    }

    fn verify(&self, session: [u8; TAG_BYTES], key: [u8; TAG_BYTES]) -> Outcome {
        let peer = ConfirmTags { session, key };
        match self
            .confirmer
            .check(DIRECTION, &self.bitmap, &self.tagged_key, &peer)
        {
            Ok(()) => self.verified.clone(),
            Err(why) => Outcome::Unconfirmed(format!("the robot's {why}")),
        }
    }
}

/// What a robot endpoint waits for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum RobotPhase {
    ExpectCommand,
    ExpectFinish,
    ExpectConfirm,
    Done,
}

/// What both robot endpoints (odometry and private sensing) share: their outputs, in order,
/// what they wait for, the command bookkeeping, the fates and the key, and the closing
/// (`Finish` → `FinishAck` and tags, the controller's tags, an `Abort`).
pub(crate) struct RobotLifecycle {
    phase: RobotPhase,
    outputs: VecDeque<RobotOutput>,
    /// The fate of each codeword (odometry) or doublet (private sensing).
    pub(crate) fates: FateLedger,
    /// The step whose command the robot waits for.
    pub(crate) next_command: u32,
    /// The step whose command was applied since the last sample, reported with the next.
    pub(crate) applied_step: Option<u32>,
    /// Commands missing in a row: the robot holds its last input for up to `max_hold`.
    pub(crate) missing_in_a_row: u32,
    /// Commands applied to the wheels (stop commands and fallbacks excluded).
    pub(crate) commands_applied: u32,
    key: KeyBits,
}

impl std::fmt::Debug for RobotLifecycle {
    /// The phase and the next command (key material is never printed).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RobotLifecycle")
            .field("phase", &self.phase)
            .field("next_command", &self.next_command)
            .finish_non_exhaustive()
    }
}

/// What differs in how the two robots close: which units they may keep, how the key
/// follows from the fates, and what their tags cover.
pub(crate) struct RobotClosing<'a> {
    /// The session's confirmer.
    pub(crate) confirmer: &'a Confirmer,
    /// Whether unit `index` may be kept (one the robot saw erased or did not carry never is).
    pub(crate) keepable: &'a dyn Fn(u32) -> bool,
    /// The robot's key from the final fates.
    pub(crate) key: &'a dyn Fn(&FateLedger) -> KeyBits,
    /// Whether the tags cover the key (odometry) or not (private sensing: per block).
    pub(crate) tags_cover_key: bool,
    /// The outcome once the controller's tags verify.
    pub(crate) verified: Outcome,
    /// The `Abort` reason for a `Finish` covering `codewords` units when the session has `len`.
    pub(crate) count_mismatch: fn(codewords: u32, len: u32) -> String,
}

impl RobotLifecycle {
    /// A session waiting for its first command, with `units` fates to learn.
    pub(crate) fn new(units: u32) -> Self {
        Self {
            phase: RobotPhase::ExpectCommand,
            outputs: VecDeque::new(),
            fates: FateLedger::new(units),
            next_command: 0,
            applied_step: None,
            missing_in_a_row: 0,
            commands_applied: 0,
            key: KeyBits::default(),
        }
    }

    /// The next output, if any.
    pub(crate) fn poll(&mut self) -> Option<RobotOutput> {
        self.outputs.pop_front()
    }

    /// The robot's key (complete once the Finish has arrived).
    pub(crate) fn key(&self) -> &[u8] {
        &self.key
    }

    /// Whether the session is over.
    pub(crate) fn is_done(&self) -> bool {
        self.phase == RobotPhase::Done
    }

    /// Whether commands still drive the session.
    pub(crate) fn expects_command(&self) -> bool {
        self.phase == RobotPhase::ExpectCommand
    }

    /// Whether the run is over and the robot waits for the `Finish`.
    pub(crate) fn expects_finish(&self) -> bool {
        self.phase == RobotPhase::ExpectFinish
    }

    /// Whether the robot waits for step `step`'s command now.
    pub(crate) fn awaits(&self, step: u32) -> bool {
        self.expects_command() && step == self.next_command
    }

    /// The run is over (the stop step passed): the robot waits for the `Finish`.
    pub(crate) fn end_run(&mut self) {
        self.phase = RobotPhase::ExpectFinish;
    }

    /// Step `step`'s command arrived and is applied.
    pub(crate) fn command_arrived(&mut self, step: u32) {
        self.next_command = step + 1;
        self.missing_in_a_row = 0;
        self.applied_step = Some(step);
    }

    /// Step `step`'s command is missing: when the robot waits for it, moves on and returns
    /// how many are missing in a row; otherwise (stale, or not running) `None`.
    pub(crate) fn command_missing(&mut self, step: u32) -> Option<u32> {
        if !self.awaits(step) {
            return None;
        }
        self.next_command = step + 1;
        self.missing_in_a_row += 1;
        self.applied_step = None;
        Some(self.missing_in_a_row)
    }

    /// Sends a message to the controller.
    pub(crate) fn send(&mut self, message: Message) {
        self.outputs.push_back(RobotOutput::Transmit(message));
    }

    /// Drives the wheels.
    pub(crate) fn apply(&mut self, actuation: Actuation) {
        self.outputs.push_back(RobotOutput::Apply(actuation));
    }

    /// Stops the wheels at `step`.
    pub(crate) fn stop_wheels(&mut self, step: u32) {
        self.apply(Actuation {
            step,
            wheels: WheelSpeeds::zeros(),
            bit: None,
            erased: false,
        });
    }

    fn finish(&mut self, outcome: Outcome) {
        self.phase = RobotPhase::Done;
        self.outputs.push_back(RobotOutput::Finished(outcome));
    }

    /// A closing-layer message from the controller: ignored once done; a `Finish` fixes the
    /// fates and the key and is answered with `FinishAck` and the robot's tags, the
    /// controller's tags then decide the outcome, an `Abort` stops the wheels and ends the
    /// session; anything else is ignored.
    pub(crate) fn on_message(&mut self, message: Closing, closing: &RobotClosing<'_>) {
        match (self.phase, message) {
            (
                phase @ (RobotPhase::ExpectCommand
                | RobotPhase::ExpectFinish
                | RobotPhase::ExpectConfirm),
                Closing::Finish { codewords, bitmap },
            ) => {
                if phase == RobotPhase::ExpectCommand {
                    // The stop command was lost: the Finish ends the run wherever it is.
                    self.stop_wheels(self.next_command);
                }
                if codewords != self.fates.len() {
                    let reason = (closing.count_mismatch)(codewords, self.fates.len());
                    self.send(
                        Closing::Abort {
                            reason: reason.clone(),
                        }
                        .into(),
                    );
                    self.finish(Outcome::Aborted(reason));
                    return;
                }
                for index in 0..codewords {
                    let accepted = bitmap_bit(&bitmap, index) && (closing.keepable)(index);
                    self.fates.record(index, accepted);
                }
                self.key = (closing.key)(&self.fates);
                self.phase = RobotPhase::ExpectConfirm;
                for message in self.closer(closing, &self.fates.bitmap()).answer() {
                    self.send(message.into());
                }
            }
            (
                RobotPhase::ExpectConfirm,
                Closing::Confirm {
                    session_tag,
                    key_tag,
                },
            ) => {
                let outcome = self.closer(closing, &self.fates.bitmap()).verdict(
                    session_tag,
                    key_tag,
                    closing.verified.clone(),
                );
                self.finish(outcome);
            }
            (RobotPhase::Done, _) => {}
            (_, Closing::Abort { reason }) => {
                self.stop_wheels(self.next_command);
                self.finish(Outcome::Aborted(format!("controller aborted: {reason}")));
            }
            _ => {}
        }
    }

    fn closer<'a>(&'a self, closing: &RobotClosing<'a>, bitmap: &'a [u64]) -> RobotCloser<'a> {
        RobotCloser {
            confirmer: closing.confirmer,
            bitmap,
            tagged_key: if closing.tags_cover_key {
                &self.key
            } else {
                &[]
            },
        }
    }
}

/// The robot's end of a session (docs/protocol.md): a `Finish` is answered with `FinishAck`
/// and its tags, and the controller's tags decide the outcome.
#[derive(Clone, Debug)]
pub(crate) struct RobotCloser<'a> {
    /// The session's confirmer.
    pub(crate) confirmer: &'a Confirmer,
    /// The final fate bitmap.
    pub(crate) bitmap: &'a [u64],
    /// The key the tags cover: the raw key in odometry mode, empty in private sensing.
    pub(crate) tagged_key: &'a [u8],
}

impl RobotCloser<'_> {
    /// The answer to a `Finish`: `FinishAck`, then the robot's tags.
    pub(crate) fn answer(&self) -> [Closing; 2] {
        let ours = self
            .confirmer
            .tags(DIRECTION.reverse(), self.bitmap, self.tagged_key);
        [
            Closing::FinishAck,
            Closing::Confirm {
                session_tag: ours.session,
                key_tag: ours.key,
            },
        ]
    }

    /// The outcome the controller's tags give: `verified`, or unconfirmed naming the tag
    /// that differs.
    pub(crate) fn verdict(
        &self,
        session: [u8; TAG_BYTES],
        key: [u8; TAG_BYTES],
        verified: Outcome,
    ) -> Outcome {
        let peer = ConfirmTags { session, key };
        match self
            .confirmer
            .check(DIRECTION.reverse(), self.bitmap, self.tagged_key, &peer)
        {
            Ok(()) => verified,
            Err(why) => Outcome::Unconfirmed(format!("the controller's {why}")),
        }
    }
}

/// Whether bit `index` of a `Finish` bitmap is set (bit `i % 64` of word `i / 64`).
pub(crate) fn bitmap_bit(bitmap: &[u64], index: u32) -> bool {
    bitmap
        .get(index as usize / 64)
        .is_some_and(|w| w >> (index % 64) & 1 == 1)
}
