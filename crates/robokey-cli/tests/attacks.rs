//! An attacker on the network, against paired agents (docs/threat-model.md): each test is
//! one row of issue 14's attack table, run with real processes over loopback. The attacker
//! uses stock binaries, an on-path relay thread that edits, drops, reflects and injects
//! datagrams, and a socket of its own; it replays **captured authentic frames** as well as
//! forged ones. Every test is bounded in time and stops by itself.

mod common;

use std::net::{SocketAddr, UdpSocket};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use common::{Process, pairing, report, run_code, s, scratch, start, wait_code};
use robokey::protocol::auth::{AuthMode, PairingSecret, seal};
use robokey::protocol::wire::{Frame, MAC_BYTES, decode, encode};
use robokey::protocol::{Closing, FateWindow, Handshake, Message, SessionMessage};

/// A short session: one lap with 6 s sides.
const SHORT: [&str; 4] = [
    "--set",
    "trajectory.laps=1",
    "--set",
    "trajectory.side_time=6",
];

/// Where a datagram goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum To {
    Robot,
    Controller,
}

/// An on-path relay thread between the controller and the robot.
struct Relay {
    address: String,
    thread: JoinHandle<Vec<(To, Vec<u8>)>>,
}

type Tamper = Box<dyn FnMut(To, Vec<u8>) -> Vec<(To, Vec<u8>)> + Send>;

/// Starts a relay towards `robot` that sends what `tamper` makes of each datagram; it
/// records every datagram as heard and stops after 2 s without traffic (or 60 s in all).
fn relay(robot: &str, mut tamper: Tamper) -> Relay {
    let robot: SocketAddr = robot.parse().unwrap();
    let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
    let address = socket.local_addr().unwrap().to_string();
    socket
        .set_read_timeout(Some(Duration::from_millis(100)))
        .unwrap();
    let thread = std::thread::spawn(move || {
        let (start, mut last) = (Instant::now(), Instant::now());
        let mut controller: Option<SocketAddr> = None;
        let mut heard = Vec::new();
        let mut buffer = [0u8; 65_536];
        while start.elapsed() < Duration::from_secs(60) && last.elapsed() < Duration::from_secs(2) {
            let Ok((len, from)) = socket.recv_from(&mut buffer) else {
                continue;
            };
            last = Instant::now();
            let to = if from == robot {
                To::Controller
            } else {
                controller = Some(from);
                To::Robot
            };
            heard.push((to, buffer[..len].to_vec()));
            for (to, bytes) in tamper(to, buffer[..len].to_vec()) {
                let target = match to {
                    To::Robot => Some(robot),
                    To::Controller => controller,
                };
                if let Some(target) = target {
                    let _ = socket.send_to(&bytes, target);
                }
            }
        }
        heard
    });
    Relay { address, thread }
}

/// Forwards everything unchanged.
fn forward() -> Tamper {
    Box::new(|to, bytes| vec![(to, bytes)])
}

/// `frame` encoded with a MAC the attacker can make: all zeros.
fn forged(frame: &Frame) -> Vec<u8> {
    [encode(frame), vec![0; MAC_BYTES]].concat()
}

/// `bytes` with its header and payload replaced by `frame`'s, keeping the original MAC.
fn edited(bytes: &[u8], frame: &Frame) -> Vec<u8> {
    [encode(frame), bytes[bytes.len() - MAC_BYTES..].to_vec()].concat()
}

fn is(bytes: &[u8], pick: fn(&Message) -> bool) -> Option<Frame> {
    decode(bytes).ok().filter(|f| pick(&f.message))
}

