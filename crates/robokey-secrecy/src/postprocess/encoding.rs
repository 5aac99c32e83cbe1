//! The byte encoding of [`Message`] (docs/postprocessing.md, "Encoding"): one tag byte, then
//! the fields in declaration order, big-endian. Lists are `len u32` then the items; bit lists
//! are `len u32` (bits) then ⌈len/8⌉ bytes, first bit in the most significant bit, padding
//! bits zero. The decoder never panics, checks every length against its bound and against the
//! bytes left before allocating, and accepts only canonical encodings: what decodes
//! re-encodes to the same bytes.

use crate::cascade::BlockQuery;

use super::{
    AbortReason, MAX_BLOCK_SESSIONS, MAX_QUESTIONS, MAX_SAMPLE_BITS, Message, RejectReason,
};

/// Why bytes are not an encoded post-processing message.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum EncodingError {
    /// The first byte names no message (or there is none).
    #[error("unknown message tag {0}")]
    UnknownTag(u8),
    /// The input ends inside a field.
    #[error("truncated: {field} needs {needed} bytes, {left} left")]
    Truncated {
        /// The field being read.
        field: &'static str,
        /// Bytes it needs.
        needed: usize,
        /// Bytes left.
        left: usize,
    },
    /// Bytes follow a complete message.
    #[error("{0} bytes after the end of the message")]
    TrailingBytes(usize),
    /// A list longer than its bound.
    #[error("{field} has {len} items (at most {max})")]
    TooLong {
        /// The list.
        field: &'static str,
        /// Its declared length.
        len: u32,
        /// Its bound.
        max: usize,
    },
    /// A reason byte outside its enumeration.
    #[error("{field} {value} is not a known reason")]
    BadReason {
        /// The field.
        field: &'static str,
        /// The byte.
        value: u8,
    },
    /// The padding bits after a bit list are not zero.
    #[error("{0}: padding bits are not zero")]
    NonZeroPadding(&'static str),
}

const PROPOSE: u8 = 1;
const AGREE: u8 = 2;
const ASK: u8 = 3;
const ANSWER: u8 = 4;
const CONFIRM: u8 = 5;
const CONFIRMED: u8 = 6;
const COMMIT: u8 = 7;
const COMMIT_ACK: u8 = 8;
const ABORT: u8 = 9;
const ABORT_ACK: u8 = 10;
const REJECT: u8 = 11;

/// Bytes of one [`BlockQuery`]: `permutation u32 | start u32 | end u32`.
const QUERY_BYTES: usize = 12;

/// Encodes `message`. It never fails; a message whose lists exceed the bounds
/// ([`MAX_BLOCK_SESSIONS`], [`MAX_QUESTIONS`], [`MAX_SAMPLE_BITS`]), which the endpoints never
/// send, encodes but does not decode.
#[must_use]
pub fn encode(message: &Message) -> Vec<u8> {
    let mut out = Vec::with_capacity(64);
    match message {
        Message::Propose {
            block,
            sessions,
            nonce,
            separation_micros,
        } => {
            head(&mut out, PROPOSE, *block);
            put_sessions(&mut out, sessions);
            out.extend_from_slice(nonce);
            out.extend_from_slice(&separation_micros.to_be_bytes());
        }
        Message::Agree {
            block,
            sessions,
            nonce,
            sample,
        } => {
            head(&mut out, AGREE, *block);
            put_sessions(&mut out, sessions);
            out.extend_from_slice(nonce);
            put_bits(&mut out, sample);
        }
        Message::Ask {
            block,
            round,
            queries,
        } => {
            head(&mut out, ASK, *block);
            out.extend_from_slice(&round.to_be_bytes());
            put_len(&mut out, queries.len());
            for q in queries {
                for field in [q.permutation, q.start, q.end] {
                    out.extend_from_slice(&field.to_be_bytes());
                }
            }
        }
        Message::Answer {
            block,
            round,
            parities,
        } => {
            head(&mut out, ANSWER, *block);
            out.extend_from_slice(&round.to_be_bytes());
            put_bits(&mut out, parities);
        }
        Message::Confirm { block, length, tag } => {
            head(&mut out, CONFIRM, *block);
            out.extend_from_slice(&length.to_be_bytes());
            out.extend_from_slice(tag);
        }
        Message::Confirmed { block, tag } => {
            head(&mut out, CONFIRMED, *block);
            out.extend_from_slice(tag);
        }
        Message::Commit { block } => head(&mut out, COMMIT, *block),
        Message::CommitAck { block } => head(&mut out, COMMIT_ACK, *block),
        Message::Abort {
            block,
            sessions,
            reason,
        } => {
            head(&mut out, ABORT, *block);
            put_sessions(&mut out, sessions);
            out.push(abort_byte(*reason));
        }
        Message::AbortAck { block } => head(&mut out, ABORT_ACK, *block),
        Message::Reject { block, reason } => {
            head(&mut out, REJECT, *block);
            out.push(reject_byte(*reason));
        }
    }
    out
}

