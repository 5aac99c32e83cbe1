//! One simulated session of private sensing: the plant with true noise, the controller
//! reading its own pose sensor and commanding doublets from their boundary samples, the
//! robot applying `u ± s·Δ`, and the eavesdroppers' views (docs/private-sensing.md).

use nalgebra::Matrix3;
use rand::RngExt;
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use subtle::ConstantTimeEq;

use super::doublet::{DoubletInputs, Perturbation};
use super::likelihood::{DoubletModel, DoubletView, PoseObservation};
use super::{BitKind, DoubletBit, PrivateRun};
use crate::config::{Config, EveStrategy};
use crate::control::{TrackingController, TrackingGains};
use crate::metrics::Metrics;
use crate::model::{DiffDrive, Pose, Unicycle, clip_wheels, unicycle_step};
use crate::protocol::Outcome;
use crate::rng::{Purpose, stream};
use crate::sim::{RunKeys, RunOutput, StepBits, TraceRows};

/// How a private session ends for both sides: its raw bits are confirmed per
/// post-processing block, never per session.
pub const SESSION_OUTCOME: &str =
    "private sensing: raw bits await post-processing (confirmed per block, not per session)";

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

/// The views of one doublet: the controller's, the camera Eve's and the commands Eve's;
/// and the camera Eve's as the controller can model it (her stated noise around its own
/// samples), which sizes the key.
struct Views {
    controller: DoubletView,
    camera: DoubletView,
    commands: DoubletView,
    assumed_camera: DoubletView,
}