/// A paired robot agent in lockstep, writing `robot.json` and `robot.key` into `dir`.
fn robot(dir: &Path, pairing: &str, extra: &[&str]) -> Process {
    let (key, json) = (s(&dir.join("robot.key")), s(&dir.join("robot.json")));
    let mut args = vec![
        "robot",
        "--listen",
        "127.0.0.1:0",
        "--pace",
        "lockstep",
        "--silence-timeout",
        "1",
        "--wait",
        "4",
        "--seed",
        "3",
        "--pairing",
        pairing,
        "--key-out",
        &key,
        "--report",
        &json,
    ];
    args.extend(SHORT);
    args.extend(extra);
    start(&args)
}

/// Runs a paired controller towards `target` to its end, writing `controller.json` and
/// `controller.key` into `dir`; checks its exit code and returns its output.
fn controller(dir: &Path, pairing: &str, target: &str, code: i32) -> String {
    let (key, json) = (
        s(&dir.join("controller.key")),
        s(&dir.join("controller.json")),
    );
    let mut args = vec![
        "controller",
        "--robot",
        target,
        "--pace",
        "lockstep",
        "--silence-timeout",
        "1",
        "--pairing",
        pairing,
        "--key-out",
        &key,
        "--report",
        &json,
    ];
    args.extend(SHORT);
    let (exit, text) = run_code(&args);
    assert_eq!(exit, code, "{text}");
    text
}

/// Waits for a robot and checks its exit code (0 key, 3 no key, 4 authentication failed).
fn wait_robot(robot: Process, code: i32) -> String {
    let (exit, text) = wait_code(robot);
    assert_eq!(exit, code, "{text}");
    text
}

fn reports(dir: &Path) -> (serde_json::Value, serde_json::Value) {
    (
        report(&dir.join("robot.json")),
        report(&dir.join("controller.json")),
    )
}

fn rejected(report: &serde_json::Value, why: &str) -> u64 {
    report["frames_rejected"][why].as_u64().unwrap()
}

/// Both sides confirmed and wrote the same key; every step was applied from a genuine
/// command or erased, never twice.
fn assert_completed(dir: &Path) {
    let (robot, controller) = reports(dir);
    assert_eq!(robot["outcome"], "confirmed", "{robot}");
    assert_eq!(controller["outcome"], "confirmed", "{controller}");
    assert_eq!(
        std::fs::read_to_string(dir.join("robot.key")).unwrap(),
        std::fs::read_to_string(dir.join("controller.key")).unwrap()
    );
    let applied = robot["commands_applied"].as_u64().unwrap();
    let erased = robot["erased_steps"].as_u64().unwrap();
    assert_eq!(
        applied + erased,
        robot["steps"].as_u64().unwrap(),
        "{robot}"
    );
}

/// A clean paired session through a recording relay: its datagrams, as heard.
fn captured_session(dir: &Path, pairing: &str) -> Vec<(To, Vec<u8>)> {
    std::fs::create_dir_all(dir).unwrap();
    let robot = robot(dir, pairing, &[]);
    let relay = relay(&robot.address, forward());
    controller(dir, pairing, &relay.address, 0);
    wait_robot(robot, 0);
    assert_completed(dir);
    relay.thread.join().unwrap()
}

