//! The agents' LLRs recomputed at block time are the simulator's (docs/estimation.md,
//! "Causality"): the same sessions of a world the parties' configuration does not describe,
//! pooled under the same IDs into endpoints seeded alike, give the same LDPC leak, rounds and
//! key length through the agents' post-processing link as through the lab's pipeline; and
//! there the prior's LLRs fail where the recomputed ones key.

use std::collections::BTreeSet;

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use robokey::Config;
use robokey::config::{EveStrategy, LlrModel};
use robokey::connection::{PostLink, PostOutput};
use robokey::estimate::kept_doublet;
use robokey::post_settings::post_settings;
use robokey::protocol::Outcome;
use robokey::sim::{RunOutput, simulate};
use robokey_lab::secrecy::pipeline::{self, Block, BlockSettings, Pooling};
use robokey_lab::secrecy::private::assumed_separations;
use robokey_secrecy::postprocess::{
    BlockReport, ControllerPost, LlrProvenance, RobotPost, SessionSamples,
};

/// The parties at the defaults with LDPC on `llrs` and `bits` binary bits per doublet, one
/// 10⁴-bit block, the robot in an 8 mm world (twice the 4 mm they believe). The plant
/// configured (stated: unset, private sensing sizes from the measured plant): these tests
/// compare the LLRs, the lab's pipeline sizing from the configured assumption.
fn parties(llrs: &str, bits: u8) -> Config {
    Config::from_toml(
        &format!(
            "[sensing]\nmode = \"private\"\n[protocol]\nbits_per_doublet = {bits}\n\
             [postprocess]\nreconciliation = \"ldpc\"\nllrs = \"{llrs}\"\nsizing = \"configured\"\n\
             [world]\nprocess_std = [0.008, 0.008, 0.008]\n"
        ),
        "test",
    )
    .unwrap()
}

/// A block report's provenance: decoded on `model`'s LLRs, no fallback.
fn named(model: &str) -> LlrProvenance {
    LlrProvenance {
        model: model.into(),
        fallback: None,
    }
}

fn kept(run: &RunOutput) -> SessionSamples {
    let private = run.private.as_ref().unwrap();
    private
        .controller_samples
        .iter()
        .map(|d| kept_doublet(d.doublet, &d.inputs, &d.samples, d.late.as_ref()))
        .collect()
}

/// The lab's block of `runs` (the first pool of 10⁴ bits) and the agents' report of the same
/// sessions, both endpoints seeded from `seed`.
fn both(config: &Config, runs: &[RunOutput], seed: u64) -> (Block, BlockReport) {
    let mut pools = pipeline::pools(runs, Pooling::Complete, 10_000, EveStrategy::Camera);
    pools.truncate(1);
    let pool = &mut pools[0];
    pool.separations = pool
        .runs
        .iter()
        .map(|&i| assumed_separations(&runs[i]))
        .collect();
    pool.kept = pool.runs.iter().map(|&i| kept(&runs[i])).collect();
    let endpoints = post_settings(config);
    let settings = BlockSettings {
        pooling: Pooling::Complete,
        epsilon: endpoints.epsilon,
        sample_bits: endpoints.sample_bits,
        block_bits: endpoints.block_bits,
        assumption: endpoints.assumption.clone(),
        reconciliation: endpoints.reconciliation,
        block_llrs: (!config.llr_model().is_prior()).then(|| (config.clone(), config.llr_model())),
    };
    let lab = pipeline::post_process(&pools, &settings, &mut ChaCha8Rng::seed_from_u64(seed))
        .into_iter()
        .next()
        .expect("a block");
    // The lab's endpoints draw their seeds from the same stream, the controller's first.
    let mut public = ChaCha8Rng::seed_from_u64(seed);
    let (controller_seed, robot_seed): ([u8; 32], [u8; 32]) = (public.random(), public.random());
    let mut controller = PostLink::new(
        ControllerPost::new(endpoints.clone(), controller_seed).unwrap(),
        BTreeSet::new(),
        config,
    );
    let mut robot = PostLink::new(
        RobotPost::new(endpoints, robot_seed).unwrap(),
        BTreeSet::new(),
        config,
    );
    // The robot holds every session before the controller proposes.
    let sessions: Vec<(u32, &RunOutput)> = pools[0]
        .runs
        .iter()
        .enumerate()
        .map(|(id, &i)| (id as u32, &runs[i]))
        .collect();
    for &(id, run) in &sessions {
        robot.pool(
            id,
            &Outcome::Kept,
            &run.keys.robot,
            vec![],
            vec![],
            vec![],
            vec![],
        );
    }
    for &(id, run) in &sessions {
        let private = run.private.as_ref().unwrap();
        controller.pool(
            id,
            &Outcome::Kept,
            &run.keys.controller,
            assumed_separations(run),
            kept(run),
            private.bits.iter().map(|b| b.controller).collect(),
            vec![],
        );
    }
    let mut ended = Vec::new();
    for _ in 0..200 {
        let mut out = Vec::new();
        let to_robot = controller.flush(&mut out).unwrap();
        let mut robot_out = Vec::new();
        for fragment in &to_robot {
            robot.receive(fragment, &mut robot_out);
        }
        let to_controller = robot.flush(&mut robot_out).unwrap();
        for fragment in &to_controller {
            controller.receive(fragment, &mut out);
        }
        ended.extend(out.into_iter().filter_map(|o| match o {
            PostOutput::BlockEnded(report) => Some(report),
            _ => None,
        }));
        if to_robot.is_empty() && to_controller.is_empty() && !ended.is_empty() {
            break;
        }
    }
    (
        lab,
        ended.into_iter().next().expect("the agents ended a block"),
    )
}

