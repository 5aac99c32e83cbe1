//! The endpoints with LDPC reconciliation: the same keys on both sides, a failed decoding and
//! a changed syndrome end without a key, odometry sessions and dishonest requests refused.

use super::*;
use crate::ldpc::LdpcSettings;

/// Sessions (ID, the robot's bits, the controller's decisions) and the controller's LLRs of
/// each session's bits.
type SoftSessions = (Vec<(u32, BitString, BitString)>, Vec<Vec<f64>>);

/// Sessions of 300–700 bits seen by the controller through a binary-input Gaussian channel
/// of noise σ: y = ±1 + N(0, σ²), its LLR 2y/σ² (calibrated) and its decision the LLR's sign.
fn soft_sessions(count: u32, sigma: f64, rng: &mut ChaCha8Rng) -> SoftSessions {
    let mut pool = Vec::new();
    let mut llrs = Vec::new();
    for id in 0..count {
        let n = rng.random_range(300..700);
        let robot = BitString::random(n, rng);
        let session: Vec<f64> = (0..n)
            .map(|i| {
                // Box–Muller.
                let (u, v): (f64, f64) = (rng.random::<f64>().max(1e-300), rng.random());
                let noise = sigma * (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos();
                let sent = if robot.get(i) == Some(true) {
                    -1.0
                } else {
                    1.0
                };
                2.0 * (sent + noise) / (sigma * sigma)
            })
            .collect();
        let decided: Vec<bool> = session.iter().map(|&l| l < 0.0).collect();
        pool.push((id, robot, BitString::from_bools(&decided)));
        llrs.push(session);
    }
    (pool, llrs)
}

/// Each LLR's sign at a confidence of 12 nats (an error probability of 6·10⁻⁶), far above
/// what the channel gives.
fn overconfident(llrs: &[Vec<f64>]) -> Vec<Vec<f64>> {
    llrs.iter()
        .map(|s| s.iter().map(|l| 12.0 * l.signum()).collect())
        .collect()
}

fn ldpc(assumption: Assumption) -> Settings {
    Settings {
        reconciliation: ReconciliationMethod::Ldpc(LdpcSettings::DEFAULT),
        ..settings(assumption)
    }
}

/// Blocks of 6,000 bits or more: at 2,000 LDPC fails a block in a few (the code is short
/// for its rate, docs/postprocessing.md), which would only be discarded.
#[test]
fn ldpc_makes_the_same_keys_and_both_sides_charge_every_syndrome_bit() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let (mut committed, mut blocks) = (0, 0);
    for trial in 0..4 {
        // Q ≈ 1 % to 6 %.
        let sigma = rng.random_range(0.42..0.62);
        let (pool, llrs) = soft_sessions(rng.random_range(14..30), sigma, &mut rng);
        let settings = Settings {
            block_bits: 6_000,
            ..ldpc(weak_eve())
        };
        let mut pair = Pair::with_views(settings, &pool, &[], &[], &llrs);
        assert!(pair.settle(100_000, None), "trial {trial} did not settle");
        pair.assert_same_keys(&format!("trial {trial}"));
        committed += pair.controller_keys.len();
        for report in &pair.reports {
            blocks += 1;
            let rounds = report
                .ldpc_rounds
                .unwrap_or_else(|| panic!("trial {trial}: no rounds: {report:?}"));
            assert!((1..=9).contains(&rounds), "{report:?}");
            // Every syndrome bit, and ⌈log₂ 9⌉ = 4 bits for the number of rounds.
            assert_eq!(report.leak_ec, report.questions + 4, "{report:?}");
            // The key records its reconciliation and leak, the same on both sides.
            let recorded = Some(crate::postprocess::KeyReconciliation {
                method: "ldpc".into(),
                leak_ec: report.leak_ec,
            });
            for key in pair
                .controller_keys
                .iter()
                .filter(|k| k.block == report.block)
            {
                assert_eq!(key.reconciliation, recorded, "trial {trial}");
            }
            let robot = pair
                .robot_reports
                .iter()
                .find(|r| r.block == report.block)
                .expect("the robot reports the block");
            assert_eq!(robot.leak_ec, report.leak_ec);
            assert_eq!(robot.length, report.length);
            assert_eq!(robot.ldpc_rounds, report.ldpc_rounds);
        }
    }
    assert!(
        blocks >= 4 && committed == blocks,
        "{committed} keys of {blocks} blocks"
    );
}

