//! `--sensor ros2:TOPIC`: the controller's private pose from a `geometry_msgs/PoseStamped`
//! topic (a motion-capture bridge, or `robokey ros2-sim --mocap-topic`), on a participant
//! restricted to localhost like the robot's. The topic is the secret side-channel of
//! private sensing: it must not leave the host (docs/ros2.md).

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use ros2_client::{Context, Node};

use super::msg::{Kind, PoseStamped, Stamped, Unwrap};
use super::node::{Listener, TopicSpec, localhost_node, topic};
use crate::error::NetError;
use crate::pose_stream::{PoseSample, Reading};
use crate::sensor::Sensor;

/// Unread poses kept (the oldest are dropped beyond it): 51 s of steps at T = 0.2 s, or 13 s
/// of the emulator's repeats at 20 Hz; the sensor's thread takes them as they come.
const QUEUE: usize = 256;

/// Where and how to read the pose topic.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseTopicOptions {
    /// DDS domain (ROS_DOMAIN_ID).
    pub domain_id: u16,
    /// The topic (`geometry_msgs/PoseStamped`) and its QoS.
    pub topic: TopicSpec,
    /// The robot's sample period T (s): step k is the pose stamped `T·k` after step 0's.
    pub period: f64,
    /// How long to wait for the first pose when the sensor opens.
    pub timeout: Duration,
}

/// Which step a pose's stamp falls on, if any: `(stamp − origin)/T` within a quarter period
/// of a whole number from 0 to `u32::MAX`.
fn step_of(stamp: f64, origin: f64, period: f64) -> Option<u32> {
    let steps = (stamp - origin) / period;
    let step = steps.round();
    ((steps - step).abs() <= 0.25 && (0.0..=f64::from(u32::MAX)).contains(&step))
        .then_some(step as u32)
}

/// Matches poses to steps.
///
/// The first pose is step 0: it sets the time origin and the frame (the samples are relative
/// to it, so a session starts at the origin facing +x, as the robot's odometry does). A later
/// pose is step k when it is stamped `k·T` after it (within T/4); the first pose of each new
/// step is delivered, repeats and earlier steps are skipped, and a pose off the step grid is
/// counted and skipped. Stamps on the step grid are what the emulator's virtual time gives
/// (`ros2-sim --time virtual`); a real motion-capture clock is not matched to the robot's
/// sample instants (docs/ros2.md).
#[derive(Clone, Debug, PartialEq)]
struct StepGrid {
    period: f64,
    origin: Option<Stamped>,
    /// The next step a pose may be delivered for (`None` once `u32::MAX` was).
    next_step: Option<u32>,
    off_grid: u64,
}

impl StepGrid {
    /// A grid of period `T` (s), origin at the first pose.
    fn new(period: f64) -> Self {
        Self {
            period,
            origin: None,
            next_step: Some(0),
            off_grid: 0,
        }
    }

    /// The sample a pose gives, if it is the first of a new step.
    fn sample(&mut self, pose: Stamped) -> Option<PoseSample> {
        let origin = *self.origin.get_or_insert(pose);
        let Some(step) = step_of(pose.stamp, origin.stamp, self.period) else {
            self.off_grid += 1;
            return None;
        };
        if self.next_step.is_none_or(|next| step < next) {
            return None;
        }
        self.next_step = step.checked_add(1);
        Some(PoseSample {
            step,
            pose: pose.relative_to(&origin),
        })
    }

    /// Poses skipped because their stamp was off the step grid.
    fn off_grid(&self) -> u64 {
        self.off_grid
    }
}

/// The controller's pose sensor on a ROS 2 topic: poses matched to steps by [`StepGrid`].
pub struct Ros2PoseSensor {
    poses: Listener<Stamped>,
    topic: String,
    /// Drained from the listener, not yet looked at.
    pending: VecDeque<Stamped>,
    grid: StepGrid,
    // Dropped last: the listener above belongs to them.
    _node: Node,
    _context: Context,
}

