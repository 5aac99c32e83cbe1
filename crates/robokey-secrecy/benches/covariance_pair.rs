//! Speed of a bit's moment `E[e^(−λS)]` seen through a pair of Gaussians with their own
//! covariances (per-wheel slip's sizing, `covariance_pair`): pairs of 9 coordinates (a two-step
//! doublet's three instants) and of 21 (a three-step doublet's four and the next doublet's
//! entry), each at the Bhattacharyya λ = ½ and at five Chernoff parameters from 10⁻³ to 2.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use robokey_secrecy::covariance_pair::{Coordinate, CovariancePair};

/// A pair of `dimension` coordinates with shifts from 0 to 1.2 and variances from 0.6 to 2.4
/// (the spread a slip view's whitened coordinates take).
fn pair(dimension: u32) -> CovariancePair {
    CovariancePair::new((0..dimension).map(|k| {
        let x = f64::from(k) / f64::from(dimension);
        Coordinate {
            shift: 1.2 * (1.0 - x) * if k % 2 == 0 { 1.0 } else { -0.5 },
            variance: 0.6 + 1.8 * (x * 7.0).fract(),
        }
    }))
    .expect("finite shifts, positive variances")
}

fn moment_of_a_pair(c: &mut Criterion) {
    let mut group = c.benchmark_group("ln E[e^(−λS)] of a covariance pair");
    group.sample_size(20);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(3));
    let lambdas = [0.5, 1e-3, 0.02, 0.1, 0.5, 2.0];
    for dimension in [9, 21] {
        let pair = pair(dimension);
        group.bench_function(format!("{dimension} coordinates, 6 λ"), |b| {
            b.iter(|| {
                lambdas
                    .iter()
                    .map(|&l| black_box(&pair).ln_moment(black_box(l)))
                    .sum::<f64>()
            });
        });
    }
    group.finish();
}

criterion_group!(benches, moment_of_a_pair);
criterion_main!(benches);
