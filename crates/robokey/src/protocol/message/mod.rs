//! The messages of the protocol, by layer (docs/wire.md, "Payloads"), as in rustls's `msgs/`:
//! each layer is one type in its own file, taken by the part of the system that handles it,
//! and [`MessageType`] is the one table of their wire types. Session id and frame sequence
//! numbers live in the wire header, added by the session layer ([`super::wire`]).

mod closing;
mod handshake;
mod message_type;
mod post;
mod session;
mod text;

pub use closing::{Closing, MAX_FINISH_CODEWORDS};
pub use handshake::{AuthMode, Handshake, MAX_TERMS_BYTES, NONCE_BYTES};
pub use message_type::{Layer, MessageType, TypeError};
pub use post::{MAX_POST_FRAGMENT_BYTES, MAX_POST_FRAGMENTS, PostFragment};
pub use session::SessionMessage;
pub use text::MAX_REASON_BYTES;

use robokey_codec::{Codec, DecodeError, Reader, Writer};

/// Length of every MAC the protocol sends (bytes): a frame's trailer and each confirmation
/// tag, HMAC-SHA256 truncated to 128 bits.
pub const TAG_BYTES: usize = 16;

/// One protocol message, of one of four layers.
#[derive(Clone, Debug, PartialEq)]
pub enum Message {
    /// Opens a session: `Hello`, `HelloAck`, `Refuse`, `Ready`.
    Handshake(Handshake),
    /// One step of the run: `Measurement`, `Command`, `PrivateMeasurement`,
    /// `DoubletCommand`.
    Session(SessionMessage),
    /// Ends a session: `Finish`, `FinishAck`, `Confirm`, `Done`, `Abort`.
    Closing(Closing),
    /// One fragment of an encoded post-processing message.
    Post(PostFragment),
}

impl From<Handshake> for Message {
    fn from(message: Handshake) -> Self {
        Self::Handshake(message)
    }
}

impl From<SessionMessage> for Message {
    fn from(message: SessionMessage) -> Self {
        Self::Session(message)
    }
}

impl From<Closing> for Message {
    fn from(message: Closing) -> Self {
        Self::Closing(message)
    }
}

impl From<PostFragment> for Message {
    fn from(fragment: PostFragment) -> Self {
        Self::Post(fragment)
    }
}

impl Message {
    /// Its wire type.
    #[must_use]
    pub fn message_type(&self) -> MessageType {
        match self {
            Self::Handshake(message) => message.message_type(),
            Self::Session(message) => message.message_type(),
            Self::Closing(message) => message.message_type(),
            Self::Post(_) => MessageType::PostFragment,
        }
    }

    /// The header's `step`: a session message's sample index k, 0 for every other layer.
    #[must_use]
    pub fn step(&self) -> u32 {
        match self {
            Self::Session(message) => message.step(),
            Self::Handshake(_) | Self::Closing(_) | Self::Post(_) => 0,
        }
    }

    /// Appends its payload: the frame's bytes between the header and the MAC.
    pub(crate) fn encode_payload(&self, writer: &mut Writer) {
        match self {
            Self::Handshake(message) => message.encode_payload(writer),
            Self::Session(message) => message.encode_payload(writer),
            Self::Closing(message) => message.encode_payload(writer),
            Self::Post(fragment) => fragment.encode(writer),
        }
    }

    /// Reads the payload of a `kind` message whose header carries `step` (0 unless
    /// `kind` [carries one](MessageType::carries_step)); the caller checks that no byte is
    /// left.
    ///
    /// # Errors
    /// A [`DecodeError`] naming the field that is missing or wrong; never panics.
    pub(crate) fn decode_payload(
        kind: MessageType,
        step: u32,
        reader: &mut Reader<'_>,
    ) -> Result<Self, DecodeError> {
        Ok(match kind {
            MessageType::Hello => Handshake::decode_hello(reader)?.into(),
            MessageType::HelloAck => Handshake::decode_hello_ack(reader)?.into(),
            MessageType::Refuse => Handshake::decode_refuse(reader)?.into(),
            MessageType::Ready => Handshake::Ready.into(),
            MessageType::Measurement => SessionMessage::decode_measurement(step, reader)?.into(),
            MessageType::Command => SessionMessage::decode_command(step, reader)?.into(),
            MessageType::PrivateMeasurement => {
                SessionMessage::decode_private_measurement(step, reader)?.into()
            }
            MessageType::DoubletCommand => {
                SessionMessage::decode_doublet_command(step, reader)?.into()
            }
            MessageType::Finish => Closing::decode_finish(reader)?.into(),
            MessageType::FinishAck => Closing::FinishAck.into(),
            MessageType::Confirm => Closing::decode_confirm(reader)?.into(),
            MessageType::Done => Closing::Done.into(),
            MessageType::Abort => Closing::decode_abort(reader)?.into(),
            MessageType::PostFragment => PostFragment::decode(reader)?.into(),
        })
    }
}