/// 32 sessions of the parties recomputing their LLRs (`bits` per doublet) in the 8 mm world,
/// keyed in the lab and through the agents alike — the same leak, LDPC rounds and length, both
/// reports naming the measured LLRs; returns the sessions.
fn keyed_alike_on_measured_llrs(bits: u8) -> Vec<RunOutput> {
    let measured = parties("measured", bits);
    let runs: Vec<RunOutput> = (0..32)
        .map(|r| simulate(&measured, r, false).unwrap())
        .collect();
    let (lab, agents) = both(&measured, &runs, 11);
    assert!(lab.consistent && lab.secret_bits > 0, "{lab:?}");
    assert_eq!(
        (Some(agents.leak_ec), agents.ldpc_rounds, agents.length),
        (Some(lab.leak_ec), lab.ldpc_rounds, lab.secret_bits),
        "agents {agents:?}, lab {lab:?}"
    );
    assert_eq!(lab.llrs, Some(named("measured")));
    assert_eq!(agents.llrs.as_deref(), Some(&named("measured")));
    runs
}

#[test]
fn the_agents_recompute_the_llrs_as_the_simulator_does_in_a_noisier_world() {
    let runs = keyed_alike_on_measured_llrs(1);
    // The prior's LLRs (the configured 4 mm) on the same sessions: overconfident, LDPC's
    // syndrome is too short and the block fails in the lab and through the agents alike.
    let (lab, agents) = both(&parties("prior", 1), &runs, 11);
    assert_eq!(lab.secret_bits, 0, "{lab:?}");
    assert_eq!(agents.length, 0, "{agents:?}");
    assert_eq!(lab.llrs, Some(named("prior")));
    assert_eq!(agents.llrs.as_deref(), Some(&named("prior")));
}

/// Two binary bits per doublet (v and ω) in the same 8 mm world: the sample discloses a
/// doublet whole too rarely for a fit on whole doublets, and the fit over the patterns its
/// disclosed bit leaves open gives the lab and the agents the same block, keyed on the
/// measured LLRs (no fallback in either report).
#[test]
fn the_agents_recompute_two_bit_llrs_as_the_simulator_does() {
    keyed_alike_on_measured_llrs(2);
}

/// A multilevel block (two dimensions of 4 levels) in an 8 mm world, the parties believing
/// 4 mm, through the lab's pipeline slice by slice: on the prior's overconfident staged LLRs
/// its fine slice fails, and the coarse slice with it; recomputed at each slice's block
/// time both slices reconcile, each within the leak of the world's own LLRs (the oracle)
/// plus a tenth, and the coarse slice keys (the fine one, at 39 % errors, leaks more than
/// its length under the oracle's LLRs too); each block's report names the LLRs it decoded
/// on.
#[test]
fn a_multilevel_blocks_slices_recompute_their_staged_llrs() {
    let config = |llrs: &str| {
        Config::from_toml(
            &format!(
                "[sensing]\nmode = \"private\"\n[protocol]\nbits_per_doublet = 2\nlevels = 4\n\
                 [postprocess]\nreconciliation = \"ldpc\"\nllrs = \"{llrs}\"\n\
                 sizing = \"configured\"\n[world]\nprocess_std = [0.008, 0.008, 0.008]\n"
            ),
            "test",
        )
        .unwrap()
    };
    let measured = config("measured");
    let runs: Vec<RunOutput> = (0..16)
        .map(|r| simulate(&measured, r, false).unwrap())
        .collect();
    let slices = |basis: Option<LlrModel>| -> Vec<Block> {
        let mut pools = pipeline::pools(&runs, Pooling::Complete, 10_000, EveStrategy::Camera);
        pools.truncate(1);
        let pool = &mut pools[0];
        pool.separations = pool
            .runs
            .iter()
            .map(|&i| assumed_separations(&runs[i]))
            .collect();
        if basis.is_some() {
            pool.kept = pool.runs.iter().map(|&i| kept(&runs[i])).collect();
        }
        let parts = pool.slices(4, 2);
        let endpoints = post_settings(&measured);
        let settings = BlockSettings {
            pooling: Pooling::Complete,
            epsilon: endpoints.epsilon,
            sample_bits: endpoints.sample_bits,
            block_bits: endpoints.block_bits.div_ceil(2),
            assumption: endpoints.assumption.clone(),
            reconciliation: endpoints.reconciliation,
            block_llrs: basis.map(|b| (measured.clone(), b)),
        };
        let mut blocks =
            pipeline::post_process(&parts, &settings, &mut ChaCha8Rng::seed_from_u64(3));
        pipeline::fail_later_slices(&mut blocks, 2);
        assert_eq!(blocks.len(), 2);
        blocks
    };
    let prior = slices(None);
    assert!(prior.iter().all(|b| b.secret_bits == 0), "prior {prior:?}");
    assert!(prior[0].failed_reconciliation, "{:?}", prior[0]);
    let world = slices(Some(LlrModel::World));
    let recomputed = slices(Some(LlrModel::Measured));
    assert!(recomputed[1].secret_bits > 0, "{:?}", recomputed[1]);
    for (m, w) in recomputed.iter().zip(&world) {
        assert!(m.consistent && !m.failed_reconciliation, "measured {m:?}");
        assert!(
            (m.leak_ec as f64) < 1.1 * w.leak_ec as f64,
            "measured {} vs the world's {}",
            m.leak_ec,
            w.leak_ec
        );
        let model = |b: &Block| {
            b.llrs
                .as_ref()
                .map(|l| (l.model.clone(), l.fallback.clone()))
        };
        assert_eq!(model(m), Some(("measured".into(), None)));
        assert_eq!(model(w), Some(("world".into(), None)));
    }
    assert!(
        prior
            .iter()
            .all(|b| b.llrs.as_ref().is_some_and(|l| l.model == "prior"))
    );
}
