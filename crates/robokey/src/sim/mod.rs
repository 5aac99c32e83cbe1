//! Closed-loop simulation of one run (docs/model.md, docs/protocol.md, docs/experiments.md):
//! the robot and controller endpoints the agents run, on an ideal virtual link
//! ([`crate::pair::Pair`]), in a world of a plant and its sensors, with the eavesdropper
//! listening. One loop for both sensing modes.

mod metrics;
mod trace;
mod world;

use std::collections::{BTreeMap, VecDeque};
use std::time::Duration;

pub use trace::TraceRow;
pub(crate) use trace::TraceRows;

use self::world::{PrivateSenses, Senses, World};
use crate::config::{Config, EveStrategy};
use crate::eve;
use crate::metrics::Metrics;
use crate::pair::Pair;
use crate::private::{DoubletEavesdropper, Eavesdroppers, PrivateRun};
use crate::protocol::{
    Controller, KeyBits, Message, ModePlan, Outcome, Robot, SessionPlan, Time, Timing,
};
use crate::rng::{Purpose, stream};
use crate::world::Scene;

/// Everything one run produced.
#[derive(Clone, Debug)]
pub struct RunOutput {
    /// The metrics of docs/experiments.md.
    pub metrics: Metrics,
    /// Per-step rows (empty unless requested from [`simulate`] or [`simulate_plan`]).
    pub trace: Vec<TraceRow>,
    /// How the session ended for the robot.
    pub robot_outcome: Option<Outcome>,
    /// How the session ended for the controller.
    pub controller_outcome: Option<Outcome>,
    /// The applied bit and both decisions of every step `k < N`.
    pub steps: Vec<StepBits>,
    /// The three keys.
    pub keys: RunKeys,
    /// Private mode: the doublets and every party's evidence on each bit.
    pub private: Option<PrivateRun>,
}

/// The keys of a run (zeroized on drop).
#[derive(Clone, Debug, Default)]
pub struct RunKeys {
    /// `K_r`, the robot's.
    pub robot: KeyBits,
    /// `K_c`, the controller's.
    pub controller: KeyBits,
    /// `K_a`, Eve's, when the run had one.
    pub eve: Option<KeyBits>,
}

/// A failure of the simulation itself (not of the protocol).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// The controller aborted the session.
    #[error("replicate {replicate}: the session aborted: {reason}")]
    Aborted {
        /// Replicate index.
        replicate: u32,
        /// Why.
        reason: String,
    },
}

/// Step k's applied bit and the decisions made about it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepBits {
    /// `b(k)` (none: protocol off or erased).
    pub bit: Option<u8>,
    /// The controller's `b̂(k)`.
    pub bhat: Option<u8>,
    /// Eve's `b̂(k)`.
    pub bhat_eve: Option<u8>,
}

/// Simulates replicate `replicate` of a validated configuration. Deterministic: a pure
/// function of `(config, replicate)`.
///
/// # Errors
/// [`SimError`] when the observer breaks down and the session aborts.
pub fn simulate(
    config: &Config,
    replicate: u32,
    record_trace: bool,
) -> Result<RunOutput, SimError> {
    let plan = SessionPlan::from_config(config, replicate);
    simulate_plan(config, plan, replicate, record_trace, Eavesdroppers::Both)
}

/// [`simulate`] with a precomputed plan (the config digest is computed once per sweep
/// point rather than once per run), judging each private-sensing doublet for the
/// eavesdroppers `judged` names: with [`Eavesdroppers::Camera`] the bits' `commands`
/// evidence is none, and so are Eve's key and decisions if she is the `commands` one.
///
/// # Errors
/// [`SimError`] when the session aborts.
pub fn simulate_plan(
    config: &Config,
    plan: SessionPlan,
    replicate: u32,
    record_trace: bool,
    judged: Eavesdroppers,
) -> Result<RunOutput, SimError> {
    if !record_trace {
        return run(config, plan, replicate, None, None, judged);
    }
    let mut trace = Vec::new();
    let mut output = run(
        config,
        plan,
        replicate,
        Some(&mut |row| trace.push(row)),
        None,
        judged,
    )?;
    output.trace = trace;
    Ok(output)
}

