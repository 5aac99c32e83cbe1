//! Keys delivered to applications (docs/keys.md): `robokey kme` on both sides' stores over
//! loopback with certificates made for the test, fetched with curl as an ETSI GS QKD 014
//! application would; `robokey keys take` on both sides. The same keys by ID on both sides,
//! each once; never a pending key; a wrong client certificate refused; malformed requests
//! answered with the standard's errors while the server keeps serving.

mod common;

use std::io::{Read as _, Write as _};
use std::path::{Path, PathBuf};

use common::kme::{CONTROLLER_SAE, Kme, Pki, ROBOT_SAE, curl, have_curl, start_pair};
use common::{pairing, run_code, s, scratch};
use robokey_net::key_store::{KeyLabels, KeyStatus, StoredKey};
use robokey_net::post_store::{PostStore, open_keys};
use robokey_secrecy::BitString;
use robokey_secrecy::postprocess::{ControllerSnapshot, FinalKey, RobotSnapshot};

/// The final keys of both stores: 2,048 bits settled, 1,024 bits pending.
const SETTLED: &str = "5e771ed0000000aa";
const PENDING: &str = "9e9d1e9000000bbb";
/// The first 256 bits of the pending key: the ID a controller side would give them.
const INTO_PENDING: &str = "9e9d1e90-0000-80bb-8b00-000000000100";

/// A final key of `bits` bits whose byte `i` is `i ^ seed`.
fn final_key(id: &str, bits: usize, seed: u8) -> FinalKey {
    let bools: Vec<bool> = (0..bits)
        .map(|i| ((i / 8) as u8 ^ seed) & (0x80 >> (i % 8)) != 0)
        .collect();
    FinalKey {
        id: id.into(),
        block: u64::from(seed),
        key: BitString::from_bools(&bools),
        sessions: vec![u32::from(seed)],
        epsilon: 4e-6,
        assumption: "stated for the test".into(),
        reconciliation: None,
    }
}

/// Both agents' stores under `dir`, as their agents leave them: the same settled key and the
/// same pending key in each.
fn stores(dir: &Path, pairing: &str) -> (PathBuf, PathBuf) {
    let (secret, _) = robokey_net::pairing::read_pairing(Path::new(pairing), false).unwrap();
    let (controller, robot) = (dir.join("controller"), dir.join("robot"));
    drop(
        PostStore::<ControllerSnapshot>::open(&controller, &secret, KeyLabels::default()).unwrap(),
    );
    drop(PostStore::<RobotSnapshot>::open(&robot, &secret, KeyLabels::default()).unwrap());
    for (store, role) in [(&controller, "controller"), (&robot, "robot")] {
        let keys = open_keys(store, &secret).unwrap();
        for (key, status) in [
            (final_key(SETTLED, 2048, 0x5a), KeyStatus::Settled),
            (
                final_key(PENDING, 1024, 0x33),
                KeyStatus::Pending("awaiting the peer's acknowledgement".into()),
            ),
        ] {
            keys.store(&StoredKey::new(&key, role, &KeyLabels::default(), status))
                .unwrap();
        }
    }
    (controller, robot)
}

/// Both sides' servers on the stores of a scratch folder named `name`, with certificates made
/// for it: (the certificates, the controller side's server, the robot side's); `None`, said,
/// where curl is missing.
fn served_pair(name: &str) -> Option<(Pki, Kme, Kme)> {
    if !have_curl() {
        return None;
    }
    let dir = scratch(name);
    let pki = Pki::new(&dir);
    let pairing = pairing(&dir);
    stores(&dir, &pairing);
    let (controller, robot) = start_pair(&pki, &dir, &pairing);
    Some((pki, controller, robot))
}

fn key_ids(json: &serde_json::Value) -> Vec<String> {
    json["keys"]
        .as_array()
        .unwrap()
        .iter()
        .map(|k| k["key_ID"].as_str().unwrap().to_owned())
        .collect()
}

