//! The table of message types (docs/wire.md, "Payloads"), written once: each type's wire
//! byte, its name, its layer, and whether it uses the header's `step` field. The encoder and
//! the parser both go through it, and so do their errors for unknown and reserved types;
//! tests hold docs/wire.md and the Wireshark dissector to it.

use std::ops::RangeInclusive;

/// The layer a message belongs to, and so the part of the system that takes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Layer {
    /// Opens a session: the session channel ([`crate::protocol::auth`]) takes it.
    Handshake,
    /// One step of the run (a measurement or a command, sample index k in the header's
    /// `step`): the session endpoints take it.
    Session,
    /// Ends a session once every fate is known: the session endpoints take it.
    Closing,
    /// Carries post-processing: the agents' post-processing link takes it.
    Post,
}

/// A type byte that names no message this build speaks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TypeError {
    /// No type has this byte.
    #[error("unknown message type {0}")]
    Unknown(u8),
    /// One of [`MessageType::RESERVED`].
    #[error(
        "message type {0} is reserved for {for_} and not spoken by this build",
        for_ = MessageType::RESERVED_FOR
    )]
    Reserved(u8),
}

/// Defines [`MessageType`] and its table from one list of `Name = byte, Layer;` rows.
macro_rules! message_types {
    ($($(#[$doc:meta])* $name:ident = $byte:literal, $layer:ident;)*) => {
        /// A message type: the `type` byte of a frame's header (docs/wire.md).
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum MessageType {
            $($(#[$doc])* $name = $byte,)*
        }

        impl MessageType {
            /// Every type, in wire-byte order.
            pub const ALL: &[Self] = &[$(Self::$name),*];

            /// The type of a header's `type` byte.
            ///
            /// # Errors
            /// [`TypeError::Reserved`] for [`Self::RESERVED`], else [`TypeError::Unknown`].
            pub fn from_byte(byte: u8) -> Result<Self, TypeError> {
                match byte {
                    $($byte => Ok(Self::$name),)*
                    reserved if Self::RESERVED.contains(&reserved) => {
                        Err(TypeError::Reserved(reserved))
                    }
                    unknown => Err(TypeError::Unknown(unknown)),
                }
            }

            /// Its name, as docs/wire.md and the Wireshark dissector spell it.
            #[must_use]
            pub const fn name(self) -> &'static str {
                match self {
                    $(Self::$name => stringify!($name),)*
                }
            }

            /// The layer it belongs to.
            #[must_use]
            pub const fn layer(self) -> Layer {
                match self {
                    $(Self::$name => Layer::$layer,)*
                }
            }
        }
    };
}

message_types! {
    /// Controller → robot: opens a session.
    Hello = 1, Handshake;
    /// Robot → controller: accepts a session.
    HelloAck = 2, Handshake;
    /// Robot → controller: odometry `y(k)`.
    Measurement = 3, Session;
    /// Controller → robot: the pair of wheel commands for step k.
    Command = 4, Session;
    /// Controller → robot: every codeword's fate.
    Finish = 5, Closing;
    /// Robot → controller: the Finish arrived.
    FinishAck = 6, Closing;
    /// Either side: its confirmation tags.
    Confirm = 7, Closing;
    /// Either side: the session is over, with a reason.
    Abort = 8, Closing;
    /// Robot → controller: refuses a Hello.
    Refuse = 9, Handshake;
    /// Controller → robot: the first frame under the session key.
    Ready = 10, Handshake;
    /// Robot → controller, private sensing: the sample instant `t_k` has passed.
    PrivateMeasurement = 11, Session;
    /// Controller → robot, private sensing: the nominal inputs of a doublet.
    DoubletCommand = 12, Session;
    /// Either side: it needs nothing more from the peer.
    Done = 13, Closing;
    /// Either side: one fragment of an encoded post-processing message.
    PostFragment = 16, Post;
}

impl MessageType {
    /// Types 17–21: reserved for a later use, [`Self::RESERVED_FOR`].
    pub const RESERVED: RangeInclusive<u8> = 17..=21;

    /// What the reserved types are kept for.
    pub const RESERVED_FOR: &str = "post-processing";

    /// Its wire byte.
    #[must_use]
    pub const fn byte(self) -> u8 {
        self as u8
    }

    /// Whether it uses the header's `step` field (sample index k): the session layer's
    /// types do; every other type sends 0 there, and a parser rejects anything else.
    #[must_use]
    pub const fn carries_step(self) -> bool {
        matches!(self.layer(), Layer::Session)
    }
}

impl std::fmt::Display for MessageType {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_byte_is_one_type_reserved_or_unknown() {
        let mut types = 0;
        for byte in 0..=u8::MAX {
            match MessageType::from_byte(byte) {
                Ok(kind) => {
                    assert_eq!(kind.byte(), byte);
                    types += 1;
                }
                Err(TypeError::Reserved(b)) => {
                    assert!(b == byte && MessageType::RESERVED.contains(&b));
                }
                Err(TypeError::Unknown(b)) => assert_eq!(b, byte),
            }
        }
        assert_eq!(types, MessageType::ALL.len());
        assert!(
            MessageType::ALL
                .windows(2)
                .all(|w| w[0].byte() < w[1].byte())
        );
    }

    #[test]
    fn exactly_the_session_layer_carries_a_step() {
        let stepped: Vec<&str> = MessageType::ALL
            .iter()
            .filter(|t| t.carries_step())
            .map(|t| t.name())
            .collect();
        assert_eq!(
            stepped,
            [
                "Measurement",
                "Command",
                "PrivateMeasurement",
                "DoubletCommand"
            ]
        );
    }
}
