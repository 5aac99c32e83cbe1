//! A virtual network between a robot and a controller (as quinn-proto's test `Pair`): a
//! virtual clock and, per direction, latency, loss, duplication, reordering and corruption
//! ([`LinkFaults`]). It drives any two [`Peer`]s — the bare endpoints exchanging messages
//! (the simulator, over an ideal link) or whole connections exchanging the authenticated
//! channel's bytes — and hands every other output to the world around them
//! ([`Surroundings`]): the plant, the sensors, an eavesdropper, a test's bookkeeping.

mod faults;
mod peers;

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::time::Duration;

use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;

pub use faults::{Datagram, LinkFaults};
pub use peers::Connected;

use crate::protocol::Time;
use crate::protocol::timing::earliest;

/// One side of a [`Pair`].
pub trait Peer {
    /// What it sends and receives.
    type Datagram: Datagram;
    /// Its other outputs, for the world around it.
    type Output;
    /// A datagram arrived at `now`.
    fn handle_datagram(&mut self, now: Time, datagram: Self::Datagram);
    /// Its timers due at `now`.
    fn handle_timeout(&mut self, now: Time);
    /// When it must next be woken.
    fn poll_timeout(&self) -> Option<Time>;
    /// Its next output.
    fn poll(&mut self) -> Option<Polled<Self::Datagram, Self::Output>>;
}

/// An output of a [`Peer`].
#[derive(Clone, Debug, PartialEq)]
pub enum Polled<D, O> {
    /// Send this to the other side.
    Transmit(D),
    /// Anything else, for the world.
    Output(O),
}

/// Which side of a [`Pair`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Side {
    /// The robot.
    Robot,
    /// The controller.
    Controller,
}

/// The world around a [`Pair`]: it takes every output that is not a datagram, may feed the
/// endpoints (a sample, a sensor reading), hears every datagram sent, and says when to stop.
pub trait Surroundings<R: Peer, C: Peer> {
    /// An output of the robot at `now`.
    fn robot_output(&mut self, now: Time, output: R::Output, robot: &mut R, controller: &mut C);
    /// An output of the controller at `now`.
    fn controller_output(
        &mut self,
        now: Time,
        output: C::Output,
        robot: &mut R,
        controller: &mut C,
    );
    /// A datagram `from` a side, as sent (before the link's faults): what a tap hears.
    fn heard(&mut self, _from: Side, _datagram: &R::Datagram) {}
    /// What goes on the link instead of `datagram`: an active attacker (or a test) may drop
    /// it (`None`) or change it. By default it passes unchanged.
    fn intercept(&mut self, _from: Side, datagram: R::Datagram) -> Option<R::Datagram> {
        Some(datagram)
    }
    /// Whether to stop now (checked whenever both sides are quiet).
    fn done(&self) -> bool {
        false
    }
}

/// A datagram on its way.
struct InFlight<D> {
    at: Time,
    /// Send order: ties at the same instant arrive in it.
    seq: u64,
    to: Side,
    datagram: D,
}

impl<D> PartialEq for InFlight<D> {
    fn eq(&self, other: &Self) -> bool {
        (self.at, self.seq) == (other.at, other.seq)
    }
}

impl<D> Eq for InFlight<D> {}

impl<D> PartialOrd for InFlight<D> {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl<D> Ord for InFlight<D> {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        (self.at, self.seq).cmp(&(other.at, other.seq))
    }
}

/// How a [`Pair::drive`] ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ending {
    /// The world said so.
    Done,
    /// Nothing was in flight and neither side had a timer: both have ended.
    Quiet,
    /// The virtual clock passed the limit.
    TimeLimit,
}

/// A robot and a controller on a virtual network.
pub struct Pair<R: Peer, C: Peer<Datagram = R::Datagram>> {
    /// The robot side.
    pub robot: R,
    /// The controller side.
    pub controller: C,
    now: Time,
    to_controller: LinkFaults,
    to_robot: LinkFaults,
    rng: ChaCha8Rng,
    in_flight: BinaryHeap<Reverse<InFlight<R::Datagram>>>,
    sent: u64,
}

impl<R: Peer, C: Peer<Datagram = R::Datagram>> Pair<R, C> {
    /// Both sides on an ideal link (every datagram delivered at once, in order), at time
    /// zero.
    pub fn ideal(robot: R, controller: C) -> Self {
        Self::new(
            robot,
            controller,
            LinkFaults::default(),
            LinkFaults::default(),
            0,
        )
    }

