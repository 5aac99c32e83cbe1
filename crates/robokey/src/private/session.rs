//! One simulated session of private sensing: the plant with true noise, the controller's
//! sensor and Eve's camera, around the same robot, controller and eavesdropper endpoints
//! the network agents run (docs/private-sensing.md).

use std::collections::{BTreeMap, VecDeque};

use nalgebra::Matrix3;
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use subtle::ConstantTimeEq;

use super::controller::{DoubletDecision, PrivateControllerEndpoint};
use super::doublet::Perturbation;
use super::eve::{DoubletEavesdropper, EveDoublet};
use super::likelihood::DoubletModel;
use super::plan::PrivatePlan;
use super::robot::PrivateRobotEndpoint;
use super::{BitKind, DoubletBit, PrivateRun};
use crate::config::{Config, EveStrategy};
use crate::metrics::Metrics;
use crate::model::{Pose, Unicycle, WheelSpeeds, clip_wheels, unicycle_step};
use crate::protocol::{
    ControllerEvent, ControllerInput, ControllerOutput, RobotInput, RobotOutput,
};
use crate::rng::{Purpose, stream};
use crate::sim::{RunKeys, RunOutput, StepBits, TraceRows};

/// The true-noise doublet model of `config`.
#[must_use]
pub fn doublet_model(config: &Config) -> DoubletModel {
    let q = config.noise.process_std.map(|s| s * s);
    DoubletModel {
        sample_time: config.robot.sample_time,
        process_covariance: Matrix3::from_diagonal(&q.into()),
        perturbation: Perturbation {
            delta: Unicycle::new(config.protocol.delta_v, config.perturbed_delta_omega()),
            bits_per_doublet: config.protocol.bits_per_doublet,
        },
    }
}

fn gaussian(rng: &mut ChaCha8Rng, std: &[f64; 3]) -> Pose {
    Pose::from_fn(|i, _| {
        let z: f64 = StandardNormal.sample(rng);
        std[i] * z
    })
}

