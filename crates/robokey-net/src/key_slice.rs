//! Keys cut from final keys (docs/keys.md, "Key IDs"): a slice is a run of whole bytes of one
//! settled final key, and its ID — a UUID both sides compute — names the final key and the
//! run, so the robot side cuts the same bits from the ID the controller side gave.
//!
//! The ID is an RFC 9562 version-8 UUID whose 32 hex digits are, in order: the final key's
//! 16-digit ID F with the version digit `8` after its 12th digit and the variant digit `8`
//! after its 15th (`F[0..12] 8 F[12..15] 8 F[15]`), the slice's offset in bits (8 digits) and
//! its length in bits (6 digits). For example bits 256–511 of the final key
//! `00112233aabbccdd` are `00112233-aabb-8ccd-8d00-000100000100`. The bits are the final key's
//! bits `offset … offset + bits − 1`, most significant bit first (the key file's order).

use serde::{Deserialize, Serialize};
use uuid::Uuid;

/// Shortest slice (bits).
pub const MIN_SLICE_BITS: u32 = 64;
/// Longest slice (bits): a slice never spans two final keys, so longer ones rarely exist.
pub const MAX_SLICE_BITS: u32 = 8192;
/// The length a request that names none gets (bits).
pub const DEFAULT_SLICE_BITS: u32 = 256;

/// The version digit of a slice ID (RFC 9562: 8, custom layout).
const VERSION: u128 = 8;
/// The variant digit of a slice ID: the RFC 9562 variant `10`, then `00` for this layout.
const VARIANT_AND_LAYOUT: u128 = 8;

/// A run of a final key's bits: `bits` bits from bit `offset`, both multiples of 8.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Span {
    /// The first bit.
    pub offset: u32,
    /// How many bits.
    pub bits: u32,
}

impl Span {
    /// One past the last bit.
    #[must_use]
    pub fn end(&self) -> u64 {
        u64::from(self.offset) + u64::from(self.bits)
    }

    /// Whether the two runs share a bit.
    #[must_use]
    pub fn overlaps(&self, other: &Self) -> bool {
        u64::from(self.offset) < other.end() && u64::from(other.offset) < self.end()
    }

    /// The bytes it covers (offset and length in bytes).
    #[must_use]
    pub fn bytes(&self) -> std::ops::Range<usize> {
        self.offset as usize / 8..self.end() as usize / 8
    }
}

/// A slice's identity: the final key it is cut from and its run of bits.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct SliceId {
    /// The final key's ID (16 hex digits, as both stores name it).
    pub key: String,
    /// The run of the final key's bits.
    pub span: Span,
}

impl SliceId {
    /// The slice `span` of the final key `key`.
    ///
    /// # Errors
    /// `key` is not 16 hex digits, or the span's length is not a slice length
    /// ([`check_slice_bits`]) or its offset not a whole byte.
    pub fn new(key: &str, span: Span) -> Result<Self, String> {
        if key.len() != 16 || !key.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(format!(
                "final key ID {key:?} is not 16 hex digits (`robokey keys list` shows them)"
            ));
        }
        check_slice_bits(span.bits)?;
        if !span.offset.is_multiple_of(8) {
            return Err(format!(
                "offset {} is not a whole byte (a multiple of 8 bits)",
                span.offset
            ));
        }
        Ok(Self {
            key: key.to_ascii_lowercase(),
            span,
        })
    }

    /// Its UUID (the module documentation gives the layout).
    #[must_use]
    pub fn uuid(&self) -> Uuid {
        let key = u128::from(
            u64::from_str_radix(&self.key, 16).expect("SliceId::new checked 16 hex digits"),
        );
        let value = (key >> 16) << 80
            | VERSION << 76
            | (key >> 4 & 0xfff) << 64
            | VARIANT_AND_LAYOUT << 60
            | (key & 0xf) << 56
            | u128::from(self.span.offset) << 24
            | u128::from(self.span.bits);
        Uuid::from_u128(value)
    }

    /// The slice a UUID names.
    ///
    /// # Errors
    /// The text is not a UUID, not one of robokey's slice IDs (version and variant digits),
    /// or names a length or offset no slice has; the message quotes the text briefly.
    pub fn parse(text: &str) -> Result<Self, String> {
        let quoted = brief(text);
        let uuid = Uuid::try_parse(text).map_err(|_| format!("key_ID {quoted} is not a UUID"))?;
        let value = uuid.as_u128();
        if value >> 76 & 0xf != VERSION || value >> 60 & 0xf != VARIANT_AND_LAYOUT {
            return Err(format!(
                "key_ID {quoted} is not a robokey key ID (its 13th hex digit must be 8, its 17th \
                 8): it was not given by a robokey controller side"
            ));
        }
        let key = (value >> 80) << 16 | (value >> 64 & 0xfff) << 4 | (value >> 56 & 0xf);
        let span = Span {
            offset: (value >> 24 & 0xffff_ffff) as u32,
            bits: (value & 0xff_ffff) as u32,
        };
        Self::new(&format!("{key:016x}"), span).map_err(|e| format!("key_ID {quoted}: {e}"))
    }
}

