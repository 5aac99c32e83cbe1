//! The endpoints against each other: lossless, over a lossy channel, and with a crash
//! injected at every message boundary.

use std::collections::VecDeque;

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};

use super::controller::ControllerInput;
use super::robot::RobotInput;
use super::*;

fn settings(assumption: Assumption) -> Settings {
    Settings {
        block_bits: 2_000,
        sample_bits: 100,
        epsilon: 1e-6,
        schedule: CascadeSchedule::BICONF,
        assumption,
        reconciliation: ReconciliationMethod::Cascade,
    }
}

fn weak_eve() -> Assumption {
    Assumption::IndependentErrors { error_rate: 0.3 }
}

/// Sessions of 300–700 bits; the controller's copy has errors at rate `q`.
fn sessions(count: u32, q: f64, rng: &mut ChaCha8Rng) -> Vec<(u32, BitString, BitString)> {
    (0..count)
        .map(|id| {
            let n = rng.random_range(300..700);
            let robot = BitString::random(n, rng);
            let mut controller = robot.clone();
            for i in 0..n {
                if rng.random::<f64>() < q {
                    controller.flip(i).unwrap();
                }
            }
            (id, robot, controller)
        })
        .collect()
}

/// Faults of the channel: each message is dropped, duplicated or delayed (reordered) with
/// these probabilities.
#[derive(Clone, Copy)]
struct Faults {
    drop: f64,
    duplicate: f64,
    reorder: f64,
}

/// The two endpoints, the messages between them, and their last stored snapshots.
struct Pair {
    settings: Settings,
    controller: ControllerPost,
    robot: RobotPost,
    controller_snapshot: ControllerSnapshot,
    robot_snapshot: RobotSnapshot,
    to_robot: VecDeque<Message>,
    to_controller: VecDeque<Message>,
    reports: Vec<BlockReport>,
    /// The key stores: a committed key is stored with the snapshot of its batch.
    controller_keys: Vec<FinalKey>,
    robot_keys: Vec<FinalKey>,
    delivered: usize,
    restarts: u8,
    /// The shell's answer when the controller asks for the plant's estimate (measured
    /// sizing), and the requests it asked.
    estimate: EstimateOutcome,
    requests: Vec<EstimateRequest>,
    robot_reports: Vec<BlockReport>,
    /// LLRs recomputed at block time: the shell's LLRs of each session (by ID; none: it
    /// answers with none), and the requests the controller asked.
    recomputed: Vec<Vec<f64>>,
    llr_requests: Vec<LlrRequest>,
}

impl Pair {
    fn new(settings: Settings, pool: &[(u32, BitString, BitString)]) -> Self {
        Self::with_separations(settings, pool, &[], &[])
    }

    /// [`Self::new`] with each session's per-bit Eve separations (none for a session past
    /// the list) and sessions the robot lacks.
    fn with_separations(
        settings: Settings,
        pool: &[(u32, BitString, BitString)],
        separations: &[Vec<f64>],
        robot_lacks: &[u32],
    ) -> Self {
        Self::with_views(settings, pool, separations, robot_lacks, &[])
    }

