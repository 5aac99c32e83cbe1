//! The robot agent: it owns the clock and the key bits, applies one of the offered commands
//! each period (or the fallback), reports each sample (in private sensing, no pose), then
//! answers post-processing (docs/protocol.md, "On a network").

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use rand::CryptoRng;
use robokey::Config;
use robokey::connection::{RobotConnection, Setup};
use robokey::interrupt::Interrupt;
use robokey::protocol::auth::PairingSecret;
use robokey::protocol::{RobotOutput, SessionPlan, Timing};
use robokey_secrecy::postprocess::RobotPost;

use super::post::AgentStore;
use super::report::{Progress, SessionReport, authentication_label};
use super::socket::Socket;
use super::{Carry, Counted, Run, finish};
use crate::backend::{Backend, WheelGuard};
use crate::error::NetError;
use crate::random::os_rng;
use crate::secret_file::check_writable;

/// Options of the robot agent.
#[derive(Clone, Debug)]
pub struct RobotOptions {
    /// UDP address to listen on.
    pub listen: SocketAddr,
    /// Pacing and timeouts.
    pub timing: Timing,
    /// How long to wait for a controller to bind a session.
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

/// Runs one session as the robot: waits for a controller, then drives `backend` for N steps
/// with key bits from a stream seeded by `key_source` (the OS CSPRNG in deployment).
///
/// Every way out after the socket is bound returns a report: a robot no controller bound, an
/// error of the socket or the backend, a stop request. The wheels are stopped on every way
/// out that runs destructors (normal end, error, stop request, panic).
///
/// # Errors
/// `--key-out` exists or has no folder, the store cannot be opened, or the socket cannot be
/// bound.
pub fn run_robot<B: Backend + ?Sized, R: CryptoRng + ?Sized>(
    config: &Config,
    backend: &mut B,
    key_source: &mut R,
    options: &RobotOptions,
) -> Result<SessionReport, NetError> {
    if let Some(path) = &options.key_out {
        check_writable(path, "key file")?;
    }
    let pairing = &options.pairing;
    let (link, mut store) = AgentStore::<RobotPost>::for_agent(
        config,
        options.store.as_ref(),
        pairing,
        options.allow_restricted,
    )?
    .unzip();
    let mut socket = Socket::bind(options.listen, options.interrupt.clone())?;
    println!(
        "robot listening on {}, {}",
        socket.local_addr()?,
        authentication_label(pairing)
    );
    let setup = Setup {
        config,
        pairing,
        timing: options.timing,
    };
    let mut connection = RobotConnection::new(
        setup,
        options.wait_for_hello,
        link,
        os_rng()?,
        key_source,
        socket.now(),
    );
    let plan = SessionPlan::from_config(config, 0);
    let mut report = SessionReport::new("robot", pairing);
    report.commands_applied = Some(0);
    let mut progress = Progress::new("robot", plan.agreed.steps);
    let mut wheels = WheelGuard::new(backend);
    let mut run = Run::default();
    loop {
        while let Some(output) = connection.poll_output() {
            let post_running = connection.post().is_some() && run.outcome.is_some();
            let mut carry = Carry {
                socket: &mut socket,
                run: &mut run,
                report: &mut report,
                plan: &plan,
                store: store.as_mut(),
            };
            let failed = match carry.output(output, connection.post()) {
                Ok(Some(RobotOutput::Sense { step })) => wheels.sample().map(|y| {
                    report.steps_done = step;
                    progress.tick(step, report.erased_steps);
                    connection.handle_sample(socket.now(), step, y);
                }),
                Ok(Some(RobotOutput::Apply(actuation))) => {
                    let applied = connection.endpoint().map_or(0, |e| e.commands_applied());
                    report.applied(&actuation, &plan, applied);
                    wheels.set_wheels(actuation.wheels)
                }
                Ok(_) => Ok(()),
                Err(error) => Err(error),
            };
            if let Err(error) = failed {
                // Nothing queued goes out: what the failure left undone (a sample, a write
                // to the store) had to come first. Before the outcome, the controller is told
                // why (the abort replaces the queue), so that it ends now, not after silence.
                let before_outcome = run.outcome.is_none();
                if before_outcome {
                    connection.abort(error.to_string());
                }
                run.stop(error, post_running);
                if !before_outcome {
                    break;
                }
            }
        }
        if connection.is_closed() || run.halted {
            break;
        }
        let Some(deadline) = connection.poll_timeout() else {
            break;
        };
        match socket.recv_until(deadline) {
            Ok(Some((from, now, bytes))) => connection.handle_datagram(now, from, bytes),
            Ok(None) => connection.handle_timeout(socket.now()),
            Err(error) => {
                // A stop request or a socket error: the next round sends the Abort, if any.
                let post_running = connection.post().is_some() && run.outcome.is_some();
                if run.outcome.is_none() {
                    connection.abort(error.to_string());
                }
                run.stop(error, post_running);
            }
        }
    }
    wheels.stop();
    let counted = Counted {
        socket: socket.counts(),
        channel: connection.counts(),
        authenticated: connection.endpoint().is_some(),
    };
    if let Some(endpoint) = connection.endpoint() {
        report.commands_applied = Some(endpoint.commands_applied());
    }
    let key = connection.endpoint().map_or(&[][..], |e| e.key());
    let store = store.zip(connection.post().map(|link| link.endpoint()));
    Ok(finish(
        report,
        run,
        key,
        options.key_out.as_ref(),
        plan.bits_per_unit(),
        &counted,
        store,
    ))
}
