//! The controller agent: opens the session, answers every measurement with a command
//! pair, acks codewords, finishes and confirms (docs/protocol.md, "On a network"); in
//! private sensing it commands each doublet from its own sensor's samples.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use robokey::Config;
use robokey::config::SensingMode;
use robokey::interrupt::Interrupt;
use robokey::protocol::auth::{AuthMode, ControllerChannel, Delivery, PairingSecret};
use robokey::protocol::{
    Closing, ControllerEvent, ControllerInput, ControllerOutput, Handshake, Message, Outcome,
    agreement_terms, config_digest,
};

use crate::endpoint::shape;
use crate::error::NetError;
use crate::post_link::PostSide;
use crate::robot_agent::finish_report;
use crate::secret_file::check_writable;
use crate::sensor::{SensorEvent, SensorFeed, SensorSpec};
use crate::session::{
    Courtesy, DoubletCounts, Ending, Progress, SessionReport, Timing, authentication_label, linger,
    os_rng,
};
use crate::transport::Transport;
use robokey_secrecy::postprocess::ControllerPost;
use zeroize::Zeroizing;

/// Options of the controller agent.
#[derive(Clone, Debug)]
pub struct ControllerOptions {
    /// The robot agent's UDP address.
    pub robot: SocketAddr,
    /// Local address to bind (port 0: any).
    pub bind: SocketAddr,
    /// Pacing and timeouts.
    pub timing: Timing,
    /// Where to write the key once confirmed.
    pub key_out: Option<PathBuf>,
    /// Session id (random when `None`).
    pub session: Option<u32>,
    /// The pairing secret ([`PairingSecret::unauthenticated`] for `--unauthenticated`).
    pub pairing: PairingSecret,
    /// A stop request (SIGINT, SIGTERM): the session ends within 50 ms, report written.
    pub interrupt: Interrupt,
    /// Private sensing: the controller's own pose sensor (required there, refused in
    /// odometry mode).
    pub sensor: Option<SensorSpec>,
    /// The post-processing store (`--store`): pool, journal and final keys.
    pub store: Option<PathBuf>,
    /// Make keys under a restricted assumption (`--allow-restricted`).
    pub allow_restricted: bool,
}

/// Runs one session as the controller. Every way out after the socket is bound returns a
/// report: a robot that does not answer, a socket error, a stop request.
///
/// # Errors
/// `--key-out` exists or has no folder, the sensor is missing (private sensing), refused
/// (odometry mode) or unreachable, or the socket cannot be bound.
pub fn run_controller(
    config: &Config,
    options: &ControllerOptions,
) -> Result<SessionReport, NetError> {
    if let Some(path) = &options.key_out {
        check_writable(path, "key file")?;
    }
    let mut post = PostSide::<ControllerPost>::for_agent(
        config,
        options.store.as_ref(),
        &options.pairing,
        options.allow_restricted,
    )?;
    let sensor = match (config.sensing.mode, &options.sensor) {
        (SensingMode::Private, Some(spec)) => Some(SensorFeed::start(spec.open()?)),
        (SensingMode::Private, None) => {
            return Err(NetError::Usage(
                "private sensing: the controller decides from its own pose sensor; pass \
                 --sensor mocap:ADDR (its link must be private: wired or localhost)"
                    .into(),
            ));
        }
        (SensingMode::Odometry, Some(_)) => {
            return Err(NetError::Usage(
                "--sensor is used only in private sensing (sensing.mode = private); the \
                 odometry mode decides from the robot's measurements"
                    .into(),
            ));
        }
        (SensingMode::Odometry, None) => None,
    };
    let mut rng = os_rng()?;
    let session = match options.session {
        Some(id) => id,
        None => {
            use rand::RngExt;
            rng.random()
        }
    };
    let channel = ControllerChannel::new(
        options.pairing.clone(),
        options.robot,
        session,
        config_digest(config),
        agreement_terms(config),
        &mut rng,
    );
    let mut transport =
        Transport::controller(options.bind, channel)?.with_interrupt(options.interrupt.clone());
    let shape = shape(config);
    let mut report = SessionReport {
        role: "controller".into(),
        authentication: authentication_label(&options.pairing),
        session,
        steps: shape.steps,
        codewords: shape.units,
        doublets: shape.doublets.then(DoubletCounts::default),
        ..SessionReport::default()
    };
    let conversed = converse(
        config,
        options,
        sensor,
        &mut transport,
        &mut report,
        post.as_mut(),
    );
    let post = post.map(PostSide::finish);
    match conversed {
        Ok(ended) => {
            let mut report = finish_report(
                report,
                Some(ended.outcome),
                &ended.key,
                &transport,
                options.key_out.as_ref(),
                shape.bits_per_unit,
            );
            let rejected = transport.rejected();
            if !ended.robot_authenticated && rejected.bad_mac + rejected.pairing_mode > 0 {
                report.ending = Ending::AuthenticationFailed;
            }
            if let Some(error) = ended.post_error {
                report.post_stopped(&error);
            }
            report.set_post(post);
            Ok(report)
        }
        Err(error) => {
            let _ = transport.send(
                Closing::Abort {
                    reason: error.to_string(),
                }
                .into(),
            );
            report.set_error(&error);
            report.count_frames(&transport);
            report.set_post(post);
            Ok(report)
        }
    }
}

