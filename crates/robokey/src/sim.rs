//! Closed-loop simulation of one run: plant with true noise, robot and controller
//! endpoints exchanging every message, and the eavesdropper listening (docs/model.md, docs/protocol.md, docs/experiments.md).

use std::collections::VecDeque;

use rand_distr::{Distribution, StandardNormal};
use subtle::ConstantTimeEq;

use crate::config::Config;
use crate::config::SensingMode;
use crate::eve;
use crate::metrics::Metrics;
use crate::model::{Pose, Unicycle, clip_wheels, unicycle_step};
use crate::private::PrivateRun;
use crate::protocol::{
    ControllerEndpoint, ControllerEvent, ControllerInput, ControllerOutput, KeyBits, Message,
    Outcome, RobotEndpoint, RobotInput, RobotOutput, SessionMessage, SessionPlan,
};
use crate::rng::{Purpose, stream};

/// One row of `trace.csv` (docs/experiments.md): step k and what each party knew at k.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TraceRow {
    /// Step k.
    pub k: u32,
    /// `t = k·T` (s).
    pub t: f64,
    /// Reference position (m).
    pub reference: [f64; 2],
    /// True pose `x(k)`.
    pub pose: [f64; 3],
    /// Measurement `y(k)`.
    pub measurement: [f64; 3],
    /// Clipped nominal `uU(k)` (m/s, rad/s); none at the stop step.
    pub nominal: Option<[f64; 2]>,
    /// `u0D(k)` (rad/s).
    pub u0: Option<[f64; 2]>,
    /// `u1D(k)` (rad/s).
    pub u1: Option<[f64; 2]>,
    /// `b(k)`, applied on `[k, k+1)`.
    pub bit: Option<u8>,
    /// `d̂(k−1)` as `[Δv̂, Δω̂]`.
    pub dhat: Option<[f64; 2]>,
    /// `x̂(k)`.
    pub xhat: Option<[f64; 3]>,
    /// `b̂(k−1)` of the controller.
    pub bhat: Option<u8>,
    /// `b̂(k−1)` of Eve.
    pub bhat_eve: Option<u8>,
    /// Private mode: the ω bit the step's perturbation carries.
    pub bit_omega: Option<u8>,
    /// Private mode: Eve's camera sample `y_e(k)`.
    pub camera: Option<[f64; 3]>,
}

impl TraceRow {
    /// Column names of `trace.csv`.
    pub const COLUMNS: [&'static str; 28] = [
        "k",
        "t",
        "ref_x",
        "ref_y",
        "px",
        "py",
        "theta",
        "meas_x",
        "meas_y",
        "meas_theta",
        "v_nom",
        "omega_nom",
        "u0_r",
        "u0_l",
        "u1_r",
        "u1_l",
        "b",
        "dhat_v",
        "dhat_omega",
        "xhat_x",
        "xhat_y",
        "xhat_theta",
        "bhat",
        "bhat_eve",
        "b_omega",
        "eve_x",
        "eve_y",
        "eve_theta",
    ];
}

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
    simulate_plan(config, plan, replicate, record_trace)
}

/// [`simulate`] with a precomputed plan (the config digest is computed once per sweep
/// point rather than once per run).
///
/// # Errors
/// [`SimError`] when the session aborts.
pub fn simulate_plan(
    config: &Config,
    plan: SessionPlan,
    replicate: u32,
    record_trace: bool,
) -> Result<RunOutput, SimError> {
    if !record_trace {
        return run(config, plan, replicate, None, None);
    }
    let mut trace = Vec::new();
    let mut output = run(
        config,
        plan,
        replicate,
        Some(&mut |row| trace.push(row)),
        None,
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
    run(config, plan, replicate, Some(sink), None)
}

/// The rows of a trace still being filled in, between the simulation and its sink. Each
/// step writes its own row and, in private mode, its neighbours (a doublet spans two steps
/// and is decided at the sample after it); [`TraceRows::complete_before`] hands over the
/// rows no later step writes.
pub(crate) struct TraceRows<'a> {
    sink: Option<&'a mut dyn FnMut(TraceRow)>,
    /// Rows `first, first + 1, …` not handed over yet.
    open: VecDeque<TraceRow>,
    first: usize,
}