/// Simulates replicate `replicate` of a validated private-sensing configuration: a pure
/// function of `(config, replicate)`. The plant and the sensors live here; the robot, the
/// controller and the eavesdroppers are the endpoints the network agents run.
#[must_use]
pub(crate) fn simulate(config: &Config, replicate: u32, trace: &mut TraceRows<'_>) -> RunOutput {
    let seed = config.run.seed;
    let stream_of = |purpose| stream(seed, purpose, u64::from(replicate));
    let (mut process_rng, mut sensor_rng, mut camera_rng) = (
        stream_of(Purpose::Process),
        stream_of(Purpose::Measurement),
        stream_of(Purpose::Camera),
    );
    let plan = PrivatePlan::from_config(config, replicate);
    let (steps, t, drive) = (plan.steps, plan.sample_time, plan.drive);
    let two_bits = plan.perturbation.bits_per_doublet == 2;
    let mut robot = PrivateRobotEndpoint::new(plan.clone(), &mut stream_of(Purpose::Key));
    let mut controller = PrivateControllerEndpoint::new(config, plan);
    let mut eve = DoubletEavesdropper::new(config);
    let trajectory = config.trajectory();
    let reference = |k: u32| trajectory.at(f64::from(k) * t);

    let mut pose = Pose::zeros();
    let mut log = vec![StepBits::default(); steps as usize];
    let mut run = PrivateRun::default();
    let mut tracking_error = 0.0;
    let mut outcomes = (None, None);
    // Decisions of the controller and of the eavesdroppers, paired by doublet.
    let mut decided: VecDeque<DoubletDecision> = VecDeque::new();
    let mut heard: BTreeMap<u32, EveDoublet> = BTreeMap::new();

    for k in 0..=steps {
        if k > 0 {
            tracking_error += (pose.xy() - reference(k).position).norm();
        }
        let sensed = pose + gaussian(&mut sensor_rng, &config.sensing.controller_std);
        let filmed = pose + gaussian(&mut camera_rng, &config.eve.camera_std);
        if let Some(row) = trace.row(k as usize) {
            row.k = k;
            row.t = f64::from(k) * t;
            row.reference = reference(k).position.into();
            row.pose = pose.into();
            row.measurement = sensed.into();
            row.camera = Some(filmed.into());
        }
        eve.film(k, filmed);
        // The simulated robot has no odometry of its own: it would send none anyway.
        robot.handle_input(RobotInput::Sample { step: k, y: pose });
        controller.handle_input(ControllerInput::Sensor {
            step: k,
            pose: sensed,
        });
        let mut wheels = None;
        // Deliver until both sides are quiet; the robot's Apply ends the step.
        loop {
            let mut quiet = true;
            while let Some(output) = robot.poll_output() {
                quiet = false;
                match output {
                    RobotOutput::Transmit(message) => {
                        eve.observe(&message);
                        controller.handle_input(ControllerInput::Frame(message));
                    }
                    RobotOutput::Apply(actuation) => {
                        if let Some(row) = trace.row(actuation.step as usize) {
                            row.bit = actuation.bit;
                            row.bit_omega = actuation
                                .bit
                                .and(robot.carried_bits(actuation.step / 2))
                                .filter(|_| two_bits)
                                .map(|b| b[1]);
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
                        eve.observe(&message);
                        robot.handle_input(RobotInput::Frame(message));
                    }
                    ControllerOutput::Event(event) => match event {
                        ControllerEvent::DoubletCommanded {
                            step,
                            inputs,
                            carries,
                        } => {
                            run.doublets += 1;
                            run.gated += u32::from(config.protocol.enabled && !carries);
                            for (k, nominal) in [(step, inputs.first), (step + 1, inputs.second)] {
                                if let Some(row) = trace.row(k as usize) {
                                    row.nominal = Some(nominal.into());
                                }
                            }
                        }
                        ControllerEvent::Commanded { step, nominal } => {
                            if let Some(row) = trace.row(step as usize) {
                                row.nominal = Some(nominal.into());
                            }
                        }
                        ControllerEvent::DoubletDecided(decision) => decided.push_back(decision),
                        ControllerEvent::Finished(outcome) => outcomes.1 = Some(outcome),
                        _ => {}
                    },
                }
            }
            while let Some(doublet) = eve.poll() {
                heard.insert(doublet.doublet, doublet);
            }
            if quiet {
                break;
            }
        }
        // Every party has decided the doublet that ended at k: record its bits.
        while let Some(e) = decided.front().and_then(|d| heard.remove(&d.doublet)) {
            let d = decided.pop_front().expect("paired with the front decision");
            let bits = robot
                .carried_bits(d.doublet)
                .expect("the robot carried every doublet the simulated controller decides");
            record(config, &d, &e, bits, &mut run, &mut log, trace);
        }
        // Row k − 1 is complete: a doublet's decision lands on its second step's row.
        trace.complete_before(k as usize);
        if k < steps {
            let applied = drive.to_unicycle(clip_wheels(
                wheels.unwrap_or_else(WheelSpeeds::zeros),
                config.robot.wheel_limit,
            ));
            pose = unicycle_step(&pose, &applied, t)
                + gaussian(&mut process_rng, &config.noise.process_std);
        }
    }

    let keys = RunKeys {
        robot: robot.key().to_vec().into(),
        controller: controller.key().to_vec().into(),
        eve: config
            .eve
            .enabled
            .then(|| eve.key(config.eve_strategy() != EveStrategy::Commands)),
    };
    let jx = tracking_error / f64::from(steps.max(1));
    RunOutput {
        metrics: metrics(config, &run.bits, &keys, jx),
        trace: Vec::new(),
        robot_outcome: outcomes.0,
        controller_outcome: outcomes.1,
        steps: log,
        keys,
        private: Some(run),
    }
}

/// Records a decided doublet's bits — the robot's, and every party's evidence — in the run,
/// the step log and the trace.
fn record(
    config: &Config,
    d: &DoubletDecision,
    e: &EveDoublet,
    bits: [u8; 2],
    run: &mut PrivateRun,
    log: &mut [StepBits],
    trace: &mut TraceRows<'_>,
) {
    for (i, kind) in BitKind::ALL
        .iter()
        .enumerate()
        .take(usize::from(config.protocol.bits_per_doublet))
    {
        run.bits.push(DoubletBit {
            step: d.step,
            kind: *kind,
            bit: bits[i],
            turn_rate: d.inputs.turn_rate(),
            controller: d.evidence.llr[i],
            camera: e.camera.llr[i],
            commands: e.commands.llr[i],
            camera_separation: e.camera.separation[i],
            assumed_separation: d.assumed_separation[i],
            commands_separation: e.commands.separation[i],
        });
    }
    let decide = |llr: f64| u8::from(llr < 0.0);
    let eve_llr = match config.eve_strategy() {
        EveStrategy::Commands => e.commands.llr[0],
        _ => e.camera.llr[0],
    };
    let logged = StepBits {
        bit: Some(bits[0]),
        bhat: Some(decide(d.evidence.llr[0])),
        bhat_eve: config.eve.enabled.then(|| decide(eve_llr)),
    };
    log[d.step as usize] = logged;
    if let Some(row) = trace.row(d.step as usize + 1) {
        row.bhat = logged.bhat;
        row.bhat_eve = logged.bhat_eve;
    }
}

fn metrics(config: &Config, bits: &[DoubletBit], keys: &RunKeys, jx: f64) -> Metrics {
    if !config.protocol.enabled {
        return Metrics {
            jx,
            ..Metrics::default()
        };
    }
    let n = bits.len();
    let share = |other: &[u8], equal: bool| {
        (n > 0).then(|| {
            let count = other
                .iter()
                .zip(keys.controller.iter())
                .filter(|(a, b)| (a == b) == equal)
                .count();
            100.0 * count as f64 / n as f64
        })
    };
    let rate = |key: &[u8]| {
        (n > 0).then(|| {
            key.iter()
                .zip(keys.robot.iter())
                .filter(|(a, b)| a != b)
                .count() as f64
                / n as f64
        })
    };
    let table = keys.eve.as_ref().map(|eve| {
        let mut table = [0u64; 8];
        for ((b, c), a) in keys
            .robot
            .iter()
            .zip(keys.controller.iter())
            .zip(eve.iter())
        {
            table[usize::from(b << 2 | c << 1 | a)] += 1;
        }
        table
    });
    Metrics {
        codewords_sent: None,
        accepted: None,
        accepted_pct: None,
        correct_pct: share(&keys.robot, true),
        ber_controller: rate(&keys.controller),
        ber_eve: keys.eve.as_deref().and_then(|eve| rate(eve)),
        jx,
        eve_disagreement_pct: keys.eve.as_deref().and_then(|eve| share(eve, false)),
        key_match: (n > 0).then(|| bool::from(keys.robot.ct_eq(&keys.controller))),
        n_bce: table,
        n_acc: table,
    }
}
