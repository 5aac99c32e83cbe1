//! The metrics of one run (docs/experiments.md) from its keys and step log.

use subtle::ConstantTimeEq;

use super::{RunKeys, StepBits};
use crate::config::Config;
use crate::metrics::Metrics;
use crate::private::DoubletBit;
use crate::protocol::SessionPlan;

/// The odometry mode's metrics: acceptance, error rates, Eve's disagreement, the joint
/// counts of every step and of the accepted bits.
pub(super) fn odometry(
    log: &[StepBits],
    jx: f64,
    keys: &RunKeys,
    plan: &SessionPlan,
    enabled: bool,
) -> Metrics {
    if !enabled {
        return Metrics {
            jx,
            ..Metrics::default()
        };
    }
    let applied: Vec<&StepBits> = log.iter().filter(|s| s.bit.is_some()).collect();
    let error_rate = |pick: fn(&StepBits) -> Option<u8>| {
        let wrong = applied.iter().filter(|s| pick(s) != s.bit).count();
        (!applied.is_empty()).then(|| wrong as f64 / applied.len() as f64)
    };
    let (k_r, k_c) = (keys.robot.as_slice(), keys.controller.as_slice());
    let k_a = keys.eve.as_ref();
    let codewords = u64::from(plan.units());
    let accepted_bits = k_c.len();
    let accepted = (accepted_bits / plan.bits_per_unit()) as u64;
    let share = |other: &[u8], equal: bool| {
        let count = other
            .iter()
            .zip(k_c)
            .filter(|(a, b)| (a == b) == equal)
            .count();
        (accepted_bits > 0).then(|| 100.0 * count as f64 / accepted_bits as f64)
    };
    let n_bce = k_a.map(|_| {
        let mut table = [0u64; 8];
        for s in &applied {
            if let (Some(b), Some(c), Some(a)) = (s.bit, s.bhat, s.bhat_eve) {
                table[usize::from(b << 2 | c << 1 | a)] += 1;
            }
        }
        table
    });
    let n_acc = k_a.map(|k_a| {
        let mut table = [0u64; 8];
        for ((s, c), a) in k_r.iter().zip(k_c).zip(k_a.iter()) {
            table[usize::from(s << 2 | c << 1 | a)] += 1;
        }
        table
    });
    Metrics {
        codewords_sent: Some(codewords),
        accepted: Some(accepted),
        accepted_pct: (codewords > 0).then(|| 100.0 * accepted as f64 / codewords as f64),
        correct_pct: share(k_r, true),
        ber_controller: error_rate(|s| s.bhat),
        ber_eve: k_a.and_then(|_| error_rate(|s| s.bhat_eve)),
        jx,
        eve_disagreement_pct: k_a.and_then(|k_a| share(k_a, false)),
        key_match: (accepted_bits > 0)
            .then(|| k_r.len() == k_c.len() && bool::from(k_r.ct_eq(k_c))),
        n_bce,
        n_acc,
    }
}

/// Private sensing's metrics over the bits of the kept doublets.
pub(super) fn private(config: &Config, bits: &[DoubletBit], keys: &RunKeys, jx: f64) -> Metrics {
    if !config.protocol.enabled {
        return Metrics {
            jx,
            ..Metrics::default()
        };
    }
    let n = bits.len();
    let share = |other: &[u8], equal: bool| {
        (n > 0).then(|| {
            let count = other
                .iter()
                .zip(keys.controller.iter())
                .filter(|(a, b)| (a == b) == equal)
                .count();
            100.0 * count as f64 / n as f64
        })
    };
    let rate = |key: &[u8]| {
        (n > 0).then(|| {
            key.iter()
                .zip(keys.robot.iter())
                .filter(|(a, b)| a != b)
                .count() as f64
                / n as f64
        })
    };
    let table = keys.eve.as_ref().map(|eve| {
        let mut table = [0u64; 8];
        for ((b, c), a) in keys
            .robot
            .iter()
            .zip(keys.controller.iter())
            .zip(eve.iter())
        {
            table[usize::from(b << 2 | c << 1 | a)] += 1;
        }
        table
    });
    Metrics {
        codewords_sent: None,
        accepted: None,
        accepted_pct: None,
        correct_pct: share(&keys.robot, true),
        ber_controller: rate(&keys.controller),
        ber_eve: keys.eve.as_deref().and_then(|eve| rate(eve)),
        jx,
        eve_disagreement_pct: keys.eve.as_deref().and_then(|eve| share(eve, false)),
        key_match: (n > 0).then(|| bool::from(keys.robot.ct_eq(&keys.controller))),
        n_bce: table,
        n_acc: table,
    }
}
