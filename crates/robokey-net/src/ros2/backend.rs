//! The robot agent's `ros2` backend: wheel speeds out as `/cmd_vel`, the latest `/odom` in.

use std::time::{Duration, Instant};

use robokey::model::{DiffDrive, Pose, WheelSpeeds};
use ros2_client::{Context, Node, Publisher};

use super::msg::{Header, Kind, Odometry, Stamped, Time, Twist, TwistStamped, Unwrap, type_name};
use super::node::{
    Listener, Peer, RobotTopics, localhost_node, reliability_mismatch, topic, wait_for_peer,
};
use crate::backend::Backend;
use crate::error::NetError;

/// How the backend's samples relate to time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Ros2Clock {
    /// A real robot (or `ros2-sim --time real`): a command is published when the agent sets
    /// it; the sample at `t_k` is the latest `/odom`, which must have arrived at most
    /// `max_age` before (else a named error).
    Real {
        /// Oldest acceptable `/odom` (default: two periods of a 20 Hz odometry, 0.1 s).
        max_age: Duration,
    },
    /// `ros2-sim --time virtual` in lockstep sessions: each sample after the first
    /// publishes the command set since the previous one — the emulator advances one
    /// period `T` per command — and waits for the `/odom` stamped `T` later.
    Virtual {
        /// The period `T` (s), the same as the emulator's `--period`.
        period: f64,
    },
}

/// Options of the `ros2` backend.
#[derive(Clone, Debug)]
pub struct Ros2BackendOptions {
    /// Topics, message types and QoS.
    pub topics: RobotTopics,
    /// Wheel radius `r` and axle length `D` that convert wheel speeds to `(v, ω)`.
    pub drive: DiffDrive,
    /// Real or virtual time.
    pub clock: Ros2Clock,
    /// `header.frame_id` of each `TwistStamped`: the frame the twist is expressed in, the
    /// robot's base (`base_link` on a TurtleBot3).
    pub cmd_frame_id: String,
    /// How long to wait at start for the robot (its `/odom` and a `/cmd_vel` subscriber),
    /// and in virtual time for each step's `/odom`.
    pub timeout: Duration,
}

/// The command publisher: `Twist`, or `TwistStamped` in the frame `frame_id`.
enum CmdPublisher {
    Plain(Publisher<Twist>),
    Stamped {
        publisher: Publisher<TwistStamped>,
        frame_id: String,
    },
}

impl CmdPublisher {
    fn publish(&self, twist: Twist, stamp: Time) -> Result<(), String> {
        match self {
            Self::Plain(publisher) => publisher.publish(twist).map_err(|e| format!("{e:?}")),
            Self::Stamped {
                publisher,
                frame_id,
            } => publisher
                .publish(TwistStamped {
                    header: Header {
                        stamp,
                        frame_id: frame_id.clone(),
                    },
                    twist,
                })
                .map_err(|e| format!("{e:?}")),
        }
    }
}

/// A ROS 2 differential-drive robot (TurtleBot3 and its kin, or `robokey ros2-sim`), on
/// a participant restricted to localhost.
///
/// The pose it reports is the odometry relative to the first sample, in the robot's frame
/// at that sample (so a session starts at the origin facing +x, as on the Khepera IV), with
/// θ unwrapped from the quaternion's yaw message by message.
pub struct Ros2Backend {
    cmd: CmdPublisher,
    cmd_topic: String,
    odom: Listener<Stamped>,
    odom_topic: String,
    drive: DiffDrive,
    clock: Ros2Clock,
    timeout: Duration,
    origin: Option<Stamped>,
    wheels: WheelSpeeds,
    ticks: u32,
    // Dropped last: the publisher and listener above belong to them.
    _node: Node,
    _context: Context,
}

impl std::fmt::Debug for Ros2Backend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ros2Backend")
            .field("cmd_topic", &self.cmd_topic)
            .field("odom_topic", &self.odom_topic)
            .field("clock", &self.clock)
            .finish_non_exhaustive()
    }
}