impl Ros2PoseSensor {
    /// Joins the graph on localhost, subscribes to the topic and waits (up to
    /// `options.timeout`) for its first valid pose.
    ///
    /// # Errors
    /// A bad period or topic name, the participant cannot be created, or no valid pose
    /// within the timeout (naming what was found on the graph instead).
    pub fn open(options: &PoseTopicOptions) -> Result<Self, NetError> {
        if !(options.period > 0.0 && options.period.is_finite()) {
            return Err(NetError::Usage(format!(
                "robot.sample_time {} is not allowed for the ROS 2 pose sensor (allowed: > 0 s)",
                options.period
            )));
        }
        let spec = &options.topic;
        let (context, mut node) = localhost_node("controller_sensor", options.domain_id)?;
        let pose_topic = topic(&node, spec, Kind::PoseStamped)?;
        let subscription = node
            .create_subscription::<PoseStamped>(&pose_topic, Some(spec.qos()))
            .map_err(|e| NetError::Ros2(format!("subscribe to {}: {e:?}", spec.name)))?;
        let mut unwrap = Unwrap::default();
        let poses = Listener::spawn(subscription, &spec.name, QUEUE, move |m: PoseStamped| {
            unwrap.stamped(&m.header, &m.pose)
        })?;
        poses.wait_for_first(
            &context,
            Kind::PoseStamped,
            (spec.delivery, "--ros2-pose-qos"),
            options.timeout,
            "the motion-capture bridge (or `robokey ros2-sim --mocap-topic`) must publish \
             geometry_msgs/PoseStamped on this computer, in the same ROS domain, with \
             localhost discovery (docs/ros2.md)",
        )?;
        Ok(Self {
            poses,
            topic: spec.name.clone(),
            pending: VecDeque::new(),
            grid: StepGrid::new(options.period),
            _node: node,
            _context: context,
        })
    }
}

impl Sensor for Ros2PoseSensor {
    fn next_sample(&mut self, deadline: Instant) -> Result<Reading, NetError> {
        loop {
            while let Some(pose) = self.pending.pop_front() {
                if let Some(sample) = self.grid.sample(pose) {
                    return Ok(Reading::Sample(sample));
                }
            }
            if !self.poses.wait(deadline, true, |_| false)? {
                return Ok(Reading::Nothing);
            }
            self.pending
                .extend(self.poses.drain().into_iter().map(|arrival| arrival.value));
        }
    }

    fn describe(&self) -> String {
        let off_grid = match self.grid.off_grid() {
            0 => String::new(),
            n => format!(", {n} poses off the step grid"),
        };
        format!(
            "ROS 2 pose topic {} (localhost only){off_grid}{}",
            self.topic,
            self.poses.rejections()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stamps_fall_on_steps_or_off_the_grid() {
        let (origin, period) = (1_700_000_000.25, 0.2);
        assert_eq!(step_of(origin, origin, period), Some(0));
        assert_eq!(step_of(origin + 0.2 * 7.0, origin, period), Some(7));
        // Virtual time accumulates T in floating point: still step 1020.
        let mut t = origin;
        for _ in 0..1020 {
            t += period;
        }
        assert_eq!(step_of(t, origin, period), Some(1020));
        // Within T/4 of a step, and not beyond.
        assert_eq!(step_of(origin + 0.2 * 3.0 + 0.049, origin, period), Some(3));
        assert_eq!(step_of(origin + 0.2 * 3.0 - 0.049, origin, period), Some(3));
        assert_eq!(step_of(origin + 0.2 * 3.0 + 0.06, origin, period), None);
        // Before the origin, past u32, or not a number.
        assert_eq!(step_of(origin - 0.2, origin, period), None);
        assert_eq!(step_of(origin + 1e12, origin, period), None);
        assert_eq!(step_of(f64::NAN, origin, period), None);
    }

    fn at(stamp: f64, x: f64, y: f64, theta: f64) -> Stamped {
        Stamped {
            pose: robokey::model::Pose::new(x, y, theta),
            stamp,
        }
    }

    #[test]
    fn the_first_pose_of_each_new_step_is_delivered_in_the_first_poses_frame() {
        let mut grid = StepGrid::new(0.2);
        let half_pi = std::f64::consts::FRAC_PI_2;
        // Step 0 at (1, 2) facing +y: the origin of the session's frame.
        let first = grid.sample(at(100.0, 1.0, 2.0, half_pi)).unwrap();
        assert_eq!(first.step, 0);
        assert_eq!(first.pose, robokey::model::Pose::new(0.0, 0.0, 0.0));
        // A repeat of step 0 (the emulator repeats the unchanged pose at its rate).
        assert_eq!(grid.sample(at(100.0, 1.0, 2.0, half_pi)), None);
        // Step 1: 0.1 m further along +y is 0.1 m ahead (+x) in the session's frame.
        let one = grid.sample(at(100.2, 1.0, 2.1, half_pi + 0.05)).unwrap();
        assert_eq!(one.step, 1);
        assert!((one.pose.x - 0.1).abs() < 1e-12 && one.pose.y.abs() < 1e-12);
        assert!((one.pose.z - 0.05).abs() < 1e-12);
        // Off the grid: counted, skipped. An older step: skipped.
        assert_eq!(grid.sample(at(100.3, 0.0, 0.0, 0.0)), None);
        assert_eq!(grid.off_grid(), 1);
        assert_eq!(grid.sample(at(100.0, 0.0, 0.0, 0.0)), None);
        // A lost step leaves a gap; the next one is delivered.
        assert_eq!(grid.sample(at(100.6, 1.0, 2.0, half_pi)).unwrap().step, 3);
        assert_eq!(grid.sample(at(100.4, 1.0, 2.0, half_pi)), None);
    }
}
