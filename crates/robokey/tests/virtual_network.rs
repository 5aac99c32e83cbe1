//! The protocol over a faulty virtual network, for thousands of seeds: whatever the link
//! loses, duplicates, delays or reorders, every side ends, and no two sides that believe
//! they agree hold different keys.

use std::time::Duration;

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use robokey::Config;
use robokey::pair::{Ending, LinkFaults};
use robokey::protocol::{Outcome, Timing};
use support::{
    Address, ControllerSide, Network, RobotSide, Session, connection_plant, drive_plant, session,
};

mod support;

/// Seeds per sensing mode.
const SEEDS: u64 = 10_000;

/// A short session: four sides of 2 s, 40 steps.
fn short(mode: &str) -> Config {
    Config::from_toml(
        &format!("[sensing]\nmode = \"{mode}\"\n[trajectory]\nside_time = 2.0\nlaps = 1\n"),
        "test",
    )
    .expect("a valid configuration")
}

/// A short private session of three-step doublets (`private.prior_lag` = 50 ms).
fn three_step() -> Config {
    let mut config = short("private");
    config.private.prior_lag = 0.05;
    config
}

/// The faults of one direction, drawn for a seed: up to 40 % loss, 20 % duplication, 20 %
/// reordering (held back up to 300 ms), 10 % corruption, latency and jitter up to 40 ms.
fn faults(rng: &mut ChaCha8Rng) -> LinkFaults {
    LinkFaults {
        latency: Duration::from_millis(rng.random_range(0..40)),
        jitter: Duration::from_millis(rng.random_range(0..40)),
        loss: rng.random_range(0.0..0.4),
        duplicate: rng.random_range(0.0..0.2),
        reorder: rng.random_range(0.0..0.2),
        reorder_delay: Duration::from_millis(300),
        corrupt: rng.random_range(0.0..0.1),
    }
}

/// The network of seed `seed`.
fn network(seed: u64) -> Network {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    Network {
        to_controller: faults(&mut rng),
        to_robot: faults(&mut rng),
        seed,
        timing: Timing::default(),
    }
}

/// Whether a side believes the peer holds its key (odometry) or kept the same doublets
/// (private sensing).
fn agrees(outcome: Option<&Outcome>) -> bool {
    matches!(outcome, Some(Outcome::Confirmed | Outcome::Kept))
}

/// Checks one session; returns whether both sides agreed. A confirmed odometry key is the
/// peer's key; private sensing's raw bits differ where the controller erred, but both sides
/// keep the same doublets, so their raw keys have the same length.
fn check(seed: u64, s: &Session) -> bool {
    assert_eq!(
        s.ending,
        Ending::Done,
        "seed {seed}: a side never ended: {s:?}"
    );
    let either = agrees(s.robot_outcome.as_ref()) || agrees(s.controller_outcome.as_ref());
    let kept = matches!(s.robot_outcome, Some(Outcome::Kept))
        || matches!(s.controller_outcome, Some(Outcome::Kept));
    if kept {
        assert_eq!(
            s.robot_key.len(),
            s.controller_key.len(),
            "seed {seed}: kept sets differ: {s:?}"
        );
    } else if either {
        assert_eq!(
            s.robot_key, s.controller_key,
            "seed {seed}: keys differ: {s:?}"
        );
    }
    agrees(s.robot_outcome.as_ref()) && agrees(s.controller_outcome.as_ref())
}

fn property(mode: &str) {
    property_of(mode, &short(mode));
}

fn property_of(mode: &str, config: &Config) {
    let (mut both, mut bits, mut differ) = (0, 0, 0);
    for seed in 0..SEEDS {
        let s = session(config, network(seed), |_, _| false, |_| false);
        both += u64::from(check(seed, &s));
        bits += s.robot_key.len();
        differ += s
            .robot_key
            .iter()
            .zip(&s.controller_key)
            .filter(|(a, b)| a != b)
            .count();
    }
    println!("{mode}: {bits} raw bits, {differ} differ");
    // Sanity, not a rate claim: the faults are harsh, but most sessions still agree.
    assert!(
        both > SEEDS / 2,
        "{mode}: only {both} of {SEEDS} sessions agreed"
    );
    println!("{mode}: {both} of {SEEDS} sessions agreed on both sides");
}

#[test]
fn over_a_faulty_network_odometry_sessions_end_and_never_hold_differing_keys() {
    property("odometry");
}

#[test]
fn over_a_faulty_network_private_sessions_end_and_never_hold_differing_keys() {
    property("private");
}

#[test]
fn over_a_faulty_network_three_step_private_sessions_end_and_never_hold_differing_keys() {
    property_of("private, three steps", &three_step());
}

