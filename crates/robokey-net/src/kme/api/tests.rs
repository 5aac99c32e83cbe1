//! The ETSI API on real stores, request by request (the server and an HTTP client that is not
//! robokey code are tested in crates/robokey-cli/tests/kme.rs).

use robokey_secrecy::postprocess::{ControllerSnapshot, RobotSnapshot};
use serde_json::json;

use super::*;
use crate::key_delivery::tests::{expected, final_key, store_with};

fn identity(side: Side) -> KmeIdentity {
    let (sae, peer_sae) = match side {
        Side::Controller => ("ctl-app", "bot-app"),
        Side::Robot => ("bot-app", "ctl-app"),
    };
    KmeIdentity {
        sae: sae.into(),
        peer_sae: peer_sae.into(),
        kme: format!("robokey-{}", side.name()),
        peer_kme: format!("robokey-{}", side.peer().name()),
    }
}

/// Both sides' APIs over stores holding a settled 1,024-bit and a pending 2,048-bit key.
fn apis(name: &str) -> (KeyApi, KeyApi) {
    let keys = [
        (final_key(0, 1024, 11), true),
        (final_key(1, 2048, 77), false),
    ];
    let (_, controller) = store_with::<ControllerSnapshot>(&format!("{name}-c"), &keys);
    let (_, robot) = store_with::<RobotSnapshot>(&format!("{name}-r"), &keys);
    (
        KeyApi::new(controller, identity(Side::Controller)),
        KeyApi::new(robot, identity(Side::Robot)),
    )
}

fn ask(api: &KeyApi, method: &str, target: &str, body: &str) -> (u16, serde_json::Value) {
    let sae = api.identity().sae.clone();
    ask_as(api, Some(&sae), method, target, body)
}

fn ask_as(
    api: &KeyApi,
    client: Option<&str>,
    method: &str,
    target: &str,
    body: &str,
) -> (u16, serde_json::Value) {
    let answer = api.answer(
        &Request {
            method: method.into(),
            target: target.into(),
            body: body.as_bytes().to_vec(),
        },
        client,
    );
    let json = serde_json::from_slice(&answer.response.body).unwrap();
    assert_eq!(answer.error.is_some(), answer.response.status != 200);
    (answer.response.status, json)
}

fn key_bytes(entry: &serde_json::Value) -> Vec<u8> {
    <base64ct::Base64 as base64ct::Encoding>::decode_vec(entry["key"].as_str().unwrap())
        .unwrap_or_else(|_| panic!("{entry}"))
}

#[test]
fn status_names_both_sides_and_counts_keys_of_the_default_size() {
    let (controller, robot) = apis("api-status");
    let (code, status) = ask(&controller, "GET", "/api/v1/keys/bot-app/status", "");
    assert_eq!(code, 200, "{status}");
    assert_eq!(
        status,
        json!({
            "source_KME_ID": "robokey-controller",
            "target_KME_ID": "robokey-robot",
            "master_SAE_ID": "ctl-app",
            "slave_SAE_ID": "bot-app",
            "key_size": 256,
            "stored_key_count": 4,
            "max_key_count": 12,
            "max_key_per_request": 128,
            "max_key_size": 8192,
            "min_key_size": 64,
            "max_SAE_ID_count": 0
        })
    );
    let (code, status) = ask(&robot, "GET", "/api/v1/keys/ctl-app/status", "");
    assert_eq!(code, 200, "{status}");
    assert_eq!(
        (&status["master_SAE_ID"], &status["slave_SAE_ID"]),
        (&json!("ctl-app"), &json!("bot-app"))
    );
}