#[test]
fn a_man_in_the_middle_with_stock_binaries_gets_no_session_and_no_key() {
    let dir = scratch("attack-mitm");
    let victim = pairing(&dir.join("victim"));
    let attacker = pairing(&dir.join("attacker"));
    // Towards the robot: stock controllers, unpaired and with another pairing.
    let robot = robot(&dir, &victim, &[]);
    let (code, text) = run_code(&[
        "controller",
        "--robot",
        &robot.address,
        "--unauthenticated",
        "--silence-timeout",
        "1",
    ]);
    // The robot drops the Hello unanswered: to the controller, that is silence (no key).
    assert!(
        code == 3 && text.contains("passive adversary only"),
        "{text}"
    );
    assert!(
        text.contains("aborted: no HelloAck that verifies"),
        "{text}"
    );
    let (code, text) = run_code(&[
        "controller",
        "--robot",
        &robot.address,
        "--pairing",
        &attacker,
        "--silence-timeout",
        "1",
    ]);
    assert!(
        code == 3 && text.contains("aborted: no HelloAck that verifies"),
        "{text}"
    );
    // Towards the controller: a stock robot with the attacker's pairing (it cannot verify
    // the Hello, so it never answers), then a custom one that answers with a HelloAck
    // echoing the controller's nonce, MACed under the key the attacker has.
    let fake = scratch("attack-mitm-fake-robot");
    let fake_robot = self::robot(&fake, &attacker, &[]);
    let text = controller(&dir, &victim, &fake_robot.address, 3);
    assert!(
        text.contains("aborted: no HelloAck that verifies")
            && text.contains("nothing came from it: no robot agent listens there")
            && text.contains("or it holds another pairing secret"),
        "{text}"
    );
    wait_robot(fake_robot, 4);
    assert!(!fake.join("robot.key").exists());
    let answering = UdpSocket::bind("127.0.0.1:0").unwrap();
    let address = answering.local_addr().unwrap().to_string();
    let answerer = std::thread::spawn(move || {
        answering
            .set_read_timeout(Some(Duration::from_millis(1500)))
            .unwrap();
        let mut buffer = [0u8; 8192];
        let mut answered = 0;
        while let Ok((len, from)) = answering.recv_from(&mut buffer) {
            let Ok(Frame {
                session,
                message:
                    Message::Handshake(Handshake::Hello {
                        nonce,
                        config_digest,
                        ..
                    }),
                ..
            }) = decode(&buffer[..len])
            else {
                continue;
            };
            let ack = Message::Handshake(Handshake::HelloAck {
                auth: AuthMode::Paired,
                nonce_c: nonce,
                nonce_r: [9; 16],
                config_digest,
            });
            let frame = Frame {
                session,
                seq: 0,
                message: ack,
            };
            let key = PairingSecret::unauthenticated().handshake_key();
            answering.send_to(&seal(&frame, &key), from).unwrap();
            answered += 1;
        }
        answered
    });
    let text = controller(&dir, &victim, &address, 4);
    assert!(
        text.contains("HelloAck(s) from it failed to verify: it holds another pairing secret"),
        "{text}"
    );
    assert!(answerer.join().unwrap() > 0);
    wait_robot(robot, 4);
    let (robot, controller) = reports(&dir);
    assert_eq!(robot["outcome"], "aborted", "{robot}");
    assert_eq!(robot["commands_applied"], 0);
    assert!(rejected(&robot, "pairing_mode") > 0 && rejected(&robot, "handshake_bad_mac") > 0);
    assert_eq!(controller["outcome"], "aborted", "{controller}");
    assert!(
        rejected(&controller, "handshake_bad_mac") > 0,
        "{controller}"
    );
    assert!(!dir.join("robot.key").exists() && !dir.join("controller.key").exists());
}

#[test]
fn on_path_edits_of_fates_and_tags_are_dropped_and_no_key_is_confirmed() {
    let dir = scratch("attack-on-path");
    let pairing = pairing(&dir);
    let robot = robot(&dir, &pairing, &[]);
    let mut cleared = false;
    let relay = relay(
        &robot.address,
        Box::new(move |to, bytes| {
            let mut out = bytes.clone();
            if let Some(mut frame) = is(&bytes, |m| {
                matches!(m, Message::Closing(Closing::Confirm { .. }))
            }) {
                // Both sides' tags replaced.
                frame.message = Message::Closing(Closing::Confirm {
                    session_tag: [0xAA; 16],
                    key_tag: [0xBB; 16],
                });
                out = edited(&bytes, &frame);
            } else if let Some(mut frame) = is(
                &bytes,
                |m| matches!(m, Message::Session(SessionMessage::Command { fates, .. }) if fates.accepted != 0),
            ) && !cleared
            {
                // One accepted fate cleared towards the robot.
                if let Message::Session(SessionMessage::Command { fates, .. }) = &mut frame.message
                {
                    fates.accepted = 0;
                }
                out = edited(&bytes, &frame);
                cleared = true;
            }
            vec![(to, out)]
        }),
    );
    controller(&dir, &pairing, &relay.address, 3);
    wait_robot(robot, 3);
    relay.thread.join().unwrap();
    let (robot, controller) = reports(&dir);
    for r in [&robot, &controller] {
        assert_ne!(r["outcome"], "confirmed", "{r}");
        assert!(rejected(r, "bad_mac") > 0, "{r}");
    }
    assert!(!dir.join("robot.key").exists() && !dir.join("controller.key").exists());
}

