//! The post-processing store between real agents, against lost messages and an attacker who
//! can write beside it (docs/threat-model.md, "Beside the store"): a key the peer has not
//! acknowledged stays pending, withheld from `keys get`, until a later session settles it;
//! a name planted in `keys/` is never reported as a commit; links, open modes and foreign
//! pairings are refused by name; key servers beside the running agents deliver only settled
//! keys, the same by ID on both sides.

mod common;

use std::net::{SocketAddr, UdpSocket};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use common::kme::{CONTROLLER_SAE, Pki, ROBOT_SAE, curl, have_curl, start_pair};
use common::{address_after, pairing, report, run, run_code, s, scratch, start_lines, wait_code};
use robokey::protocol::{Message, PostFragment};
use robokey_secrecy::postprocess::{self, Message as Post};

/// The agents' settings: small blocks under a restricted assumption, so that the second
/// session makes a key.
const SETTINGS: [&str; 5] = [
    "--set",
    "postprocess.block_bits=500",
    "--set",
    "postprocess.assumed_eve_error=0.25",
    "--allow-restricted",
];

/// The agents' settings with the plant measured: private sensing, blocks of 300 raw bits (one
/// session's ≈ 300 decided doublets, enough for the estimate).
/// Eve's camera is stated at 50 mm so that a block that small makes a key.
const MEASURED: [&str; 8] = [
    "--set",
    "sensing.mode=private",
    "--set",
    "postprocess.block_bits=300",
    "--set",
    "postprocess.sizing=measured",
    "--set",
    "eve.camera_std=[0.05, 0.05, 0.05]",
];

/// The agents' settings with LDPC reconciliation: private sensing, blocks of 300 raw bits,
/// Eve's camera at 50 mm (as [`MEASURED`]), the plant configured (stated: unset, private
/// sensing sizes from the measured plant).
const LDPC: [&str; 10] = [
    "--set",
    "sensing.mode=private",
    "--set",
    "postprocess.block_bits=300",
    "--set",
    "postprocess.reconciliation=ldpc",
    "--set",
    "eve.camera_std=[0.05, 0.05, 0.05]",
    "--set",
    "postprocess.sizing=configured",
];

/// Added to [`LDPC`]: two dimensions of 4-level symbols, each session's two slices
/// reconciled in turn (docs/postprocessing.md, "Multilevel slices").
const MULTILEVEL: [&str; 4] = [
    "--set",
    "protocol.levels=4",
    "--set",
    "protocol.bits_per_doublet=2",
];

/// What the man in the middle does to post-processing.
#[derive(Clone, Copy, PartialEq)]
enum Attack {
    /// Forwards everything.
    None,
    /// Drops every `Commit` (controller → robot).
    DropCommit,
    /// Drops every `CommitAck` (robot → controller).
    DropCommitAck,
    /// Reads the key's ID off the clear messages and plants a file of that name in the
    /// robot's `keys/` before the robot prepares the key.
    Plant,
    /// The plant measured ([`MEASURED`]): changes the estimate a `Confirm` carries in flight
    /// (its last byte before the frame's MAC), keeping the MAC.
    TamperEstimate,
    /// LDPC reconciliation ([`LDPC`]): forwards everything.
    Ldpc,
    /// LDPC reconciliation: changes a syndrome bit of every `Syndrome` in flight (the last
    /// byte before the frame's MAC), keeping the MAC.
    TamperSyndrome,
    /// Multilevel symbols ([`MULTILEVEL`]): forwards everything.
    Multilevel,
    /// Multilevel symbols with the plant measured ([`MULTILEVEL`], `sizing = measured`):
    /// forwards everything.
    MultilevelMeasured,
}

impl Attack {
    /// Whether the agents run private sensing.
    fn private(self) -> bool {
        matches!(
            self,
            Self::TamperEstimate
                | Self::Ldpc
                | Self::TamperSyndrome
                | Self::Multilevel
                | Self::MultilevelMeasured
        )
    }
}

/// A UDP relay on loopback between the controller and the robot at `robot`, doing `attack`
/// to the post-processing messages it can read (they are authenticated, not encrypted). It
/// stops when told, or after 5 s without traffic.
struct Relay {
    address: SocketAddr,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<usize>>,
}