impl Ros2Backend {
    /// Joins the ROS 2 graph on localhost, waits (up to `options.timeout`) until an
    /// `/odom` arrived and a subscriber of `/cmd_vel` taking the agent's message type is
    /// discovered, then stops the wheels.
    ///
    /// # Errors
    /// The participant cannot be created, or the robot does not show up in time.
    pub fn start(options: &Ros2BackendOptions) -> Result<Self, NetError> {
        let topics = &options.topics;
        let (context, mut node) = localhost_node("robot_agent", topics.domain_id)?;
        let cmd_topic = topic(&node, &topics.cmd_vel, topics.cmd_kind())?;
        let qos = Some(topics.cmd_vel.qos());
        let publisher_error = |e| {
            NetError::Ros2(format!(
                "create the publisher of {}: {e:?}",
                topics.cmd_vel.name
            ))
        };
        let cmd = match topics.cmd_kind() {
            Kind::TwistStamped => CmdPublisher::Stamped {
                publisher: node
                    .create_publisher(&cmd_topic, qos)
                    .map_err(publisher_error)?,
                frame_id: options.cmd_frame_id.clone(),
            },
            _ => CmdPublisher::Plain(
                node.create_publisher(&cmd_topic, qos)
                    .map_err(publisher_error)?,
            ),
        };
        let odom_topic = topic(&node, &topics.odom, Kind::Odometry)?;
        let subscription = node
            .create_subscription::<Odometry>(&odom_topic, Some(topics.odom.qos()))
            .map_err(|e| NetError::Ros2(format!("subscribe to {}: {e:?}", topics.odom.name)))?;
        let mut unwrap = Unwrap::default();
        let odom = Listener::spawn(subscription, &topics.odom.name, 0, move |odom: Odometry| {
            unwrap.stamped(&odom.header, &odom.pose.pose)
        })?;
        let deadline = Instant::now() + options.timeout;
        let hint = "the robot's ROS 2 driver (or `robokey ros2-sim`) must run on this computer, \
                    in the same ROS domain, with localhost discovery (docs/ros2.md)";
        // The other command type, which DDS never matches with ours.
        let (other, flag) = if topics.stamped {
            (Kind::Twist, "the robot takes Twist: drop --ros2-stamped")
        } else {
            (
                Kind::TwistStamped,
                "the robot takes TwistStamped: add --ros2-stamped",
            )
        };
        odom.wait_for_first(
            &context,
            Kind::Odometry,
            (topics.odom.delivery, "--ros2-odom-qos"),
            options.timeout,
            hint,
        )?;
        let waited = options.timeout.as_secs_f64();
        match wait_for_peer(
            &context,
            &topics.cmd_vel.name,
            topics.cmd_kind(),
            Peer::Subscriber,
            deadline,
        ) {
            Ok(()) => {
                if let Some(mismatch) = reliability_mismatch(
                    &context,
                    &topics.cmd_vel.name,
                    topics.cmd_kind(),
                    Peer::Subscriber,
                    topics.cmd_vel.delivery,
                ) {
                    return Err(NetError::Ros2(format!(
                        "{mismatch}: publish reliable (--ros2-cmd-qos reliable)"
                    )));
                }
            }
            Err(why) if why.starts_with("no ") => {
                return Err(NetError::Ros2(format!(
                    "{why} within {waited:.1} s: {hint}"
                )));
            }
            Err(why) if why.contains(&type_name(other).dds_msg_type()) => {
                return Err(NetError::Ros2(format!("{why}: {flag}")));
            }
            Err(why) => return Err(NetError::Ros2(why)),
        }
        let backend = Self {
            cmd,
            cmd_topic: topics.cmd_vel.name.clone(),
            odom,
            odom_topic: topics.odom.name.clone(),
            drive: options.drive,
            clock: options.clock,
            timeout: options.timeout,
            origin: None,
            wheels: WheelSpeeds::zeros(),
            ticks: 0,
            _node: node,
            _context: context,
        };
        if matches!(backend.clock, Ros2Clock::Real { .. }) {
            backend.publish(WheelSpeeds::zeros(), Time::now())?;
        }
        Ok(backend)
    }

    /// Publishes wheel speeds as `v = r(ωR+ωL)/2`, `ω = r(ωR−ωL)/D`.
    fn publish(&self, wheels: WheelSpeeds, stamp: Time) -> Result<(), NetError> {
        let twist = wheels_to_twist(&self.drive, wheels)?;
        self.cmd
            .publish(twist, stamp)
            .map_err(|e| NetError::Ros2(format!("publish on {}: {e}", self.cmd_topic)))
    }

    /// The latest `/odom` in the frame of the first sample.
    fn relative(&mut self, sample: Stamped) -> Pose {
        sample.relative_to(self.origin.get_or_insert(sample))
    }
}

/// `v = r(ωR+ωL)/2`, `ω = r(ωR−ωL)/D` as a planar [`Twist`].
///
/// # Errors
/// A non-finite wheel speed.
pub fn wheels_to_twist(drive: &DiffDrive, wheels: WheelSpeeds) -> Result<Twist, NetError> {
    let input = drive.to_unicycle(wheels);
    if !(input.x.is_finite() && input.y.is_finite()) {
        return Err(NetError::Ros2(format!(
            "wheel speeds ({}, {}) rad/s are not finite",
            wheels.x, wheels.y
        )));
    }
    Ok(Twist::planar(input.x, input.y))
}

