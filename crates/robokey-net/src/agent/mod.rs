//! The agents (docs/protocol.md, "On a network"): each is one loop around its side's
//! connection in the core ([`robokey::connection`]) — wait on the socket until the
//! connection's next timeout, feed the datagram or the timeout, carry out the outputs (send,
//! sample or drive the robot, read the sensor, write the store) — and a report.

pub mod controller;
pub mod key_file;
pub mod post;
pub mod report;
pub mod robot;
pub mod socket;

use std::path::PathBuf;

use robokey::protocol::Outcome;
use robokey::protocol::auth::ChannelCounts;

use self::key_file::conclude;
use self::post::{AgentStore, StoredEndpoint};
use self::report::{Ending, SessionReport};
use self::socket::SocketCounts;
use crate::error::NetError;

/// How an agent's run went beyond its report's counters.
#[derive(Debug, Default)]
pub(crate) struct Run {
    /// How the session ended for this side.
    pub(crate) outcome: Option<Outcome>,
    /// What stopped the conversation before it closed: a signal, a socket, robot or sensor
    /// error.
    pub(crate) stopped: Option<NetError>,
    /// What stopped post-processing after the session: the store, a message too long.
    pub(crate) post_error: Option<NetError>,
    /// Whether the agent stops now, whatever the connection still waits for.
    pub(crate) halted: bool,
}

impl Run {
    /// Stops on `error`: before the outcome it ends the session; after it, only the
    /// post-processing and the courtesy to the peer, which a stop shortens.
    pub(crate) fn stop(&mut self, error: NetError, post_running: bool) {
        self.halted = true;
        if self.outcome.is_none() {
            self.stopped = Some(error);
        } else if post_running {
            self.post_error.get_or_insert(error);
        }
    }
}

/// What the agent's session layer and socket counted, and whether a peer proved it holds the
/// pairing secret.
pub(crate) struct Counted {
    pub(crate) socket: SocketCounts,
    pub(crate) channel: ChannelCounts,
    pub(crate) authenticated: bool,
}

/// Completes `report`: frames, outcome and key file (`key`, kept in units of
/// `bits_per_unit` bits, written to `key_out` when the peer confirmed it), how the run
/// stopped, and post-processing's report (`store` with its endpoint).
pub(crate) fn finish<E: StoredEndpoint>(
    mut report: SessionReport,
    run: Run,
    key: &[u8],
    key_out: Option<&PathBuf>,
    bits_per_unit: usize,
    counted: &Counted,
    store: Option<(AgentStore<E>, &E)>,
) -> SessionReport {
    report.count_frames(counted.socket, counted.channel);
    let outcome = run
        .outcome
        .unwrap_or_else(|| Outcome::Aborted("ended without an outcome".into()));
    conclude(&mut report, &outcome, key, key_out, bits_per_unit);
    let rejected = counted.channel.rejected;
    if !counted.authenticated && rejected.bad_mac + rejected.pairing_mode > 0 {
        report.ending = Ending::AuthenticationFailed;
    }
    if let Some(error) = &run.stopped {
        report.set_error(error);
    }
    if let Some(error) = &run.post_error {
        report.post_stopped(error);
    }
    report.set_post(store.map(|(store, endpoint)| store.finish(endpoint)));
    report
}
