//! The key-agreement protocol as sans-I/O endpoints (docs/protocol.md): the robot and the
//! controller each take one input enum and emit one output enum, with time as an input
//! ([`timing`]); the shells (simulator, UDP agents) carry the [`Message`]s. A message belongs
//! to one [`Layer`] — handshake, session, closing or post-processing — and [`MessageType`] is
//! the one table of their wire types. On a network, the session layer ([`auth`]) lies between
//! the endpoints and the datagrams ([`wire`]).

mod assembler;
pub mod auth;
pub mod controller;
pub(crate) mod decoder;
pub(crate) mod fates;
pub(crate) mod message;
pub(crate) mod plan;
pub mod robot;
mod terms;
pub mod timing;
pub mod wire;

pub use assembler::{CodewordAssembler, ReceivedWord};
pub use auth::{ConfirmTags, Confirmer, Direction};
pub use controller::{Controller, ControllerEvent, ControllerInput, ControllerOutput};
pub use decoder::{Measured, StepDecision, StepDecoder};
pub use fates::{FateLedger, FateWindow};
pub use message::{
    AuthMode, Closing, Handshake, Layer, Message, MessageType, PostFragment, SessionMessage,
    TAG_BYTES, TypeError,
};
pub use plan::{Agreed, ModePlan, OdometryPlan, SessionPlan};
pub use robot::{Actuation, Robot, RobotInput, RobotOutput};
pub use terms::{agreement_terms, config_digest, terms_difference};
pub use timing::{Pace, Time, Timing};

/// How a session ended for one side.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// The peer's tag matched: both sides hold the same key (up to the tag's collision
    /// probability).
    Confirmed,
    /// Private sensing: the peer's session tag matched, so both ran the same session and
    /// kept the same doublets. Their raw bits differ where the controller erred: they become
    /// a key only through post-processing, confirmed per block (docs/private-sensing.md).
    Kept,
    /// The session finished, but the peer's tag did not match or never arrived.
    Unconfirmed(String),
    /// The session was aborted.
    Aborted(String),
}

/// A key as a bit string (one `u8` of 0/1 per bit), zeroized on drop; its `Debug` prints
/// the length only.
#[derive(Clone, Default, PartialEq, Eq)]
pub struct KeyBits(zeroize::Zeroizing<Vec<u8>>);

impl std::ops::Deref for KeyBits {
    type Target = Vec<u8>;

    fn deref(&self) -> &Vec<u8> {
        &self.0
    }
}

impl std::ops::DerefMut for KeyBits {
    fn deref_mut(&mut self) -> &mut Vec<u8> {
        &mut self.0
    }
}

impl From<Vec<u8>> for KeyBits {
    fn from(bits: Vec<u8>) -> Self {
        Self(zeroize::Zeroizing::new(bits))
    }
}

impl std::fmt::Debug for KeyBits {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "KeyBits({} bits)", self.0.len())
    }
}
