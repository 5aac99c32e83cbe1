//! Time to reconcile one 10⁶-bit block by LDPC at the default world's soft limit (binary-input
//! Gaussian LLRs with hard-decision error rate 0.78 %, the default settings
//! [`LdpcSettings::DEFAULT`]): code construction, syndrome, belief propagation and any
//! feedback rounds, on one core (the decoder is sequential, so two blocks run on two cores in
//! this time).

use std::hint::black_box;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};
use robokey_secrecy::BitString;
use robokey_secrecy::ldpc::{LdpcSettings, reconcile};

/// σ of the Gaussian noise on ±1 whose hard decisions err with probability 0.78 %
/// (Φ(−1/σ) = 0.0078).
const SIGMA: f64 = 0.4135;

fn ldpc(c: &mut Criterion) {
    let mut group = c.benchmark_group("ldpc reconciliation");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(30));
    for n in [100_000, 1_000_000] {
        let mut rng = ChaCha8Rng::seed_from_u64(n as u64);
        let bits = BitString::random(n, &mut rng);
        let noise = Normal::new(0.0, SIGMA).unwrap();
        let llrs: Vec<f64> = (0..n)
            .map(|i| {
                let s = if bits.get(i).unwrap() { -1.0 } else { 1.0 };
                2.0 * (s + noise.sample(&mut rng)) / (SIGMA * SIGMA)
            })
            .collect();
        let seed: [u8; 32] = rng.random();
        group.throughput(Throughput::Elements(n as u64));
        group.bench_with_input(
            BenchmarkId::new("default world, default settings, n bits", n),
            &(bits, llrs),
            |b, (bits, llrs)| {
                b.iter(|| reconcile(black_box(bits), llrs, LdpcSettings::DEFAULT, seed).unwrap());
            },
        );
    }
    group.finish();
}

criterion_group!(benches, ldpc);
criterion_main!(benches);