    /// [`Self::with_separations`] with each session's controller LLRs (none for a session
    /// past the list).
    fn with_views(
        settings: Settings,
        pool: &[(u32, BitString, BitString)],
        separations: &[Vec<f64>],
        robot_lacks: &[u32],
        llrs: &[Vec<f64>],
    ) -> Self {
        let controller = ControllerPost::new(settings.clone(), [1; 32]).unwrap();
        let mut robot = RobotPost::new(settings.clone(), [2; 32]).unwrap();
        // The robot learns of its sessions first, as on the network.
        for (id, reference, _) in pool.iter().filter(|s| !robot_lacks.contains(&s.0)) {
            robot
                .handle_input(RobotInput::Session {
                    id: *id,
                    bits: reference.clone(),
                })
                .unwrap();
        }
        let robot_snapshot = robot.snapshot();
        let controller_snapshot = controller.snapshot();
        let mut pair = Self {
            settings,
            controller,
            robot,
            controller_snapshot,
            robot_snapshot,
            to_robot: VecDeque::new(),
            to_controller: VecDeque::new(),
            reports: Vec::new(),
            controller_keys: Vec::new(),
            robot_keys: Vec::new(),
            delivered: 0,
            restarts: 0,
            estimate: Ok(0),
            requests: Vec::new(),
            robot_reports: Vec::new(),
            recomputed: Vec::new(),
            llr_requests: Vec::new(),
        };
        pair.collect();
        for (i, (id, _, bits)) in pool.iter().enumerate() {
            pair.controller
                .handle_input(ControllerInput::Session {
                    id: *id,
                    bits: bits.clone(),
                    separations: separations.get(i).cloned().unwrap_or_default(),
                    samples: SessionSamples::new(),
                    llrs: llrs.get(i).cloned().unwrap_or_default(),
                })
                .unwrap();
            pair.collect();
        }
        pair
    }

    /// Takes every output of both endpoints: transmissions queue, snapshots are stored.
    fn collect(&mut self) {
        while let Some(output) = self.controller.poll_output() {
            match output {
                Output::Transmit(m) => self.to_robot.push_back(m),
                Output::Persist => self.controller_snapshot = self.controller.snapshot(),
                Output::BlockEnded(report) => self.reports.push(report),
                Output::KeyCommitted(key) => self.controller_keys.push(key),
                Output::EstimateNeeded(request) => {
                    let block = request.block;
                    self.requests.push(request);
                    self.controller
                        .handle_input(ControllerInput::Estimate {
                            block,
                            outcome: self.estimate.clone(),
                        })
                        .unwrap();
                }
                Output::LlrsNeeded(request) => {
                    let llrs = request
                        .sessions
                        .iter()
                        .map(|(id, ..)| self.recomputed.get(*id as usize).cloned())
                        .collect::<Option<Vec<_>>>()
                        .map(|l| RecomputedLlrs {
                            model: "measured".into(),
                            llrs: l.concat(),
                        })
                        .ok_or_else(|| "a session without recomputed LLRs".to_owned());
                    let block = request.block;
                    self.llr_requests.push(*request);
                    self.controller
                        .handle_input(ControllerInput::Llrs { block, llrs })
                        .unwrap();
                }
                Output::Ignored(_)
                | Output::SliceReconciled(_)
                | Output::SlicesEstimateNeeded(_) => {}
            }
        }
        while let Some(output) = self.robot.poll_output() {
            match output {
                Output::Transmit(m) => self.to_controller.push_back(m),
                Output::Persist => self.robot_snapshot = self.robot.snapshot(),
                Output::KeyCommitted(key) => self.robot_keys.push(key),
                Output::BlockEnded(report) => self.robot_reports.push(report),
                Output::Ignored(_)
                | Output::EstimateNeeded(_)
                | Output::LlrsNeeded(_)
                | Output::SliceReconciled(_)
                | Output::SlicesEstimateNeeded(_) => {}
            }
        }
    }

    /// Delivers one message (the robot's first), through `faults` if given; false when
    /// nothing is in flight.
    fn deliver(&mut self, faults: Option<(Faults, &mut ChaCha8Rng)>) -> bool {
        let (queue, to_robot) = if self.to_controller.is_empty() {
            (&mut self.to_robot, true)
        } else {
            (&mut self.to_controller, false)
        };
        let Some(message) = queue.pop_front() else {
            return false;
        };
        if let Some((f, rng)) = faults {
            if rng.random::<f64>() < f.drop {
                return true;
            }
            if rng.random::<f64>() < f.reorder && !queue.is_empty() {
                let at = rng.random_range(1..=queue.len());
                queue.insert(at, message);
                return true;
            }
            if rng.random::<f64>() < f.duplicate {
                queue.push_back(message.clone());
            }
        }
        self.delivered += 1;
        if to_robot {
            self.robot.handle_input(RobotInput::Frame(message)).unwrap();
        } else {
            self.controller
                .handle_input(ControllerInput::Frame(message))
                .unwrap();
        }
        self.collect();
        self.assert_settled_keys_held_by_both("after a delivery");
        true
    }

