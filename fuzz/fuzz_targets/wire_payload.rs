//! Like `wire_decode`, but with a valid CRC-32C appended, so the fuzzer explores the header
//! and payload parsers instead of stopping at the checksum.
#![no_main]

use libfuzzer_sys::fuzz_target;
use robokey::protocol::wire::{crc32c, decode, encode};

fuzz_target!(|data: &[u8]| {
    let mut bytes = data.to_vec();
    bytes.extend_from_slice(&crc32c(data).to_be_bytes());
    if let Ok(frame) = decode(&bytes) {
        assert_eq!(encode(&frame), bytes, "a decoded frame re-encodes to its bytes");
    }
});
