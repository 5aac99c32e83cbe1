//! Sessions over ROS 2 topics (docs/ros2.md): `robokey ros2-sim`, `robokey robot --backend
//! ros2` and `robokey controller`, each test inside a network namespace it creates.
//!
//! DDS multicasts discovery on every multicast-capable interface, so these tests never run
//! on the machine's interfaces: each re-executes itself under
//! `unshare -rn sh -c 'ip link set lo up; ip link set lo multicast on; exec …'` (a new user
//! and network namespace holding only `lo`, and a veth pair the localhost-only test adds), and
//! its body runs there. Without a working `unshare` they are skipped with a message.
#![cfg(feature = "ros2")]

mod common;

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use common::{in_namespace, pairing, report, run_code, s, scratch, start, wait_code};

/// Runs a command inside the namespace and returns its stdout.
fn sh(command: &str) -> String {
    let out = Command::new("sh").args(["-c", command]).output().unwrap();
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Runs `robokey args…` with the arguments printed first (the test's log says what ran).
fn logged(args: &[&str]) -> Vec<String> {
    println!("$ robokey {}", args.join(" "));
    args.iter().map(|a| (*a).to_owned()).collect()
}

/// Runs `robokey base… extra…`, printing the command first and its exit code and output
/// after; returns them.
fn run_logged(base: &[&str], extra: &[&str]) -> (i32, String) {
    let args: Vec<&str> = base.iter().chain(extra).copied().collect();
    let (code, text) = run_code(&logged(&args).iter().map(String::as_str).collect::<Vec<_>>());
    println!("exit {code}: {}", text.trim_end());
    (code, text)
}

/// The robot agent on the `ros2` backend, listening on loopback; its pairing file follows.
const ROBOT: [&str; 6] = [
    "robot",
    "--listen",
    "127.0.0.1:0",
    "--backend",
    "ros2",
    "--pairing",
];

/// Checks that a command exited with `code` and printed each of `needles`.
fn assert_fails((code, text): (i32, String), expected: i32, needles: &[&str]) {
    assert_eq!(code, expected, "{text}");
    for needle in needles {
        assert!(text.contains(needle), "{needle:?} not in {text}");
    }
}

/// A whole session: ros2-sim, the robot agent on it, the controller. Returns the folder
/// with robot.json, controller.json and the keys, and each process's output.
fn ros2_session(
    name: &str,
    sim_args: &[&str],
    robot_args: &[&str],
    controller_args: &[&str],
    common_args: &[&str],
    during: impl FnOnce(&mut common::Process),
) -> (std::path::PathBuf, [(i32, String); 3]) {
    let dir = scratch(name);
    let file = |f: &str| s(&dir.join(f));
    let pairing = pairing(&dir);
    let mut sim_all = vec!["ros2-sim", "--idle-exit", "3"];
    sim_all.extend(sim_args);
    let mut sim = start(
        &logged(&sim_all)
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
    );
    let (robot_key, robot_json) = (file("robot.key"), file("robot.json"));
    let mut robot_all = ROBOT.to_vec();
    robot_all.extend([
        pairing.as_str(),
        "--key-out",
        &robot_key,
        "--report",
        &robot_json,
        "--silence-timeout",
        "2",
    ]);
    robot_all.extend(robot_args);
    robot_all.extend(common_args);
    let robot = start(
        &logged(&robot_all)
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
    );
    let (controller_key, controller_json) = (file("controller.key"), file("controller.json"));
    let mut controller_all = vec![
        "controller",
        "--robot",
        &robot.address,
        "--pairing",
        &pairing,
        "--key-out",
        &controller_key,
        "--report",
        &controller_json,
        "--silence-timeout",
        "2",
    ];
    controller_all.extend(controller_args);
    controller_all.extend(common_args);
    let controller_args = logged(&controller_all);
    let controller = std::thread::spawn(move || {
        run_code(
            &controller_args
                .iter()
                .map(String::as_str)
                .collect::<Vec<_>>(),
        )
    });
    during(&mut sim);
    let controller = controller.join().unwrap();
    let robot = wait_code(robot);
    let sim = wait_code(sim);
    for (who, (code, text)) in [
        ("controller", &controller),
        ("robot", &robot),
        ("ros2-sim", &sim),
    ] {
        println!("{who} exited {code}:\n{}", text.trim_end());
    }
    (dir, [controller, robot, sim])
}

fn assert_confirmed_with_equal_keys(dir: &Path) {
    let (robot, controller) = (
        report(&dir.join("robot.json")),
        report(&dir.join("controller.json")),
    );
    assert_eq!(robot["outcome"], "confirmed", "{robot}");
    assert_eq!(controller["outcome"], "confirmed", "{controller}");
    assert_eq!(robot["erased_steps"], 0, "{robot}");
    let key = std::fs::read_to_string(dir.join("robot.key")).unwrap();
    assert_eq!(
        key,
        std::fs::read_to_string(dir.join("controller.key")).unwrap()
    );
    println!(
        "keys equal: {} bits, {} codewords accepted",
        robot["key_bits"], robot["accepted"]
    );
}

/// Packets sent through interface `name` so far (from /proc/net/dev, this namespace's).
fn tx_packets(name: &str) -> u64 {
    let dev = std::fs::read_to_string("/proc/net/dev").unwrap();
    let line = dev
        .lines()
        .find(|l| l.trim_start().starts_with(&format!("{name}:")))
        .unwrap_or_else(|| panic!("no {name} in /proc/net/dev:\n{dev}"));
    let fields: Vec<&str> = line.split(':').nth(1).unwrap().split_whitespace().collect();
    fields[9].parse().unwrap()
}

/// A second interface (a veth pair `rk0`–`rk1`, rk0 at 10.213.0.1, IPv6 off so the kernel
/// sends nothing on its own) that a participant not restricted to localhost would multicast
/// discovery on.
const SECOND_INTERFACE: &str = "sysctl -qw net.ipv6.conf.all.disable_ipv6=1 net.ipv6.conf.default.disable_ipv6=1; \
     ip link add rk0 type veth peer name rk1; ip addr add 10.213.0.1/24 dev rk0; \
     ip link set rk1 up; ip link set rk0 up";

/// Test `test`, in its namespace with [`SECOND_INTERFACE`]: a session ([`ros2_session`] with
/// these arguments) during which nothing is sent through that interface. `None` outside
/// the namespace (the test ran there, or was skipped).
fn lo_only_session(
    test: &str,
    name: &str,
    [sim, robot, controller, common]: [&[&str]; 4],
) -> Option<(std::path::PathBuf, [(i32, String); 3])> {
    if !in_namespace(test, SECOND_INTERFACE) {
        return None;
    }
    println!("namespace interfaces:\n{}", sh("ip -brief address"));
    let before = tx_packets("rk0");
    let out = ros2_session(name, sim, robot, controller, common, |_| {});
    let sent = tx_packets("rk0") - before;
    println!("packets sent on rk0 (10.213.0.1) during the session: {sent}");
    assert_eq!(sent, 0, "a participant sent on an interface other than lo");
    Some(out)
}

/// The statistics `ros2-sim` prints last (`ros2-sim: {…}`).
fn sim_stats(output: &str) -> serde_json::Value {
    let line = output.lines().last().unwrap_or_default();
    let json = line
        .strip_prefix("ros2-sim: ")
        .unwrap_or_else(|| panic!("no statistics in {output}"));
    serde_json::from_str(json).unwrap()
}

#[test]
fn lockstep_session_over_ros2_topics_confirms_a_key_and_nothing_leaves_localhost() {
    let Some((dir, [controller, robot, sim])) = lo_only_session(
        "lockstep_session_over_ros2_topics_confirms_a_key_and_nothing_leaves_localhost",
        "ros2-lockstep",
        [
            &["--time", "virtual", "--period", "0.2"],
            &["--seed", "11", "--ros2-odom-qos", "reliable"],
            &[],
            &["--pace", "lockstep", "--set", "protocol.delta_v=0.04"],
        ],
    ) else {
        return;
    };
    assert_eq!((controller.0, robot.0, sim.0), (0, 0, 0));
    assert_confirmed_with_equal_keys(&dir);
    let robot_report = report(&dir.join("robot.json"));
    assert_eq!(robot_report["steps"], 1020);
    assert_eq!(robot_report["commands_applied"], 1020);
    // The emulator applied every command: 1020 steps (+ the stops at the end).
    let stats = sim_stats(&sim.1);
    assert!(stats["commands"].as_u64().unwrap() >= 1020, "{stats}");
}

#[test]
fn private_session_reads_the_controllers_pose_from_a_ros2_topic_and_keeps_equal_bits() {
    // The emulator plays the robot (/cmd_vel, /odom) and the controller's motion capture
    // (/mocap/robot/pose, 0.5 mm / 0.5 mrad noise, seeded); the controller decides every
    // doublet from that topic; the robot sends no pose.
    let Some((dir, [controller, robot, sim])) = lo_only_session(
        "private_session_reads_the_controllers_pose_from_a_ros2_topic_and_keeps_equal_bits",
        "ros2-private",
        [
            &[
                "--time",
                "virtual",
                "--mocap-topic",
                "/mocap/robot/pose",
                "--seed",
                "5",
                "--set",
                "world.process_std=[0.0, 0.0, 0.0]",
            ],
            &["--seed", "11", "--ros2-odom-qos", "reliable"],
            &[
                "--sensor",
                "ros2:/mocap/robot/pose",
                "--ros2-pose-qos",
                "reliable",
            ],
            &[
                "--pace",
                "lockstep",
                "--set",
                "protocol.delta_v=0.04",
                "--set",
                "sensing.mode=private",
            ],
        ],
    ) else {
        return;
    };
    assert_eq!((controller.0, robot.0, sim.0), (0, 0, 0));
    let (robot_report, controller_report) = (
        report(&dir.join("robot.json")),
        report(&dir.join("controller.json")),
    );
    for r in [&robot_report, &controller_report] {
        assert_eq!(r["outcome"], "kept", "{r}");
        assert_eq!(r["steps"], 1020, "{r}");
        assert_eq!(r["doublets"]["erased"], 0, "{r}");
        assert_eq!(r["accepted"], robot_report["accepted"], "{r}");
    }
    let accepted = robot_report["accepted"].as_u64().unwrap();
    assert!(accepted > 400, "{robot_report}");
    // Same kept positions (confirmed by both session tags), and no bit decided wrong: the
    // emulator's world has no motion noise (set here: the default world is the parties' 4 mm),
    // its motion capture 0.5 mm, and Δv = 0.04 m/s is a whole
    // number of command quanta, so the truncation shifts both hypotheses alike.
    let key = std::fs::read_to_string(dir.join("robot.key")).unwrap();
    assert!(
        key.starts_with(&format!("robokey-key-v1 bits={accepted}\n")),
        "{key}"
    );
    assert_eq!(
        key,
        std::fs::read_to_string(dir.join("controller.key")).unwrap()
    );
    let stats = sim_stats(&sim.1);
    assert!(stats["mocap"].as_u64().unwrap() >= 1021, "{stats}");
    println!("raw bits equal on both sides: {accepted} kept doublets; emulator {stats}");
}

#[test]
fn realtime_session_with_twist_stamped_confirms_a_key() {
    if !in_namespace("realtime_session_with_twist_stamped_confirms_a_key", "true") {
        return;
    }
    // 36 steps of 0.2 s; /odom at 20 Hz, the sample the latest one.
    let (dir, [controller, robot, sim]) = ros2_session(
        "ros2-realtime",
        &["--time", "real", "--stamped"],
        &["--ros2-stamped"],
        &[],
        &[
            "--pace",
            "realtime",
            "--set",
            "protocol.delta_v=0.04",
            "--set",
            "code.key_bits=12",
        ],
        |_| {},
    );
    assert_eq!((controller.0, robot.0, sim.0), (0, 0, 0));
    assert_confirmed_with_equal_keys(&dir);
    assert_eq!(report(&dir.join("robot.json"))["steps"], 36);
    // Each TwistStamped says the frame of its twist, the robot's base.
    assert_eq!(sim_stats(&sim.1)["cmd_frame_id"], "base_link", "{}", sim.1);
}

#[test]
fn a_silent_robot_ends_the_session_with_a_named_stale_odom_error() {
    if !in_namespace(
        "a_silent_robot_ends_the_session_with_a_named_stale_odom_error",
        "true",
    ) {
        return;
    }
    let (dir, [controller, robot, _]) = ros2_session(
        "ros2-stale",
        &["--time", "real"],
        &[],
        &[],
        &["--pace", "realtime", "--set", "protocol.delta_v=0.04"],
        |sim| {
            // The robot's driver dies 3 s into the session (as `kill -9` would do it).
            std::thread::sleep(Duration::from_secs(3));
            sim.child.kill().unwrap();
        },
    );
    // The robot failed (1: its robot failed) and told the controller, which ended without a
    // key (3); both name the reason.
    assert_eq!((controller.0, robot.0), (3, 1));
    let robot_report = report(&dir.join("robot.json"));
    let reason = robot_report["reason"].as_str().unwrap();
    assert!(
        reason.contains("stale /odom") && reason.contains("limit 0.100 s"),
        "{robot_report}"
    );
    assert!(
        robot_report["steps_done"].as_u64().unwrap() < 30,
        "{robot_report}"
    );
    let controller_report = report(&dir.join("controller.json"));
    assert!(
        controller_report["reason"]
            .as_str()
            .unwrap()
            .contains("stale /odom"),
        "{controller_report}"
    );
}

#[test]
fn missing_peers_bad_names_and_a_delta_off_the_quantum_are_named_errors() {
    if !in_namespace(
        "missing_peers_bad_names_and_a_delta_off_the_quantum_are_named_errors",
        "true",
    ) {
        return;
    }
    let dir = scratch("ros2-errors");
    let pairing = pairing(&dir);
    let robot = |extra: &[&str]| run_logged(&[&ROBOT[..], &[pairing.as_str()]].concat(), extra);
    // No ROS 2 robot on this host: an error (1) that says what was missing; with --log,
    // RustDDS's own messages on stderr too.
    assert_fails(
        robot(&["--set", "protocol.delta_v=0.04", "--ros2-wait", "1"]),
        1,
        &["no valid /odom within 1.0 s"],
    );
    assert_fails(
        robot(&[
            "--set",
            "protocol.delta_v=0.04",
            "--ros2-wait",
            "1",
            "--log",
            "rustdds=info",
        ]),
        1,
        &[" INFO rustdds::", "no valid /odom within 1.0 s"],
    );
    // The default Δv = 0.035 m/s is not a multiple of the TurtleBot3's 0.01: a usage error.
    assert_fails(
        robot(&[]),
        2,
        &["protocol.delta_v = 0.035 m/s is not a multiple", "0.0400"],
    );
    // A topic that is not an absolute ROS name.
    assert_fails(
        robot(&["--set", "protocol.delta_v=0.04", "--ros2-odom", "odom"]),
        2,
        &["give an absolute ROS name"],
    );
    // A robot that takes Twist while the agent publishes TwistStamped (or the reverse, the
    // Jazzy TurtleBot3's pitfall): DDS never matches them; the error says what is there.
    let sim = start(&["ros2-sim", "--idle-exit", "5"]);
    assert_fails(
        robot(&[
            "--set",
            "protocol.delta_v=0.04",
            "--ros2-stamped",
            "--ros2-wait",
            "3",
        ]),
        1,
        &[
            "the subscribers of /cmd_vel use geometry_msgs::msg::dds_::Twist_, not \
             geometry_msgs::msg::dds_::TwistStamped_: the robot takes Twist: drop --ros2-stamped",
        ],
    );
    drop(sim);
    // Reliability QoS that DDS never matches, on either topic, is named as such.
    let sim = start(&["ros2-sim", "--idle-exit", "5", "--odom-qos", "best-effort"]);
    assert_fails(
        robot(&[
            "--set",
            "protocol.delta_v=0.04",
            "--ros2-odom-qos",
            "reliable",
            "--ros2-wait",
            "3",
        ]),
        1,
        &[
            "no valid /odom within 3.0 s: a QoS reliability mismatch: the publishers of /odom \
             are best effort and this subscription is reliable",
            "(--ros2-odom-qos best-effort)",
        ],
    );
    drop(sim);
    let sim = start(&["ros2-sim", "--idle-exit", "5"]);
    assert_fails(
        robot(&[
            "--set",
            "protocol.delta_v=0.04",
            "--ros2-cmd-qos",
            "best-effort",
            "--ros2-wait",
            "3",
        ]),
        1,
        &[
            "a QoS reliability mismatch: the subscribers of /cmd_vel are reliable and this \
             publisher is best effort",
            "(--ros2-cmd-qos reliable)",
        ],
    );
    drop(sim);
    // The controller's pose sensor.
    let controller = |extra: &[&str]| {
        run_logged(
            &[
                "controller",
                "--robot",
                "127.0.0.1:9",
                "--pairing",
                &pairing,
                "--set",
                "sensing.mode=private",
            ],
            extra,
        )
    };
    // Nothing publishes the pose: an error (1) naming the topic, the wait and what is missing.
    assert_fails(
        controller(&[
            "--pace",
            "lockstep",
            "--sensor",
            "ros2:/mocap/robot/pose",
            "--ros2-wait",
            "1",
        ]),
        1,
        &["no valid /mocap/robot/pose within 1.0 s (no publisher of /mocap/robot/pose)"],
    );
    // A relative name, and real time: usage errors (2) that say why.
    assert_fails(
        controller(&["--pace", "lockstep", "--sensor", "ros2:mocap/pose"]),
        2,
        &["--sensor ros2:mocap/pose", "give an absolute ROS name"],
    );
    assert_fails(
        controller(&["--pace", "realtime", "--sensor", "ros2:/mocap/robot/pose"]),
        2,
        &["needs --pace lockstep"],
    );
}