    /// The block whose key the controller committed and the robot has not acknowledged.
    fn controller_pending(&self) -> Option<u64> {
        match self.controller_snapshot.in_flight {
            Some(InFlight::Committed { block, .. }) => Some(block),
            _ => None,
        }
    }

    /// The keys each side's store would deliver: the robot's committed keys, and the
    /// controller's but the one whose `CommitAck` is outstanding (pending).
    fn settled(&self) -> (Vec<&FinalKey>, Vec<&FinalKey>) {
        let pending = self.controller_pending();
        let controller = self
            .controller_keys
            .iter()
            .filter(|k| Some(k.block) != pending)
            .collect();
        (controller, self.robot_keys.iter().collect())
    }

    /// At every moment, a key one side would deliver is held by the other — settled, or
    /// pending there: neither side ever delivers a key the other may lack.
    fn assert_settled_keys_held_by_both(&self, what: &str) {
        let (controller, robot) = self.settled();
        for key in controller {
            assert!(
                self.robot_keys.contains(key),
                "{what}: the controller delivers key {} the robot lacks",
                key.id
            );
        }
        let robot_prepared = self.robot_snapshot.prepared.as_ref().map(|p| &p.key);
        for key in robot {
            assert!(
                self.controller_keys.contains(key),
                "{what}: the robot delivers key {} the controller lacks",
                key.id
            );
        }
        if let Some(prepared) = robot_prepared {
            assert!(!self.robot_keys.contains(prepared), "{what}");
        }
    }

    /// Runs until both sides are quiet and no block is in flight (the controller's timer
    /// fires whenever nothing is in flight); false if `steps` did not suffice.
    fn settle(&mut self, steps: usize, mut faults: Option<(Faults, &mut ChaCha8Rng)>) -> bool {
        for _ in 0..steps {
            let delivered = match faults.as_mut() {
                Some((f, rng)) => self.deliver(Some((*f, &mut **rng))),
                None => self.deliver(None),
            };
            if !delivered {
                if self.controller.is_idle() {
                    return true;
                }
                self.controller
                    .handle_input(ControllerInput::Timeout)
                    .unwrap();
                self.collect();
            }
        }
        false
    }

    fn crash_controller(&mut self) {
        self.restarts += 1;
        self.controller = ControllerPost::restore(
            self.controller_snapshot.clone(),
            self.settings.clone(),
            [10 + self.restarts; 32],
        )
        .unwrap();
        self.collect();
        self.assert_settled_keys_held_by_both("after a controller restart");
    }

    fn crash_robot(&mut self) {
        self.restarts += 1;
        self.robot = RobotPost::restore(
            self.robot_snapshot.clone(),
            self.settings.clone(),
            [20 + self.restarts; 32],
        )
        .unwrap();
        self.collect();
        self.assert_settled_keys_held_by_both("after a robot restart");
    }

    /// A later session after messages were lost: both endpoints restarted from their stores
    /// (`restart`), or the controller's timer (`timer`); it must settle every key alike.
    fn later_session(&mut self, later: &str) {
        if later == "restart" {
            self.crash_robot();
            self.crash_controller();
        } else {
            self.controller
                .handle_input(ControllerInput::Timeout)
                .unwrap();
            self.collect();
        }
        assert!(self.settle(100_000, None), "{later}");
        self.assert_same_keys(later);
    }

    /// Delivers until the next message in flight is one `is_it` picks, and returns it, taken
    /// off the channel (lost); `None` if the exchange ended first.
    fn lose_next(&mut self, is_it: impl Fn(&Message) -> bool) -> Option<Message> {
        loop {
            let next = self.to_controller.front().or(self.to_robot.front())?;
            if is_it(next) {
                return match self.to_controller.front() {
                    Some(_) => self.to_controller.pop_front(),
                    None => self.to_robot.pop_front(),
                };
            }
            self.deliver(None);
        }
    }

