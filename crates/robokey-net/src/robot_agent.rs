//! The robot agent: owns the clock and the key bits, applies one of the two offered
//! commands each period (or the fallback), reports odometry (docs/protocol.md, "On a
//! network"); in private sensing it applies each doublet's inputs and reports no pose.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use rand::CryptoRng;
use robokey::Config;
use robokey::interrupt::Interrupt;
use robokey::model::WheelSpeeds;
use robokey::protocol::auth::{Delivery, PairingSecret, RobotChannel};
use robokey::protocol::{
    Closing, Handshake, Message, Outcome, RobotInput, RobotOutput, SessionMessage, agreement_terms,
    config_digest,
};

use crate::backend::{Backend, WheelGuard};
use crate::endpoint::{RobotSide, Shape, shape};
use crate::error::NetError;
use crate::post_link::PostSide;
use crate::secret_file::check_writable;
use crate::session::{
    Courtesy, DoubletCounts, Ending, Pace, Progress, STOP_POLL, SessionReport, Timing,
    authentication_label, linger, os_rng, write_key_file,
};
use crate::transport::Transport;
use robokey_secrecy::postprocess::RobotPost;

/// Options of the robot agent.
#[derive(Clone, Debug)]
pub struct RobotOptions {
    /// UDP address to listen on.
    pub listen: SocketAddr,
    /// Pacing and timeouts.
    pub timing: Timing,
    /// How long to wait for the controller's `Hello`.
    pub wait_for_hello: Duration,
    /// Where to write the key once confirmed.
    pub key_out: Option<PathBuf>,
    /// The pairing secret ([`PairingSecret::unauthenticated`] for `--unauthenticated`).
    pub pairing: PairingSecret,
    /// A stop request (SIGINT, SIGTERM): the session ends within 50 ms, wheels stopped,
    /// report written.
    pub interrupt: Interrupt,
    /// The post-processing store (`--store`): pool, journal and final keys.
    pub store: Option<PathBuf>,
    /// Make keys under a restricted assumption (`--allow-restricted`).
    pub allow_restricted: bool,
}

/// The robot's side of a running session.
struct RobotSession<'a, B: Backend + ?Sized> {
    transport: Transport,
    endpoint: Box<dyn RobotSide>,
    shape: Shape,
    backend: WheelGuard<'a, B>,
    timing: Timing,
    report: SessionReport,
    outcome: Option<Outcome>,
    last_frame: Instant,
    last_confirm: Option<Message>,
    last_measurement: Option<Message>,
}

