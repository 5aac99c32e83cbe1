//! The controller agent: opens the session, answers every measurement with a command
//! pair, acks codewords, finishes and confirms (docs/protocol.md, "On a network").

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use robokey::Config;
use robokey::protocol::{
    ControllerEndpoint, ControllerEvent, ControllerInput, ControllerOutput, Message, Outcome,
    SessionPlan, agreement_terms, config_digest,
};

use crate::error::NetError;
use crate::robot_agent::{PROTOCOL_VERSION, finish_report};
use crate::session::{SessionReport, Timing, linger, os_rng};
use crate::transport::Transport;

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
}

/// Runs one session as the controller.
///
/// # Errors
/// Socket failures.
pub fn run_controller(
    config: &Config,
    options: &ControllerOptions,
) -> Result<SessionReport, NetError> {
    let session = match options.session {
        Some(id) => id,
        None => {
            use rand::RngExt;
            os_rng()?.random()
        }
    };
    let mut transport = Transport::bind(options.bind, Some(options.robot))?;
    transport.set_session(session);
    let timing = options.timing;
    let plan = SessionPlan::from_config(config, session);
    let mut report = SessionReport {
        role: "controller".into(),
        session,
        steps: plan.steps,
        codewords: plan.codewords(),
        ..SessionReport::default()
    };
    let message_bits = plan.code.k();

    // Handshake: repeat Hello until HelloAck (or a refusal), within the silence timeout.
    let hello = Message::Hello {
        version: PROTOCOL_VERSION,
        config_digest: config_digest(config),
        terms: agreement_terms(config),
    };
    let give_up = Instant::now() + timing.silence_timeout;
    let accepted = loop {
        if Instant::now() >= give_up {
            break Err(format!(
                "no HelloAck from the robot at {} within {:.1} s",
                options.robot,
                timing.silence_timeout.as_secs_f64()
            ));
        }
        transport.send(hello.clone())?;
        match transport.recv_until(Instant::now() + timing.retransmit_interval())? {
            Some((_, Message::HelloAck { .. })) => break Ok(()),
            Some((_, Message::Abort { reason })) => {
                break Err(format!("robot refused the session: {reason}"));
            }
            _ => {}
        }
    };
    if let Err(reason) = accepted {
        return finish_report(
            report,
            Some(Outcome::Aborted(reason)),
            &[],
            transport.counts,
            None,
            message_bits,
        );
    }

    let mut endpoint = ControllerEndpoint::new(config, plan);
    let mut outcome = None;
    let mut last_frame = Instant::now();
    let mut last_confirm = None;
    while outcome.is_none() {
        match transport.recv_until(Instant::now() + timing.retransmit_interval())? {
            Some((_, Message::HelloAck { .. })) => last_frame = Instant::now(),
            Some((_, message)) => {
                last_frame = Instant::now();
                endpoint.handle_input(ControllerInput::Frame(message));
            }
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
        linger(&mut transport, &timing, &[confirm])?;
    }
    finish_report(
        report,
        outcome,
        endpoint.key(),
        transport.counts,
        options.key_out.as_ref(),
        message_bits,
    )
}

/// Default silence timeout (docs/protocol.md).
pub const DEFAULT_SILENCE: Duration = Duration::from_secs(2);