    /// The key stores of both sides hold the same keys (IDs, blocks, bits), and each
    /// side's durable state names exactly the blocks of its stored keys.
    fn assert_same_keys(&self, what: &str) {
        let ids = |keys: &[FinalKey]| -> Vec<(String, u64, BitString)> {
            keys.iter()
                .map(|k| (k.id.clone(), k.block, k.key.clone()))
                .collect()
        };
        assert_eq!(
            ids(&self.controller_keys),
            ids(&self.robot_keys),
            "{what}: the committed keys differ"
        );
        let blocks = |keys: &[FinalKey]| keys.iter().map(|k| k.block).collect::<Vec<_>>();
        assert_eq!(
            self.controller_snapshot.committed,
            blocks(&self.controller_keys),
            "{what}"
        );
        assert_eq!(
            self.robot_snapshot.committed,
            blocks(&self.robot_keys),
            "{what}"
        );
        // Settled: nothing is left pending on either side.
        assert_eq!(self.controller_pending(), None, "{what}");
        assert!(self.robot_snapshot.prepared.is_none(), "{what}");
    }
}

#[test]
fn both_sides_commit_the_same_keys_on_random_pools() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut committed = 0;
    for trial in 0..12 {
        let q = rng.random_range(0.0..0.06);
        let pool = sessions(rng.random_range(6..20), q, &mut rng);
        let mut pair = Pair::new(settings(weak_eve()), &pool);
        assert!(pair.settle(100_000, None), "trial {trial} did not settle");
        pair.assert_same_keys(&format!("trial {trial}"));
        committed += pair.controller_keys.len();
        for report in &pair.reports {
            // Everything public is charged: both sides' parities and both tags.
            assert_eq!(report.leak_ec, 2 * report.questions);
            assert!(report.sample_bits <= 100 && report.sample_bits <= report.bits / 10);
            assert_eq!(report.reconciled_bits, report.bits - report.sample_bits);
            if report.length > 0 {
                assert_eq!(report.leak_confirmation, 128);
            }
        }
        // Every session that entered a block is spent on both sides.
        let proposed: usize = pair.reports.iter().map(|r| r.sessions.len()).sum();
        assert!(pair.robot.snapshot().spent.len() >= proposed);
    }
    assert!(committed >= 12, "only {committed} keys over 12 trials");
}

#[test]
fn no_key_without_secrecy() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let pool = sessions(10, 0.01, &mut rng);
    let assumption = Assumption::NoSecrecy {
        reason: "Eve can learn the model".into(),
    };
    let mut pair = Pair::new(settings(assumption), &pool);
    assert!(pair.settle(100_000, None));
    assert!(pair.controller_keys.is_empty() && pair.robot_keys.is_empty());
    assert!(!pair.reports.is_empty());
    for report in &pair.reports {
        assert_eq!(report.length, 0);
        assert!(
            report
                .reason
                .as_deref()
                .unwrap()
                .contains("Eve can learn the model"),
            "{report:?}"
        );
    }
    // The sessions are spent: nothing is left to pool.
    assert!(pair.controller.snapshot().pool.len() < 4);
}

/// A lossy, duplicating, reordering channel never makes the two sides commit different
/// keys. 40 seeded trials, 10–30 % loss, 10 % duplication, 10 % reordering.
#[test]
fn a_faulty_channel_never_splits_the_keys() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut committed = 0;
    for trial in 0..40 {
        let pool = sessions(rng.random_range(5..12), 0.03, &mut rng);
        let faults = Faults {
            drop: rng.random_range(0.1..0.3),
            duplicate: 0.1,
            reorder: 0.1,
        };
        let mut pair = Pair::new(settings(weak_eve()), &pool);
        let mut channel = ChaCha8Rng::seed_from_u64(1000 + trial);
        assert!(
            pair.settle(200_000, Some((faults, &mut channel))),
            "trial {trial} did not settle"
        );
        pair.assert_same_keys(&format!("trial {trial}"));
        committed += pair.controller_keys.len();
    }
    assert!(committed >= 20, "only {committed} keys over 40 trials");
}

