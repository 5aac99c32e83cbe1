//! The wire format, version 2 (documented in `docs/wire.md`): hand-written, big-endian,
//! `magic u16 | version u8 | type u8 | session u32 | seq u32 | step u32 | payload | mac [16]`.
//! This module encodes and parses frames: the header here, the type through the one
//! [`MessageType`] table, the payload through the codec of its [`Message`] layer. The
//! MAC is computed and checked by the session layer ([`super::auth`]). The decoder never
//! panics: every malformed input is a [`WireError`].

use robokey_codec::{DecodeError, Reader, Writer};

pub use super::message::{
    MAX_FINISH_CODEWORDS, MAX_POST_FRAGMENT_BYTES, MAX_POST_FRAGMENTS, MAX_REASON_BYTES,
    MAX_TERMS_BYTES,
};
use super::message::{Message, MessageType, TAG_BYTES, TypeError};

/// `"RK"`.
pub const MAGIC: u16 = 0x524B;
/// Wire-format version.
pub const VERSION: u8 = 2;
/// Header length (bytes), before the payload.
pub const HEADER_BYTES: usize = 2 + 1 + 1 + 4 + 4 + 4;
/// Trailer length (bytes): the MAC.
pub const MAC_BYTES: usize = TAG_BYTES;
/// Longest frame the decoder accepts (bytes): a `Finish` of [`MAX_FINISH_CODEWORDS`].
pub const MAX_FRAME_BYTES: usize =
    HEADER_BYTES + 4 + 8 * (MAX_FINISH_CODEWORDS as usize / 64) + MAC_BYTES;
/// Bytes of a `PostFragment` payload before its chunk: `message u32 | index u16 | count u16 |
/// len u16`.
const POST_FRAGMENT_HEAD: usize = 4 + 2 + 2 + 2;
const _: () = assert!(
    HEADER_BYTES + POST_FRAGMENT_HEAD + MAX_POST_FRAGMENT_BYTES as usize + MAC_BYTES
        <= MAX_FRAME_BYTES
);

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
    /// A type byte that is unknown or reserved ([`MessageType::from_byte`]).
    #[error(transparent)]
    Type(#[from] TypeError),
    /// The header's `step` or the payload does not fit the message type: a field missing,
    /// out of its range, or bytes left over.
    #[error("{kind}: {error}")]
    Invalid {
        /// The message type.
        kind: MessageType,
        /// What is wrong, naming the field.
        error: DecodeError,
    },
}

/// Encodes a frame's header and payload: the bytes its MAC covers (the session layer
/// appends the MAC).
#[must_use]
pub fn encode(frame: &Frame) -> Vec<u8> {
    let mut writer = Writer::with_capacity(64);
    writer.u16(MAGIC);
    writer.u8(VERSION);
    writer.u8(frame.message.message_type().byte());
    writer.u32(frame.session);
    writer.u32(frame.seq);
    writer.u32(frame.message.step());
    frame.message.encode_payload(&mut writer);
    writer.into_bytes()
}

/// Splits a datagram into the bytes its MAC covers and the MAC.
#[must_use]
pub fn split_mac(bytes: &[u8]) -> Option<(&[u8], &[u8])> {
    bytes
        .len()
        .checked_sub(MAC_BYTES)
        .map(|at| bytes.split_at(at))
}

