//! The post-processing layer: fragments of encoded post-processing messages
//! (`robokey_secrecy::postprocess::encode`, docs/postprocessing.md), which the agents'
//! post-processing link reassembles. They belong to no session step.

use robokey_codec::{Codec, DecodeError, Reader, Writer};

/// Most fragments one encoded post-processing message may be split into.
pub const MAX_POST_FRAGMENTS: u16 = 1024;
/// Longest chunk of an encoded post-processing message one `PostFragment` carries (bytes).
pub const MAX_POST_FRAGMENT_BYTES: u16 = 1024;

/// Either side: one fragment of an encoded post-processing message, which the receiver
/// reassembles. Session endpoints never see it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PostFragment {
    /// The sender's id of the encoded message (fresh for every transmission).
    pub message: u32,
    /// This fragment's position, `0..count`.
    pub index: u16,
    /// Fragments of the message, `1..=MAX_POST_FRAGMENTS`.
    pub count: u16,
    /// The chunk, 1 to `MAX_POST_FRAGMENT_BYTES` bytes.
    pub bytes: Vec<u8>,
}

impl Codec for PostFragment {
    /// `message u32 | index u16 | count u16 | len u16 | bytes[len]`; like a text, a chunk
    /// over the bound (which no valid sender builds) is cut.
    fn encode(&self, writer: &mut Writer) {
        let len = self.bytes.len().min(usize::from(MAX_POST_FRAGMENT_BYTES));
        writer.u32(self.message);
        writer.u16(self.index);
        writer.u16(self.count);
        writer.u16(len as u16);
        writer.bytes(&self.bytes[..len]);
    }

    /// Accepts `1 ≤ count ≤ MAX_POST_FRAGMENTS`, `index < count` and
    /// `1 ≤ len ≤ MAX_POST_FRAGMENT_BYTES`.
    fn decode(reader: &mut Reader<'_>) -> Result<Self, DecodeError> {
        let message = reader.u32("message")?;
        let index = reader.u16("index")?;
        let count = reader.u16("count")?;
        let len = reader.u16("len")?;
        if !(1..=MAX_POST_FRAGMENTS).contains(&count) {
            return Err(DecodeError::Invalid {
                field: "count",
                value: count.into(),
                allowed: "1 to 1024 (MAX_POST_FRAGMENTS)",
            });
        }
        if index >= count {
            return Err(DecodeError::Invalid {
                field: "index",
                value: index.into(),
                allowed: "below count",
            });
        }
        if !(1..=MAX_POST_FRAGMENT_BYTES).contains(&len) {
            return Err(DecodeError::Invalid {
                field: "len",
                value: len.into(),
                allowed: "1 to 1024 (MAX_POST_FRAGMENT_BYTES)",
            });
        }
        Ok(Self {
            message,
            index,
            count,
            bytes: reader.take("bytes", usize::from(len))?.to_vec(),
        })
    }
}
