//! A value that encodes and decodes itself.

use crate::{DecodeError, Reader, Writer};

/// A value with a byte encoding. Implementations decode only canonical encodings: whatever
/// [`Codec::decode`] accepts, [`Codec::encode`] writes back byte for byte.
pub trait Codec: Sized {
    /// Appends the encoding of `self`.
    fn encode(&self, writer: &mut Writer);

    /// Reads one value from the front of `reader`.
    ///
    /// # Errors
    /// A [`DecodeError`] naming the field that is missing or wrong; never panics.
    fn decode(reader: &mut Reader<'_>) -> Result<Self, DecodeError>;

    /// The encoding of `self` as a byte vector.
    #[must_use]
    fn to_bytes(&self) -> Vec<u8> {
        let mut writer = Writer::new();
        self.encode(&mut writer);
        writer.into_bytes()
    }

    /// Decodes one value filling all of `bytes`.
    ///
    /// # Errors
    /// As [`Codec::decode`], or [`DecodeError::TrailingBytes`] when bytes follow the value.
    fn from_bytes(bytes: &[u8]) -> Result<Self, DecodeError> {
        let mut reader = Reader::new(bytes);
        let value = Self::decode(&mut reader)?;
        reader.finish()?;
        Ok(value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `a u16 | b [2]`, with `a ≤ 9`.
    #[derive(Debug, PartialEq)]
    struct Pair {
        a: u16,
        b: [u8; 2],
    }

    impl Codec for Pair {
        fn encode(&self, writer: &mut Writer) {
            writer.u16(self.a);
            writer.bytes(&self.b);
        }

        fn decode(reader: &mut Reader<'_>) -> Result<Self, DecodeError> {
            let a = reader.u16("a")?;
            if a > 9 {
                return Err(DecodeError::Invalid {
                    field: "a",
                    value: a.into(),
                    allowed: "0 to 9",
                });
            }
            Ok(Self {
                a,
                b: reader.array("b")?,
            })
        }
    }

    #[test]
    fn a_value_round_trips_and_whole_input_decoding_names_what_is_wrong() {
        let pair = Pair { a: 7, b: [1, 2] };
        assert_eq!(pair.to_bytes(), [0, 7, 1, 2]);
        assert_eq!(Pair::from_bytes(&[0, 7, 1, 2]), Ok(pair));
        assert_eq!(
            Pair::from_bytes(&[0, 7, 1, 2, 3]),
            Err(DecodeError::TrailingBytes(1))
        );
        assert_eq!(
            Pair::from_bytes(&[0, 7, 1]),
            Err(DecodeError::Truncated {
                field: "b",
                needed: 2,
                left: 1
            })
        );
        assert_eq!(
            Pair::from_bytes(&[0, 10, 1, 2]),
            Err(DecodeError::Invalid {
                field: "a",
                value: 10,
                allowed: "0 to 9"
            })
        );
    }
}
