//! The robot's conversation: it answers verified `Hello`s until a controller binds a session
//! (its first frame under the session key), runs the session on its own clock, then — after a
//! session it did not abort — pools its raw bits (with a store) and answers post-processing and
//! the controller's repeated closing until the controller's `Done` or quiet.

use std::collections::VecDeque;
use std::time::Duration;

use rand::CryptoRng;
use rand::rngs::ChaCha20Rng;
use robokey_secrecy::postprocess::{RobotPost, RobotSnapshot};

use super::linger::{Courtesy, Linger};
use super::post::PostLink;
use super::{Output, Setup};
use crate::model::Pose;
use crate::protocol::auth::{ChannelCounts, Delivery, RobotChannel};
use crate::protocol::{
    Closing, Message, Outcome, Robot, RobotInput, RobotOutput, SessionPlan, Time, Timing,
    agreement_terms, config_digest,
};

/// What the robot's shell is asked to do: its endpoint's outputs are sample requests
/// ([`RobotOutput::Sense`]) and actuations ([`RobotOutput::Apply`]).
pub type RobotAction<A> = Output<A, RobotOutput, RobotSnapshot>;

/// Where the conversation is.
#[derive(Debug)]
enum Stage {
    /// Answering `Hello`s until a controller binds a session, or `until`.
    Listening {
        until: Time,
    },
    /// The session runs.
    Session,
    /// `Done` sent: answering post-processing and the controller's repeated closing.
    Linger(Linger),
    Closed,
}

/// The robot side of a conversation over the network, with addresses of type `A`, its raw
/// key bits drawn from `K`.
pub struct RobotConnection<A, K> {
    channel: RobotChannel<A>,
    plan: SessionPlan,
    timing: Timing,
    wait: Duration,
    stage: Stage,
    endpoint: Option<Robot>,
    post: Option<PostLink<RobotPost>>,
    /// Draws each `nonce_r`: the OS CSPRNG's stream, whatever the key bits come from.
    nonces: ChaCha20Rng,
    /// Draws the raw key bits.
    key_source: K,
    /// Why the last verified `Hello` was refused, if one was.
    refused: Option<String>,
    outputs: VecDeque<RobotAction<A>>,
}

impl<A, K> std::fmt::Debug for RobotConnection<A, K> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RobotConnection")
            .field("stage", &self.stage)
            .field("endpoint", &self.endpoint)
            .finish_non_exhaustive()
    }
}

impl<A: Copy + PartialEq, K: CryptoRng> RobotConnection<A, K> {
    /// Listens from `now` for `wait` for a controller, as `setup` says; `post`
    /// post-processes the sessions it keeps (`--store`); `nonces` (seeded from the OS CSPRNG,
    /// always) draws the handshake's nonces, `key_source` the raw key bits (the OS CSPRNG in
    /// deployment, a seeded stream in a reproducible test).
    pub fn new(
        setup: Setup<'_>,
        wait: Duration,
        post: Option<PostLink<RobotPost>>,
        nonces: ChaCha20Rng,
        key_source: K,
        now: Time,
    ) -> Self {
        let config = setup.config;
        Self {
            channel: RobotChannel::new(
                setup.pairing.clone(),
                config_digest(config),
                agreement_terms(config),
            ),
            plan: SessionPlan::from_config(config, 0),
            timing: setup.timing,
            wait,
            stage: Stage::Listening { until: now + wait },
            endpoint: None,
            post,
            nonces,
            key_source,
            refused: None,
            outputs: VecDeque::new(),
        }
    }

    /// A datagram from `from` arrived at `now`.
    pub fn handle_datagram(&mut self, now: Time, from: A, bytes: &[u8]) {
        match self.channel.on_datagram(from, bytes, &mut self.nonces) {
            Ok(Delivery::Answer { bytes, refused }) => {
                self.outputs.push_back(Output::Transmit { to: from, bytes });
                if refused.is_some() {
                    self.refused = refused;
                }
            }
            Ok(Delivery::Message(message)) => {
                if matches!(self.stage, Stage::Listening { .. }) {
                    self.bind(now);
                }
                self.on_message(now, message);
            }
            // Rejected (and counted by the channel), or the controller's only.
            _ => {}
        }
        self.after(now);
    }

