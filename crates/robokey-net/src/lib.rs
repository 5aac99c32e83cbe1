//! robokey-net: the network shells around the robokey core — the same sans-I/O endpoints as
//! the simulator, carried over UDP between separate processes.

pub mod backend;
pub mod capture_eve;
pub mod controller_agent;
pub mod error;
pub mod khepera;
pub mod pairing;
pub mod pcap;
pub mod relay;
pub mod robot_agent;
#[cfg(feature = "ros2")]
pub mod ros2;
pub mod secret_file;
pub mod session;
pub mod sim_backend;
pub mod transport;

pub use error::NetError;
