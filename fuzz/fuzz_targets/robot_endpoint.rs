//! The robot endpoint under arbitrary samples (non-finite poses included), deadlines and
//! messages (structured, mutated genuine ones, arbitrary bytes through the wire decoder),
//! with a genuine controller as its peer: no panic, bounded outputs, wheel speeds finite
//! and within the agreed limit, no motion after the last step (`robokey::fuzzing`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| robokey::fuzzing::robot_endpoint(data));
