//! The ROS 2 options of `robokey robot --backend ros2`, of the controller's
//! `--sensor ros2:TOPIC`, and `robokey ros2-sim` (docs/ros2.md). All need a build with the
//! `ros2` feature; without it they are a usage error that says so.

use clap::{Args, ValueEnum};

/// A topic's reliability QoS.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum QosArg {
    /// Lost samples are resent (ROS 2's default); does not match a best-effort publisher.
    Reliable,
    /// Samples may be lost (ROS 2's sensor-data profile); matches any publisher.
    BestEffort,
}

/// The options of the robot agent's `ros2` backend.
#[derive(Args, Debug, Clone)]
#[command(next_help_heading = "ROS 2 backend (--backend ros2; docs/ros2.md)")]
pub struct Ros2RobotArgs {
    /// Velocity command topic.
    #[arg(long, default_value = "/cmd_vel", value_name = "TOPIC")]
    ros2_cmd_vel: String,
    /// Publish geometry_msgs/TwistStamped (ROS 2 Jazzy's TurtleBot3) instead of Twist.
    #[arg(long)]
    ros2_stamped: bool,
    /// header.frame_id of each TwistStamped: the robot's base frame.
    #[arg(long, default_value = "base_link", value_name = "FRAME")]
    ros2_frame_id: String,
    /// Odometry topic (nav_msgs/Odometry).
    #[arg(long, default_value = "/odom", value_name = "TOPIC")]
    ros2_odom: String,
    /// Reliability of the command topic.
    #[arg(long, value_enum, default_value = "reliable", value_name = "QOS")]
    ros2_cmd_qos: QosArg,
    /// Reliability of the odometry subscription (best-effort matches either publisher).
    #[arg(long, value_enum, default_value = "best-effort", value_name = "QOS")]
    ros2_odom_qos: QosArg,
    /// History depth of both topics.
    #[arg(long, default_value_t = 10, value_name = "N")]
    ros2_depth: usize,
    /// ROS domain (default: $ROS_DOMAIN_ID, else 0).
    #[arg(long, value_name = "ID")]
    ros2_domain: Option<u16>,
    /// The robot's /odom rate (Hz): 20 on a TurtleBot3.
    #[arg(long, default_value_t = 20.0, value_name = "HZ")]
    ros2_odom_rate: f64,
    /// Oldest /odom a sample may use (s; realtime); older is an error. Default: two /odom
    /// periods.
    #[arg(long, value_name = "SECONDS")]
    ros2_max_age: Option<f64>,
    /// The robot's command quantum (m/s and rad/s; 0 for none): protocol.delta_v and
    /// delta_omega must be multiples of it. 0.01 on a TurtleBot3.
    #[arg(long, default_value_t = 0.01, value_name = "Q")]
    ros2_quantum: f64,
    /// Seconds to wait at start for /odom and a /cmd_vel subscriber (and, with --pace
    /// lockstep, for each step's /odom).
    #[arg(long, default_value_t = 10.0, value_name = "SECONDS")]
    ros2_wait: f64,
}

/// The options of the controller's `--sensor ros2:TOPIC`.
#[derive(Args, Debug, Clone)]
#[command(next_help_heading = "ROS 2 pose sensor (--sensor ros2:TOPIC; docs/ros2.md)")]
pub struct Ros2SensorArgs {
    /// Reliability of the pose subscription (best-effort matches either publisher).
    #[arg(long, value_enum, default_value = "best-effort", value_name = "QOS")]
    ros2_pose_qos: QosArg,
    /// History depth of the pose topic.
    #[arg(long, default_value_t = 10, value_name = "N")]
    ros2_depth: usize,
    /// ROS domain (default: $ROS_DOMAIN_ID, else 0).
    #[arg(long, value_name = "ID")]
    ros2_domain: Option<u16>,
    /// Seconds to wait at start for the first pose.
    #[arg(long, default_value_t = 10.0, value_name = "SECONDS")]
    ros2_wait: f64,
}

