//! The controller's LLRs recomputed at block time (docs/estimation.md, "Causality"), one
//! implementation for the simulator and the agents. Online, each doublet is decided with
//! the prior (`noise.process_std`); LDPC's code rate and its decoding follow the LLRs'
//! magnitudes, which the prior's scale sets. Before reconciliation the block's estimate
//! cannot be used (it needs the reconciled bits), but the disclosed sample's bits are
//! public: the motion noise's covariance and its correlation between steps are fitted to the
//! doublets the sample discloses a bit of (the EM fit over the patterns their known bits
//! leave open, `pattern_fit`: `Q̂` from their one-step residuals, ρ̂ from consecutive ones;
//! with one bit per doublet each is known whole and the fit is those moments at once), and
//! every pooled bit's LLR is recomputed from the kept samples with them,
//! `Lᵢ = ln P(y | bᵢ = 0; Q̂, ρ̂) − ln P(y | bᵢ = 1; Q̂, ρ̂)` (the other bits marginalised;
//! `Q̂` in the robot's frame, turned to each doublet's start heading; the likelihood's steps
//! correlated by ρ̂).
//!
//! Covered: binary symbols, one or two bits per doublet (a multilevel slice's block goes to
//! `slice_llrs`), two-step doublets and three-step ones (`private.prior_lag`). A three-step
//! doublet's likelihood takes its four samples — the start, after the first and the second
//! step, the end — and the wheels' entry speed through the prior lag that the online
//! decision used, all kept beside it; its residuals for the fit are its three one-step ones
//! through the prior lag from that entry speed. The lag stays the prior's: τ is measured
//! from the reconciled bits only. Where a session was pooled without a three-step doublet's
//! sample after its second step, or the sample discloses a bit of fewer than
//! [`MIN_DOUBLETS_PER_PARITY`](super::motion_noise::MIN_DOUBLETS_PER_PARITY) doublets of
//! each parity, or their fit is not positive definite, the prior's LLRs stay, and the
//! reason is returned.

use robokey_secrecy::postprocess::{LlrAnswer, LlrRequest, RecomputedLlrs};

use super::block::{doublet_samples, own_view};
use super::pattern_fit::{MotionFit, PartlyKnown, open_pattern_fit, turned, world_llr_model};
use super::slice_llrs::{SliceSession, recomputed_slice_llrs};
use crate::Config;
use crate::config::LlrModel;
use crate::private::{DoubletModel, DoubletSamples, Perturbation, doublet_model};

/// The LLRs of `request`'s block (one per raw bit, in block order) recomputed with `basis`
/// under the parties' `config`.
///
/// # Errors
/// Why the prior's LLRs stay: `basis` is the prior, the doublets are not covered (three
/// steps, multilevel), a session was pooled without its samples, or the sample is too small
/// for the fit or its fit not positive definite — each naming the value.
pub fn recomputed_llrs(
    config: &Config,
    request: &LlrRequest,
    basis: LlrModel,
) -> Result<Vec<f64>, String> {
    let key_bits = config.protocol.key_bits_per_doublet();
    if basis == LlrModel::Prior {
        return Err("postprocess.llrs = \"prior\"".into());
    }
    let three_steps = config.doublet_settle().is_some();
    if let Some((id, k)) = request.sessions.iter().find_map(|(id, _, kept)| {
        kept.iter()
            .find(|k| k.late.is_some() != three_steps)
            .map(|k| (id, k))
    }) {
        return Err(if three_steps {
            format!(
                "three-step doublets: session {id:08x}'s doublet {} was pooled without its \
                 sample after the second step and entry speed (a store written before they \
                 were kept)",
                k.doublet
            )
        } else {
            format!(
                "session {id:08x}'s doublet {} keeps a sample after a second step, but the \
                 doublets have two steps (private.prior_lag = 0)",
                k.doublet
            )
        });
    }
    if Perturbation::of(config).levels > 2 {
        return Err(
            "multilevel symbols: each slice's LLRs are staged, recomputed per slice's block".into(),
        );
    }
    let mut disclosed = request.disclosed.iter().peekable();
    let mut all = Vec::new();
    let mut offset = 0_usize;
    for (id, bits, kept) in &request.sessions {
        if kept.len() * key_bits != *bits {
            return Err(format!(
                "session {id:08x}: the pool kept {} doublets for its {bits} raw bits",
                kept.len()
            ));
        }
        for (i, k) in kept.iter().enumerate() {
            let start = offset + i * key_bits;
            let (mut mask, mut word) = (0, 0);
            while let Some(&&(position, bit)) = disclosed.peek() {
                let position = position as usize;
                if position >= start + key_bits {
                    break;
                }
                disclosed.next();
                if position >= start {
                    mask |= 1 << (position - start);
                    word |= usize::from(bit) << (position - start);
                }
            }
            all.push(PartlyKnown {
                samples: doublet_samples(k, word),
                mask,
                word,
            });
        }
        offset += bits;
    }
    let prior = doublet_model(config);
    let motion = match basis {
        LlrModel::World => Motion::World(world_llr_model(config)),
        _ => {
            // The doublets the sample discloses a bit of; with one bit per doublet, those it
            // discloses whole.
            let touched: Vec<PartlyKnown> = all.iter().filter(|d| d.mask != 0).copied().collect();
            Motion::Fitted(open_pattern_fit(
                config,
                &prior,
                &touched,
                "the disclosed sample",
            )?)
        }
    };
    Ok(all
        .iter()
        .flat_map(|d| {
            let model = match &motion {
                Motion::World(model) => *model,
                Motion::Fitted(fit) => turned(&prior, fit, &d.samples),
            };
            doublet_llrs(config, &model, &d.samples)
        })
        .collect())
}

