//! Texts on the wire: `len u16 | UTF-8 bytes`, bounded.

use robokey_codec::{DecodeError, Reader, Writer};

/// Longest `Abort` or `Refuse` reason (bytes of UTF-8).
pub const MAX_REASON_BYTES: usize = 1024;

/// Appends `len u16 | UTF-8 bytes`, cut at a character boundary to at most `max` bytes (a
/// longer text is never sent whole: a reason is for people, and the bound keeps frames small).
pub(super) fn put_text(writer: &mut Writer, text: &str, max: usize) {
    let mut end = text.len().min(max).min(usize::from(u16::MAX));
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    writer.u16(end as u16);
    writer.bytes(&text.as_bytes()[..end]);
}

/// Reads `len u16 | UTF-8 bytes` of `field`, with `len ≤ max`.
pub(super) fn read_text(
    reader: &mut Reader<'_>,
    field: &'static str,
    max: usize,
) -> Result<String, DecodeError> {
    let len = reader.u16(field)?;
    if usize::from(len) > max {
        return Err(DecodeError::TooLong {
            field,
            len: len.into(),
            max,
        });
    }
    let bytes = reader.take(field, usize::from(len))?;
    std::str::from_utf8(bytes)
        .map(str::to_owned)
        .map_err(|_| DecodeError::NotUtf8(field))
}
