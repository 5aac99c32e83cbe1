//! The wire decoder must never panic, and whatever it accepts must re-encode to the same
//! bytes.
#![no_main]

use libfuzzer_sys::fuzz_target;
use robokey::protocol::wire::{decode, encode};

fuzz_target!(|data: &[u8]| {
    if let Ok(frame) = decode(data) {
        assert_eq!(encode(&frame), data, "a decoded frame re-encodes to its bytes");
    }
});
