//! The byte encoding of [`Message`] (docs/postprocessing.md, "Encoding"), on the codec
//! robokey's wire format uses too ([`robokey_codec`]): one tag byte, then the fields in
//! declaration order, big-endian. Lists are `len u32` then the items; bit lists are `len u32`
//! (bits) then ⌈len/8⌉ bytes, first bit in the most significant bit, padding bits zero. The
//! decoder never panics, checks every length against its bound and against the bytes left
//! before allocating, and accepts only canonical encodings: what decodes re-encodes to the
//! same bytes.

use robokey_codec::{Codec, DecodeError, Reader, Writer};

use crate::cascade::BlockQuery;

use super::{
    AbortReason, MAX_BLOCK_SESSIONS, MAX_QUESTIONS, MAX_SAMPLE_BITS, MAX_SYNDROME_BITS, Message,
    RejectReason,
};

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
const SYNDROME_ASK: u8 = 12;
const SYNDROME: u8 = 13;

/// Encodes `message`. It never fails; a message whose lists exceed the bounds
/// ([`MAX_BLOCK_SESSIONS`], [`MAX_QUESTIONS`], [`MAX_SAMPLE_BITS`], [`MAX_SYNDROME_BITS`]),
/// which the endpoints never
/// send, encodes but does not decode.
#[must_use]
pub fn encode(message: &Message) -> Vec<u8> {
    message.to_bytes()
}

/// Decodes one message filling all of `bytes`.
///
/// # Errors
/// A [`DecodeError`] naming what is wrong; never panics.
pub fn decode(bytes: &[u8]) -> Result<Message, DecodeError> {
    Message::from_bytes(bytes)
}

impl Codec for Message {
    fn encode(&self, w: &mut Writer) {
        match self {
            Self::Propose {
                block,
                sessions,
                nonce,
                separation_micros,
            } => {
                head(w, PROPOSE, *block);
                put_sessions(w, sessions);
                w.bytes(nonce);
                w.u64(*separation_micros);
            }
            Self::Agree {
                block,
                sessions,
                nonce,
                sample,
            } => {
                head(w, AGREE, *block);
                put_sessions(w, sessions);
                w.bytes(nonce);
                put_bits(w, sample);
            }
            Self::Ask {
                block,
                round,
                queries,
            } => {
                head(w, ASK, *block);
                w.u32(*round);
                w.len_u32(queries.len());
                for query in queries {
                    query.encode(w);
                }
            }
            Self::Answer {
                block,
                round,
                parities,
            } => {
                head(w, ANSWER, *block);
                w.u32(*round);
                put_bits(w, parities);
            }
            Self::Confirm {
                block,
                length,
                tag,
                estimate,
            } => {
                head(w, CONFIRM, *block);
                w.u64(*length);
                w.bytes(tag);
                if let Some(steps) = estimate {
                    w.u32(*steps);
                }
            }
            Self::Confirmed { block, tag } => {
                head(w, CONFIRMED, *block);
                w.bytes(tag);
            }
            Self::Commit { block } => head(w, COMMIT, *block),
            Self::CommitAck { block } => head(w, COMMIT_ACK, *block),
            Self::Abort {
                block,
                sessions,
                reason,
            } => {
                head(w, ABORT, *block);
                put_sessions(w, sessions);
                reason.encode(w);
            }
            Self::AbortAck { block } => head(w, ABORT_ACK, *block),
            Self::Reject { block, reason } => {
                head(w, REJECT, *block);
                reason.encode(w);
            }
            Self::SyndromeAsk {
                block,
                round,
                syndrome_bits,
                bhattacharyya,
            } => {
                head(w, SYNDROME_ASK, *block);
                w.u32(*round);
                w.u32(*syndrome_bits);
                w.u16(*bhattacharyya);
            }
            Self::Syndrome {
                block,
                round,
                syndrome,
            } => {
                head(w, SYNDROME, *block);
                w.u32(*round);
                put_bits(w, syndrome);
            }
        }
    }