impl Relay {
    fn start(robot: SocketAddr, attack: Attack, robot_store: &Path) -> Self {
        let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
        socket
            .set_read_timeout(Some(Duration::from_millis(20)))
            .unwrap();
        let address = socket.local_addr().unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let keys = robot_store.join("keys");
        let thread = std::thread::spawn({
            let stop = Arc::clone(&stop);
            move || {
                let mut controller = None;
                let mut seen = IdParts::default();
                let mut dropped = 0;
                let mut heard = Instant::now();
                let mut buffer = [0_u8; 2048];
                while !stop.load(Ordering::Relaxed) && heard.elapsed() < Duration::from_secs(5) {
                    let Ok((n, from)) = socket.recv_from(&mut buffer) else {
                        continue;
                    };
                    heard = Instant::now();
                    let to_robot = from != robot;
                    if to_robot {
                        controller = Some(from);
                    }
                    let tampered = match post_message(&buffer[..n]) {
                        Some(Post::Confirm {
                            estimate: Some(_), ..
                        }) => attack == Attack::TamperEstimate,
                        Some(Post::Syndrome { .. }) => attack == Attack::TamperSyndrome,
                        _ => false,
                    };
                    if tampered {
                        buffer[n - robokey::protocol::wire::MAC_BYTES - 1] ^= 0x80;
                        dropped += 1;
                    }
                    let bytes = &buffer[..n];
                    if let Some(message) = post_message(bytes) {
                        seen.note(&message);
                        let drop = match (attack, &message) {
                            (Attack::DropCommit, Post::Commit { .. }) => true,
                            (Attack::DropCommitAck, Post::CommitAck { .. }) => true,
                            (Attack::Plant, Post::Confirm { .. }) => {
                                seen.plant(&keys);
                                false
                            }
                            _ => false,
                        };
                        if drop {
                            dropped += 1;
                            continue;
                        }
                    }
                    let target = if to_robot { Some(robot) } else { controller };
                    if let Some(target) = target {
                        let _ = socket.send_to(bytes, target);
                    }
                }
                dropped
            }
        });
        Self {
            address,
            stop,
            thread: Some(thread),
        }
    }

    /// Stops the relay; the number of messages it dropped.
    fn finish(mut self) -> usize {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.take().unwrap().join().unwrap()
    }
}

impl Drop for Relay {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

/// The post-processing message a datagram carries whole, if any.
fn post_message(datagram: &[u8]) -> Option<Post> {
    let frame = robokey::protocol::wire::decode(datagram).ok()?;
    match frame.message {
        Message::Post(PostFragment {
            count: 1, bytes, ..
        }) => postprocess::decode(&bytes).ok(),
        _ => None,
    }
}

/// The public parts of a key's ID, as a man in the middle reads them.
#[derive(Default)]
struct IdParts {
    block: u64,
    nonce_c: [u8; 32],
    nonce_r: [u8; 32],
    sessions: Vec<u32>,
    length: u64,
}

impl IdParts {
    fn note(&mut self, message: &Post) {
        match message {
            Post::Propose { block, nonce, .. } => (self.block, self.nonce_c) = (*block, *nonce),
            Post::Agree {
                sessions, nonce, ..
            } => (self.sessions, self.nonce_r) = (sessions.clone(), *nonce),
            Post::Confirm { length, .. } => self.length = *length,
            _ => {}
        }
    }

    /// The key's ID: 16 hex digits of SHA-256("robokey/key-id/v1" ‖ block ‖ sessions ‖
    /// nonces ‖ ℓ) (docs/postprocessing.md, "Key store").
    fn id(&self) -> String {
        use sha2::{Digest, Sha256};
        let mut hash = Sha256::new();
        hash.update(b"robokey/key-id/v1");
        hash.update(self.block.to_be_bytes());
        hash.update((self.sessions.len() as u64).to_be_bytes());
        for id in &self.sessions {
            hash.update(id.to_be_bytes());
        }
        hash.update(self.nonce_c);
        hash.update(self.nonce_r);
        hash.update(self.length.to_be_bytes());
        hash.finalize()[..8]
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect()
    }