/// The motion noise the LLRs are recomputed with.
enum Motion {
    /// The world's own doublet model (`world_llr_model`).
    World(DoubletModel),
    /// `Q̂` in the robot's frame, turned to each doublet's start heading, and ρ̂.
    Fitted(MotionFit),
}

/// One doublet's key bits' LLRs under `model`, from the controller's own samples (stated
/// sensor noise `sensing.controller_std`), as the online decision computes them.
#[must_use]
pub fn doublet_llrs(config: &Config, model: &DoubletModel, d: &DoubletSamples) -> Vec<f64> {
    let (evidence, _) = model.evidence_and_likelihoods(&d.inputs, &own_view(config, d));
    evidence.llr[..config.protocol.key_bits_per_doublet()].to_vec()
}

/// The shell's answer to `request` under the parties' `config` with `basis`: a multilevel
/// slice's block through [`recomputed_slice_llrs`] (each session's staged material), every
/// other block through [`recomputed_llrs`]; the LLRs with `basis`' name, or why the prior's
/// stay (the block's report records either).
///
/// # Errors
/// Why the prior's LLRs stay, naming the value.
pub fn llr_answer(config: &Config, request: &LlrRequest, basis: LlrModel) -> LlrAnswer {
    let llrs = if Perturbation::of(config).levels > 2 {
        slice_block_llrs(config, request, basis)
    } else {
        recomputed_llrs(config, request, basis)
    };
    llrs.map(|llrs| RecomputedLlrs {
        model: basis.name().into(),
        llrs,
    })
}

/// A multilevel slice's block: every session with its staged material, all of one slice.
fn slice_block_llrs(
    config: &Config,
    request: &LlrRequest,
    basis: LlrModel,
) -> Result<Vec<f64>, String> {
    if request.staged.len() != request.sessions.len() {
        return Err(format!(
            "{} of the slice's {} sessions were pooled with their staged material (the kept \
             samples and the lower slices' bits)",
            request.staged.len(),
            request.sessions.len()
        ));
    }
    let slice = request.staged.first().map_or(0, |s| s.slice);
    let mut sessions = Vec::with_capacity(request.staged.len());
    for (staged, (id, bits, _)) in request.staged.iter().zip(&request.sessions) {
        if staged.slice != slice || staged.slice_bits() != *bits {
            return Err(format!(
                "session {id:08x}: staged slice {} of {} bits in a block of slice {slice} \
                 pooling {bits} of its bits",
                staged.slice,
                staged.slice_bits()
            ));
        }
        sessions.push(SliceSession {
            kept: &staged.samples,
            bits: &staged.known,
        });
    }
    recomputed_slice_llrs(
        config,
        usize::from(slice),
        &sessions,
        &request.disclosed,
        basis,
    )
}

