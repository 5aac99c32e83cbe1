//! Why bytes do not decode.

/// Why bytes are not an encoding of the value being read. Each names the field it concerns.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
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
    /// Bytes follow a complete value.
    #[error("{0} bytes after the end of the message")]
    TrailingBytes(usize),
    /// A list (or text) longer than its bound.
    #[error("{field} has {len} items (at most {max})")]
    TooLong {
        /// The list.
        field: &'static str,
        /// Its declared length.
        len: u32,
        /// Its bound.
        max: usize,
    },
    /// A field holds a value outside the ones it allows.
    #[error("{field} is {value}, allowed: {allowed}")]
    Invalid {
        /// The field.
        field: &'static str,
        /// Its value (a float as its IEEE-754 bits).
        value: u64,
        /// What it may hold.
        allowed: &'static str,
    },
    /// The padding bits after a bit list are not zero.
    #[error("{0}: padding bits are not zero")]
    NonZeroPadding(&'static str),
    /// A text is not UTF-8.
    #[error("{0} is not UTF-8")]
    NotUtf8(&'static str),
}