/// [`simulate_plan`] that hands each row of the trace to `sink` as soon as it is complete,
/// in order of k, instead of keeping them: memory does not grow with the number of steps.
/// The output's `trace` is empty.
///
/// # Errors
/// [`SimError`] when the session aborts (the rows before the abort have been handed over).
pub fn simulate_plan_streaming(
    config: &Config,
    plan: SessionPlan,
    replicate: u32,
    sink: &mut dyn FnMut(TraceRow),
) -> Result<RunOutput, SimError> {
    run(
        config,
        plan,
        replicate,
        Some(sink),
        None,
        Eavesdroppers::Both,
    )
}

/// Messages of a session's handshake and closing, besides its steps' (measured: 6).
const FRAMING_MESSAGES: usize = 8;

/// What a session of `steps` steps' transcript is sized for up front, so that it is not
/// copied as it grows: `2·N + 8` — a command and a measurement per step, and the
/// handshake's and the closing's messages (a default session: 2,046 messages of 1,020
/// steps; a longer transcript grows as before).
fn transcript_capacity(steps: u32) -> usize {
    2 * steps as usize + FRAMING_MESSAGES
}

/// [`simulate`] that also returns every message in the order an eavesdropper hears it, so
/// that several eavesdroppers can be fed the same session.
///
/// # Errors
/// [`SimError`] when the session aborts.
pub fn simulate_transcript(
    config: &Config,
    replicate: u32,
) -> Result<(RunOutput, Vec<Message>), SimError> {
    let plan = SessionPlan::from_config(config, replicate);
    let mut transcript = Vec::with_capacity(transcript_capacity(plan.agreed.steps));
    let output = run(
        config,
        plan,
        replicate,
        None,
        Some(&mut transcript),
        Eavesdroppers::Both,
    )?;
    Ok((output, transcript))
}

/// What [`simulate`] gives for replicate `replicate` of `config`, from the session simulated
/// once without an eavesdropper: `run` and `transcript` are what [`simulate_transcript`]
/// returned for the same replicate of a configuration that differs at most in its `[eve]`
/// table (she never changes the session). The eavesdropper `config` asks for, drawn as
/// [`simulate`] draws her, hears the transcript: the output is bit for bit the live run's.
#[must_use]
pub fn replay(
    config: &Config,
    replicate: u32,
    run: &RunOutput,
    transcript: &[Message],
) -> RunOutput {
    if !(config.eve.enabled && config.protocol.enabled) {
        let mut output = run.clone();
        output.keys.eve = None;
        output.steps.iter_mut().for_each(|s| s.bhat_eve = None);
        output.metrics = metrics::odometry(
            &output.steps,
            run.metrics.jx,
            &output.keys,
            &SessionPlan::from_config(config, replicate),
            config.protocol.enabled,
        );
        return output;
    }
    let mut eve = eve::build(
        config,
        &mut stream(config.run.seed, Purpose::Eve, u64::from(replicate)),
    );
    overheard(config, replicate, run, transcript, eve.as_mut(), |_, _| {})
}

