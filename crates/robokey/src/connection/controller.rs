//! The controller's conversation: `Hello` until the robot's `HelloAck` verifies, `Ready` until
//! the robot is heard, the session, then — after a confirmed session, with a store —
//! post-processing until no block is in flight, and the courtesy of a side that has its
//! outcome.

use std::collections::VecDeque;

use rand::rngs::ChaCha20Rng;
use robokey_secrecy::postprocess::{ControllerPost, ControllerSnapshot, SessionSamples};

use super::computation::{BlockComputation, Computed};
use super::linger::{Courtesy, Linger};
use super::post::{PostLink, PostOutput};
use super::{Output, Setup};
use crate::config::{Config, Reconciliation, SensingMode, Sizing};
use crate::estimate::kept_doublet;
use crate::model::Pose;
use crate::protocol::auth::{AuthMode, ChannelCounts, ControllerChannel, Delivery, PairingSecret};
use crate::protocol::timing::earliest;
use crate::protocol::{
    Closing, Controller, ControllerEvent, ControllerInput, ControllerOutput, Handshake, Message,
    Outcome, PostFragment, SessionPlan, Time, Timing, agreement_terms, config_digest,
};

/// How many `Ready`s go unanswered before the controller starts a fresh handshake.
const READY_TRIES: u32 = 10;

/// Most handshakes one conversation starts.
const HANDSHAKES: u32 = 3;

/// While a computation handed to the shell is outstanding, the controller repeats its last
/// post-processing fragment this many times per block timeout: the robot waits the block
/// timeout after each fragment it receives (a duplicate, which it otherwise ignores,
/// included), so it stays for as long as the controller computes, unless all of them are
/// lost (probability `p⁶` at a loss rate `p`).
const KEEPALIVES_PER_BLOCK_TIMEOUT: u32 = 6;

/// What the controller's shell is asked to do.
pub type ControllerAction<A> = Output<A, ControllerEvent, ControllerSnapshot>;

/// Where the conversation is.
#[derive(Debug)]
enum Stage {
    /// `Hello` repeats until a `HelloAck` (or a `Refuse`) verifies, until `give_up`.
    Handshake {
        next_hello: Time,
        give_up: Time,
    },
    /// The session runs; `Ready` repeats at `ready_at` until the robot is heard, `readies`
    /// sent so far.
    Session {
        ready_at: Time,
        readies: u32,
    },
    /// After the outcome: post-processing until no block is in flight, its retransmission
    /// timer, when the robot last answered it, whether the last flush computed a block's
    /// estimate (the robot's silence then restarts at the next wake-up, when the answer has
    /// left: the controller's own computing is not the robot's silence), and, while a
    /// computation handed to the shell is outstanding (the robot silent, waiting for its
    /// answer), when the last fragment is next repeated to keep the robot waiting.
    Post {
        courtesy: Courtesy,
        timer: Time,
        heard: Time,
        computed: bool,
        keepalive: Option<Time>,
    },
    /// `Done` sent: answering until the robot's `Done` or quiet.
    Linger(Linger),
    Closed,
}

