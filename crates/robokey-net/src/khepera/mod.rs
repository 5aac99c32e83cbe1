//! A Khepera IV through K-Team's `kh4server` line protocol (docs/protocol.md): the robot agent's
//! `kh4` backend, and an emulator of the server so a session runs without hardware.
//!
//! The robot agent must run **on the robot**, talking to kh4server locally: driving it over
//! Bluetooth from the laptop would put the chosen command — the key bit — on the radio.

mod backend;
mod emulator;
mod link;
mod protocol;

pub use backend::Kh4Backend;
pub use emulator::{EmulatorOptions, Listen, TimeMode, serve};
pub use link::{Link, MAX_REPLY_BYTES};
pub use protocol::{MAX_UNITS, Odometry, PULSE_M, SPEED_UNIT_M_S, parse_reply, speed_units};