/// Decodes one message filling all of `bytes`.
///
/// # Errors
/// An [`EncodingError`] naming what is wrong; never panics.
pub fn decode(bytes: &[u8]) -> Result<Message, EncodingError> {
    let mut r = Reader { bytes };
    let tag = r.u8("tag")?;
    let block = r.u64("block")?;
    let message = match tag {
        PROPOSE => Message::Propose {
            block,
            sessions: r.sessions()?,
            nonce: r.array("nonce")?,
            separation_micros: r.u64("separation_micros")?,
        },
        AGREE => Message::Agree {
            block,
            sessions: r.sessions()?,
            nonce: r.array("nonce")?,
            sample: r.bits("sample", MAX_SAMPLE_BITS)?,
        },
        ASK => Message::Ask {
            block,
            round: r.u32("round")?,
            queries: r.queries()?,
        },
        ANSWER => Message::Answer {
            block,
            round: r.u32("round")?,
            parities: r.bits("parities", MAX_QUESTIONS)?,
        },
        CONFIRM => Message::Confirm {
            block,
            length: r.u64("length")?,
            tag: r.array("tag")?,
        },
        CONFIRMED => Message::Confirmed {
            block,
            tag: r.array("tag")?,
        },
        COMMIT => Message::Commit { block },
        COMMIT_ACK => Message::CommitAck { block },
        ABORT => Message::Abort {
            block,
            sessions: r.sessions()?,
            reason: abort_reason(r.u8("reason")?)?,
        },
        ABORT_ACK => Message::AbortAck { block },
        REJECT => Message::Reject {
            block,
            reason: reject_reason(r.u8("reason")?)?,
        },
        other => return Err(EncodingError::UnknownTag(other)),
    };
    if r.bytes.is_empty() {
        Ok(message)
    } else {
        Err(EncodingError::TrailingBytes(r.bytes.len()))
    }
}

/// Appends `tag u8 | block u64`.
fn head(out: &mut Vec<u8>, tag: u8, block: u64) {
    out.push(tag);
    out.extend_from_slice(&block.to_be_bytes());
}

/// Appends a list length as a u32 (saturating: such a list is over every bound anyway).
fn put_len(out: &mut Vec<u8>, len: usize) {
    out.extend_from_slice(&u32::try_from(len).unwrap_or(u32::MAX).to_be_bytes());
}

/// Appends `len u32 | len × u32`.
fn put_sessions(out: &mut Vec<u8>, sessions: &[u32]) {
    put_len(out, sessions.len());
    for id in sessions {
        out.extend_from_slice(&id.to_be_bytes());
    }
}

/// Appends `len u32 | ⌈len/8⌉ bytes`, packed MSB-first, padding zero.
fn put_bits(out: &mut Vec<u8>, bits: &[bool]) {
    put_len(out, bits.len());
    for chunk in bits.chunks(8) {
        out.push(
            chunk
                .iter()
                .enumerate()
                .fold(0u8, |byte, (i, &bit)| byte | (u8::from(bit) << (7 - i))),
        );
    }
}

fn abort_byte(reason: AbortReason) -> u8 {
    match reason {
        AbortReason::NoSecretBits => 0,
        AbortReason::Reconciliation => 1,
        AbortReason::Restart => 2,
        AbortReason::Refused => 3,
    }
}

fn abort_reason(value: u8) -> Result<AbortReason, EncodingError> {
    Ok(match value {
        0 => AbortReason::NoSecretBits,
        1 => AbortReason::Reconciliation,
        2 => AbortReason::Restart,
        3 => AbortReason::Refused,
        value => {
            return Err(EncodingError::BadReason {
                field: "abort reason",
                value,
            });
        }
    })
}

