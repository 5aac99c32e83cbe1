//! What a [`super::Pair`] can drive: the bare session endpoints, which exchange
//! [`Message`]s directly without the session layer (the simulator's link, and the protocol's
//! property tests), and whole connections, which exchange the session layer's bytes.

use super::{Peer, Polled};
use crate::connection::{
    ControllerAction, ControllerConnection, Output, RobotAction, RobotConnection,
};
use crate::protocol::{
    Controller, ControllerInput, ControllerOutput, Message, Robot, RobotInput, RobotOutput, Time,
};

impl Peer for Robot {
    type Datagram = Message;
    /// Every output but `Transmit`.
    type Output = RobotOutput;

    fn handle_datagram(&mut self, now: Time, message: Message) {
        self.handle_input(now, RobotInput::Frame(message));
    }

    fn handle_timeout(&mut self, now: Time) {
        Robot::handle_timeout(self, now);
    }

    fn poll_timeout(&self) -> Option<Time> {
        Robot::poll_timeout(self)
    }

    fn poll(&mut self) -> Option<Polled<Message, RobotOutput>> {
        self.poll_output().map(|output| match output {
            RobotOutput::Transmit(message) => Polled::Transmit(message),
            other => Polled::Output(other),
        })
    }
}

impl Peer for Controller {
    type Datagram = Message;
    /// Every output but `Transmit`.
    type Output = ControllerOutput;

    fn handle_datagram(&mut self, now: Time, message: Message) {
        self.handle_input(now, ControllerInput::Frame(message));
    }

    fn handle_timeout(&mut self, now: Time) {
        Controller::handle_timeout(self, now);
    }

    fn poll_timeout(&self) -> Option<Time> {
        Controller::poll_timeout(self)
    }

    fn poll(&mut self) -> Option<Polled<Message, ControllerOutput>> {
        self.poll_output().map(|output| match output {
            ControllerOutput::Transmit(message) => Polled::Transmit(message),
            other => Polled::Output(other),
        })
    }
}

/// A connection on a [`super::Pair`]: the whole conversation of one side over the session
/// layer's real bytes, seeing the other side at address `peer`.
#[derive(Debug)]
pub struct Connected<C, A> {
    /// The connection.
    pub connection: C,
    /// The address it sees the other side at.
    pub peer: A,
}

impl<A: Copy + PartialEq, K: rand::CryptoRng> Peer for Connected<RobotConnection<A, K>, A> {
    type Datagram = Vec<u8>;
    /// Every output but `Transmit`.
    type Output = RobotAction<A>;

    fn handle_datagram(&mut self, now: Time, bytes: Vec<u8>) {
        self.connection.handle_datagram(now, self.peer, &bytes);
    }

    fn handle_timeout(&mut self, now: Time) {
        self.connection.handle_timeout(now);
    }

    fn poll_timeout(&self) -> Option<Time> {
        self.connection.poll_timeout()
    }

    fn poll(&mut self) -> Option<Polled<Vec<u8>, RobotAction<A>>> {
        self.connection.poll_output().map(|output| match output {
            Output::Transmit { bytes, .. } => Polled::Transmit(bytes),
            other => Polled::Output(other),
        })
    }
}

impl<A: Copy + PartialEq + std::fmt::Display> Peer for Connected<ControllerConnection<A>, A> {
    type Datagram = Vec<u8>;
    /// Every output but `Transmit`.
    type Output = ControllerAction<A>;

    fn handle_datagram(&mut self, now: Time, bytes: Vec<u8>) {
        self.connection.handle_datagram(now, self.peer, &bytes);
    }

    fn handle_timeout(&mut self, now: Time) {
        self.connection.handle_timeout(now);
    }

    fn poll_timeout(&self) -> Option<Time> {
        self.connection.poll_timeout()
    }

    fn poll(&mut self) -> Option<Polled<Vec<u8>, ControllerAction<A>>> {
        self.connection.poll_output().map(|output| match output {
            Output::Transmit { bytes, .. } => Polled::Transmit(bytes),
            other => Polled::Output(other),
        })
    }
}