#[test]
fn an_ideal_link_agrees_in_both_modes() {
    for (mode, config) in [
        ("odometry", short("odometry")),
        ("private", short("private")),
        ("private, three steps", three_step()),
    ] {
        let s = session(&config, Network::default(), |_, _| false, |_| false);
        assert!(check(0, &s), "{mode}: {s:?}");
        assert!(!s.robot_key.is_empty(), "{mode}");
    }
}

mod through_the_session_layer {
    use super::*;
    use rand::rngs::ChaCha20Rng;
    use robokey::connection::{
        ControllerAction, ControllerConnection, Output, RobotAction, RobotConnection, Setup,
    };
    use robokey::pair::Side;
    use robokey::pair::{Connected, Pair, Surroundings};
    use robokey::protocol::auth::PairingSecret;
    use robokey::protocol::{Handshake, Message, Time};
    use robokey::rng::{Purpose, stream};
    use robokey::world::WorldPlant;

    /// The plant both agents' worlds share, how each side ended, and how many of the
    /// controller's `Ready`s an attacker drops.
    struct World {
        plant: WorldPlant,
        private: bool,
        outcomes: [Option<Outcome>; 2],
        closed: [bool; 2],
        drop_readies: u32,
    }

    impl Surroundings<RobotSide, ControllerSide> for World {
        fn robot_output(
            &mut self,
            now: Time,
            output: RobotAction<Address>,
            robot: &mut RobotSide,
            controller: &mut ControllerSide,
        ) {
            match output {
                Output::Endpoint(event) => {
                    let sensor = self.private.then_some(controller);
                    drive_plant(&mut self.plant, now, event, robot, sensor);
                }
                Output::Finished(outcome) => self.outcomes[0] = Some(outcome),
                Output::Closed => self.closed[0] = true,
                _ => {}
            }
        }

        fn controller_output(
            &mut self,
            _now: Time,
            output: ControllerAction<Address>,
            _robot: &mut RobotSide,
            _controller: &mut ControllerSide,
        ) {
            match output {
                Output::Finished(outcome) => self.outcomes[1] = Some(outcome),
                Output::Closed => self.closed[1] = true,
                _ => {}
            }
        }

        fn done(&self) -> bool {
            self.closed == [true; 2]
        }

        fn intercept(&mut self, from: Side, bytes: Vec<u8>) -> Option<Vec<u8>> {
            let ready = robokey::protocol::wire::decode(&bytes)
                .is_ok_and(|f| f.message == Message::Handshake(Handshake::Ready));
            if from == Side::Controller && ready && self.drop_readies > 0 {
                self.drop_readies -= 1;
                return None;
            }
            Some(bytes)
        }
    }

    /// One whole conversation of `config` between two paired agents on `network`.
    fn conversation(config: &Config, network: Network) -> Session {
        conversation_dropping_readies(config, network, 0)
    }

    /// [`conversation`], with the first `drop_readies` of the controller's `Ready`s lost.
    fn conversation_dropping_readies(
        config: &Config,
        network: Network,
        drop_readies: u32,
    ) -> Session {
        conversation_between(config, config, network, drop_readies)
    }

    /// [`conversation_dropping_readies`] between a robot configured with `config` and a
    /// controller configured with `controller_config` (the world is the robot's).
    fn conversation_between(
        config: &Config,
        controller_config: &Config,
        network: Network,
        drop_readies: u32,
    ) -> Session {
        let seed = network.seed;
        let pairing = PairingSecret::generate(&mut stream(seed, Purpose::Key, 1));
        let setup = Setup {
            config,
            pairing: &pairing,
            timing: network.timing,
        };
        let controller_setup = Setup {
            config: controller_config,
            ..setup
        };
        let robot = RobotConnection::new(
            setup,
            Duration::from_secs(5),
            None,
            <ChaCha20Rng as SeedableRng>::seed_from_u64(seed),
            <ChaCha20Rng as SeedableRng>::seed_from_u64(!seed),
            Time::ZERO,
        );
        let controller = ControllerConnection::new(
            controller_setup,
            Address::Robot,
            seed as u32,
            None,
            <ChaCha20Rng as SeedableRng>::seed_from_u64(seed ^ 0x5eed),
            Time::ZERO,
        );
        let plan = robokey::protocol::SessionPlan::from_config(config, 0);
        let mut world = World {
            plant: connection_plant(config, seed),
            private: plan.private().is_some(),
            outcomes: [None, None],
            closed: [false; 2],
            drop_readies,
        };
        let mut pair = Pair::new(
            Connected {
                connection: robot,
                peer: Address::Controller,
            },
            Connected {
                connection: controller,
                peer: Address::Robot,
            },
            network.to_controller,
            network.to_robot,
            seed,
        );
        let limit = Duration::from_secs_f64(plan.agreed.sample_time * f64::from(plan.agreed.steps))
            + Duration::from_secs(30);
        let ending = pair.drive(&mut world, limit);
        let key = |endpoint: Option<&[u8]>| endpoint.unwrap_or_default().to_vec();
        let [robot_outcome, controller_outcome] = world.outcomes;
        Session {
            robot_key: key(pair.robot.connection.endpoint().map(|e| e.key())),
            controller_key: key(pair.controller.connection.endpoint().map(|e| e.key())),
            fates: Vec::new(),
            decided: Vec::new(),
            erased: Vec::new(),
            robot_outcome,
            controller_outcome,
            ending,
        }
    }