/// [`replay`] with a given eavesdropper (e.g. one who learned from earlier sessions):
/// `eve` hears `transcript` as session `replicate`; her decisions and key are written into a
/// copy of `run` and its metrics recomputed. `on_decision` sees her after each decision.
pub fn overheard<E: eve::Eavesdropper + ?Sized>(
    config: &Config,
    replicate: u32,
    run: &RunOutput,
    transcript: &[Message],
    eve: &mut E,
    mut on_decision: impl FnMut(&E, &crate::protocol::StepDecision),
) -> RunOutput {
    let plan = SessionPlan::from_config(config, replicate);
    let mut output = run.clone();
    let steps = &mut output.steps;
    let key = eve::hear(eve, &plan, transcript, |eve, d| {
        if let Some(logged) = steps.get_mut(d.step as usize) {
            logged.bhat_eve = d.bit;
        }
        on_decision(eve, d);
    });
    output.keys.eve = Some(key);
    output.metrics = metrics::odometry(
        &output.steps,
        run.metrics.jx,
        &output.keys,
        &plan,
        config.protocol.enabled,
    );
    output
}

fn run<'a>(
    config: &'a Config,
    plan: SessionPlan,
    replicate: u32,
    trace_sink: Option<&'a mut dyn FnMut(TraceRow)>,
    transcript: Option<&'a mut Vec<Message>>,
    judged: Eavesdroppers,
) -> Result<RunOutput, SimError> {
    let stream_of = |purpose| stream(config.run.seed, purpose, u64::from(replicate));
    let agreed = &plan.agreed;
    let steps = agreed.steps;
    let senses = match &plan.mode {
        ModePlan::Odometry(_) => Senses::Odometry {
            eve: (config.eve.enabled && agreed.enabled).then(|| {
                let mut eve = eve::build(config, &mut stream_of(Purpose::Eve));
                eve.begin_session(&plan);
                eve
            }),
            transcript,
        },
        ModePlan::Private(private) => Senses::Private(Box::new(PrivateSenses {
            eve: DoubletEavesdropper::new(config, judged),
            decided: VecDeque::new(),
            heard: BTreeMap::new(),
            run: PrivateRun::sized_for(private, steps),
        })),
    };
    let mut world = World {
        config,
        trajectory: config.trajectory(),
        sample_time: agreed.sample_time,
        scene: Scene::new(config, config.sensing.mode, stream_of),
        senses,
        tracking_error: 0.0,
        log: vec![StepBits::default(); steps as usize + 1],
        trace: TraceRows::new(trace_sink),
        robot_outcome: None,
        controller_outcome: None,
        abort: None,
    };
    let timing = Timing::default();
    let robot = Robot::new(
        plan.clone(),
        timing,
        &mut stream_of(Purpose::Key),
        Time::ZERO,
    );
    let controller = Controller::new(config, plan.clone(), timing, Time::ZERO);
    let mut pair = Pair::ideal(robot, controller);
    // The session ends at `t_N`; the limit only bounds a session that would not end.
    let limit = Duration::from_secs_f64(agreed.sample_time * f64::from(steps + 1))
        + timing.silence_timeout * 4;
    pair.drive(&mut world, limit);
    if let Some(reason) = world.abort {
        return Err(SimError::Aborted { replicate, reason });
    }
    if let Senses::Private(p) = &mut world.senses {
        p.eve.finish();
        p.collect();
    }
    world.record_private(&pair.robot);
    let mut log = std::mem::take(&mut world.log);
    log.truncate(steps as usize);
    let jx = world.tracking_error / f64::from(steps.max(1));
    let (keys, private) = match world.senses {
        Senses::Odometry { eve, .. } => (
            RunKeys {
                robot: pair.robot.key().to_vec().into(),
                controller: pair.controller.key().to_vec().into(),
                eve: eve.as_ref().map(|e| e.key()),
            },
            None,
        ),
        Senses::Private(p) => {
            let key = |camera: bool| config.eve.enabled.then(|| p.eve.key(camera)).flatten();
            (
                RunKeys {
                    robot: pair.robot.key().to_vec().into(),
                    controller: pair.controller.key().to_vec().into(),
                    eve: key(config.eve_strategy() != EveStrategy::Commands),
                },
                Some(PrivateRun {
                    camera_key: key(true),
                    commands_key: key(false),
                    ..p.run
                }),
            )
        }
    };
    let metrics = match &private {
        None => metrics::odometry(&log, jx, &keys, &plan, config.protocol.enabled),
        Some(run) => metrics::private(config, &run.bits, &keys, jx),
    };
    Ok(RunOutput {
        metrics,
        trace: Vec::new(),
        robot_outcome: world.robot_outcome,
        controller_outcome: world.controller_outcome,
        steps: log,
        keys,
        private,
    })
}