impl<'a> TraceRows<'a> {
    /// Rows for `sink`; none are kept without one.
    pub(crate) fn new(sink: Option<&'a mut dyn FnMut(TraceRow)>) -> Self {
        Self {
            sink,
            open: VecDeque::new(),
            first: 0,
        }
    }

    /// Row `k`, when a trace is recorded.
    ///
    /// # Panics
    /// When row `k` was already handed over (a simulation bug).
    pub(crate) fn row(&mut self, k: usize) -> Option<&mut TraceRow> {
        self.sink.as_ref()?;
        let index = k
            .checked_sub(self.first)
            .expect("a trace row is written after it was handed over");
        if index >= self.open.len() {
            self.open.resize_with(index + 1, TraceRow::default);
        }
        Some(&mut self.open[index])
    }

    /// Hands every row before `k` to the sink.
    pub(crate) fn complete_before(&mut self, k: usize) {
        let Some(sink) = self.sink.as_mut() else {
            return;
        };
        while self.first < k {
            sink(self.open.pop_front().unwrap_or_default());
            self.first += 1;
        }
    }
}

impl Drop for TraceRows<'_> {
    /// The rows still open are complete once the simulation has ended.
    fn drop(&mut self) {
        self.complete_before(self.first + self.open.len());
    }
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
    let mut transcript = Vec::new();
    let plan = SessionPlan::from_config(config, replicate);
    let output = run(config, plan, replicate, None, Some(&mut transcript))?;
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
        output.metrics = compute_metrics(
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
    output.metrics = compute_metrics(
        &output.steps,
        run.metrics.jx,
        &output.keys,
        &plan,
        config.protocol.enabled,
    );
    output
}