/// A crash of either side at every message boundary of a session with several blocks,
/// restarting from the last stored snapshot, never leaves one side with a committed key the
/// other lacks.
#[test]
fn a_crash_at_any_message_boundary_never_splits_the_keys() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let pool = sessions(14, 0.03, &mut rng);
    let mut reference = Pair::new(settings(weak_eve()), &pool);
    assert!(reference.settle(100_000, None));
    let boundaries = reference.delivered;
    assert!(boundaries > 30, "{boundaries}");
    assert!(reference.controller_keys.len() >= 2);
    let trials = crash_at_every_boundary(boundaries, || Pair::new(settings(weak_eve()), &pool));
    println!("{trials} crash trials over {} boundaries", boundaries + 1);
}

/// Crashes the controller, the robot or both at each of the first `boundaries` + 1 message
/// boundaries of the exchange `new` starts, restarting from the last stored snapshots; every
/// run must settle with the same keys on both sides. Returns the trials.
fn crash_at_every_boundary(boundaries: usize, new: impl Fn() -> Pair) -> usize {
    let mut trials = 0;
    for crash_at in 0..=boundaries {
        for side in ["controller", "robot", "both"] {
            let mut pair = new();
            while pair.delivered < crash_at && pair.deliver(None) {}
            match side {
                "controller" => pair.crash_controller(),
                "robot" => pair.crash_robot(),
                _ => {
                    pair.crash_robot();
                    pair.crash_controller();
                }
            }
            assert!(
                pair.settle(100_000, None),
                "{side} crash at {crash_at} did not settle"
            );
            pair.assert_same_keys(&format!("{side} crash at boundary {crash_at}"));
            trials += 1;
        }
    }
    trials
}

#[test]
fn the_robot_refuses_what_an_honest_controller_never_sends() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let pool = sessions(6, 0.02, &mut rng);
    let mut pair = Pair::new(settings(weak_eve()), &pool);
    // Let the block reach reconciliation, then inject nonsense.
    while !matches!(pair.to_robot.front(), Some(Message::Ask { .. })) {
        assert!(pair.deliver(None));
    }
    let block = pair.to_robot.front().unwrap().block();
    let nonsense = [
        Message::Ask {
            block,
            round: 1,
            queries: vec![crate::cascade::BlockQuery {
                permutation: 7,
                start: 0,
                end: 10,
            }],
        },
        Message::Confirm {
            block,
            length: 5,
            tag: [0; 8],
            estimate: None,
        },
        Message::Commit { block: block + 1 },
        Message::Agree {
            block,
            sessions: vec![],
            nonce: [0; 32],
            sample: vec![],
        },
    ];
    for message in nonsense {
        pair.robot.handle_input(RobotInput::Frame(message)).unwrap();
    }
    assert!(pair.robot_keys.is_empty());
    // Forged replies to the controller change nothing either.
    pair.controller
        .handle_input(ControllerInput::Frame(Message::CommitAck { block: 99 }))
        .unwrap();
    // The robot's refusals reach the controller, which aborts the block; all ends
    // consistently.
    pair.collect();
    assert!(pair.settle(100_000, None));
    pair.assert_same_keys("after injected messages");
}

/// The robot finding the controller's tag wrong means reconciliation left the keys different:
/// the controller aborts for that reason (so nobody advises pooling more), not as a refusal.
#[test]
fn a_tag_mismatch_seen_by_the_robot_aborts_as_failed_reconciliation() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let pool = sessions(6, 0.02, &mut rng);
    let mut pair = Pair::new(settings(weak_eve()), &pool);
    while !matches!(pair.to_robot.front(), Some(Message::Confirm { .. })) {
        assert!(pair.deliver(None));
    }
    let block = pair.to_robot.pop_front().unwrap().block();
    pair.controller
        .handle_input(ControllerInput::Frame(Message::Reject {
            block,
            reason: RejectReason::TagMismatch,
        }))
        .unwrap();
    pair.collect();
    assert!(
        pair.to_robot.iter().any(|m| matches!(
            m,
            Message::Abort {
                reason: AbortReason::Reconciliation,
                ..
            }
        )),
        "{:?}",
        pair.to_robot
    );
}