/// The controller side of a conversation over the network, with addresses of type `A`.
pub struct ControllerConnection<A> {
    channel: ControllerChannel<A>,
    /// The counts of the channels of earlier handshakes (restarted when `Ready` went
    /// unanswered).
    earlier: ChannelCounts,
    /// Handshakes started.
    handshakes: u32,
    /// Draws each handshake's `nonce_c`: seeded from the OS CSPRNG.
    nonces: ChaCha20Rng,
    config: Config,
    plan: SessionPlan,
    pairing: PairingSecret,
    timing: Timing,
    stage: Stage,
    endpoint: Option<Controller>,
    post: Option<PostLink<ControllerPost>>,
    /// The Eve separation the camera statement gives each decided bit: they size the keys of
    /// the blocks this session enters (private sensing).
    separations: Vec<f64>,
    /// What the pool keeps of the decided doublets for the block's estimate of the plant or
    /// its commands check ([`keeps_samples`]; empty otherwise).
    kept: SessionSamples,
    /// The controller's LLR of each decided bit (private sensing), which LDPC reconciliation
    /// decodes on (`postprocess.reconciliation = "ldpc"`; empty otherwise).
    llrs: Vec<f64>,
    /// Multilevel symbols: each decided doublet's patterns' log-likelihoods as kept
    /// ([`super::slices::keep_likelihoods`]), from which its later slices' LLRs follow.
    likelihoods: Vec<i16>,
    /// The last post-processing fragment sent, which keeps the robot waiting while the shell
    /// computes.
    last_fragment: Option<PostFragment>,
    outputs: VecDeque<ControllerAction<A>>,
}

impl<A> std::fmt::Debug for ControllerConnection<A> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ControllerConnection")
            .field("stage", &self.stage)
            .field("endpoint", &self.endpoint)
            .finish_non_exhaustive()
    }
}

impl<A: Copy + PartialEq + std::fmt::Display> ControllerConnection<A> {
    /// Opens session `session` with the robot at `robot` at `now` (the first `Hello` goes
    /// out), as `setup` says; `post` post-processes confirmed sessions (`--store`); `nonces`
    /// (seeded from the OS CSPRNG) draws each handshake's `nonce_c`.
    pub fn new(
        setup: Setup<'_>,
        robot: A,
        session: u32,
        post: Option<PostLink<ControllerPost>>,
        mut nonces: ChaCha20Rng,
        now: Time,
    ) -> Self {
        let (config, pairing, timing) = (setup.config, setup.pairing, setup.timing);
        let channel = ControllerChannel::new(
            pairing.clone(),
            robot,
            session,
            config_digest(config),
            agreement_terms(config),
            &mut nonces,
        );
        let mut connection = Self {
            plan: SessionPlan::from_config(config, session),
            config: config.clone(),
            pairing: pairing.clone(),
            timing,
            stage: Stage::Handshake {
                next_hello: now + timing.retransmit_interval(),
                give_up: now + timing.silence_timeout,
            },
            endpoint: None,
            post,
            separations: Vec::new(),
            kept: SessionSamples::new(),
            llrs: Vec::new(),
            likelihoods: Vec::new(),
            last_fragment: None,
            outputs: VecDeque::new(),
            channel,
            earlier: ChannelCounts::default(),
            handshakes: 1,
            nonces,
        };
        connection.send_hello();
        connection
    }

    /// A datagram from `from` arrived at `now`.
    pub fn handle_datagram(&mut self, now: Time, from: A, bytes: &[u8]) {
        match self.channel.on_datagram(from, bytes) {
            Ok(Delivery::Established) if matches!(self.stage, Stage::Handshake { .. }) => {
                self.establish(now);
            }
            Ok(Delivery::Refused(reason)) if matches!(self.stage, Stage::Handshake { .. }) => {
                self.end(Outcome::Aborted(format!(
                    "robot refused the session: {reason}"
                )));
            }
            Ok(Delivery::Message(message)) => self.on_message(now, message),
            // Rejected (and counted by the channel), or not for this stage.
            _ => {}
        }
        self.after(now);
    }

    /// The controller's own sensor sampled `y_c(k)` at `now` (private sensing).
    pub fn handle_sensor(&mut self, now: Time, step: u32, pose: Pose) {
        self.feed(now, ControllerInput::Sensor { step, pose });
    }

    /// The controller's own sensor stopped for good (private sensing).
    pub fn handle_sensor_stopped(&mut self, now: Time, why: String) {
        self.feed(now, ControllerInput::SensorStopped(why));
    }

