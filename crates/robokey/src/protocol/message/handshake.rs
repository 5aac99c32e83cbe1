//! The handshake layer (docs/wire.md, "Handshake"): the messages that open a session. The
//! session channel ([`crate::protocol::auth`]) takes them; `Hello`, `HelloAck` and `Refuse`
//! are MACed under the handshake key, `Ready` under the controller's session key.

use robokey_codec::{Codec, DecodeError, Reader, Writer};

use super::MessageType;
use super::text::{MAX_REASON_BYTES, put_text, read_text};

/// Nonce length (bytes): 128 bits.
pub const NONCE_BYTES: usize = 16;
/// Longest `Hello` terms text (bytes of UTF-8).
pub const MAX_TERMS_BYTES: usize = 4096;

/// Whether an agent holds a pairing secret (declared in `Hello` and `HelloAck`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AuthMode {
    /// A secret installed with `robokey pair`: an active attacker cannot forge frames.
    Paired,
    /// The all-zero public secret: integrity against faults only, "passive adversary only".
    Unauthenticated,
}

impl Codec for AuthMode {
    /// `auth u8`: 0 = paired, 1 = unauthenticated.
    fn encode(&self, writer: &mut Writer) {
        writer.u8(match self {
            Self::Paired => 0,
            Self::Unauthenticated => 1,
        });
    }

    fn decode(reader: &mut Reader<'_>) -> Result<Self, DecodeError> {
        match reader.u8("auth")? {
            0 => Ok(Self::Paired),
            1 => Ok(Self::Unauthenticated),
            other => Err(DecodeError::Invalid {
                field: "auth",
                value: other.into(),
                allowed: "0 (paired) or 1 (unauthenticated)",
            }),
        }
    }
}

/// A message of the handshake layer.
#[derive(Clone, Debug, PartialEq)]
pub enum Handshake {
    /// Controller → robot: opens a session (MACed under the handshake key).
    Hello {
        /// Whether the sender holds a pairing secret.
        auth: AuthMode,
        /// `nonce_c`, fresh from the OS CSPRNG.
        nonce: [u8; NONCE_BYTES],
        /// SHA-256 of `terms`.
        config_digest: [u8; 32],
        /// The agreement terms as `field = value` lines, so a mismatch can be named.
        terms: String,
    },
    /// Robot → controller: accepts a session with the same configuration digest (MACed
    /// under the handshake key, over both nonces).
    HelloAck {
        /// Whether the sender holds a pairing secret.
        auth: AuthMode,
        /// The controller's `nonce_c`, echoed.
        nonce_c: [u8; NONCE_BYTES],
        /// `nonce_r`, fresh from the robot's CSPRNG.
        nonce_r: [u8; NONCE_BYTES],
        /// SHA-256 of the robot's agreement terms.
        config_digest: [u8; 32],
    },
    /// Robot → controller: refuses the Hello carrying `nonce_c` (MACed under the handshake
    /// key), e.g. because the terms differ.
    Refuse {
        /// The refused Hello's `nonce_c`.
        nonce_c: [u8; NONCE_BYTES],
        /// Human-readable reason.
        reason: String,
    },
    /// Controller → robot: the first frame under the controller→robot session key; it
    /// binds the session and the controller's address at the robot.
    Ready,
}

impl Handshake {
    /// Its wire type.
    #[must_use]
    pub fn message_type(&self) -> MessageType {
        match self {
            Self::Hello { .. } => MessageType::Hello,
            Self::HelloAck { .. } => MessageType::HelloAck,
            Self::Refuse { .. } => MessageType::Refuse,
            Self::Ready => MessageType::Ready,
        }
    }

    /// Appends its payload (docs/wire.md, "Payloads").
    pub(super) fn encode_payload(&self, writer: &mut Writer) {
        match self {
            Self::Hello {
                auth,
                nonce,
                config_digest,
                terms,
            } => {
                auth.encode(writer);
                writer.bytes(nonce);
                writer.bytes(config_digest);
                put_text(writer, terms, MAX_TERMS_BYTES);
            }
            Self::HelloAck {
                auth,
                nonce_c,
                nonce_r,
                config_digest,
            } => {
                auth.encode(writer);
                writer.bytes(nonce_c);
                writer.bytes(nonce_r);
                writer.bytes(config_digest);
            }
            Self::Refuse { nonce_c, reason } => {
                writer.bytes(nonce_c);
                put_text(writer, reason, MAX_REASON_BYTES);
            }
            Self::Ready => {}
        }
    }

    /// `auth u8 | nonce_c [16] | config_digest [32] | terms_len u16 | terms`.
    pub(super) fn decode_hello(reader: &mut Reader<'_>) -> Result<Self, DecodeError> {
        Ok(Self::Hello {
            auth: AuthMode::decode(reader)?,
            nonce: reader.array("nonce_c")?,
            config_digest: reader.array("config_digest")?,
            terms: read_text(reader, "terms", MAX_TERMS_BYTES)?,
        })
    }

    /// `auth u8 | nonce_c [16] | nonce_r [16] | config_digest [32]`.
    pub(super) fn decode_hello_ack(reader: &mut Reader<'_>) -> Result<Self, DecodeError> {
        Ok(Self::HelloAck {
            auth: AuthMode::decode(reader)?,
            nonce_c: reader.array("nonce_c")?,
            nonce_r: reader.array("nonce_r")?,
            config_digest: reader.array("config_digest")?,
        })
    }

    /// `nonce_c [16] | len u16 | reason`.
    pub(super) fn decode_refuse(reader: &mut Reader<'_>) -> Result<Self, DecodeError> {
        Ok(Self::Refuse {
            nonce_c: reader.array("nonce_c")?,
            reason: read_text(reader, "reason", MAX_REASON_BYTES)?,
        })
    }
}
