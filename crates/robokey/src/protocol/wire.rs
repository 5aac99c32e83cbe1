//! The wire format, version 2 (documented in `docs/wire.md`): hand-written, big-endian,
//! `magic u16 | version u8 | type u8 | session u32 | seq u32 | step u32 | payload | mac [16]`.
//! This module encodes and parses frames; the MAC is computed and checked by the session
//! layer ([`super::auth`]). The decoder never panics: every malformed input is a
//! [`WireError`].

use super::auth::{AuthMode, NONCE_BYTES, TAG_BYTES};
use super::fates::FateWindow;
use super::message::Message;

/// `"RK"`.
pub const MAGIC: u16 = 0x524B;
/// Wire-format version.
pub const VERSION: u8 = 2;
/// Header length (bytes), before the payload.
pub const HEADER_BYTES: usize = 2 + 1 + 1 + 4 + 4 + 4;
/// Trailer length (bytes): the MAC.
pub const MAC_BYTES: usize = TAG_BYTES;
/// Longest `Abort` or `Refuse` reason (bytes of UTF-8).
pub const MAX_REASON_BYTES: usize = 1024;
/// Longest `Hello` terms text (bytes of UTF-8).
pub const MAX_TERMS_BYTES: usize = 4096;
/// Most codewords a `Finish` may cover.
pub const MAX_FINISH_CODEWORDS: u32 = 1 << 20;
/// Most fragments one encoded post-processing message may be split into.
pub const MAX_POST_FRAGMENTS: u16 = 1024;
/// Longest chunk of an encoded post-processing message one `PostFragment` carries (bytes).
pub const MAX_POST_FRAGMENT_BYTES: u16 = 1024;
/// Longest frame the decoder accepts (bytes): a `Finish` of [`MAX_FINISH_CODEWORDS`].
pub const MAX_FRAME_BYTES: usize =
    HEADER_BYTES + 4 + 8 * (MAX_FINISH_CODEWORDS as usize / 64) + MAC_BYTES;

/// A message with its session id and frame sequence number.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Session id.
    pub session: u32,
    /// The sender's per-direction sequence number (0 on handshake frames; retransmissions
    /// get new numbers).
    pub seq: u32,
    /// The message.
    pub message: Message,
}

/// Why bytes are not a valid frame.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum WireError {
    /// Shorter than a header plus MAC.
    #[error("frame of {0} bytes is too short")]
    TooShort(usize),
    /// Longer than any valid frame.
    #[error("frame of {0} bytes is too long")]
    TooLong(usize),
    /// The first two bytes are not `RK`.
    #[error("bad magic 0x{0:04x}")]
    BadMagic(u16),
    /// A version this build does not speak.
    #[error("unsupported wire version {0} (this build speaks {VERSION})")]
    UnsupportedVersion(u8),
    /// An unknown message type.
    #[error("unknown message type {0}")]
    UnknownType(u8),
    /// A type reserved for a later use (post-processing).
    #[error("message type {0} is reserved and not spoken by this build")]
    Reserved(u8),
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
const REFUSE: u8 = 9;
const READY: u8 = 10;
const PRIVATE_MEASUREMENT: u8 = 11;
const DOUBLET_COMMAND: u8 = 12;
const DONE: u8 = 13;
/// One fragment of an encoded post-processing message.
const POST_FRAGMENT: u8 = 16;
/// Reserved: 17–21 = later post-processing use.
const RESERVED: [u8; 5] = [17, 18, 19, 20, 21];
/// Bytes of a `PostFragment` payload before its chunk: `message u32 | index u16 | count u16 |
/// len u16`.
const POST_FRAGMENT_HEAD: usize = 4 + 2 + 2 + 2;
const _: () = assert!(
    HEADER_BYTES + POST_FRAGMENT_HEAD + MAX_POST_FRAGMENT_BYTES as usize + MAC_BYTES
        <= MAX_FRAME_BYTES
);

