//! robokey-net: the network shells around the robokey core — the same sans-I/O endpoints as
//! the simulator, carried over UDP between separate processes.

pub mod backend;
pub mod error;

pub use error::NetError;