#[cfg(test)]
mod tests {
    use sha2::{Digest, Sha256};

    use super::*;
    use crate::config::{EveStrategy, Feedback, SensingMode};
    use crate::observer::Variant;

    /// The configurations whose runs are pinned: the default, m = 1, the paper's variant,
    /// feedback from the estimate, the soft and identifying eavesdroppers, and private
    /// sensing (one and two bits per doublet, the camera and the commands eavesdroppers).
    fn pinned_configs() -> Vec<(&'static str, Config)> {
        let with = |edit: fn(&mut Config)| {
            let mut config = Config::default();
            edit(&mut config);
            config.validate().expect("a valid pinned configuration");
            config
        };
        vec![
            ("default", Config::default()),
            ("m=1", with(|c| c.observer.m = 1)),
            ("paper", with(|c| c.observer.variant = Variant::Paper)),
            (
                "estimate",
                with(|c| c.controller.feedback = Feedback::Estimate),
            ),
            ("soft", with(|c| c.eve.strategy = Some(EveStrategy::Soft))),
            (
                "identify",
                with(|c| c.eve.strategy = Some(EveStrategy::Identify)),
            ),
            ("dv=0.01", with(|c| c.protocol.delta_v = 0.01)),
            ("alpha=0.3", with(|c| c.eve.alpha = 0.3)),
            ("private", with(|c| c.sensing.mode = SensingMode::Private)),
            (
                "private, two bits",
                with(|c| {
                    c.sensing.mode = SensingMode::Private;
                    c.protocol.bits_per_doublet = 2;
                    c.protocol.delta_omega = Some(0.035);
                }),
            ),
            (
                "private, commands Eve",
                with(|c| {
                    c.sensing.mode = SensingMode::Private;
                    c.eve.strategy = Some(EveStrategy::Commands);
                }),
            ),
        ]
    }

    /// SHA-256 (first 8 bytes, hex) of every decision, key and metric of replicates 0–2
    /// (real numbers to 9 significant digits), of the controller's `d̂` and `x̂` (to 6), and
    /// in private sensing of every bit's evidence.
    fn fingerprint(config: &Config) -> String {
        let mut hash = Sha256::new();
        for replicate in 0..3 {
            let out = simulate(config, replicate, true).expect("the pinned runs complete");
            for row in &out.trace {
                for x in row.dhat.iter().flatten().chain(row.xhat.iter().flatten()) {
                    hash.update(format!("{x:.5e}"));
                }
            }
            for s in &out.steps {
                hash.update([
                    s.bit.unwrap_or(9),
                    s.bhat.unwrap_or(9),
                    s.bhat_eve.unwrap_or(9),
                ]);
            }
            hash.update(out.keys.robot.as_slice());
            hash.update(out.keys.controller.as_slice());
            if let Some(eve) = &out.keys.eve {
                hash.update(eve.as_slice());
            }
            let real = |x: Option<f64>| x.map_or_else(|| "-".into(), |x| format!("{x:.9e}"));
            if let Some(private) = &out.private {
                hash.update(format!("{} {}", private.doublets, private.gated));
                for b in &private.bits {
                    hash.update(format!(
                        "{} {:?} {} {} {} {} {} {} {} {}",
                        b.step,
                        b.kind,
                        b.bit,
                        real(Some(b.turn_rate)),
                        real(Some(b.controller)),
                        real(Some(b.camera)),
                        real(b.commands),
                        real(Some(b.camera_separation)),
                        real(Some(b.assumed_separation)),
                        real(b.commands_separation)
                    ));
                }
            }
            let m = &out.metrics;
            hash.update(format!(
                "{:?} {:?} {} {} {} {} {} {} {} {:?} {:?} {:?}",
                m.codewords_sent,
                m.accepted,
                real(m.accepted_pct),
                real(m.correct_pct),
                real(m.ber_controller),
                real(m.ber_eve),
                real(Some(m.jx)),
                real(m.eve_disagreement_pct),
                real(m.accepted_pct),
                m.key_match,
                m.n_bce,
                m.n_acc
            ));
        }
        hash.finalize()[..8]
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect()
    }

