//! The two ends of an authenticated session, as sans-I/O state machines over datagrams:
//! bytes in, a [`Delivery`] or a counted [`Rejection`] out. The endpoints above them never
//! see an unauthenticated frame, and a rejected datagram changes no state.

use std::collections::VecDeque;

use rand::CryptoRng;

use super::window::{Freshness, ReplayWindow};
use super::{
    Confirmer, Direction, MacKey, NONCE_BYTES, PairingSecret, SessionKeys, seal, verifies,
};
use crate::protocol::message::{Handshake, Message};
use crate::protocol::terms::terms_difference;
use crate::protocol::wire::{Frame, decode};

/// Most half-open handshakes (verified Hellos without a session-key frame yet) the robot
/// remembers; the oldest is forgotten first.
pub const HALF_OPEN: usize = 8;

/// How many answered `Hello`s (their `nonce_c`) the robot remembers, so that a replayed one is
/// answered at most once: far more distinct recordings than an attacker can have of one robot.
pub const ANSWERED: usize = 4096;

/// Why a datagram was dropped. None of these changes state, resets a timer or ends a
/// session.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum Rejection {
    /// Not a version-2 frame (too short, bad magic, other version, unknown type, bad
    /// length or field).
    #[error("malformed frame")]
    Malformed,
    /// The MAC does not verify.
    #[error("MAC does not verify")]
    BadMac,
    /// A handshake frame (`Hello`, `HelloAck`, `Refuse`) whose MAC does not verify under the
    /// handshake key: a peer that tried to pair with another secret (or a forgery).
    #[error("handshake MAC does not verify")]
    HandshakeBadMac,
    /// A sequence number already accepted, or a handshake frame answering another Hello.
    #[error("replayed")]
    Replayed,
    /// 64 or more sequence numbers behind the highest accepted.
    #[error("behind the replay window")]
    BehindWindow,
    /// From another address than the bound peer.
    #[error("from another address than the peer")]
    WrongPeer,
    /// Of another session (or of no handshake the robot remembers).
    #[error("of another session")]
    OtherSession,
    /// The peer declares another pairing mode (paired vs `--unauthenticated`).
    #[error("the peer's pairing mode differs")]
    PairingMode,
    /// A valid frame that does not fit the state (e.g. a session frame before the
    /// handshake, a Hello after binding).
    #[error("unexpected in this state")]
    Unexpected,
}

/// Dropped datagrams, by [`Rejection`] reason.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct RejectionCounts {
    /// [`Rejection::Malformed`].
    pub malformed: u64,
    /// [`Rejection::BadMac`].
    pub bad_mac: u64,
    /// [`Rejection::HandshakeBadMac`].
    pub handshake_bad_mac: u64,
    /// [`Rejection::Replayed`].
    pub replayed: u64,
    /// [`Rejection::BehindWindow`].
    pub behind_window: u64,
    /// [`Rejection::WrongPeer`].
    pub wrong_peer: u64,
    /// [`Rejection::OtherSession`].
    pub other_session: u64,
    /// [`Rejection::PairingMode`].
    pub pairing_mode: u64,
    /// [`Rejection::Unexpected`].
    pub unexpected: u64,
}

impl RejectionCounts {
    fn count(&mut self, rejection: Rejection) {
        let slot = match rejection {
            Rejection::Malformed => &mut self.malformed,
            Rejection::BadMac => &mut self.bad_mac,
            Rejection::HandshakeBadMac => &mut self.handshake_bad_mac,
            Rejection::Replayed => &mut self.replayed,
            Rejection::BehindWindow => &mut self.behind_window,
            Rejection::WrongPeer => &mut self.wrong_peer,
            Rejection::OtherSession => &mut self.other_session,
            Rejection::PairingMode => &mut self.pairing_mode,
            Rejection::Unexpected => &mut self.unexpected,
        };
        *slot += 1;
    }

    /// All rejections.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.malformed
            + self.bad_mac
            + self.handshake_bad_mac
            + self.replayed
            + self.behind_window
            + self.wrong_peer
            + self.other_session
            + self.pairing_mode
            + self.unexpected
    }
}