    /// Plants the attacker's key file under the ID the agents are about to use.
    fn plant(&self, keys: &Path) {
        use std::os::unix::fs::PermissionsExt as _;
        let path = keys.join(format!("{}.key", self.id()));
        let text = format!(
            "{{\"id\": \"{}\", \"role\": \"robot\", \"hex\": \"00000000\", \"status\": \"settled\"}}\n",
            self.id()
        );
        if std::fs::write(&path, text).is_ok() {
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
        }
    }
}

/// One session between the agents, with stores `DIR/robot` and `DIR/controller`, through a
/// relay doing `attack`. Returns the exit codes (robot, controller) and the reports.
fn session(
    dir: &Path,
    pairing: &str,
    seed: u64,
    attack: Attack,
) -> ([i32; 2], [serde_json::Value; 2]) {
    let file = |name: &str| s(&dir.join(format!("{name}-{seed}.json")));
    let store = |role: &str| s(&dir.join(role));
    let common = |role: &'static str| -> Vec<String> {
        let mut args: Vec<String> = [
            "--pace",
            "lockstep",
            "--silence-timeout",
            "1",
            "--pairing",
            pairing,
            "--store",
            &store(role),
            "--report",
            &file(role),
        ]
        .map(str::to_owned)
        .to_vec();
        match attack {
            Attack::TamperEstimate => args.extend(MEASURED.map(str::to_owned)),
            Attack::Ldpc | Attack::TamperSyndrome => args.extend(LDPC.map(str::to_owned)),
            Attack::Multilevel => {
                args.extend(LDPC.iter().chain(&MULTILEVEL).map(|&a| a.to_owned()));
            }
            Attack::MultilevelMeasured => {
                args.extend(LDPC.iter().chain(&MULTILEVEL).map(|&a| a.to_owned()));
                args.extend(["--set", "postprocess.sizing=measured"].map(str::to_owned));
            }
            _ => args.extend(SETTINGS.map(str::to_owned)),
        }
        args
    };
    let mut robot_args = vec!["robot".to_owned(), "--listen".into(), "127.0.0.1:0".into()];
    robot_args.extend(["--seed".to_owned(), seed.to_string()]);
    robot_args.extend(common("robot"));
    let private = attack.private();
    if private {
        robot_args.extend(["--mocap".to_owned(), "127.0.0.1:0".to_owned()]);
    }
    let robot_args: Vec<&str> = robot_args.iter().map(String::as_str).collect();
    let (robot, lines) = start_lines(&robot_args, if private { 2 } else { 1 });
    let relay = Relay::start(robot.address.parse().unwrap(), attack, &dir.join("robot"));
    let mut controller_args = vec![
        "controller".to_owned(),
        "--robot".into(),
        relay.address.to_string(),
    ];
    controller_args.extend(common("controller"));
    if private {
        let mocap = address_after(&lines[0], "motion capture on ");
        controller_args.extend(["--sensor".to_owned(), format!("mocap:{mocap}")]);
    }
    let controller_args: Vec<&str> = controller_args.iter().map(String::as_str).collect();
    let (controller_code, text) = run_code(&controller_args);
    let (robot_code, robot_text) = wait_code(robot);
    let dropped = relay.finish();
    if matches!(
        attack,
        Attack::DropCommit
            | Attack::DropCommitAck
            | Attack::TamperEstimate
            | Attack::TamperSyndrome
    ) {
        assert!(dropped > 0, "nothing dropped: {text}\n{robot_text}");
    }
    (
        [robot_code, controller_code],
        [
            report(Path::new(&file("robot"))),
            report(Path::new(&file("controller"))),
        ],
    )
}

/// `robokey keys list --json` of a role's store.
fn listed(dir: &Path, pairing: &str, role: &str) -> Vec<serde_json::Value> {
    let store = s(&dir.join(role));
    let (ok, text) = run(&[
        "keys",
        "list",
        "--json",
        "--store",
        &store,
        "--pairing",
        pairing,
    ]);
    assert!(ok, "{text}");
    serde_json::from_str(&text).unwrap()
}

/// `robokey keys get` of a role's store: (exit code, output).
fn get(dir: &Path, pairing: &str, role: &str, id: &str) -> (i32, String) {
    let store = s(&dir.join(role));
    run_code(&["keys", "get", "--store", &store, "--pairing", pairing, id])
}

/// The statuses of a role's keys, by ID.
fn statuses(dir: &Path, pairing: &str, role: &str) -> Vec<(String, String)> {
    listed(dir, pairing, role)
        .iter()
        .map(|k| {
            (
                k["id"].as_str().unwrap().to_owned(),
                k["status"].as_str().unwrap().to_owned(),
            )
        })
        .collect()
}

/// After a settling session, both stores hold the same settled keys with the same bits.
fn assert_settled_alike(dir: &Path, pairing: &str) {
    let robot = statuses(dir, pairing, "robot");
    assert!(!robot.is_empty());
    assert_eq!(robot, statuses(dir, pairing, "controller"));
    for (id, status) in &robot {
        assert_eq!(status, "settled", "{id}");
        let (code, hex) = get(dir, pairing, "robot", id);
        assert_eq!(code, 0, "{hex}");
        assert_eq!((code, hex.clone()), get(dir, pairing, "controller", id));
    }
}

