//! A controller whose block-time estimate of the plant is slow, on the virtual network: the
//! estimate runs between the block's reconciliation and its `Confirm`, while the robot lingers
//! with the block in flight. Computed inline, its duration is modelled by holding the
//! controller (no input, its sends held back) for that long of virtual time, as a shell
//! computing it synchronously does; deferred (`PostLink::deferring`, the agents' worker
//! thread), the connection takes input and fires its timers meanwhile and the answer comes
//! that much later. Longer than the silence timeout but shorter than the robot's block
//! timeout, both stores get the same key; longer than the block timeout, the robot leaves
//! an inline controller first and neither side keys, while a deferring controller keeps it
//! waiting (it repeats its last fragment, 6 times per block timeout) and both key.

use std::collections::{BTreeSet, VecDeque};
use std::time::Duration;

use rand::SeedableRng;
use rand::rngs::ChaCha20Rng;
use robokey::Config;
use robokey::connection::{
    Computed, ControllerAction, ControllerConnection, Output, PostLink, PostOutput, RobotAction,
    RobotConnection, Setup,
};
use robokey::pair::{Connected, Ending, Pair, Peer, Polled, Surroundings};
use robokey::post_settings::post_settings;
use robokey::protocol::auth::PairingSecret;
use robokey::protocol::{SessionPlan, Time, Timing};
use robokey::rng::{Purpose, stream};
use robokey::world::WorldPlant;
use robokey_secrecy::postprocess::{ControllerPost, FinalKey, RobotPost};
use support::{Address, ControllerSide, RobotSide, connection_plant, drive_plant};

mod support;

/// The controller with its estimates taking `compute` of virtual time. Inline: from the
/// moment it reports one, it takes no input and its sends wait until the computation ends;
/// then they leave, what arrived meanwhile is delivered, and its timers run. Deferred: its
/// link hands the computation out, which answers `compute` after it was taken, the
/// connection live meanwhile.
struct SlowController {
    inner: ControllerSide,
    compute: Duration,
    /// Whether its link defers the computation.
    deferred: bool,
    /// The time of the last input.
    now: Time,
    busy_until: Option<Time>,
    held: VecDeque<Vec<u8>>,
    released: VecDeque<Vec<u8>>,
    arrived: Vec<Vec<u8>>,
    estimates: u32,
    /// Deferred: the computation's answer and when it comes.
    answer: Option<(Time, Computed)>,
    /// Deferred: the inputs (datagrams and timers) the connection took while computing.
    inputs_while_computing: u32,
    /// Deferred: the datagrams it sent while computing.
    sent_while_computing: u32,
}

impl SlowController {
    /// Deferred: takes the computation its link asks for, computes it now and holds the
    /// answer `compute` long.
    fn take_computation(&mut self) {
        if let Some(job) = self.inner.connection.take_computation() {
            self.answer = Some((self.now + self.compute, job.run()));
        }
    }
}

impl Peer for SlowController {
    type Datagram = Vec<u8>;
    type Output = ControllerAction<Address>;

    fn handle_datagram(&mut self, now: Time, bytes: &Vec<u8>) {
        self.now = now;
        self.inputs_while_computing += u32::from(self.answer.is_some());
        if self.busy_until.is_some() {
            self.arrived.push(bytes.clone());
        } else {
            self.inner.handle_datagram(now, bytes);
        }
    }

    fn handle_timeout(&mut self, now: Time) {
        self.now = now;
        if let Some((at, _)) = &self.answer {
            if now >= *at {
                let (_, computed) = self.answer.take().expect("an answer");
                self.inner.connection.handle_computed(now, computed);
            } else {
                self.inputs_while_computing += 1;
            }
        }
        if let Some(until) = self.busy_until {
            if now < until {
                return;
            }
            self.busy_until = None;
            self.released.extend(self.held.drain(..));
            for bytes in std::mem::take(&mut self.arrived) {
                self.inner.handle_datagram(now, &bytes);
            }
        }
        self.inner.handle_timeout(now);
    }

    fn poll_timeout(&self) -> Option<Time> {
        let answer = self.answer.as_ref().map(|(at, _)| *at);
        let inner = self.busy_until.or_else(|| self.inner.poll_timeout());
        [answer, inner].into_iter().flatten().min()
    }

