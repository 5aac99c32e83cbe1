//! Multilevel sessions reconciled slice by slice (docs/postprocessing.md, "Multilevel
//! slices"), the controller's side of the computation, shared by the agents and the lab:
//! what the controller keeps of each decided doublet (its patterns' log-likelihoods), and
//! each slice's decisions and LLRs given the robot's bits of the lower slices
//! ([`staged_llrs`]) once their blocks are reconciled.

use robokey_secrecy::BitString;
use robokey_secrecy::postprocess::{
    SliceInput, Slicing, StagedSession, dequantise_llr, quantise_llr,
};

use crate::config::{Config, Reconciliation, SensingMode};
use crate::private::Perturbation;
use crate::private::likelihood::staged_llrs;

/// How `config`'s sessions fall into slices: private sensing with more than two levels
/// (`None`: binary symbols, one slice, reconciled whole).
#[must_use]
pub fn slicing(config: &Config) -> Option<Slicing> {
    let perturbation = Perturbation::of(config);
    (config.sensing.mode == SensingMode::Private && perturbation.levels > 2)
        .then(|| Slicing::new(perturbation.key_bits(), perturbation.bits_per_symbol()).ok())
        .flatten()
}

/// One doublet's `ln p(view | h)` as kept: each less its largest, quantised
/// ([`quantise_llr`]: toward zero, floored ≈ 128 nats below the largest).
pub fn keep_likelihoods(log_likelihoods: &[f64], kept: &mut Vec<i16>) {
    let largest = log_likelihoods
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    kept.extend(log_likelihoods.iter().map(|&l| quantise_llr(l - largest)));
}

/// The staged material of a session's first slice: `likelihoods` as kept
/// ([`keep_likelihoods`]) and `separations` (one per bit, `bits` of them).
#[must_use]
pub fn first_slice(
    session: u32,
    slicing: Slicing,
    bits: usize,
    likelihoods: Vec<i16>,
    separations: Vec<f64>,
) -> StagedSession {
    StagedSession {
        session,
        slice: 0,
        slicing,
        likelihoods,
        separations,
        known: BitString::zeros(bits),
    }
}

/// The controller's decisions and LLRs of `staged`'s slice: each bit's LLR given the robot's
/// bits of the lower slices ([`staged_llrs`] under `config`'s alphabet), its decision the
/// sign; the LLRs kept only where LDPC reconciles (`config`).
#[must_use]
pub fn slice_input(config: &Config, staged: StagedSession) -> SliceInput {
    let perturbation = Perturbation::of(config);
    let key_bits = usize::from(staged.slicing.key_bits);
    let slice = usize::from(staged.slice);
    let mut decisions = Vec::with_capacity(staged.slice_bits());
    let mut llrs = Vec::with_capacity(staged.slice_bits());
    let mut ll = Vec::with_capacity(staged.slicing.patterns());
    for (doublet, kept) in staged
        .likelihoods
        .chunks(staged.slicing.patterns())
        .enumerate()
    {
        ll.clear();
        ll.extend(kept.iter().map(|&q| dequantise_llr(q)));
        let word = (0..key_bits).fold(0_u64, |word, i| {
            word | u64::from(staged.known.get(doublet * key_bits + i) == Some(true)) << i
        });
        let staged_llr = staged_llrs(&ll, &perturbation, word);
        for (i, &llr) in staged_llr.iter().enumerate().take(key_bits) {
            if staged.slicing.slice_of(i) == slice {
                decisions.push(llr < 0.0);
                llrs.push(llr);
            }
        }
    }
    if config.postprocess.reconciliation != Reconciliation::Ldpc {
        llrs.clear();
    }
    SliceInput {
        bits: BitString::from_bools(&decisions),
        llrs,
        staged,
    }
}
