//! The robot agent's `kh4` backend: wheel speeds out, encoder odometry in.

use robokey::model::{DiffDrive, Pose, WheelSpeeds};

use super::link::Link;
use super::protocol::{Odometry, parse_reply, set_speed_request, speed_units};
use crate::backend::Backend;
use crate::error::NetError;

/// A Khepera IV driven through kh4server.
#[derive(Debug)]
pub struct Kh4Backend {
    link: Link,
    drive: DiffDrive,
    odometry: Odometry,
}

impl Kh4Backend {
    /// Starts a robot: synchronises with kh4server, then ultrasound off, encoders reset,
    /// wheels stopped. `drive.axle_length` is the odometry's D (robokey's `robot.axle_length`,
    /// 104.7 mm from the authors' lab code; kh4server's own wheel distance is 105.4 mm).
    ///
    /// # Errors
    /// The robot does not answer as expected.
    pub fn start(mut link: Link, drive: DiffDrive) -> Result<Self, NetError> {
        link.synchronise()?;
        for (request, letter) in [("U,0\n", 'U'), ("I\n", 'I'), ("D,0,0\n", 'D')] {
            parse_reply(letter, &link.request(request)?, 0)?;
        }
        Ok(Self {
            link,
            drive,
            odometry: Odometry::new(drive.axle_length),
        })
    }
}

impl Backend for Kh4Backend {
    fn sample(&mut self) -> Result<Pose, NetError> {
        let counts = parse_reply('R', &self.link.request("R\n")?, 2)?;
        // The robot's encoder counters are 32-bit: anything else is not a reading.
        if let Some(bad) = counts.iter().find(|&&c| i32::try_from(c).is_err()) {
            return Err(NetError::Kh4(format!(
                "request R: encoder count {bad} is outside the robot's 32-bit counters"
            )));
        }
        Ok(self.odometry.update(counts[0], counts[1]))
    }

    fn set_wheels(&mut self, wheels: WheelSpeeds) -> Result<(), NetError> {
        let r = self.drive.wheel_radius;
        let request = set_speed_request(speed_units(wheels.y, r), speed_units(wheels.x, r));
        parse_reply('D', &self.link.request(&request)?, 0).map(|_| ())
    }

    fn stop(&mut self) {
        let _ = self.link.request("D,0,0\n");
    }
}