/// Counters of one channel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct ChannelCounts {
    /// Session frames accepted.
    pub accepted: u64,
    /// Of those, accepted out of order within the replay window.
    pub reordered: u64,
    /// Robot: verified `Hello`s answered (a `HelloAck` or a `Refuse`), each controller's
    /// retransmissions included. A replayed old `Hello` answered before it was known as one
    /// is among them; once known, it is rejected as replayed.
    pub hellos_answered: u64,
    /// Dropped datagrams by reason.
    pub rejected: RejectionCounts,
}

impl ChannelCounts {
    /// The counts of two channels in turn (a controller that restarted its handshake).
    #[must_use]
    pub fn plus(self, other: Self) -> Self {
        let (a, b) = (self.rejected, other.rejected);
        Self {
            accepted: self.accepted + other.accepted,
            reordered: self.reordered + other.reordered,
            hellos_answered: self.hellos_answered + other.hellos_answered,
            rejected: RejectionCounts {
                malformed: a.malformed + b.malformed,
                bad_mac: a.bad_mac + b.bad_mac,
                handshake_bad_mac: a.handshake_bad_mac + b.handshake_bad_mac,
                replayed: a.replayed + b.replayed,
                behind_window: a.behind_window + b.behind_window,
                wrong_peer: a.wrong_peer + b.wrong_peer,
                other_session: a.other_session + b.other_session,
                pairing_mode: a.pairing_mode + b.pairing_mode,
                unexpected: a.unexpected + b.unexpected,
            },
        }
    }
}

/// What an accepted datagram gives.
#[derive(Clone, Debug, PartialEq)]
pub enum Delivery {
    /// An authenticated, fresh session message for the endpoint.
    Message(Message),
    /// Robot: send `bytes` back to the datagram's sender (the answer to a verified Hello:
    /// a HelloAck, or a Refuse naming `refused`). Nothing was committed.
    Answer {
        /// The sealed answer.
        bytes: Vec<u8>,
        /// Why the Hello was refused, if it was.
        refused: Option<String>,
    },
    /// Controller: the HelloAck verified; the session keys are derived.
    Established,
    /// A Hello was refused, with the reason: at the controller, its own (by the robot); at
    /// the robot's shell, one it answered with a Refuse.
    Refused(String),
}

/// A session's keys, replay window and numbering once both nonces are known.
struct Keyed {
    session: u32,
    keys: SessionKeys,
    /// Receiving direction's window.
    window: ReplayWindow,
    next_seq: u32,
    /// `Hello ‖ HelloAck` as exact bytes.
    transcript: Vec<u8>,
}

impl Keyed {
    fn new(session: u32, keys: SessionKeys, transcript: Vec<u8>) -> Self {
        Self {
            session,
            keys,
            window: ReplayWindow::default(),
            next_seq: 1,
            transcript,
        }
    }

    /// Checks a decoded session frame received in `direction`; on success records it.
    fn open(
        &mut self,
        frame: &Frame,
        bytes: &[u8],
        direction: Direction,
    ) -> Result<Freshness, Rejection> {
        let freshness = self.window.check(frame.seq)?;
        if !verifies(bytes, self.keys.key(direction)) {
            return Err(Rejection::BadMac);
        }
        self.window.accept(frame.seq);
        Ok(freshness)
    }

    fn seal(&mut self, message: Message, direction: Direction) -> Option<Vec<u8>> {
        let seq = self.next_seq;
        self.next_seq = seq.checked_add(1)?;
        let frame = Frame {
            session: self.session,
            seq,
            message,
        };
        Some(seal(&frame, self.keys.key(direction)))
    }

    fn confirmer(&self) -> Confirmer {
        Confirmer::new(self.keys.clone(), self.transcript.clone())
    }
}

/// Whether a message is MACed under the handshake key (every other one is under a session
/// key, `Ready` included).
fn is_handshake(message: &Message) -> bool {
    matches!(
        message,
        Message::Handshake(
            Handshake::Hello { .. } | Handshake::HelloAck { .. } | Handshake::Refuse { .. }
        )
    )
}

fn handshake_frame(session: u32, message: Handshake) -> Frame {
    Frame {
        session,
        seq: 0,
        message: message.into(),
    }
}

