//! The wire format (documented in `docs/wire.md`): hand-written, big-endian,
//! `magic u16 | version u8 | type u8 | session u32 | seq u32 | step u32 | payload |
//! crc32c u32`. The decoder never panics: every malformed input is a [`WireError`].

use super::TAG_BYTES;
use super::fates::FateWindow;
use super::message::Message;

/// `"RK"`.
pub const MAGIC: u16 = 0x524B;
/// Wire-format version.
pub const VERSION: u8 = 1;
/// Header length (bytes), before the payload.
pub const HEADER_BYTES: usize = 2 + 1 + 1 + 4 + 4 + 4;
/// Longest `Abort` reason (bytes of UTF-8).
pub const MAX_REASON_BYTES: usize = 1024;
/// Longest `Hello` terms text (bytes of UTF-8).
pub const MAX_TERMS_BYTES: usize = 4096;
/// Most codewords a `Finish` may cover.
pub const MAX_FINISH_CODEWORDS: u32 = 1 << 20;

/// A message with its session id and frame sequence number.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Session id.
    pub session: u32,
    /// Frame counter of the sender (retransmissions get new numbers).
    pub seq: u32,
    /// The message.
    pub message: Message,
}

/// Why bytes are not a valid frame.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum WireError {
    /// Shorter than a header plus checksum.
    #[error("frame of {0} bytes is too short")]
    TooShort(usize),
    /// The first two bytes are not `RK`.
    #[error("bad magic 0x{0:04x}")]
    BadMagic(u16),
    /// A version this build does not speak.
    #[error("unsupported wire version {0} (this build speaks {VERSION})")]
    UnsupportedVersion(u8),
    /// An unknown message type.
    #[error("unknown message type {0}")]
    UnknownType(u8),
    /// The CRC-32C does not match (corrupted in transit).
    #[error("checksum mismatch")]
    BadChecksum,
    /// The payload length does not fit the message type.
    #[error("{kind}: payload of {got} bytes, expected {expected}")]
    BadLength {
        /// Message type.
        kind: &'static str,
        /// Bytes present.
        got: usize,
        /// Bytes expected.
        expected: usize,
    },
    /// A field holds a value the protocol does not allow.
    #[error("{0}")]
    BadField(&'static str),
}

const HELLO: u8 = 1;
const HELLO_ACK: u8 = 2;
const MEASUREMENT: u8 = 3;
const COMMAND: u8 = 4;
const FINISH: u8 = 5;
const FINISH_ACK: u8 = 6;
const CONFIRM: u8 = 7;
const ABORT: u8 = 8;

/// Encodes a frame.
#[must_use]
pub fn encode(frame: &Frame) -> Vec<u8> {
    let (kind, step) = match &frame.message {
        Message::Hello { .. } => (HELLO, 0),
        Message::HelloAck { .. } => (HELLO_ACK, 0),
        Message::Measurement { step, .. } => (MEASUREMENT, *step),
        Message::Command { step, .. } => (COMMAND, *step),
        Message::Finish { .. } => (FINISH, 0),
        Message::FinishAck => (FINISH_ACK, 0),
        Message::Confirm { .. } => (CONFIRM, 0),
        Message::Abort { .. } => (ABORT, 0),
    };
    let mut out = Vec::with_capacity(64);
    out.extend_from_slice(&MAGIC.to_be_bytes());
    out.push(VERSION);
    out.push(kind);
    out.extend_from_slice(&frame.session.to_be_bytes());
    out.extend_from_slice(&frame.seq.to_be_bytes());
    out.extend_from_slice(&step.to_be_bytes());
    match &frame.message {
        Message::Hello {
            version,
            config_digest,
            terms,
        } => {
            out.push(*version);
            out.extend_from_slice(config_digest);
            put_text(&mut out, terms, MAX_TERMS_BYTES);
        }
        Message::HelloAck { config_digest } => out.extend_from_slice(config_digest),
        Message::Measurement {
            y,
            applied_step,
            fate_cursor,
            ..
        } => {
            for v in y {
                out.extend_from_slice(&v.to_be_bytes());
            }
            out.push(u8::from(applied_step.is_some()));
            out.extend_from_slice(&applied_step.unwrap_or(0).to_be_bytes());
            out.extend_from_slice(&fate_cursor.to_be_bytes());
        }
        Message::Command { u0, u1, fates, .. } => {
            for v in u0.iter().chain(u1) {
                out.extend_from_slice(&v.to_be_bytes());
            }
            out.extend_from_slice(&fates.first.to_be_bytes());
            out.push(fates.count);
            out.extend_from_slice(&fates.accepted.to_be_bytes());
        }
        Message::Finish { codewords, bitmap } => {
            out.extend_from_slice(&codewords.to_be_bytes());
            for word in bitmap.iter().take(codewords.div_ceil(64) as usize) {
                out.extend_from_slice(&word.to_be_bytes());
            }
            for _ in bitmap.len()..codewords.div_ceil(64) as usize {
                out.extend_from_slice(&0u64.to_be_bytes());
            }
        }
        Message::FinishAck => {}
        Message::Confirm { tag } => out.extend_from_slice(tag),
        Message::Abort { reason } => put_text(&mut out, reason, MAX_REASON_BYTES),
    }
    let crc = crc32c(&out);
    out.extend_from_slice(&crc.to_be_bytes());
    out
}