impl<B: Backend + ?Sized> RobotSession<'_, B> {
    fn pump(&mut self) -> Result<(), NetError> {
        while let Some(output) = self.endpoint.poll_output() {
            match output {
                RobotOutput::Transmit(message) => {
                    match &message {
                        Message::Closing(Closing::Confirm { .. }) => {
                            self.last_confirm = Some(message.clone())
                        }
                        Message::Session(SessionMessage::Measurement { .. })
                        | Message::Session(SessionMessage::PrivateMeasurement { .. }) => {
                            self.last_measurement = Some(message.clone())
                        }
                        _ => {}
                    }
                    self.transport.send(message)?;
                }
                RobotOutput::Apply(actuation) => {
                    self.report.erased_steps += u32::from(actuation.erased);
                    // Stopped for want of commands, once they had started the wheels.
                    if actuation.erased
                        && actuation.wheels == WheelSpeeds::zeros()
                        && self.endpoint.commands_applied() > 0
                    {
                        self.report
                            .wheels_stopped_at_step
                            .get_or_insert(actuation.step);
                    }
                    if let Some(counts) = &mut self.report.doublets
                        && self.shape.starts_doublet(actuation.step)
                    {
                        // A doublet's first step tells its fate at the robot.
                        if actuation.erased {
                            counts.erased += 1;
                        } else if actuation.bit.is_none() && self.shape.enabled {
                            counts.gated += 1;
                        }
                    }
                    self.backend.set_wheels(actuation.wheels)?;
                }
                RobotOutput::Finished(outcome) => self.outcome = Some(outcome),
            }
        }
        Ok(())
    }

    /// Receives until `deadline` or until `done(self)`; aborts on silence.
    fn receive_until(
        &mut self,
        deadline: Instant,
        done: impl Fn(&Self) -> bool,
    ) -> Result<(), NetError> {
        while !done(self) && self.outcome.is_none() {
            match self
                .transport
                .recv_until(deadline.min(self.last_frame + self.timing.silence_timeout))?
            {
                Some(Delivery::Message(message)) => {
                    self.last_frame = Instant::now();
                    // A repeated Ready (the controller has not heard us yet) needs nothing.
                    if message != Message::Handshake(Handshake::Ready) {
                        self.endpoint.handle_input(RobotInput::Frame(message));
                        self.pump()?;
                    }
                }
                Some(_) => {}
                None if self.last_frame.elapsed() >= self.timing.silence_timeout => {
                    let reason = format!(
                        "silence: no valid frame from the controller for {:.1} s",
                        self.timing.silence_timeout.as_secs_f64()
                    );
                    self.transport.send(
                        Closing::Abort {
                            reason: reason.clone(),
                        }
                        .into(),
                    )?;
                    self.outcome = Some(Outcome::Aborted(reason));
                }
                None => return Ok(()),
            }
        }
        Ok(())
    }
}

/// Answers verified Hellos until a controller binds a session (its first frame under the
/// controller→robot session key). Returns the session id, or the report of a robot that no
/// controller bound within the wait.
fn handshake(
    transport: &mut Transport,
    options: &RobotOptions,
) -> Result<Result<u32, SessionReport>, NetError> {
    let wait = options.wait_for_hello;
    let deadline = Instant::now() + wait;
    let mut refused = None;
    loop {
        match transport.recv_until(deadline)? {
            Some(Delivery::Message(_)) => {
                let session = transport.session().expect("a delivered message binds");
                return Ok(Ok(session));
            }
            Some(Delivery::Refused(reason)) => refused = Some(reason),
            Some(_) => {}
            None => break,
        }
    }
    let rejected = transport.rejected();
    let mut reason = format!(
        "no controller bound a session within {:.0} s ({} datagrams rejected)",
        wait.as_secs_f64(),
        rejected.total()
    );
    if let Some(refused) = refused {
        reason += &format!("; last Hello refused: {refused}");
    }
    let mut report = robot_report(options);
    report.set_outcome(&Outcome::Aborted(reason));
    if rejected.bad_mac + rejected.pairing_mode > 0 {
        report.ending = Ending::AuthenticationFailed;
    }
    report.count_frames(transport);
    Ok(Err(report))
}

/// The robot's report before a session binds.
fn robot_report(options: &RobotOptions) -> SessionReport {
    SessionReport {
        role: "robot".into(),
        authentication: authentication_label(&options.pairing),
        commands_applied: Some(0),
        ..SessionReport::default()
    }
}