    /// Fires every timer due at `now`.
    pub fn handle_timeout(&mut self, now: Time) {
        match &mut self.stage {
            Stage::Handshake {
                next_hello,
                give_up,
            } => {
                if now >= *give_up {
                    let reason = self.no_hello_ack();
                    return self.end(Outcome::Aborted(reason));
                }
                if now >= *next_hello {
                    *next_hello = now + self.timing.retransmit_interval();
                    self.send_hello();
                }
            }
            Stage::Session { ready_at, readies } => {
                let heard = self.endpoint.as_ref().is_some_and(Controller::robot_heard);
                if !heard && now >= *ready_at {
                    if *readies >= READY_TRIES {
                        // The robot never bound this handshake (a replayed Hello may have
                        // pushed it out): start a fresh one.
                        return self.rehandshake(now);
                    }
                    *ready_at = now + self.timing.retransmit_interval();
                    *readies += 1;
                    self.send(Handshake::Ready.into());
                }
                if let Some(endpoint) = &mut self.endpoint {
                    endpoint.handle_timeout(now);
                }
                self.drain(now);
            }
            Stage::Post {
                timer, keepalive, ..
            } => {
                if now >= *timer {
                    *timer = now + self.timing.retransmit_interval();
                    if let Some(post) = &mut self.post {
                        post.on_timeout();
                    }
                }
                if let Some(at) = keepalive
                    && now >= *at
                {
                    *at = now + keepalive_interval(&self.timing);
                    if let Some(fragment) = self.last_fragment.clone() {
                        self.send(fragment.into());
                    }
                }
            }
            Stage::Linger(_) | Stage::Closed => {}
        }
        self.after(now);
    }

    /// When the connection must next be woken (`None` once closed).
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Time> {
        match &self.stage {
            Stage::Handshake {
                next_hello,
                give_up,
            } => Some((*next_hello).min(*give_up)),
            Stage::Session { ready_at, .. } => {
                let endpoint = self.endpoint.as_ref();
                let ready = (!endpoint.is_some_and(Controller::robot_heard)).then_some(*ready_at);
                earliest(ready, endpoint.and_then(Controller::poll_timeout))
            }
            Stage::Post {
                timer,
                heard,
                keepalive,
                ..
            } => Some((*timer).min(keepalive.unwrap_or(*heard + self.timing.silence_timeout))),
            Stage::Linger(linger) => Some(linger.deadline()),
            Stage::Closed => None,
        }
    }

    /// The next output, if any.
    pub fn poll_output(&mut self) -> Option<ControllerAction<A>> {
        self.outputs.pop_front()
    }

