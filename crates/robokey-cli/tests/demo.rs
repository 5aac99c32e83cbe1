//! `robokey demo`: a final key in one command, shown on both sides, its bits never printed;
//! bounded in sessions and time; the odometry mode ends without a key and says why.

mod common;

use common::{assert_sized_from_the_measured_plant, run_code, s, scratch};

#[test]
fn the_demo_ends_with_the_same_settled_key_in_both_stores_and_never_prints_it() {
    let dir = scratch("demo");
    let out = dir.join("demo");
    // Two bits per doublet (a session pools about 600 raw bits through the relay's faults)
    // and 1,600-bit blocks: a block after three sessions, whose key (319 to 400 bits in three
    // runs, sized from the measured plant, private sensing's default; 292 and 525 in two with
    // the plant configured) is long enough to look for in the output.
    let (code, text) = run_code(&[
        "demo",
        "--out",
        &s(&out),
        "--set",
        "postprocess.block_bits=1600",
        "--set",
        "protocol.bits_per_doublet=2",
        "--max-sessions",
        "6",
    ]);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("the bits are equal on both sides"), "{text}");
    let id = text
        .split("  ID ")
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .unwrap_or_else(|| panic!("no key ID in {text}"));
    let pairing = s(&out.join("pairing.key"));
    let mut bits = Vec::new();
    for role in ["robot", "controller"] {
        let (code, hex) = run_code(&[
            "keys",
            "get",
            "--store",
            &s(&out.join(role)),
            "--pairing",
            &pairing,
            id,
        ]);
        assert_eq!(code, 0, "{hex}");
        bits.push(hex.trim().to_owned());
    }
    assert_eq!(bits[0], bits[1]);
    // The default sizing under private sensing: the key rests on the plant the controller
    // measured, not on the configured noise.
    let (code, listed) = run_code(&[
        "keys",
        "list",
        "--store",
        &s(&out.join("controller")),
        "--pairing",
        &pairing,
        "--json",
    ]);
    assert_eq!(code, 0, "{listed}");
    let keys: Vec<serde_json::Value> = serde_json::from_str(&listed).unwrap();
    assert!(!keys.is_empty(), "{listed}");
    assert_sized_from_the_measured_plant(&keys);
    // Eight hex digits or more: a chance match in the output has odds below 1e-6.
    let probe = &bits[0][..bits[0].len().min(16)];
    assert!(probe.len() >= 8, "a key of {} hex digits", bits[0].len());
    assert!(!text.contains(probe), "the demo printed key bits: {text}");
    // The folder is refused once it holds a demo.
    let (code, text) = run_code(&["demo", "--out", &s(&out)]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("is not empty"), "{text}");
}

#[test]
fn the_odometry_demo_ends_without_a_key_and_says_why_and_every_bound_holds() {
    let dir = scratch("demo-bounds");
    let (code, text) = run_code(&[
        "demo",
        "--mode",
        "odometry",
        "--out",
        &s(&dir.join("odometry")),
        "--set",
        "postprocess.block_bits=64",
    ]);
    assert_eq!(code, 3, "{text}");
    assert!(
        text.contains("no key: no secret bits: zero by structure")
            && text.contains("demo: no final key, by structure"),
        "{text}"
    );
    let (code, text) = run_code(&["demo", "--out", &s(&dir.join("one")), "--max-sessions", "1"]);
    assert_eq!(code, 3, "{text}");
    assert!(
        text.contains("session 1: ") && text.contains("no final key within 1 sessions"),
        "{text}"
    );
    let (code, text) = run_code(&["demo", "--out", &s(&dir.join("brief")), "--timeout", "1"]);
    assert_eq!(code, 3, "{text}");
    assert!(
        text.contains("within the time allowed (--timeout)"),
        "{text}"
    );
}