    fn poll(&mut self) -> Option<Polled<Vec<u8>, Self::Output>> {
        if let Some(bytes) = self.released.pop_front() {
            return Some(Polled::Transmit(bytes));
        }
        self.take_computation();
        loop {
            match self.inner.poll()? {
                Polled::Output(Output::Post(PostOutput::Estimated(estimate))) => {
                    self.estimates += 1;
                    // Inline, the estimate was computed just now; deferred, its answer came.
                    if !self.deferred {
                        self.busy_until = Some(self.now + self.compute);
                    }
                    return Some(Polled::Output(Output::Post(PostOutput::Estimated(
                        estimate,
                    ))));
                }
                Polled::Transmit(bytes) if self.busy_until.is_some() => self.held.push_back(bytes),
                Polled::Transmit(bytes) => {
                    self.sent_while_computing += u32::from(self.answer.is_some());
                    return Some(Polled::Transmit(bytes));
                }
                other => return Some(other),
            }
        }
    }
}

/// The plant, and what each side committed, noted and whether it closed.
struct World {
    plant: WorldPlant,
    keys: [Vec<FinalKey>; 2],
    notes: Vec<String>,
    closed: [bool; 2],
}

impl Surroundings<RobotSide, SlowController> for World {
    fn robot_output(
        &mut self,
        now: Time,
        output: RobotAction<Address>,
        robot: &mut RobotSide,
        controller: &mut SlowController,
    ) {
        match output {
            Output::Endpoint(event) => {
                drive_plant(
                    &mut self.plant,
                    now,
                    event,
                    robot,
                    Some(&mut controller.inner),
                );
            }
            Output::Post(PostOutput::Persist { keys, .. }) => self.keys[0].extend(keys),
            Output::Closed => self.closed[0] = true,
            _ => {}
        }
    }

    fn controller_output(
        &mut self,
        _now: Time,
        output: ControllerAction<Address>,
        _robot: &mut RobotSide,
        _controller: &mut SlowController,
    ) {
        match output {
            Output::Post(PostOutput::Persist { keys, .. }) => self.keys[1].extend(keys),
            Output::Post(PostOutput::Note(note)) => self.notes.push(note),
            Output::Closed => self.closed[1] = true,
            _ => {}
        }
    }

    fn done(&self) -> bool {
        self.closed == [true; 2]
    }
}

/// Private sensing, the plant measured at block time, one session's bits a block (as the
/// agents' store tests), Eve's camera stated at 50 mm so that a block that small makes a key.
fn measured() -> Config {
    Config::from_toml(
        "[sensing]\nmode = \"private\"\n[postprocess]\nblock_bits = 300\nsizing = \"measured\"\n\
         [eve]\ncamera_std = [0.05, 0.05, 0.05]\n",
        "test",
    )
    .expect("a valid configuration")
}

/// One conversation with fresh stores, the controller's estimate taking `compute`, computed
/// inline or `deferred`: the pair, how it ended, and the world.
fn conversation(
    compute: Duration,
    deferred: bool,
) -> (Pair<RobotSide, SlowController>, Ending, World) {
    let config = measured();
    let seed = 7;
    let timing = Timing::default();
    let pairing = PairingSecret::generate(&mut stream(seed, Purpose::Key, 1));
    let setup = Setup {
        config: &config,
        pairing: &pairing,
        timing,
    };
    let settings = post_settings(&config);
    let robot_post = RobotPost::new(settings.clone(), [1; 32]).expect("valid settings");
    let controller_post = ControllerPost::new(settings, [2; 32]).expect("valid settings");
    let robot = RobotConnection::new(
        setup,
        Duration::from_secs(5),
        Some(PostLink::new(robot_post, BTreeSet::new(), &config)),
        ChaCha20Rng::seed_from_u64(seed),
        ChaCha20Rng::seed_from_u64(!seed),
        Time::ZERO,
    );
    let mut controller_link = PostLink::new(controller_post, BTreeSet::new(), &config);
    if deferred {
        controller_link = controller_link.deferring();
    }
    let controller = ControllerConnection::new(
        setup,
        Address::Robot,
        seed as u32,
        Some(controller_link),
        ChaCha20Rng::seed_from_u64(seed ^ 0x5eed),
        Time::ZERO,
    );
    let plan = SessionPlan::from_config(&config, 0);
    let mut world = World {
        plant: connection_plant(&config, seed),
        keys: [Vec::new(), Vec::new()],
        notes: Vec::new(),
        closed: [false; 2],
    };
    let mut pair = Pair::ideal(
        Connected {
            connection: robot,
            peer: Address::Controller,
        },
        SlowController {
            inner: Connected {
                connection: controller,
                peer: Address::Robot,
            },
            compute,
            deferred,
            now: Time::ZERO,
            busy_until: None,
            held: VecDeque::new(),
            released: VecDeque::new(),
            arrived: Vec::new(),
            estimates: 0,
            answer: None,
            inputs_while_computing: 0,
            sent_while_computing: 0,
        },
    );
    // The session, the estimate, and every timer after it, with room to spare.
    let limit = Duration::from_secs_f64(plan.agreed.sample_time * f64::from(plan.agreed.steps))
        + compute
        + timing.block_timeout * 2;
    let ending = pair.drive(&mut world, limit);
    (pair, ending, world)
}