/// The controller's end, generic over the robot's address `A`: sends `Hello`, accepts the
/// matching `HelloAck`, then seals and opens session frames.
pub struct ControllerChannel<A> {
    robot: A,
    secret: PairingSecret,
    handshake: MacKey,
    session: u32,
    nonce: [u8; NONCE_BYTES],
    hello: Vec<u8>,
    keyed: Option<Keyed>,
    counts: ChannelCounts,
}

impl<A> std::fmt::Debug for ControllerChannel<A> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ControllerChannel")
            .field("session", &self.session)
            .field("established", &self.keyed.is_some())
            .finish_non_exhaustive()
    }
}

impl<A: Copy + PartialEq> ControllerChannel<A> {
    /// A channel to the robot at `robot` for session `session`, with a fresh `nonce_c` from
    /// `rng` (the OS CSPRNG).
    pub fn new<R: CryptoRng + ?Sized>(
        secret: PairingSecret,
        robot: A,
        session: u32,
        config_digest: [u8; 32],
        terms: String,
        rng: &mut R,
    ) -> Self {
        let mut nonce = [0u8; NONCE_BYTES];
        rng.fill_bytes(&mut nonce);
        let handshake = secret.handshake_key();
        let hello = Handshake::Hello {
            auth: secret.mode(),
            nonce,
            config_digest,
            terms,
        };
        let hello = seal(&handshake_frame(session, hello), &handshake);
        Self {
            robot,
            secret,
            handshake,
            session,
            nonce,
            hello,
            keyed: None,
            counts: ChannelCounts::default(),
        }
    }

    /// The sealed Hello (the same bytes on every retransmission).
    #[must_use]
    pub fn hello(&self) -> &[u8] {
        &self.hello
    }

    /// Whether the HelloAck arrived.
    #[must_use]
    pub fn is_established(&self) -> bool {
        self.keyed.is_some()
    }

    /// Counters so far.
    #[must_use]
    pub fn counts(&self) -> ChannelCounts {
        self.counts
    }

    /// The session's confirmer, once established.
    #[must_use]
    pub fn confirmer(&self) -> Option<Confirmer> {
        self.keyed.as_ref().map(Keyed::confirmer)
    }

    /// Seals a session message for the robot; `None` before the HelloAck (or after 2³²−1
    /// frames).
    pub fn seal(&mut self, message: Message) -> Option<Vec<u8>> {
        self.keyed.as_mut()?.seal(message, Direction::ToRobot)
    }

    /// The session id.
    #[must_use]
    pub fn session(&self) -> u32 {
        self.session
    }

    /// The robot's address.
    #[must_use]
    pub fn robot(&self) -> A {
        self.robot
    }

    /// Takes one datagram from `from`.
    ///
    /// # Errors
    /// The [`Rejection`] it was dropped for (already counted).
    pub fn on_datagram(&mut self, from: A, bytes: &[u8]) -> Result<Delivery, Rejection> {
        let result = if from == self.robot {
            self.accept(bytes)
        } else {
            Err(Rejection::WrongPeer)
        };
        match &result {
            Ok(Delivery::Message(_)) => self.counts.accepted += 1,
            Ok(_) => {}
            Err(rejection) => self.counts.rejected.count(*rejection),
        }
        result
    }

    fn accept(&mut self, bytes: &[u8]) -> Result<Delivery, Rejection> {
        let frame = decode(bytes).map_err(|_| Rejection::Malformed)?;
        if frame.session != self.session {
            return Err(Rejection::OtherSession);
        }
        match &frame.message {
            Message::Handshake(Handshake::HelloAck {
                auth,
                nonce_c,
                nonce_r,
                ..
            }) => {
                if *auth != self.secret.mode() {
                    return Err(Rejection::PairingMode);
                }
                if !verifies(bytes, &self.handshake) {
                    return Err(Rejection::HandshakeBadMac);
                }
                if *nonce_c != self.nonce || self.keyed.is_some() {
                    return Err(Rejection::Replayed);
                }
                let keys = self.secret.session_keys(&self.nonce, nonce_r);
                let transcript = [self.hello.as_slice(), bytes].concat();
                self.keyed = Some(Keyed::new(self.session, keys, transcript));
                Ok(Delivery::Established)
            }
            Message::Handshake(Handshake::Refuse { nonce_c, reason }) => {
                if !verifies(bytes, &self.handshake) {
                    return Err(Rejection::HandshakeBadMac);
                }
                if *nonce_c != self.nonce || self.keyed.is_some() {
                    return Err(Rejection::Replayed);
                }
                Ok(Delivery::Refused(reason.clone()))
            }
            Message::Handshake(Handshake::Hello { .. }) => Err(Rejection::Unexpected),
            _ => {
                let keyed = self.keyed.as_mut().ok_or(Rejection::Unexpected)?;
                let freshness = keyed.open(&frame, bytes, Direction::ToController)?;
                self.counts.reordered += u64::from(freshness == Freshness::Reordered);
                Ok(Delivery::Message(frame.message))
            }
        }
    }
}