#[test]
fn an_early_datagram_and_a_replayed_hello_do_not_steer_the_robot() {
    let dir = scratch("attack-early");
    let pairing = pairing(&dir);
    let old = captured_session(&dir.join("old"), &pairing);
    let hello = old
        .iter()
        .find(|(_, b)| {
            is(b, |m| {
                matches!(m, Message::Handshake(Handshake::Hello { .. }))
            })
            .is_some()
        })
        .unwrap();
    let ready = old
        .iter()
        .find(|(_, b)| is(b, |m| *m == Message::Handshake(Handshake::Ready)).is_some())
        .unwrap();
    let robot = robot(&dir, &pairing, &[]);
    let attacker = UdpSocket::bind("127.0.0.1:0").unwrap();
    attacker
        .set_read_timeout(Some(Duration::from_millis(500)))
        .unwrap();
    // A FinishAck for session 0 before any controller, then the old session's authentic
    // Hello and Ready.
    let finish_ack = Frame {
        session: 0,
        seq: 1,
        message: Message::Closing(Closing::FinishAck),
    };
    attacker
        .send_to(&forged(&finish_ack), &robot.address)
        .unwrap();
    attacker.send_to(&hello.1, &robot.address).unwrap();
    let mut answer = [0u8; 2048];
    let (len, _) = attacker
        .recv_from(&mut answer)
        .expect("a replayed Hello is answered");
    assert!(
        is(&answer[..len], |m| matches!(
            m,
            Message::Handshake(Handshake::HelloAck { .. })
        ))
        .is_some()
    );
    attacker.send_to(&ready.1, &robot.address).unwrap();
    std::thread::sleep(Duration::from_millis(100));
    // The real controller still gets the session.
    controller(&dir, &pairing, &robot.address, 0);
    wait_robot(robot, 0);
    assert_completed(&dir);
    let (robot, _) = reports(&dir);
    assert!(rejected(&robot, "other_session") >= 1, "{robot}");
    assert!(rejected(&robot, "bad_mac") >= 1, "{robot}");
}

#[test]
fn a_reflected_confirm_fails_and_the_controller_writes_no_key() {
    let dir = scratch("attack-reflect");
    let pairing = pairing(&dir);
    let robot = robot(&dir, &pairing, &[]);
    let relay = relay(
        &robot.address,
        Box::new(|to, bytes| {
            match (
                to,
                is(&bytes, |m| {
                    matches!(m, Message::Closing(Closing::Confirm { .. }))
                }),
            ) {
                // The robot's tags never reach the controller; its own come back to it.
                (To::Controller, Some(_)) => vec![],
                (To::Robot, Some(_)) => vec![(To::Robot, bytes.clone()), (To::Controller, bytes)],
                _ => vec![(to, bytes)],
            }
        }),
    );
    controller(&dir, &pairing, &relay.address, 3);
    wait_robot(robot, 0);
    relay.thread.join().unwrap();
    let (_, controller) = reports(&dir);
    assert_eq!(controller["outcome"], "unconfirmed", "{controller}");
    assert!(rejected(&controller, "bad_mac") > 0, "{controller}");
    assert!(!dir.join("controller.key").exists());
}