/// Refuses a slice length that is not a whole number of bytes within
/// [`MIN_SLICE_BITS`]`..=`[`MAX_SLICE_BITS`].
///
/// # Errors
/// The message names the length and the allowed range.
pub fn check_slice_bits(bits: u32) -> Result<(), String> {
    if !(MIN_SLICE_BITS..=MAX_SLICE_BITS).contains(&bits) || !bits.is_multiple_of(8) {
        return Err(format!(
            "a key of {bits} bits: sizes are multiples of 8 from {MIN_SLICE_BITS} to \
             {MAX_SLICE_BITS} bits"
        ));
    }
    Ok(())
}

/// `text` as an error quotes it: whole if short, else its start and its length.
fn brief(text: &str) -> String {
    const QUOTED: usize = 40;
    if text.chars().count() <= QUOTED {
        return format!("{text:?}");
    }
    let start: String = text.chars().take(QUOTED).collect();
    format!("{start:?}… ({} characters)", text.chars().count())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_show_the_final_key_offset_and_length_and_parse_back() {
        let id = SliceId::new(
            "00112233AABBCCDD",
            Span {
                offset: 256,
                bits: 256,
            },
        )
        .unwrap();
        let uuid = id.uuid();
        assert_eq!(uuid.to_string(), "00112233-aabb-8ccd-8d00-000100000100");
        assert_eq!(uuid.get_version_num(), 8);
        assert_eq!(uuid.get_variant(), uuid::Variant::RFC4122);
        assert_eq!(SliceId::parse(&uuid.to_string()).unwrap(), id);
        assert_eq!(
            SliceId::parse(&uuid.to_string().to_uppercase()).unwrap(),
            id
        );
        // Extremes round-trip.
        for (key, offset, bits) in [
            ("ffffffffffffffff", u32::MAX - 7, MAX_SLICE_BITS),
            ("0000000000000000", 0, MIN_SLICE_BITS),
        ] {
            let id = SliceId::new(key, Span { offset, bits }).unwrap();
            assert_eq!(SliceId::parse(&id.uuid().to_string()).unwrap(), id);
        }
    }

    #[test]
    fn foreign_uuids_and_impossible_slices_are_refused_by_name() {
        for (text, says) in [
            (
                "550e8400-e29b-41d4-a716-446655440000",
                "not a robokey key ID",
            ),
            (
                "00112233-aabb-8ccd-cd00-000100000100",
                "not a robokey key ID",
            ),
            ("00112233-aabb-8ccd-8d00-000100000101", "multiples of 8"),
            ("00112233-aabb-8ccd-8d00-000100000008", "multiples of 8"),
            ("00112233-aabb-8ccd-8d00-000100ffffff", "multiples of 8"),
            ("00112233-aabb-8ccd-8d00-000101000100", "not a whole byte"),
            ("not a uuid", "not a UUID"),
            ("", "not a UUID"),
        ] {
            let error = SliceId::parse(text).unwrap_err();
            assert!(error.contains(says), "{text}: {error}");
        }
        let long = "8".repeat(5000);
        let error = SliceId::parse(&long).unwrap_err();
        assert!(
            error.contains("(5000 characters)") && error.len() < 120,
            "{error}"
        );
        assert!(
            SliceId::new(
                "xyz",
                Span {
                    offset: 0,
                    bits: 256
                }
            )
            .is_err()
        );
    }

    #[test]
    fn spans_overlap_exactly_when_they_share_a_bit() {
        let [a, b, c] =
            [(0, 256), (256, 64), (248, 64)].map(|(offset, bits)| Span { offset, bits });
        assert!(!a.overlaps(&b) && !b.overlaps(&a));
        assert!(a.overlaps(&c) && c.overlaps(&b) && a.overlaps(&a));
        assert_eq!(c.bytes(), 31..39);
    }
}
