//! The controller endpoint under arbitrary measurements (NaN, infinite and huge poses,
//! steps out of order, duplicated, past the end, `u32::MAX`), timeouts and messages, with a
//! genuine robot as its peer: no panic, bounded outputs, only finite commands within the
//! robot's wheel limit, codewords decided once and in order (`robokey::fuzzing`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| robokey::fuzzing::controller_endpoint(data));