/// Runs one session as the robot: waits for the controller, then drives `backend` for N
/// steps with key bits drawn from `key_source` (the OS CSPRNG in deployment).
///
/// Every way out after the socket is bound returns a report: a robot no controller bound,
/// an error of the socket or the backend, a stop request. The wheels are stopped on every
/// way out that runs destructors (normal end, error, stop request, panic).
///
/// # Errors
/// `--key-out` exists or has no folder, or the socket cannot be bound.
pub fn run_robot<B: Backend + ?Sized, R: CryptoRng + ?Sized>(
    config: &Config,
    backend: &mut B,
    key_source: &mut R,
    options: &RobotOptions,
) -> Result<SessionReport, NetError> {
    if let Some(path) = &options.key_out {
        check_writable(path, "key file")?;
    }
    let mut post = PostSide::<RobotPost>::for_agent(
        config,
        options.store.as_ref(),
        &options.pairing,
        options.allow_restricted,
    )?;
    let channel = RobotChannel::new(
        options.pairing.clone(),
        config_digest(config),
        agreement_terms(config),
    );
    let mut transport = Transport::robot(options.listen, channel, os_rng()?)?
        .with_interrupt(options.interrupt.clone());
    println!(
        "robot listening on {}, {}",
        transport.local_addr()?,
        authentication_label(&options.pairing)
    );
    let session = match handshake(&mut transport, options) {
        Ok(Ok(session)) => session,
        Ok(Err(mut report)) => {
            report.set_post(post.map(PostSide::finish));
            return Ok(report);
        }
        Err(error) => {
            let mut report = robot_report(options);
            report.set_error(&error);
            report.count_frames(&transport);
            report.set_post(post.map(PostSide::finish));
            return Ok(report);
        }
    };
    let confirmer = transport
        .confirmer()
        .expect("a bound session has a confirmer");
    let shape = shape(config);
    let report = SessionReport {
        session,
        steps: shape.steps,
        codewords: shape.units,
        doublets: shape.doublets.then(DoubletCounts::default),
        ..robot_report(options)
    };
    let mut s = RobotSession {
        transport,
        endpoint: crate::endpoint::robot(config, session, confirmer, key_source),
        shape,
        backend: WheelGuard::new(backend),
        timing: options.timing,
        report,
        outcome: None,
        last_frame: Instant::now(),
        last_confirm: None,
        last_measurement: None,
    };
    let driven = s.drive(&options.interrupt);
    s.backend.stop();
    s.report.commands_applied = Some(s.endpoint.commands_applied());
    if let Err(error) = driven {
        // Tell the controller, so that it ends now rather than after its silence timeout.
        let _ = s.transport.send(
            Closing::Abort {
                reason: error.to_string(),
            }
            .into(),
        );
        s.report.set_error(&error);
        s.report.count_frames(&s.transport);
        s.report.set_post(post.map(PostSide::finish));
        return Ok(s.report);
    }
    let mut post_error = None;
    if let (Some(confirm), false) = (
        s.last_confirm.clone(),
        matches!(s.outcome, Some(Outcome::Aborted(_))),
    ) {
        let reply = [Message::Closing(Closing::FinishAck), confirm];
        let mut courtesy = Courtesy::new(&reply, &s.timing);
        post_error = match post.as_mut() {
            Some(post) => settle(post, &mut s, &mut courtesy, session).err(),
            None => {
                // The key is settled; a signal now only shortens the courtesy to the peer.
                let _ = linger(&mut s.transport, &s.timing, &mut courtesy, false, None);
                None
            }
        };
    }
    let mut report = finish_report(
        s.report,
        s.outcome,
        s.endpoint.key(),
        &s.transport,
        options.key_out.as_ref(),
        s.shape.bits_per_unit,
    );
    if let Some(error) = post_error {
        report.post_stopped(&error);
    }
    report.set_post(post.map(PostSide::finish));
    Ok(report)
}