/// Every `Commit` lost: the controller's key pending, the robot's prepared key pending; both
/// agents say so (report, terminal line, exit 5) and `keys get` withholds it on both sides
/// (exit 5) until the next session settles it.
#[test]
fn a_lost_commit_leaves_both_keys_pending_until_the_next_session() {
    let dir = scratch("store-lost-commit");
    let pairing = pairing(&dir);
    let (codes, _) = session(&dir, &pairing, 70, Attack::None);
    assert_eq!(codes, [0, 0]);
    let (codes, [robot, controller]) = session(&dir, &pairing, 71, Attack::DropCommit);
    assert_eq!(codes, [5, 5], "{robot}\n{controller}");
    for (r, what) in [
        (&robot, "Commit has not arrived"),
        (&controller, "CommitAck"),
    ] {
        assert_eq!(r["ending"], "in-flight", "{r}");
        let in_flight = r["post"]["in_flight"].as_str().unwrap();
        assert!(in_flight.contains("pending"), "{in_flight}");
        assert_eq!(
            r["post"]["pending_keys"].as_array().unwrap().len(),
            1,
            "{r}"
        );
        let reason = r["post"]["pending_keys"][0]["reason"].as_str().unwrap();
        assert!(reason.contains(what), "{reason}");
    }
    let pending = statuses(&dir, &pairing, "controller");
    assert_eq!(pending.len(), 1);
    assert_eq!(pending, statuses(&dir, &pairing, "robot"));
    assert_eq!(pending[0].1, "pending");
    for role in ["robot", "controller"] {
        let (code, text) = get(&dir, &pairing, role, &pending[0].0);
        assert_eq!(code, 5, "{role}: {text}");
        assert!(text.contains("is pending"), "{text}");
    }
    let (codes, [robot, controller]) = session(&dir, &pairing, 72, Attack::None);
    assert!(codes.iter().all(|&c| c == 0 || c == 5), "{codes:?}");
    assert!(
        controller["post"]["recovery"].is_null(),
        "flattened: {controller}"
    );
    assert_eq!(robot["post"]["torn_bytes"], 0);
    assert_settled_alike(&dir, &pairing);
}

/// The plant measured: a `Confirm` whose estimate is changed in flight fails the frame's MAC
/// and is dropped by the robot, every retransmission alike; neither store commits a key.
#[test]
fn an_estimate_changed_in_flight_is_refused_by_the_channel_and_commits_nothing() {
    let dir = scratch("store-tamper-estimate");
    let pairing = pairing(&dir);
    let (_, [robot, controller]) = session(&dir, &pairing, 73, Attack::TamperEstimate);
    assert!(
        robot["frames_rejected"]["bad_mac"].as_u64().unwrap() > 0,
        "{robot}"
    );
    for r in [&robot, &controller] {
        assert!(r["post"]["keys"].as_array().unwrap().is_empty(), "{r}");
    }
    for role in ["robot", "controller"] {
        assert!(listed(&dir, &pairing, role).is_empty(), "{role}");
    }
}

/// LDPC reconciliation between the agents: the robot's syndrome decoded on the controller's
/// LLRs; both stores hold the same settled key, and both reports name the reconciliation's
/// rounds and charge the same leak.
#[test]
fn ldpc_between_the_agents_makes_the_same_key() {
    let dir = scratch("store-ldpc");
    let pairing = pairing(&dir);
    let (codes, [robot, controller]) = session(&dir, &pairing, 74, Attack::Ldpc);
    assert_eq!(codes, [0, 0], "{robot}\n{controller}");
    let blocks = |r: &serde_json::Value| r["post"]["blocks"].as_array().unwrap().clone();
    let (robot_blocks, controller_blocks) = (blocks(&robot), blocks(&controller));
    assert!(!controller_blocks.is_empty(), "{controller}");
    for (r, c) in robot_blocks.iter().zip(&controller_blocks) {
        assert!(c["ldpc_rounds"].as_u64().is_some(), "{c}");
        assert_eq!(r["leak_ec"], c["leak_ec"]);
        assert_eq!(r["length"], c["length"]);
    }
    assert!(
        !listed(&dir, &pairing, "controller").is_empty(),
        "{controller}"
    );
    // Each key's record names its reconciliation and the leak its block was charged.
    for role in ["robot", "controller"] {
        for key in listed(&dir, &pairing, role) {
            let block = controller_blocks
                .iter()
                .find(|b| b["block"] == key["block"])
                .unwrap_or_else(|| panic!("{role}: no block for {key}"));
            assert_eq!(key["reconciliation"], "ldpc", "{key}");
            assert_eq!(key["leak_ec"], block["leak_ec"], "{key}");
        }
    }
    assert_settled_alike(&dir, &pairing);
}