/// Both stores committed the same keys, at least one, and nothing was noted.
fn assert_both_keyed(world: &World) {
    let [robot, controller] = &world.keys;
    assert!(!controller.is_empty(), "no key: {:?}", world.notes);
    let ids = |keys: &[FinalKey]| keys.iter().map(|k| k.id.clone()).collect::<Vec<_>>();
    assert_eq!(ids(robot), ids(controller));
    for (r, c) in robot.iter().zip(controller) {
        assert_eq!(r.key, c.key, "key {}", r.id);
    }
    assert!(world.notes.is_empty(), "{:?}", world.notes);
}

/// An estimate of 5 s — longer than the 2 s silence timeout, shorter than the robot's 30 s
/// block timeout, inline or deferred: the robot waits for the `Confirm`, the controller does
/// not count its own computing as the robot's silence, and both stores commit the same key.
/// Deferred, the connection's timers fire while it computes.
#[test]
fn an_estimate_longer_than_the_silence_timeout_still_keys_both_stores() {
    let timing = Timing::default();
    let compute = Duration::from_secs(5);
    assert!(timing.silence_timeout < compute && compute < timing.block_timeout);
    for deferred in [false, true] {
        let (pair, ending, world) = conversation(compute, deferred);
        assert_eq!(ending, Ending::Done, "{:?}", world.notes);
        assert_eq!(pair.controller.estimates, 1);
        assert_both_keyed(&world);
        // The retransmission timer, every 100 ms in lockstep, over 5 s.
        let live = pair.controller.inputs_while_computing;
        assert_eq!(live > 10, deferred, "{live} inputs while computing");
    }
}

/// An estimate longer than the robot's block timeout. Inline, the robot leaves with the
/// block in flight, the controller's `Confirm` goes unanswered and it leaves after its silence
/// timeout (saying so); neither store commits a key, and both still hold the block in flight
/// for the next session to settle. Deferred, the controller repeats its last fragment every
/// 5 s while it computes, the robot waits, and both stores commit the same key.
#[test]
fn an_estimate_longer_than_the_block_timeout_keys_only_a_deferring_controller() {
    let timing = Timing::default();
    let compute = timing.block_timeout + Duration::from_secs(10);
    let (pair, ending, world) = conversation(compute, false);
    assert_eq!(ending, Ending::Done, "{:?}", world.notes);
    assert_eq!(pair.controller.estimates, 1);
    assert_eq!(world.keys, [Vec::new(), Vec::new()]);
    assert!(
        world.notes.iter().any(|n| n.contains("did not answer")),
        "{:?}",
        world.notes
    );
    let robot_post = pair.robot.connection.post().expect("a store");
    assert!(robot_post.endpoint().block_in_flight().is_some());
    let controller_post = pair.controller.inner.connection.post().expect("a store");
    assert!(!controller_post.is_idle());

    let (pair, ending, world) = conversation(compute, true);
    assert_eq!(ending, Ending::Done, "{:?}", world.notes);
    assert_eq!(pair.controller.estimates, 1);
    assert_both_keyed(&world);
    // Over 40 s, one repeat every 5 s: at 5, 10, …, 35 s.
    assert_eq!(pair.controller.sent_while_computing, 7);
}