    fn decode(r: &mut Reader<'_>) -> Result<Self, DecodeError> {
        let tag = r.u8("tag")?;
        let block = r.u64("block")?;
        Ok(match tag {
            PROPOSE => Self::Propose {
                block,
                sessions: read_sessions(r)?,
                nonce: r.array("nonce")?,
                separation_micros: r.u64("separation_micros")?,
            },
            AGREE => Self::Agree {
                block,
                sessions: read_sessions(r)?,
                nonce: r.array("nonce")?,
                sample: read_bits(r, "sample", MAX_SAMPLE_BITS)?,
            },
            ASK => Self::Ask {
                block,
                round: r.u32("round")?,
                queries: read_queries(r)?,
            },
            ANSWER => Self::Answer {
                block,
                round: r.u32("round")?,
                parities: read_bits(r, "parities", MAX_QUESTIONS)?,
            },
            CONFIRM => Self::Confirm {
                block,
                length: r.u64("length")?,
                tag: r.array("tag")?,
                // The last field, present only with the plant measured.
                estimate: if r.clone().finish().is_ok() {
                    None
                } else {
                    Some(r.u32("estimate")?)
                },
            },
            CONFIRMED => Self::Confirmed {
                block,
                tag: r.array("tag")?,
            },
            COMMIT => Self::Commit { block },
            COMMIT_ACK => Self::CommitAck { block },
            ABORT => Self::Abort {
                block,
                sessions: read_sessions(r)?,
                reason: AbortReason::decode(r)?,
            },
            ABORT_ACK => Self::AbortAck { block },
            REJECT => Self::Reject {
                block,
                reason: RejectReason::decode(r)?,
            },
            SYNDROME_ASK => Self::SyndromeAsk {
                block,
                round: r.u32("round")?,
                syndrome_bits: r.u32("syndrome_bits")?,
                bhattacharyya: r.u16("bhattacharyya")?,
            },
            SYNDROME => Self::Syndrome {
                block,
                round: r.u32("round")?,
                syndrome: read_bits(r, "syndrome", MAX_SYNDROME_BITS)?,
            },
            other => {
                return Err(DecodeError::Invalid {
                    field: "tag",
                    value: other.into(),
                    allowed: "1 to 13",
                });
            }
        })
    }
}

/// Appends `tag u8 | block u64`.
fn head(w: &mut Writer, tag: u8, block: u64) {
    w.u8(tag);
    w.u64(block);
}

/// Appends `len u32 | len × u32`.
fn put_sessions(w: &mut Writer, sessions: &[u32]) {
    w.len_u32(sessions.len());
    for &id in sessions {
        w.u32(id);
    }
}

/// Reads `len u32 | len × u32`, at most [`MAX_BLOCK_SESSIONS`].
fn read_sessions(r: &mut Reader<'_>) -> Result<Vec<u32>, DecodeError> {
    let len = r.len_u32("sessions", MAX_BLOCK_SESSIONS)?;
    let raw = r.take("sessions", 4 * len)?;
    let mut ids = Reader::new(raw);
    (0..len).map(|_| ids.u32("sessions")).collect()
}

/// Appends `len u32 | ⌈len/8⌉ bytes`, packed MSB-first, padding zero.
fn put_bits(w: &mut Writer, bits: &[bool]) {
    w.len_u32(bits.len());
    for chunk in bits.chunks(8) {
        w.u8(chunk
            .iter()
            .enumerate()
            .fold(0u8, |byte, (i, &bit)| byte | (u8::from(bit) << (7 - i))));
    }
}

/// Reads `len u32 | ⌈len/8⌉ bytes` of `field`, MSB-first, padding zero, `len ≤ max`.
fn read_bits(
    r: &mut Reader<'_>,
    field: &'static str,
    max: usize,
) -> Result<Vec<bool>, DecodeError> {
    let len = r.len_u32(field, max)?;
    let packed = r.take(field, len.div_ceil(8))?;
    if !len.is_multiple_of(8) && packed.last().is_some_and(|&b| b << (len % 8) != 0) {
        return Err(DecodeError::NonZeroPadding(field));
    }
    Ok((0..len)
        .map(|i| packed[i / 8] & (0x80 >> (i % 8)) != 0)
        .collect())
}

/// Bytes of one [`BlockQuery`]: `permutation u32 | start u32 | end u32`.
const QUERY_BYTES: usize = 12;

/// Reads `len u32 | len × query`, at most [`MAX_QUESTIONS`].
fn read_queries(r: &mut Reader<'_>) -> Result<Vec<BlockQuery>, DecodeError> {
    let len = r.len_u32("queries", MAX_QUESTIONS)?;
    let mut queries = Reader::new(r.take("queries", QUERY_BYTES * len)?);
    (0..len).map(|_| BlockQuery::decode(&mut queries)).collect()
}

impl Codec for BlockQuery {
    /// `permutation u32 | start u32 | end u32`.
    fn encode(&self, w: &mut Writer) {
        w.u32(self.permutation);
        w.u32(self.start);
        w.u32(self.end);
    }

    fn decode(r: &mut Reader<'_>) -> Result<Self, DecodeError> {
        Ok(Self {
            permutation: r.u32("queries")?,
            start: r.u32("queries")?,
            end: r.u32("queries")?,
        })
    }
}

