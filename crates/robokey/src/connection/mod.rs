//! A whole conversation of one side over the network, sans I/O (docs/protocol.md, "On a
//! network"): the session layer's handshake and sealing ([`crate::protocol::auth`]), the
//! session endpoint, post-processing after it ([`post`]) and the courtesy of a side that has
//! its outcome (`linger`). An agent is one loop around a connection: wait for a datagram
//! until [`ControllerConnection::poll_timeout`] (or the robot's), feed it or the timeout, and
//! carry out the outputs — send bytes, sample or drive the robot, write the store, report.

pub mod computation;
pub(crate) mod controller;
mod linger;
pub mod post;
pub(crate) mod robot;
pub mod slices;

pub use computation::{BlockComputation, Computed};
pub use controller::{ControllerAction, ControllerConnection};
pub use post::{PostEndpoint, PostLink, PostOutput};
pub use robot::{RobotAction, RobotConnection};

use crate::config::Config;
use crate::protocol::auth::PairingSecret;
use crate::protocol::{Outcome, Timing};

/// What a side's conversation is configured with.
#[derive(Clone, Copy, Debug)]
pub struct Setup<'a> {
    /// A validated configuration: the agreement terms and the side's own settings.
    pub config: &'a Config,
    /// The pairing secret ([`PairingSecret::unauthenticated`] for `--unauthenticated`).
    pub pairing: &'a PairingSecret,
    /// Pacing and timeouts.
    pub timing: Timing,
}

/// What a connection asks of its shell, or tells it, in order.
#[derive(Clone, Debug)]
pub enum Output<A, E, S> {
    /// Send these bytes to `to` (best effort: a datagram that cannot be sent is lost).
    Transmit {
        /// The address.
        to: A,
        /// The sealed frame.
        bytes: Vec<u8>,
    },
    /// What the session endpoint asks of the shell or tells it: the robot's sample requests
    /// and actuations, the controller's events.
    Endpoint(E),
    /// The session layer bound session `0` (its id): the endpoint runs.
    Established(u32),
    /// The session ended for this side.
    Finished(Outcome),
    /// Post-processing: store before what follows is sent; what happened.
    Post(PostOutput<S>),
    /// Post-processing stopped, and why: the session's outcome stands.
    PostFailed(String),
    /// The conversation is over: nothing more is sent or needed.
    Closed,
}