/// What a conversation with the robot ended with.
struct Ended {
    outcome: Outcome,
    /// Whether a HelloAck proved that the robot holds the pairing secret.
    robot_authenticated: bool,
    /// The key bits (empty unless confirmed); zeroized when dropped.
    key: Zeroizing<Vec<u8>>,
    /// What stopped post-processing after the session, if anything did.
    post_error: Option<NetError>,
}

/// The handshake and the session, counting into `report`.
fn converse(
    config: &Config,
    options: &ControllerOptions,
    sensor: Option<SensorFeed>,
    transport: &mut Transport,
    report: &mut SessionReport,
    post: Option<&mut PostSide<ControllerPost>>,
) -> Result<Ended, NetError> {
    let timing = options.timing;

    // Handshake: repeat Hello until a HelloAck (or a Refuse) that verifies, within the
    // silence timeout.
    let give_up = Instant::now() + timing.silence_timeout;
    let accepted = loop {
        if Instant::now() >= give_up {
            let hint = match options.pairing.mode() {
                AuthMode::Paired => format!(
                    "is it paired with the same secret, fingerprint {}?",
                    options.pairing.fingerprint()
                ),
                AuthMode::Unauthenticated => "is it running with --unauthenticated?".into(),
            };
            break Err(format!(
                "no HelloAck that verifies from the robot at {} within {:.1} s ({hint})",
                options.robot,
                timing.silence_timeout.as_secs_f64()
            ));
        }
        transport.send_hello()?;
        let wait_until = Instant::now() + timing.retransmit_interval();
        match transport.recv_until(wait_until)? {
            Some(Delivery::Established) => break Ok(()),
            Some(Delivery::Refused(reason)) => {
                break Err(format!("robot refused the session: {reason}"));
            }
            _ => {}
        }
    };
    if let Err(reason) = accepted {
        return Ok(Ended {
            outcome: Outcome::Aborted(reason),
            robot_authenticated: false,
            key: Zeroizing::new(Vec::new()),
            post_error: None,
        });
    }
    let confirmer = transport
        .confirmer()
        .expect("an established session has a confirmer");
    let session = transport
        .session()
        .expect("the controller knows its session");

    // The first frame under the session key binds the session at the robot; repeat it until
    // the robot's first measurement shows it arrived.
    transport.send(Handshake::Ready.into())?;
    let mut robot_heard = false;
    let mut endpoint = crate::endpoint::controller(config, session, confirmer);
    let mut outcome = None;
    let mut last_frame = Instant::now();
    let mut last_confirm = None;
    let mut progress = Progress::new("controller", report.steps);
    // The retransmission timer restarts at every delivery; with a sensor, the socket is
    // also left every millisecond to take its samples.
    let mut timer_from = Instant::now();
    let mut sensed = SensorClock::new(shape(config).steps);
    // The largest Eve separation the camera statement gives over the decided bits: it
    // sizes the keys of the blocks this session enters (private sensing).
    let mut separation: f64 = 0.0;
    let bits_per_doublet = shape(config).bits_per_unit;
    while outcome.is_none() {
        let tick = timer_from + timing.retransmit_interval();
        let wake = match sensor {
            Some(_) => tick.min(Instant::now() + SENSOR_POLL),
            None => tick,
        };
        let delivery = transport.recv_until(wake)?;
        if delivery.is_some() || Instant::now() >= tick {
            timer_from = Instant::now();
        }
        match delivery {
            Some(Delivery::Message(message)) => {
                robot_heard = true;
                last_frame = Instant::now();
                endpoint.handle_input(ControllerInput::Frame(message));
            }
            Some(_) => {}
            None if Instant::now() < tick => {}
            None if last_frame.elapsed() >= timing.silence_timeout => {
                let reason = format!(
                    "silence: no valid frame from the robot for {:.1} s",
                    timing.silence_timeout.as_secs_f64()
                );
                transport.send(
                    Closing::Abort {
                        reason: reason.clone(),
                    }
                    .into(),
                )?;
                outcome = Some(Outcome::Aborted(reason));
            }
            None if !robot_heard => transport.send(Handshake::Ready.into())?,
            // Retransmission timer: Finish until FinishAck (bounded by the endpoint).
            None => endpoint.handle_input(ControllerInput::Timeout),
        }
        if let Some(feed) = &sensor {
            while let Some(event) = feed.try_next() {
                match event {
                    SensorEvent::Sample(sample) => {
                        sensed.sampled(sample.step);
                        report.steps_done = sample.step;
                        endpoint.handle_input(ControllerInput::Sensor {
                            step: sample.step,
                            pose: sample.pose,
                        });
                    }
                    SensorEvent::Stopped(why) => sensed.stopped(why),
                }
            }
            if let Some(reason) = sensed.failure(robot_heard, timing.silence_timeout) {
                transport.send(
                    Closing::Abort {
                        reason: reason.clone(),
                    }
                    .into(),
                )?;
                outcome = Some(Outcome::Aborted(reason));
            }
        }
        while let Some(output) = endpoint.poll_output() {
            match output {
                ControllerOutput::Transmit(message) => {
                    if matches!(message, Message::Closing(Closing::Confirm { .. })) {
                        last_confirm = Some(message.clone());
                    }
                    transport.send(message)?;
                }
                ControllerOutput::Event(event) => match event {
                    ControllerEvent::Decoded(decision) => {
                        report.steps_done = decision.step + 1;
                        progress.tick(report.steps_done, report.erased_steps);
                        report.erased_steps +=
                            u32::from(decision.bit.is_none() && config.protocol.enabled);
                    }
                    ControllerEvent::Missing(range) => report.erased_steps += range.len() as u32,
                    ControllerEvent::DoubletCommanded { carries, .. } => {
                        if let Some(counts) = &mut report.doublets {
                            counts.gated += u32::from(config.protocol.enabled && !carries);
                        }
                    }
                    ControllerEvent::DoubletErased { .. } => {
                        report.erased_steps += 2;
                        if let Some(counts) = &mut report.doublets {
                            counts.erased += 1;
                        }
                    }
                    ControllerEvent::DoubletDecided(decision) => {
                        separation = decision.assumed_separation[..bits_per_doublet]
                            .iter()
                            .fold(separation, |m, &d| m.max(d));
                    }
                    ControllerEvent::Finished(o) => outcome = Some(o),
                    _ => {}
                },
            }
        }
    }
    let outcome = outcome.expect("the loop ends on an outcome");
    let mut post_error = None;
    if let Some(confirm) = last_confirm {
        let reply = [confirm];
        let mut courtesy = Courtesy::new(&reply, &timing);
        let mut peer_done = false;
        if let Some(post) = post {
            post.pool(session, Some(&outcome), endpoint.key(), separation);
            match post.run(transport, &timing, &mut courtesy) {
                Ok(done) => peer_done = done,
                Err(error) => post_error = Some(error),
            }
        }
        if post_error.is_none() {
            // The key is settled; a signal now only shortens the courtesy to the peer.
            let _ = linger(transport, &timing, &mut courtesy, peer_done, None);
        }
    }
    Ok(Ended {
        outcome,
        robot_authenticated: true,
        key: Zeroizing::new(endpoint.key().to_vec()),
        post_error,
    })
}

