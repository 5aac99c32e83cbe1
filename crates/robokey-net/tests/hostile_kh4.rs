//! The `kh4` backend against a hostile kh4server (loopback TCP): garbage, silence, an
//! endless line, a slow reply and counts that overflow. Each case ends with a named error,
//! and the last request the server receives is the stop command `D,0,0`.

use std::io::{BufRead, BufReader, Write};
use std::net::{SocketAddr, TcpListener};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use robokey::Config;
use robokey::interrupt::Interrupt;
use robokey::model::{DiffDrive, WheelSpeeds};
use robokey::protocol::auth::PairingSecret;
use robokey::protocol::{Pace, Timing};
use robokey_net::agent::controller::{ControllerOptions, run_controller};
use robokey_net::agent::report::{Ending, SessionReport};
use robokey_net::agent::robot::{RobotOptions, run_robot};
use robokey_net::backend::{Backend, WheelGuard};
use robokey_net::khepera::{Kh4Backend, Link, MAX_REPLY_BYTES};

/// What the fake server answers to the first `R` (every other request is answered
/// correctly, so the robot starts and its wheels turn first).
#[derive(Clone, Copy, Debug)]
enum Hostile {
    /// Bytes that are not UTF-8, with a line end.
    Garbage,
    /// No answer.
    Silence,
    /// A reply line that never ends (bounded here at 1 MiB so the test ends).
    EndlessLine,
    /// A correct reply, one byte every 300 ms.
    SlowReply,
    /// Counts of i64::MAX.
    OverflowingCounts,
    /// Nothing: every request is answered correctly.
    None,
}

/// A fake kh4server for one connection; returns its address and the lines it received.
fn fake_kh4server(hostile: Hostile) -> (SocketAddr, Arc<Mutex<Vec<String>>>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap();
    let received = Arc::new(Mutex::new(Vec::new()));
    let log = Arc::clone(&received);
    std::thread::spawn(move || {
        let (client, _) = listener.accept().unwrap();
        let mut writer = client.try_clone().unwrap();
        let (lines, requests) = mpsc::channel::<String>();
        // The reader logs every request, whatever the writer is doing.
        std::thread::spawn(move || {
            for line in BufReader::new(client).lines() {
                let Ok(line) = line else { break };
                log.lock().unwrap().push(line.clone());
                if lines.send(line).is_err() {
                    break;
                }
            }
        });
        let mut hostile_done = false;
        for request in requests {
            let reply: Vec<u8> = match request.split(',').next().unwrap_or("") {
                "" => continue,
                "B" => b"b,2,0\r\n".to_vec(),
                "U" => b"u\r\n".to_vec(),
                "I" => b"i\r\n".to_vec(),
                "D" => b"d\r\n".to_vec(),
                "R" if !std::mem::replace(&mut hostile_done, true) => match hostile {
                    Hostile::Garbage => b"r,\xff\xfe\x00garbage\r\n".to_vec(),
                    Hostile::Silence => continue,
                    Hostile::EndlessLine => {
                        let _ = writer.write_all(b"r,");
                        for _ in 0..1024 {
                            if writer.write_all(&[b'7'; 1024]).is_err() {
                                break;
                            }
                        }
                        continue;
                    }
                    Hostile::SlowReply => {
                        for byte in b"r,1,2\r\n" {
                            std::thread::sleep(Duration::from_millis(300));
                            let _ = writer.write_all(&[*byte]);
                        }
                        continue;
                    }
                    Hostile::OverflowingCounts => {
                        format!("r,{},{}\r\n", i64::MAX, i64::MAX).into_bytes()
                    }
                    Hostile::None => b"r,0,0\r\n".to_vec(),
                },
                "R" => b"r,0,0\r\n".to_vec(),
                _ => b"$\r\n".to_vec(),
            };
            if writer.write_all(&reply).is_err() {
                break;
            }
        }
    });
    (address, received)
}

fn drive() -> DiffDrive {
    DiffDrive {
        wheel_radius: 0.021,
        axle_length: 0.1047,
    }
}

