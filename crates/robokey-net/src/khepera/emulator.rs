//! A simulated Khepera IV speaking kh4server's line protocol over TCP, so the `kh4`
//! backend and a whole session can be tested without hardware. Its robot lives in a world
//! (docs/world.md: the parties' own model unless given one, e.g. the `khepera-iv` preset):
//! the speed units it is sent drive the world's wheels, its encoders count the world's wheel
//! angles (at the world's resolution) in pulses, and at every encoder read (a sample instant)
//! it serves the motion capture and the camera from its true pose (docs/sensors.md).

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener};
use std::time::{Duration, Instant};

use robokey::Config;
use robokey::config::SensingMode;
use robokey::model::WheelSpeeds;
use serialport::SerialPort as _;

use super::protocol::{MAX_UNITS, PULSE_M, SPEED_UNIT_M_S};
use crate::error::{NetError, is_wait_over};
use crate::world::{StreamAddresses, WorldProcess};

/// How the emulated robot's time advances.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TimeMode {
    /// Each encoder read (`R`) advances this many seconds at the current speeds, so a
    /// session runs as fast as the agent talks.
    Virtual(Duration),
    /// The wheels turn with the wall clock.
    Real,
}

/// Where the emulator listens.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Listen {
    /// A TCP address (port 0: any; the address is printed).
    Tcp(SocketAddr),
    /// A new pseudo-terminal pair: the agent opens the printed device path, as it would
    /// open the pty that `socat` makes on the robot.
    Pty,
}

/// Options of the emulator.
#[derive(Clone, Debug)]
pub struct EmulatorOptions {
    /// Where to listen.
    pub listen: Listen,
    /// Time mode.
    pub time: TimeMode,
    /// The robot's world: its `[world]` (the parties' model without one), wheel geometry
    /// (`robot.r`, `robot.D`), the sensors' noise and `run.seed`. Each connection is a
    /// session, replicate `i` of every noise for the `i`-th connection.
    pub world: Config,
    /// Serve this many connections, then return (`None`: forever; a pty is one connection
    /// that lasts as long as the emulator).
    pub connections: Option<usize>,
    /// Where the world serves its sensor streams.
    pub sensors: StreamAddresses,
}

/// Longest request line the emulator reads (bytes); a longer one is answered with `$`.
const MAX_REQUEST_BYTES: usize = 256;

/// The emulated robot: its speeds in units, its encoders' zero, and its world.
struct Robot<'w> {
    /// Speed units, left first (as kh4server takes them).
    speeds: [i64; 2],
    /// Pulse counts at the last reset, left first.
    zero: [i64; 2],
    last: Instant,
    /// Encoder reads so far.
    reads: u32,
    world: &'w mut WorldProcess,
    wheel_radius: f64,
    encoder_quantum: f64,
}

impl Robot<'_> {
    /// Each wheel's pulses counted since the world began, left first: its angle (at the
    /// world's encoder resolution) as travel of the Khepera's pulse.
    fn counts(&self) -> [i64; 2] {
        let angles = self.world.plant().wheel_angles();
        let q = self.encoder_quantum;
        let pulses = |angle: f64| {
            let read = if q > 0.0 {
                (angle / q).round() * q
            } else {
                angle
            };
            (read * self.wheel_radius / PULSE_M).round() as i64
        };
        [pulses(angles.y), pulses(angles.x)]
    }

    /// Answers one request line.
    fn answer(&mut self, line: &str, time: TimeMode) -> String {
        if time == TimeMode::Real {
            let now = Instant::now();
            self.world.advance((now - self.last).as_secs_f64());
            self.last = now;
        }
        let mut parts = line.trim().split(',');
        let numbers = |parts: std::str::Split<'_, char>| -> Option<Vec<i64>> {
            parts.map(|p| p.trim().parse().ok()).collect()
        };
        let reply = match parts.next() {
            Some("D") => match numbers(parts).as_deref() {
                Some(&[left, right]) => {
                    self.speeds = [
                        left.clamp(-MAX_UNITS, MAX_UNITS),
                        right.clamp(-MAX_UNITS, MAX_UNITS),
                    ];
                    let wheel = |units: i64| units as f64 * SPEED_UNIT_M_S / self.wheel_radius;
                    self.world.apply(WheelSpeeds::new(
                        wheel(self.speeds[1]),
                        wheel(self.speeds[0]),
                    ));
                    Some("d".to_owned())
                }
                _ => None,
            },
            Some("R") => {
                if let TimeMode::Virtual(period) = time
                    && self.reads > 0
                {
                    self.world.advance(period.as_secs_f64());
                }
                self.world.sample();
                self.reads = self.reads.saturating_add(1);
                let counts = self.counts();
                Some(format!(
                    "r,{},{}",
                    counts[0] - self.zero[0],
                    counts[1] - self.zero[1]
                ))
            }
            Some("E") => Some(format!("e,{},{}", self.speeds[0], self.speeds[1])),
            Some("I") => {
                self.zero = self.counts();
                Some("i".to_owned())
            }
            Some("U") => Some("u".to_owned()),
            Some("V") => Some("v,3700".to_owned()),
            Some("B") => Some("b,2,0".to_owned()),
            _ => None,
        };
        reply.unwrap_or_else(|| "$".to_owned()) + "\r\n"
    }
}

