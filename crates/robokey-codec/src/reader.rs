//! Takes fields, big-endian, checking each against the bytes left.

use crate::DecodeError;

/// A cursor over bytes. Every read names the field it reads and fails with a
/// [`DecodeError`] instead of reading past the end; no read panics.
#[derive(Clone, Debug)]
pub struct Reader<'a> {
    bytes: &'a [u8],
}

impl<'a> Reader<'a> {
    /// A reader at the start of `bytes`.
    #[must_use]
    pub fn new(bytes: &'a [u8]) -> Self {
        Self { bytes }
    }

    /// The next `n` bytes of `field`.
    ///
    /// # Errors
    /// [`DecodeError::Truncated`] when fewer than `n` are left (nothing is consumed then).
    pub fn take(&mut self, field: &'static str, n: usize) -> Result<&'a [u8], DecodeError> {
        if n > self.bytes.len() {
            return Err(DecodeError::Truncated {
                field,
                needed: n,
                left: self.bytes.len(),
            });
        }
        let (head, rest) = self.bytes.split_at(n);
        self.bytes = rest;
        Ok(head)
    }

    /// The next `N` bytes of `field`, as an array.
    ///
    /// # Errors
    /// As [`Reader::take`].
    pub fn array<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], DecodeError> {
        let mut array = [0; N];
        array.copy_from_slice(self.take(field, N)?);
        Ok(array)
    }

    /// A byte.
    ///
    /// # Errors
    /// As [`Reader::take`].
    pub fn u8(&mut self, field: &'static str) -> Result<u8, DecodeError> {
        Ok(self.array::<1>(field)?[0])
    }

    /// A `u16`.
    ///
    /// # Errors
    /// As [`Reader::take`].
    pub fn u16(&mut self, field: &'static str) -> Result<u16, DecodeError> {
        self.array(field).map(u16::from_be_bytes)
    }

    /// A `u32`.
    ///
    /// # Errors
    /// As [`Reader::take`].
    pub fn u32(&mut self, field: &'static str) -> Result<u32, DecodeError> {
        self.array(field).map(u32::from_be_bytes)
    }

    /// A `u64`.
    ///
    /// # Errors
    /// As [`Reader::take`].
    pub fn u64(&mut self, field: &'static str) -> Result<u64, DecodeError> {
        self.array(field).map(u64::from_be_bytes)
    }

    /// An IEEE-754 `f64` (any bit pattern, NaNs included).
    ///
    /// # Errors
    /// As [`Reader::take`].
    pub fn f64(&mut self, field: &'static str) -> Result<f64, DecodeError> {
        self.array(field).map(f64::from_be_bytes)
    }

    /// `N` consecutive `f64`s of `field`.
    ///
    /// # Errors
    /// As [`Reader::take`].
    pub fn f64s<const N: usize>(&mut self, field: &'static str) -> Result<[f64; N], DecodeError> {
        let raw = self.take(field, 8 * N)?;
        let mut values = [0.0; N];
        for (value, bytes) in values.iter_mut().zip(raw.chunks_exact(8)) {
            let mut be = [0; 8];
            be.copy_from_slice(bytes);
            *value = f64::from_be_bytes(be);
        }
        Ok(values)
    }

    /// A list length `len u32` of `field`, at most `max`.
    ///
    /// # Errors
    /// As [`Reader::take`], or [`DecodeError::TooLong`] above `max`.
    pub fn len_u32(&mut self, field: &'static str, max: usize) -> Result<usize, DecodeError> {
        let len = self.u32(field)?;
        usize::try_from(len)
            .ok()
            .filter(|&n| n <= max)
            .ok_or(DecodeError::TooLong { field, len, max })
    }

    /// Ends reading: every byte must have been read.
    ///
    /// # Errors
    /// [`DecodeError::TrailingBytes`] when some are left.
    pub fn finish(self) -> Result<(), DecodeError> {
        if self.bytes.is_empty() {
            Ok(())
        } else {
            Err(DecodeError::TrailingBytes(self.bytes.len()))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Writer;

    #[test]
    fn every_field_reads_back_what_the_writer_wrote() {
        let mut w = Writer::new();
        w.u8(0xAB);
        w.u16(0x0102);
        w.u32(0x0304_0506);
        w.u64(0x0708_090A_0B0C_0D0E);
        w.f64(-0.5);
        w.f64s(&[1.0, f64::INFINITY]);
        w.len_u32(3);
        w.bytes(&[9, 8, 7]);
        let bytes = w.into_bytes();
        assert_eq!(bytes.len(), 1 + 2 + 4 + 8 + 8 + 16 + 4 + 3);
        let mut r = Reader::new(&bytes);
        assert_eq!(r.u8("a"), Ok(0xAB));
        assert_eq!(r.u16("b"), Ok(0x0102));
        assert_eq!(r.u32("c"), Ok(0x0304_0506));
        assert_eq!(r.u64("d"), Ok(0x0708_090A_0B0C_0D0E));
        assert_eq!(r.f64("e"), Ok(-0.5));
        assert_eq!(r.f64s::<2>("f"), Ok([1.0, f64::INFINITY]));
        assert_eq!(r.len_u32("g", 3), Ok(3));
        assert_eq!(r.clone().finish(), Err(DecodeError::TrailingBytes(3)));
        assert_eq!(r.array::<3>("h"), Ok([9, 8, 7]));
        assert_eq!(r.finish(), Ok(()));
    }

    #[test]
    fn short_input_long_lists_and_leftovers_are_named_and_consume_nothing() {
        let mut r = Reader::new(&[0, 0, 0, 5, 1]);
        assert_eq!(
            r.len_u32("items", 4),
            Err(DecodeError::TooLong {
                field: "items",
                len: 5,
                max: 4
            })
        );
        let mut r = Reader::new(&[1, 2, 3]);
        assert_eq!(
            r.u32("count"),
            Err(DecodeError::Truncated {
                field: "count",
                needed: 4,
                left: 3
            })
        );
        // A failed read leaves the bytes in place.
        assert_eq!(r.u16("half"), Ok(0x0102));
        assert_eq!(r.finish(), Err(DecodeError::TrailingBytes(1)));
        assert_eq!(
            Reader::new(&[]).take("huge", usize::MAX),
            Err(DecodeError::Truncated {
                field: "huge",
                needed: usize::MAX,
                left: 0
            })
        );
    }

    #[test]
    fn a_saturated_length_never_reads_back() {
        let mut w = Writer::new();
        w.len_u32(usize::MAX);
        let bytes = w.into_bytes();
        assert_eq!(bytes, [0xFF; 4]);
        assert!(matches!(
            Reader::new(&bytes).len_u32("items", 1 << 20),
            Err(DecodeError::TooLong { .. })
        ));
    }
}
