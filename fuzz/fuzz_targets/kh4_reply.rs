//! kh4server reply lines and encoder counts through `parse_reply` and `Odometry`: no
//! panic, replies read exactly, a finite pose that moves no further per update than two
//! 32-bit counts allow (`robokey_net::fuzzing`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| robokey_net::fuzzing::kh4_reply(data));
