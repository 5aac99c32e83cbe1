//! `robokey ros2-sim`: an emulated ROS 2 differential-drive robot. It subscribes to
//! `/cmd_vel`, applies each command as a TurtleBot3's firmware does (clamped to its speed
//! limits, then truncated to the command quantum), drives the wheels of its world with it
//! (docs/world.md: the parties' own model unless given one, e.g. `turtlebot3-burger`), and
//! publishes its true pose on `/odom`, so the `ros2` backend and a whole session run without
//! hardware or ROS. For private sensing it also plays the motion capture: the world's
//! controller sensor, as `geometry_msgs/PoseStamped`.

use std::time::{Duration, Instant};

use robokey::Config;
use robokey::config::SensingMode;
use robokey::interrupt::Interrupt;
use robokey::model::{DiffDrive, Unicycle};
use robokey::world::Observed;
use ros2_client::{Context, Node, Publisher};

use super::msg::{Header, Kind, Odometry, Pose, PoseStamped, Time, Twist, TwistStamped};
use super::node::{Listener, RobotTopics, TopicSpec, localhost_node, topic};
use crate::error::NetError;
use crate::world::{StreamAddresses, WorldProcess};

/// How the emulated robot's time advances.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SimTime {
    /// Each `/cmd_vel` message advances the robot by this period (s) at its speeds and
    /// publishes the `/odom` stamped with the new virtual time, so a lockstep session runs
    /// as fast as the agents talk. `/odom` is also repeated at the rate, unchanged, so a
    /// late joiner finds the robot.
    Virtual(f64),
    /// The wheels turn with the wall clock; `/odom` is published at the rate, stamped with
    /// the wall clock.
    Real,
}

/// The emulated motion capture: the world's controller sensor (noise
/// `world.controller_std`, the simulator's `measurement` stream of `run.seed`, replicate 0),
/// published as `geometry_msgs/PoseStamped` with each `/odom` (same stamp). In virtual time
/// it is sampled once per step and the repeats carry the same pose.
#[derive(Clone, Debug, PartialEq)]
pub struct MocapOptions {
    /// The topic and its QoS, e.g. `/mocap/robot/pose`.
    pub topic: TopicSpec,
    /// `header.frame_id` of the poses.
    pub frame_id: String,
}

/// Options of the emulator.
#[derive(Clone, Debug)]
pub struct SimOptions {
    /// Topics, message types and QoS.
    pub topics: RobotTopics,
    /// Time mode.
    pub time: SimTime,
    /// `/odom` rate (Hz): 20 on a TurtleBot3.
    pub rate: f64,
    /// Command quantum (m/s and rad/s): each of v and ω is truncated toward zero to a
    /// multiple of it, as the TurtleBot3 does with `int32(x * 100)` (0.01); 0 for none.
    pub quantum: f64,
    /// Largest |v| (m/s): 0.22 on a TurtleBot3 Burger.
    pub max_v: f64,
    /// Largest |ω| (rad/s): 2.84 on a TurtleBot3 Burger.
    pub max_omega: f64,
    /// `header.frame_id` of `/odom`.
    pub frame_id: String,
    /// `child_frame_id` of `/odom`.
    pub child_frame_id: String,
    /// The motion capture, if published.
    pub mocap: Option<MocapOptions>,
    /// The robot's world: its `[world]`, wheel geometry (`robot.r`, `robot.D`), the
    /// controller sensor's noise and `run.seed`.
    pub world: Config,
    /// Exit after this long without a command (after the first), or without any if none came.
    pub idle_exit: Option<Duration>,
    /// A stop request (SIGINT, SIGTERM).
    pub interrupt: Interrupt,
}

/// What the emulator did, printed when it exits.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct SimStats {
    /// Commands applied.
    pub commands: u64,
    /// `/odom` messages published.
    pub odometry: u64,
    /// Motion-capture poses published.
    pub mocap: u64,
    /// Virtual time reached or wall time run (s).
    pub time: f64,
    /// The final pose (m, m, rad; θ unwrapped).
    pub pose: [f64; 3],
    /// `header.frame_id` of the last `TwistStamped` command (`--stamped`), the frame its
    /// sender said the twist is in.
    pub cmd_frame_id: Option<String>,
}

