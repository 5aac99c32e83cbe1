//! Speed of one default run: 1020 steps, controller and Eve observers, plant noise.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use robokey::Config;
use robokey::protocol::SessionPlan;
use robokey::sim::simulate_plan;

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

criterion_group!(benches, one_run);
criterion_main!(benches);