/// The issue's test: both sides' servers, keys of 256 bits from the controller side and the
/// same keys by ID from the robot side, equal; a taken key not delivered again; a wrong
/// client certificate refused; a pending key never delivered.
#[test]
fn both_sides_deliver_the_same_keys_by_id_once_to_their_applications_only() {
    let Some((pki, controller, robot)) = served_pair("kme-pair") else {
        return;
    };
    let (master, slave) = (&controller.url, &robot.url);
    let me = Some(&pki.controller_app);
    let it = Some(&pki.robot_app);

    let status_url = format!("{master}/api/v1/keys/{ROBOT_SAE}/status");
    let status = curl(&pki, me, "GET", &status_url, None);
    assert_eq!(status.status, 200, "{status:?}");
    let status = status.json();
    // 2,048 settled bits: 8 keys of 256 bits now; 4 more once the pending key settles.
    assert_eq!(
        (&status["stored_key_count"], &status["max_key_count"]),
        (&8.into(), &12.into())
    );
    assert_eq!(status["master_SAE_ID"], CONTROLLER_SAE);
    assert_eq!(status["slave_SAE_ID"], ROBOT_SAE);

    let enc = format!("{master}/api/v1/keys/{ROBOT_SAE}/enc_keys");
    let dec = format!("{slave}/api/v1/keys/{CONTROLLER_SAE}/dec_keys");
    let got = curl(
        &pki,
        me,
        "POST",
        &enc,
        Some(r#"{"number": 3, "size": 256}"#),
    );
    assert_eq!(got.status, 200, "{got:?}");
    let sent = got.json();
    let ids = key_ids(&sent);
    assert_eq!(ids.len(), 3);
    let one = curl(&pki, it, "GET", &format!("{dec}?key_ID={}", ids[0]), None);
    assert_eq!(one.status, 200, "{one:?}");
    let body = serde_json::json!({"key_IDs": [{"key_ID": ids[2]}, {"key_ID": ids[1]}]});
    let two = curl(&pki, it, "POST", &dec, Some(&body.to_string()));
    assert_eq!(two.status, 200, "{two:?}");
    let (one, two) = (one.json(), two.json());
    assert_eq!(one["keys"][0], sent["keys"][0]);
    assert_eq!(
        (&two["keys"][0], &two["keys"][1]),
        (&sent["keys"][2], &sent["keys"][1])
    );
    for key in sent["keys"].as_array().unwrap() {
        let bytes = key["key"].as_str().unwrap();
        assert_eq!(bytes.len(), 44, "256 bits in base64: {key}");
        assert!(
            key["key_ID"]
                .as_str()
                .unwrap()
                .starts_with("5e771ed0-0000-800a-8a")
        );
    }

    // Taken: not delivered again, on either side.
    let again = curl(&pki, it, "GET", &format!("{dec}?key_ID={}", ids[0]), None);
    again.assert_error(400, "delivered already");
    let rest = curl(&pki, me, "GET", &format!("{enc}?number=5&size=256"), None);
    assert_eq!(rest.status, 200, "{rest:?}");
    assert!(key_ids(&rest.json()).iter().all(|id| !ids.contains(id)));

    // The settled key is used up; the pending one is never delivered, on either side.
    curl(&pki, me, "GET", &enc, None).assert_error(503, "pending");
    let pending = format!("{dec}?key_ID={INTO_PENDING}");
    curl(&pki, it, "GET", &pending, None).assert_error(503, "pending");

    // A wrong client certificate: another CA's fails the handshake, none too; the right
    // CA's for another application is unauthorised; the other side's application too.
    for client in [Some(&pki.rogue_app), None] {
        let refused = curl(&pki, client, "GET", &enc, None);
        assert_ne!(refused.exit, 0, "{refused:?}");
        assert_eq!(refused.status, 0, "no HTTP answer: {refused:?}");
    }
    for client in [&pki.other_app, &pki.robot_app] {
        let refused = curl(&pki, Some(client), "GET", &status_url, None);
        assert_eq!(refused.status, 401, "{refused:?}");
    }

    // Each server logs a line per connection — the SAE, the request, the status, the IDs —
    // and never a key.
    let logged = |kme: &Kme, what: &str| {
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
        loop {
            let log = kme.log.lock().unwrap().clone();
            if log.contains(what) || std::time::Instant::now() > deadline {
                return log;
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
    };
    let master_log = logged(&controller, "SAE robot-app: GET");
    let slave_log = logged(&robot, "→ 503");
    assert!(
        master_log.contains(&format!(
            "SAE controller-app: POST /api/v1/keys/robot-app/enc_keys → 200, keys {} {} {}",
            ids[0], ids[1], ids[2]
        )),
        "{master_log}"
    );
    assert!(master_log.contains("TLS handshake failed"), "{master_log}");
    assert!(
        master_log.contains("SAE eve-app: GET /api/v1/keys/robot-app/status → 401"),
        "{master_log}"
    );
    assert!(
        slave_log.contains(&format!(
            "SAE robot-app: GET /api/v1/keys/controller-app/dec_keys?key_ID={} → 200",
            ids[0]
        )),
        "{slave_log}"
    );
    let rest = rest.json();
    let keys = sent["keys"].as_array().unwrap().iter();
    let keys = keys.chain(rest["keys"].as_array().unwrap());
    for key in keys {
        let key = key["key"].as_str().unwrap();
        assert!(
            !master_log.contains(key) && !slave_log.contains(key),
            "{key} in a log"
        );
    }
}

/// Requests no application should send get the standard's errors (400), bytes that are not
/// TLS or not HTTP end the connection, and the server goes on serving.
#[test]
fn malformed_requests_are_answered_and_the_server_goes_on() {
    let Some((pki, controller, _robot)) = served_pair("kme-malformed") else {
        return;
    };
    let master = &controller.url;
    let me = Some(&pki.controller_app);
    let enc = format!("{master}/api/v1/keys/{ROBOT_SAE}/enc_keys");
    let huge = format!("{{\"number\": 1, \"pad\": \"{}\"}}", "x".repeat(70_000));
    for (method, url, body, says) in [
        ("POST", enc.clone(), Some("{\"number\": 1,"), "JSON body"),
        ("POST", enc.clone(), Some("{\"number\": 1e9}"), "JSON body"),
        ("POST", enc.clone(), Some(huge.as_str()), "exceeds 65536"),
        ("BREW", enc.clone(), None, "not allowed"),
        ("GET", format!("{enc}?size=12"), None, "multiples of 8"),
        (
            "GET",
            format!("{master}/../../etc/passwd"),
            None,
            "no such resource",
        ),
        (
            "GET",
            format!("{master}/api/v1/keys/{ROBOT_SAE}/dec_keys?key_ID=x"),
            None,
            "controller side",
        ),
    ] {
        curl(&pki, me, method, &url, body).assert_error(400, says);
    }
    // Plain bytes on the TLS port: the handshake fails, the connection ends.
    let address = master.trim_start_matches("https://");
    for garbage in [
        &b"GET / HTTP/1.1\r\n\r\n"[..],
        &[0x16, 0x03, 0x01, 0xff, 0xff, 0x01][..],
        &[0_u8; 4096][..],
    ] {
        let mut socket = std::net::TcpStream::connect(address).unwrap();
        socket
            .set_read_timeout(Some(std::time::Duration::from_secs(15)))
            .unwrap();
        let _ = socket.write_all(garbage);
        let mut answer = Vec::new();
        let _ = socket.read_to_end(&mut answer);
        assert!(!answer.starts_with(b"HTTP"), "{answer:?}");
    }
    // Nothing was taken, and the server still serves.
    let status_url = format!("{master}/api/v1/keys/{ROBOT_SAE}/status");
    let status = curl(&pki, me, "GET", &status_url, None);
    assert_eq!(status.status, 200, "{status:?}");
    assert_eq!(status.json()["stored_key_count"], 8);
    assert_eq!(curl(&pki, me, "GET", &enc, None).status, 200);
}

/// `robokey keys take`: the controller's store cuts a new key and prints its ID and the key;
/// the robot's store gives the same key by that ID, once; each refuses the other's way; a
/// pending key is withheld (exit 5), none left is exit 3; `keys list` shows what is taken;
/// `keys get` refuses a final key something was taken from.
#[test]
fn keys_take_gives_the_same_key_on_both_sides_once() {
    let dir = scratch("keys-take");
    let pairing = pairing(&dir);
    let (controller, robot) = stores(&dir, &pairing);
    let take = |store: &Path, extra: &[&str]| {
        let store = s(store);
        let mut args = vec!["keys", "take", "--store", &store, "--pairing", &pairing];
        args.extend(extra);
        run_code(&args)
    };
    let (code, text) = take(&controller, &["--format", "base64"]);
    assert_eq!(code, 0, "{text}");
    let lines: Vec<&str> = text.lines().collect();
    let (id, key) = (lines[0], lines[1]);
    assert_eq!(key.len(), 44, "{text}");
    let (code, theirs) = take(&robot, &["--id", id, "--format", "base64"]);
    assert_eq!(code, 0, "{theirs}");
    assert_eq!(theirs, text);
    let (code, again) = take(&robot, &["--id", id]);
    assert_eq!(code, 2, "{again}");
    assert!(again.contains("delivered already"), "{again}");
    // Hex and raw give the same bits in other clothes.
    let (code, hex) = take(&controller, &["--bits", "512"]);
    assert_eq!(code, 0, "{hex}");
    let hex_id = hex.lines().next().unwrap().to_owned();
    let raw_file = dir.join("raw");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_robokey"))
        .args([
            "keys",
            "take",
            "--store",
            &s(&robot),
            "--pairing",
            &pairing,
            "--id",
            &hex_id,
            "--format",
            "raw",
        ])
        .stdout(std::fs::File::create(&raw_file).unwrap())
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    assert_eq!(String::from_utf8_lossy(&out.stderr).trim(), hex_id);
    let raw = std::fs::read(&raw_file).unwrap();
    assert_eq!(raw.len(), 64);
    let hex_key = hex.lines().nth(1).unwrap();
    let raw_hex: String = raw.iter().map(|b| format!("{b:02x}")).collect();
    assert_eq!(raw_hex, hex_key);
    // Each side refuses the other's way.
    let (code, text) = take(&controller, &["--id", id]);
    assert!(code == 2 && text.contains("drop --id"), "{text}");
    let (code, text) = take(&robot, &[]);
    assert!(code == 2 && text.contains("pass --id"), "{text}");
    let (code, text) = take(&robot, &["--id", &hex_id, "--bits", "256"]);
    assert!(code == 2 && text.contains("has 512 bits"), "{text}");
    // 2,048 − 256 − 512 bits settled are left: five keys of 256 bits, then none (exit 3,
    // naming the pending key's bits to come).
    for _ in 0..5 {
        assert_eq!(take(&controller, &[]).0, 0);
    }
    let (code, text) = take(&controller, &[]);
    assert_eq!(code, 3, "{text}");
    assert!(
        text.contains("4 more once the pending ones settle"),
        "{text}"
    );
    let (code, text) = take(&robot, &["--id", INTO_PENDING]);
    assert_eq!(code, 5, "{text}");
    // The list says what was taken, by ID, and what is left.
    let (code, text) = run_code(&[
        "keys",
        "list",
        "--json",
        "--store",
        &s(&robot),
        "--pairing",
        &pairing,
    ]);
    assert_eq!(code, 0, "{text}");
    let listed: serde_json::Value = serde_json::from_str(&text).unwrap();
    let settled = &listed
        .as_array()
        .unwrap()
        .iter()
        .find(|k| k["id"] == SETTLED)
        .unwrap();
    assert_eq!(settled["taken"], serde_json::json!([id, hex_id]));
    assert_eq!(
        (&settled["taken_bits"], &settled["available_bits"]),
        (&768.into(), &1280.into())
    );
    let pending = listed
        .as_array()
        .unwrap()
        .iter()
        .find(|k| k["id"] == PENDING)
        .unwrap();
    assert_eq!(
        (&pending["status"], &pending["available_bits"]),
        (&"pending".into(), &0.into())
    );
    let (code, text) = run_code(&[
        "keys",
        "get",
        "--store",
        &s(&robot),
        "--pairing",
        &pairing,
        SETTLED,
    ]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("were taken"), "{text}");
}

/// The WireGuard recipe's hand-over (`contrib/wireguard/robokey-wg-psk`): the controller side
/// sets a 256-bit preshared key and prints its ID, the robot side sets the same key by that
/// ID; a rotation gives a new key; an ID is good once. No WireGuard device can be made on this
/// test's machine (its kernel has no wireguard module), so `wg` is a stand-in that records
/// what `wg set` would get: the interface, the peer, the key file's mode and the key.
#[test]
fn wireguard_preshared_keys_are_handed_over_by_id() {
    let dir = scratch("wireguard");
    let pairing = pairing(&dir);
    let (controller, robot) = stores(&dir, &pairing);
    let wg = dir.join("wg");
    std::fs::write(
        &wg,
        "#!/bin/sh\n[ \"$1 $3 $5\" = 'set peer preshared-key' ] || exit 9\n\
         printf '%s %s %s %s %s\\n' \"$2\" \"$4\" \"$(stat -c %a \"$6\")\" \"$(cat \"$6\")\" \"$6\" >> \"$WG_LOG\"\n",
    )
    .unwrap();
    use std::os::unix::fs::PermissionsExt as _;
    std::fs::set_permissions(&wg, std::fs::Permissions::from_mode(0o700)).unwrap();
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../contrib/wireguard/robokey-wg-psk"
    );
    let log = dir.join("wg.log");
    let rotate = |args: &[&str]| {
        let out = std::process::Command::new("bash")
            .arg(script)
            .args(args)
            .env("ROBOKEY", env!("CARGO_BIN_EXE_robokey"))
            .env("WG", &wg)
            .env("WG_LOG", &log)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout).trim().to_owned();
        (
            out.status.code().unwrap_or(-1),
            text + &String::from_utf8_lossy(&out.stderr),
        )
    };
    let (controller, robot) = (s(&controller), s(&robot));
    let robot_public = "RobotPublicKeyRobotPublicKeyRobotPublicKey0=";
    let controller_public = "ControllerPublicKeyControllerPublicKeyCont=";
    let mut ids = Vec::new();
    for _ in 0..2 {
        let (code, id) = rotate(&["controller", "wg0", robot_public, &controller, &pairing]);
        assert_eq!(code, 0, "{id}");
        let (code, same) = rotate(&["robot", "wg1", controller_public, &robot, &pairing, &id]);
        assert_eq!((code, &same), (0, &id));
        ids.push(id);
    }
    assert_ne!(ids[0], ids[1]);
    let text = std::fs::read_to_string(&log).unwrap();
    let calls: Vec<Vec<&str>> = text.lines().map(|l| l.split(' ').collect()).collect();
    assert_eq!(calls.len(), 4, "{text}");
    for pair in calls.chunks(2) {
        let (theirs, ours) = (&pair[0], &pair[1]);
        assert_eq!(theirs[..3], ["wg0", robot_public, "600"]);
        assert_eq!(ours[..3], ["wg1", controller_public, "600"]);
        assert_eq!(theirs[3], ours[3], "the same preshared key on both ends");
        let key = <base64ct::Base64 as base64ct::Encoding>::decode_vec(theirs[3]).unwrap();
        assert_eq!(key.len(), 32, "{}", theirs[3]);
        assert!(!Path::new(theirs[4]).exists(), "the key file is removed");
    }
    assert_ne!(calls[0][3], calls[2][3], "a rotation brings a new key");
    // An ID is good once: the robot side refuses it again and calls no `wg`.
    let (code, text) = rotate(&["robot", "wg1", controller_public, &robot, &pairing, &ids[0]]);
    assert_ne!(code, 0, "{text}");
    assert!(text.contains("delivered already"), "{text}");
    let (code, _) = rotate(&["robot", "wg1", controller_public, &robot, &pairing]);
    assert_eq!(code, 2);
    assert_eq!(std::fs::read_to_string(&log).unwrap().lines().count(), 4);
}