impl Backend for Ros2Backend {
    fn sample(&mut self) -> Result<Pose, NetError> {
        match self.clock {
            Ros2Clock::Real { max_age } => {
                let latest = self
                    .odom
                    .latest()
                    .ok_or_else(|| NetError::Ros2(format!("no {} yet", self.odom_topic)))?;
                let age = latest.at.elapsed();
                if age > max_age {
                    return Err(NetError::Ros2(format!(
                        "stale {}: the latest valid message arrived {:.3} s ago (limit {:.3} s){}",
                        self.odom_topic,
                        age.as_secs_f64(),
                        max_age.as_secs_f64(),
                        self.odom.rejections()
                    )));
                }
                Ok(self.relative(latest.value))
            }
            Ros2Clock::Virtual { period } => {
                let Some(origin) = self.origin else {
                    let latest = self
                        .odom
                        .latest()
                        .ok_or_else(|| NetError::Ros2(format!("no {} yet", self.odom_topic)))?;
                    return Ok(self.relative(latest.value));
                };
                self.ticks += 1;
                let due = origin.stamp + f64::from(self.ticks) * period;
                self.publish(self.wheels, Time::from_secs_f64(due - period))?;
                let deadline = Instant::now() + self.timeout;
                if !self
                    .odom
                    .wait(deadline, false, |a| a.value.stamp >= due - period / 2.0)?
                {
                    return Err(NetError::Ros2(format!(
                        "virtual step {}: no {} stamped {due:.3} s within {:.1} s (is \
                         `robokey ros2-sim --time virtual --period {period}` running?){}",
                        self.ticks,
                        self.odom_topic,
                        self.timeout.as_secs_f64(),
                        self.odom.rejections()
                    )));
                }
                let latest = self.odom.latest().expect("the wait saw one");
                Ok(self.relative(latest.value))
            }
        }
    }

    fn set_wheels(&mut self, wheels: WheelSpeeds) -> Result<(), NetError> {
        wheels_to_twist(&self.drive, wheels)?;
        self.wheels = wheels;
        match self.clock {
            Ros2Clock::Real { .. } => self.publish(wheels, Time::now()),
            // Published as the next step's tick.
            Ros2Clock::Virtual { .. } => Ok(()),
        }
    }

    fn stop(&mut self) {
        self.wheels = WheelSpeeds::zeros();
        // In virtual time this advances the emulator by one period, at rest.
        let _ = self.publish(WheelSpeeds::zeros(), Time::now());
    }
}

/// Checks that `Δv` and `Δω` are whole multiples of the robot's command quantum `q`
/// (m/s and rad/s; 0: none), so that the two offered commands of a step are truncated
/// alike and a doublet cancels (docs/ros2.md).
///
/// # Errors
/// A usage error naming the field, its value and the nearest allowed values.
pub fn check_quantum(delta_v: f64, delta_omega: f64, quantum: f64) -> Result<(), NetError> {
    if !(quantum >= 0.0 && quantum.is_finite()) {
        return Err(NetError::Usage(format!(
            "--ros2-quantum {quantum} is not allowed (allowed: ≥ 0; 0 for none)"
        )));
    }
    if quantum == 0.0 {
        return Ok(());
    }
    for (field, delta, unit) in [
        ("protocol.delta_v", delta_v, "m/s"),
        ("protocol.delta_omega", delta_omega, "rad/s"),
    ] {
        let units = delta / quantum;
        if (units - units.round()).abs() > 1e-6 * units.abs().max(1.0) {
            let (below, above) = (units.floor() * quantum, units.ceil() * quantum);
            return Err(NetError::Usage(format!(
                "{field} = {delta} {unit} is not a multiple of the robot's command quantum \
                 {quantum} (--ros2-quantum): the robot truncates each command to it, so the two \
                 offered commands would be truncated unevenly (docs/ros2.md); use e.g. \
                 {below:.4} or {above:.4}"
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wheel_speeds_become_v_and_omega() {
        let drive = DiffDrive {
            wheel_radius: 0.033,
            axle_length: 0.160,
        };
        let twist = wheels_to_twist(&drive, WheelSpeeds::new(4.0, 2.0)).unwrap();
        assert!((twist.linear.x - 0.033 * 3.0).abs() < 1e-15);
        assert!((twist.angular.z - 0.033 * 2.0 / 0.160).abs() < 1e-15);
        assert_eq!(
            (
                twist.linear.y,
                twist.linear.z,
                twist.angular.x,
                twist.angular.y
            ),
            (0.0, 0.0, 0.0, 0.0)
        );
        assert!(wheels_to_twist(&drive, WheelSpeeds::new(f64::NAN, 0.0)).is_err());
    }

    #[test]
    fn deltas_must_be_multiples_of_the_quantum() {
        assert!(check_quantum(0.04, 0.0, 0.01).is_ok());
        assert!(check_quantum(0.03, 0.07, 0.01).is_ok());
        assert!(check_quantum(0.035, 0.0, 0.0).is_ok());
        let err = check_quantum(0.035, 0.0, 0.01).unwrap_err().to_string();
        assert!(err.contains("protocol.delta_v = 0.035"), "{err}");
        assert!(err.contains("0.0300 or 0.0400"), "{err}");
        let err = check_quantum(0.04, 0.015, 0.01).unwrap_err().to_string();
        assert!(err.contains("protocol.delta_omega"), "{err}");
        assert!(check_quantum(0.04, 0.0, -1.0).is_err());
    }
}