    /// Whole runs keep every decision, key and metric (recorded before the observer and the
    /// simulation loop were rewritten for speed, docs/speed.md).
    #[test]
    fn pinned_runs_keep_their_decisions_keys_and_metrics() {
        let got: Vec<String> = pinned_configs()
            .iter()
            .map(|(name, config)| format!("{name} {}", fingerprint(config)))
            .collect();
        assert_eq!(got.join("\n"), PINNED.trim());
    }

    /// In a lagging world the camera eavesdropper smooths over later doublets and decides a
    /// doublet after the controller has: that doublet's row stays open until she has, and the
    /// trace comes out whole and in order.
    #[test]
    fn a_trace_waits_for_an_eavesdropper_who_decides_late() {
        let mut config = Config::default();
        config.sensing.mode = SensingMode::Private;
        config.world = Some(crate::world::WorldConfig {
            lag: Some(0.05),
            ..Default::default()
        });
        config.validate().expect("a valid lagging world");
        let out = simulate(&config, 0, true).expect("the session runs");
        let ks: Vec<u32> = out.trace.iter().map(|row| row.k).collect();
        assert_eq!(ks, (0..ks.len() as u32).collect::<Vec<_>>());
        let decided = out
            .trace
            .iter()
            .filter(|row| row.bhat_eve.is_some())
            .count();
        let bits = out.private.expect("private sensing").bits.len();
        assert!(bits > 0);
        assert_eq!(decided, bits);
    }

    /// Three-step doublets (a prior lag): the trace comes out whole and in order (it panicked
    /// before), every step of a doublet has its nominal input, and each decision lands on its
    /// doublet's last row.
    #[test]
    fn a_trace_of_three_step_doublets_is_whole() {
        let mut config = Config::default();
        config.sensing.mode = SensingMode::Private;
        config.private.prior_lag = 0.05;
        config.world = Some(crate::world::WorldConfig {
            lag: Some(0.05),
            ..Default::default()
        });
        config
            .validate()
            .expect("a valid lagging world with its prior");
        let out = simulate(&config, 0, true).expect("the session runs");
        let ks: Vec<u32> = out.trace.iter().map(|row| row.k).collect();
        assert_eq!(ks, (0..ks.len() as u32).collect::<Vec<_>>());
        let last = out.trace.len() - 1;
        assert!(out.trace[..last].iter().all(|row| row.nominal.is_some()));
        let decided: Vec<usize> = (0..out.trace.len())
            .filter(|&k| out.trace[k].bhat.is_some())
            .collect();
        let bits = out.private.expect("private sensing").bits.len();
        assert!(bits > 0);
        assert_eq!(decided.len(), bits);
        assert!(decided.iter().all(|k| k % 3 == 2), "{decided:?}");
    }

    const PINNED: &str = "
default b430a4a2ebbec88f
m=1 8dfc3212a670aefb
paper eaa14f0a00b2a279
estimate 0142c4a09e0b7394
soft b430a4a2ebbec88f
identify f28af9b932546d1a
dv=0.01 eb2af466b7c3bc55
alpha=0.3 5af0a2a0aba0e6f1
private 5d971265101167fc
private, two bits 0fd1404aa740f626
private, commands Eve 62af15a5ef685d26
";
}
