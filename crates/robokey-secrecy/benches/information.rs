//! Speed of a bit's predicted information `I(d)` (private sensing's leak prediction): the
//! 2,401-point integral against its interpolation, over separations spread across the
//! private-sensing map's range.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use robokey_secrecy::gaussian_llr::{information, information_interpolated};

/// One way to compute `I(d)`.
type Way = fn(f64) -> f64;

fn information_of_a_bit(c: &mut Criterion) {
    let mut group = c.benchmark_group("I(d) of 64 separations from 0.8 to 5");
    group.sample_size(20);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(3));
    let separations: Vec<f64> = (0..64).map(|i| 0.8 + 4.2 * f64::from(i) / 64.0).collect();
    black_box(information_interpolated(1.0)); // the table, built once per process
    let ways: [(&str, Way); 2] = [
        ("integral", information),
        ("interpolated", information_interpolated),
    ];
    for (name, way) in ways {
        group.bench_function(name, |b| {
            b.iter(|| separations.iter().map(|&d| way(black_box(d))).sum::<f64>());
        });
    }
    group.finish();
}

criterion_group!(benches, information_of_a_bit);
criterion_main!(benches);