/// The `Commit` lost, and every retransmission of it until the session ends: the controller's
/// key is pending, the robot's key prepared (pending) and not committed; neither delivers
/// it. A later session — the controller restarted from its store, or its timer — repeats the
/// `Commit` and settles both.
#[test]
fn a_lost_commit_leaves_both_keys_pending_until_a_later_session_settles_them() {
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let pool = sessions(8, 0.02, &mut rng);
    for later in ["restart", "timer"] {
        let mut pair = Pair::new(settings(weak_eve()), &pool);
        let lost = pair.lose_next(|m| matches!(m, Message::Commit { .. }));
        let block = lost.expect("a block reaches its commit").block();
        // Its retransmissions are lost too: the session ends here.
        for _ in 0..3 {
            pair.controller
                .handle_input(ControllerInput::Timeout)
                .unwrap();
            pair.collect();
            pair.to_robot.clear();
        }
        assert_eq!(pair.controller_pending(), Some(block));
        assert!(pair.settled().0.is_empty() && pair.settled().1.is_empty());
        assert_eq!(pair.controller_keys.len(), 1);
        assert_eq!(
            pair.robot_snapshot.prepared.as_ref().map(|p| p.block),
            Some(block)
        );
        assert_eq!(pair.robot.block_in_flight(), Some(block));
        pair.later_session(later);
        assert_eq!(pair.robot.block_in_flight(), None);
    }
}

/// The `CommitAck` lost: the robot's key is settled, the controller's pending until a later
/// `Commit` — after a restart or on its timer — draws the acknowledgement again.
#[test]
fn a_lost_commit_ack_leaves_the_controllers_key_pending_until_a_later_session() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let pool = sessions(8, 0.02, &mut rng);
    for later in ["restart", "timer"] {
        let mut pair = Pair::new(settings(weak_eve()), &pool);
        let lost = pair.lose_next(|m| matches!(m, Message::CommitAck { .. }));
        let block = lost.expect("a block reaches its acknowledgement").block();
        assert_eq!(pair.controller_pending(), Some(block));
        let (controller, robot) = pair.settled();
        assert!(controller.is_empty());
        assert_eq!(robot.len(), 1);
        assert_eq!(pair.robot.block_in_flight(), None);
        pair.later_session(later);
    }
}

/// The robot answers at most [`super::robot::max_rounds`] question rounds beyond the parities
/// already revealed, and never more parities than the block has bits. Honest schedules stay
/// within it at every error rate and size tried, so only a controller that asks more than an
/// honest one could is refused.
#[test]
fn honest_schedules_stay_within_the_robots_bound_on_questions() {
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    for schedule in [CascadeSchedule::ORIGINAL, CascadeSchedule::BICONF] {
        for q in [0.005, 0.02, 0.05, 0.1, 0.2] {
            for block_bits in [2_000, 20_000] {
                let settings = Settings {
                    block_bits,
                    schedule,
                    ..settings(weak_eve())
                };
                let pool = sessions((block_bits / 300 + 2) as u32, q, &mut rng);
                let mut pair = Pair::new(settings, &pool);
                assert!(pair.settle(1_000_000, None), "{q} {block_bits}");
                for report in &pair.reports {
                    let refused = report
                        .reason
                        .as_deref()
                        .is_some_and(|why| why.contains("BadQuestions"));
                    assert!(
                        !refused,
                        "{schedule:?} at Q {q}, {block_bits} bits: {report:?}"
                    );
                }
            }
        }
    }
}