    /// The pose `y(k)` sampled at `now`, as a [`RobotOutput::Sense`] asked.
    pub fn handle_sample(&mut self, now: Time, step: u32, y: Pose) {
        if let (Stage::Session, Some(endpoint)) = (&self.stage, &mut self.endpoint) {
            endpoint.handle_input(now, RobotInput::Sample { step, y });
            self.drain(now);
        }
        self.after(now);
    }

    /// Fires every timer due at `now`.
    pub fn handle_timeout(&mut self, now: Time) {
        match &self.stage {
            Stage::Listening { until } if now >= *until => {
                let rejected = self.channel.counts().rejected.total();
                let mut reason = format!(
                    "no controller bound a session within {:.0} s ({rejected} datagrams \
                     rejected)",
                    self.wait.as_secs_f64()
                );
                if let Some(refused) = &self.refused {
                    reason += &format!("; last Hello refused: {refused}");
                }
                self.outputs
                    .push_back(Output::Finished(Outcome::Aborted(reason)));
                self.close();
            }
            Stage::Session => {
                if let Some(endpoint) = &mut self.endpoint {
                    endpoint.handle_timeout(now);
                }
                self.drain(now);
            }
            _ => {}
        }
        self.after(now);
    }

    /// When the connection must next be woken (`None` once closed).
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Time> {
        match &self.stage {
            Stage::Listening { until } => Some(*until),
            Stage::Session => self.endpoint.as_ref().and_then(Robot::poll_timeout),
            Stage::Linger(linger) => Some(linger.deadline()),
            Stage::Closed => None,
        }
    }

    /// The next output, if any.
    pub fn poll_output(&mut self) -> Option<RobotAction<A>> {
        self.outputs.pop_front()
    }

    /// Ends the conversation now (a stop request, a failing robot or socket): drops the
    /// outputs not taken yet and tells the controller why, once a session is bound.
    pub fn abort(&mut self, reason: String) {
        if matches!(self.stage, Stage::Closed) {
            return;
        }
        // What was queued is moot: only the abort goes out.
        self.outputs.clear();
        self.send(
            Closing::Abort {
                reason: reason.clone(),
            }
            .into(),
        );
        if matches!(self.stage, Stage::Listening { .. } | Stage::Session) {
            self.outputs
                .push_back(Output::Finished(Outcome::Aborted(reason)));
        }
        self.close();
    }

    /// The session layer's counts.
    #[must_use]
    pub fn counts(&self) -> ChannelCounts {
        self.channel.counts()
    }

    /// The session endpoint, once a session is bound.
    #[must_use]
    pub fn endpoint(&self) -> Option<&Robot> {
        self.endpoint.as_ref()
    }

    /// Post-processing, with a store.
    #[must_use]
    pub fn post(&self) -> Option<&PostLink<RobotPost>> {
        self.post.as_ref()
    }

    /// Whether the conversation is over.
    #[must_use]
    pub fn is_closed(&self) -> bool {
        matches!(self.stage, Stage::Closed)
    }

    /// Seals `message` under the session key and sends it to the bound controller (nothing
    /// before binding).
    fn send(&mut self, message: Message) {
        let Some((to, _)) = self.channel.bound() else {
            return;
        };
        if let Some(bytes) = self.channel.seal(message) {
            self.outputs.push_back(Output::Transmit { to, bytes });
        }
    }

    /// A controller bound a session: the robot's clock starts now.
    fn bind(&mut self, now: Time) {
        let (session, confirmer) = match (self.channel.bound(), self.channel.confirmer()) {
            (Some((_, session)), Some(confirmer)) => (session, confirmer),
            _ => return,
        };
        let plan = self.plan.clone().for_session(session, confirmer);
        self.endpoint = Some(Robot::new(plan, self.timing, &mut self.key_source, now));
        self.outputs.push_back(Output::Established(session));
        self.stage = Stage::Session;
    }