#[test]
fn ldpc_leaks_less_than_cascade_on_the_same_sessions() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let (pool, llrs) = soft_sessions(12, 0.5, &mut rng);
    let mut cascade = Pair::new(settings(weak_eve()), &pool);
    let mut soft = Pair::with_views(ldpc(weak_eve()), &pool, &[], &[], &llrs);
    assert!(cascade.settle(100_000, None) && soft.settle(100_000, None));
    let leak = |pair: &Pair| pair.reports.iter().map(|r| r.leak_ec).sum::<u64>();
    let length = |pair: &Pair| pair.reports.iter().map(|r| r.length).sum::<u64>();
    assert!(
        leak(&soft) < leak(&cascade),
        "{} ≥ {}",
        leak(&soft),
        leak(&cascade)
    );
    assert!(length(&soft) > length(&cascade));
    for (pair, method) in [(&cascade, "cascade"), (&soft, "ldpc")] {
        assert!(!pair.controller_keys.is_empty(), "{method}");
        for key in pair.controller_keys.iter().chain(&pair.robot_keys) {
            let report = pair.reports.iter().find(|r| r.block == key.block).unwrap();
            let recorded = key.reconciliation.as_ref().unwrap();
            assert_eq!(
                (recorded.method.as_str(), recorded.leak_ec),
                (method, report.leak_ec)
            );
        }
    }
}

/// LLRs that claim far more confidence than the channel gives ask for too short a syndrome:
/// decoding fails on every round, and the block ends as failed reconciliation, named, with
/// no key on either side.
#[test]
fn a_block_ldpc_fails_to_decode_aborts_as_failed_reconciliation() {
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let (pool, llrs) = soft_sessions(6, 0.9, &mut rng);
    let overconfident = overconfident(&llrs);
    let mut pair = Pair::with_views(ldpc(weak_eve()), &pool, &[], &[], &overconfident);
    assert!(pair.settle(100_000, None));
    assert!(pair.controller_keys.is_empty() && pair.robot_keys.is_empty());
    assert!(!pair.reports.is_empty());
    for report in &pair.reports {
        let reason = report.reason.as_deref().unwrap_or_default();
        assert!(
            reason.contains("failed reconciliation") || reason.contains("tag differs"),
            "{reason}"
        );
        assert_eq!(report.length, 0);
    }
}

