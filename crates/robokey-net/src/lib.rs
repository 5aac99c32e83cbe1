//! robokey-net: the network shells around the robokey core — the same sans-I/O endpoints as
//! the simulator, carried over UDP between separate processes — and the world they run in:
//! the plant and the sensor streams it serves.

pub mod agent;
pub mod backend;
pub mod capture_eve;
pub mod error;
pub mod frame_listing;
#[doc(hidden)]
pub mod fuzzing;
pub mod journal;
pub mod key_delivery;
pub mod key_listing;
pub mod key_slice;
pub mod key_store;
pub mod khepera;
pub mod kme;
pub mod owned_file;
pub mod pairing;
pub mod pcap;
pub mod pose_stream;
pub mod post_store;
pub mod random;
pub mod recorded_eve;
pub mod relay;
#[cfg(feature = "ros2")]
pub mod ros2;
pub mod secret_file;
pub mod sensor;
pub mod sim_backend;
pub mod store_keys;
pub mod world;

pub use error::NetError;