/// A verified Hello the robot answered, waiting for its first session-key frame.
struct HalfOpen {
    nonce_c: [u8; NONCE_BYTES],
    answer: Vec<u8>,
    keyed: Keyed,
}

/// The bound session.
struct Bound<A> {
    peer: A,
    keyed: Keyed,
}

/// The robot's end, generic over the peer address `A`: answers verified Hellos without
/// committing, binds session and peer on the first frame MACed under the controller→robot
/// key, then seals and opens session frames.
pub struct RobotChannel<A> {
    secret: PairingSecret,
    handshake: MacKey,
    config_digest: [u8; 32],
    terms: String,
    half_open: VecDeque<HalfOpen>,
    /// The `nonce_c` of every `Hello` answered, the last [`ANSWERED`].
    answered: VecDeque<[u8; NONCE_BYTES]>,
    bound: Option<Bound<A>>,
    counts: ChannelCounts,
}

impl<A> std::fmt::Debug for RobotChannel<A> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RobotChannel")
            .field("half_open", &self.half_open.len())
            .field("bound", &self.bound.is_some())
            .finish_non_exhaustive()
    }
}

impl<A: Copy + PartialEq> RobotChannel<A> {
    /// A listening channel that accepts Hellos with the robot's `terms` (and their
    /// SHA-256 `config_digest`).
    #[must_use]
    pub fn new(secret: PairingSecret, config_digest: [u8; 32], terms: String) -> Self {
        Self {
            handshake: secret.handshake_key(),
            secret,
            config_digest,
            terms,
            half_open: VecDeque::new(),
            answered: VecDeque::new(),
            bound: None,
            counts: ChannelCounts::default(),
        }
    }

    /// The bound controller's address and session id.
    #[must_use]
    pub fn bound(&self) -> Option<(A, u32)> {
        self.bound.as_ref().map(|b| (b.peer, b.keyed.session))
    }

    /// Counters so far.
    #[must_use]
    pub fn counts(&self) -> ChannelCounts {
        self.counts
    }

    /// The session's confirmer, once bound.
    #[must_use]
    pub fn confirmer(&self) -> Option<Confirmer> {
        self.bound.as_ref().map(|b| b.keyed.confirmer())
    }

    /// Seals a session message for the bound controller; `None` before binding.
    pub fn seal(&mut self, message: Message) -> Option<Vec<u8>> {
        self.bound
            .as_mut()?
            .keyed
            .seal(message, Direction::ToController)
    }

    /// Takes one datagram from `from`; `rng` (the OS CSPRNG) draws `nonce_r` for a new
    /// Hello.
    ///
    /// # Errors
    /// The [`Rejection`] it was dropped for (already counted).
    pub fn on_datagram<R: CryptoRng + ?Sized>(
        &mut self,
        from: A,
        bytes: &[u8],
        rng: &mut R,
    ) -> Result<Delivery, Rejection> {
        let result = self.accept(from, bytes, rng);
        match &result {
            Ok(Delivery::Message(_)) => self.counts.accepted += 1,
            Ok(_) => {}
            Err(rejection) => self.counts.rejected.count(*rejection),
        }
        result
    }