fn run(
    config: &Config,
    plan: SessionPlan,
    replicate: u32,
    trace_sink: Option<&mut dyn FnMut(TraceRow)>,
    mut transcript: Option<&mut Vec<Message>>,
) -> Result<RunOutput, SimError> {
    let mut trace = TraceRows::new(trace_sink);
    if config.sensing.mode == SensingMode::Private {
        return Ok(crate::private::simulate(config, replicate, &mut trace));
    }
    let seed = config.run.seed;
    let stream_of = |purpose| stream(seed, purpose, u64::from(replicate));
    let (mut process_rng, mut measurement_rng) =
        (stream_of(Purpose::Process), stream_of(Purpose::Measurement));
    let process_std = Pose::from(config.noise.process_std);
    let measurement_std = Pose::from(config.noise.measurement_std);
    let gaussian = |rng: &mut rand::rngs::ChaCha8Rng, std: &Pose| {
        Pose::new(
            StandardNormal.sample(rng),
            StandardNormal.sample(rng),
            StandardNormal.sample(rng),
        )
        .component_mul(std)
    };

    let steps = plan.steps;
    let sample_time = plan.sample_time;
    let drive = plan.drive;
    let trajectory = config.trajectory();
    let mut robot = RobotEndpoint::new(plan.clone(), &mut stream_of(Purpose::Key));
    let mut eve = (config.eve.enabled && plan.enabled).then(|| {
        let mut eve = eve::build(config, &mut stream_of(Purpose::Eve));
        eve.begin_session(&plan);
        eve
    });
    let mut controller = ControllerEndpoint::new(config, plan);

    let mut log = vec![StepBits::default(); steps as usize + 1];
    let mut pose = Pose::zeros();
    let mut tracking_error = 0.0;
    let mut outcomes = (None, None);
    let mut abort = None;

    for k in 0..=steps {
        let reference = trajectory.at(f64::from(k) * sample_time).position;
        if k > 0 {
            tracking_error += (pose.xy() - reference).norm();
        }
        let y = pose + gaussian(&mut measurement_rng, &measurement_std);
        if let Some(row) = trace.row(k as usize) {
            row.k = k;
            row.t = f64::from(k) * sample_time;
            row.reference = reference.into();
            row.pose = pose.into();
            row.measurement = y.into();
        }
        robot.handle_input(RobotInput::Sample { step: k, y });
        let mut wheels = None;
        // Deliver until both sides are quiet; the robot's Apply ends the step.
        loop {
            let mut quiet = true;
            while let Some(output) = robot.poll_output() {
                quiet = false;
                match output {
                    RobotOutput::Transmit(message) => {
                        if let Some(transcript) = transcript.as_deref_mut() {
                            transcript.push(message.clone());
                        }
                        if let Some(d) = eve.as_mut().and_then(|eve| eve.observe(&message)) {
                            log[d.step as usize].bhat_eve = d.bit;
                            if let Some(row) = trace.row(d.step as usize + 1) {
                                row.bhat_eve = d.bit;
                            }
                        }
                        controller.handle_input(ControllerInput::Frame(message));
                    }
                    RobotOutput::Apply(actuation) => {
                        log[actuation.step as usize].bit = actuation.bit;
                        if let Some(row) = trace.row(actuation.step as usize) {
                            row.bit = actuation.bit;
                        }
                        wheels = Some(actuation.wheels);
                    }
                    RobotOutput::Finished(outcome) => outcomes.0 = Some(outcome),
                }
            }
            while let Some(output) = controller.poll_output() {
                quiet = false;
                match output {
                    ControllerOutput::Transmit(message) => {
                        if let Some(transcript) = transcript.as_deref_mut() {
                            transcript.push(message.clone());
                        }
                        if let Some(eve) = eve.as_mut() {
                            eve.observe(&message);
                        }
                        if let Message::Session(SessionMessage::Command { step, u0, u1, .. }) =
                            &message
                            && let Some(row) = trace.row(*step as usize)
                        {
                            row.u0 = Some(*u0);
                            row.u1 = Some(*u1);
                        }
                        robot.handle_input(RobotInput::Frame(message));
                    }
                    ControllerOutput::Event(event) => match event {
                        ControllerEvent::Decoded(d) => {
                            log[d.step as usize].bhat = d.bit;
                            if let Some(row) = trace.row(d.step as usize + 1) {
                                row.bhat = d.bit;
                                row.dhat = Some(d.estimate.deviation.into());
                                row.xhat = Some(d.estimate.state.into());
                            }
                        }
                        ControllerEvent::Commanded { step, nominal } => {
                            if let Some(row) = trace.row(step as usize) {
                                row.nominal = Some(nominal.into());
                            }
                        }
                        ControllerEvent::Finished(outcome) => {
                            if let Outcome::Aborted(reason) = &outcome {
                                abort = Some(reason.clone());
                            }
                            outcomes.1 = Some(outcome);
                        }
                        _ => {}
                    },
                }
            }
            if quiet {
                break;
            }
        }
        if let Some(reason) = abort {
            return Err(SimError::Aborted { replicate, reason });
        }
        // Every message of step k has been delivered: no later step writes row k.
        trace.complete_before(k as usize + 1);
        if k < steps {
            let applied = wheels.map_or_else(Unicycle::zeros, |w| {
                drive.to_unicycle(clip_wheels(w, config.robot.wheel_limit))
            });
            pose = unicycle_step(&pose, &applied, sample_time)
                + gaussian(&mut process_rng, &process_std);
        }
    }

    log.truncate(steps as usize);
    let keys = RunKeys {
        robot: robot.key().to_vec().into(),
        controller: controller.key().to_vec().into(),
        eve: eve.as_ref().map(|e| e.key()),
    };
    let metrics = compute_metrics(
        &log,
        tracking_error / f64::from(steps.max(1)),
        &keys,
        controller.plan(),
        config.protocol.enabled,
    );
    Ok(RunOutput {
        metrics,
        trace: Vec::new(),
        robot_outcome: outcomes.0,
        controller_outcome: outcomes.1,
        steps: log,
        keys,
        private: None,
    })
}