/// Encodes a frame's header and payload: the bytes its MAC covers (the session layer
/// appends the MAC).
#[must_use]
pub fn encode(frame: &Frame) -> Vec<u8> {
    let (kind, step) = match &frame.message {
        Message::Hello { .. } => (HELLO, 0),
        Message::HelloAck { .. } => (HELLO_ACK, 0),
        Message::Refuse { .. } => (REFUSE, 0),
        Message::Ready => (READY, 0),
        Message::Measurement { step, .. } => (MEASUREMENT, *step),
        Message::Command { step, .. } => (COMMAND, *step),
        Message::PrivateMeasurement { step, .. } => (PRIVATE_MEASUREMENT, *step),
        Message::DoubletCommand { step, .. } => (DOUBLET_COMMAND, *step),
        Message::Finish { .. } => (FINISH, 0),
        Message::FinishAck => (FINISH_ACK, 0),
        Message::Confirm { .. } => (CONFIRM, 0),
        Message::Done => (DONE, 0),
        Message::Abort { .. } => (ABORT, 0),
        Message::PostFragment { .. } => (POST_FRAGMENT, 0),
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
            auth,
            nonce,
            config_digest,
            terms,
        } => {
            out.push(auth.byte());
            out.extend_from_slice(nonce);
            out.extend_from_slice(config_digest);
            put_text(&mut out, terms, MAX_TERMS_BYTES);
        }
        Message::HelloAck {
            auth,
            nonce_c,
            nonce_r,
            config_digest,
        } => {
            out.push(auth.byte());
            out.extend_from_slice(nonce_c);
            out.extend_from_slice(nonce_r);
            out.extend_from_slice(config_digest);
        }
        Message::Refuse { nonce_c, reason } => {
            out.extend_from_slice(nonce_c);
            put_text(&mut out, reason, MAX_REASON_BYTES);
        }
        Message::Ready => {}
        Message::Measurement {
            y,
            applied_step,
            fate_cursor,
            ..
        } => {
            put_f64s(&mut out, y);
            put_optional(&mut out, applied_step.map(u32::to_be_bytes), [0; 4]);
            out.extend_from_slice(&fate_cursor.to_be_bytes());
        }
        Message::PrivateMeasurement {
            applied_step,
            fate_cursor,
            ..
        } => {
            put_optional(&mut out, applied_step.map(u32::to_be_bytes), [0; 4]);
            out.extend_from_slice(&fate_cursor.to_be_bytes());
        }
        Message::Command { u0, u1, fates, .. } => {
            put_f64s(&mut out, u0);
            put_f64s(&mut out, u1);
            put_fates(&mut out, fates);
        }
        Message::DoubletCommand {
            sample,
            first,
            second,
            fates,
            ..
        } => {
            put_f64s(&mut out, sample);
            put_f64s(&mut out, first);
            put_optional(&mut out, second.map(pair_bytes), [0; 16]);
            put_fates(&mut out, fates);
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
        Message::FinishAck | Message::Done => {}
        Message::Confirm {
            session_tag,
            key_tag,
        } => {
            out.extend_from_slice(session_tag);
            out.extend_from_slice(key_tag);
        }
        Message::Abort { reason } => put_text(&mut out, reason, MAX_REASON_BYTES),
        Message::PostFragment {
            message,
            index,
            count,
            bytes,
        } => {
            out.extend_from_slice(&message.to_be_bytes());
            out.extend_from_slice(&index.to_be_bytes());
            out.extend_from_slice(&count.to_be_bytes());
            // Like a text, a chunk over the bound (which no valid sender builds) is cut.
            let len = bytes.len().min(usize::from(MAX_POST_FRAGMENT_BYTES));
            out.extend_from_slice(&(len as u16).to_be_bytes());
            out.extend_from_slice(&bytes[..len]);
        }
    }
    out
}

fn put_f64s(out: &mut Vec<u8>, values: &[f64]) {
    for v in values {
        out.extend_from_slice(&v.to_be_bytes());
    }
}

/// `[a, b]` as 16 big-endian bytes.
fn pair_bytes(pair: [f64; 2]) -> [u8; 16] {
    let mut bytes = [0; 16];
    bytes[..8].copy_from_slice(&pair[0].to_be_bytes());
    bytes[8..].copy_from_slice(&pair[1].to_be_bytes());
    bytes
}

/// Appends `present u8 | value`, the value zeroed when absent.
fn put_optional<const N: usize>(out: &mut Vec<u8>, value: Option<[u8; N]>, absent: [u8; N]) {
    out.push(u8::from(value.is_some()));
    out.extend_from_slice(&value.unwrap_or(absent));
}

