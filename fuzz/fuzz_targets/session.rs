//! The session layer's state machines on arbitrary datagrams: an established controller
//! channel and a robot channel (listening, then bound) never panic, and a datagram they
//! reject changes nothing: the genuine next frame is still accepted afterwards.
#![no_main]

use libfuzzer_sys::fuzz_target;
use rand::SeedableRng;
use robokey::protocol::auth::{ControllerChannel, Delivery, PairingSecret, RobotChannel};
use robokey::protocol::{Closing, Handshake, Message};

const CONTROLLER: u8 = 1;
const ROBOT: u8 = 2;

fuzz_target!(|data: &[u8]| {
    let mut rng = rand::rngs::ChaCha20Rng::seed_from_u64(1);
    let secret = PairingSecret::from_bytes(&[7; 32]);
    let mut controller =
        ControllerChannel::new(secret.clone(), ROBOT, 5, [0; 32], String::new(), &mut rng);
    let mut robot = RobotChannel::new(secret, [0; 32], String::new());
    // Arbitrary bytes at a listening robot, from the controller's address.
    for chunk in data.split(|&b| b == 0xFF) {
        let _ = robot.on_datagram(CONTROLLER, chunk, &mut rng);
    }
    let Ok(Delivery::Answer { bytes, .. }) =
        robot.on_datagram(CONTROLLER, controller.hello(), &mut rng)
    else {
        panic!("the genuine Hello is answered");
    };
    assert_eq!(
        controller.on_datagram(ROBOT, &bytes),
        Ok(Delivery::Established)
    );
    let ready = controller.seal(Handshake::Ready.into()).unwrap();
    assert!(robot.on_datagram(CONTROLLER, &ready, &mut rng).is_ok());
    // Arbitrary bytes at both bound ends.
    for chunk in data.split(|&b| b == 0xFF) {
        let _ = robot.on_datagram(CONTROLLER, chunk, &mut rng);
        let _ = controller.on_datagram(ROBOT, chunk);
    }
    let next = controller.seal(Closing::FinishAck.into()).unwrap();
    assert_eq!(
        robot.on_datagram(CONTROLLER, &next, &mut rng),
        Ok(Delivery::Message(Message::Closing(Closing::FinishAck)))
    );
    let back = robot.seal(Closing::FinishAck.into()).unwrap();
    assert_eq!(
        controller.on_datagram(ROBOT, &back),
        Ok(Delivery::Message(Message::Closing(Closing::FinishAck)))
    );
});
