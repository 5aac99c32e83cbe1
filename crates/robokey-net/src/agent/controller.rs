//! The controller agent: it opens the session, answers every report with a command, decides
//! the fates and confirms (docs/protocol.md, "On a network"); in private sensing it commands
//! each doublet from its own sensor's samples; with a store it then drives post-processing.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use rand::RngExt;
use robokey::Config;
use robokey::config::SensingMode;
use robokey::connection::{ControllerConnection, PostLink, Setup};
use robokey::interrupt::Interrupt;
use robokey::protocol::auth::PairingSecret;
use robokey::protocol::{ControllerEvent, SessionPlan, Timing};
use robokey_secrecy::postprocess::ControllerPost;

use super::post::AgentStore;
use super::report::{Progress, SessionReport};
use super::socket::Socket;
use super::worker::{ANSWER_POLL, Worker};
use super::{Carry, Counted, Run, finish};
use crate::error::NetError;
use crate::random::os_rng;
use crate::secret_file::check_writable;
use crate::sensor::{SensorEvent, SensorFeed, SensorSpec};

/// How often the controller's loop takes its sensor's samples.
const SENSOR_POLL: Duration = Duration::from_millis(1);

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
    /// Threads of the block's estimate (`--jobs`; 0: one per core, never more than one per
    /// core). The keys do not depend on it.
    pub jobs: usize,
}

/// Runs one session as the controller. Every way out after the socket is bound returns a
/// report: a robot that does not answer, a socket error, a stop request.
///
/// # Errors
/// `--key-out` exists or has no folder, the sensor is missing (private sensing), refused
/// (odometry mode) or unreachable, the store cannot be opened, or the socket cannot be bound.
pub fn run_controller(
    config: &Config,
    options: &ControllerOptions,
) -> Result<SessionReport, NetError> {
    if let Some(path) = &options.key_out {
        check_writable(path, "key file")?;
    }
    let pairing = &options.pairing;
    let (link, mut store) = AgentStore::<ControllerPost>::for_agent(
        config,
        options.store.as_ref(),
        pairing,
        options.allow_restricted,
    )?
    .unzip();
    // Block-time computations (seconds with slip) run on a worker thread while the loop goes
    // on answering the robot.
    let link = link.map(PostLink::deferring);
    let mut worker = match link {
        Some(_) => Some(Worker::start(options.jobs)?),
        None => None,
    };
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
    let session = options.session.unwrap_or_else(|| rng.random());
    let mut socket = Socket::bind(options.bind, options.interrupt.clone())?;
    let setup = Setup {
        config,
        pairing,
        timing: options.timing,
    };
    let mut connection =
        ControllerConnection::new(setup, options.robot, session, link, rng, socket.now());
    let plan = SessionPlan::from_config(config, session);
    let mut report = SessionReport::new("controller", pairing);
    report.bound(session, &plan);
    let mut progress = Progress::new("controller", plan.agreed.steps);
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
            let failed = carry.output(output, connection.post()).map(|event| {
                if let Some(event) = event {
                    report.controller_event(&event, &plan);
                    if let ControllerEvent::Decoded(_) = event {
                        progress.tick(report.steps_done, report.erased_steps);
                    }
                }
            });
            if let Err(error) = failed {
                // Nothing that follows goes out: the store must be written first.
                run.stop(error, post_running);
                break;
            }
        }
        if let (Some(worker), Some(job)) = (worker.as_mut(), connection.take_computation())
            && let Err(error) = worker.submit(job)
        {
            run.stop(error, true);
        }
        if connection.is_closed() || run.halted {
            break;
        }
        let Some(deadline) = connection.poll_timeout() else {
            break;
        };
        // With a sensor, the socket is left every millisecond to take its samples; with a
        // computation out, every few to take its answer.
        let mut wake = match &sensor {
            Some(_) => deadline.min(socket.now() + SENSOR_POLL),
            None => deadline,
        };
        if worker.as_ref().is_some_and(Worker::is_busy) {
            wake = wake.min(socket.now() + ANSWER_POLL);
        }
        let mut woke = false;
        match socket.recv_until(wake) {
            Ok(Some((from, now, bytes))) => connection.handle_datagram(now, from, bytes),
            Ok(None) => woke = true,
            Err(error) => {
                // A stop request or a socket error: the next round sends the Abort, if any.
                let post_running = connection.post().is_some() && run.outcome.is_some();
                if run.outcome.is_none() {
                    connection.abort(error.to_string());
                }
                run.stop(error, post_running);
            }
        }
        if woke && socket.now() >= deadline {
            connection.handle_timeout(socket.now());
        }
        while let Some(event) = sensor.as_ref().and_then(SensorFeed::try_next) {
            match event {
                SensorEvent::Sample(sample) => {
                    report.steps_done = sample.step;
                    connection.handle_sensor(socket.now(), sample.step, sample.pose);
                }
                SensorEvent::Stopped(why) => connection.handle_sensor_stopped(socket.now(), why),
            }
        }
        match worker.as_mut().map(Worker::try_answer).transpose() {
            Ok(Some(Some(answered))) => {
                let block = answered.computed.block();
                let seconds = answered.took.as_secs_f64();
                println!(
                    "controller: block {block}: {} took {seconds:.1} s (on a worker thread, the \
                     link answered meanwhile)",
                    answered.what
                );
                if let Some(store) = store.as_mut() {
                    store.report.computing_seconds.push(seconds);
                }
                connection.handle_computed(socket.now(), answered.computed);
            }
            Ok(_) => {}
            Err(error) => run.stop(error, true),
        }
    }
    let counted = Counted {
        socket: socket.counts(),
        channel: connection.counts(),
        authenticated: connection.is_established(),
    };
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