/// Serves one client: reads request lines (each at most [`MAX_REQUEST_BYTES`]), answers each
/// but the first (kh4server ignores the first line after a connection, as the authors' lab
/// code notes), until the stream closes.
fn serve_one(
    stream: &mut (impl Read + Write),
    options: &EmulatorOptions,
    world: &mut WorldProcess,
) -> Result<(), NetError> {
    let mut robot = Robot {
        speeds: [0; 2],
        zero: [0; 2],
        last: Instant::now(),
        reads: 0,
        wheel_radius: options.world.robot.r,
        encoder_quantum: options.world.world_model().encoder_quantum,
        world,
    };
    let mut pending = Vec::with_capacity(MAX_REQUEST_BYTES);
    let mut chunk = [0u8; 256];
    let mut first = true;
    loop {
        let n = match stream.read(&mut chunk) {
            Ok(0) => return Ok(()),
            Ok(n) => n,
            Err(e) if is_wait_over(&e) => continue,
            Err(_) => return Ok(()),
        };
        for &byte in &chunk[..n] {
            if byte != b'\n' {
                if pending.len() < MAX_REQUEST_BYTES {
                    pending.push(byte);
                }
                continue;
            }
            let line = String::from_utf8_lossy(&pending).into_owned();
            let too_long = pending.len() >= MAX_REQUEST_BYTES;
            pending.clear();
            if std::mem::replace(&mut first, false) {
                continue;
            }
            let reply = if too_long {
                "$\r\n".to_owned()
            } else {
                robot.answer(&line, options.time)
            };
            if stream.write_all(reply.as_bytes()).is_err() {
                return Ok(());
            }
        }
    }
}

/// Serves kh4server's protocol on TCP (one client at a time) or on a pseudo-terminal;
/// prints where (`kh4-emulator listening on tcp:ADDR` or `… on /dev/pts/N`) and, on a second
/// line, the world's sensor streams.
///
/// # Errors
/// An address cannot be bound, or no pseudo-terminal can be made.
pub fn serve(options: &EmulatorOptions) -> Result<(), NetError> {
    let mut world = WorldProcess::new(&options.world, SensingMode::Private, &options.sensors)?;
    match options.listen {
        Listen::Tcp(address) => {
            let listener =
                TcpListener::bind(address).map_err(NetError::io(format!("bind TCP {address}")))?;
            let address = listener
                .local_addr()
                .map_err(NetError::io("local address"))?;
            announce(&format!("tcp:{address}"), &world);
            for (index, client) in listener.incoming().enumerate() {
                world.begin_session(index as u64);
                if let Ok(mut client) = client {
                    serve_one(&mut client, options, &mut world)?;
                }
                world.end_session();
                if options.connections.is_some_and(|n| index + 1 >= n) {
                    break;
                }
            }
            Ok(())
        }
        Listen::Pty => {
            let (mut emulator, agent) = pty_pair()?;
            let device = agent
                .name()
                .ok_or_else(|| NetError::Kh4("the pseudo-terminal has no device name".into()))?;
            announce(&device, &world);
            // Held open while serving: the agent may close and reopen the device.
            let _agent_end = agent;
            world.begin_session(0);
            serve_one(&mut emulator, options, &mut world)
        }
    }
}

fn announce(address: &str, world: &WorldProcess) {
    println!("kh4-emulator listening on {address}");
    if let Some(streams) = world.describe() {
        println!("{streams}");
    }
    let _ = std::io::stdout().flush();
}

/// A pseudo-terminal pair: the emulator's end, and the agent's (whose device path it prints).
pub(crate) fn pty_pair() -> Result<(serialport::TTYPort, serialport::TTYPort), NetError> {
    let (mut emulator, agent) = serialport::TTYPort::pair()
        .map_err(|e| NetError::io("make a pseudo-terminal pair")(e.into()))?;
    emulator
        .set_timeout(Duration::from_millis(100))
        .map_err(|e| NetError::io("set the pty timeout")(e.into()))?;
    Ok((emulator, agent))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::Backend;
    use crate::khepera::{Kh4Backend, Link};
    use robokey::model::{DiffDrive, WheelSpeeds};

    #[test]
    fn the_backend_drives_the_emulator_straight_and_spins() {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let address = listener.local_addr().unwrap();
        drop(listener);
        let options = EmulatorOptions {
            listen: Listen::Tcp(address),
            time: TimeMode::Virtual(Duration::from_millis(200)),
            // Without noise, lag or delay: the backend's conversions alone.
            world: Config::from_toml(
                "[world]\nprocess_std = [0.0, 0.0, 0.0]\nintegration = \"continuous\"\n",
                "test",
            )
            .unwrap(),
            connections: Some(1),
            sensors: StreamAddresses::default(),
        };
        let server = std::thread::spawn(move || serve(&options));
        std::thread::sleep(Duration::from_millis(100));
        let drive = DiffDrive {
            wheel_radius: 0.021,
            axle_length: 0.1047,
        };
        let mut robot = Kh4Backend::start(
            Link::open(&format!("tcp:{address}"), Duration::from_secs(1)).unwrap(),
            drive,
        )
        .unwrap();
        assert_eq!(robot.sample().unwrap(), robokey::model::Pose::zeros());
        robot.set_wheels(WheelSpeeds::new(4.0, 4.0)).unwrap();
        let mut pose = robokey::model::Pose::zeros();
        for _ in 0..10 {
            pose = robot.sample().unwrap();
        }
        // 124 units = 84.08 mm/s for 2 s: 0.16817 m, within encoder and unit quantization.
        assert!(
            (pose.x - 124.0 * SPEED_UNIT_M_S * 2.0).abs() < 2.0 * PULSE_M,
            "{pose}"
        );
        assert!(pose.y.abs() < 1e-9 && pose.z.abs() < 1e-9);
        robot.set_wheels(WheelSpeeds::new(2.0, -2.0)).unwrap();
        let spun = robot.sample().unwrap().z;
        let expected = 2.0 * 62.0 * SPEED_UNIT_M_S * 0.2 / 0.1047;
        assert!((spun - expected).abs() < 1e-3, "{spun} vs {expected}");
        robot.stop();
        drop(robot);
        server.join().unwrap().unwrap();
    }
}
