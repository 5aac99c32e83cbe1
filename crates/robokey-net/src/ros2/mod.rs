//! ROS 2 differential-drive robots (TurtleBot3 and its kin) without a ROS install
//! (docs/ros2.md): the robot agent's `ros2` backend publishes `/cmd_vel` and reads `/odom`
//! over a pure-Rust DDS participant restricted to localhost, and `robokey ros2-sim`
//! emulates such a robot so a whole session runs without hardware. In private sensing the
//! controller reads its pose from a `geometry_msgs/PoseStamped` topic the same way
//! (`--sensor ros2:TOPIC`), which the emulator can publish.
//!
//! On ROS, `/cmd_vel` carries the key bit: the agent must run on the robot's own computer,
//! next to its driver, and nothing of this graph may leave the host.

mod backend;
pub mod msg;
mod node;
mod pose_sensor;
mod sim;

pub use backend::{Ros2Backend, Ros2BackendOptions, Ros2Clock, check_quantum, wheels_to_twist};
pub use node::{Delivery, MAX_DOMAIN_ID, RobotTopics, TopicSpec};
pub use pose_sensor::{PoseTopicOptions, Ros2PoseSensor};
pub use sim::{MocapOptions, Ros2Sim, SimOptions, SimStats, SimTime, quantise};