    fn on_message(&mut self, now: Time, message: Message) {
        match (&mut self.stage, message) {
            (Stage::Session, message) => {
                if let Some(endpoint) = &mut self.endpoint {
                    endpoint.handle_input(now, RobotInput::Frame(message));
                }
                self.drain(now);
            }
            (Stage::Linger(linger), Message::Post(fragment)) => {
                // With a block in flight the controller's next request may follow its
                // block-time estimate of the plant (seconds for a multilevel block): the
                // robot waits for it the block timeout, not only the quiet time (0.3 s in
                // lockstep) nor the silence timeout — after every fragment, a duplicate the
                // reassembler drops included: the controller repeats its last one while it
                // computes.
                let mut patience = Duration::ZERO;
                if let Some(post) = &mut self.post {
                    let mut out = Vec::new();
                    post.receive(&fragment, &mut out);
                    self.outputs.extend(out.into_iter().map(Output::Post));
                    if post.endpoint().block_in_flight().is_some() {
                        patience = self.timing.block_timeout;
                    }
                }
                linger.busy(now, patience);
                self.flush_post();
            }
            (Stage::Linger(linger), Message::Closing(closing)) => {
                for reply in linger.answer(now, &closing) {
                    self.send(reply);
                }
            }
            _ => {}
        }
    }

    /// Takes the endpoint's outputs; its outcome moves the conversation on.
    fn drain(&mut self, now: Time) {
        while let Some(output) = self.endpoint.as_mut().and_then(Robot::poll_output) {
            match output {
                RobotOutput::Transmit(message) => self.send(message),
                RobotOutput::Finished(outcome) => self.on_outcome(now, outcome),
                other => self.outputs.push_back(Output::Endpoint(other)),
            }
        }
    }

    /// The session ended: a session it aborted, or one without its tags sent, needs nothing
    /// more; otherwise its raw bits are pooled (with a store), and it lingers.
    fn on_outcome(&mut self, now: Time, outcome: Outcome) {
        self.outputs.push_back(Output::Finished(outcome.clone()));
        let Some(endpoint) = &self.endpoint else {
            return self.close();
        };
        let Some(reply) = endpoint.courtesy_reply() else {
            return self.close();
        };
        if let (Some(post), Some((_, session))) = (&mut self.post, self.channel.bound()) {
            let pooled = post.pool(
                session,
                &outcome,
                endpoint.key(),
                Vec::new(),
                robokey_secrecy::postprocess::SessionSamples::new(),
                Vec::new(),
                Vec::new(),
            );
            self.outputs.push_back(Output::Post(pooled));
            self.flush_post();
        }
        self.send(Closing::Done.into());
        self.stage = Stage::Linger(Linger::new(
            Courtesy::new(reply, &self.timing),
            &self.timing,
            now,
        ));
    }

    /// The post-processing endpoint's outputs: store, then send.
    fn flush_post(&mut self) {
        let Some(post) = &mut self.post else {
            return;
        };
        let mut out = Vec::new();
        let flushed = post.flush(&mut out);
        self.outputs.extend(out.into_iter().map(Output::Post));
        match flushed {
            Ok(fragments) => {
                for fragment in fragments {
                    self.send(fragment.into());
                }
            }
            Err(why) => {
                self.outputs.push_back(Output::PostFailed(why));
                self.close();
            }
        }
    }

    /// Closes a lingering conversation once it is over.
    fn after(&mut self, now: Time) {
        if let Stage::Linger(linger) = &self.stage
            && linger.is_over(now)
        {
            self.close();
        }
    }

    fn close(&mut self) {
        self.stage = Stage::Closed;
        self.outputs.push_back(Output::Closed);
    }
}
