//! Multilevel sessions reconciled slice by slice (docs/postprocessing.md, "Multilevel
//! slices"), the agents' controller's side of the computation: what it keeps of each
//! decided doublet (its patterns' log-likelihoods), and each slice's decisions and LLRs given
//! the robot's bits of the lower slices once their blocks are reconciled — [`staged_llrs`],
//! the function the simulator uses for the lab's slices (which it conditions on the robot's
//! bits directly, not through this hand-off) — and a block's estimate of the plant on whole
//! symbols once every slice is reconciled ([`slice_estimates`]), each slice sized from it as
//! the lab sizes it.

use robokey_secrecy::BitString;
use robokey_secrecy::postprocess::{
    EstimateRequest, SessionSamples, SliceInput, Slicing, StagedSession, dequantise_llr,
    quantise_llr,
};

use crate::config::{Config, Reconciliation, SensingMode};
use crate::estimate::{BlockEstimate, request_separations};
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
/// ([`keep_likelihoods`]), `separations` (one per bit, `bits` of them) and what the
/// controller keeps of its doublets for the block's estimate (`samples`, one per doublet, or
/// none).
#[must_use]
pub fn first_slice(
    session: u32,
    slicing: Slicing,
    bits: usize,
    likelihoods: Vec<i16>,
    separations: Vec<f64>,
    samples: SessionSamples,
) -> StagedSession {
    StagedSession {
        session,
        slice: 0,
        slicing,
        likelihoods,
        separations,
        known: BitString::zeros(bits),
        samples,
    }
}

/// A multilevel block's estimate of the plant once its last slice is reconciled, and what
/// sizes each slice (docs/estimation.md, "Multilevel symbols"): `sessions` advanced past
/// their last slice (`known` holds the robot's bits of every slice, `samples` what the
/// controller kept), `disclosed[s]` the bits slice `s`'s block disclosed in its sample. The
/// block is estimated on whole symbols by the simulator's computation
/// ([`request_separations`]: the estimate, then the commands check), every slice sized from
/// that one estimate with its own bits' worst-case separations less its own sample
/// ([`BlockEstimate::for_slice`]), as `robokey secrecy --sizing measured` sizes the lab's
/// slices. A refusal refuses every slice. Returns one estimate per slice.
#[must_use]
pub fn slice_estimates(
    config: &Config,
    sessions: &[StagedSession],
    disclosed: &[u64],
    epsilon: f64,
) -> Vec<BlockEstimate> {
    let request = EstimateRequest {
        block: 0,
        sessions: sessions
            .iter()
            .map(|s| (s.session, s.samples.clone(), s.known.clone()))
            .collect(),
        disclosed: disclosed.iter().sum(),
    };
    let (separations, estimate) = request_separations(config, &request, epsilon);
    disclosed
        .iter()
        .enumerate()
        .map(|(slice, &disclosed)| {
            let picked: Vec<Vec<f64>> = sessions
                .iter()
                .zip(&separations)
                .map(|(staged, all)| staged.slicing.pick(all, slice))
                .collect();
            estimate.for_slice(slice, &picked, disclosed)
        })
        .collect()
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

#[cfg(test)]
mod tests {
    use rand::rngs::ChaCha8Rng;
    use rand::{RngExt, SeedableRng};

    use super::*;

    /// Two dimensions of 4 levels, LDPC.
    fn config() -> Config {
        let mut config = Config::default();
        config.sensing.mode = SensingMode::Private;
        config.protocol.bits_per_doublet = 2;
        config.protocol.levels = 4;
        config.postprocess.reconciliation = Reconciliation::Ldpc;
        config
    }

    /// The agents' LLRs of each slice — from the kept likelihoods and the robot's bits of
    /// the lower slices as their blocks reconcile them — are the simulator's
    /// ([`staged_llrs`] given the robot's word), within the kept likelihoods' quantum, and
    /// decide alike wherever the simulator's is not within it of 0.
    #[test]
    fn the_agents_slices_are_the_simulators() {
        let config = config();
        let perturbation = Perturbation::of(&config);
        let slicing = slicing(&config).expect("4 levels slice");
        assert_eq!((slicing.key_bits, slicing.slices), (4, 2));
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let doublets = 300;
        let (mut kept, mut all_ll, mut words) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..doublets {
            let word: u64 = rng.random_range(0..16);
            let truth = perturbation.pattern(word);
            // A noisy view: the true pattern likeliest on average, a few nats of spread.
            let ll: Vec<f64> = (0..16)
                .map(|h| {
                    let far = f64::from(u8::from(h != truth)) * 2.0;
                    -far + 3.0 * (rng.random::<f64>() - 0.5) + 40.0
                })
                .collect();
            keep_likelihoods(&ll, &mut kept);
            all_ll.push(ll);
            words.push(word);
        }
        let bits = doublets * 4;
        let robot: Vec<bool> = (0..bits)
            .map(|i| words[i / 4] >> (i % 4) & 1 == 1)
            .collect();
        let mut staged = first_slice(7, slicing, bits, kept, vec![1.0; bits], Vec::new());
        for slice in 0..2 {
            let input = slice_input(&config, staged.clone());
            let mut j = 0;
            for (d, ll) in all_ll.iter().enumerate() {
                let simulator = staged_llrs(ll, &perturbation, words[d]);
                for (i, &expected) in simulator.iter().enumerate().take(4) {
                    if slicing.slice_of(i) != slice {
                        continue;
                    }
                    let agents = input.llrs[j];
                    assert!((agents - expected).abs() < 0.02, "{agents} vs {expected}");
                    if expected.abs() > 0.02 {
                        assert_eq!(input.bits.get(j), Some(expected < 0.0));
                    }
                    j += 1;
                }
            }
            assert_eq!(j, input.bits.len());
            let reference = BitString::from_bools(&slicing.pick(&robot, slice));
            staged = staged.advanced(&reference);
        }
    }
}