#[test]
fn injected_and_impersonated_commands_are_never_applied_and_the_session_completes() {
    let dir = scratch("attack-inject");
    let pairing = pairing(&dir);
    let robot = robot(&dir, &pairing, &[]);
    let target: SocketAddr = robot.address.parse().unwrap();
    let outsider = UdpSocket::bind("127.0.0.1:0").unwrap();
    let injected = Arc::new(AtomicU64::new(0));
    let counter = Arc::clone(&injected);
    let relay = relay(
        &robot.address,
        Box::new(move |to, bytes| {
            let mut out = vec![(to, bytes.clone())];
            let Some(frame) = is(&bytes, |m| {
                matches!(m, Message::Session(SessionMessage::Command { .. }))
            }) else {
                return out;
            };
            let Message::Session(SessionMessage::Command { step, .. }) = frame.message else {
                unreachable!("matched above")
            };
            // Offers that spin the robot and reveal the bit, for the next step: edited
            // under the genuine MAC, forged, and from the attacker's own address.
            let spin = Frame {
                session: frame.session,
                seq: frame.seq + 1,
                message: Message::Session(SessionMessage::Command {
                    step: step + 1,
                    u0: [5.0, 5.0],
                    u1: [-5.0, -5.0],
                    fates: FateWindow::default(),
                }),
            };
            out.push((To::Robot, edited(&bytes, &spin)));
            out.push((To::Robot, forged(&spin)));
            let _ = outsider.send_to(&bytes, target);
            // The genuine frame again: a replay.
            out.push((To::Robot, bytes.clone()));
            counter.fetch_add(1, Ordering::Relaxed);
            out
        }),
    );
    controller(&dir, &pairing, &relay.address, 0);
    // The robot says so on its console, not only in its report.
    let console = wait_robot(robot, 0);
    assert!(console.contains("datagrams rejected"), "{console}");
    relay.thread.join().unwrap();
    let injected = injected.load(Ordering::Relaxed);
    assert!(injected > 10);
    assert_completed(&dir);
    let (robot, _) = reports(&dir);
    assert!(rejected(&robot, "bad_mac") >= 2 * injected, "{robot}");
    assert!(rejected(&robot, "replayed") >= injected, "{robot}");
    assert!(rejected(&robot, "wrong_peer") >= injected, "{robot}");
}

#[test]
fn an_old_controller_transcript_replayed_to_a_fresh_robot_drives_nothing() {
    let dir = scratch("attack-replay");
    let pairing = pairing(&dir);
    let old = captured_session(&dir.join("old"), &pairing);
    let robot = robot(&dir, &pairing, &[]);
    let attacker = UdpSocket::bind("127.0.0.1:0").unwrap();
    let mut sent = 0;
    for (_, bytes) in old.iter().filter(|(to, _)| *to == To::Robot) {
        attacker.send_to(bytes, &robot.address).unwrap();
        sent += 1;
        std::thread::sleep(Duration::from_millis(1));
    }
    assert!(sent > 50);
    // The old Hello is authentic and answered; its session's frames fail under the fresh
    // keys: no controller bound a session (exit 3), and nobody tried another secret (4).
    wait_robot(robot, 3);
    let r = report(&dir.join("robot.json"));
    assert_eq!(r["outcome"], "aborted", "{r}");
    assert_eq!(r["commands_applied"], 0, "{r}");
    assert!(rejected(&r, "bad_mac") > 0, "{r}");
    assert_eq!(rejected(&r, "handshake_bad_mac"), 0, "{r}");
    assert!(!dir.join("robot.key").exists());
}