impl Codec for AbortReason {
    /// `reason u8`: 0 no secret bits, 1 reconciliation, 2 restart, 3 refused, 4 the plant's
    /// estimate refused the block.
    fn encode(&self, w: &mut Writer) {
        w.u8(match self {
            Self::NoSecretBits => 0,
            Self::Reconciliation => 1,
            Self::Restart => 2,
            Self::Refused => 3,
            Self::PlantRefused => 4,
        });
    }

    fn decode(r: &mut Reader<'_>) -> Result<Self, DecodeError> {
        Ok(match r.u8("abort reason")? {
            0 => Self::NoSecretBits,
            1 => Self::Reconciliation,
            2 => Self::Restart,
            3 => Self::Refused,
            4 => Self::PlantRefused,
            value => {
                return Err(DecodeError::Invalid {
                    field: "abort reason",
                    value: value.into(),
                    allowed: "0 to 4",
                });
            }
        })
    }
}

impl Codec for RejectReason {
    /// `reason u8`: 0 unknown block, 1 tag mismatch, 2 length mismatch, 3 busy, 4 bad
    /// questions.
    fn encode(&self, w: &mut Writer) {
        w.u8(match self {
            Self::UnknownBlock => 0,
            Self::TagMismatch => 1,
            Self::LengthMismatch => 2,
            Self::Busy => 3,
            Self::BadQuestions => 4,
        });
    }