/// Where `ros2-sim`'s time comes from.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum SimTimeArg {
    /// Each /cmd_vel message advances one period: for `--pace lockstep` sessions.
    Virtual,
    /// The wheels turn with the wall clock: for `--pace realtime` sessions.
    Real,
}

#[derive(Args, Debug)]
pub struct SimArgs {
    /// Time mode.
    #[arg(long, value_enum, default_value = "virtual")]
    time: SimTimeArg,
    /// Virtual time advanced per /cmd_vel message (s): the robot agent's T.
    #[arg(long, default_value_t = 0.2)]
    period: f64,
    /// /odom rate (Hz); in virtual time, how often the unchanged /odom is repeated.
    #[arg(long, default_value_t = 20.0)]
    rate: f64,
    /// Command quantum (m/s and rad/s): v and ω are truncated toward zero to multiples of
    /// it, as the TurtleBot3 does (0 for none).
    #[arg(long, default_value_t = 0.01)]
    quantum: f64,
    /// Largest |v| (m/s): a TurtleBot3 Burger's.
    #[arg(long, default_value_t = 0.22)]
    max_v: f64,
    /// Largest |ω| (rad/s): a TurtleBot3 Burger's.
    #[arg(long, default_value_t = 2.84)]
    max_omega: f64,
    /// Velocity command topic.
    #[arg(long, default_value = "/cmd_vel")]
    cmd_vel: String,
    /// Subscribe to geometry_msgs/TwistStamped instead of Twist.
    #[arg(long)]
    stamped: bool,
    /// Odometry topic.
    #[arg(long, default_value = "/odom")]
    odom: String,
    /// Reliability of the command subscription.
    #[arg(long, value_enum, default_value = "reliable")]
    cmd_qos: QosArg,
    /// Reliability of the odometry publisher.
    #[arg(long, value_enum, default_value = "reliable")]
    odom_qos: QosArg,
    /// History depth of both topics.
    #[arg(long, default_value_t = 10)]
    depth: usize,
    /// ROS domain (default: $ROS_DOMAIN_ID, else 0).
    #[arg(long)]
    domain: Option<u16>,
    /// header.frame_id of /odom.
    #[arg(long, default_value = "odom")]
    frame_id: String,
    /// child_frame_id of /odom.
    #[arg(long, default_value = "base_footprint")]
    child_frame_id: String,
    /// Exit after this many seconds without a command (default: run until killed).
    #[arg(long)]
    idle_exit: Option<f64>,
    /// Also play the controller's motion capture (private sensing): publish the true pose
    /// plus noise `sensing.controller_std` as geometry_msgs/PoseStamped on this topic, e.g.
    /// /mocap/robot/pose, with each /odom. The controller reads it with --sensor ros2:TOPIC.
    #[arg(long, value_name = "TOPIC")]
    mocap_topic: Option<String>,
    /// Reliability of the motion-capture publisher.
    #[arg(long, value_enum, default_value = "reliable")]
    mocap_qos: QosArg,
    /// header.frame_id of the motion-capture poses.
    #[arg(long, default_value = "mocap")]
    mocap_frame_id: String,
    #[command(flatten)]
    noise: crate::configuration::WorldNoiseArgs,
}

#[cfg(not(feature = "ros2"))]
const NOT_BUILT: &str = "this robokey was built without ROS 2 support: build it with \
                         `cargo build --release --features robokey-cli/ros2` (docs/ros2.md)";

/// `robokey ros2-sim` without the feature.
#[cfg(not(feature = "ros2"))]
pub fn ros2_sim(_args: SimArgs) -> anyhow::Result<crate::exit::Status> {
    crate::exit::usage!("{NOT_BUILT}")
}

/// The controller's `--sensor ros2:TOPIC`, without the feature.
#[cfg(not(feature = "ros2"))]
pub fn sensor(
    topic: &str,
    _args: &Ros2SensorArgs,
    _config: &robokey::Config,
    _pace: robokey::protocol::Pace,
) -> anyhow::Result<robokey_net::sensor::SensorSpec> {
    crate::exit::usage!("--sensor ros2:{topic}: {NOT_BUILT}")
}

