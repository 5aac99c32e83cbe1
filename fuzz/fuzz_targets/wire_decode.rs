//! The wire parser must never panic, and whatever it accepts must re-encode to the same
//! bytes (the MAC trailer aside, which the parser does not check).
#![no_main]

use libfuzzer_sys::fuzz_target;
use robokey::protocol::wire::{MAC_BYTES, decode, encode};

fuzz_target!(|data: &[u8]| {
    if let Ok(frame) = decode(data) {
        assert_eq!(
            encode(&frame),
            data[..data.len() - MAC_BYTES],
            "a decoded frame re-encodes to its bytes"
        );
    }
});
