//! The fuzz targets `robot_endpoint` and `controller_endpoint` (fuzz/) as a stable proptest
//! driver: the same byte decoder and invariant checks (`robokey::fuzzing`), a fixed seed
//! and a fixed number of cases, so the normal test suite covers them.

use proptest::collection::vec;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};

fn config() -> Config {
    Config {
        cases: 16384,
        rng_seed: RngSeed::Fixed(0x5eed),
        failure_persistence: None,
        ..Config::default()
    }
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn robot_endpoint_keeps_its_invariants(data in vec(any::<u8>(), 0..4096)) {
        robokey::fuzzing::robot_endpoint(&data);
    }

    #[test]
    fn controller_endpoint_keeps_its_invariants(data in vec(any::<u8>(), 0..4096)) {
        robokey::fuzzing::controller_endpoint(&data);
    }
}

/// Inputs the fuzzers found, kept as regressions (each panicked before its fix).
#[test]
fn fuzz_findings_stay_fixed() {
    // `FateWindow::iter` overflowed on a command whose window starts near `u32::MAX`.
    let robot: &[&[u8]] = &[&[
        0x00, 0x0c, 0x21, 0x01, 0x00, 0x00, 0x00, 0x12, 0x0c, 0x00, 0x00, 0x00, 0x00, 0x00, 0x8e,
        0x00, 0x12, 0x0c, 0x00, 0x00, 0x00, 0x00, 0x00, 0x8e,
    ]];
    for data in robot {
        robokey::fuzzing::robot_endpoint(data);
    }
    let controller: &[&[u8]] = &[];
    for data in controller {
        robokey::fuzzing::controller_endpoint(data);
    }
}