/// Waits (≤ 3 s) until the server has received `D,0,0` after other requests; returns them.
fn requests_until_stop(received: &Mutex<Vec<String>>) -> Vec<String> {
    let until = Instant::now() + Duration::from_secs(3);
    loop {
        let lines = received.lock().unwrap().clone();
        if lines.last().map(String::as_str) == Some("D,0,0") || Instant::now() > until {
            return lines;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Starts the robot, drives its wheels, then samples once into the hostile reply.
fn sample_into(hostile: Hostile) -> (String, Vec<String>) {
    let (address, received) = fake_kh4server(hostile);
    let link = Link::open(&format!("tcp:{address}"), Duration::from_secs(1)).unwrap();
    let mut robot = Kh4Backend::start(link, drive()).unwrap();
    let error = {
        let mut wheels = WheelGuard::new(&mut robot);
        wheels.set_wheels(WheelSpeeds::new(-1.3, -1.3)).unwrap();
        wheels.sample().unwrap_err().to_string()
    };
    (error, requests_until_stop(&received))
}

#[test]
fn every_hostile_reply_ends_in_a_named_error_and_a_stop_command() {
    let cases = [
        (Hostile::Garbage, "not text (invalid UTF-8)"),
        (Hostile::Silence, "no complete reply within 1.0 s"),
        (Hostile::EndlessLine, "exceeds 128 bytes without a line end"),
        (Hostile::SlowReply, "no complete reply within 1.0 s"),
        (
            Hostile::OverflowingCounts,
            "outside the robot's 32-bit counters",
        ),
    ];
    assert_eq!(MAX_REPLY_BYTES, 128);
    std::thread::scope(|scope| {
        for (hostile, named) in cases {
            scope.spawn(move || {
                let (error, requests) = sample_into(hostile);
                assert!(error.contains(named), "{hostile:?}: {error}");
                assert!(error.starts_with("kh4: "), "{hostile:?}: {error}");
                // The wheels were driven (-1.3 rad/s · 21 mm = -40 units), then stopped.
                assert!(requests.contains(&"D,-40,-40".to_owned()), "{requests:?}");
                assert_eq!(
                    requests.last().map(String::as_str),
                    Some("D,0,0"),
                    "{hostile:?}: {requests:?}"
                );
            });
        }
    });
}

/// A session of the robot agent on the fake kh4server and a controller, both in this
/// process; the robot's stop is requested after `interrupt_after` if given. Returns both
/// reports and the requests the server received.
fn agent_session(
    hostile: Hostile,
    pace: Pace,
    interrupt_after: Option<Duration>,
) -> (SessionReport, SessionReport, Vec<String>) {
    let (address, received) = fake_kh4server(hostile);
    let mut config = Config::default();
    config.trajectory.laps = 1;
    config.trajectory.side_time = 6.0;
    let timing = Timing::new(pace, Duration::from_secs(1));
    let pairing = PairingSecret::from_bytes(&[5; 32]);
    // A free port for the robot (run_robot prints, but does not return, the one it binds).
    let socket = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let robot_address = socket.local_addr().unwrap();
    drop(socket);
    let interrupt = Interrupt::new();
    let robot_options = RobotOptions {
        listen: robot_address,
        timing,
        wait_for_hello: Duration::from_secs(5),
        key_out: None,
        pairing: pairing.clone(),
        interrupt: interrupt.clone(),
        store: None,
        allow_restricted: false,
    };
    let robot_config = config.clone();
    let robot = std::thread::spawn(move || {
        let link = Link::open(&format!("tcp:{address}"), Duration::from_secs(1)).unwrap();
        let mut backend = Kh4Backend::start(link, drive()).unwrap();
        let mut key_source = robokey::rng::stream(1, robokey::rng::Purpose::Key, 0);
        run_robot(&robot_config, &mut backend, &mut key_source, &robot_options).unwrap()
    });
    if let Some(after) = interrupt_after {
        std::thread::spawn(move || {
            std::thread::sleep(after);
            interrupt.request(2);
        });
    }
    std::thread::sleep(Duration::from_millis(200));
    let controller = run_controller(
        &config,
        &ControllerOptions {
            robot: robot_address,
            bind: "127.0.0.1:0".parse().unwrap(),
            timing,
            key_out: None,
            session: Some(7),
            pairing,
            interrupt: Interrupt::new(),
            sensor: None,
            store: None,
            allow_restricted: false,
            jobs: 1,
        },
    )
    .unwrap();
    let robot = robot.join().unwrap();
    (robot, controller, requests_until_stop(&received))
}

#[test]
fn a_robot_agent_session_that_fails_reports_it_and_stops_the_wheels() {
    let (robot, controller, requests) = agent_session(Hostile::EndlessLine, Pace::Lockstep, None);
    assert_eq!(robot.ending, Ending::Failed, "{robot:?}");
    let reason = robot.reason.clone().unwrap();
    assert!(reason.contains("exceeds 128 bytes"), "{reason}");
    // The robot told the controller, which ended at once rather than after its timeout.
    assert_eq!(controller.ending, Ending::NoKey);
    assert!(
        controller
            .reason
            .as_deref()
            .unwrap()
            .contains("robot aborted: kh4"),
        "{controller:?}"
    );
    assert_eq!(requests.last().map(String::as_str), Some("D,0,0"));
}

#[test]
fn an_interrupted_robot_agent_reports_it_and_stops_the_wheels() {
    // Real time (T = 0.2 s): the stop comes after about three steps.
    let (robot, controller, requests) = agent_session(
        Hostile::None,
        Pace::Realtime,
        Some(Duration::from_millis(600)),
    );
    assert_eq!(robot.ending, Ending::Interrupted, "{robot:?}");
    assert_eq!(robot.reason.as_deref(), Some("interrupted by SIGINT"));
    assert!(robot.steps_done > 0, "{robot:?}");
    assert!(
        controller
            .reason
            .as_deref()
            .unwrap()
            .contains("robot aborted: interrupted by SIGINT"),
        "{controller:?}"
    );
    let driven = requests.iter().filter(|r| r.starts_with("D,")).count();
    assert!(driven > 2, "{requests:?}");
    assert_eq!(requests.last().map(String::as_str), Some("D,0,0"));
}