/// One multilevel session between the agents (`attack`'s settings, `seed`) in the scratch
/// folder `name`: both exit 0 and the controller reports two blocks, one per slice. Returns
/// the folder, the pairing file, the controller's report and both sides' blocks (robot,
/// controller).
fn multilevel_session(
    name: &str,
    seed: u64,
    attack: Attack,
) -> (
    std::path::PathBuf,
    String,
    serde_json::Value,
    [Vec<serde_json::Value>; 2],
) {
    // A block of ≈ 900 bits decoded by LDPC meets its syndrome with a wrong word about 3 times
    // in 100 (measured over 100 sessions of each test below; the sample's positions and the
    // code come from the agents' random generator, not the seed): only the tags catch it, and
    // the block ends without a key. That outcome is checked here — the slice whose tags differ
    // keeps no key on either side, and a slice committed before it stands, held by both
    // (docs/postprocessing.md, "Multilevel slices") — and the session run again in a fresh
    // pair of stores, at most `ATTEMPTS` times.
    const ATTEMPTS: usize = 3;
    const TAGS_DIFFER: &str = "the robot found our tag wrong: the reconciled keys differ";
    for attempt in 1..=ATTEMPTS {
        let dir = scratch(&format!("{name}-{attempt}"));
        let pairing = pairing(&dir);
        let (codes, [robot, controller]) = session(&dir, &pairing, seed, attack);
        assert_eq!(codes, [0, 0], "{robot}\n{controller}");
        let blocks = |r: &serde_json::Value| r["post"]["blocks"].as_array().unwrap().clone();
        let both = [blocks(&robot), blocks(&controller)];
        assert_eq!(both[1].len(), 2, "{controller}");
        if both[1].iter().all(|b| b["reason"] != TAGS_DIFFER) {
            return (dir, pairing, controller, both);
        }
        let keyed: Vec<&serde_json::Value> = both[1]
            .iter()
            .filter(|b| b["reason"].is_null() && b["length"].as_u64().unwrap_or(0) > 0)
            .map(|b| &b["block"])
            .collect();
        for role in ["robot", "controller"] {
            let held = listed(&dir, &pairing, role);
            let held: Vec<&serde_json::Value> = held.iter().map(|k| &k["block"]).collect();
            assert_eq!(held, keyed, "{role}: {controller}");
        }
    }
    panic!("{ATTEMPTS} sessions in a row ended on differing reconciled keys");
}

/// Multilevel symbols between the agents: the session's fine slice is a block of its own
/// under the session's ID, then its coarse slice under the derived slice ID, decoded on the
/// controller's LLRs given the fine slice's reconciled bits; both sides report the same
/// blocks, and every key either store holds is held alike by the other.
#[test]
fn multilevel_sessions_are_reconciled_slice_by_slice_between_the_agents() {
    let (dir, pairing, controller, [robot_blocks, controller_blocks]) =
        multilevel_session("store-multilevel", 76, Attack::Multilevel);
    let session = controller["session"].as_str().unwrap().to_owned();
    let id = u32::from_str_radix(&session, 16).unwrap();
    let coarse = format!("{:08x}", robokey_secrecy::postprocess::slice_id(id, 1));
    assert_eq!(
        controller_blocks[0]["session_ids"],
        serde_json::json!([session]),
        "{controller}"
    );
    assert_eq!(
        controller_blocks[1]["session_ids"],
        serde_json::json!([coarse]),
        "{controller}"
    );
    // The coarse slice, given the fine one, decodes with far fewer syndrome bits.
    let leak = |b: &serde_json::Value| b["leak_ec"].as_u64().unwrap();
    assert!(leak(&controller_blocks[1]) < leak(&controller_blocks[0]) / 2);
    assert!(
        controller_blocks[1]["length"].as_u64().unwrap() > 0,
        "{controller}"
    );
    for (r, c) in robot_blocks.iter().zip(&controller_blocks) {
        assert_eq!(r["session_ids"], c["session_ids"]);
        assert_eq!(r["length"], c["length"]);
    }
    assert_settled_alike(&dir, &pairing);
}

/// Multilevel symbols with the plant measured: the fine slice's block is held reconciled
/// until the coarse slice's is; the controller then estimates the plant on whole symbols
/// once, sizes each slice from it with its own separation, and confirms and commits them in
/// turn. Both sides report each slice's published separation and the same lengths (the
/// robot recomputing ℓ from what was carried), and both stores hold the same settled keys.
#[test]
fn multilevel_blocks_are_sized_from_the_measured_plant_between_the_agents() {
    let (dir, pairing, controller, [robot_blocks, controller_blocks]) =
        multilevel_session("store-multilevel-measured", 77, Attack::MultilevelMeasured);
    assert_eq!(robot_blocks.len(), 2, "{robot_blocks:?}");
    // One estimate per slice, of the one block: the same plant, each slice's separation.
    let estimates = controller["post"]["estimates"].as_array().unwrap();
    assert_eq!(estimates.len(), 2, "{controller}");
    assert_eq!(estimates[0]["point_std_mm"], estimates[1]["point_std_mm"]);
    // Each slice sized from its own published separation; a slice too short for a key (the
    // fine one of a single session: ℓ = 0) ends alone, the robot never confirming it.
    for (r, c) in robot_blocks.iter().zip(&controller_blocks) {
        assert_eq!(r["session_ids"], c["session_ids"]);
        assert_eq!(r["length"], c["length"]);
        assert!(c["separation"].as_f64().is_some(), "{c}");
        if c["length"].as_u64().unwrap() > 0 {
            assert_eq!(r["separation"], c["separation"]);
        }
    }
    assert_ne!(
        controller_blocks[0]["separation"], controller_blocks[1]["separation"],
        "{controller}"
    );
    assert!(
        controller_blocks[1]["length"].as_u64().unwrap() > 0,
        "{controller}"
    );
    assert_settled_alike(&dir, &pairing);
}