/// The robot agent's session over the `ros2` backend, without the feature.
#[cfg(not(feature = "ros2"))]
pub fn run_robot<R: rand::CryptoRng>(
    _args: &Ros2RobotArgs,
    _config: &robokey::Config,
    _options: &robokey_net::agent::robot::RobotOptions,
    _key_source: &mut R,
) -> anyhow::Result<robokey_net::agent::report::SessionReport> {
    crate::exit::usage!("--backend ros2: {NOT_BUILT}")
}

#[cfg(feature = "ros2")]
pub use with_ros2::{ros2_sim, run_robot, sensor};

#[cfg(feature = "ros2")]
mod with_ros2 {
    use std::time::Duration;

    use anyhow::Result;
    use robokey::protocol::Pace;
    use robokey_net::agent::report::SessionReport;
    use robokey_net::agent::robot::{RobotOptions, run_robot as run_session};
    use robokey_net::ros2::{
        Delivery, MocapOptions, PoseTopicOptions, RobotTopics, Ros2Backend, Ros2BackendOptions,
        Ros2Clock, Ros2Sim, SimOptions, SimTime, TopicSpec, check_quantum,
    };
    use robokey_net::sensor::SensorSpec;

    use super::{QosArg, Ros2RobotArgs, Ros2SensorArgs, SimArgs, SimTimeArg};
    use crate::exit::{Status, on_signals, usage};

    fn delivery(qos: QosArg) -> Delivery {
        match qos {
            QosArg::Reliable => Delivery::Reliable,
            QosArg::BestEffort => Delivery::BestEffort,
        }
    }

    /// `--ros2-domain`/`--domain`, else `$ROS_DOMAIN_ID`, else 0.
    fn domain(flag: &str, given: Option<u16>) -> Result<u16> {
        let (id, from) = match given {
            Some(id) => (id, format!("--{flag} {id}")),
            None => match std::env::var("ROS_DOMAIN_ID") {
                Ok(text) if !text.trim().is_empty() => match text.trim().parse::<u16>() {
                    Ok(id) => (id, format!("ROS_DOMAIN_ID={text}")),
                    Err(_) => usage!("ROS_DOMAIN_ID={text} is not a domain id (allowed: 0 to 232)"),
                },
                _ => (0, String::new()),
            },
        };
        if id > robokey_net::ros2::MAX_DOMAIN_ID {
            usage!(
                "{from}: domain {id} is not allowed (allowed: 0 to {})",
                robokey_net::ros2::MAX_DOMAIN_ID
            );
        }
        Ok(id)
    }

    fn positive(name: &str, value: f64) -> Result<f64> {
        if !(value > 0.0 && value <= 86_400.0) {
            usage!("--{name} {value} is not allowed (allowed: > 0 and ≤ 86400)");
        }
        Ok(value)
    }

