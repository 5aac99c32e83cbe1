//! Speed of Toeplitz hashing (privacy amplification) of 10⁵ and 10⁶-bit keys to half their
//! length.

use std::hint::black_box;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use robokey_secrecy::{BitString, ToeplitzHash};

fn toeplitz(c: &mut Criterion) {
    let mut group = c.benchmark_group("toeplitz hash");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(5));
    for n in [100_000, 1_000_000] {
        let mut rng = ChaCha8Rng::seed_from_u64(n as u64);
        let hash = ToeplitzHash::random(n, n / 2, &mut rng).unwrap();
        let key = BitString::random(n, &mut rng);
        group.throughput(Throughput::Elements(n as u64));
        group.bench_with_input(
            BenchmarkId::new("l = n over 2, n bits", n),
            &key,
            |b, key| {
                b.iter(|| hash.hash(black_box(key)).unwrap());
            },
        );
    }
    group.finish();
}

criterion_group!(benches, toeplitz);
criterion_main!(benches);