/// LLRs recomputed at block time (docs/estimation.md, "Causality"): the controller asks its
/// shell after the robot's sample and before the first syndrome, with every agreed session's
/// bit count and the disclosed positions with the robot's bits; decoding on the shell's
/// calibrated LLRs makes the keys that the pooled, overconfident ones fail to; an answer that
/// does not cover the block ends it naming why.
#[test]
fn ldpc_decodes_on_the_llrs_the_shell_recomputes_at_block_time() {
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let (pool, llrs) = soft_sessions(14, 0.55, &mut rng);
    let overconfident = overconfident(&llrs);
    let settings = Settings {
        block_bits: 6_000,
        ..ldpc(weak_eve())
    };
    let recomputing = |answer: Vec<Vec<f64>>| {
        let mut pair = Pair::with_views(settings.clone(), &pool, &[], &[], &overconfident);
        pair.controller.recompute_llrs(true);
        pair.recomputed = answer;
        // The block was proposed as the sessions were pooled: the switch acts at the
        // robot's Agree.
        assert!(pair.settle(100_000, None));
        pair
    };
    let pair = recomputing(llrs.clone());
    assert!(!pair.llr_requests.is_empty() && !pair.controller_keys.is_empty());
    pair.assert_same_keys("recomputed LLRs");
    for (request, report) in pair.llr_requests.iter().zip(&pair.reports) {
        assert_eq!(request.block, report.block);
        let sampled: Vec<u32> = request.disclosed.iter().map(|&(i, _)| i).collect();
        assert_eq!(sampled, report.sampled);
        let robot: Vec<bool> = request
            .sessions
            .iter()
            .flat_map(|(id, bits, kept)| {
                assert!(kept.is_empty());
                let reference = &pool[*id as usize].1;
                assert_eq!(*bits, reference.len());
                (0..*bits).map(move |i| reference.get(i) == Some(true))
            })
            .collect();
        for &(i, bit) in &request.disclosed {
            assert_eq!(robot[i as usize], bit, "disclosed bit {i}");
        }
    }
    let pooled = recomputing(Vec::new());
    assert!(pooled.controller_keys.is_empty() && !pooled.llr_requests.is_empty());
    let short: Vec<Vec<f64>> = llrs.iter().map(|s| s[1..].to_vec()).collect();
    let ended = recomputing(short);
    assert!(ended.controller_keys.is_empty() && ended.robot_keys.is_empty());
    let reason = ended.reports[0].reason.as_deref().unwrap_or_default();
    assert!(reason.contains("recomputed LLRs do not cover"), "{reason}");
}

/// A syndrome changed in flight decodes to other bits (or none): the tags differ and neither
/// store holds a key.
#[test]
fn a_changed_syndrome_leaves_no_key_on_either_side() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (pool, llrs) = soft_sessions(6, 0.5, &mut rng);
    let mut pair = Pair::with_views(ldpc(weak_eve()), &pool, &[], &[], &llrs);
    let Some(Message::Syndrome {
        block,
        round,
        mut syndrome,
    }) = pair.lose_next(|m| matches!(m, Message::Syndrome { .. }))
    else {
        panic!("no syndrome was sent");
    };
    for i in (0..syndrome.len()).step_by(7) {
        syndrome[i] = !syndrome[i];
    }
    pair.to_controller.push_front(Message::Syndrome {
        block,
        round,
        syndrome,
    });
    assert!(pair.settle(100_000, None));
    let first = |keys: &[FinalKey]| keys.iter().any(|k| k.block == block);
    assert!(!first(&pair.controller_keys) && !first(&pair.robot_keys));
    let report = pair.reports.iter().find(|r| r.block == block).unwrap();
    assert_eq!(report.length, 0, "{report:?}");
    pair.assert_same_keys("after a changed syndrome");
}

#[test]
fn ldpc_refuses_sessions_without_llrs_by_name() {
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let pool = sessions(1, 0.02, &mut rng);
    let mut controller = ControllerPost::new(ldpc(weak_eve()), [1; 32]).unwrap();
    let session = |llrs: Vec<f64>| ControllerInput::Session {
        id: pool[0].0,
        bits: pool[0].2.clone(),
        separations: Vec::new(),
        samples: SessionSamples::new(),
        llrs,
    };
    let refused = controller.handle_input(session(Vec::new())).unwrap_err();
    assert!(refused.to_string().contains("ldpc"), "{refused}");
    let short = controller.handle_input(session(vec![1.0; 3])).unwrap_err();
    assert!(matches!(short, PostError::Llrs { .. }), "{short}");
    assert!(controller.snapshot().pool.is_empty());
}

