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
mod worker;

use std::net::SocketAddr;
use std::path::PathBuf;

use robokey::connection::{Output, PostLink};
use robokey::protocol::auth::ChannelCounts;
use robokey::protocol::{Outcome, SessionPlan};

use self::key_file::conclude;
use self::post::{AgentStore, StoredEndpoint};
use self::report::{Ending, SessionReport};
use self::socket::{Socket, SocketCounts};
use crate::error::NetError;

/// Handshake frames that fail to verify before an agent that authenticated no peer calls it an
/// authentication failure (exit 4): a peer paired with another secret repeats its `Hello` every
/// retransmission interval; one stray datagram is no such peer.
const HANDSHAKE_TRIES: u64 = 3;

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

/// What an agent's run holds while it carries out its connection's outputs.
pub(crate) struct Carry<'a, P: StoredEndpoint> {
    pub(crate) socket: &'a mut Socket,
    pub(crate) run: &'a mut Run,
    pub(crate) report: &'a mut SessionReport,
    pub(crate) plan: &'a SessionPlan,
    pub(crate) store: Option<&'a mut AgentStore<P>>,
}

impl<P: StoredEndpoint> Carry<'_, P> {
    /// Carries out an output both agents treat alike — sends it, notes the bound session and
    /// the session's end, stores what post-processing asks (before anything that follows is
    /// sent) — and hands back the endpoint's own (a sample request, an actuation, an event).
    ///
    /// # Errors
    /// The store fails, or post-processing stopped.
    pub(crate) fn output<E>(
        &mut self,
        output: Output<SocketAddr, E, P::Snapshot>,
        link: Option<&PostLink<P>>,
    ) -> Result<Option<E>, NetError> {
        match output {
            Output::Transmit { to, bytes } => self.socket.send(to, &bytes),
            Output::Endpoint(own) => return Ok(Some(own)),
            Output::Established(session) => self.report.bound(session, self.plan),
            Output::Finished(outcome) => self.run.outcome = Some(outcome),
            Output::Post(output) => {
                if let (Some(store), Some(link)) = (self.store.as_deref_mut(), link) {
                    store.apply(output, link.endpoint())?;
                }
            }
            Output::PostFailed(why) => return Err(NetError::Usage(why)),
            Output::Closed => {}
        }
        Ok(None)
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
    // A peer kept trying the handshake with another secret (a controller repeats its Hello), or
    // declared the other pairing mode, and none proved it holds ours: a stray datagram with a
    // bad MAC is no such attempt.
    let rejected = counted.channel.rejected;
    let tried = rejected.handshake_bad_mac >= HANDSHAKE_TRIES || rejected.pairing_mode > 0;
    if !counted.authenticated && tried {
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