fn compute_metrics(
    log: &[StepBits],
    jx: f64,
    keys: &RunKeys,
    plan: &SessionPlan,
    enabled: bool,
) -> Metrics {
    if !enabled {
        return Metrics {
            jx,
            ..Metrics::default()
        };
    }
    let applied: Vec<&StepBits> = log.iter().filter(|s| s.bit.is_some()).collect();
    let error_rate = |pick: fn(&StepBits) -> Option<u8>| {
        let wrong = applied.iter().filter(|s| pick(s) != s.bit).count();
        (!applied.is_empty()).then(|| wrong as f64 / applied.len() as f64)
    };
    let (k_r, k_c) = (keys.robot.as_slice(), keys.controller.as_slice());
    let k_a = keys.eve.as_ref();
    let codewords = u64::from(plan.codewords());
    let accepted_bits = k_c.len();
    let accepted = (accepted_bits / plan.code.k()) as u64;
    let share = |other: &[u8], equal: bool| {
        let count = other
            .iter()
            .zip(k_c)
            .filter(|(a, b)| (a == b) == equal)
            .count();
        (accepted_bits > 0).then(|| 100.0 * count as f64 / accepted_bits as f64)
    };
    let n_bce = k_a.map(|_| {
        let mut table = [0u64; 8];
        for s in &applied {
            if let (Some(b), Some(c), Some(a)) = (s.bit, s.bhat, s.bhat_eve) {
                table[usize::from(b << 2 | c << 1 | a)] += 1;
            }
        }
        table
    });
    let n_acc = k_a.map(|k_a| {
        let mut table = [0u64; 8];
        for ((s, c), a) in k_r.iter().zip(k_c).zip(k_a.iter()) {
            table[usize::from(s << 2 | c << 1 | a)] += 1;
        }
        table
    });
    Metrics {
        codewords_sent: Some(codewords),
        accepted: Some(accepted),
        accepted_pct: (codewords > 0).then(|| 100.0 * accepted as f64 / codewords as f64),
        correct_pct: share(k_r, true),
        ber_controller: error_rate(|s| s.bhat),
        ber_eve: k_a.and_then(|_| error_rate(|s| s.bhat_eve)),
        jx,
        eve_disagreement_pct: k_a.and_then(|k_a| share(k_a, false)),
        key_match: (accepted_bits > 0)
            .then(|| k_r.len() == k_c.len() && bool::from(k_r.ct_eq(k_c))),
        n_bce,
        n_acc,
    }
}

#[cfg(test)]
mod tests {
    use sha2::{Digest, Sha256};

    use super::*;
    use crate::config::{EveStrategy, Feedback};
    use crate::observer::Variant;

    /// The configurations whose runs are pinned: the default, m = 1, the paper's variant,
    /// feedback from the estimate, and the soft and identifying eavesdroppers.
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
        ]
    }

    /// SHA-256 (first 8 bytes, hex) of every decision, key and metric of replicates 0–2
    /// (real numbers to 9 significant digits) and of the controller's `d̂` and `x̂` (to 6).
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
            let m = &out.metrics;
            let real = |x: Option<f64>| x.map_or_else(|| "-".into(), |x| format!("{x:.9e}"));
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

    const PINNED: &str = "
default b430a4a2ebbec88f
m=1 8dfc3212a670aefb
paper eaa14f0a00b2a279
estimate 0142c4a09e0b7394
soft b430a4a2ebbec88f
identify f28af9b932546d1a
dv=0.01 eb2af466b7c3bc55
alpha=0.3 5af0a2a0aba0e6f1
";
}
