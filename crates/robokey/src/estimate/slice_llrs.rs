//! The LLRs of a multilevel slice recomputed at block time (docs/estimation.md,
//! "Causality"; docs/postprocessing.md, "Multilevel slices"), one implementation for the
//! simulator and the agents. A slice's LLRs are staged ([`staged_llrs`]): the symbols' lower
//! slices known (the controller's reconciled bits of their blocks), the slice's own and
//! higher bits summed over. Online they come from the prior's pattern likelihoods; here
//! every kept doublet's pattern likelihoods are recomputed with the motion noise `Q̂` and its
//! correlation ρ̂ between steps fitted at the slice's block time, and the staged LLRs taken
//! from them.
//!
//! The fit uses what the controller holds when the slice's block is reconciled: every
//! doublet's kept samples, the lower slices' reconciled bits, and this slice's disclosed
//! sample (the robot's published bits). A symbol is almost never known whole then (its
//! higher slices are not reconciled yet), so `Q̂` and ρ̂ are the EM fit over the patterns each
//! doublet's known bits leave open (`pattern_fit`), every kept doublet of the block in it.

use robokey_secrecy::BitString;
use robokey_secrecy::postprocess::KeptDoublet;

use super::block::{doublet_samples, own_view};
use super::pattern_fit::{PartlyKnown, open_pattern_fit, turned, world_llr_model};
use crate::Config;
use crate::config::LlrModel;
use crate::private::likelihood::staged_llrs;
use crate::private::{DoubletModel, DoubletSamples, Perturbation, doublet_model};

/// One session of a slice's block as the controller holds it.
#[derive(Clone, Copy, Debug)]
pub struct SliceSession<'a> {
    /// What the pool kept of each of its doublets, in order.
    pub kept: &'a [KeptDoublet],
    /// Its raw bits, `key_bits` per doublet in order (the v-symbol's label, then the
    /// ω-symbol's), of which only the lower slices' are read: the controller's reconciled
    /// bits of those slices' blocks.
    pub bits: &'a BitString,
}