/// Appends `len u16 | UTF-8 bytes`, truncated at a character boundary to `max` bytes.
fn put_text(out: &mut Vec<u8>, text: &str, max: usize) {
    let mut end = text.len().min(max);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    out.extend_from_slice(&(end as u16).to_be_bytes());
    out.extend_from_slice(&text.as_bytes()[..end]);
}

/// Reads `len u16 | UTF-8 bytes` filling the rest of the payload.
fn get_text(kind: &'static str, r: &mut Reader<'_>, max: usize) -> Result<String, WireError> {
    if r.bytes.len() < 2 {
        return Err(WireError::BadLength {
            kind,
            got: r.bytes.len(),
            expected: 2,
        });
    }
    let len = usize::from(u16::from_be_bytes(r.take()));
    if len > max {
        return Err(WireError::BadField("text longer than allowed"));
    }
    if r.bytes.len() != len {
        return Err(WireError::BadLength {
            kind,
            got: r.bytes.len(),
            expected: len,
        });
    }
    let text =
        std::str::from_utf8(r.bytes).map_err(|_| WireError::BadField("text is not UTF-8"))?;
    Ok(text.to_owned())
}

/// A cursor over a payload whose length was checked up front.
struct Reader<'a> {
    bytes: &'a [u8],
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let (head, rest) = self.bytes.split_at(N);
        self.bytes = rest;
        head.try_into().expect("length checked before reading")
    }
    fn u8(&mut self) -> u8 {
        self.take::<1>()[0]
    }
    fn u32(&mut self) -> u32 {
        u32::from_be_bytes(self.take())
    }
    fn u64(&mut self) -> u64 {
        u64::from_be_bytes(self.take())
    }
    fn f64(&mut self) -> f64 {
        f64::from_be_bytes(self.take())
    }
}

fn expect_len(kind: &'static str, payload: &[u8], expected: usize) -> Result<(), WireError> {
    if payload.len() == expected {
        Ok(())
    } else {
        Err(WireError::BadLength {
            kind,
            got: payload.len(),
            expected,
        })
    }
}

/// Decodes a frame, checking magic, version, type, checksum and lengths.
///
/// # Errors
/// A [`WireError`] naming what is wrong; never panics.
pub fn decode(bytes: &[u8]) -> Result<Frame, WireError> {
    if bytes.len() < HEADER_BYTES + 4 {
        return Err(WireError::TooShort(bytes.len()));
    }
    let magic = u16::from_be_bytes([bytes[0], bytes[1]]);
    if magic != MAGIC {
        return Err(WireError::BadMagic(magic));
    }
    if bytes[2] != VERSION {
        return Err(WireError::UnsupportedVersion(bytes[2]));
    }
    let (body, crc) = bytes.split_at(bytes.len() - 4);
    if crc32c(body) != u32::from_be_bytes(crc.try_into().expect("4 bytes")) {
        return Err(WireError::BadChecksum);
    }
    let kind = bytes[3];
    let mut header = Reader {
        bytes: &body[4..HEADER_BYTES],
    };
    let (session, seq, step) = (header.u32(), header.u32(), header.u32());
    let payload = &body[HEADER_BYTES..];
    let mut r = Reader { bytes: payload };
    let message = match kind {
        HELLO => {
            if payload.len() < 33 {
                return Err(WireError::BadLength {
                    kind: "Hello",
                    got: payload.len(),
                    expected: 35,
                });
            }
            let (version, config_digest) = (r.u8(), r.take());
            let terms = get_text("Hello", &mut r, MAX_TERMS_BYTES)?;
            Message::Hello {
                version,
                config_digest,
                terms,
            }
        }
        HELLO_ACK => {
            expect_len("HelloAck", payload, 32)?;
            Message::HelloAck {
                config_digest: r.take(),
            }
        }
        MEASUREMENT => {
            expect_len("Measurement", payload, 24 + 1 + 4 + 4)?;
            let y = [r.f64(), r.f64(), r.f64()];
            let (flag, value) = (r.u8(), r.u32());
            let applied = match (flag, value) {
                (0, 0) => None,
                (1, step) => Some(step),
                (0, _) => {
                    return Err(WireError::BadField(
                        "Measurement: applied_step set while flagged absent",
                    ));
                }
                _ => {
                    return Err(WireError::BadField(
                        "Measurement: applied_step flag is not 0 or 1",
                    ));
                }
            };
            Message::Measurement {
                step,
                y,
                applied_step: applied,
                fate_cursor: r.u32(),
            }
        }
        COMMAND => {
            expect_len("Command", payload, 32 + 4 + 1 + 8)?;
            let u0 = [r.f64(), r.f64()];
            let u1 = [r.f64(), r.f64()];
            let fates = FateWindow {
                first: r.u32(),
                count: r.u8(),
                accepted: r.u64(),
            };
            if u32::from(fates.count) > FateWindow::CAPACITY {
                return Err(WireError::BadField("Command: fate window longer than 64"));
            }
            Message::Command {
                step,
                u0,
                u1,
                fates,
            }
        }
        FINISH => {
            if payload.len() < 4 {
                return Err(WireError::BadLength {
                    kind: "Finish",
                    got: payload.len(),
                    expected: 4,
                });
            }
            let codewords = r.u32();
            if codewords > MAX_FINISH_CODEWORDS {
                return Err(WireError::BadField("Finish: too many codewords"));
            }
            let words = codewords.div_ceil(64) as usize;
            expect_len("Finish", payload, 4 + 8 * words)?;
            Message::Finish {
                codewords,
                bitmap: (0..words).map(|_| r.u64()).collect(),
            }
        }
        FINISH_ACK => {
            expect_len("FinishAck", payload, 0)?;
            Message::FinishAck
        }
        CONFIRM => {
            expect_len("Confirm", payload, TAG_BYTES)?;
            Message::Confirm { tag: r.take() }
        }
        ABORT => Message::Abort {
            reason: get_text("Abort", &mut r, MAX_REASON_BYTES)?,
        },
        other => return Err(WireError::UnknownType(other)),
    };
    // Only Measurement and Command carry a step; the others encode 0, and a frame must
    // re-encode to its own bytes.
    if step != 0 && !matches!(kind, MEASUREMENT | COMMAND) {
        return Err(WireError::BadField(
            "header step is set on a message that has none",
        ));
    }
    Ok(Frame {
        session,
        seq,
        message,
    })
}

