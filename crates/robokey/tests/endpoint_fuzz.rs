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

/// Inputs the fuzzers found, kept as regressions: each drives the session to the finding
/// (each panicked before its fix). Bytes: the configuration (a choice byte, then its own),
/// the session id (4), the key seed (8), then one operation per byte with its arguments
/// (`robokey::fuzzing`).
#[test]
fn fuzz_findings_stay_fixed() {
    let header = |choice: &[u8]| {
        let mut bytes = choice.to_vec();
        bytes.extend([0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 7]);
        bytes
    };
    // The robot: a command whose fate window starts near `u32::MAX` overflowed
    // `FateWindow::iter`. Sample 0; inject a command for step 0 from a genuine pair of
    // nominal (0.1, 0), with the window `u32::MAX − 3`, 64 fates.
    let mut robot = header(&[3]);
    robot.extend([3, 9, 0, 2, 1, 9, 0, 0, 9, 0, 0, 1, 3, 64]);
    robot.extend([0xff; 8]);
    robokey::fuzzing::robot_endpoint(&robot);
    // The odometry controller: a finite but absurd first measurement (f64::MAX m) overflowed
    // the tracking controller into a NaN command. A measurement of step 0 at
    // (f64::MAX, f64::MAX, −0).
    let mut huge = header(&[3]);
    huge.extend([9, 1, 2, 3, 3, 6, 0, 2]);
    robokey::fuzzing::controller_endpoint(&huge);
    // The private controller: a finite but absurd sensor sample (f64::MAX m) made the
    // doublet's tracking command non-finite. A 20-step private session; sample 0; then the
    // controller's sensor reads step 2 at (f64::MAX, f64::MAX, −0).
    let mut absurd = header(&[4, 4]);
    absurd.extend([3, 8, 1, 7, 2, 3, 3, 6]);
    robokey::fuzzing::controller_endpoint(&absurd);
}
