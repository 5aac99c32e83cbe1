//! Seeded statistical agreement with the reference values of docs/experiments.md (mean ± standard error
//! over 100 runs of an independent implementation).

use robokey::Config;
use robokey::sim::simulate;

/// Mean and standard error of a sample.
fn mean_se(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// Asserts |ours − reference| < 4 combined standard errors (two-sided p ≈ 6e-5 under
/// agreement), the tolerance derived from both sample sizes.
fn agrees(name: &str, values: &[f64], reference: f64, reference_se: f64) {
    let (mean, se) = mean_se(values);
    let combined = (se * se + reference_se * reference_se).sqrt();
    assert!(
        (mean - reference).abs() < 4.0 * combined,
        "{name}: {mean:.3} ± {se:.3} vs reference {reference} ± {reference_se}"
    );
}

#[test]
fn defaults_agree_with_the_reference_implementation() {
    const RUNS: u32 = 40;
    let config = Config::default();
    let metrics: Vec<_> = (0..RUNS)
        .map(|r| simulate(&config, r, false).unwrap().metrics)
        .collect();
    let accepted: Vec<f64> = metrics.iter().map(|m| m.accepted_pct.unwrap()).collect();
    let ber: Vec<f64> = metrics
        .iter()
        .map(|m| 100.0 * m.ber_controller.unwrap())
        .collect();
    let jx: Vec<f64> = metrics.iter().map(|m| 1000.0 * m.jx).collect();
    agrees("accepted %", &accepted, 87.6, 0.18);
    agrees("controller BER %", &ber, 4.31, 0.06);
    agrees("J_x mm", &jx, 24.8, 0.12);
}