/// Whether `config` asks for LLRs recomputed at block time (`postprocess.llrs`, or unset
/// under the measured sizing with LDPC).
#[must_use]
pub fn recomputes_llrs(config: &Config) -> bool {
    config.llr_model() != LlrModel::Prior
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::kept_doublet;

    fn private(world: &str) -> Config {
        Config::from_toml(&format!("[sensing]\nmode = \"private\"\n{world}"), "t").unwrap()
    }

    /// `sessions` simulated sessions of `config`' as the controller's endpoint asks for
    /// their LLRs, every `stride`-th bit disclosed with the robot's bit; and the online LLRs.
    fn request(config: &Config, sessions: u32, stride: usize) -> (LlrRequest, Vec<f64>) {
        let runs: Vec<_> = (0..sessions)
            .map(|r| crate::sim::simulate(config, r, false).unwrap())
            .collect();
        let mut request = LlrRequest {
            block: 0,
            sessions: Vec::new(),
            disclosed: Vec::new(),
            staged: Vec::new(),
        };
        let (mut online, mut offset) = (Vec::new(), 0);
        for (id, run) in runs.iter().enumerate() {
            let private = run.private.as_ref().unwrap();
            let kept = private
                .controller_samples
                .iter()
                .map(|d| kept_doublet(d.doublet, &d.inputs, &d.samples, d.late.as_ref()))
                .collect();
            request.sessions.push((id as u32, private.bits.len(), kept));
            for (i, bit) in private.bits.iter().enumerate() {
                if (offset + i) % stride == 0 {
                    request.disclosed.push(((offset + i) as u32, bit.bit == 1));
                }
            }
            online.extend(private.bits.iter().map(|b| b.controller));
            offset += private.bits.len();
        }
        (request, online)
    }

    /// With the prior's own model the recomputation gives the online LLRs; a sample too
    /// small for the estimate keeps the prior's, naming why.
    /// Run 0 of `config`: its kept samples give the online LLRs again under the prior's own
    /// model (to 10⁻⁹ relative); its kept samples are returned.
    fn online_llrs_again(config: &Config) -> Vec<DoubletSamples> {
        let run = crate::sim::simulate(config, 0, false).unwrap();
        let private = run.private.expect("private sensing");
        let online: Vec<f64> = private.bits.iter().map(|b| b.controller).collect();
        let model = doublet_model(config);
        let again: Vec<f64> = private
            .controller_samples
            .iter()
            .flat_map(|d| doublet_llrs(config, &model, d))
            .collect();
        assert_eq!(online.len(), again.len());
        for (a, b) in online.iter().zip(&again) {
            assert!((a - b).abs() <= 1e-9 * a.abs().max(1.0), "{a} vs {b}");
        }
        private.controller_samples
    }

    /// The mean magnitude of `llrs`.
    fn mean_magnitude(llrs: &[f64]) -> f64 {
        llrs.iter().map(|x| x.abs()).sum::<f64>() / llrs.len() as f64
    }

    /// Mean |L| of the LLRs recomputed from 8 sessions of `config` (a bit in `stride`
    /// disclosed) with the block's measured `Q̂`, with the world's own model, and of the
    /// online ones (as many of each).
    fn measured_world_online(config: &Config, stride: usize) -> (f64, f64, f64) {
        let (request, online) = request(config, 8, stride);
        let measured = recomputed_llrs(config, &request, LlrModel::Measured).unwrap();
        let world = recomputed_llrs(config, &request, LlrModel::World).unwrap();
        assert_eq!(measured.len(), online.len());
        (
            mean_magnitude(&measured),
            mean_magnitude(&world),
            mean_magnitude(&online),
        )
    }

    #[test]
    fn the_prior_model_recomputes_the_online_llrs() {
        let config = private("");
        online_llrs_again(&config);
        let (small, _) = request(&config, 1, 50);
        let why = recomputed_llrs(&config, &small, LlrModel::Measured).unwrap_err();
        assert!(
            why.contains("disclosed sample") && why.contains("of one parity"),
            "{why}"
        );
        assert!(recomputed_llrs(&config, &small, LlrModel::Prior).is_err());
    }

    /// In a 1 mm world (the prior 4 mm) the LLRs recomputed with Q̂ from a disclosed quarter
    /// of the bits are as large as the world's own model gives (mean |L| within 10 %), and
    /// larger than the prior's online ones.
    #[test]
    fn a_quieter_world_recomputes_to_the_worlds_llrs() {
        let config = private("[world]\nprocess_std = [0.001, 0.001, 0.001]\n");
        let (m, w, p) = measured_world_online(&config, 4);
        assert!((m / w - 1.0).abs() < 0.1, "measured {m}, world {w}");
        assert!(m > 1.5 * p, "measured {m}, prior {p}");
    }

    /// Two bits per doublet (v and ω), a tenth of the bits disclosed: a doublet is almost
    /// never disclosed whole (1 %), yet the fit over the patterns the disclosed bit leaves
    /// open recomputes the LLRs. In a 1 mm world (the prior 4 mm) their mean |L| lies within
    /// 10 % of the world's own model's and above 1.5 times the prior's; in an 8 mm world
    /// within 10 % of the world's and below 1/1.5 of the prior's (overconfident online).
    #[test]
    fn two_bit_doublets_are_recomputed_from_partly_disclosed_ones() {
        for (world, quieter) in [("0.001", true), ("0.008", false)] {
            let config = private(&format!(
                "[protocol]\nbits_per_doublet = 2\n[world]\nprocess_std = [{world}, {world}, \
                 {world}]\n"
            ));
            let (m, w, p) = measured_world_online(&config, 10);
            assert!(
                (m / w - 1.0).abs() < 0.1,
                "{world}: measured {m}, world {w}"
            );
            if quieter {
                assert!(m > 1.5 * p, "{world}: measured {m}, prior {p}");
            } else {
                assert!(1.5 * m < p, "{world}: measured {m}, prior {p}");
            }
        }
    }

    /// AR(1)-correlated motion noise at the parties' 4 mm (ρ = 0.9 between steps), one and two
    /// bits per doublet, a quarter of the bits disclosed: the LLRs recomputed with `Q̂` and ρ̂
    /// have a mean |L| within 10 % of the world's own correlated model's, and above 1.5 times
    /// the white prior's (which overstates the middle sample's motion noise given the end).
    #[test]
    fn correlated_noise_recomputes_to_the_worlds_correlated_llrs() {
        for bits in [1, 2] {
            let config = private(&format!(
                "[protocol]\nbits_per_doublet = {bits}\n[world]\nprocess_rho = 0.9\n"
            ));
            let (m, w, p) = measured_world_online(&config, 4);
            assert!(
                (m / w - 1.0).abs() < 0.1,
                "{bits} bits: measured {m}, world {w}"
            );
            assert!(m > 1.5 * p, "{bits} bits: measured {m}, prior {p}");
        }
    }

    /// Three-step doublets (50 ms of lag, stated as the prior): with the prior's own model
    /// the kept samples — the sample after the second step and the entry speed included —
    /// give the online LLRs again; at a matched prior (the world's 4 mm) the recomputed
    /// LLRs' mean |L| lies within 10 % of the online ones, and in a 1 mm world (the prior
    /// 4 mm) within 10 % of the world's own model's and above 1.5 times the prior's.
    #[test]
    fn three_step_llrs_are_recomputed_from_the_kept_samples() {
        let lag = "[private]\nprior_lag = 0.05\n[world]\nlag = 0.05\n";
        let config = private(lag);
        assert!(online_llrs_again(&config).iter().all(|d| d.late.is_some()));
        let (matched, online) = request(&config, 8, 4);
        let recomputed = recomputed_llrs(&config, &matched, LlrModel::Measured).unwrap();
        let (m, p) = (mean_magnitude(&recomputed), mean_magnitude(&online));
        assert!(
            (m / p - 1.0).abs() < 0.1,
            "matched: measured {m}, prior {p}"
        );
        let quiet = private(&format!("{lag}process_std = [0.001, 0.001, 0.001]\n"));
        let (m, w, p) = measured_world_online(&quiet, 4);
        assert!((m / w - 1.0).abs() < 0.1, "measured {m}, world {w}");
        assert!(m > 1.5 * p, "measured {m}, prior {p}");
    }

    /// A three-step session pooled without its sample after the second step (a store
    /// written before it was kept) keeps the prior's LLRs, naming the session and doublet.
    #[test]
    fn three_step_sessions_without_their_late_sample_keep_the_prior() {
        let config = private("[private]\nprior_lag = 0.05\n[world]\nlag = 0.05\n");
        let (mut old, _) = request(&config, 2, 4);
        for (_, _, kept) in &mut old.sessions {
            for k in kept.iter_mut() {
                k.late = None;
            }
        }
        let why = recomputed_llrs(&config, &old, LlrModel::Measured).unwrap_err();
        assert!(
            why.contains("session 00000000") && why.contains("after the second step"),
            "{why}"
        );
    }
}