impl<B: Backend + ?Sized> RobotSession<'_, B> {
    /// The N steps, then the wait for the Finish and the controller's tag.
    fn drive(&mut self, interrupt: &Interrupt) -> Result<(), NetError> {
        let steps = self.shape.steps;
        let sample_time = Duration::from_secs_f64(self.shape.sample_time);
        let start = Instant::now();
        let mut progress = Progress::new("robot", steps);
        for k in 0..=steps {
            if self.outcome.is_some() {
                break;
            }
            let sample_at = start + sample_time * k;
            if self.timing.pace == Pace::Realtime {
                sleep_until(sample_at, interrupt)?;
            }
            let y = self.backend.sample()?;
            self.endpoint
                .handle_input(RobotInput::Sample { step: k, y });
            self.pump()?;
            let deadline = match self.timing.pace {
                Pace::Lockstep => Instant::now() + self.timing.step_timeout,
                Pace::Realtime => sample_at + sample_time.mul_f64(self.timing.deadline_fraction),
            };
            self.receive_until(deadline, |s| s.endpoint.next_command() > k)?;
            if self.outcome.is_none() && self.endpoint.next_command() <= k {
                self.endpoint.handle_input(RobotInput::Deadline { step: k });
                self.pump()?;
            }
            self.report.steps_done = k;
            progress.tick(k, self.report.erased_steps);
        }
        // Stopped: wait for the Finish and the controller's tag. Until the Finish arrives,
        // repeat the last measurement (the controller finishes on y(N), which has no
        // successor if lost); after it, repeat our tag.
        self.backend.set_wheels(WheelSpeeds::zeros())?;
        while self.outcome.is_none() {
            let next = Instant::now() + self.timing.retransmit_interval();
            self.receive_until(next, |s| s.endpoint.is_done())?;
            if self.outcome.is_none()
                && let Some(repeat) = self
                    .last_confirm
                    .clone()
                    .or_else(|| self.last_measurement.clone())
            {
                self.transport.send(repeat)?;
            }
        }
        Ok(())
    }
}

/// After a session both sides closed: pools its bits if the controller confirmed them, then
/// answers post-processing until the controller's `Done` (flushing first stores the pool).
fn settle<B: Backend + ?Sized>(
    post: &mut PostSide<RobotPost>,
    s: &mut RobotSession<'_, B>,
    courtesy: &mut Courtesy<'_>,
    session: u32,
) -> Result<(), NetError> {
    post.pool(session, s.outcome.as_ref(), s.endpoint.key(), 0.0);
    post.flush(&mut s.transport)?;
    linger(&mut s.transport, &s.timing, courtesy, false, Some(post))
}

/// Sleeps until `at`, looking at the stop request every 50 ms.
fn sleep_until(at: Instant, interrupt: &Interrupt) -> Result<(), NetError> {
    loop {
        if let Some(signal) = interrupt.signal() {
            return Err(NetError::Interrupted(signal));
        }
        let left = at.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Ok(());
        }
        std::thread::sleep(left.min(STOP_POLL));
    }
}

/// Completes a report and writes the key when (and only when) the peer confirmed it — in
/// private sensing the raw bits, once the peer confirmed the kept doublets. A key that cannot
/// be written ends the session as failed, with the reason.
pub(crate) fn finish_report(
    mut report: SessionReport,
    outcome: Option<Outcome>,
    key: &[u8],
    transport: &Transport,
    key_out: Option<&PathBuf>,
    message_bits: usize,
) -> SessionReport {
    let outcome = outcome.unwrap_or_else(|| Outcome::Aborted("ended without an outcome".into()));
    report.set_outcome(&outcome);
    report.count_frames(transport);
    report.key_bits = key.len();
    report.accepted = (key.len() / message_bits.max(1)) as u32;
    let written = match &outcome {
        Outcome::Confirmed => Some(vec![
            "raw: not secret against an eavesdropper who learns the model",
            "confirmed by the peer's directional key tag",
        ]),
        Outcome::Kept => Some(vec![
            "raw private-sensing bits of the kept doublets, in order (v, then ω with two bits per \
             doublet): the robot's are the reference, the controller's differ where it erred; \
             not a key until reconciled and amplified over a block (docs/postprocessing.md)",
            "kept positions confirmed by the peer's session tag",
        ]),
        _ => None,
    };
    if let (Some(mut labels), Some(path)) = (written, key_out) {
        if report.is_unauthenticated() {
            labels.push("passive adversary only: the session was not authenticated");
        }
        match write_key_file(path, key, &labels) {
            Ok(()) => report.key_file = Some(path.display().to_string()),
            Err(error) => {
                report.ending = Ending::Failed;
                report.reason = Some(format!("the key was confirmed but not written: {error}"));
            }
        }
    }
    report
}