fn put_fates(out: &mut Vec<u8>, fates: &FateWindow) {
    out.extend_from_slice(&fates.first.to_be_bytes());
    out.push(fates.count);
    out.extend_from_slice(&fates.accepted.to_be_bytes());
}

/// Splits a datagram into the bytes its MAC covers and the MAC.
#[must_use]
pub fn split_mac(bytes: &[u8]) -> Option<(&[u8], &[u8])> {
    bytes
        .len()
        .checked_sub(MAC_BYTES)
        .map(|at| bytes.split_at(at))
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
    /// `applied_flag u8 | applied_step u32` of a measurement.
    fn applied_step(&mut self) -> Result<Option<u32>, WireError> {
        match (self.u8(), self.u32()) {
            (0, 0) => Ok(None),
            (1, step) => Ok(Some(step)),
            (0, _) => Err(WireError::BadField(
                "measurement: applied_step set while flagged absent",
            )),
            _ => Err(WireError::BadField(
                "measurement: applied_step flag is not 0 or 1",
            )),
        }
    }
    /// `first u32 | count u8 | accepted u64` of a command.
    fn fates(&mut self) -> Result<FateWindow, WireError> {
        let fates = FateWindow {
            first: self.u32(),
            count: self.u8(),
            accepted: self.u64(),
        };
        if u32::from(fates.count) > FateWindow::CAPACITY {
            return Err(WireError::BadField("command: fate window longer than 64"));
        }
        Ok(fates)
    }
}

/// Bytes of a fate window on the wire.
const FATES_BYTES: usize = 4 + 1 + 8;

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