/// A command as received: planar speeds, finite, and the frame of a `TwistStamped`.
#[derive(Clone, Debug, PartialEq)]
struct Command {
    v: f64,
    omega: f64,
    frame_id: Option<String>,
}

fn command(twist: &Twist, frame_id: Option<&str>) -> Result<Command, String> {
    let (v, omega) = (twist.linear.x, twist.angular.z);
    if v.is_finite() && omega.is_finite() {
        Ok(Command {
            v,
            omega,
            frame_id: frame_id.map(str::to_owned),
        })
    } else {
        Err(format!("speeds ({v}, {omega}) are not finite"))
    }
}

/// Truncates `x` toward zero to a multiple of `quantum` (0: unchanged), computed as the
/// TurtleBot3 does, `int32(x * 100) / 100` for 0.01.
#[must_use]
pub fn quantise(x: f64, quantum: f64) -> f64 {
    if quantum <= 0.0 {
        return x;
    }
    let scale = 1.0 / quantum;
    let scale = if (scale - scale.round()).abs() < 1e-9 {
        scale.round()
    } else {
        scale
    };
    (x * scale).trunc() / scale
}

/// The emulated robot, joined to the graph.
pub struct Ros2Sim {
    options: SimOptions,
    commands: Listener<Command>,
    odom: Publisher<Odometry>,
    mocap: Option<Publisher<PoseStamped>>,
    // Dropped last: the publisher and listener above belong to them.
    _node: Node,
    _context: Context,
}

impl Ros2Sim {
    /// Joins the ROS 2 graph on localhost: subscribes to `/cmd_vel`, offers `/odom`.
    ///
    /// # Errors
    /// Bad options, or the participant cannot be created.
    pub fn start(options: SimOptions) -> Result<Self, NetError> {
        for (name, value, least) in [
            ("rate", options.rate, 0.0),
            ("max-v", options.max_v, 0.0),
            ("max-omega", options.max_omega, 0.0),
        ] {
            if !(value > least && value.is_finite()) {
                return Err(NetError::Usage(format!(
                    "--{name} {value} is not allowed (allowed: > {least})"
                )));
            }
        }
        if !(options.quantum >= 0.0 && options.quantum.is_finite()) {
            return Err(NetError::Usage(format!(
                "--quantum {} is not allowed (allowed: ≥ 0; 0 for none)",
                options.quantum
            )));
        }
        if let SimTime::Virtual(period) = options.time
            && !(period > 0.0 && period.is_finite())
        {
            return Err(NetError::Usage(format!(
                "--period {period} is not allowed (allowed: > 0 s)"
            )));
        }
        let topics = &options.topics;
        let (context, mut node) = localhost_node("ros2_sim", topics.domain_id)?;
        let cmd_topic = topic(&node, &topics.cmd_vel, topics.cmd_kind())?;
        let qos = Some(topics.cmd_vel.qos());
        let subscribe_error =
            |e| NetError::Ros2(format!("subscribe to {}: {e:?}", topics.cmd_vel.name));
        // Every command counts in virtual time: keep the unread ones, not only the latest.
        let queue = 1024;
        let commands = match topics.cmd_kind() {
            Kind::TwistStamped => Listener::spawn(
                node.create_subscription::<TwistStamped>(&cmd_topic, qos)
                    .map_err(subscribe_error)?,
                &topics.cmd_vel.name,
                queue,
                |m: TwistStamped| command(&m.twist, Some(&m.header.frame_id)),
            )?,
            _ => Listener::spawn(
                node.create_subscription::<Twist>(&cmd_topic, qos)
                    .map_err(subscribe_error)?,
                &topics.cmd_vel.name,
                queue,
                |m: Twist| command(&m, None),
            )?,
        };
        let odom_topic = topic(&node, &topics.odom, Kind::Odometry)?;
        let odom = node
            .create_publisher(&odom_topic, Some(topics.odom.qos()))
            .map_err(|e| {
                NetError::Ros2(format!(
                    "create the publisher of {}: {e:?}",
                    topics.odom.name
                ))
            })?;
        let mocap = match &options.mocap {
            Some(mocap) => {
                let pose_topic = topic(&node, &mocap.topic, Kind::PoseStamped)?;
                Some(
                    node.create_publisher(&pose_topic, Some(mocap.topic.qos()))
                        .map_err(|e| {
                            NetError::Ros2(format!(
                                "create the publisher of {}: {e:?}",
                                mocap.topic.name
                            ))
                        })?,
                )
            }
            None => None,
        };
        Ok(Self {
            options,
            commands,
            odom,
            mocap,
            _node: node,
            _context: context,
        })
    }