/// Keys fetched from the controller side by GET and POST come back from the robot side by
/// their IDs, by GET and POST, with the same bytes; never twice.
#[test]
fn enc_keys_then_dec_keys_give_the_same_keys_once() {
    let (controller, robot) = apis("api-keys");
    let (code, first) = ask(
        &controller,
        "GET",
        "/api/v1/keys/bot-app/enc_keys?number=2&size=128",
        "",
    );
    assert_eq!(code, 200, "{first}");
    let (code, second) = ask(
        &controller,
        "POST",
        "/api/v1/keys/bot-app/enc_keys",
        r#"{"number": 1, "size": 512, "extension_optional": [{"x": 1}]}"#,
    );
    assert_eq!(code, 200, "{second}");
    let keys: Vec<&serde_json::Value> = first["keys"]
        .as_array()
        .unwrap()
        .iter()
        .chain(second["keys"].as_array().unwrap())
        .collect();
    assert_eq!(keys.len(), 3);
    assert_eq!(key_bytes(keys[0]), expected(11, 0..16));
    assert_eq!(key_bytes(keys[1]), expected(11, 16..32));
    assert_eq!(key_bytes(keys[2]), expected(11, 32..96));
    let id = |i: usize| keys[i]["key_ID"].as_str().unwrap().to_owned();
    let (code, one) = ask(
        &robot,
        "GET",
        &format!("/api/v1/keys/ctl-app/dec_keys?key_ID={}", id(1)),
        "",
    );
    assert_eq!(code, 200, "{one}");
    assert_eq!(one["keys"][0], *keys[1]);
    let body = json!({"key_IDs": [{"key_ID": id(2)}, {"key_ID": id(0), "key_ID_extension": {}}]});
    let ask_both = || {
        ask(
            &robot,
            "POST",
            "/api/v1/keys/ctl-app/dec_keys",
            &body.to_string(),
        )
    };
    let (code, two) = ask_both();
    assert_eq!(code, 200, "{two}");
    assert_eq!((&two["keys"][0], &two["keys"][1]), (keys[2], keys[0]));
    let (code, again) = ask_both();
    assert_eq!(code, 400, "{again}");
    assert!(
        again["message"]
            .as_str()
            .unwrap()
            .contains("delivered already"),
        "{again}"
    );
    // 1,024 bits: 128 + 128 + 512 taken, 256 left: one more 256-bit key, then none (503).
    let (code, _) = ask(&controller, "GET", "/api/v1/keys/bot-app/enc_keys", "");
    assert_eq!(code, 200);
    let (code, none) = ask(&controller, "GET", "/api/v1/keys/bot-app/enc_keys", "");
    assert_eq!(code, 503, "{none}");
    assert!(
        none["message"].as_str().unwrap().contains("0 available"),
        "{none}"
    );
}