/// Parses a datagram (header, payload, MAC), checking magic, version, type and lengths.
/// It does **not** check the MAC: that is the session layer's job ([`super::auth`]); an
/// eavesdropper reads captures with it.
///
/// # Errors
/// A [`WireError`] naming what is wrong; never panics.
pub fn decode(bytes: &[u8]) -> Result<Frame, WireError> {
    if bytes.len() < HEADER_BYTES + MAC_BYTES {
        return Err(WireError::TooShort(bytes.len()));
    }
    if bytes.len() > MAX_FRAME_BYTES {
        return Err(WireError::TooLong(bytes.len()));
    }
    let magic = u16::from_be_bytes([bytes[0], bytes[1]]);
    if magic != MAGIC {
        return Err(WireError::BadMagic(magic));
    }
    if bytes[2] != VERSION {
        return Err(WireError::UnsupportedVersion(bytes[2]));
    }
    let body = &bytes[..bytes.len() - MAC_BYTES];
    let kind = bytes[3];
    let mut header = Reader {
        bytes: &body[4..HEADER_BYTES],
    };
    let (session, seq, step) = (header.u32(), header.u32(), header.u32());
    let payload = &body[HEADER_BYTES..];
    let mut r = Reader { bytes: payload };
    let message = match kind {
        HELLO => {
            if payload.len() < 1 + NONCE_BYTES + 32 {
                return Err(WireError::BadLength {
                    kind: "Hello",
                    got: payload.len(),
                    expected: 1 + NONCE_BYTES + 32 + 2,
                });
            }
            let auth = auth_mode(r.u8())?;
            let (nonce, config_digest) = (r.take(), r.take());
            let terms = get_text("Hello", &mut r, MAX_TERMS_BYTES)?;
            Message::Hello {
                auth,
                nonce,
                config_digest,
                terms,
            }
        }
        HELLO_ACK => {
            expect_len("HelloAck", payload, 1 + 2 * NONCE_BYTES + 32)?;
            Message::HelloAck {
                auth: auth_mode(r.u8())?,
                nonce_c: r.take(),
                nonce_r: r.take(),
                config_digest: r.take(),
            }
        }
        REFUSE => {
            if payload.len() < NONCE_BYTES {
                return Err(WireError::BadLength {
                    kind: "Refuse",
                    got: payload.len(),
                    expected: NONCE_BYTES + 2,
                });
            }
            Message::Refuse {
                nonce_c: r.take(),
                reason: get_text("Refuse", &mut r, MAX_REASON_BYTES)?,
            }
        }
        READY => {
            expect_len("Ready", payload, 0)?;
            Message::Ready
        }
        MEASUREMENT => {
            expect_len("Measurement", payload, 24 + 1 + 4 + 4)?;
            Message::Measurement {
                step,
                y: [r.f64(), r.f64(), r.f64()],
                applied_step: r.applied_step()?,
                fate_cursor: r.u32(),
            }
        }
        PRIVATE_MEASUREMENT => {
            expect_len("PrivateMeasurement", payload, 1 + 4 + 4)?;
            Message::PrivateMeasurement {
                step,
                applied_step: r.applied_step()?,
                fate_cursor: r.u32(),
            }
        }
        COMMAND => {
            expect_len("Command", payload, 32 + FATES_BYTES)?;
            Message::Command {
                step,
                u0: [r.f64(), r.f64()],
                u1: [r.f64(), r.f64()],
                fates: r.fates()?,
            }
        }
        DOUBLET_COMMAND => {
            expect_len("DoubletCommand", payload, 24 + 16 + 1 + 16 + FATES_BYTES)?;
            let sample = [r.f64(), r.f64(), r.f64()];
            let first = [r.f64(), r.f64()];
            let (flag, pair) = (r.u8(), [r.f64(), r.f64()]);
            let second = match flag {
                0 if pair.iter().all(|v| v.to_bits() == 0) => None,
                0 => {
                    return Err(WireError::BadField(
                        "DoubletCommand: second input set while flagged absent",
                    ));
                }
                1 => Some(pair),
                _ => {
                    return Err(WireError::BadField(
                        "DoubletCommand: second input flag is not 0 or 1",
                    ));
                }
            };
            Message::DoubletCommand {
                step,
                sample,
                first,
                second,
                fates: r.fates()?,
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
        DONE => {
            expect_len("Done", payload, 0)?;
            Message::Done
        }
        CONFIRM => {
            expect_len("Confirm", payload, 2 * TAG_BYTES)?;
            Message::Confirm {
                session_tag: r.take(),
                key_tag: r.take(),
            }
        }
        ABORT => Message::Abort {
            reason: get_text("Abort", &mut r, MAX_REASON_BYTES)?,
        },
        POST_FRAGMENT => post_fragment(payload)?,
        other if RESERVED.contains(&other) => return Err(WireError::Reserved(other)),
        other => return Err(WireError::UnknownType(other)),
    };
    // Only measurements and commands carry a step; the others encode 0, and a frame must
    // re-encode to its own bytes.
    if step != 0
        && !matches!(
            kind,
            MEASUREMENT | COMMAND | PRIVATE_MEASUREMENT | DOUBLET_COMMAND
        )
    {
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

/// Parses a `PostFragment` payload: `message u32 | index u16 | count u16 | len u16 |
/// bytes[len]`, exactly, with `1 ≤ count ≤ MAX_POST_FRAGMENTS`, `index < count` and
/// `1 ≤ len ≤ MAX_POST_FRAGMENT_BYTES`.
fn post_fragment(payload: &[u8]) -> Result<Message, WireError> {
    if payload.len() < POST_FRAGMENT_HEAD {
        return Err(WireError::BadLength {
            kind: "PostFragment",
            got: payload.len(),
            expected: POST_FRAGMENT_HEAD + 1,
        });
    }
    let mut r = Reader { bytes: payload };
    let message = r.u32();
    let index = u16::from_be_bytes(r.take());
    let count = u16::from_be_bytes(r.take());
    let len = u16::from_be_bytes(r.take());
    if !(1..=MAX_POST_FRAGMENTS).contains(&count) {
        return Err(WireError::BadField(
            "PostFragment: count is not 1 to MAX_POST_FRAGMENTS",
        ));
    }
    if index >= count {
        return Err(WireError::BadField(
            "PostFragment: index is not below count",
        ));
    }
    if !(1..=MAX_POST_FRAGMENT_BYTES).contains(&len) {
        return Err(WireError::BadField(
            "PostFragment: chunk length is not 1 to MAX_POST_FRAGMENT_BYTES",
        ));
    }
    expect_len(
        "PostFragment",
        payload,
        POST_FRAGMENT_HEAD + usize::from(len),
    )?;
    Ok(Message::PostFragment {
        message,
        index,
        count,
        bytes: r.bytes.to_vec(),
    })
}

fn auth_mode(byte: u8) -> Result<AuthMode, WireError> {
    AuthMode::from_byte(byte).ok_or(WireError::BadField("auth mode is not 0 or 1"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::auth::{PairingSecret, seal};
    use proptest::prelude::*;

    fn hex(bytes: &[u8]) -> String {
        bytes.iter().map(|b| format!("{b:02x}")).collect()
    }

    fn examples() -> Vec<Message> {
        vec![
            Message::Hello {
                auth: AuthMode::Paired,
                nonce: [0x11; 16],
                config_digest: [0xAB; 32],
                terms: "robot.T = 0.2\n".into(),
            },
            Message::HelloAck {
                auth: AuthMode::Paired,
                nonce_c: [0x11; 16],
                nonce_r: [0x22; 16],
                config_digest: [0xCD; 32],
            },
            Message::Refuse {
                nonce_c: [0x11; 16],
                reason: "terms".into(),
            },
            Message::Ready,
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
                session_tag: [1; 16],
                key_tag: [2; 16],
            },
            Message::Done,
            Message::Abort {
                reason: "silence".into(),
            },
            Message::PrivateMeasurement {
                step: 7,
                applied_step: Some(6),
                fate_cursor: 2,
            },
            Message::DoubletCommand {
                step: 6,
                sample: [1.0, -0.5, 0.25],
                first: [0.1, -0.2],
                second: Some([0.125, 0.5]),
                fates: FateWindow {
                    first: 2,
                    count: 1,
                    accepted: 1,
                },
            },
            Message::DoubletCommand {
                step: 9,
                sample: [0.0; 3],
                first: [0.0; 2],
                second: None,
                fates: FateWindow::default(),
            },
            Message::PostFragment {
                message: 0x0A0B_0C0D,
                index: 2,
                count: 3,
                bytes: vec![0xEE, 0xFF, 0x01],
            },
        ]
    }

    #[test]
    fn golden_bytes_per_message_type() {
        let got: Vec<String> = examples()
            .into_iter()
            .map(|message| {
                let frame = Frame {
                    session: 0x0102_0304,
                    seq: 9,
                    message,
                };
                hex(&seal(
                    &frame,
                    &PairingSecret::from_bytes(&[0x42; 32]).handshake_key(),
                ))
            })
            .collect();
        assert_eq!(got.join("\n"), GOLDEN.trim());
    }

    const GOLDEN: &str = "
524b02010102030400000009000000000011111111111111111111111111111111abababababababababababababababababababababababababababababababab000e726f626f742e54203d20302e320a9cd17ff836ebce39533e5dc75a037038
524b0202010203040000000900000000001111111111111111111111111111111122222222222222222222222222222222cdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcd44f23def5ad7cfb5a540f541580cc8d4
524b02090102030400000009000000001111111111111111111111111111111100057465726d7347508f27a01309c326b0ba3693dde018
524b020a010203040000000900000000be49285fe4e95f417b2d13489b61cf5d
524b02030102030400000009000000073ff0000000000000bfe00000000000003fd0000000000000010000000600000002f63164cc44079e52303c61cd97638b81
524b0203010203040000000900000008000000000000000000000000000000000000000000000000000000000000000002a63d9a56de3a5da3848aa055edc256de
524b02040102030400000009000000074010000000000000400c0000000000003fe0000000000000bff0000000000000000000020300000000000000053b0594da4f956d5f26e6b64f812e561d
524b020501020304000000090000000000000041ffffffffffffffff00000000000000011b4a5dbf129e269e3f5e542d0f7af339
524b0206010203040000000900000000d03c19cd1ad7d318d42af9ec58fbfdef
524b02070102030400000009000000000101010101010101010101010101010102020202020202020202020202020202e8362a11b1a425c3537475c5c2dfe96a
524b020d010203040000000900000000f8fc3135beedf80669dcb65ff4e768fb
524b0208010203040000000900000000000773696c656e63650ecfc3100c2974e5fd222aaa9fa04404
524b020b010203040000000900000007010000000600000002307e02dc80f926232919ed1470d8dbc5
524b020c0102030400000009000000063ff0000000000000bfe00000000000003fd00000000000003fb999999999999abfc999999999999a013fc00000000000003fe000000000000000000002010000000000000001cf71fd3ad249f444883253241f1ba255
524b020c0102030400000009000000090000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000097adc8c13bf278e19357b6551dd41757
524b02100102030400000009000000000a0b0c0d000200030003eeff018eeaeb30e8bf5cd9e217805a78aaff92
";

    #[test]
    fn typed_errors_for_bad_frames() {
        let good = encode(&Frame {
            session: 1,
            seq: 1,
            message: Message::FinishAck,
        });
        let good = [good, vec![0; MAC_BYTES]].concat();
        assert_eq!(decode(&good[..5]), Err(WireError::TooShort(5)));
        let mut bad = good.clone();
        bad[2] = 1;
        assert_eq!(decode(&bad), Err(WireError::UnsupportedVersion(1)));
        let mut bad = good.clone();
        bad[0] = 0;
        assert!(matches!(decode(&bad), Err(WireError::BadMagic(_))));
        let mut bad = good.clone();
        bad[3] = 99;
        assert_eq!(decode(&bad), Err(WireError::UnknownType(99)));
        bad[3] = 17;
        assert_eq!(decode(&bad), Err(WireError::Reserved(17)));
        let long = vec![0; MAX_FRAME_BYTES + 1];
        assert_eq!(decode(&long), Err(WireError::TooLong(MAX_FRAME_BYTES + 1)));
    }

    #[test]
    fn typed_errors_for_bad_post_fragments() {
        let frame = |index, count, bytes: Vec<u8>| {
            let message = Message::PostFragment {
                message: 5,
                index,
                count,
                bytes,
            };
            let frame = Frame {
                session: 1,
                seq: 1,
                message,
            };
            [encode(&frame), vec![0; MAC_BYTES]].concat()
        };
        let field = |bytes: &[u8]| match decode(bytes) {
            Err(WireError::BadField(why)) => why,
            other => panic!("expected a bad field, got {other:?}"),
        };
        assert!(decode(&frame(1023, 1024, vec![1; 1024])).is_ok());
        assert!(field(&frame(0, 0, vec![1])).contains("count"));
        assert!(field(&frame(0, MAX_POST_FRAGMENTS + 1, vec![1])).contains("count"));
        assert!(field(&frame(3, 3, vec![1])).contains("index"));
        assert!(field(&frame(0, 1, Vec::new())).contains("length"));
        // The encoder cuts an oversized chunk; a forged length over the bound is refused.
        let mut long = frame(0, 1, vec![1; 1024]);
        long[HEADER_BYTES + 8..HEADER_BYTES + 10].copy_from_slice(&1025u16.to_be_bytes());
        long.insert(HEADER_BYTES + 10, 1);
        assert!(field(&long).contains("length"));
        // The chunk must fill the payload exactly.
        let mut extra = frame(0, 1, vec![1; 4]);
        extra.insert(HEADER_BYTES + 10, 1);
        assert_eq!(
            decode(&extra),
            Err(WireError::BadLength {
                kind: "PostFragment",
                got: 15,
                expected: 14
            })
        );
        let short = [&frame(0, 1, vec![1])[..HEADER_BYTES + 9], &[0; MAC_BYTES]].concat();
        assert!(matches!(
            decode(&short),
            Err(WireError::BadLength {
                kind: "PostFragment",
                got: 9,
                ..
            })
        ));
    }

    #[test]
    fn post_fragment_bounds_match_the_secrecy_crate() {
        assert_eq!(
            usize::from(MAX_POST_FRAGMENT_BYTES),
            robokey_secrecy::postprocess::FRAGMENT_BYTES
        );
        assert_eq!(
            usize::from(MAX_POST_FRAGMENTS),
            robokey_secrecy::postprocess::MAX_FRAGMENTS
        );
    }

    #[test]
    fn a_step_on_a_stepless_message_is_rejected() {
        // Found by the wire_payload fuzz target: a HelloAck whose header step was ignored,
        // so the frame did not re-encode to its bytes.
        let mut bytes = encode(&Frame {
            session: 1,
            seq: 1,
            message: Message::Ready,
        });
        bytes[12..16].copy_from_slice(&[249, 252, 151, 82]);
        bytes.extend_from_slice(&[0; MAC_BYTES]);
        assert!(matches!(decode(&bytes), Err(WireError::BadField(_))));
    }

    #[test]
    fn an_absent_second_input_must_be_zero() {
        let mut bytes = encode(&Frame {
            session: 1,
            seq: 1,
            message: Message::DoubletCommand {
                step: 4,
                sample: [0.5; 3],
                first: [0.1, 0.0],
                second: None,
                fates: FateWindow::default(),
            },
        });
        bytes.extend_from_slice(&[0; MAC_BYTES]);
        assert!(decode(&bytes).is_ok());
        let flag = HEADER_BYTES + 24 + 16;
        bytes[flag + 3] = 1;
        assert!(matches!(decode(&bytes), Err(WireError::BadField(_))));
        bytes[flag] = 2;
        assert!(matches!(decode(&bytes), Err(WireError::BadField(_))));
    }

    fn mode(paired: bool) -> AuthMode {
        if paired {
            AuthMode::Paired
        } else {
            AuthMode::Unauthenticated
        }
    }

    fn arb_message() -> impl Strategy<Value = Message> {
        let f = proptest::num::f64::ANY;
        prop_oneof![
            (
                any::<bool>(),
                any::<[u8; 16]>(),
                any::<[u8; 32]>(),
                ".{0,60}"
            )
                .prop_map(|(paired, nonce, config_digest, terms)| Message::Hello {
                    auth: mode(paired),
                    nonce,
                    config_digest,
                    terms
                }),
            (
                any::<bool>(),
                any::<[u8; 16]>(),
                any::<[u8; 16]>(),
                any::<[u8; 32]>()
            )
                .prop_map(|(paired, nonce_c, nonce_r, config_digest)| {
                    Message::HelloAck {
                        auth: mode(paired),
                        nonce_c,
                        nonce_r,
                        config_digest,
                    }
                }),
            (any::<[u8; 16]>(), ".{0,40}")
                .prop_map(|(nonce_c, reason)| Message::Refuse { nonce_c, reason }),
            Just(Message::Ready),
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
            Just(Message::Done),
            (any::<[u8; 16]>(), any::<[u8; 16]>()).prop_map(|(session_tag, key_tag)| {
                Message::Confirm {
                    session_tag,
                    key_tag,
                }
            }),
            ".{0,40}".prop_map(|reason| Message::Abort { reason }),
            (any::<u32>(), any::<Option<u32>>(), any::<u32>()).prop_map(
                |(step, applied_step, fate_cursor)| Message::PrivateMeasurement {
                    step,
                    applied_step,
                    fate_cursor
                }
            ),
            (
                any::<u32>(),
                [f, f, f],
                [f, f],
                proptest::option::of([f, f]),
                (any::<u32>(), 0u8..=64, any::<u64>())
            )
                .prop_map(
                    |(step, sample, first, second, (first_fate, count, accepted))| {
                        Message::DoubletCommand {
                            step,
                            sample,
                            first,
                            second,
                            fates: FateWindow {
                                first: first_fate,
                                count,
                                accepted,
                            },
                        }
                    }
                ),
            (
                any::<u32>(),
                1..=MAX_POST_FRAGMENTS,
                proptest::collection::vec(any::<u8>(), 1..=usize::from(MAX_POST_FRAGMENT_BYTES))
            )
                .prop_flat_map(|(message, count, bytes)| {
                    (0..count).prop_map(move |index| Message::PostFragment {
                        message,
                        index,
                        count,
                        bytes: bytes.clone(),
                    })
                }),
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
            let mut bytes = [encode(&Frame { session: 3, seq: 4, message }), vec![0; MAC_BYTES]].concat();
            for (at, x) in flips {
                let i = at % bytes.len();
                bytes[i] ^= x;
            }
            let _ = decode(&bytes);
        }

        #[test]
        fn round_trip(message in arb_message(), session in any::<u32>(), seq in any::<u32>()) {
            let frame = Frame { session, seq, message };
            let back = decode(&[encode(&frame), vec![7; MAC_BYTES]].concat()).unwrap();
            prop_assert!(same(&back, &frame), "{:?} vs {:?}", back, frame);
        }
    }
}