    /// Runs the robot agent's session on a ROS 2 robot.
    pub fn run_robot<R: rand::CryptoRng>(
        args: &Ros2RobotArgs,
        config: &robokey::Config,
        options: &RobotOptions,
        key_source: &mut R,
    ) -> Result<SessionReport> {
        check_quantum(
            config.protocol.delta_v,
            config.perturbed_delta_omega(),
            args.ros2_quantum,
        )?;
        let rate = positive("ros2-odom-rate", args.ros2_odom_rate)?;
        let max_age = positive("ros2-max-age", args.ros2_max_age.unwrap_or(2.0 / rate))?;
        let wait = positive("ros2-wait", args.ros2_wait)?;
        let clock = match options.timing.pace {
            Pace::Lockstep => Ros2Clock::Virtual {
                period: config.robot.sample_time,
            },
            Pace::Realtime => Ros2Clock::Real {
                max_age: Duration::from_secs_f64(max_age),
            },
        };
        let topics = RobotTopics {
            domain_id: domain("ros2-domain", args.ros2_domain)?,
            cmd_vel: TopicSpec {
                name: args.ros2_cmd_vel.clone(),
                delivery: delivery(args.ros2_cmd_qos),
                depth: args.ros2_depth,
            },
            stamped: args.ros2_stamped,
            odom: TopicSpec {
                name: args.ros2_odom.clone(),
                delivery: delivery(args.ros2_odom_qos),
                depth: args.ros2_depth,
            },
        };
        let mut backend = Ros2Backend::start(&Ros2BackendOptions {
            topics,
            drive: robokey::model::DiffDrive {
                wheel_radius: config.robot.r,
                axle_length: config.robot.axle_length,
            },
            clock,
            cmd_frame_id: args.ros2_frame_id.clone(),
            timeout: Duration::from_secs_f64(wait),
        })?;
        Ok(run_session(config, &mut backend, key_source, options)?)
    }

    /// The controller's `--sensor ros2:TOPIC`.
    pub fn sensor(
        topic: &str,
        args: &Ros2SensorArgs,
        config: &robokey::Config,
        pace: Pace,
    ) -> Result<SensorSpec> {
        let spec = TopicSpec {
            name: topic.to_owned(),
            delivery: delivery(args.ros2_pose_qos),
            depth: args.ros2_depth,
        };
        if let Err(e) = spec.ros_name() {
            usage!("--sensor ros2:{topic}: {e}");
        }
        if pace != Pace::Lockstep {
            usage!(
                "--sensor ros2:{topic} needs --pace lockstep: its poses are matched to the \
                 robot's steps by their stamps in the emulator's virtual time (ros2-sim --time \
                 virtual); matching a real motion-capture clock to the robot's sample instants \
                 is not implemented (docs/ros2.md)"
            );
        }
        Ok(SensorSpec::Ros2(PoseTopicOptions {
            domain_id: domain("ros2-domain", args.ros2_domain)?,
            topic: spec,
            period: config.robot.sample_time,
            timeout: Duration::from_secs_f64(positive("ros2-wait", args.ros2_wait)?),
        }))
    }

    /// `robokey ros2-sim`.
    pub fn ros2_sim(args: SimArgs) -> Result<Status> {
        let time = match args.time {
            SimTimeArg::Virtual => SimTime::Virtual(positive("period", args.period)?),
            SimTimeArg::Real => SimTime::Real,
        };
        let idle_exit = args
            .idle_exit
            .map(|s| positive("idle-exit", s).map(Duration::from_secs_f64))
            .transpose()?;
        let config = args.noise.load()?;
        let mocap = args.mocap_topic.map(|name| MocapOptions {
            topic: TopicSpec {
                name,
                delivery: delivery(args.mocap_qos),
                depth: args.depth,
            },
            frame_id: args.mocap_frame_id,
        });
        let sim = Ros2Sim::start(SimOptions {
            topics: RobotTopics {
                domain_id: domain("domain", args.domain)?,
                cmd_vel: TopicSpec {
                    name: args.cmd_vel,
                    delivery: delivery(args.cmd_qos),
                    depth: args.depth,
                },
                stamped: args.stamped,
                odom: TopicSpec {
                    name: args.odom,
                    delivery: delivery(args.odom_qos),
                    depth: args.depth,
                },
            },
            time,
            rate: args.rate,
            quantum: args.quantum,
            max_v: args.max_v,
            max_omega: args.max_omega,
            frame_id: args.frame_id,
            child_frame_id: args.child_frame_id,
            mocap,
            world: config,
            idle_exit,
            interrupt: on_signals()?,
        })?;
        println!("{}", sim.describe());
        let stats = sim.run()?;
        println!("ros2-sim: {}", serde_json::to_string(&stats)?);
        Ok(match sim.interrupt().signal() {
            Some(signal) => Status::Interrupted(signal),
            None => Status::Success,
        })
    }
}
