//! The controller agent: opens the session, answers every measurement with a command
//! pair, acks codewords, finishes and confirms (docs/protocol.md, "On a network").

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use robokey::Config;
use robokey::interrupt::Interrupt;
use robokey::protocol::auth::{AuthMode, ControllerChannel, Delivery, PairingSecret};
use robokey::protocol::{
    ControllerEndpoint, ControllerEvent, ControllerInput, ControllerOutput, Message, Outcome,
    SessionPlan, agreement_terms, config_digest,
};

use crate::error::NetError;
use crate::robot_agent::finish_report;
use crate::secret_file::check_writable;
use crate::session::{
    Ending, Progress, SessionReport, Timing, authentication_label, linger, os_rng,
};
use crate::transport::Transport;
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
}

/// Runs one session as the controller. Every way out after the socket is bound returns a
/// report: a robot that does not answer, a socket error, a stop request.
///
/// # Errors
/// `--key-out` exists or has no folder, or the socket cannot be bound.
pub fn run_controller(
    config: &Config,
    options: &ControllerOptions,
) -> Result<SessionReport, NetError> {
    if let Some(path) = &options.key_out {
        check_writable(path, "key file")?;
    }
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
    let plan = SessionPlan::from_config(config, session);
    let mut report = SessionReport {
        role: "controller".into(),
        authentication: authentication_label(&options.pairing),
        session,
        steps: plan.steps,
        codewords: plan.codewords(),
        ..SessionReport::default()
    };
    let message_bits = plan.code.k();
    match converse(config, options, plan, &mut transport, &mut report) {
        Ok(ended) => {
            let mut report = finish_report(
                report,
                Some(ended.outcome),
                &ended.key,
                &transport,
                options.key_out.as_ref(),
                message_bits,
            );
            let rejected = transport.rejected();
            if !ended.robot_authenticated && rejected.bad_mac + rejected.pairing_mode > 0 {
                report.ending = Ending::AuthenticationFailed;
            }
            Ok(report)
        }
        Err(error) => {
            let _ = transport.send(Message::Abort {
                reason: error.to_string(),
            });
            report.set_error(&error);
            report.frames = transport.counts();
            report.frames_rejected = transport.rejected();
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
}

/// The handshake and the session, counting into `report`.
fn converse(
    config: &Config,
    options: &ControllerOptions,
    mut plan: SessionPlan,
    transport: &mut Transport,
    report: &mut SessionReport,
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
        });
    }
    plan.confirmer = transport
        .confirmer()
        .expect("an established session has a confirmer");

    // The first frame under the session key binds the session at the robot; repeat it until
    // the robot's first measurement shows it arrived.
    transport.send(Message::Ready)?;
    let mut robot_heard = false;
    let mut endpoint = ControllerEndpoint::new(config, plan);
    let mut outcome = None;
    let mut last_frame = Instant::now();
    let mut last_confirm = None;
    let mut progress = Progress::new("controller", report.steps);
    while outcome.is_none() {
        match transport.recv_until(Instant::now() + timing.retransmit_interval())? {
            Some(Delivery::Message(message)) => {
                robot_heard = true;
                last_frame = Instant::now();
                endpoint.handle_input(ControllerInput::Frame(message));
            }
            Some(_) => {}
            None if last_frame.elapsed() >= timing.silence_timeout => {
                let reason = format!(
                    "silence: no valid frame from the robot for {:.1} s",
                    timing.silence_timeout.as_secs_f64()
                );
                transport.send(Message::Abort {
                    reason: reason.clone(),
                })?;
                outcome = Some(Outcome::Aborted(reason));
            }
            None if !robot_heard => transport.send(Message::Ready)?,
            // Retransmission timer: Finish until FinishAck (bounded by the endpoint).
            None => endpoint.handle_input(ControllerInput::Timeout),
        }
        while let Some(output) = endpoint.poll_output() {
            match output {
                ControllerOutput::Transmit(message) => {
                    if matches!(message, Message::Confirm { .. }) {
                        last_confirm = Some(message.clone());
                    }
                    transport.send(message)?;
                }
                ControllerOutput::Event(event) => match event {
                    ControllerEvent::Decoded(decision) => {
                        report.steps_done = decision.step + 1;
                        progress.tick(report.steps_done, report.erased_steps);
                        report.erased_steps +=
                            u32::from(decision.bit.is_none() && endpoint.plan().enabled);
                    }
                    ControllerEvent::Missing(range) => report.erased_steps += range.len() as u32,
                    ControllerEvent::Finished(o) => outcome = Some(o),
                    _ => {}
                },
            }
        }
    }
    if let Some(confirm) = last_confirm {
        // The key is settled; a signal now only shortens the courtesy to the peer.
        let _ = linger(transport, &timing, &[confirm]);
    }
    Ok(Ended {
        outcome: outcome.expect("the loop ends on an outcome"),
        robot_authenticated: true,
        key: Zeroizing::new(endpoint.key().to_vec()),
    })
}

/// Default silence timeout (docs/protocol.md).
pub const DEFAULT_SILENCE: Duration = Duration::from_secs(2);