/// A `Syndrome` changed in flight fails the frame's MAC and is dropped by the controller,
/// every retransmission alike; neither store commits a key.
#[test]
fn a_syndrome_changed_in_flight_is_refused_by_the_channel_and_commits_nothing() {
    let dir = scratch("store-tamper-syndrome");
    let pairing = pairing(&dir);
    let (_, [robot, controller]) = session(&dir, &pairing, 75, Attack::TamperSyndrome);
    assert!(
        controller["frames_rejected"]["bad_mac"].as_u64().unwrap() > 0,
        "{controller}"
    );
    for r in [&robot, &controller] {
        assert!(r["post"]["keys"].as_array().unwrap().is_empty(), "{r}");
    }
    for role in ["robot", "controller"] {
        assert!(listed(&dir, &pairing, role).is_empty(), "{role}");
    }
}

/// Every `CommitAck` lost: the robot's key settled, the controller's pending (exit 5 for the
/// controller only) until the next session repeats the `Commit`.
#[test]
fn a_lost_commit_ack_leaves_the_controllers_key_pending_until_the_next_session() {
    let dir = scratch("store-lost-ack");
    let pairing = pairing(&dir);
    session(&dir, &pairing, 80, Attack::None);
    let (codes, [robot, controller]) = session(&dir, &pairing, 81, Attack::DropCommitAck);
    assert_eq!(codes, [0, 5], "{robot}\n{controller}");
    let line_says = controller["post"]["in_flight"].as_str().unwrap();
    assert!(line_says.contains("CommitAck"), "{line_says}");
    let controller_keys = statuses(&dir, &pairing, "controller");
    let robot_keys = statuses(&dir, &pairing, "robot");
    assert_eq!(controller_keys[0].1, "pending");
    assert_eq!(robot_keys[0].1, "settled");
    assert_eq!(controller_keys[0].0, robot_keys[0].0);
    assert_eq!(
        get(&dir, &pairing, "controller", &controller_keys[0].0).0,
        5
    );
    session(&dir, &pairing, 82, Attack::None);
    assert_settled_alike(&dir, &pairing);
}

/// The attack: a file planted under the key's ID (computed from the clear messages)
/// before the robot prepares the key. No agent reports a commit, the robot fails naming the
/// file, and `keys` refuses the planted file.
#[test]
fn a_key_file_planted_before_the_commit_is_never_reported_as_one() {
    let dir = scratch("store-planted");
    let pairing = pairing(&dir);
    session(&dir, &pairing, 90, Attack::None);
    let (codes, [robot, controller]) = session(&dir, &pairing, 91, Attack::Plant);
    assert_eq!(codes[0], 1, "the robot fails: {robot}");
    let reason = robot["reason"].as_str().unwrap();
    assert!(
        reason.contains("refusing to report the key as committed"),
        "{reason}"
    );
    assert_ne!(codes[1], 0, "{controller}");
    for r in [&robot, &controller] {
        assert!(r["post"]["keys"].as_array().unwrap().is_empty(), "{r}");
    }
    let store = s(&dir.join("robot"));
    let (code, text) = run_code(&["keys", "list", "--store", &store, "--pairing", &pairing]);
    assert_eq!(code, 1, "{text}");
    assert!(text.contains("does not verify"), "{text}");
}

