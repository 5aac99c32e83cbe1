//! The closing layer (docs/protocol.md, "Closing"): the messages that end a session once
//! every fate is known, or abort it. The session endpoints take them.

use robokey_codec::{DecodeError, Reader, Writer};

use super::text::{MAX_REASON_BYTES, put_text, read_text};
use super::{MessageType, TAG_BYTES};

/// Most codewords a `Finish` may cover.
pub const MAX_FINISH_CODEWORDS: u32 = 1 << 20;

/// A message of the closing layer.
#[derive(Clone, Debug, PartialEq)]
pub enum Closing {
    /// Controller → robot: every codeword's (private sensing: doublet's) fate, sent after
    /// the stop command.
    Finish {
        /// Number of decided codewords (doublets).
        codewords: u32,
        /// Fate bitmap, bit `i % 64` of word `i / 64` = codeword `i` accepted.
        bitmap: Vec<u64>,
    },
    /// Robot → controller: the Finish arrived.
    FinishAck,
    /// Either side: its session and key confirmation tags (see
    /// [`crate::protocol::Confirmer`]).
    Confirm {
        /// `MAC(k_dir, "confirm" ‖ dir ‖ Hello ‖ HelloAck ‖ fate bitmap)`, truncated.
        session_tag: [u8; TAG_BYTES],
        /// `MAC(k_dir, "key" ‖ dir ‖ Hello ‖ HelloAck ‖ key)`, truncated.
        key_tag: [u8; TAG_BYTES],
    },
    /// Either side, after its outcome (confirmed or not): it needs nothing more from the peer,
    /// which may stop lingering (docs/protocol.md, "Lingering").
    Done,
    /// Either side: the session is over, with a reason.
    Abort {
        /// Human-readable reason.
        reason: String,
    },
}

impl Closing {
    /// Its wire type.
    #[must_use]
    pub fn message_type(&self) -> MessageType {
        match self {
            Self::Finish { .. } => MessageType::Finish,
            Self::FinishAck => MessageType::FinishAck,
            Self::Confirm { .. } => MessageType::Confirm,
            Self::Done => MessageType::Done,
            Self::Abort { .. } => MessageType::Abort,
        }
    }

    /// Appends its payload (docs/wire.md, "Payloads"). A `Finish` bitmap shorter than
    /// ⌈codewords/64⌉ words is padded with zero words, a longer one cut.
    pub(super) fn encode_payload(&self, writer: &mut Writer) {
        match self {
            Self::Finish { codewords, bitmap } => {
                let words = codewords.div_ceil(64) as usize;
                writer.u32(*codewords);
                for word in bitmap.iter().chain(std::iter::repeat(&0)).take(words) {
                    writer.u64(*word);
                }
            }
            Self::FinishAck | Self::Done => {}
            Self::Confirm {
                session_tag,
                key_tag,
            } => {
                writer.bytes(session_tag);
                writer.bytes(key_tag);
            }
            Self::Abort { reason } => put_text(writer, reason, MAX_REASON_BYTES),
        }
    }

    /// `codewords u32 | ⌈codewords/64⌉ × u64`, with `codewords ≤ MAX_FINISH_CODEWORDS`.
    pub(super) fn decode_finish(reader: &mut Reader<'_>) -> Result<Self, DecodeError> {
        let codewords = reader.u32("codewords")?;
        if codewords > MAX_FINISH_CODEWORDS {
            return Err(DecodeError::Invalid {
                field: "codewords",
                value: codewords.into(),
                allowed: "at most 2^20",
            });
        }
        let words = codewords.div_ceil(64) as usize;
        let raw = reader.take("bitmap", 8 * words)?;
        let bitmap = raw
            .chunks_exact(8)
            .map(|word| word.iter().fold(0, |n, &b| n << 8 | u64::from(b)))
            .collect();
        Ok(Self::Finish { codewords, bitmap })
    }

    /// `session_tag [16] | key_tag [16]`.
    pub(super) fn decode_confirm(reader: &mut Reader<'_>) -> Result<Self, DecodeError> {
        Ok(Self::Confirm {
            session_tag: reader.array("session_tag")?,
            key_tag: reader.array("key_tag")?,
        })
    }

    /// `len u16 | reason`.
    pub(super) fn decode_abort(reader: &mut Reader<'_>) -> Result<Self, DecodeError> {
        Ok(Self::Abort {
            reason: read_text(reader, "reason", MAX_REASON_BYTES)?,
        })
    }
}