    fn accept<R: CryptoRng + ?Sized>(
        &mut self,
        from: A,
        bytes: &[u8],
        rng: &mut R,
    ) -> Result<Delivery, Rejection> {
        let frame = decode(bytes).map_err(|_| Rejection::Malformed)?;
        if let Some(bound) = &mut self.bound {
            if frame.session != bound.keyed.session {
                return Err(Rejection::OtherSession);
            }
            if from != bound.peer {
                return Err(Rejection::WrongPeer);
            }
            if is_handshake(&frame.message) {
                return Err(Rejection::Unexpected);
            }
            let freshness = bound.keyed.open(&frame, bytes, Direction::ToRobot)?;
            self.counts.reordered += u64::from(freshness == Freshness::Reordered);
            return Ok(Delivery::Message(frame.message));
        }
        match &frame.message {
            Message::Handshake(Handshake::Hello {
                auth,
                nonce,
                config_digest,
                terms,
            }) => {
                if *auth != self.secret.mode() {
                    return Err(Rejection::PairingMode);
                }
                if !verifies(bytes, &self.handshake) {
                    return Err(Rejection::HandshakeBadMac);
                }
                if let Some(open) = self
                    .half_open
                    .iter()
                    .find(|h| h.nonce_c == *nonce && h.keyed.session == frame.session)
                {
                    // The controller's retransmission: the same answer.
                    self.counts.hellos_answered += 1;
                    return Ok(Delivery::Answer {
                        bytes: open.answer.clone(),
                        refused: None,
                    });
                }
                // A Hello answered before and no longer waiting: an old one replayed (or a
                // controller whose handshake was pushed out, which starts a fresh one). It
                // never takes a fresh controller's slot.
                if self.answered.contains(nonce) {
                    return Err(Rejection::Replayed);
                }
                if self.answered.len() == ANSWERED {
                    self.answered.pop_front();
                }
                self.answered.push_back(*nonce);
                self.counts.hellos_answered += 1;
                if *config_digest != self.config_digest {
                    let reason = format!(
                        "configurations differ: {}",
                        terms_difference(&self.terms, terms, "robot", "controller")
                    );
                    let refuse = Handshake::Refuse {
                        nonce_c: *nonce,
                        reason: reason.clone(),
                    };
                    return Ok(Delivery::Answer {
                        bytes: seal(&handshake_frame(frame.session, refuse), &self.handshake),
                        refused: Some(reason),
                    });
                }
                let mut nonce_r = [0u8; NONCE_BYTES];
                rng.fill_bytes(&mut nonce_r);
                let ack = Handshake::HelloAck {
                    auth: self.secret.mode(),
                    nonce_c: *nonce,
                    nonce_r,
                    config_digest: self.config_digest,
                };
                let answer = seal(&handshake_frame(frame.session, ack), &self.handshake);
                let keys = self.secret.session_keys(nonce, &nonce_r);
                let transcript = [bytes, answer.as_slice()].concat();
                if self.half_open.len() == HALF_OPEN {
                    self.half_open.pop_front();
                }
                self.half_open.push_back(HalfOpen {
                    nonce_c: *nonce,
                    answer: answer.clone(),
                    keyed: Keyed::new(frame.session, keys, transcript),
                });
                Ok(Delivery::Answer {
                    bytes: answer,
                    refused: None,
                })
            }
            Message::Handshake(Handshake::HelloAck { .. } | Handshake::Refuse { .. }) => {
                Err(Rejection::Unexpected)
            }
            _ => {
                let mut candidates = self
                    .half_open
                    .iter()
                    .enumerate()
                    .filter(|(_, h)| h.keyed.session == frame.session)
                    .peekable();
                if candidates.peek().is_none() {
                    return Err(Rejection::OtherSession);
                }
                let index = candidates
                    .find(|(_, h)| verifies(bytes, h.keyed.keys.key(Direction::ToRobot)))
                    .map(|(i, _)| i)
                    .ok_or(Rejection::BadMac)?;
                let mut open = self.half_open.remove(index).expect("index found above");
                open.keyed.window.accept(frame.seq);
                self.half_open.clear();
                self.bound = Some(Bound {
                    peer: from,
                    keyed: open.keyed,
                });
                Ok(Delivery::Message(frame.message))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::message::Closing;
    use rand::SeedableRng;
    use rand::rngs::ChaCha20Rng;

    const CONTROLLER: u8 = 1;
    const ATTACKER: u8 = 2;
    const ROBOT: u8 = 3;

    fn pair(
        secret: &PairingSecret,
        rng: &mut ChaCha20Rng,
    ) -> (ControllerChannel<u8>, RobotChannel<u8>) {
        let controller =
            ControllerChannel::new(secret.clone(), ROBOT, 77, [5; 32], "t = 1\n".into(), rng);
        let robot = RobotChannel::new(secret.clone(), [5; 32], "t = 1\n".into());
        (controller, robot)
    }

    /// Hello → HelloAck → Ready: both ends keyed, the robot bound to `CONTROLLER`.
    fn established(rng: &mut ChaCha20Rng) -> (ControllerChannel<u8>, RobotChannel<u8>) {
        let (mut controller, mut robot) = pair(&PairingSecret::from_bytes(&[3; 32]), rng);
        let Ok(Delivery::Answer {
            bytes,
            refused: None,
        }) = robot.on_datagram(CONTROLLER, controller.hello(), rng)
        else {
            panic!("the Hello is answered");
        };
        assert_eq!(
            controller.on_datagram(ROBOT, &bytes),
            Ok(Delivery::Established)
        );
        let ready = controller.seal(Handshake::Ready.into()).unwrap();
        assert_eq!(
            robot.on_datagram(CONTROLLER, &ready, rng),
            Ok(Delivery::Message(Message::Handshake(Handshake::Ready)))
        );
        assert_eq!(robot.bound(), Some((CONTROLLER, 77)));
        (controller, robot)
    }

    #[test]
    fn flipping_any_byte_of_a_frame_gets_it_rejected_and_changes_nothing() {
        let mut rng = ChaCha20Rng::seed_from_u64(1);
        let (mut controller, mut robot) = established(&mut rng);
        let abort = controller
            .seal(
                Closing::Abort {
                    reason: "forged".into(),
                }
                .into(),
            )
            .unwrap();
        for at in 0..abort.len() {
            for flip in [0x01, 0x80] {
                let mut bytes = abort.clone();
                bytes[at] ^= flip;
                let rejection = robot.on_datagram(CONTROLLER, &bytes, &mut rng).unwrap_err();
                assert!(
                    matches!(
                        rejection,
                        Rejection::Malformed
                            | Rejection::BadMac
                            | Rejection::OtherSession
                            | Rejection::Unexpected
                    ),
                    "byte {at}: {rejection:?}"
                );
            }
        }
        let counts = robot.counts();
        assert_eq!(counts.rejected.total(), 2 * abort.len() as u64);
        assert!(counts.rejected.bad_mac > 0 && counts.rejected.malformed > 0);
        // The genuine frame still goes through: nothing was consumed by the forgeries.
        assert!(matches!(
            robot.on_datagram(CONTROLLER, &abort, &mut rng),
            Ok(Delivery::Message(Message::Closing(Closing::Abort { .. })))
        ));
        // Sent again, it is a replay.
        assert_eq!(
            robot.on_datagram(CONTROLLER, &abort, &mut rng),
            Err(Rejection::Replayed)
        );
    }

    #[test]
    fn reflected_frames_other_peers_and_truncation_are_rejected() {
        let mut rng = ChaCha20Rng::seed_from_u64(2);
        let (mut controller, mut robot) = established(&mut rng);
        let finish_ack = controller.seal(Closing::FinishAck.into()).unwrap();
        // The controller's own frame, reflected to it, is under the other direction's key.
        assert_eq!(
            controller.on_datagram(ROBOT, &finish_ack),
            Err(Rejection::BadMac)
        );
        // The right frame from another address.
        assert_eq!(
            robot.on_datagram(ATTACKER, &finish_ack, &mut rng),
            Err(Rejection::WrongPeer)
        );
        assert_eq!(
            robot.on_datagram(CONTROLLER, &finish_ack[..finish_ack.len() - 1], &mut rng),
            Err(Rejection::Malformed)
        );
        // A fresh Hello after binding is not answered.
        assert_eq!(
            robot.on_datagram(CONTROLLER, controller.hello(), &mut rng),
            Err(Rejection::Unexpected)
        );
        let reply = robot.seal(Closing::FinishAck.into()).unwrap();
        assert_eq!(
            controller.on_datagram(ATTACKER, &reply),
            Err(Rejection::WrongPeer)
        );
        assert_eq!(
            controller.on_datagram(ROBOT, &reply),
            Ok(Delivery::Message(Message::Closing(Closing::FinishAck)))
        );
    }

    proptest::proptest! {
        /// Random edits of genuine frames (any bytes, any length) and arbitrary datagrams at
        /// both bound ends: each is rejected or is a genuine frame, and afterwards the genuine
        /// next frame in each direction still goes through.
        #[test]
        fn no_datagram_an_attacker_makes_changes_state(
            seed in proptest::prelude::any::<u64>(),
            edits in proptest::collection::vec(
                (proptest::prelude::any::<usize>(), proptest::prelude::any::<u8>(), 0usize..3),
                1..6,
            ),
            junk in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..120),
        ) {
            let mut rng = ChaCha20Rng::seed_from_u64(seed);
            let (mut controller, mut robot) = established(&mut rng);
            let genuine = controller.seal(Closing::Finish { codewords: 70, bitmap: vec![5, 1] }.into()).unwrap();
            let mut edited = genuine.clone();
            for (at, byte, action) in edits {
                let at = at % (edited.len() + 1);
                match action {
                    0 if at < edited.len() => edited[at] ^= byte | 1,
                    1 => edited.insert(at, byte),
                    _ if at < edited.len() => { edited.remove(at); }
                    _ => edited.push(byte),
                }
            }
            for bytes in [&edited, &junk] {
                proptest::prop_assume!(*bytes != genuine);
                proptest::prop_assert!(robot.on_datagram(CONTROLLER, bytes, &mut rng).is_err());
                proptest::prop_assert!(controller.on_datagram(ROBOT, bytes).is_err());
            }
            let delivered = robot.on_datagram(CONTROLLER, &genuine, &mut rng);
            let finish = matches!(delivered, Ok(Delivery::Message(Message::Closing(Closing::Finish { .. }))));
            proptest::prop_assert!(finish, "{:?}", delivered);
            let back = robot.seal(Closing::FinishAck.into()).unwrap();
            proptest::prop_assert_eq!(
                controller.on_datagram(ROBOT, &back),
                Ok(Delivery::Message(Message::Closing(Closing::FinishAck)))
            );
        }
    }

    #[test]
    fn reordering_within_the_window_is_accepted_and_counted_apart() {
        let mut rng = ChaCha20Rng::seed_from_u64(3);
        let (mut controller, mut robot) = established(&mut rng);
        let frames: Vec<Vec<u8>> = (0..70)
            .map(|_| controller.seal(Closing::FinishAck.into()).unwrap())
            .collect();
        for bytes in frames[1..68].iter().chain([&frames[0], &frames[69]]) {
            let _ = robot.on_datagram(CONTROLLER, bytes, &mut rng);
        }
        // Frame 0 (seq 2) arrived 67 numbers late: behind the window.
        assert_eq!(robot.counts().rejected.behind_window, 1);
        assert_eq!(
            robot.on_datagram(CONTROLLER, &frames[68], &mut rng),
            Ok(Delivery::Message(Message::Closing(Closing::FinishAck)))
        );
        assert_eq!(robot.counts().reordered, 1);
        assert_eq!(robot.counts().accepted, 1 + 69);
    }

    #[test]
    fn a_replayed_hello_is_answered_alike_and_binds_nothing() {
        let mut rng = ChaCha20Rng::seed_from_u64(4);
        let secret = PairingSecret::from_bytes(&[3; 32]);
        let (controller, mut robot) = pair(&secret, &mut rng);
        let first = robot.on_datagram(ATTACKER, controller.hello(), &mut rng);
        let again = robot.on_datagram(ATTACKER, controller.hello(), &mut rng);
        assert!(matches!(first, Ok(Delivery::Answer { .. })));
        assert_eq!(first, again);
        assert_eq!(robot.bound(), None);
        // Without the session keys the attacker cannot bind: a Ready sealed under the
        // handshake key (the only key a replay shows) fails.
        let forged = seal(
            &Frame {
                session: 77,
                seq: 1,
                message: Message::Handshake(Handshake::Ready),
            },
            &secret.handshake_key(),
        );
        assert_eq!(
            robot.on_datagram(ATTACKER, &forged, &mut rng),
            Err(Rejection::BadMac)
        );
        assert_eq!(robot.bound(), None);
        // Half-open state stays bounded under a flood of distinct Hellos.
        for session in 0..3 * HALF_OPEN as u32 {
            let c = ControllerChannel::new(
                secret.clone(),
                ROBOT,
                session,
                [5; 32],
                "t = 1\n".into(),
                &mut rng,
            );
            let _ = robot.on_datagram(ATTACKER, c.hello(), &mut rng);
        }
        assert_eq!(robot.half_open.len(), HALF_OPEN);
    }

    /// The lock-out: ten recorded Hellos cycled at the robot pushed a fresh
    /// controller's half-open handshake out. Each is now answered once; its replays are
    /// rejected as such and take no slot, so the fresh controller's `Ready` binds.
    #[test]
    fn cycled_old_hellos_are_answered_once_and_never_push_a_fresh_handshake_out() {
        let mut rng = ChaCha20Rng::seed_from_u64(6);
        let secret = PairingSecret::from_bytes(&[3; 32]);
        let old: Vec<Vec<u8>> = (0..10)
            .map(|session| {
                let c = ControllerChannel::<u8>::new(
                    secret.clone(),
                    ROBOT,
                    1000 + session,
                    [5; 32],
                    "t = 1\n".into(),
                    &mut rng,
                );
                c.hello().to_vec()
            })
            .collect();
        let (mut controller, mut robot) = pair(&secret, &mut rng);
        for hello in &old {
            assert!(matches!(
                robot.on_datagram(ATTACKER, hello, &mut rng),
                Ok(Delivery::Answer { .. })
            ));
        }
        let Ok(Delivery::Answer { bytes, .. }) =
            robot.on_datagram(CONTROLLER, controller.hello(), &mut rng)
        else {
            panic!("the fresh Hello is answered");
        };
        // The three oldest were pushed out by the others: their replays are rejected. The
        // seven still waiting get their same answer again, which takes no slot.
        for _ in 0..100 {
            for (i, hello) in old.iter().enumerate() {
                let answer = robot.on_datagram(ATTACKER, hello, &mut rng);
                if i < 3 {
                    assert_eq!(answer, Err(Rejection::Replayed));
                } else {
                    assert!(matches!(answer, Ok(Delivery::Answer { .. })), "{answer:?}");
                }
            }
        }
        assert_eq!(
            controller.on_datagram(ROBOT, &bytes),
            Ok(Delivery::Established)
        );
        let ready = controller.seal(Handshake::Ready.into()).unwrap();
        assert!(robot.on_datagram(CONTROLLER, &ready, &mut rng).is_ok());
        assert_eq!(robot.bound(), Some((CONTROLLER, 77)));
        // Every answer and every replay is counted.
        let counts = robot.counts();
        assert_eq!(
            (counts.hellos_answered, counts.rejected.replayed),
            (11 + 700, 300)
        );
    }

    #[test]
    fn pairing_secrets_and_modes_must_match_and_terms_are_refused_by_name() {
        let mut rng = ChaCha20Rng::seed_from_u64(5);
        let (controller, _) = pair(&PairingSecret::unauthenticated(), &mut rng);
        let mut robot = RobotChannel::<u8>::new(
            PairingSecret::from_bytes(&[3; 32]),
            [5; 32],
            "t = 1\n".into(),
        );
        assert_eq!(
            robot.on_datagram(CONTROLLER, controller.hello(), &mut rng),
            Err(Rejection::PairingMode)
        );
        let (controller, _) = pair(&PairingSecret::from_bytes(&[4; 32]), &mut rng);
        assert_eq!(
            robot.on_datagram(CONTROLLER, controller.hello(), &mut rng),
            Err(Rejection::HandshakeBadMac)
        );
        let secret = PairingSecret::from_bytes(&[3; 32]);
        let mut controller =
            ControllerChannel::new(secret, ROBOT, 9, [6; 32], "t = 2\n".into(), &mut rng);
        let Ok(Delivery::Answer {
            bytes,
            refused: Some(why),
        }) = robot.on_datagram(CONTROLLER, controller.hello(), &mut rng)
        else {
            panic!("differing terms are refused");
        };
        assert!(why.contains("t: robot has 1, controller has 2"), "{why}");
        assert_eq!(
            controller.on_datagram(ROBOT, &bytes),
            Ok(Delivery::Refused(why))
        );
        assert!(robot.half_open.is_empty());
    }
}
