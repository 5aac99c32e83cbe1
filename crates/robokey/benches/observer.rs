//! Speed of one observer step (docs/speed.md): the default observer (corrected, m = 2) and the
//! m = 1 one, over the nominal inputs and measurements of a recorded default run.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use robokey::Config;
use robokey::model::{Pose, Unicycle};
use robokey::observer::{Observer, ObserverParams, Variant};
use robokey::sim::simulate;

/// The controller's `(uU(k−1), y(k))` of every step k ≥ 1 of the default run.
fn recorded_steps(config: &Config) -> Vec<(Unicycle, Pose)> {
    let trace = simulate(config, 0, true)
        .expect("the default run completes")
        .trace;
    trace
        .windows(2)
        .filter_map(|rows| {
            let nominal = rows[0].nominal?;
            Some((Unicycle::from(nominal), Pose::from(rows[1].measurement)))
        })
        .collect()
}

fn observer_step(c: &mut Criterion) {
    let config = Config::default();
    let steps = recorded_steps(&config);
    let mut group = c.benchmark_group("observer");
    group.throughput(Throughput::Elements(steps.len() as u64));
    for (name, variant, channels) in [
        ("corrected m=2 (steps)", Variant::Corrected, 2),
        ("corrected m=1 (steps)", Variant::Corrected, 1),
        ("paper m=2 (steps)", Variant::Paper, 2),
    ] {
        let params = ObserverParams {
            sample_time: config.robot.sample_time,
            w_var: config.observer.w_var,
            v_var: config.observer.v_var,
            variant,
            channels,
        };
        group.bench_function(name, |b| {
            b.iter(|| {
                let mut observer = Observer::new(&params).expect("m is 1 or 2");
                for (input, y) in &steps {
                    std::hint::black_box(observer.step(input, y).expect("the run is regular"));
                }
                observer.state()
            });
        });
    }
    group.finish();
}

criterion_group!(benches, observer_step);
criterion_main!(benches);