fn reject_byte(reason: RejectReason) -> u8 {
    match reason {
        RejectReason::UnknownBlock => 0,
        RejectReason::TagMismatch => 1,
        RejectReason::LengthMismatch => 2,
        RejectReason::Busy => 3,
        RejectReason::BadQuestions => 4,
    }
}

fn reject_reason(value: u8) -> Result<RejectReason, EncodingError> {
    Ok(match value {
        0 => RejectReason::UnknownBlock,
        1 => RejectReason::TagMismatch,
        2 => RejectReason::LengthMismatch,
        3 => RejectReason::Busy,
        4 => RejectReason::BadQuestions,
        value => {
            return Err(EncodingError::BadReason {
                field: "reject reason",
                value,
            });
        }
    })
}

/// A big-endian u32 from exactly 4 bytes.
fn be_u32(bytes: &[u8]) -> u32 {
    bytes.iter().fold(0, |n, &b| n << 8 | u32::from(b))
}

/// A cursor that checks every read against the bytes left.
struct Reader<'a> {
    bytes: &'a [u8],
}

impl<'a> Reader<'a> {
    /// The next `n` bytes.
    fn take(&mut self, field: &'static str, n: usize) -> Result<&'a [u8], EncodingError> {
        if n > self.bytes.len() {
            return Err(EncodingError::Truncated {
                field,
                needed: n,
                left: self.bytes.len(),
            });
        }
        let (head, rest) = self.bytes.split_at(n);
        self.bytes = rest;
        Ok(head)
    }

    fn array<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], EncodingError> {
        let mut array = [0; N];
        array.copy_from_slice(self.take(field, N)?);
        Ok(array)
    }

    fn u8(&mut self, field: &'static str) -> Result<u8, EncodingError> {
        // An empty input has no tag: reported as truncated, like any missing field.
        Ok(self.array::<1>(field)?[0])
    }

    fn u32(&mut self, field: &'static str) -> Result<u32, EncodingError> {
        self.array(field).map(u32::from_be_bytes)
    }

    fn u64(&mut self, field: &'static str) -> Result<u64, EncodingError> {
        self.array(field).map(u64::from_be_bytes)
    }

    /// A list length `u32`, at most `max` (≤ 2²⁰, so any item size times it fits a usize).
    fn len(&mut self, field: &'static str, max: usize) -> Result<usize, EncodingError> {
        let len = self.u32(field)?;
        usize::try_from(len)
            .ok()
            .filter(|&n| n <= max)
            .ok_or(EncodingError::TooLong { field, len, max })
    }

    /// `len u32 | len × u32`.
    fn sessions(&mut self) -> Result<Vec<u32>, EncodingError> {
        let len = self.len("sessions", MAX_BLOCK_SESSIONS)?;
        let raw = self.take("sessions", 4 * len)?;
        Ok(raw.chunks_exact(4).map(be_u32).collect())
    }

    /// `len u32 | len × (permutation u32 | start u32 | end u32)`.
    fn queries(&mut self) -> Result<Vec<BlockQuery>, EncodingError> {
        let len = self.len("queries", MAX_QUESTIONS)?;
        let raw = self.take("queries", QUERY_BYTES * len)?;
        Ok(raw
            .chunks_exact(QUERY_BYTES)
            .map(|q| BlockQuery {
                permutation: be_u32(&q[..4]),
                start: be_u32(&q[4..8]),
                end: be_u32(&q[8..]),
            })
            .collect())
    }