    /// Ends the conversation now (a stop request, a failing sensor or socket): drops the
    /// outputs not taken yet and tells the robot why, once the session is keyed.
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
        if matches!(self.stage, Stage::Handshake { .. } | Stage::Session { .. }) {
            self.outputs
                .push_back(Output::Finished(Outcome::Aborted(reason)));
        }
        self.close();
    }

    /// The session layer's counts, over every handshake.
    #[must_use]
    pub fn counts(&self) -> ChannelCounts {
        self.earlier.plus(self.channel.counts())
    }

    /// Whether a `HelloAck` verified: the robot proved it holds the pairing secret.
    #[must_use]
    pub fn is_established(&self) -> bool {
        self.channel.is_established()
    }

    /// The session endpoint, once the handshake is done.
    #[must_use]
    pub fn endpoint(&self) -> Option<&Controller> {
        self.endpoint.as_ref()
    }

    /// Post-processing, with a store.
    #[must_use]
    pub fn post(&self) -> Option<&PostLink<ControllerPost>> {
        self.post.as_ref()
    }

    /// The block-time computation post-processing waits for, once, with a link that defers
    /// them ([`PostLink::deferring`]): the shell runs it and hands its answer to
    /// [`Self::handle_computed`], answering the network meanwhile.
    pub fn take_computation(&mut self) -> Option<BlockComputation> {
        self.post.as_mut()?.take_computation()
    }

    /// The shell's answer to the computation it took, at `now`: post-processing carries on
    /// (an answer after the conversation ended, stopped, is dropped).
    pub fn handle_computed(&mut self, now: Time, computed: Computed) {
        if let (Stage::Post { heard, .. }, Some(post)) = (&mut self.stage, &mut self.post) {
            let mut out = Vec::new();
            post.answer(computed, &mut out);
            self.outputs.extend(out.into_iter().map(Output::Post));
            // The robot's silence counts from now: it waited for this answer.
            *heard = (*heard).max(now);
        }
        self.after(now);
    }

    /// Whether the conversation is over.
    #[must_use]
    pub fn is_closed(&self) -> bool {
        matches!(self.stage, Stage::Closed)
    }

    /// Starts a fresh handshake at `now` (a new `nonce_c`, the same session id), at most
    /// [`HANDSHAKES`] in all.
    fn rehandshake(&mut self, now: Time) {
        if self.handshakes >= HANDSHAKES {
            return self.end(Outcome::Aborted(format!(
                "the robot answered {HANDSHAKES} handshakes but never bound one: its Ready went \
                 unanswered each time"
            )));
        }
        self.handshakes += 1;
        let fresh = ControllerChannel::new(
            self.pairing.clone(),
            self.channel.robot(),
            self.channel.session(),
            config_digest(&self.config),
            agreement_terms(&self.config),
            &mut self.nonces,
        );
        let earlier = std::mem::replace(&mut self.channel, fresh).counts();
        self.earlier = self.earlier.plus(earlier);
        self.endpoint = None;
        self.stage = Stage::Handshake {
            next_hello: now + self.timing.retransmit_interval(),
            give_up: now + self.timing.silence_timeout,
        };
        self.send_hello();
    }

    fn send_hello(&mut self) {
        let (to, bytes) = (self.channel.robot(), self.channel.hello().to_vec());
        self.outputs.push_back(Output::Transmit { to, bytes });
    }

    /// Seals `message` under the session key and sends it to the robot (nothing before the
    /// handshake is done).
    fn send(&mut self, message: Message) {
        if let Some(bytes) = self.channel.seal(message) {
            let to = self.channel.robot();
            self.outputs.push_back(Output::Transmit { to, bytes });
        }
    }

    /// Why no `HelloAck` verified, from what came back: a robot drops a `Hello` it cannot
    /// verify unanswered, so silence means no robot listens there *or* it holds another
    /// secret; `HelloAck`s that fail to verify or declare the other pairing mode say which.
    fn no_hello_ack(&self) -> String {
        let rejected = self.earlier.plus(self.channel.counts()).rejected;
        let from_robot = rejected.total() - rejected.wrong_peer;
        let ours = match self.pairing.mode() {
            AuthMode::Paired => format!("fingerprint {}", self.pairing.fingerprint()),
            AuthMode::Unauthenticated => "this controller runs --unauthenticated".into(),
        };
        let cause = if rejected.pairing_mode > 0 {
            format!("it answered in the other pairing mode ({ours})")
        } else if rejected.handshake_bad_mac > 0 {
            format!(
                "{} HelloAck(s) from it failed to verify: it holds another pairing secret ({ours})",
                rejected.handshake_bad_mac
            )
        } else if from_robot == 0 {
            format!(
                "nothing came from it: no robot agent listens there (one that failed to start \
                 says why in its own output), or it holds another pairing secret and drops our \
                 Hellos unanswered ({ours})"
            )
        } else {
            format!("{from_robot} datagram(s) from it were dropped unverified ({ours})")
        };
        format!(
            "no HelloAck that verifies from the robot at {} within {:.1} s: {cause}",
            self.channel.robot(),
            self.timing.silence_timeout.as_secs_f64()
        )
    }

    /// The `HelloAck` verified: the session runs, bound at the robot by `Ready`.
    fn establish(&mut self, now: Time) {
        let confirmer = self
            .channel
            .confirmer()
            .expect("an established channel has a confirmer");
        let session = self.channel.session();
        let plan = self.plan.clone().for_session(session, confirmer);
        self.endpoint = Some(Controller::new(&self.config, plan, self.timing, now));
        self.outputs.push_back(Output::Established(session));
        self.send(Handshake::Ready.into());
        self.stage = Stage::Session {
            ready_at: now + self.timing.retransmit_interval(),
            readies: 1,
        };
    }

    fn feed(&mut self, now: Time, input: ControllerInput) {
        if let (Stage::Session { .. }, Some(endpoint)) = (&self.stage, &mut self.endpoint) {
            endpoint.handle_input(now, input);
            self.drain(now);
        }
        self.after(now);
    }

    fn on_message(&mut self, now: Time, message: Message) {
        match (&mut self.stage, message) {
            (Stage::Session { .. }, message) => {
                if let Some(endpoint) = &mut self.endpoint {
                    endpoint.handle_input(now, ControllerInput::Frame(message));
                }
                self.drain(now);
            }
            (Stage::Post { heard, .. }, Message::Post(fragment)) => {
                *heard = now;
                if let Some(post) = &mut self.post {
                    let mut out = Vec::new();
                    post.receive(&fragment, &mut out);
                    self.outputs.extend(out.into_iter().map(Output::Post));
                }
            }
            (Stage::Post { courtesy, .. }, Message::Closing(closing)) => {
                // No `Done` yet: it would end the robot's wait for post-processing.
                for reply in courtesy.answer(now, &closing, false) {
                    self.send(reply);
                }
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
        while let Some(output) = self.endpoint.as_mut().and_then(Controller::poll_output) {
            match output {
                ControllerOutput::Transmit(message) => self.send(message),
                ControllerOutput::Event(ControllerEvent::Finished(outcome)) => {
                    self.on_outcome(now, outcome);
                }
                ControllerOutput::Event(event) => {
                    if let ControllerEvent::DoubletDecided(decision) = &event {
                        let bits = self.plan.bits_per_unit();
                        self.separations
                            .extend_from_slice(&decision.assumed_separation[..bits]);
                        if self.config.postprocess.reconciliation == Reconciliation::Ldpc {
                            self.llrs.extend_from_slice(&decision.evidence.llr[..bits]);
                        }
                        if !decision.log_likelihoods.is_empty() {
                            super::slices::keep_likelihoods(
                                &decision.log_likelihoods,
                                &mut self.likelihoods,
                            );
                        }
                        if keeps_samples(&self.config) {
                            self.kept.push(kept_doublet(
                                decision.doublet,
                                &decision.inputs,
                                &decision.samples,
                                decision.late.as_ref(),
                            ));
                        }
                    }
                    self.outputs.push_back(Output::Endpoint(event));
                }
            }
        }
    }

    /// The session ended: without tags sent there is nothing to answer; otherwise its raw
    /// bits are pooled and post-processed (with a store), then the courtesy.
    fn on_outcome(&mut self, now: Time, outcome: Outcome) {
        self.outputs.push_back(Output::Finished(outcome.clone()));
        let Some(endpoint) = &self.endpoint else {
            return self.close();
        };
        let Some(reply) = endpoint.courtesy_reply() else {
            return self.close();
        };
        let courtesy = Courtesy::new(reply, &self.timing);
        match &mut self.post {
            Some(post) => {
                let session = self.channel.session();
                let pooled = post.pool(
                    session,
                    &outcome,
                    endpoint.key(),
                    std::mem::take(&mut self.separations),
                    std::mem::take(&mut self.kept),
                    std::mem::take(&mut self.llrs),
                    std::mem::take(&mut self.likelihoods),
                );
                self.outputs.push_back(Output::Post(pooled));
                self.stage = Stage::Post {
                    courtesy,
                    timer: now + self.timing.retransmit_interval(),
                    heard: now,
                    computed: false,
                    keepalive: None,
                };
            }
            None => self.linger(now, courtesy),
        }
    }

    /// Moves post-processing on after an input or a timer: flushes the endpoint (store, then
    /// send), and ends it when no block is in flight or the robot fell silent.
    fn after(&mut self, now: Time) {
        let Stage::Post {
            timer,
            heard,
            computed,
            keepalive,
            ..
        } = &mut self.stage
        else {
            if let Stage::Linger(linger) = &self.stage
                && linger.is_over(now)
            {
                self.close();
            }
            return;
        };
        if *computed {
            *heard = (*heard).max(now);
        }
        let Some(post) = &mut self.post else {
            return;
        };
        let mut out = Vec::new();
        let flushed = post.flush(&mut out);
        *computed = post.computed();
        self.outputs.extend(out.into_iter().map(Output::Post));
        let fragments = match flushed {
            Ok(fragments) => fragments,
            Err(why) => {
                self.outputs.push_back(Output::PostFailed(why));
                return self.close();
            }
        };
        if !fragments.is_empty() {
            *timer = now + self.timing.retransmit_interval();
        }
        // While the shell computes, the robot waits for its answer: its silence is expected.
        *keepalive = match (post.is_computing(), *keepalive) {
            (true, at) => Some(at.unwrap_or(now + keepalive_interval(&self.timing))),
            (false, _) => None,
        };
        let idle = post.is_idle();
        let silent = keepalive.is_none() && now >= *heard + self.timing.silence_timeout;
        if let Some(last) = fragments.last() {
            self.last_fragment = Some(last.clone());
        }
        for fragment in fragments {
            self.send(fragment.into());
        }
        if silent && !idle {
            self.outputs
                .push_back(Output::Post(PostOutput::Note(format!(
                    "the robot did not answer post-processing for {:.1} s (does it run with \
                 --store?): the block in flight is settled in the next session",
                    self.timing.silence_timeout.as_secs_f64()
                ))));
        }
        if (idle || silent)
            && let Stage::Post { courtesy, .. } = std::mem::replace(&mut self.stage, Stage::Closed)
        {
            self.linger(now, courtesy);
        }
    }

    /// Sends `Done` and answers until the robot's `Done` or quiet.
    fn linger(&mut self, now: Time, courtesy: Courtesy) {
        self.send(Closing::Done.into());
        if courtesy.peer_done {
            return self.close();
        }
        self.stage = Stage::Linger(Linger::new(courtesy, &self.timing, now));
    }

    /// Ends the conversation with `outcome` before any tags were sent.
    fn end(&mut self, outcome: Outcome) {
        self.outputs.push_back(Output::Finished(outcome));
        self.close();
    }

    fn close(&mut self) {
        self.stage = Stage::Closed;
        self.outputs.push_back(Output::Closed);
    }
}

/// How often the controller repeats its last post-processing fragment while the shell
/// computes: `timing`'s block timeout over [`KEEPALIVES_PER_BLOCK_TIMEOUT`] (5 s by default).
fn keepalive_interval(timing: &Timing) -> std::time::Duration {
    timing.block_timeout / KEEPALIVES_PER_BLOCK_TIMEOUT
}

/// Whether the controller keeps each decided doublet (its inputs and samples) for its
/// blocks: the block's estimate under the measured [`Config::sizing`]; under
/// `"configured"` in private sensing, the commands check on the robot's bits
/// (docs/estimation.md, "The commands check"). A multilevel block's slices are then held
/// until the last is reconciled, and the block estimated or checked on whole symbols.
fn keeps_samples(config: &Config) -> bool {
    match config.sizing() {
        Sizing::Measured => true,
        Sizing::Configured => config.sensing.mode == SensingMode::Private,
        Sizing::World => false,
    }
}
