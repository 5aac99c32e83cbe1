//! Like `wire_decode`, but with a MAC trailer appended, so the fuzzer spends its input on the
//! header and payload parsers.
#![no_main]

use libfuzzer_sys::fuzz_target;
use robokey::protocol::wire::{MAC_BYTES, decode, encode};

fuzz_target!(|data: &[u8]| {
    let mut bytes = data.to_vec();
    bytes.extend_from_slice(&[0; MAC_BYTES]);
    if let Ok(frame) = decode(&bytes) {
        assert_eq!(
            encode(&frame),
            data,
            "a decoded frame re-encodes to its bytes"
        );
    }
});
