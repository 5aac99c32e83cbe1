//! What both robot modes share (docs/protocol.md): the outputs in order, what the robot waits
//! for, the command bookkeeping, the fates and the key, and the closing — a `Finish` is
//! answered with `FinishAck` and the robot's tags, the controller's tags decide the outcome,
//! an `Abort` stops the wheels.

use std::collections::VecDeque;

use super::io::{Actuation, RobotOutput};
use crate::model::WheelSpeeds;
use crate::protocol::fates::{FateLedger, bitmap_bit};
use crate::protocol::{
    Closing, ConfirmTags, Confirmer, Direction, KeyBits, Message, Outcome, TAG_BYTES,
};

/// The direction the robot sends in.
const SENDS: Direction = Direction::ToController;

/// What a robot endpoint waits for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum RobotPhase {
    ExpectCommand,
    ExpectFinish,
    ExpectConfirm,
    Done,
}

/// What both robot modes share: their outputs, in order, what they wait for, the command
/// bookkeeping, the fates and the key, and the closing (`Finish` → `FinishAck` and tags, the
/// controller's tags, an `Abort`).
pub(crate) struct RobotLifecycle {
    phase: RobotPhase,
    outputs: VecDeque<RobotOutput>,
    outcome: Option<Outcome>,
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

/// How a sensing mode closes a session: which units its key keeps, and what its tags cover.
pub(crate) trait ClosingRules {
    /// Whether unit `index` may be kept: one the robot saw erased, or did not carry, never is.
    fn keepable(&self, index: u32) -> bool;

    /// The robot's key from the final fates.
    fn key(&self, fates: &FateLedger) -> KeyBits;

    /// Whether the confirmation tags cover the key (odometry) or not (private sensing: its
    /// raw bits are confirmed per post-processing block).
    fn tags_cover_key(&self) -> bool;

    /// The outcome once the controller's tags verify.
    fn verified(&self) -> Outcome;

    /// The `Abort` reason for a `Finish` covering `codewords` units when the session has `len`.
    fn count_mismatch(&self, codewords: u32, len: u32) -> String;
}

impl RobotLifecycle {
    /// A session waiting for its first command, with `units` fates to learn.
    pub(crate) fn new(units: u32) -> Self {
        Self {
            phase: RobotPhase::ExpectCommand,
            outputs: VecDeque::new(),
            outcome: None,
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
    pub(crate) fn send(&mut self, message: impl Into<Message>) {
        self.outputs
            .push_back(RobotOutput::Transmit(message.into()));
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
        self.outcome = Some(outcome.clone());
        self.outputs.push_back(RobotOutput::Finished(outcome));
    }

    /// How the session ended, once it has.
    pub(crate) fn outcome(&self) -> Option<&Outcome> {
        self.outcome.as_ref()
    }

    /// Asks the shell for sample `step`.
    pub(crate) fn sense(&mut self, step: u32) {
        self.outputs.push_back(RobotOutput::Sense { step });
    }

    /// Ends the session aborted (the robot's own reason: silence), stopping the wheels.
    pub(crate) fn abort(&mut self, reason: String) {
        self.stop_wheels(self.next_command);
        self.finish(Outcome::Aborted(reason));
    }

    /// A message from the controller that the endpoint did not take (its commands):
    /// ignored once done; a `Finish` fixes the fates and the key and is answered with
    /// `FinishAck` and the robot's tags, the controller's tags then decide the outcome, an
    /// `Abort` stops the wheels and ends the session; anything else is ignored.
    pub(crate) fn on_message(
        &mut self,
        message: Closing,
        confirmer: &Confirmer,
        mode: &dyn ClosingRules,
    ) {
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
                    let reason = mode.count_mismatch(codewords, self.fates.len());
                    self.send(Closing::Abort {
                        reason: reason.clone(),
                    });
                    self.finish(Outcome::Aborted(reason));
                    return;
                }
                for index in 0..codewords {
                    let accepted = bitmap_bit(&bitmap, index) && mode.keepable(index);
                    self.fates.record(index, accepted);
                }
                self.key = mode.key(&self.fates);
                self.phase = RobotPhase::ExpectConfirm;
                for message in self.closer(confirmer, mode, &self.fates.bitmap()).answer() {
                    self.send(message);
                }
            }
            (
                RobotPhase::ExpectConfirm,
                Closing::Confirm {
                    session_tag,
                    key_tag,
                },
            ) => {
                let outcome = self.closer(confirmer, mode, &self.fates.bitmap()).verdict(
                    session_tag,
                    key_tag,
                    mode.verified(),
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

    fn closer<'a>(
        &'a self,
        confirmer: &'a Confirmer,
        mode: &dyn ClosingRules,
        bitmap: &'a [u64],
    ) -> RobotCloser<'a> {
        RobotCloser {
            confirmer,
            bitmap,
            tagged_key: if mode.tags_cover_key() {
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
        let ours = self.confirmer.tags(SENDS, self.bitmap, self.tagged_key);
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
            .check(SENDS, self.bitmap, self.tagged_key, &peer)
        {
            Ok(()) => verified,
            Err(why) => Outcome::Unconfirmed(format!("the controller's {why}")),
        }
    }
}
