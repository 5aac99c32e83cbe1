//! robokey: a remotely controlled robot and its controller agree on a secret key through
//! the robot's motion (Naseri, Lucia, Youssef, IFAC 2023).
//!
//! This crate is the I/O-free core: kinematics ([`model`]), references ([`trajectory`]),
//! the tracking controller ([`control`]), the unknown-input observer ([`observer`]), block
//! codes ([`code`]), the protocol endpoints ([`protocol`]), the eavesdroppers ([`eve`]),
//! private sensing ([`private`]), a side's whole conversation over the network
//! ([`connection`]), configuration ([`config`]), seeded random streams ([`rng`]), stop
//! requests ([`interrupt`]), a virtual network ([`pair`]), the true physics apart from the
//! parties' configuration ([`world`]) and the closed-loop simulation of one run ([`sim`]).
//! Time is an input ([`protocol::Time`]); randomness is
//! passed in.

pub mod code;
pub mod config;
pub mod connection;
pub mod control;
pub mod estimate;
pub mod eve;
#[doc(hidden)]
pub mod fuzzing;
pub mod interrupt;
pub mod metrics;
pub mod model;
pub mod observer;
pub mod pair;
pub mod post_settings;
pub mod private;
pub mod protocol;
pub mod rng;
pub mod sim;
pub mod trajectory;
pub mod world;

pub use config::Config;
pub use metrics::Metrics;
