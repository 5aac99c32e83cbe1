//! Speed of one default run (1020 steps, controller and Eve observers, plant noise), and of
//! each eavesdropper strategy listening to one recorded session.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use robokey::Config;
use robokey::config::{EveStrategy, SensingMode};
use robokey::eve::{Eavesdropper, Eve, ModelErrors};
use robokey::protocol::SessionPlan;
use robokey::sim::{simulate_plan, simulate_transcript};

fn one_run(c: &mut Criterion) {
    let config = Config::default();
    let plan = SessionPlan::from_config(&config, 0);
    let mut group = c.benchmark_group("simulate");
    group.throughput(Throughput::Elements(u64::from(plan.steps)));
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
    group.throughput(Throughput::Elements(u64::from(plan.steps)));
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

criterion_group!(benches, one_run, eavesdroppers);
criterion_main!(benches);
