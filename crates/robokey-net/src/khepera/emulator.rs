//! A simulated Khepera IV speaking kh4server's line protocol over TCP, so the `kh4`
//! backend and a whole session can be tested without hardware. With sensor options it is
//! also the world: at every encoder read (a sample instant) it serves the motion capture and
//! the camera from its true pose (docs/sensors.md).

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener};
use std::time::{Duration, Instant};

use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use robokey::model::Pose;
use robokey::rng::{Purpose, stream as stream_of};
use serialport::SerialPort as _;

use super::protocol::{MAX_UNITS, PULSE_M, SPEED_UNIT_M_S};
use crate::error::{NetError, is_wait_over};
use crate::world::{SensorOptions, WorldSensors};

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
    /// Wheel slip: each advance multiplies each wheel's travel by `1 + N(0, σ²)` (0: exact).
    pub slip: f64,
    /// Seed of the slip noise.
    pub seed: u64,
    /// Serve this many connections, then return (`None`: forever; a pty is one connection
    /// that lasts as long as the emulator).
    pub connections: Option<usize>,
    /// The emulated robot's axle length D (m), for its true pose.
    pub axle_length: f64,
    /// The world's sensor streams, if served: each connection is a session, replicate
    /// `i` of their noise for the `i`-th connection.
    pub sensors: Option<SensorOptions>,
}

/// Longest request line the emulator reads (bytes); a longer one is answered with `$`.
const MAX_REQUEST_BYTES: usize = 256;

/// The emulated robot: wheel speeds, encoder positions, and where it truly is.
struct Robot<'w> {
    speeds: [i64; 2],
    pulses: [f64; 2],
    last: Instant,
    slip: f64,
    noise: ChaCha8Rng,
    axle_length: f64,
    /// The true pose (m, m, rad): the wheels' travel, slip included, by midpoint
    /// integration.
    truth: Pose,
    /// Encoder reads so far: the next sample instant.
    reads: u32,
    world: Option<&'w mut WorldSensors>,
}

impl Robot<'_> {
    fn advance(&mut self, seconds: f64) {
        let mut travel = [0.0; 2];
        for ((distance, pulses), speed) in travel.iter_mut().zip(&mut self.pulses).zip(self.speeds)
        {
            let factor = if self.slip > 0.0 {
                let z: f64 = StandardNormal.sample(&mut self.noise);
                1.0 + self.slip * z
            } else {
                1.0
            };
            *distance = speed as f64 * SPEED_UNIT_M_S * seconds * factor;
            *pulses += *distance / PULSE_M;
        }
        let [left, right] = travel;
        let turn = (right - left) / self.axle_length;
        let heading = self.truth.z + turn / 2.0;
        let distance = (left + right) / 2.0;
        self.truth += Pose::new(distance * heading.cos(), distance * heading.sin(), turn);
    }

    /// Answers one request line.
    fn answer(&mut self, line: &str, time: TimeMode) -> String {
        if time == TimeMode::Real {
            let now = Instant::now();
            self.advance((now - self.last).as_secs_f64());
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
                    Some("d".to_owned())
                }
                _ => None,
            },
            Some("R") => {
                if let TimeMode::Virtual(period) = time {
                    self.advance(period.as_secs_f64());
                }
                if let Some(world) = self.world.as_mut() {
                    world.publish(self.reads, &self.truth);
                }
                self.reads = self.reads.saturating_add(1);
                Some(format!(
                    "r,{},{}",
                    self.pulses[0].round() as i64,
                    self.pulses[1].round() as i64
                ))
            }
            Some("E") => Some(format!("e,{},{}", self.speeds[0], self.speeds[1])),
            Some("I") => {
                self.pulses = [0.0; 2];
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
    index: u64,
    world: Option<&mut WorldSensors>,
) -> Result<(), NetError> {
    let mut robot = Robot {
        speeds: [0; 2],
        pulses: [0.0; 2],
        last: Instant::now(),
        slip: options.slip,
        noise: stream_of(options.seed, Purpose::Process, index),
        axle_length: options.axle_length,
        truth: Pose::zeros(),
        reads: 0,
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
    let mut world = options
        .sensors
        .as_ref()
        .map(WorldSensors::serve)
        .transpose()?;
    match options.listen {
        Listen::Tcp(address) => {
            let listener =
                TcpListener::bind(address).map_err(NetError::io(format!("bind TCP {address}")))?;
            let address = listener
                .local_addr()
                .map_err(NetError::io("local address"))?;
            announce(&format!("tcp:{address}"), world.as_ref());
            for (index, client) in listener.incoming().enumerate() {
                if let Some(world) = world.as_mut() {
                    world.begin_session(index as u64);
                }
                if let Ok(mut client) = client {
                    serve_one(&mut client, options, index as u64, world.as_mut())?;
                }
                if let Some(world) = world.as_mut() {
                    world.end_session();
                }
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
            announce(&device, world.as_ref());
            // Held open while serving: the agent may close and reopen the device.
            let _agent_end = agent;
            if let Some(world) = world.as_mut() {
                world.begin_session(0);
            }
            serve_one(&mut emulator, options, 0, world.as_mut())
        }
    }
}

fn announce(address: &str, world: Option<&WorldSensors>) {
    println!("kh4-emulator listening on {address}");
    if let Some(world) = world {
        println!("{}", world.describe());
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
            slip: 0.0,
            seed: 1,
            connections: Some(1),
            axle_length: 0.1047,
            sensors: None,
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
