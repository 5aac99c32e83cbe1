//! Where the controller's pose comes from in private sensing: its own sensor, behind one
//! trait like the robot's drive backends (docs/sensors.md): the world's emulated motion
//! capture, and (with the `ros2` feature) a ROS 2 `geometry_msgs/PoseStamped` topic. A real
//! motion-capture protocol is another implementation of [`Sensor`] and another [`SensorSpec`].
//!
//! The sensor's link is part of the secret: wired or localhost, never a topic or a
//! multicast stream on the lab network (docs/threat-model.md).

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::error::NetError;
use crate::pose_stream::{PoseSample, PoseStreamClient, Reading};

/// The controller's pose sensor, sampled at the robot's sample instants.
pub trait Sensor: Send {
    /// The next sample `y_c(k)` (step k; m, m, rad), waiting until `deadline`:
    /// [`Reading::Nothing`] when none came, [`Reading::Ended`] when the sensor stopped.
    ///
    /// # Errors
    /// The sensor cannot be read.
    fn next_sample(&mut self, deadline: Instant) -> Result<Reading, NetError>;

    /// What it is and where, for messages.
    fn describe(&self) -> String;
}

impl Sensor for PoseStreamClient {
    fn next_sample(&mut self, deadline: Instant) -> Result<Reading, NetError> {
        self.next_until(deadline)
    }

    fn describe(&self) -> String {
        format!("motion capture at {}", self.address())
    }
}

/// A sensor named on the command line.
#[derive(Clone, Debug, PartialEq)]
pub enum SensorSpec {
    /// `mocap:ADDR`: the world's emulated motion capture, a pose stream on TCP.
    Mocap(SocketAddr),
    /// `ros2:TOPIC`: a `geometry_msgs/PoseStamped` topic on a localhost-only participant
    /// (the CLI builds it: the topic's QoS, domain and wait are flags of their own).
    #[cfg(feature = "ros2")]
    Ros2(crate::ros2::PoseTopicOptions),
}

impl SensorSpec {
    /// Parses `mocap:HOST:PORT` (`ros2:TOPIC` is the CLI's, which knows its flags).
    ///
    /// # Errors
    /// Names what is wrong.
    pub fn parse(text: &str) -> Result<Self, NetError> {
        let usage = |why: &str| NetError::Usage(format!("--sensor {text}: {why}"));
        match text.split_once(':') {
            Some(("mocap", address)) => address
                .parse()
                .map(Self::Mocap)
                .map_err(|_| usage("expected mocap:HOST:PORT with a numeric address")),
            _ => Err(usage(
                "expected mocap:HOST:PORT (the world's motion capture) or ros2:TOPIC (a \
                 geometry_msgs/PoseStamped topic)",
            )),
        }
    }

    /// Opens the sensor.
    ///
    /// # Errors
    /// It cannot be reached.
    pub fn open(&self) -> Result<Box<dyn Sensor>, NetError> {
        match self {
            Self::Mocap(address) => Ok(Box::new(PoseStreamClient::connect(
                *address,
                Duration::from_secs(5),
            )?)),
            #[cfg(feature = "ros2")]
            Self::Ros2(options) => Ok(Box::new(crate::ros2::Ros2PoseSensor::open(options)?)),
        }
    }
}

/// What the sensor's thread passes on.
#[derive(Debug)]
pub enum SensorEvent {
    /// A sample.
    Sample(PoseSample),
    /// The sensor stopped (end of stream, or an error: the reason).
    Stopped(String),
}

/// A sensor read on its own thread, so that the controller's loop waits on its socket and
/// takes the samples between datagrams.
#[derive(Debug)]
pub struct SensorFeed {
    events: mpsc::Receiver<SensorEvent>,
    stop: Arc<AtomicBool>,
    reader: Option<JoinHandle<()>>,
}

impl SensorFeed {
    /// Starts reading `sensor`.
    #[must_use]
    pub fn start(mut sensor: Box<dyn Sensor>) -> Self {
        let (sender, events) = mpsc::channel();
        let stop = Arc::new(AtomicBool::new(false));
        let reader = {
            let stop = Arc::clone(&stop);
            std::thread::spawn(move || {
                while !stop.load(Ordering::SeqCst) {
                    let event = match sensor.next_sample(Instant::now() + Duration::from_millis(50))
                    {
                        Ok(Reading::Sample(sample)) => SensorEvent::Sample(sample),
                        Ok(Reading::Nothing) => continue,
                        Ok(Reading::Ended) => {
                            SensorEvent::Stopped(format!("{}: the stream ended", sensor.describe()))
                        }
                        Err(error) => {
                            SensorEvent::Stopped(format!("{}: {error}", sensor.describe()))
                        }
                    };
                    let stopped = matches!(event, SensorEvent::Stopped(_));
                    if sender.send(event).is_err() || stopped {
                        return;
                    }
                }
            })
        };
        Self {
            events,
            stop,
            reader: Some(reader),
        }
    }

    /// The next event already read, if any.
    #[must_use]
    pub fn try_next(&self) -> Option<SensorEvent> {
        self.events.try_recv().ok()
    }
}

impl Drop for SensorFeed {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(reader) = self.reader.take() {
            let _ = reader.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_parse_or_name_the_problem() {
        assert_eq!(
            SensorSpec::parse("mocap:127.0.0.1:7400").unwrap(),
            SensorSpec::Mocap("127.0.0.1:7400".parse().unwrap())
        );
        for bad in ["mocap:localhost", "127.0.0.1:7400", ""] {
            let error = SensorSpec::parse(bad).unwrap_err().to_string();
            assert!(error.contains("--sensor"), "{error}");
        }
    }
}