    /// Seeds per sensing mode through the session layer (each frame sealed and verified).
    const SEEDS: u64 = 2_000;

    fn property(mode: &str) {
        let config = short(mode);
        let mut both = 0;
        for seed in 0..SEEDS {
            let s = conversation(&config, network(seed));
            both += u64::from(check(seed, &s));
        }
        assert!(
            both > SEEDS / 2,
            "{mode}: only {both} of {SEEDS} conversations agreed"
        );
        println!("{mode}, session layer: {both} of {SEEDS} conversations agreed on both sides");
    }

    #[test]
    fn over_a_faulty_network_odometry_conversations_close_and_never_hold_differing_keys() {
        property("odometry");
    }

    #[test]
    fn over_a_faulty_network_private_conversations_close_and_never_hold_differing_keys() {
        property("private");
    }

    /// A controller whose `Ready`s all go unanswered (an attacker drops them, or a replayed
    /// `Hello` pushed its handshake out at the robot) starts a fresh handshake, and the
    /// session confirms; a robot that never binds one ends the controller with the reason.
    #[test]
    fn a_controller_whose_ready_goes_unanswered_starts_a_fresh_handshake() {
        let config = short("odometry");
        let s = conversation_dropping_readies(&config, Network::default(), 10);
        assert!(check(0, &s), "{s:?}");
        let s = conversation_dropping_readies(&config, Network::default(), u32::MAX);
        let Some(Outcome::Aborted(why)) = &s.controller_outcome else {
            panic!("{s:?}");
        };
        assert!(why.contains("never bound"), "{why}");
    }

    /// What sizes or labels the keys and differs between the agents — the motion noise the
    /// assumption names, Eve's camera in frames, the prior lag that shapes the doublets, the
    /// measured plant (here a robot stating `sizing = "configured"` against a controller
    /// that leaves it unset, hence measured under private sensing), the reconciliation —
    /// ends the session at `Hello`, named.
    #[test]
    fn terms_that_size_or_label_keys_and_differ_are_refused_by_name() {
        let mut robot = short("private");
        robot.postprocess.sizing = Some(robokey::config::Sizing::Configured);
        let mut lag = robot.clone();
        lag.private.prior_lag = 0.05;
        let mut noise = robot.clone();
        noise.noise.process_std = [0.002; 3];
        let mut frames = robot.clone();
        frames.eve.camera_fps = Some(30.0);
        frames.eve.camera_frame_std = Some([0.016; 3]);
        let mut measured = robot.clone();
        measured.postprocess.sizing = None;
        let mut ldpc = robot.clone();
        ldpc.postprocess.reconciliation = robokey::config::Reconciliation::Ldpc;
        for (controller, named) in [
            (lag, "private.prior_lag: robot has 0, controller has 0.05"),
            (
                noise,
                "noise.process_std: robot has [0.004, 0.004, 0.004], controller has [0.002, \
                 0.002, 0.002]",
            ),
            (
                frames,
                "eve.camera_fps: robot has none (a per-instant camera), controller has 30",
            ),
            (
                measured,
                "postprocess.sizing: robot has configured, controller has measured",
            ),
            (
                ldpc,
                "postprocess.reconciliation: robot has cascade, controller has ldpc",
            ),
        ] {
            let s = conversation_between(&robot, &controller, Network::default(), 0);
            let Some(Outcome::Aborted(why)) = &s.controller_outcome else {
                panic!("{named}: {s:?}");
            };
            assert!(why.contains(named), "{why}");
            assert!(s.robot_key.is_empty() && s.controller_key.is_empty());
        }
    }

    /// Agreement is on the effective sizing: a robot that leaves `postprocess.sizing` unset
    /// under private sensing (measured) and a controller that states `"measured"` confirm.
    #[test]
    fn an_unset_sizing_agrees_with_its_explicit_value() {
        let robot = short("private");
        let mut controller = robot.clone();
        controller.postprocess.sizing = Some(robokey::config::Sizing::Measured);
        let s = conversation_between(&robot, &controller, Network::default(), 0);
        assert!(check(0, &s), "{s:?}");
        assert!(!s.robot_key.is_empty());
    }

    #[test]
    fn an_ideal_link_confirms_through_the_session_layer() {
        for mode in ["odometry", "private"] {
            let s = conversation(&short(mode), Network::default());
            assert!(check(0, &s), "{mode}: {s:?}");
            assert!(!s.robot_key.is_empty(), "{mode}");
        }
    }
}
