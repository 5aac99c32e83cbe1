//! What both controller modes share (docs/protocol.md): the outputs in order, the fates, the
//! key, and how a session ends once every fate is known — the controller sends `Finish` until
//! the robot's `FinishAck`, then its confirmation tags until the robot's verify, each at most
//! [`FINISH_TRIES`] times.

use std::collections::VecDeque;

use super::{ControllerEvent, ControllerOutput};
use crate::protocol::fates::FateLedger;
use crate::protocol::{
    Closing, ConfirmTags, Confirmer, Direction, KeyBits, Message, Outcome, TAG_BYTES,
};

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

/// What both controller modes share: their outputs, in order, where the session is — running,
/// closing (every fate known: [`Closer`]) or done —, the fates, the robot's fate cursor as it
/// last reported it, and the key.
#[derive(Clone)]
pub(crate) struct ControllerLifecycle {
    phase: Phase,
    outputs: VecDeque<ControllerOutput>,
    /// The fate of each codeword (odometry) or doublet (private sensing).
    pub(crate) fates: FateLedger,
    /// The robot's contiguous fate cursor: the first unit whose fate it lacks.
    pub(crate) robot_cursor: u32,
    /// The controller's key `K_c` (complete once the session has finished).
    pub(crate) key: KeyBits,
}

impl std::fmt::Debug for ControllerLifecycle {
    /// The phase and how many outputs wait (they may carry decisions: not printed).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ControllerLifecycle")
            .field("phase", &self.phase)
            .field("outputs", &self.outputs.len())
            .field("key_bits", &self.key.len())
            .finish_non_exhaustive()
    }
}

impl ControllerLifecycle {
    /// A running session with no output yet, `units` fates to decide.
    pub(crate) fn new(units: u32) -> Self {
        Self {
            phase: Phase::Running,
            outputs: VecDeque::new(),
            fates: FateLedger::new(units),
            robot_cursor: 0,
            key: KeyBits::default(),
        }
    }

    /// Whether every fate is known and the controller closes the session.
    pub(crate) fn closing(&self) -> bool {
        matches!(self.phase, Phase::Closing(_))
    }

    /// Ends the session and tells the robot why.
    pub(crate) fn abort(&mut self, reason: String) {
        self.send(Closing::Abort {
            reason: reason.clone(),
        });
        self.finish(Outcome::Aborted(reason));
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
    pub(crate) fn send(&mut self, message: impl Into<Message>) {
        self.outputs
            .push_back(ControllerOutput::Transmit(message.into()));
    }

    /// Ends the session with `outcome`.
    pub(crate) fn finish(&mut self, outcome: Outcome) {
        self.phase = Phase::Done;
        self.emit(ControllerEvent::Finished(outcome));
    }

    /// Every fate is known and `key` is the controller's: starts closing
    /// ([`Closer::start`]); the tags cover the key when `tags_cover_key` (odometry), and a
    /// verified robot ends the session as `verified`.
    pub(crate) fn close(
        &mut self,
        confirmer: Confirmer,
        key: KeyBits,
        tags_cover_key: bool,
        verified: Outcome,
    ) {
        self.key = key;
        let tagged: &[u8] = if tags_cover_key { &self.key } else { &[] };
        let closer = Closer::start(confirmer, &self.fates, tagged, verified, &mut self.outputs);
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

    /// A message from the robot that the running endpoint did not take: ignored once done,
    /// an `Abort` ends the session, a closing session hands it to its [`Closer`]; anything
    /// else (a duplicate, a message that does not fit the phase) is ignored.
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
        let finish = Closing::Finish {
            codewords: self.codewords,
            bitmap: self.bitmap.clone(),
        };
        out.push_back(ControllerOutput::Transmit(finish.into()));
    }

    fn send_confirm(&self, out: &mut VecDeque<ControllerOutput>) {
        let ours = self
            .confirmer
            .tags(DIRECTION, &self.bitmap, &self.tagged_key);
        let confirm = Closing::Confirm {
            session_tag: ours.session,
            key_tag: ours.key,
        };
        out.push_back(ControllerOutput::Transmit(confirm.into()));
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