/// Parses a datagram (header, payload, MAC), checking magic, version, type, the header's
/// step and the payload. It does **not** check the MAC: that is the session layer's job
/// ([`super::auth`]); an eavesdropper reads captures with it.
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
    // Header fields cannot run short past the length check above; if they did, the frame
    // would be too short.
    let short = |_: DecodeError| WireError::TooShort(bytes.len());
    let mut reader = Reader::new(&bytes[..bytes.len() - MAC_BYTES]);
    let magic = reader.u16("magic").map_err(short)?;
    if magic != MAGIC {
        return Err(WireError::BadMagic(magic));
    }
    let version = reader.u8("version").map_err(short)?;
    if version != VERSION {
        return Err(WireError::UnsupportedVersion(version));
    }
    let kind = MessageType::from_byte(reader.u8("type").map_err(short)?)?;
    let session = reader.u32("session").map_err(short)?;
    let seq = reader.u32("seq").map_err(short)?;
    let step = reader.u32("step").map_err(short)?;
    let invalid = |error| WireError::Invalid { kind, error };
    // A frame must re-encode to its own bytes: a type without a step sends 0.
    if step != 0 && !kind.carries_step() {
        return Err(invalid(DecodeError::Invalid {
            field: "step",
            value: step.into(),
            allowed: "0 (this type carries no step)",
        }));
    }
    let message = Message::decode_payload(kind, step, &mut reader).map_err(invalid)?;
    reader.finish().map_err(invalid)?;
    Ok(Frame {
        session,
        seq,
        message,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::FateWindow;
    use crate::protocol::auth::{PairingSecret, seal};
    use crate::protocol::message::{AuthMode, Closing, Handshake, PostFragment, SessionMessage};
    use proptest::prelude::*;

    fn hex(bytes: &[u8]) -> String {
        bytes.iter().map(|b| format!("{b:02x}")).collect()
    }

    fn examples() -> Vec<Message> {
        vec![
            Message::Handshake(Handshake::Hello {
                auth: AuthMode::Paired,
                nonce: [0x11; 16],
                config_digest: [0xAB; 32],
                terms: "robot.T = 0.2\n".into(),
            }),
            Message::Handshake(Handshake::HelloAck {
                auth: AuthMode::Paired,
                nonce_c: [0x11; 16],
                nonce_r: [0x22; 16],
                config_digest: [0xCD; 32],
            }),
            Message::Handshake(Handshake::Refuse {
                nonce_c: [0x11; 16],
                reason: "terms".into(),
            }),
            Message::Handshake(Handshake::Ready),
            Message::Session(SessionMessage::Measurement {
                step: 7,
                y: [1.0, -0.5, 0.25],
                applied_step: Some(6),
                fate_cursor: 2,
            }),
            Message::Session(SessionMessage::Measurement {
                step: 8,
                y: [0.0; 3],
                applied_step: None,
                fate_cursor: 2,
            }),
            Message::Session(SessionMessage::Command {
                step: 7,
                u0: [4.0, 3.5],
                u1: [0.5, -1.0],
                fates: FateWindow {
                    first: 2,
                    count: 3,
                    accepted: 0b101,
                },
            }),
            Message::Closing(Closing::Finish {
                codewords: 65,
                bitmap: vec![u64::MAX, 1],
            }),
            Message::Closing(Closing::FinishAck),
            Message::Closing(Closing::Confirm {
                session_tag: [1; 16],
                key_tag: [2; 16],
            }),
            Message::Closing(Closing::Done),
            Message::Closing(Closing::Abort {
                reason: "silence".into(),
            }),
            Message::Session(SessionMessage::PrivateMeasurement {
                step: 7,
                applied_step: Some(6),
                fate_cursor: 2,
            }),
            Message::Session(SessionMessage::DoubletCommand {
                step: 6,
                sample: [1.0, -0.5, 0.25],
                first: [0.1, -0.2],
                second: Some([0.125, 0.5]),
                fates: FateWindow {
                    first: 2,
                    count: 1,
                    accepted: 1,
                },
            }),
            Message::Session(SessionMessage::DoubletCommand {
                step: 9,
                sample: [0.0; 3],
                first: [0.0; 2],
                second: None,
                fates: FateWindow::default(),
            }),
            Message::Post(PostFragment {
                message: 0x0A0B_0C0D,
                index: 2,
                count: 3,
                bytes: vec![0xEE, 0xFF, 0x01],
            }),
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
            message: Message::Closing(Closing::FinishAck),
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
        assert_eq!(decode(&bad), Err(WireError::Type(TypeError::Unknown(99))));
        bad[3] = 17;
        assert_eq!(decode(&bad), Err(WireError::Type(TypeError::Reserved(17))));
        let long = vec![0; MAX_FRAME_BYTES + 1];
        assert_eq!(decode(&long), Err(WireError::TooLong(MAX_FRAME_BYTES + 1)));
    }

    #[test]
    fn typed_errors_for_bad_post_fragments() {
        let frame = |index, count, bytes: Vec<u8>| {
            let message = Message::Post(PostFragment {
                message: 5,
                index,
                count,
                bytes,
            });
            let frame = Frame {
                session: 1,
                seq: 1,
                message,
            };
            [encode(&frame), vec![0; MAC_BYTES]].concat()
        };
        let field = |bytes: &[u8]| match decode(bytes) {
            Err(WireError::Invalid {
                kind: MessageType::PostFragment,
                error: DecodeError::Invalid { field, .. },
            }) => field,
            other => panic!("expected a bad field, got {other:?}"),
        };
        assert!(decode(&frame(1023, 1024, vec![1; 1024])).is_ok());
        assert_eq!(field(&frame(0, 0, vec![1])), "count");
        assert_eq!(field(&frame(0, MAX_POST_FRAGMENTS + 1, vec![1])), "count");
        assert_eq!(field(&frame(3, 3, vec![1])), "index");
        assert_eq!(field(&frame(0, 1, Vec::new())), "len");
        // The encoder cuts an oversized chunk; a forged length over the bound is refused.
        let mut long = frame(0, 1, vec![1; 1024]);
        long[HEADER_BYTES + 8..HEADER_BYTES + 10].copy_from_slice(&1025u16.to_be_bytes());
        long.insert(HEADER_BYTES + 10, 1);
        assert_eq!(field(&long), "len");
        // The chunk must fill the payload exactly.
        let mut extra = frame(0, 1, vec![1; 4]);
        extra.insert(HEADER_BYTES + 10, 1);
        assert_eq!(
            decode(&extra),
            Err(WireError::Invalid {
                kind: MessageType::PostFragment,
                error: DecodeError::TrailingBytes(1)
            })
        );
        let short = [&frame(0, 1, vec![1])[..HEADER_BYTES + 9], &[0; MAC_BYTES]].concat();
        assert_eq!(
            decode(&short),
            Err(WireError::Invalid {
                kind: MessageType::PostFragment,
                error: DecodeError::Truncated {
                    field: "len",
                    needed: 2,
                    left: 1
                }
            })
        );
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
            message: Message::Handshake(Handshake::Ready),
        });
        bytes[12..16].copy_from_slice(&[249, 252, 151, 82]);
        bytes.extend_from_slice(&[0; MAC_BYTES]);
        assert!(matches!(decode(&bytes), Err(WireError::Invalid { .. })));
    }

    #[test]
    fn an_absent_second_input_must_be_zero() {
        let mut bytes = encode(&Frame {
            session: 1,
            seq: 1,
            message: Message::Session(SessionMessage::DoubletCommand {
                step: 4,
                sample: [0.5; 3],
                first: [0.1, 0.0],
                second: None,
                fates: FateWindow::default(),
            }),
        });
        bytes.extend_from_slice(&[0; MAC_BYTES]);
        assert!(decode(&bytes).is_ok());
        let flag = HEADER_BYTES + 24 + 16;
        bytes[flag + 3] = 1;
        assert!(matches!(decode(&bytes), Err(WireError::Invalid { .. })));
        bytes[flag] = 2;
        assert!(matches!(decode(&bytes), Err(WireError::Invalid { .. })));
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
                .prop_map(|(paired, nonce, config_digest, terms)| Message::Handshake(
                    Handshake::Hello {
                        auth: mode(paired),
                        nonce,
                        config_digest,
                        terms
                    }
                )),
            (
                any::<bool>(),
                any::<[u8; 16]>(),
                any::<[u8; 16]>(),
                any::<[u8; 32]>()
            )
                .prop_map(|(paired, nonce_c, nonce_r, config_digest)| {
                    Message::Handshake(Handshake::HelloAck {
                        auth: mode(paired),
                        nonce_c,
                        nonce_r,
                        config_digest,
                    })
                }),
            (any::<[u8; 16]>(), ".{0,40}").prop_map(|(nonce_c, reason)| Message::Handshake(
                Handshake::Refuse { nonce_c, reason }
            )),
            Just(Message::Handshake(Handshake::Ready)),
            (any::<u32>(), [f, f, f], any::<Option<u32>>(), any::<u32>()).prop_map(
                |(step, y, applied_step, fate_cursor)| Message::Session(
                    SessionMessage::Measurement {
                        step,
                        y,
                        applied_step,
                        fate_cursor
                    }
                )
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
                    Message::Session(SessionMessage::Command {
                        step,
                        u0,
                        u1,
                        fates: FateWindow {
                            first,
                            count,
                            accepted,
                        },
                    })
                }),
            proptest::collection::vec(any::<u64>(), 0..5).prop_map(|bitmap| Message::Closing(
                Closing::Finish {
                    codewords: bitmap.len() as u32 * 64,
                    bitmap
                }
            )),
            Just(Message::Closing(Closing::FinishAck)),
            Just(Message::Closing(Closing::Done)),
            (any::<[u8; 16]>(), any::<[u8; 16]>()).prop_map(|(session_tag, key_tag)| {
                Message::Closing(Closing::Confirm {
                    session_tag,
                    key_tag,
                })
            }),
            ".{0,40}".prop_map(|reason| Message::Closing(Closing::Abort { reason })),
            (any::<u32>(), any::<Option<u32>>(), any::<u32>()).prop_map(
                |(step, applied_step, fate_cursor)| Message::Session(
                    SessionMessage::PrivateMeasurement {
                        step,
                        applied_step,
                        fate_cursor
                    }
                )
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
                        Message::Session(SessionMessage::DoubletCommand {
                            step,
                            sample,
                            first,
                            second,
                            fates: FateWindow {
                                first: first_fate,
                                count,
                                accepted,
                            },
                        })
                    }
                ),
            (
                any::<u32>(),
                1..=MAX_POST_FRAGMENTS,
                proptest::collection::vec(any::<u8>(), 1..=usize::from(MAX_POST_FRAGMENT_BYTES))
            )
                .prop_flat_map(|(message, count, bytes)| {
                    (0..count).prop_map(move |index| {
                        Message::Post(PostFragment {
                            message,
                            index,
                            count,
                            bytes: bytes.clone(),
                        })
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