/// A pairing file others may read is refused (exit 2, naming the mode and the fix) unless
/// `--insecure-pairing-file`; links at the store's lock or journal are refused and their
/// targets kept; a pre-made store others can write is refused; `keys get` names a
/// 5,000-character ID briefly.
#[test]
fn open_pairing_files_planted_links_and_open_stores_are_refused() {
    use std::os::unix::fs::PermissionsExt as _;
    let dir = scratch("store-files");
    let pairing = pairing(&dir);
    let robot = |store: &Path, extra: &[&str]| {
        let mut args = vec![
            "robot",
            "--listen",
            "127.0.0.1:0",
            "--wait",
            "0.05",
            "--pairing",
            &pairing,
        ];
        let store = s(store);
        args.extend(["--store", &store]);
        args.extend(extra);
        run_code(&args)
    };
    std::fs::set_permissions(&pairing, std::fs::Permissions::from_mode(0o644)).unwrap();
    let (code, text) = robot(&dir.join("store"), &[]);
    assert_eq!(code, 2, "{text}");
    assert!(
        text.contains("mode 644") && text.contains("chmod 600"),
        "{text}"
    );
    assert!(text.contains("--insecure-pairing-file"), "{text}");
    let (code, text) = robot(&dir.join("store"), &["--insecure-pairing-file"]);
    assert_eq!(code, 3, "runs, and no controller comes: {text}");
    assert!(text.contains("warning"), "{text}");
    std::fs::set_permissions(&pairing, std::fs::Permissions::from_mode(0o600)).unwrap();
    let victim = dir.join("victim");
    for name in ["lock", "journal"] {
        std::fs::write(&victim, b"precious").unwrap();
        let store = dir.join(format!("links-{name}"));
        std::fs::create_dir(&store).unwrap();
        std::os::unix::fs::symlink(&victim, store.join(name)).unwrap();
        let (code, text) = robot(&store, &[]);
        assert_eq!(code, 2, "{name}: {text}");
        assert!(text.contains("symbolic link"), "{name}: {text}");
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious", "{name}");
    }
    let open = dir.join("open");
    std::fs::create_dir(&open).unwrap();
    std::fs::set_permissions(&open, std::fs::Permissions::from_mode(0o777)).unwrap();
    let (code, text) = robot(&open, &[]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("mode 777"), "{text}");
    // A store that works, for `keys`.
    let store = dir.join("store");
    let long = "a".repeat(5000);
    let (code, text) = run_code(&[
        "keys",
        "get",
        "--store",
        &s(&store),
        "--pairing",
        &pairing,
        &long,
    ]);
    assert_eq!(code, 2, "{text}");
    assert!(
        text.contains("(5000 characters)") && text.len() < 300,
        "{text}"
    );
    let other = dir.join("other");
    std::fs::create_dir(&other).unwrap();
    let other = run(&["pair", "--out", &s(&other)]);
    assert!(other.0);
    let (code, text) = run_code(&[
        "keys",
        "list",
        "--store",
        &s(&store),
        "--pairing",
        &s(&dir.join("other/pairing.key")),
    ]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("belongs to the pairing"), "{text}");
}

/// The rollback: both journals restored from a copy taken before a key was made. The
/// sessions the key came from are back in both pools, and are dropped there (a stored key
/// lists them), so the next session makes no second key from them.
#[test]
fn journals_restored_from_an_older_copy_never_make_a_second_key_from_spent_bits() {
    let dir = scratch("store-rollback");
    let pairing = pairing(&dir);
    let journal = |role: &str| dir.join(role).join("journal");
    session(&dir, &pairing, 100, Attack::None);
    let copies = ["robot", "controller"].map(|role| std::fs::read(journal(role)).unwrap());
    let (codes, [_, controller]) = session(&dir, &pairing, 101, Attack::None);
    assert_eq!(codes, [0, 0]);
    assert_eq!(controller["post"]["keys"].as_array().unwrap().len(), 1);
    let made = listed(&dir, &pairing, "controller");
    let sources = made[0]["sessions"].clone();
    for (role, copy) in ["robot", "controller"].iter().zip(&copies) {
        std::fs::write(journal(role), copy).unwrap();
    }
    let (codes, reports) = session(&dir, &pairing, 102, Attack::None);
    assert_eq!(codes, [0, 0]);
    for r in &reports {
        assert_eq!(r["post"]["sessions_already_spent"], 1, "{r}");
        assert!(r["post"]["keys"].as_array().unwrap().is_empty(), "{r}");
    }
    for role in ["robot", "controller"] {
        let keys = listed(&dir, &pairing, role);
        assert_eq!(keys.len(), 1, "{role}: a second key");
        assert_eq!(keys[0]["sessions"], sources);
    }
}

/// The final key a robokey key ID names: the hex digits around its version and variant.
fn final_key_of(key_id: &str) -> String {
    let hex: String = key_id.chars().filter(|c| *c != '-').collect();
    format!("{}{}{}", &hex[..12], &hex[13..16], &hex[17..18])
}