    fn decode(r: &mut Reader<'_>) -> Result<Self, DecodeError> {
        Ok(match r.u8("reject reason")? {
            0 => Self::UnknownBlock,
            1 => Self::TagMismatch,
            2 => Self::LengthMismatch,
            3 => Self::Busy,
            4 => Self::BadQuestions,
            value => {
                return Err(DecodeError::Invalid {
                    field: "reject reason",
                    value: value.into(),
                    allowed: "0 to 4",
                });
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::postprocess::MAX_SEPARATION_STEPS;
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
                estimate: None,
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
            Message::SyndromeAsk {
                block: 3,
                round: 1,
                syndrome_bits: 0x1234,
                bhattacharyya: 0x0155,
            },
            Message::Syndrome {
                block: 3,
                round: 2,
                syndrome: vec![
                    true, false, true, true, false, false, false, false, true, true,
                ],
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
                parities: bits.clone(),
            });
            messages.push(Message::Syndrome {
                block: len as u64,
                round: u32::MAX,
                syndrome: bits,
            });
        }
        messages.push(Message::SyndromeAsk {
            block: u64::MAX,
            round: u32::MAX,
            syndrome_bits: u32::MAX,
            bhattacharyya: u16::MAX,
        });
        for reason in [
            AbortReason::NoSecretBits,
            AbortReason::Reconciliation,
            AbortReason::Restart,
            AbortReason::Refused,
            AbortReason::PlantRefused,
        ] {
            messages.push(Message::Abort {
                block: 1,
                sessions: Vec::new(),
                reason,
            });
        }
        for estimate in [None, Some(0), Some(MAX_SEPARATION_STEPS), Some(u32::MAX)] {
            messages.push(Message::Confirm {
                block: 1,
                length: u64::MAX,
                tag: [0; 8],
                estimate,
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
            Message::Agree { sample: bits, .. }
            | Message::Answer { parities: bits, .. }
            | Message::Syndrome { syndrome: bits, .. } => (8 - bits.len() as u64 % 8) % 8,
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
        assert_eq!(tags, (1..=13).collect::<Vec<u8>>());
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
0c000000000000000300000001000012340155
0d0000000000000003000000020000000ab0c0
";

    /// With the plant measured, `Confirm` ends with the estimate (`u32`, grid steps of 2⁻⁸);
    /// a refused block's `Abort` carries reason 4. Checked by hand against the layout.
    #[test]
    fn golden_bytes_of_the_measured_plant() {
        let confirm = Message::Confirm {
            block: 3,
            length: 4096,
            tag: [0xA5; 8],
            estimate: Some(436),
        };
        assert_eq!(
            hex(&encode(&confirm)),
            "0500000000000000030000000000001000a5a5a5a5a5a5a5a5000001b4"
        );
        let refused = Message::Abort {
            block: 4,
            sessions: vec![8, 9],
            reason: AbortReason::PlantRefused,
        };
        assert_eq!(
            hex(&encode(&refused)),
            "09000000000000000400000002000000080000000904"
        );
        // An estimate cut short is named; bytes after it are trailing.
        let bytes = encode(&confirm);
        for cut in 1..4 {
            assert_eq!(
                decode(&bytes[..bytes.len() - cut]),
                Err(DecodeError::Truncated {
                    field: "estimate",
                    needed: 4,
                    left: 4 - cut
                })
            );
        }
        assert_eq!(
            decode(&[&bytes[..], &[0]].concat()),
            Err(DecodeError::TrailingBytes(1))
        );
    }

    #[test]
    fn typed_errors_name_the_problem() {
        let propose = encode(&examples()[0]);
        assert_eq!(
            decode(&[]),
            Err(DecodeError::Truncated {
                field: "tag",
                needed: 1,
                left: 0
            })
        );
        let unknown_tag = |value| DecodeError::Invalid {
            field: "tag",
            value,
            allowed: "1 to 13",
        };
        assert_eq!(decode(&[0; 9]), Err(unknown_tag(0)));
        assert_eq!(decode(&[14; 9]), Err(unknown_tag(14)));
        assert_eq!(
            decode(&propose[..propose.len() - 1]),
            Err(DecodeError::Truncated {
                field: "separation_micros",
                needed: 8,
                left: 7
            })
        );
        assert_eq!(
            decode(&[&propose[..], &[0, 0]].concat()),
            Err(DecodeError::TrailingBytes(2))
        );
        // A session count over the bound, and one the input cannot hold.
        let mut long = propose.clone();
        long[9..13].copy_from_slice(&(MAX_BLOCK_SESSIONS as u32 + 1).to_be_bytes());
        assert_eq!(
            decode(&long),
            Err(DecodeError::TooLong {
                field: "sessions",
                len: MAX_BLOCK_SESSIONS as u32 + 1,
                max: MAX_BLOCK_SESSIONS
            })
        );
        long[9..13].copy_from_slice(&(MAX_BLOCK_SESSIONS as u32).to_be_bytes());
        assert!(matches!(
            decode(&long),
            Err(DecodeError::Truncated {
                field: "sessions",
                needed: 262_144,
                ..
            })
        ));
        let mut answer = encode(&examples()[3]);
        answer[13..17].copy_from_slice(&u32::MAX.to_be_bytes());
        assert!(matches!(
            decode(&answer),
            Err(DecodeError::TooLong {
                field: "parities",
                ..
            })
        ));
        // A syndrome longer than one code's block is refused before anything is read.
        let mut syndrome = encode(&examples()[12]);
        syndrome[13..17].copy_from_slice(&(MAX_SYNDROME_BITS as u32 + 1).to_be_bytes());
        assert_eq!(
            decode(&syndrome),
            Err(DecodeError::TooLong {
                field: "syndrome",
                len: MAX_SYNDROME_BITS as u32 + 1,
                max: MAX_SYNDROME_BITS
            })
        );
        let mut reject = encode(&examples()[10]);
        reject[9] = 5;
        assert_eq!(
            decode(&reject),
            Err(DecodeError::Invalid {
                field: "reject reason",
                value: 5,
                allowed: "0 to 4"
            })
        );
        let mut abort = encode(&examples()[8]);
        *abort.last_mut().unwrap() = 5;
        assert!(matches!(
            decode(&abort),
            Err(DecodeError::Invalid {
                field: "abort reason",
                value: 5,
                ..
            })
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
                Err(DecodeError::NonZeroPadding("parities"))
            );
        }
        let mut agree = encode(&examples()[1]);
        *agree.last_mut().unwrap() |= 1;
        assert_eq!(decode(&agree), Err(DecodeError::NonZeroPadding("sample")));
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
                *tag = rng.random_range(0..15);
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
            // `Confirm`'s estimate is its optional last field: without it the message is
            // a whole `Confirm` of the configured plant (which the robot refuses when the
            // plant is measured), and 1–3 bytes after one are an estimate cut short.
            let optional = match message {
                Message::Confirm { estimate, .. } => Some(estimate.is_some()),
                _ => None,
            };
            for cut in 0..bytes.len() {
                if optional == Some(true) && cut == bytes.len() - 4 {
                    assert!(matches!(
                        decode(&bytes[..cut]),
                        Ok(Message::Confirm { estimate: None, .. })
                    ));
                    continue;
                }
                assert!(decode(&bytes[..cut]).is_err(), "{message:?} cut at {cut}");
            }
            for extra in 1..4 {
                let longer = [&bytes[..], &vec![0; extra]].concat();
                let expected = if optional == Some(false) {
                    DecodeError::Truncated {
                        field: "estimate",
                        needed: 4,
                        left: extra,
                    }
                } else {
                    DecodeError::TrailingBytes(extra)
                };
                assert_eq!(decode(&longer), Err(expected));
            }
        }
    }
}