/// The LLRs of slice `slice`'s block (one per bit of the slice, in block order: each
/// session's doublets in order, each doublet's bits of the slice in label order) recomputed
/// with `basis` under the parties' `config`; `disclosed` the slice block's sample (positions
/// in the block, with the robot's bits).
///
/// # Errors
/// Why the prior's LLRs stay: `basis` is the prior, the symbols are binary or three-step,
/// `slice` is not one of the alphabet's, a session's kept doublets do not match its bits,
/// a kept value is not finite, or the fit refuses the block (too few doublets, singular or
/// not positive definite) — each naming the value.
pub fn recomputed_slice_llrs(
    config: &Config,
    slice: usize,
    sessions: &[SliceSession<'_>],
    disclosed: &[(u32, bool)],
    basis: LlrModel,
) -> Result<Vec<f64>, String> {
    let perturbation = Perturbation::of(config);
    let (m, key_bits) = (perturbation.bits_per_symbol(), perturbation.key_bits());
    if basis == LlrModel::Prior {
        return Err("postprocess.llrs = \"prior\"".into());
    }
    if perturbation.levels <= 2 {
        return Err("binary symbols: no slices".into());
    }
    if config.doublet_settle().is_some() {
        return Err(
            "three-step doublets: the kept samples lack the doublet's third sample and entry \
             speed"
                .into(),
        );
    }
    if slice >= m {
        return Err(format!(
            "slice {slice} of a {}-level alphabet (allowed: 0 to {})",
            perturbation.levels,
            m - 1
        ));
    }
    let doublets = known_doublets(slice, m, key_bits, sessions, disclosed)?;
    let prior = doublet_model(config);
    let model_of: Box<dyn Fn(&DoubletSamples) -> DoubletModel> = match basis {
        LlrModel::World => {
            let world = world_llr_model(config);
            Box::new(move |_| world)
        }
        _ => {
            let fit = open_pattern_fit(config, &prior, &doublets, "the slice")?;
            Box::new(move |d| turned(&prior, &fit, d))
        }
    };
    let mut llrs = Vec::with_capacity(doublets.len() * key_bits / m);
    for d in &doublets {
        let ll =
            model_of(&d.samples).log_likelihoods(&d.samples.inputs, &own_view(config, &d.samples));
        let staged = staged_llrs(&ll, &perturbation, d.word as u64);
        llrs.extend((0..key_bits).filter(|i| i % m == slice).map(|i| staged[i]));
    }
    Ok(llrs)
}

/// Every kept doublet of `sessions` with its known bits: the lower slices' (from each
/// session's bits) and slice `slice`'s where `disclosed` holds them.
fn known_doublets(
    slice: usize,
    m: usize,
    key_bits: usize,
    sessions: &[SliceSession<'_>],
    disclosed: &[(u32, bool)],
) -> Result<Vec<PartlyKnown>, String> {
    let lower = (0..key_bits)
        .filter(|i| i % m < slice)
        .fold(0, |mask, i| mask | 1 << i);
    let ours: Vec<usize> = (0..key_bits).filter(|i| i % m == slice).collect();
    let mut disclosed = disclosed.iter().peekable();
    let mut position = 0_usize;
    let mut out = Vec::new();
    for (s, session) in sessions.iter().enumerate() {
        if session.kept.len() * key_bits != session.bits.len() {
            return Err(format!(
                "session {s} of the slice's block: the pool kept {} doublets for its {} raw \
                 bits (allowed: one per {key_bits} bits)",
                session.kept.len(),
                session.bits.len()
            ));
        }
        for (j, k) in session.kept.iter().enumerate() {
            let finite = k.inputs.iter().flatten().chain(k.samples.iter().flatten());
            if !finite.into_iter().all(|x| x.is_finite()) {
                return Err(format!(
                    "session {s} of the slice's block: doublet {}'s kept samples are not \
                     finite",
                    k.doublet
                ));
            }
            let bit = |i: usize| usize::from(session.bits.get(j * key_bits + i) == Some(true));
            let (mut mask, mut word) = (lower, 0);
            for i in (0..key_bits).filter(|i| lower >> i & 1 == 1) {
                word |= bit(i) << i;
            }
            for &i in &ours {
                if let Some(&(_, value)) = disclosed.next_if(|&&(p, _)| p as usize == position) {
                    mask |= 1 << i;
                    word |= usize::from(value) << i;
                }
                position += 1;
            }
            out.push(PartlyKnown {
                samples: doublet_samples(k, 0),
                mask,
                word,
            });
        }
    }
    if let Some(&(p, _)) = disclosed.next() {
        return Err(format!(
            "disclosed position {p} beyond the slice's block of {position} bits"
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::kept_doublet;

    /// Two dimensions of 4 levels (4 key bits per doublet) in private sensing, `world`.
    fn multilevel(world: &str) -> Config {
        Config::from_toml(
            &format!(
                "[sensing]\nmode = \"private\"\n[protocol]\nbits_per_doublet = 2\nlevels = 4\n\
                 {world}"
            ),
            "t",
        )
        .unwrap()
    }

    /// `sessions` simulated sessions of `config`: each one's kept doublets and raw bits (the
    /// robot's), the online staged LLRs of every bit, and the bits' slices.
    struct Sessions {
        kept: Vec<Vec<KeptDoublet>>,
        bits: Vec<BitString>,
        online: Vec<Vec<f64>>,
    }

    fn sessions(config: &Config, count: u32) -> Sessions {
        let mut out = Sessions {
            kept: Vec::new(),
            bits: Vec::new(),
            online: Vec::new(),
        };
        for r in 0..count {
            let run = crate::sim::simulate(config, r, false).unwrap();
            let private = run.private.as_ref().unwrap();
            out.kept.push(
                private
                    .controller_samples
                    .iter()
                    .map(|d| kept_doublet(d.doublet, &d.inputs, &d.samples, d.late.as_ref()))
                    .collect(),
            );
            let bits: Vec<bool> = private.bits.iter().map(|b| b.bit == 1).collect();
            out.bits.push(BitString::from_bools(&bits));
            out.online
                .push(private.bits.iter().map(|b| b.controller).collect());
        }
        out
    }

    impl Sessions {
        fn slice_sessions(&self) -> Vec<SliceSession<'_>> {
            self.kept
                .iter()
                .zip(&self.bits)
                .map(|(kept, bits)| SliceSession { kept, bits })
                .collect()
        }

        /// Slice `slice`'s online LLRs in block order, and every `stride`-th of its bits
        /// disclosed.
        fn slice(&self, slice: usize, stride: usize) -> (Vec<f64>, Vec<(u32, bool)>) {
            let (mut online, mut disclosed) = (Vec::new(), Vec::new());
            for (llrs, bits) in self.online.iter().zip(&self.bits) {
                for (i, &l) in llrs.iter().enumerate() {
                    if (i % 4) % 2 == slice {
                        if online.len() % stride == 0 {
                            disclosed.push((online.len() as u32, bits.get(i) == Some(true)));
                        }
                        online.push(l);
                    }
                }
            }
            (online, disclosed)
        }
    }

    fn mean_magnitude(l: &[f64]) -> f64 {
        l.iter().map(|x| x.abs()).sum::<f64>() / l.len() as f64
    }

    /// With the prior's own motion noise (the world the parties configured, its model
    /// through the `world` basis) every slice's recomputed LLRs are the online staged ones,
    /// in the same order, to rounding; the prior basis, a binary alphabet and a slice beyond
    /// the alphabet keep the prior's, naming why.
    #[test]
    fn the_priors_model_recomputes_the_online_staged_llrs() {
        let config = multilevel("");
        let s = sessions(&config, 2);
        for slice in 0..2 {
            let (online, disclosed) = s.slice(slice, 10);
            let again = recomputed_slice_llrs(
                &config,
                slice,
                &s.slice_sessions(),
                &disclosed,
                LlrModel::World,
            )
            .unwrap();
            assert_eq!(again.len(), online.len());
            for (a, b) in online.iter().zip(&again) {
                assert!((a - b).abs() <= 1e-9 * a.abs().max(1.0), "{a} vs {b}");
            }
        }
        let (_, disclosed) = s.slice(0, 10);
        let refused = |config: &Config, slice, basis| {
            recomputed_slice_llrs(config, slice, &s.slice_sessions(), &disclosed, basis)
                .unwrap_err()
        };
        assert!(refused(&config, 0, LlrModel::Prior).contains("prior"));
        assert!(refused(&config, 2, LlrModel::Measured).contains("slice 2"));
        let binary = Config::from_toml("[sensing]\nmode = \"private\"\n", "b").unwrap();
        assert!(refused(&binary, 0, LlrModel::Measured).contains("binary"));
    }

    /// Where the world is the prior (4 mm), the measured staged LLRs of each slice are the
    /// online ones on average: their mean magnitude within 5 % (the fit from one block's
    /// 2,000 doublets errs by a few per cent).
    #[test]
    fn the_priors_world_measures_to_the_priors_llrs() {
        let config = multilevel("");
        let s = sessions(&config, 6);
        for slice in 0..2 {
            let (online, disclosed) = s.slice(slice, 10);
            let measured = recomputed_slice_llrs(
                &config,
                slice,
                &s.slice_sessions(),
                &disclosed,
                LlrModel::Measured,
            )
            .unwrap();
            let (m, p) = (mean_magnitude(&measured), mean_magnitude(&online));
            assert!(
                (m / p - 1.0).abs() < 0.05,
                "slice {slice}: measured {m}, prior {p}"
            );
        }
    }

    /// In an 8 mm world (the prior 4 mm: overconfident staged LLRs) each slice's measured
    /// LLRs are as large as the world's own model gives (mean |L| within 10 %), well below
    /// the prior's.
    #[test]
    fn a_noisier_world_recomputes_to_the_worlds_staged_llrs() {
        let config = multilevel("[world]\nprocess_std = [0.008, 0.008, 0.008]\n");
        let s = sessions(&config, 6);
        for slice in 0..2 {
            let (online, disclosed) = s.slice(slice, 10);
            let llrs = |basis| {
                recomputed_slice_llrs(&config, slice, &s.slice_sessions(), &disclosed, basis)
                    .unwrap()
            };
            let (m, w, p) = (
                mean_magnitude(&llrs(LlrModel::Measured)),
                mean_magnitude(&llrs(LlrModel::World)),
                mean_magnitude(&online),
            );
            assert!(
                (m / w - 1.0).abs() < 0.1,
                "slice {slice}: measured {m}, world {w}"
            );
            assert!(p > 1.5 * m, "slice {slice}: prior {p}, measured {m}");
        }
    }
}