fn views(config: &Config, controller: [Pose; 3], camera: [Pose; 3]) -> Views {
    let c = |k: usize| PoseObservation::new(controller[k], config.sensing.controller_std);
    let e = |k: usize| PoseObservation::new(camera[k], config.eve.camera_std);
    Views {
        controller: DoubletView {
            start: c(0),
            middle: Some(c(1)),
            end: Some(c(2)),
        },
        camera: DoubletView {
            start: c(0).fuse(&e(0)),
            middle: Some(e(1)),
            end: Some(c(2).fuse(&e(2))),
        },
        commands: DoubletView {
            start: c(0),
            middle: None,
            end: Some(c(2)),
        },
        assumed_camera: DoubletView {
            start: c(0).fuse(&PoseObservation::new(controller[0], config.eve.camera_std)),
            middle: Some(PoseObservation::new(controller[1], config.eve.camera_std)),
            end: Some(c(2).fuse(&PoseObservation::new(controller[2], config.eve.camera_std))),
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
/// function of `(config, replicate)`.
#[must_use]
pub(crate) fn simulate(config: &Config, replicate: u32, trace: &mut TraceRows<'_>) -> RunOutput {
    let seed = config.run.seed;
    let stream_of = |purpose| stream(seed, purpose, u64::from(replicate));
    let (mut process_rng, mut sensor_rng, mut camera_rng, mut key_rng) = (
        stream_of(Purpose::Process),
        stream_of(Purpose::Measurement),
        stream_of(Purpose::Camera),
        stream_of(Purpose::Key),
    );
    let t = config.robot.sample_time;
    let drive = DiffDrive {
        wheel_radius: config.robot.r,
        axle_length: config.robot.axle_length,
    };
    let ctl = &config.controller;
    let mut controller = TrackingController::new(
        TrackingGains {
            kp: ctl.kp,
            kd: ctl.kd,
            xi_eps: ctl.xi_eps,
            wheel_limit: ctl.wheel_limit,
        },
        drive,
        t,
    );
    let model = doublet_model(config);
    let trajectory = config.trajectory();
    let steps = trajectory.steps(t);
    let reference = |k: usize| trajectory.at(k as f64 * t);

    let mut pose = Pose::zeros();
    let mut sensor = Vec::with_capacity(steps + 1);
    let mut camera = Vec::with_capacity(steps + 1);
    let mut bits = Vec::new();
    let mut log = vec![StepBits::default(); steps];
    let (mut doublets, mut gated) = (0u32, 0u32);
    let mut tracking_error = 0.0;
    // The doublet in flight: its first step, inputs and bits (None: gated or protocol off).
    let mut pending: Option<(usize, DoubletInputs, Option<[u8; 2]>)> = None;

    for k in 0..=steps {
        if k > 0 {
            tracking_error += (pose.xy() - reference(k).position).norm();
        }
        sensor.push(pose + gaussian(&mut sensor_rng, &config.sensing.controller_std));
        camera.push(pose + gaussian(&mut camera_rng, &config.eve.camera_std));
        if let Some(row) = trace.row(k) {
            row.k = k as u32;
            row.t = k as f64 * t;
            row.reference = reference(k).position.into();
            row.pose = pose.into();
            row.measurement = sensor[k].into();
            row.camera = Some(camera[k].into());
        }
        // A doublet ends at its boundary sample: every party decides.
        if let Some((start, inputs, Some(carried))) = pending.filter(|p| p.0 + 2 == k) {
            let v = views(
                config,
                [sensor[start], sensor[start + 1], sensor[k]],
                [camera[start], camera[start + 1], camera[k]],
            );
            let controller_evidence = model.evidence(&inputs, &v.controller);
            let camera_evidence = model.evidence(&inputs, &v.camera);
            let commands_evidence = model.evidence(&inputs, &v.commands);
            let assumed = model.separations(&inputs, &v.assumed_camera);
            for (i, kind) in BitKind::ALL
                .iter()
                .enumerate()
                .take(usize::from(config.protocol.bits_per_doublet))
            {
                bits.push(DoubletBit {
                    step: start as u32,
                    kind: *kind,
                    bit: carried[i],
                    turn_rate: inputs.turn_rate(),
                    controller: controller_evidence.llr[i],
                    camera: camera_evidence.llr[i],
                    commands: commands_evidence.llr[i],
                    camera_separation: camera_evidence.separation[i],
                    assumed_separation: assumed[i],
                    commands_separation: commands_evidence.separation[i],
                });
            }
            let decide = |llr: f64| u8::from(llr < 0.0);
            let eve_llr = match config.eve_strategy() {
                EveStrategy::Commands => commands_evidence.llr[0],
                _ => camera_evidence.llr[0],
            };
            let logged = StepBits {
                bit: Some(carried[0]),
                bhat: Some(decide(controller_evidence.llr[0])),
                bhat_eve: config.eve.enabled.then(|| decide(eve_llr)),
            };
            log[start] = logged;
            if let Some(row) = trace.row(start + 1) {
                row.bhat = logged.bhat;
                row.bhat_eve = logged.bhat_eve;
            }
        }
        // Row k − 1 is complete: a doublet's decision lands on its second step's row.
        trace.complete_before(k);
        if k == steps {
            break;
        }
        // A doublet starts at an even step with two steps left; an odd last step is lone.
        let applied = match pending {
            Some((start, inputs, carried)) if start + 1 == k => {
                let offset = carried.map_or_else(Unicycle::zeros, |b| {
                    model.perturbation.offset(model.perturbation.pattern(b))
                });
                inputs.applied(offset)[1]
            }
            _ => {
                let first = controller.command(&sensor[k], &reference(k));
                if let Some(row) = trace.row(k) {
                    row.nominal = Some(first.into());
                }
                if k + 2 <= steps {
                    let predicted = unicycle_step(&sensor[k], &first, t);
                    let second = controller.command(&predicted, &reference(k + 1));
                    let inputs = DoubletInputs { first, second };
                    let drawn = [key_rng.random_range(0..2u8), key_rng.random_range(0..2u8)];
                    doublets += 1;
                    let carries = config.protocol.enabled
                        && inputs.turn_rate() <= config.protocol.max_turn_rate;
                    gated += u32::from(config.protocol.enabled && !carries);
                    let carried = carries.then_some(drawn);
                    pending = Some((k, inputs, carried));
                    if let Some(row) = trace.row(k + 1) {
                        row.nominal = Some(second.into());
                    }
                    if let Some(b) = carried {
                        for step in [k, k + 1] {
                            if let Some(row) = trace.row(step) {
                                row.bit = Some(b[0]);
                                row.bit_omega =
                                    (config.protocol.bits_per_doublet == 2).then_some(b[1]);
                            }
                        }
                    }
                    let offset = carried.map_or_else(Unicycle::zeros, |b| {
                        model.perturbation.offset(model.perturbation.pattern(b))
                    });
                    inputs.applied(offset)[0]
                } else {
                    pending = None;
                    first
                }
            }
        };
        let wheels = clip_wheels(drive.to_wheels(applied), config.robot.wheel_limit);
        pose = unicycle_step(&pose, &drive.to_unicycle(wheels), t)
            + gaussian(&mut process_rng, &config.noise.process_std);
    }

    let keys = keys(config, &bits);
    let jx = tracking_error / steps.max(1) as f64;
    RunOutput {
        metrics: metrics(config, &bits, &keys, jx),
        trace: Vec::new(),
        robot_outcome: Some(Outcome::Unconfirmed(SESSION_OUTCOME.into())),
        controller_outcome: Some(Outcome::Unconfirmed(SESSION_OUTCOME.into())),
        steps: log,
        keys,
        private: Some(PrivateRun {
            doublets,
            gated,
            bits,
        }),
    }
}

/// The raw keys: the robot's bits, the controller's decisions, Eve's decisions.
fn keys(config: &Config, bits: &[DoubletBit]) -> RunKeys {
    let decide = |llr: f64| u8::from(llr < 0.0);
    let eve = config.eve.enabled.then(|| {
        let strategy = config.eve_strategy();
        bits.iter()
            .map(|b| decide(b.llr_of(strategy)))
            .collect::<Vec<u8>>()
            .into()
    });
    RunKeys {
        robot: bits.iter().map(|b| b.bit).collect::<Vec<u8>>().into(),
        controller: bits
            .iter()
            .map(|b| decide(b.controller))
            .collect::<Vec<u8>>()
            .into(),
        eve,
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