#[test]
fn a_controller_asking_beyond_an_honest_schedule_is_refused() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let pool = sessions(6, 0.02, &mut rng);
    let mut pair = Pair::new(settings(weak_eve()), &pool);
    while !matches!(pair.to_robot.front(), Some(Message::Ask { .. })) {
        assert!(pair.deliver(None));
    }
    let block = pair.to_robot.front().unwrap().block();
    pair.to_robot.clear();
    // Empty rounds reveal nothing and so allow nothing more than the bound for the block's
    // size (about 2,000 bits, the sample taken out).
    let (low, high) = (
        super::robot::max_rounds(1_000, &CascadeSchedule::BICONF),
        super::robot::max_rounds(4_000, &CascadeSchedule::BICONF),
    );
    let mut answered = 0;
    for round in 1..=high + 1 {
        let ask = Message::Ask {
            block,
            round,
            queries: Vec::new(),
        };
        pair.robot.handle_input(RobotInput::Frame(ask)).unwrap();
        while let Some(output) = pair.robot.poll_output() {
            match output {
                Output::Transmit(Message::Answer { .. }) => answered += 1,
                Output::Transmit(Message::Reject { reason, .. }) => {
                    assert_eq!(reason, RejectReason::BadQuestions);
                    assert!((low..=high).contains(&answered), "refused after {answered}");
                    return;
                }
                _ => {}
            }
        }
    }
    panic!("{answered} rounds answered, the bound is at most {high}");
}

fn measured_plant() -> Assumption {
    Assumption::MeasuredViews {
        separation: 0.0,
        statement: "test".into(),
        estimation_epsilon: 1e-6,
        estimate_leak: 16.000_045,
    }
}

/// With the plant measured the controller asks its shell after reconciliation, with the
/// robot's bits of each session (the disclosed sample put back); `Confirm` carries the
/// published separation and the robot recomputes ℓ from it: the same key and record on both
/// sides, 5ε-secret with ε_est named.
#[test]
fn a_measured_plant_is_carried_in_confirm_and_both_sides_size_the_same_key() {
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let pool = sessions(10, 0.02, &mut rng);
    let mut pair = Pair::new(settings(measured_plant()), &pool);
    pair.estimate = Ok(436);
    assert!(pair.settle(100_000, None));
    pair.assert_same_keys("measured");
    assert!(!pair.controller_keys.is_empty());
    for request in &pair.requests {
        for (id, _, bits) in &request.sessions {
            let robot = &pool.iter().find(|s| s.0 == *id).unwrap().1;
            assert_eq!(
                bits, robot,
                "session {id}: the robot's bits, sample put back"
            );
        }
    }
    let expected = measured_plant().with_estimate(436);
    for (report, key) in pair.reports.iter().zip(&pair.controller_keys) {
        assert_eq!(report.separation_steps, Some(436));
        let (_, length) =
            expected.output_length(report.reconciled_bits as u64, report.leak_ec, 1e-6);
        assert_eq!(report.length, length.bits);
        assert!((key.epsilon - 5e-6).abs() < 1e-18);
        assert_eq!(key.assumption, expected.describe());
    }
    for key in &pair.robot_keys {
        assert_eq!(key.assumption, expected.describe());
    }
}

/// A refused estimate commits nothing on either side; both reports name the refusal.
#[test]
fn a_refused_estimate_commits_nothing_and_both_reports_say_so() {
    let mut rng = ChaCha8Rng::seed_from_u64(22);
    let pool = sessions(6, 0.02, &mut rng);
    let mut pair = Pair::new(settings(measured_plant()), &pool);
    pair.estimate = Err(EstimateRefusal("not white: statistic 9.1".into()));
    assert!(pair.settle(100_000, None));
    let robot_reports = &pair.robot_reports;
    assert!(pair.controller_keys.is_empty() && pair.robot_keys.is_empty());
    assert!(!pair.reports.is_empty() && !robot_reports.is_empty());
    for report in &pair.reports {
        assert_eq!(report.length, 0);
        assert_eq!(
            report.reason.as_deref(),
            Some("block refused: not white: statistic 9.1")
        );
    }
    for report in robot_reports {
        assert!(
            report
                .reason
                .as_deref()
                .unwrap()
                .starts_with("block refused")
        );
    }
}

