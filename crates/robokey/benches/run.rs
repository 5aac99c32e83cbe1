//! Speed of one default run (1020 steps, controller and Eve observers, plant noise) beside
//! its arithmetic alone (the floor of docs/speed.md), of each eavesdropper strategy listening
//! to one recorded session, the per-frame cost of the session layer's authentication, and one
//! private-sensing session in a slipping world judged by the window smoother.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand::SeedableRng;
use robokey::Config;
use robokey::config::{EveStrategy, SensingMode};
use robokey::eve::{Eavesdropper, Eve, ModelErrors};
use robokey::model::DiffDrive;
use robokey::observer::Observer;
use robokey::private::Eavesdroppers;
use robokey::protocol::StepDecoder;
use robokey::protocol::auth::{ControllerChannel, Delivery, PairingSecret, RobotChannel};
use robokey::protocol::controller::{command_pair, observer_params};
use robokey::protocol::wire::{Frame, MAC_BYTES, decode, encode};
use robokey::protocol::{FateWindow, Message, SessionMessage, SessionPlan};
use robokey::rng::stream;
use robokey::sim::{simulate_plan, simulate_transcript};
use robokey::world::Scene;

fn one_run(c: &mut Criterion) {
    let config = Config::default();
    let plan = SessionPlan::from_config(&config, 0);
    let mut group = c.benchmark_group("simulate");
    group.throughput(Throughput::Elements(u64::from(plan.agreed.steps)));
    group.bench_function("default run (steps)", |b| {
        b.iter(|| simulate_plan(&config, plan.clone(), 0, false, Eavesdroppers::Both).unwrap());
    });
    group.bench_function("its arithmetic alone (steps)", |b| {
        b.iter(|| arithmetic_only(&config, &plan));
    });
    group.finish();
}

/// The arithmetic of a default run's steps without the protocol around it (the floor of
/// docs/speed.md): per step the plant with its noise and odometry, the reference the
/// simulator scores against, the tracking controller and its command pair, and two
/// observers with their decoders (the controller's, and an eavesdropper's weighing both
/// hypotheses), in a closed loop; no message, queue, timer or log. Returns the summed
/// tracking error (m), so that nothing is optimised away.
fn arithmetic_only(config: &Config, plan: &SessionPlan) -> f64 {
    let agreed = &plan.agreed;
    let odometry = plan.odometry().expect("the default run senses odometry");
    let mut scene = Scene::new(config, SensingMode::Odometry, |purpose| {
        stream(config.run.seed, purpose, 0)
    });
    let trajectory = config.trajectory();
    let mut tracker =
        robokey::control::ReferenceTracker::new(config, agreed.drive, agreed.sample_time);
    let decoder = |drive: DiffDrive| {
        let observer = Observer::new(&observer_params(config)).expect("a valid observer");
        StepDecoder::new(drive, observer, odometry.delta, true)
    };
    let mut controller = decoder(agreed.drive);
    let mut eve = decoder(agreed.drive).weighing();
    let mut key = 0x9e37_79b9_7f4a_7c15_u64;
    let mut tracking_error = 0.0;
    for step in 0..=agreed.steps {
        if step > 0 {
            scene.step();
        }
        let observed = scene.observe();
        let reference = trajectory.at(f64::from(step) * agreed.sample_time).position;
        tracking_error += (observed.pose.xy() - reference).norm();
        let applied = step.checked_sub(1);
        let decided = controller.on_measurement(step, &observed.measured, applied);
        let heard = eve.on_measurement(step, &observed.measured, applied);
        std::hint::black_box((
            decided.expect("the default run is regular"),
            heard.expect("the default run is regular"),
        ));
        if step == agreed.steps {
            break;
        }
        let nominal = tracker.command(&observed.measured, step);
        let (u0, u1) = command_pair(agreed, odometry, nominal);
        controller.on_command(step, nominal, u0, u1);
        eve.on_command(step, agreed.drive.to_unicycle((u0 + u1) / 2.0), u0, u1);
        key = key.rotate_left(1);
        scene.apply(if key & 1 == 1 { u1 } else { u0 });
    }
    tracking_error
}

fn eavesdroppers(c: &mut Criterion) {
    let config = Config::default();
    let plan = SessionPlan::from_config(&config, 0);
    let (_, transcript) = simulate_transcript(&config, 0).unwrap();
    // 20 % off on r and D: the transcript Eve has codewords to flip.
    let errors = ModelErrors {
        r: 0.2,
        d: -0.2,
        ..ModelErrors::default()
    };
    let mut group = c.benchmark_group("eve session");
    group.throughput(Throughput::Elements(u64::from(plan.agreed.steps)));
    for strategy in EveStrategy::of_mode(SensingMode::Odometry) {
        group.bench_function(strategy.name(), |b| {
            b.iter(|| {
                let mut eve = Eve::new(&config, strategy, errors);
                eve.begin_session(&plan);
                for message in &transcript {
                    eve.observe(message);
                }
                eve.key()
            });
        });
    }
    group.finish();
}

/// One `Command` through the frame codec alone, and sealed by the controller's channel and
/// opened (MAC, replay window) by the robot's: the difference is what authentication costs.
fn frame(c: &mut Criterion) {
    let command = Message::Session(SessionMessage::Command {
        step: 7,
        u0: [4.0, 3.5],
        u1: [0.5, -1.0],
        fates: FateWindow::default(),
    });
    let secret = PairingSecret::from_bytes(&[7; 32]);
    let mut rng = rand::rngs::ChaCha20Rng::seed_from_u64(1);
    let mut controller =
        ControllerChannel::new(secret.clone(), 1u8, 5, [0; 32], String::new(), &mut rng);
    let mut robot = RobotChannel::new(secret, [0; 32], String::new());
    let Ok(Delivery::Answer { bytes, .. }) = robot.on_datagram(2u8, controller.hello(), &mut rng)
    else {
        panic!("the Hello is answered");
    };
    controller.on_datagram(1, &bytes).unwrap();
    let mut group = c.benchmark_group("frame");
    group.bench_function("Command: encode + decode, no MAC", |b| {
        let frame = Frame {
            session: 5,
            seq: 1,
            message: command.clone(),
        };
        b.iter(|| decode(&[encode(&frame), vec![0; MAC_BYTES]].concat()).unwrap());
    });
    group.bench_function("Command: seal + open (MAC, replay window)", |b| {
        b.iter(|| {
            let bytes = controller.seal(command.clone()).unwrap();
            robot.on_datagram(2, &bytes, &mut rng).unwrap()
        });
    });
    group.finish();
}

/// One private-sensing session in a world with wheel slip, heard by the camera eavesdropper
/// who knows it: her window smoother runs a Gram filter pass per slip covariance (per
/// hypothesis of the doublet judged), shared up to the first step whose slip differs.
fn slipping_world(c: &mut Criterion) {
    let config = Config::from_toml(
        "[sensing]\nmode = \"private\"\n\
         [world]\nprocess_std = [0.002, 0.002, 0.002]\nslip_std = 0.2\n",
        "bench",
    )
    .expect("a valid configuration");
    let plan = SessionPlan::from_config(&config, 0);
    let mut group = c.benchmark_group("private session");
    group.sample_size(10);
    group.bench_function("slipping world, camera eavesdropper", |b| {
        b.iter(|| simulate_plan(&config, plan.clone(), 0, false, Eavesdroppers::Camera).unwrap());
    });
    group.finish();
}

criterion_group!(benches, one_run, eavesdroppers, frame, slipping_world);
criterion_main!(benches);