/// How often the controller's loop takes its sensor's samples.
const SENSOR_POLL: Duration = Duration::from_millis(1);

/// Whether the controller's sensor keeps up: it must deliver every step up to `N`, and
/// falls silent only after the robot has been heard (the world samples when the robot does).
struct SensorClock {
    steps: u32,
    last: Option<u32>,
    at: Instant,
    stopped: Option<String>,
}

impl SensorClock {
    fn new(steps: u32) -> Self {
        Self {
            steps,
            last: None,
            at: Instant::now(),
            stopped: None,
        }
    }

    fn sampled(&mut self, step: u32) {
        self.last = Some(step);
        self.at = Instant::now();
    }

    fn stopped(&mut self, why: String) {
        self.stopped.get_or_insert(why);
    }

    /// Why the session cannot go on, if so: the sensor stopped or fell silent before `N`.
    fn failure(&mut self, robot_heard: bool, silence: Duration) -> Option<String> {
        if self.last.is_some_and(|k| k >= self.steps) {
            return None;
        }
        if let Some(why) = &self.stopped {
            return Some(format!("sensor stopped before step {}: {why}", self.steps));
        }
        if !robot_heard {
            self.at = Instant::now();
            return None;
        }
        (self.at.elapsed() >= silence).then(|| {
            format!(
                "sensor: no sample for {:.1} s (last step {})",
                silence.as_secs_f64(),
                self.last
                    .map_or_else(|| "none".to_owned(), |k| k.to_string())
            )
        })
    }
}

/// Default silence timeout (docs/protocol.md).
pub const DEFAULT_SILENCE: Duration = Duration::from_secs(2);
