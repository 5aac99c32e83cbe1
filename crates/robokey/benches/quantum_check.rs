//! Speed of the command-quantum check (docs/speed.md, "The command-quantum check's cost") on
//! one block of private-sensing doublets at the defaults: one bit a doublet (the binary
//! doublet on v) and two (a second on ω), the parties stating no quantum, the world rounding
//! none, each doublet's end heading the model's plus 6 mrad of noise.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand::RngExt;
use rand_distr::{Distribution, Normal};
use robokey::Config;
use robokey::config::SensingMode;
use robokey::estimate::quantum_check::quantum_check;
use robokey::model::{Pose, Unicycle};
use robokey::private::{DoubletInputs, DoubletSamples, doublet_model};
use robokey::rng::{Purpose, stream};

/// Doublets in the block.
const DOUBLETS: usize = 5_000;

/// `DOUBLETS` seeded doublets of nominal speeds 0.08–0.12 m/s and turns within ±0.5 rad/s.
fn block(config: &Config) -> Vec<DoubletSamples> {
    let mut rng = stream(1, Purpose::Process, 0);
    let noise = Normal::new(0.0, 6e-3).expect("a positive deviation");
    let model = doublet_model(config);
    (0..DOUBLETS)
        .map(|j| {
            let mut input =
                || Unicycle::new(rng.random_range(0.08..0.12), rng.random_range(-0.5..0.5));
            let inputs = DoubletInputs {
                first: input(),
                second: input(),
            };
            let pattern = rng.random_range(0..1 << config.protocol.bits_per_doublet);
            let start = Pose::new(0.0, 0.0, 0.3);
            let end = model.end_of(&inputs, &start, Some(pattern));
            let sensed = end + Pose::new(0.0, 0.0, noise.sample(&mut rng));
            DoubletSamples {
                doublet: j as u32,
                inputs,
                samples: [start, sensed, sensed],
                pattern,
                late: None,
            }
        })
        .collect()
}

fn check(c: &mut Criterion) {
    let mut group = c.benchmark_group("quantum check");
    group.throughput(Throughput::Elements(DOUBLETS as u64));
    group.sample_size(10);
    for bits in [1, 2] {
        let mut config = Config::default();
        config.sensing.mode = SensingMode::Private;
        config.protocol.bits_per_doublet = bits;
        let doublets = block(&config);
        let lag = doublet_model(&config).lag;
        let name = format!("{bits} bit(s) a doublet (doublets)");
        group.bench_function(name, |b| {
            b.iter(|| quantum_check(&config, &[&doublets], lag, 1e-6).expect("tested"));
        });
    }
    group.finish();
}

criterion_group!(benches, check);
criterion_main!(benches);