/// CRC-32C (Castagnoli, reflected polynomial 0x82F63B78), bitwise-table free.
#[must_use]
pub fn crc32c(bytes: &[u8]) -> u32 {
    const TABLE: [u32; 256] = {
        let mut table = [0u32; 256];
        let mut i = 0;
        while i < 256 {
            let mut crc = i as u32;
            let mut bit = 0;
            while bit < 8 {
                crc = if crc & 1 == 1 {
                    (crc >> 1) ^ 0x82F6_3B78
                } else {
                    crc >> 1
                };
                bit += 1;
            }
            table[i] = crc;
            i += 1;
        }
        table
    };
    !bytes.iter().fold(!0u32, |crc, &b| {
        (crc >> 8) ^ TABLE[((crc ^ u32::from(b)) & 0xFF) as usize]
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn hex(bytes: &[u8]) -> String {
        bytes.iter().map(|b| format!("{b:02x}")).collect()
    }

    fn examples() -> Vec<Message> {
        vec![
            Message::Hello {
                version: 1,
                config_digest: [0xAB; 32],
                terms: "robot.T = 0.2
"
                .into(),
            },
            Message::HelloAck {
                config_digest: [0xCD; 32],
            },
            Message::Measurement {
                step: 7,
                y: [1.0, -0.5, 0.25],
                applied_step: Some(6),
                fate_cursor: 2,
            },
            Message::Measurement {
                step: 8,
                y: [0.0; 3],
                applied_step: None,
                fate_cursor: 2,
            },
            Message::Command {
                step: 7,
                u0: [4.0, 3.5],
                u1: [0.5, -1.0],
                fates: FateWindow {
                    first: 2,
                    count: 3,
                    accepted: 0b101,
                },
            },
            Message::Finish {
                codewords: 65,
                bitmap: vec![u64::MAX, 1],
            },
            Message::FinishAck,
            Message::Confirm {
                tag: [1, 2, 3, 4, 5, 6, 7, 8],
            },
            Message::Abort {
                reason: "silence".into(),
            },
        ]
    }

    #[test]
    fn crc32c_matches_the_standard_check_value() {
        assert_eq!(crc32c(b"123456789"), 0xE306_9283);
    }

    #[test]
    fn golden_bytes_per_message_type() {
        let got: Vec<String> = examples()
            .into_iter()
            .map(|message| {
                hex(&encode(&Frame {
                    session: 0x0102_0304,
                    seq: 9,
                    message,
                }))
            })
            .collect();
        assert_eq!(got.join("\n"), GOLDEN.trim());
    }

    const GOLDEN: &str = "
524b010101020304000000090000000001abababababababababababababababababababababababababababababababab000e726f626f742e54203d20302e320a08bfc491
524b0102010203040000000900000000cdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcd0889cfa5
524b01030102030400000009000000073ff0000000000000bfe00000000000003fd00000000000000100000006000000023c2e954f
524b01030102030400000009000000080000000000000000000000000000000000000000000000000000000000000000029cb1c253
524b01040102030400000009000000074010000000000000400c0000000000003fe0000000000000bff0000000000000000000020300000000000000053d350a5f
524b010501020304000000090000000000000041ffffffffffffffff000000000000000119c60667
524b0106010203040000000900000000772732de
524b0107010203040000000900000000010203040506070869bc30b2
524b0108010203040000000900000000000773696c656e63658314b32a
";

    #[test]
    fn typed_errors_for_bad_frames() {
        let good = encode(&Frame {
            session: 1,
            seq: 1,
            message: Message::FinishAck,
        });
        assert_eq!(decode(&good[..5]), Err(WireError::TooShort(5)));
        let mut bad = good.clone();
        bad[2] = 9;
        assert_eq!(decode(&bad), Err(WireError::UnsupportedVersion(9)));
        let mut bad = good.clone();
        bad[0] = 0;
        assert!(matches!(decode(&bad), Err(WireError::BadMagic(_))));
        let mut bad = good.clone();
        bad[10] ^= 1;
        assert_eq!(decode(&bad), Err(WireError::BadChecksum));
        let mut bad = good[..good.len() - 4].to_vec();
        bad[3] = 99;
        let crc = crc32c(&bad);
        bad.extend_from_slice(&crc.to_be_bytes());
        assert_eq!(decode(&bad), Err(WireError::UnknownType(99)));
    }

    #[test]
    fn a_step_on_a_stepless_message_is_rejected() {
        // Found by the wire_payload fuzz target: a HelloAck whose header step was ignored,
        // so the frame did not re-encode to its bytes.
        let mut bytes = encode(&Frame {
            session: 1,
            seq: 1,
            message: Message::HelloAck {
                config_digest: [7; 32],
            },
        });
        bytes.truncate(bytes.len() - 4);
        bytes[12..16].copy_from_slice(&[249, 252, 151, 82]);
        let crc = crc32c(&bytes);
        bytes.extend_from_slice(&crc.to_be_bytes());
        assert!(matches!(decode(&bytes), Err(WireError::BadField(_))));
    }

    fn arb_message() -> impl Strategy<Value = Message> {
        let f = proptest::num::f64::ANY;
        prop_oneof![
            (any::<u8>(), any::<[u8; 32]>(), ".{0,60}").prop_map(
                |(version, config_digest, terms)| Message::Hello {
                    version,
                    config_digest,
                    terms
                }
            ),
            any::<[u8; 32]>().prop_map(|config_digest| Message::HelloAck { config_digest }),
            (any::<u32>(), [f, f, f], any::<Option<u32>>(), any::<u32>()).prop_map(
                |(step, y, applied_step, fate_cursor)| Message::Measurement {
                    step,
                    y,
                    applied_step,
                    fate_cursor
                }
            ),
            (
                any::<u32>(),
                [f, f],
                [f, f],
                any::<u32>(),
                0u8..=64,
                any::<u64>()
            )
                .prop_map(|(step, u0, u1, first, count, accepted)| {
                    Message::Command {
                        step,
                        u0,
                        u1,
                        fates: FateWindow {
                            first,
                            count,
                            accepted,
                        },
                    }
                }),
            proptest::collection::vec(any::<u64>(), 0..5).prop_map(|bitmap| Message::Finish {
                codewords: bitmap.len() as u32 * 64,
                bitmap
            }),
            Just(Message::FinishAck),
            any::<[u8; 8]>().prop_map(|tag| Message::Confirm { tag }),
            ".{0,40}".prop_map(|reason| Message::Abort { reason }),
        ]
    }

    /// Equality that treats NaNs as equal bit patterns.
    fn same(a: &Frame, b: &Frame) -> bool {
        encode(a) == encode(b)
    }

    proptest! {
        #[test]
        fn decoding_arbitrary_bytes_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
            let _ = decode(&bytes);
        }

        #[test]
        fn decoding_corrupted_frames_never_panics(message in arb_message(), flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..4)) {
            let mut bytes = encode(&Frame { session: 3, seq: 4, message });
            for (at, x) in flips {
                let i = at % bytes.len();
                bytes[i] ^= x;
            }
            let _ = decode(&bytes);
        }

        #[test]
        fn round_trip(message in arb_message(), session in any::<u32>(), seq in any::<u32>()) {
            let frame = Frame { session, seq, message };
            let back = decode(&encode(&frame)).unwrap();
            prop_assert!(same(&back, &frame), "{:?} vs {:?}", back, frame);
        }
    }
}