/// Every way a request can be wrong gets the standard's status and a message naming it.
#[test]
fn bad_requests_get_the_standards_errors() {
    let (controller, robot) = apis("api-errors");
    let pending_id = crate::key_slice::SliceId::new(
        &final_key(1, 0, 0).id,
        crate::key_slice::Span {
            offset: 0,
            bits: 256,
        },
    )
    .unwrap()
    .uuid();
    let cases: Vec<(&KeyApi, &str, String, &str, u16, &str)> = vec![
        (
            &controller,
            "GET",
            "/api/v1/keys/bot-app/stat".into(),
            "",
            400,
            "no such resource",
        ),
        (
            &controller,
            "GET",
            "/api/v2/keys/bot-app/status".into(),
            "",
            400,
            "no such resource",
        ),
        (
            &controller,
            "GET",
            "/api/v1/keys/bot-app/status/x".into(),
            "",
            400,
            "no such resource",
        ),
        (
            &controller,
            "GET",
            "/api/v1/keys/eve-app/status".into(),
            "",
            400,
            "unknown here",
        ),
        (
            &controller,
            "GET",
            "/api/v1/keys/bot-app/status?x=1".into(),
            "",
            400,
            "no query",
        ),
        (
            &controller,
            "DELETE",
            "/api/v1/keys/bot-app/enc_keys".into(),
            "",
            400,
            "not allowed",
        ),
        (
            &controller,
            "POST",
            "/api/v1/keys/bot-app/status".into(),
            "",
            400,
            "not allowed",
        ),
        (
            &controller,
            "GET",
            "/api/v1/keys/bot-app/enc_keys?number=0".into(),
            "",
            400,
            "1 to 128",
        ),
        (
            &controller,
            "GET",
            "/api/v1/keys/bot-app/enc_keys?number=129".into(),
            "",
            400,
            "1 to 128",
        ),
        (
            &controller,
            "GET",
            "/api/v1/keys/bot-app/enc_keys?size=100".into(),
            "",
            400,
            "multiples of 8",
        ),
        (
            &controller,
            "GET",
            "/api/v1/keys/bot-app/enc_keys?size=99999999999".into(),
            "",
            400,
            "multiples of 8",
        ),
        (
            &controller,
            "GET",
            "/api/v1/keys/bot-app/enc_keys?size=x".into(),
            "",
            400,
            "not a whole number",
        ),
        (
            &controller,
            "GET",
            "/api/v1/keys/bot-app/enc_keys?number=1&number=2".into(),
            "",
            400,
            "twice",
        ),
        (
            &controller,
            "GET",
            "/api/v1/keys/bot-app/enc_keys?colour=red".into(),
            "",
            400,
            "unknown query",
        ),
        (
            &controller,
            "POST",
            "/api/v1/keys/bot-app/enc_keys".into(),
            "{\"nuber\": 1}",
            400,
            "nuber",
        ),
        (
            &controller,
            "POST",
            "/api/v1/keys/bot-app/enc_keys".into(),
            "{\"number\": -1}",
            400,
            "JSON body",
        ),
        (
            &controller,
            "POST",
            "/api/v1/keys/bot-app/enc_keys".into(),
            "{\"additional_slave_SAE_IDs\": [\"x\"]}",
            400,
            "one slave",
        ),
        (
            &controller,
            "POST",
            "/api/v1/keys/bot-app/enc_keys".into(),
            "{\"extension_mandatory\": [{\"a\": 1}]}",
            400,
            "no extension",
        ),
        (
            &robot,
            "GET",
            "/api/v1/keys/ctl-app/enc_keys".into(),
            "",
            400,
            "robot side",
        ),
        (
            &robot,
            "GET",
            format!("/api/v1/keys/ctl-app/dec_keys?key_ID={pending_id}"),
            "",
            503,
            "pending",
        ),
        (
            &controller,
            "GET",
            "/api/v1/keys/bot-app/dec_keys?key_ID=x".into(),
            "",
            400,
            "controller side",
        ),
        (
            &robot,
            "GET",
            "/api/v1/keys/ctl-app/dec_keys".into(),
            "",
            400,
            "1 to 128",
        ),
        (
            &robot,
            "GET",
            "/api/v1/keys/ctl-app/dec_keys?key_ID=nope".into(),
            "",
            400,
            "not a UUID",
        ),
        (
            &robot,
            "POST",
            "/api/v1/keys/ctl-app/dec_keys".into(),
            "{\"key_IDs\": []}",
            400,
            "1 to 128",
        ),
        (
            &robot,
            "POST",
            "/api/v1/keys/ctl-app/dec_keys".into(),
            "[1, 2",
            400,
            "JSON body",
        ),
        (
            &robot,
            "POST",
            "/api/v1/keys/ctl-app/dec_keys".into(),
            "{\"key_IDs\": [{\"id\": \"x\"}]}",
            400,
            "unknown field",
        ),
    ];
    for (api, method, target, body, status, says) in &cases {
        let (code, error) = ask(api, method, target, body);
        let message = error["message"].as_str().unwrap();
        assert_eq!(
            (code, message.contains(says)),
            (*status, true),
            "{target}: {message}"
        );
    }
    // A client whose certificate names another SAE, or none, is unauthorised — before
    // anything else is looked at.
    for client in [Some("bot-app"), Some("ctl-app "), None] {
        let (code, error) = ask_as(&controller, client, "GET", "/nowhere", "");
        assert_eq!(code, 401, "{client:?}: {error}");
    }
    // Nothing was taken by any of it.
    let (_, status) = ask(&controller, "GET", "/api/v1/keys/bot-app/status", "");
    assert_eq!(status["stored_key_count"], 4);
}