    /// `len u32 | ⌈len/8⌉ bytes`, MSB-first, padding zero.
    fn bits(&mut self, field: &'static str, max: usize) -> Result<Vec<bool>, EncodingError> {
        let len = self.len(field, max)?;
        let packed = self.take(field, len.div_ceil(8))?;
        if !len.is_multiple_of(8) && packed.last().is_some_and(|&b| b << (len % 8) != 0) {
            return Err(EncodingError::NonZeroPadding(field));
        }
        Ok((0..len)
            .map(|i| packed[i / 8] & (0x80 >> (i % 8)) != 0)
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::ChaCha8Rng;
    use rand::{RngExt, SeedableRng};

    fn hex(bytes: &[u8]) -> String {
        bytes.iter().map(|b| format!("{b:02x}")).collect()
    }

    /// One message per variant, in tag order.
    fn examples() -> Vec<Message> {
        let q = |permutation, start, end| BlockQuery {
            permutation,
            start,
            end,
        };
        vec![
            Message::Propose {
                block: 0x0102,
                sessions: vec![7, 0x0A0B_0C0D],
                nonce: [0x11; 32],
                separation_micros: 250_000,
            },
            Message::Agree {
                block: 3,
                sessions: vec![7],
                nonce: [0x22; 32],
                sample: vec![
                    true, false, true, true, false, false, false, false, true, true,
                ],
            },
            Message::Ask {
                block: 3,
                round: 2,
                queries: vec![q(0, 0, 73), q(1, 146, 219)],
            },
            Message::Answer {
                block: 3,
                round: 2,
                parities: vec![false, true, true],
            },
            Message::Confirm {
                block: 3,
                length: 4096,
                tag: [0xA5; 8],
            },
            Message::Confirmed {
                block: 3,
                tag: [0x5A; 8],
            },
            Message::Commit { block: 3 },
            Message::CommitAck { block: 3 },
            Message::Abort {
                block: 4,
                sessions: vec![8, 9],
                reason: AbortReason::Reconciliation,
            },
            Message::AbortAck { block: 4 },
            Message::Reject {
                block: 5,
                reason: RejectReason::BadQuestions,
            },
        ]
    }

    /// The extreme cases the examples miss: empty lists, every reason, bit lists around
    /// byte boundaries.
    fn edge_cases() -> Vec<Message> {
        let mut messages = vec![
            Message::Propose {
                block: u64::MAX,
                sessions: Vec::new(),
                nonce: [0; 32],
                separation_micros: u64::MAX,
            },
            Message::Ask {
                block: 0,
                round: u32::MAX,
                queries: Vec::new(),
            },
        ];
        for len in [0, 1, 7, 8, 9, 15, 16, 17, 64, 1001] {
            let bits: Vec<bool> = (0..len).map(|i| i % 3 == 1).collect();
            messages.push(Message::Agree {
                block: len as u64,
                sessions: Vec::new(),
                nonce: [0xFF; 32],
                sample: bits.clone(),
            });
            messages.push(Message::Answer {
                block: len as u64,
                round: 1,
                parities: bits,
            });
        }
        for reason in [
            AbortReason::NoSecretBits,
            AbortReason::Reconciliation,
            AbortReason::Restart,
            AbortReason::Refused,
        ] {
            messages.push(Message::Abort {
                block: 1,
                sessions: Vec::new(),
                reason,
            });
        }
        for reason in [
            RejectReason::UnknownBlock,
            RejectReason::TagMismatch,
            RejectReason::LengthMismatch,
            RejectReason::Busy,
            RejectReason::BadQuestions,
        ] {
            messages.push(Message::Reject { block: 1, reason });
        }
        messages
    }

    /// Padding bits of a message's bit list (the encoding rounds it up to whole bytes).
    fn padding(message: &Message) -> u64 {
        match message {
            Message::Agree { sample: bits, .. } | Message::Answer { parities: bits, .. } => {
                (8 - bits.len() as u64 % 8) % 8
            }
            _ => 0,
        }
    }

    #[test]
    fn every_variant_round_trips_in_its_counted_size() {
        let all: Vec<Message> = examples().into_iter().chain(edge_cases()).collect();
        for message in &all {
            let bytes = encode(message);
            assert_eq!(decode(&bytes).as_ref(), Ok(message));
            // The tag byte, then exactly the fields `payload_bits` counts, padded.
            assert_eq!(
                8 * bytes.len() as u64,
                8 + message.payload_bits() + padding(message),
                "{message:?}"
            );
        }
        let tags: Vec<u8> = examples().iter().map(|m| encode(m)[0]).collect();
        assert_eq!(tags, (1..=11).collect::<Vec<u8>>());
    }

    #[test]
    fn golden_bytes_per_variant() {
        let got: Vec<String> = examples().iter().map(|m| hex(&encode(m))).collect();
        assert_eq!(got.join("\n"), GOLDEN.trim());
    }

    /// Checked by hand against the layout (docs/postprocessing.md, "Encoding").
    const GOLDEN: &str = "
01000000000000010200000002000000070a0b0c0d1111111111111111111111111111111111111111111111111111111111111111000000000003d090
020000000000000003000000010000000722222222222222222222222222222222222222222222222222222222222222220000000ab0c0
03000000000000000300000002000000020000000000000000000000490000000100000092000000db
040000000000000003000000020000000360
0500000000000000030000000000001000a5a5a5a5a5a5a5a5
0600000000000000035a5a5a5a5a5a5a5a
070000000000000003
080000000000000003
09000000000000000400000002000000080000000901
0a0000000000000004
0b000000000000000504
";

    #[test]
    fn typed_errors_name_the_problem() {
        let propose = encode(&examples()[0]);
        assert_eq!(
            decode(&[]),
            Err(EncodingError::Truncated {
                field: "tag",
                needed: 1,
                left: 0
            })
        );
        assert_eq!(decode(&[0; 9]), Err(EncodingError::UnknownTag(0)));
        assert_eq!(decode(&[12; 9]), Err(EncodingError::UnknownTag(12)));
        assert_eq!(
            decode(&propose[..propose.len() - 1]),
            Err(EncodingError::Truncated {
                field: "separation_micros",
                needed: 8,
                left: 7
            })
        );
        assert_eq!(
            decode(&[&propose[..], &[0, 0]].concat()),
            Err(EncodingError::TrailingBytes(2))
        );
        // A session count over the bound, and one the input cannot hold.
        let mut long = propose.clone();
        long[9..13].copy_from_slice(&(MAX_BLOCK_SESSIONS as u32 + 1).to_be_bytes());
        assert_eq!(
            decode(&long),
            Err(EncodingError::TooLong {
                field: "sessions",
                len: MAX_BLOCK_SESSIONS as u32 + 1,
                max: MAX_BLOCK_SESSIONS
            })
        );
        long[9..13].copy_from_slice(&(MAX_BLOCK_SESSIONS as u32).to_be_bytes());
        assert!(matches!(
            decode(&long),
            Err(EncodingError::Truncated {
                field: "sessions",
                needed: 262_144,
                ..
            })
        ));
        let mut answer = encode(&examples()[3]);
        answer[13..17].copy_from_slice(&u32::MAX.to_be_bytes());
        assert!(matches!(
            decode(&answer),
            Err(EncodingError::TooLong {
                field: "parities",
                ..
            })
        ));
        let mut reject = encode(&examples()[10]);
        reject[9] = 5;
        assert_eq!(
            decode(&reject),
            Err(EncodingError::BadReason {
                field: "reject reason",
                value: 5
            })
        );
        let mut abort = encode(&examples()[8]);
        *abort.last_mut().unwrap() = 4;
        assert!(matches!(
            decode(&abort),
            Err(EncodingError::BadReason { value: 4, .. })
        ));
    }

    #[test]
    fn nonzero_padding_is_rejected() {
        // Three parities in one byte: 011 then five padding bits.
        let mut answer = encode(&examples()[3]);
        assert_eq!(answer.last(), Some(&0b0110_0000));
        for bit in 0..5 {
            *answer.last_mut().unwrap() = 0b0110_0000 | (1 << bit);
            assert_eq!(
                decode(&answer),
                Err(EncodingError::NonZeroPadding("parities"))
            );
        }
        let mut agree = encode(&examples()[1]);
        *agree.last_mut().unwrap() |= 1;
        assert_eq!(decode(&agree), Err(EncodingError::NonZeroPadding("sample")));
    }

    #[test]
    fn random_bytes_and_damaged_encodings_give_errors_without_panicking() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut decoded = 0;
        for _ in 0..100_000 {
            let len = rng.random_range(0..64);
            let mut bytes: Vec<u8> = (0..len).map(|_| rng.random()).collect();
            if let Some(tag) = bytes.first_mut() {
                // Mostly valid tags, so the fields get read.
                *tag = rng.random_range(0..13);
            }
            if let Ok(message) = decode(&bytes) {
                assert_eq!(encode(&message), bytes);
                decoded += 1;
            }
        }
        // Commit, CommitAck, AbortAck are 9 bytes of any content: some random inputs decode.
        assert!(decoded > 0);
        for message in examples().iter().chain(&edge_cases()) {
            let bytes = encode(message);
            for cut in 0..bytes.len() {
                assert!(decode(&bytes[..cut]).is_err(), "{message:?} cut at {cut}");
            }
            for extra in 1..4 {
                let longer = [&bytes[..], &vec![0; extra]].concat();
                assert_eq!(decode(&longer), Err(EncodingError::TrailingBytes(extra)));
            }
        }
    }
}