#[test]
fn the_robot_refuses_syndrome_requests_an_honest_controller_never_sends() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let (pool, llrs) = soft_sessions(6, 0.5, &mut rng);
    let mut pair = Pair::with_views(ldpc(weak_eve()), &pool, &[], &[], &llrs);
    while !matches!(pair.to_robot.front(), Some(Message::SyndromeAsk { .. })) {
        assert!(pair.deliver(None));
    }
    let Some(Message::SyndromeAsk {
        block,
        syndrome_bits,
        bhattacharyya,
        ..
    }) = pair.to_robot.pop_front()
    else {
        unreachable!()
    };
    let ask = |round, syndrome_bits, bhattacharyya| Message::SyndromeAsk {
        block,
        round,
        syndrome_bits,
        bhattacharyya,
    };
    for bad in [
        ask(1, 0, bhattacharyya),
        ask(1, u32::MAX, bhattacharyya),
        ask(1, syndrome_bits, 0),
        ask(1, syndrome_bits, 1025),
        ask(2, syndrome_bits, bhattacharyya),
    ] {
        pair.robot.handle_input(RobotInput::Frame(bad)).unwrap();
        pair.collect();
        assert!(
            matches!(
                pair.to_controller.pop_back(),
                Some(Message::Reject {
                    reason: RejectReason::BadQuestions,
                    ..
                })
            ),
            "a dishonest request was answered"
        );
    }
    // The honest first round is answered; then feedback beyond the agreed two rounds, or
    // with another m, is refused.
    pair.robot
        .handle_input(RobotInput::Frame(ask(1, syndrome_bits, bhattacharyya)))
        .unwrap();
    pair.collect();
    assert!(matches!(
        pair.to_controller.pop_back(),
        Some(Message::Syndrome { round: 1, .. })
    ));
    for bad in [
        ask(2, syndrome_bits + 1, bhattacharyya),
        ask(4, syndrome_bits, bhattacharyya),
    ] {
        pair.robot.handle_input(RobotInput::Frame(bad)).unwrap();
        pair.collect();
        assert!(matches!(
            pair.to_controller.pop_back(),
            Some(Message::Reject {
                reason: RejectReason::BadQuestions,
                ..
            })
        ));
    }
    assert!(pair.robot_keys.is_empty());
}

/// LDPC over a lossy, duplicating, reordering channel: repeated `SyndromeAsk`s get the same
/// syndrome, stale ones are ignored, and both sides end with the same keys.
#[test]
fn ldpc_over_a_faulty_channel_never_splits_the_keys() {
    let mut rng = ChaCha8Rng::seed_from_u64(10);
    let mut committed = 0;
    for trial in 0..12 {
        let (pool, llrs) = soft_sessions(rng.random_range(8..14), 0.5, &mut rng);
        let faults = Faults {
            drop: rng.random_range(0.1..0.3),
            duplicate: 0.1,
            reorder: 0.1,
        };
        let mut pair = Pair::with_views(ldpc(weak_eve()), &pool, &[], &[], &llrs);
        let mut channel = ChaCha8Rng::seed_from_u64(2000 + trial);
        assert!(
            pair.settle(200_000, Some((faults, &mut channel))),
            "trial {trial} did not settle"
        );
        pair.assert_same_keys(&format!("trial {trial}"));
        committed += pair.controller_keys.len();
    }
    assert!(committed >= 6, "only {committed} keys over 12 trials");
}

/// A crash of either side at every message boundary of LDPC blocks, restarting from the last
/// stored snapshot (the controller's LLRs restored from it), never leaves one side with a key
/// the other lacks.
#[test]
fn ldpc_with_a_crash_at_any_message_boundary_never_splits_the_keys() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (pool, llrs) = soft_sessions(14, 0.5, &mut rng);
    let new = || Pair::with_views(ldpc(weak_eve()), &pool, &[], &[], &llrs);
    let mut reference = new();
    assert!(reference.settle(100_000, None));
    let boundaries = reference.delivered;
    assert!(
        reference.controller_keys.len() >= 2,
        "{:?}",
        reference.reports
    );
    crash_at_every_boundary(boundaries, new);
}
