//! Speed of one default run (1020 steps, controller and Eve observers, plant noise), of
//! each eavesdropper strategy listening to one recorded session, and the per-frame cost of
//! the session layer's authentication.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand::SeedableRng;
use robokey::Config;
use robokey::config::{EveStrategy, SensingMode};
use robokey::eve::{Eavesdropper, Eve, ModelErrors};
use robokey::protocol::auth::{ControllerChannel, Delivery, PairingSecret, RobotChannel};
use robokey::protocol::wire::{Frame, MAC_BYTES, decode, encode};
use robokey::protocol::{FateWindow, Message, SessionMessage, SessionPlan};
use robokey::sim::{simulate_plan, simulate_transcript};

fn one_run(c: &mut Criterion) {
    let config = Config::default();
    let plan = SessionPlan::from_config(&config, 0);
    let mut group = c.benchmark_group("simulate");
    group.throughput(Throughput::Elements(u64::from(plan.agreed.steps)));
    group.bench_function("default run (steps)", |b| {
        b.iter(|| simulate_plan(&config, plan.clone(), 0, false).unwrap());
    });
    group.finish();
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

criterion_group!(benches, one_run, eavesdroppers, frame);
criterion_main!(benches);