#[test]
fn a_forged_abort_bad_finish_wrong_version_hello_and_sequence_poisoning_change_nothing() {
    let dir = scratch("attack-forged");
    let pairing = pairing(&dir);
    let robot = robot(&dir, &pairing, &[]);
    let mut done = false;
    let relay = relay(
        &robot.address,
        Box::new(move |to, bytes| {
            let mut out = vec![(to, bytes.clone())];
            let Some(frame) = is(&bytes, |m| {
                matches!(
                    m,
                    Message::Session(SessionMessage::Command { step: 20, .. })
                )
            }) else {
                return out;
            };
            if std::mem::replace(&mut done, true) {
                return out;
            }
            let at = |seq, message| Frame {
                session: frame.session,
                seq,
                message,
            };
            let abort = at(
                frame.seq + 1,
                Message::Closing(Closing::Abort {
                    reason: "forged".into(),
                }),
            );
            let finish = at(
                frame.seq + 2,
                Message::Closing(Closing::Finish {
                    codewords: 1,
                    bitmap: vec![1],
                }),
            );
            // Sequence poisoning: a number far ahead, which must not move the window.
            let poison = at(u32::MAX - 1, Message::Closing(Closing::FinishAck));
            for bytes in [forged(&abort), forged(&finish), forged(&poison)] {
                out.push((To::Robot, bytes.clone()));
                out.push((To::Controller, bytes));
            }
            // A Hello for this session as version 1 and as version 3.
            let hello = Message::Handshake(Handshake::Hello {
                auth: AuthMode::Paired,
                nonce: [7; 16],
                config_digest: [0; 32],
                terms: String::new(),
            });
            let hello = forged(&at(0, hello));
            for version in [1, 3] {
                let mut bytes = hello.clone();
                bytes[2] = version;
                out.push((To::Robot, bytes));
            }
            out
        }),
    );
    controller(&dir, &pairing, &relay.address, 0);
    wait_robot(robot, 0);
    relay.thread.join().unwrap();
    assert_completed(&dir);
    let (robot, controller) = reports(&dir);
    assert!(rejected(&robot, "malformed") >= 2, "{robot}");
    for r in [&robot, &controller] {
        assert!(rejected(r, "bad_mac") >= 3, "{r}");
    }
}

/// The secret of the pairing file `path`.
fn secret(path: &str) -> PairingSecret {
    robokey_net::pairing::read_pairing(Path::new(path), false)
        .unwrap()
        .0
}

/// The configuration the test agents run (`SHORT`): its `Hello`s are answered with a
/// `HelloAck`.
fn short_config() -> robokey::Config {
    let mut config = robokey::Config::default();
    config.trajectory.laps = 1;
    config.trajectory.side_time = 6.0;
    config
}

/// Authentic `Hello`s of `count` sessions that never ran (what an attacker who recorded old
/// sessions holds).
fn old_hellos(secret: &PairingSecret, count: u32) -> Vec<Vec<u8>> {
    use rand::SeedableRng;
    let config = short_config();
    let mut rng = rand::rngs::ChaCha20Rng::seed_from_u64(12);
    (0..count)
        .map(|i| {
            robokey::protocol::auth::ControllerChannel::new(
                secret.clone(),
                0u8,
                1000 + i,
                robokey::protocol::config_digest(&config),
                robokey::protocol::agreement_terms(&config),
                &mut rng,
            )
            .hello()
            .to_vec()
        })
        .collect()
}