    /// Both sides on a link with these faults towards the controller and towards the robot;
    /// the faults draw from a generator seeded with `seed`.
    pub fn new(
        robot: R,
        controller: C,
        to_controller: LinkFaults,
        to_robot: LinkFaults,
        seed: u64,
    ) -> Self {
        Self {
            robot,
            controller,
            now: Time::ZERO,
            to_controller,
            to_robot,
            rng: ChaCha8Rng::seed_from_u64(seed),
            in_flight: BinaryHeap::new(),
            sent: 0,
        }
    }

    /// The virtual clock.
    #[must_use]
    pub fn now(&self) -> Time {
        self.now
    }

    /// Runs both sides until the world is done, both have ended, or the clock passes
    /// `limit` after the current time.
    pub fn drive<W: Surroundings<R, C>>(&mut self, world: &mut W, limit: Duration) -> Ending {
        let end = self.now + limit;
        loop {
            self.drain(world);
            if world.done() {
                return Ending::Done;
            }
            let timers = [self.robot.poll_timeout(), self.controller.poll_timeout()];
            let next = timers
                .into_iter()
                .fold(self.in_flight.peek().map(|f| f.0.at), earliest);
            let Some(next) = next else {
                return Ending::Quiet;
            };
            if next > end {
                return Ending::TimeLimit;
            }
            self.now = self.now.max(next);
            self.step(world, timers);
        }
    }

    /// Delivers what arrives by now, then fires the timers due (`timers`: the robot's and the
    /// controller's before the deliveries, asked again only if something was delivered).
    fn step<W: Surroundings<R, C>>(&mut self, world: &mut W, timers: [Option<Time>; 2]) {
        let mut delivered = false;
        while self.in_flight.peek().is_some_and(|f| f.0.at <= self.now) {
            if let Some(Reverse(f)) = self.in_flight.pop() {
                self.deliver(f.to, f.datagram);
                self.drain(world);
                delivered = true;
            }
        }
        let [robot, controller] = if delivered {
            [self.robot.poll_timeout(), self.controller.poll_timeout()]
        } else {
            timers
        };
        if robot.is_some_and(|t| t <= self.now) {
            self.robot.handle_timeout(self.now);
        }
        if controller.is_some_and(|t| t <= self.now) {
            self.controller.handle_timeout(self.now);
        }
    }

    /// Takes both sides' outputs until both are quiet: the robot's first, then the
    /// controller's, and again, delivering at once what an ideal link carries.
    fn drain<W: Surroundings<R, C>>(&mut self, world: &mut W) {
        let now = self.now;
        loop {
            let mut quiet = true;
            while let Some(polled) = self.robot.poll() {
                quiet = false;
                match polled {
                    Polled::Transmit(datagram) => {
                        world.heard(Side::Robot, &datagram);
                        if let Some(datagram) = world.intercept(Side::Robot, datagram) {
                            self.send(Side::Controller, datagram);
                        }
                    }
                    Polled::Output(output) => {
                        world.robot_output(now, output, &mut self.robot, &mut self.controller);
                    }
                }
            }
            while let Some(polled) = self.controller.poll() {
                quiet = false;
                match polled {
                    Polled::Transmit(datagram) => {
                        world.heard(Side::Controller, &datagram);
                        if let Some(datagram) = world.intercept(Side::Controller, datagram) {
                            self.send(Side::Robot, datagram);
                        }
                    }
                    Polled::Output(output) => {
                        world.controller_output(now, output, &mut self.robot, &mut self.controller);
                    }
                }
            }
            if quiet {
                return;
            }
        }
    }

    /// Puts a datagram on the link towards `to`: delivered at once over an ideal link,
    /// otherwise queued with each copy's delay (or dropped).
    fn send(&mut self, to: Side, datagram: R::Datagram) {
        let faults = match to {
            Side::Controller => self.to_controller,
            Side::Robot => self.to_robot,
        };
        if faults.is_ideal() {
            return self.deliver(to, datagram);
        }
        for (delay, corrupted) in faults.fate(&mut self.rng) {
            let copy = if corrupted {
                match datagram.clone().corrupt(&mut self.rng) {
                    Some(copy) => copy,
                    None => continue,
                }
            } else {
                datagram.clone()
            };
            self.sent += 1;
            self.in_flight.push(Reverse(InFlight {
                at: self.now + delay,
                seq: self.sent,
                to,
                datagram: copy,
            }));
        }
    }

    fn deliver(&mut self, to: Side, datagram: R::Datagram) {
        match to {
            Side::Robot => self.robot.handle_datagram(self.now, datagram),
            Side::Controller => self.controller.handle_datagram(self.now, datagram),
        }
    }
}
