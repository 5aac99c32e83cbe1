//! The protocol over a faulty virtual network, for thousands of seeds: whatever the link
//! loses, duplicates, delays or reorders, every side ends, and no two sides that believe
//! they agree hold different keys.

use std::time::Duration;

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use robokey::Config;
use robokey::pair::{Ending, LinkFaults};
use robokey::protocol::{Outcome, Timing};
use support::{Network, Session, session};

mod support;

/// Seeds per sensing mode.
const SEEDS: u64 = 10_000;

/// A short session: four sides of 2 s, 40 steps.
fn short(mode: &str) -> Config {
    Config::from_toml(
        &format!("[sensing]\nmode = \"{mode}\"\n[trajectory]\nside_time = 2.0\nlaps = 1\n"),
        "test",
    )
    .expect("a valid configuration")
}

/// The faults of one direction, drawn for a seed: up to 40 % loss, 20 % duplication, 20 %
/// reordering (held back up to 300 ms), 10 % corruption, latency and jitter up to 40 ms.
fn faults(rng: &mut ChaCha8Rng) -> LinkFaults {
    LinkFaults {
        latency: Duration::from_millis(rng.random_range(0..40)),
        jitter: Duration::from_millis(rng.random_range(0..40)),
        loss: rng.random_range(0.0..0.4),
        duplicate: rng.random_range(0.0..0.2),
        reorder: rng.random_range(0.0..0.2),
        reorder_delay: Duration::from_millis(300),
        corrupt: rng.random_range(0.0..0.1),
    }
}

/// The network of seed `seed`.
fn network(seed: u64) -> Network {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    Network {
        to_controller: faults(&mut rng),
        to_robot: faults(&mut rng),
        seed,
        timing: Timing::default(),
    }
}

/// Whether a side believes the peer holds its key (odometry) or kept the same doublets
/// (private sensing).
fn agrees(outcome: Option<&Outcome>) -> bool {
    matches!(outcome, Some(Outcome::Confirmed | Outcome::Kept))
}

/// Checks one session; returns whether both sides agreed. A confirmed odometry key is the
/// peer's key; private sensing's raw bits differ where the controller erred, but both sides
/// keep the same doublets, so their raw keys have the same length.
fn check(seed: u64, s: &Session) -> bool {
    assert_eq!(
        s.ending,
        Ending::Done,
        "seed {seed}: a side never ended: {s:?}"
    );
    let either = agrees(s.robot_outcome.as_ref()) || agrees(s.controller_outcome.as_ref());
    let kept = matches!(s.robot_outcome, Some(Outcome::Kept))
        || matches!(s.controller_outcome, Some(Outcome::Kept));
    if kept {
        assert_eq!(
            s.robot_key.len(),
            s.controller_key.len(),
            "seed {seed}: kept sets differ: {s:?}"
        );
    } else if either {
        assert_eq!(
            s.robot_key, s.controller_key,
            "seed {seed}: keys differ: {s:?}"
        );
    }
    agrees(s.robot_outcome.as_ref()) && agrees(s.controller_outcome.as_ref())
}

fn property(mode: &str) {
    let config = short(mode);
    let (mut both, mut bits, mut differ) = (0, 0, 0);
    for seed in 0..SEEDS {
        let s = session(&config, network(seed), |_, _| false, |_| false);
        both += u64::from(check(seed, &s));
        bits += s.robot_key.len();
        differ += s
            .robot_key
            .iter()
            .zip(&s.controller_key)
            .filter(|(a, b)| a != b)
            .count();
    }
    println!("{mode}: {bits} raw bits, {differ} differ");
    // Sanity, not a rate claim: the faults are harsh, but most sessions still agree.
    assert!(
        both > SEEDS / 2,
        "{mode}: only {both} of {SEEDS} sessions agreed"
    );
    println!("{mode}: {both} of {SEEDS} sessions agreed on both sides");
}

#[test]
fn over_a_faulty_network_odometry_sessions_end_and_never_hold_differing_keys() {
    property("odometry");
}

#[test]
fn over_a_faulty_network_private_sessions_end_and_never_hold_differing_keys() {
    property("private");
}

#[test]
fn an_ideal_link_agrees_in_both_modes() {
    for mode in ["odometry", "private"] {
        let s = session(&short(mode), Network::default(), |_, _| false, |_| false);
        assert!(check(0, &s), "{mode}: {s:?}");
        assert!(!s.robot_key.is_empty(), "{mode}");
    }
}