/// The robot refuses a `Confirm` whose estimate does not give the proposed ℓ (tampered), or
/// that carries none with the plant measured.
#[test]
fn the_robot_refuses_a_confirm_whose_estimate_does_not_size_its_length() {
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    let pool = sessions(10, 0.02, &mut rng);
    for forged in [Some(0), None, Some(MAX_SEPARATION_STEPS + 1)] {
        let mut pair = Pair::new(settings(measured_plant()), &pool);
        pair.estimate = Ok(436);
        while !matches!(pair.to_robot.front(), Some(Message::Confirm { .. })) {
            assert!(pair.deliver(None));
        }
        if let Some(Message::Confirm { estimate, .. }) = pair.to_robot.front_mut() {
            *estimate = forged;
        }
        assert!(pair.deliver(None));
        assert!(
            matches!(
                pair.to_controller.front(),
                Some(Message::Reject {
                    reason: RejectReason::LengthMismatch,
                    ..
                })
            ),
            "{forged:?}: {:?}",
            pair.to_controller.front()
        );
        assert!(pair.settle(100_000, None));
        pair.assert_same_keys("a forged estimate");
    }
}

/// Per-bit separations (most bits seen at 0.5, every tenth at 1.5): both sides commit the
/// same keys, longer than when every bit is sized at the largest separation, each no longer
/// than the per-bit bound of its reconciled bits allows; a robot holding only some of the
/// sessions gets the block aborted, not sized for bits it lacks.
#[test]
fn per_bit_separations_size_both_sides_alike() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let pool = sessions(8, 0.01, &mut rng);
    let gaussian = Assumption::GaussianViews {
        separation: 0.0,
        statement: "test".into(),
    };
    let per_bit: Vec<Vec<f64>> = pool
        .iter()
        .map(|(_, r, _)| {
            (0..r.len())
                .map(|i| if i % 10 == 0 { 1.5 } else { 0.5 })
                .collect()
        })
        .collect();
    let largest: Vec<Vec<f64>> = pool.iter().map(|_| vec![1.5]).collect();
    let run = |separations: &[Vec<f64>]| {
        let mut pair = Pair::with_separations(settings(gaussian.clone()), &pool, separations, &[]);
        assert!(pair.settle(100_000, None));
        assert_eq!(pair.controller_keys, pair.robot_keys);
        assert!(!pair.controller_keys.is_empty());
        pair
    };
    let (sized, at_largest) = (run(&per_bit), run(&largest));
    let bits = |pair: &Pair| -> usize { pair.controller_keys.iter().map(|k| k.key.len()).sum() };
    assert!(
        bits(&sized) > bits(&at_largest),
        "{} ≤ {}",
        bits(&sized),
        bits(&at_largest)
    );
    for report in sized.reports.iter().filter(|r| r.length > 0) {
        // Its bits at 1.5 (the first of every ten of each session); its sample may have
        // removed only 0.5s.
        let high: u64 = report
            .sessions
            .iter()
            .map(|id| {
                pool.iter()
                    .find(|s| s.0 == *id)
                    .unwrap()
                    .1
                    .len()
                    .div_ceil(10) as u64
            })
            .sum();
        let low = report.reconciled_bits as u64 - high;
        let groups = [
            crate::view_profile::ViewGroup {
                view: crate::view_profile::BitView::Gaussian { separation: 0.5 },
                bits: low,
            },
            crate::view_profile::ViewGroup {
                view: crate::view_profile::BitView::Gaussian { separation: 1.5 },
                bits: high,
            },
        ];
        let bound = crate::view_profile::profile_smooth_min_entropy(&groups, 1e-6)
            .unwrap()
            .h_min;
        assert!(report.h_min <= bound, "{} > {bound}", report.h_min);
    }
    let mut partial =
        Pair::with_separations(settings(gaussian.clone()), &pool, &per_bit, &[pool[0].0]);
    partial.settle(100_000, None);
    let refused = partial.reports.first().and_then(|r| r.reason.clone());
    assert!(
        refused
            .as_deref()
            .is_some_and(|r| r.contains("only some of the proposed sessions")),
        "{refused:?}"
    );
}

mod ldpc;
