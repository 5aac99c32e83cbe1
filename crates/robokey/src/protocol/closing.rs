//! How a session ends once every fate is known (docs/protocol.md), in either sensing mode:
//! the controller sends `Finish` until the robot's `FinishAck`, then its confirmation tags
//! until the robot's verify, each at most [`FINISH_TRIES`] times; the robot answers a
//! `Finish` with `FinishAck` and its tags.

use std::collections::VecDeque;

use super::controller::ControllerOutput;
use super::fates::FateLedger;
use super::message::Message;
use super::{ConfirmTags, Confirmer, Direction, KeyBits, Outcome, TAG_BYTES};

/// The direction the controller sends in.
const DIRECTION: Direction = Direction::ToRobot;

/// Largest number of Finish (and Confirm) transmissions before the session ends
/// unconfirmed.
pub(crate) const FINISH_TRIES: u32 = 10;

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
        message: Message,
        out: &mut VecDeque<ControllerOutput>,
    ) -> Option<Outcome> {
        match (self.waiting, message) {
            (Waiting::FinishAck { .. }, Message::FinishAck) => {
                self.send_confirm(out);
                self.waiting = Waiting::Confirm { tries: 1 };
                None
            }
            (
                Waiting::FinishAck { .. },
                Message::Confirm {
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
                Message::Confirm {
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
        out.push_back(ControllerOutput::Transmit(Message::Finish {
            codewords: self.codewords,
            bitmap: self.bitmap.clone(),
        }));
    }

    fn send_confirm(&self, out: &mut VecDeque<ControllerOutput>) {
        let ours = self
            .confirmer
            .tags(DIRECTION, &self.bitmap, &self.tagged_key);
        out.push_back(ControllerOutput::Transmit(Message::Confirm {
            session_tag: ours.session,
            key_tag: ours.key,
        }));
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
    pub(crate) fn answer(&self) -> [Message; 2] {
        let ours = self
            .confirmer
            .tags(DIRECTION.reverse(), self.bitmap, self.tagged_key);
        [
            Message::FinishAck,
            Message::Confirm {
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