/// An authentic `Hello` re-sent from source port 0 (through a raw socket, as root of the
/// test's own network namespace) made the waiting robot's answer fail to send, and the error
/// ended it with exit 1. A source that cannot be a controller now gets no answer, the robot
/// counts it and goes on, and a genuine controller then confirms.
#[test]
fn a_hello_from_port_zero_gets_no_answer_and_the_robot_goes_on() {
    const TEST: &str = "a_hello_from_port_zero_gets_no_answer_and_the_robot_goes_on";
    if !common::in_namespace(TEST, "true") {
        return;
    }
    let dir = scratch("attack-port-zero");
    let pairing = pairing(&dir);
    let robot = robot(&dir, &pairing, &[]);
    let port: u16 = robot.address.rsplit(':').next().unwrap().parse().unwrap();
    let hello = old_hellos(&secret(&pairing), 1).remove(0);
    // A UDP header from port 0 to the robot (checksum 0: none), then the Hello; the kernel
    // adds the IPv4 header from 127.0.0.1.
    let mut datagram = vec![0u8; 8];
    datagram[2..4].copy_from_slice(&port.to_be_bytes());
    datagram[4..6].copy_from_slice(&u16::try_from(8 + hello.len()).unwrap().to_be_bytes());
    datagram.extend_from_slice(&hello);
    let raw = socket2::Socket::new(
        socket2::Domain::IPV4,
        socket2::Type::RAW,
        Some(socket2::Protocol::UDP),
    )
    .expect("a raw socket, as root of the namespace");
    let to: SocketAddr = ([127, 0, 0, 1], port).into();
    for _ in 0..3 {
        raw.send_to(&datagram, &to.into()).unwrap();
    }
    std::thread::sleep(Duration::from_millis(200));
    controller(&dir, &pairing, &robot.address, 0);
    wait_robot(robot, 0);
    let r = report(&dir.join("robot.json"));
    assert!(
        r["frames"]["impossible_source"].as_u64().unwrap() >= 1,
        "{r}"
    );
    assert_completed(&dir);
}

/// Ten recorded `Hello`s cycled at the robot pushed a fresh controller's half-open handshake
/// out (4 of 14 runs), and its `Ready` went unanswered until its silence timeout. Each
/// recording is now answered once and rejected as replayed after, a controller whose `Ready`
/// goes unanswered starts a fresh handshake, and the session confirms; every answer and replay
/// is counted.
#[test]
fn cycled_old_hellos_never_lock_a_fresh_controller_out() {
    let dir = scratch("attack-cycled-hellos");
    let pairing = pairing(&dir);
    let robot = robot(&dir, &pairing, &[]);
    let hellos = old_hellos(&secret(&pairing), 10);
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let attacker = {
        let (stop, target) = (Arc::clone(&stop), robot.address.clone());
        std::thread::spawn(move || {
            let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
            let deadline = Instant::now() + Duration::from_secs(20);
            let mut sent = 0u64;
            while !stop.load(Ordering::Relaxed) && Instant::now() < deadline {
                for hello in &hellos {
                    let _ = socket.send_to(hello, &target);
                    sent += 1;
                }
                std::thread::sleep(Duration::from_micros(200));
            }
            sent
        })
    };
    std::thread::sleep(Duration::from_millis(100));
    controller(&dir, &pairing, &robot.address, 0);
    stop.store(true, Ordering::Relaxed);
    assert!(attacker.join().unwrap() > 100);
    wait_robot(robot, 0);
    assert_completed(&dir);
    let r = report(&dir.join("robot.json"));
    assert!(
        r["frames"]["hellos_answered"].as_u64().unwrap() >= 11,
        "{r}"
    );
    assert!(rejected(&r, "replayed") > 0, "{r}");
}

/// One stray datagram with a bad MAC turned a waiting robot's "no controller" (exit 3) into
/// "authentication failed" (4). Exit 4 now means that a peer kept trying the handshake with
/// another secret (three `Hello`s that failed to verify, as a controller repeating its `Hello`
/// sends) or the other pairing mode; a stray frame is counted, and the robot that no controller
/// bound exits 3.
#[test]
fn a_stray_datagram_does_not_turn_no_controller_into_authentication_failed() {
    let dir = scratch("attack-stray");
    let pairing = pairing(&dir);
    let robot = robot(&dir, &pairing, &[]);
    let hello = old_hellos(&PairingSecret::from_bytes(&[7; 32]), 1).remove(0);
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .send_to(&hello, &robot.address)
        .unwrap();
    wait_robot(robot, 3);
    let r = report(&dir.join("robot.json"));
    assert_eq!(rejected(&r, "handshake_bad_mac"), 1, "{r}");
    assert_eq!(r["ending"], "no-key", "{r}");
}
