//! The bare session endpoints as [`Peer`]s: they exchange [`Message`]s directly, without the
//! session layer (the simulator's link, and the protocol's property tests).

use super::{Peer, Polled};
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
