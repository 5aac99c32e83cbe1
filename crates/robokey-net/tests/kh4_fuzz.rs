//! The fuzz target `kh4_reply` (fuzz/) as a stable proptest driver: the same byte decoder
//! and checks (`robokey_net::fuzzing`), a fixed seed and a fixed number of cases.

use proptest::collection::vec;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};

fn config() -> Config {
    Config {
        cases: 4096,
        rng_seed: RngSeed::Fixed(0x5eed),
        failure_persistence: None,
        ..Config::default()
    }
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn kh4_replies_and_odometry_keep_their_invariants(data in vec(any::<u8>(), 0..1024)) {
        robokey_net::fuzzing::kh4_reply(&data);
    }
}

/// The input the fuzzer found first (`Odometry::update` overflowed on `left - last_left`).
#[test]
fn fuzz_finding_stays_fixed() {
    robokey_net::fuzzing::kh4_reply(&[0x01, 0x5b, 0x3c, 0x30, 0x2b, 0x9b]);
}