    /// One line saying what runs (the CLI prints it first).
    #[must_use]
    pub fn describe(&self) -> String {
        let o = &self.options;
        let kind = if o.topics.stamped {
            "TwistStamped"
        } else {
            "Twist"
        };
        let time = match o.time {
            SimTime::Virtual(period) => format!("virtual time, {period} s per command"),
            SimTime::Real => "real time".to_owned(),
        };
        let mocap = o.mocap.as_ref().map_or_else(String::new, |m| {
            format!(
                ", motion capture on {} (noise std {:?}, seed {})",
                m.topic.name,
                o.world.world_model().controller_std,
                o.world.run.seed
            )
        });
        format!(
            "ros2-sim on ROS domain {}, localhost only: {} ({kind}) in, {} at {} Hz out, {time}, \
             quantum {}, |v| ≤ {} m/s, |ω| ≤ {} rad/s{mocap}",
            o.topics.domain_id,
            o.topics.cmd_vel.name,
            o.topics.odom.name,
            o.rate,
            o.quantum,
            o.max_v,
            o.max_omega
        )
    }

    /// The stop request it watches.
    #[must_use]
    pub fn interrupt(&self) -> &Interrupt {
        &self.options.interrupt
    }

    /// What the robot's firmware makes of a command: clamped to its limits, then truncated.
    fn apply(&self, command: &Command) -> (f64, f64) {
        let o = &self.options;
        (
            quantise(command.v.clamp(-o.max_v, o.max_v), o.quantum),
            quantise(command.omega.clamp(-o.max_omega, o.max_omega), o.quantum),
        )
    }

    /// Publishes `/odom` at the true pose and, with a motion capture, its sample.
    fn publish(
        &self,
        observed: &Observed,
        speeds: (f64, f64),
        stamp: Time,
        stats: &mut SimStats,
    ) -> Result<(), NetError> {
        let pose = [observed.pose.x, observed.pose.y, observed.pose.z];
        let seen = [
            observed.measured.x,
            observed.measured.y,
            observed.measured.z,
        ];
        let o = &self.options;
        let header = Header {
            stamp,
            frame_id: o.frame_id.clone(),
        };
        let message = Odometry::planar(header, &o.child_frame_id, pose, [speeds.0, speeds.1]);
        let failed = |name: &str, e: &dyn std::fmt::Debug| {
            NetError::Ros2(format!("publish on {name}: {e:?}"))
        };
        self.odom
            .publish(message)
            .map_err(|e| failed(&o.topics.odom.name, &e))?;
        stats.odometry += 1;
        if let (Some(publisher), Some(mocap)) = (&self.mocap, &o.mocap) {
            let message = PoseStamped {
                header: Header {
                    stamp,
                    frame_id: mocap.frame_id.clone(),
                },
                pose: Pose::planar(seen),
            };
            publisher
                .publish(message)
                .map_err(|e| failed(&mocap.topic.name, &e))?;
            stats.mocap += 1;
        }
        Ok(())
    }