/// Key servers beside the running agents: an application fetches 128-bit keys from the
/// controller side's `robokey kme` as fast as it can while the agents pool sessions, make,
/// settle and compact (an agent and a server on one store); a key left pending by lost
/// `Commit`s is never delivered on either side until the next session settles it; the robot
/// side's server then gives every key by its ID with the same bits, once; both stores verify.
#[test]
fn key_servers_beside_the_agents_deliver_only_settled_keys_the_same_by_id() {
    if !have_curl() {
        return;
    }
    let dir = scratch("store-kme");
    let pairing = pairing(&dir);
    let pki = Pki::new(&dir);
    assert_eq!(session(&dir, &pairing, 110, Attack::None).0, [0, 0]);
    let (controller, robot) = start_pair(&pki, &dir, &pairing);
    let (master, slave) = (&controller.url, &robot.url);
    let enc = format!("{master}/api/v1/keys/{ROBOT_SAE}/enc_keys?size=128");
    let dec = format!("{slave}/api/v1/keys/{CONTROLLER_SAE}/dec_keys");
    let fetch_all = |into: &mut Vec<serde_json::Value>| -> serde_json::Value {
        loop {
            let got = curl(&pki, Some(&pki.controller_app), "GET", &enc, None);
            match got.status {
                200 => into.extend(got.json()["keys"].as_array().unwrap().clone()),
                503 => return got.json(),
                _ => panic!("{got:?}"),
            }
        }
    };
    let stop = Arc::new(AtomicBool::new(false));
    let application = std::thread::spawn({
        let (pki, enc, stop) = (Pki::clone(&pki), enc.clone(), Arc::clone(&stop));
        move || {
            let mut keys = Vec::new();
            for _ in 0..2000 {
                if stop.load(Ordering::SeqCst) {
                    break;
                }
                let got = curl(&pki, Some(&pki.controller_app), "GET", &enc, None);
                match got.status {
                    200 => keys.extend(got.json()["keys"].as_array().unwrap().clone()),
                    503 => std::thread::sleep(Duration::from_millis(20)),
                    _ => panic!("{got:?}"),
                }
            }
            keys
        }
    });
    for seed in 111..115 {
        assert_eq!(session(&dir, &pairing, seed, Attack::None).0, [0, 0]);
    }
    let (codes, _) = session(&dir, &pairing, 115, Attack::DropCommit);
    assert_eq!(codes, [5, 5]);
    stop.store(true, Ordering::SeqCst);
    let mut delivered = application.join().unwrap();
    assert!(!delivered.is_empty(), "no key while the agents ran");
    let none = fetch_all(&mut delivered);
    assert!(
        none["message"].as_str().unwrap().contains("pending"),
        "{none}"
    );
    let pending: Vec<String> = statuses(&dir, &pairing, "controller")
        .into_iter()
        .filter(|(_, status)| status == "pending")
        .map(|(id, _)| id)
        .collect();
    assert_eq!(pending.len(), 1);
    let ids: Vec<String> = delivered
        .iter()
        .map(|k| k["key_ID"].as_str().unwrap().to_owned())
        .collect();
    assert!(
        ids.iter().all(|id| final_key_of(id) != pending[0]),
        "a pending key was delivered"
    );
    let hex: String = pending[0].clone();
    let into_pending = format!(
        "{}-{}-8{}-8{}00-000000000080",
        &hex[..8],
        &hex[8..12],
        &hex[12..15],
        &hex[15..]
    );
    assert_eq!(final_key_of(&into_pending), pending[0]);
    let withheld = curl(
        &pki,
        Some(&pki.robot_app),
        "GET",
        &format!("{dec}?key_ID={into_pending}"),
        None,
    );
    assert_eq!(withheld.status, 503, "{withheld:?}");
    // The next session settles it: its keys are delivered now.
    let (codes, _) = session(&dir, &pairing, 116, Attack::None);
    assert!(codes.iter().all(|&c| c == 0 || c == 5), "{codes:?}");
    let before = delivered.len();
    fetch_all(&mut delivered);
    assert!(
        delivered[before..]
            .iter()
            .any(|k| final_key_of(k["key_ID"].as_str().unwrap()) == pending[0])
    );
    // The robot side gives every key by its ID, the same bits, once.
    for batch in delivered.chunks(100) {
        let asked: Vec<serde_json::Value> = batch
            .iter()
            .map(|k| serde_json::json!({"key_ID": k["key_ID"]}))
            .collect();
        let body = serde_json::json!({"key_IDs": asked}).to_string();
        let got = curl(&pki, Some(&pki.robot_app), "POST", &dec, Some(&body));
        assert_eq!(got.status, 200, "{got:?}");
        assert_eq!(got.json()["keys"].as_array().unwrap(), batch);
        let again = curl(&pki, Some(&pki.robot_app), "POST", &dec, Some(&body));
        assert_eq!(again.status, 400, "{again:?}");
    }
    for role in ["robot", "controller"] {
        let (code, text) = run_code(&[
            "keys",
            "list",
            "--store",
            &s(&dir.join(role)),
            "--pairing",
            &pairing,
        ]);
        assert_eq!(code, 0, "{role}: {text}");
    }
}
