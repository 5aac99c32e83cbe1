//! The byte encoding both of robokey's formats are written in: the wire frames
//! (`robokey::protocol::wire`, docs/wire.md) and the post-processing messages
//! (`robokey_secrecy::postprocess`, docs/postprocessing.md). Integers and floats are
//! big-endian; lists carry their length first.
//!
//! - [`Writer`] appends fields to a byte vector; it never fails.
//! - [`Reader`] takes fields from a byte slice; every read is checked against the bytes left
//!   and against the bound of what it reads, so no input makes it panic or allocate more
//!   than the input could hold, and every [`DecodeError`] names the field that is wrong.
//! - [`Codec`] is a value that writes itself and reads itself back: what decodes re-encodes
//!   to the same bytes.
//!
//! It performs no I/O and holds no state beyond the cursor.

#![forbid(unsafe_code)]

mod codec;
mod error;
mod reader;
mod writer;

pub use codec::Codec;
pub use error::DecodeError;
pub use reader::Reader;
pub use writer::Writer;