    /// Runs until the idle timeout or a stop request.
    ///
    /// # Errors
    /// Publishing fails, the world's streams cannot be set up, or the command listener fails.
    pub fn run(&self) -> Result<SimStats, NetError> {
        let o = &self.options;
        let drive = DiffDrive {
            wheel_radius: o.world.robot.r,
            axle_length: o.world.robot.axle_length,
        };
        let mut world =
            WorldProcess::new(&o.world, SensingMode::Private, &StreamAddresses::default())?;
        let odom_period = Duration::from_secs_f64(1.0 / o.rate);
        let started = Instant::now();
        let mut stats = SimStats::default();
        let mut speeds = (0.0, 0.0);
        let mut virtual_time = 0.0;
        let mut integrated_to = started;
        let mut last_command = started;
        let mut next_odom = started;
        let mut observed = world.sample();
        loop {
            if o.interrupt.signal().is_some() {
                break;
            }
            let now = Instant::now();
            if o.idle_exit.is_some_and(|idle| now - last_command >= idle) {
                break;
            }
            if now >= next_odom {
                let stamp = match o.time {
                    SimTime::Real => {
                        world.advance((now - integrated_to).as_secs_f64());
                        integrated_to = now;
                        observed = world.sample();
                        Time::now()
                    }
                    SimTime::Virtual(_) => Time::from_secs_f64(virtual_time),
                };
                self.publish(&observed, speeds, stamp, &mut stats)?;
                next_odom += odom_period;
                if next_odom < now {
                    next_odom = now + odom_period;
                }
            }
            let wake = next_odom.min(Instant::now() + Duration::from_millis(50));
            self.commands.wait(wake, true, |_| false)?;
            for arrival in self.commands.drain() {
                last_command = arrival.at;
                stats.commands += 1;
                if arrival.value.frame_id.is_some() {
                    stats.cmd_frame_id.clone_from(&arrival.value.frame_id);
                }
                match o.time {
                    SimTime::Real => {
                        let dt = arrival.at.saturating_duration_since(integrated_to);
                        world.advance(dt.as_secs_f64());
                        integrated_to = integrated_to.max(arrival.at);
                        speeds = self.apply(&arrival.value);
                        world.apply(drive.to_wheels(Unicycle::new(speeds.0, speeds.1)));
                    }
                    SimTime::Virtual(period) => {
                        speeds = self.apply(&arrival.value);
                        world.apply(drive.to_wheels(Unicycle::new(speeds.0, speeds.1)));
                        world.advance(period);
                        virtual_time += period;
                        observed = world.sample();
                        let stamp = Time::from_secs_f64(virtual_time);
                        self.publish(&observed, speeds, stamp, &mut stats)?;
                    }
                }
            }
        }
        stats.time = match o.time {
            SimTime::Real => started.elapsed().as_secs_f64(),
            SimTime::Virtual(_) => virtual_time,
        };
        let pose = world.plant().pose();
        stats.pose = [pose.x, pose.y, pose.z];
        Ok(stats)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_are_truncated_toward_zero_as_the_turtlebot3_does() {
        // int32(x * 100): 0.29 * 100 = 28.999999999999996, so 0.29 becomes 0.28.
        assert_eq!(quantise(0.29, 0.01), 0.28);
        assert_eq!(quantise(0.057, 0.01), 0.05);
        assert_eq!(quantise(-0.057, 0.01), -0.05);
        assert_eq!(quantise(0.009, 0.01), 0.0);
        assert_eq!(quantise(0.057, 0.0), 0.057);
        // With Δ a multiple of the quantum, each offered command u ± Δ is applied as
        // Q(u) ± Δ exactly (u ± Δ of the same sign): the offset from the quantised nominal
        // is ±Δ, as the observer models it. With Δ = 0.035 the two offsets differ.
        let q = |x: f64| quantise(x, 0.01);
        for u in [0.051, 0.0573, 0.1299, 0.2] {
            assert!((q(u + 0.04) - q(u) - 0.04).abs() < 1e-12, "{u}");
            assert!((q(u) - q(u - 0.04) - 0.04).abs() < 1e-12, "{u}");
        }
        let (up, down) = (q(0.051 + 0.035) - q(0.051), q(0.051) - q(0.051 - 0.035));
        assert!(
            (up - 0.03).abs() < 1e-12 && (down - 0.04).abs() < 1e-12,
            "{up} {down}"
        );
    }
}
