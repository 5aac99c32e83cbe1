//! Arbitrary post-processing messages fed to both endpoints (a robot with pooled sessions,
//! a controller that has proposed a block), reconciling by Cascade or by LDPC as the first
//! byte says: nothing may panic, and no key may be committed — committing needs a tag over
//! the reconciled key, which arbitrary bytes do not forge.
#![no_main]

use libfuzzer_sys::arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;
use robokey_secrecy::BitString;
use robokey_secrecy::cascade::{BlockQuery, CascadeSchedule};
use robokey_secrecy::ldpc::LdpcSettings;
use robokey_secrecy::postprocess::{
    AbortReason, Assumption, ControllerInput, ControllerPost, Message, Output,
    ReconciliationMethod, RejectReason, RobotInput, RobotPost, Settings,
};

fn list<T>(
    u: &mut Unstructured<'_>,
    item: impl Fn(&mut Unstructured<'_>) -> Result<T>,
) -> Result<Vec<T>> {
    let len = u.int_in_range(0..=64)?;
    (0..len).map(|_| item(u)).collect()
}

fn message(u: &mut Unstructured<'_>) -> Result<Message> {
    let block = u.int_in_range(0..=3)?;
    Ok(match u.int_in_range(0..=12)? {
        0 => Message::Propose {
            block,
            sessions: list(u, |u| u.int_in_range(0..=12))?,
            nonce: u.arbitrary()?,
            separation_micros: u.arbitrary()?,
        },
        1 => Message::Agree {
            block,
            sessions: list(u, |u| u.int_in_range(0..=12))?,
            nonce: u.arbitrary()?,
            sample: list(u, |u| u.arbitrary())?,
        },
        2 => Message::Ask {
            block,
            round: u.int_in_range(0..=4)?,
            queries: list(u, |u| {
                Ok(BlockQuery {
                    permutation: u.int_in_range(0..=20)?,
                    start: u.arbitrary()?,
                    end: u.arbitrary()?,
                })
            })?,
        },
        3 => Message::Answer {
            block,
            round: u.int_in_range(0..=4)?,
            parities: list(u, |u| u.arbitrary())?,
        },
        4 => Message::Confirm {
            block,
            length: u.arbitrary()?,
            tag: u.arbitrary()?,
            estimate: u.arbitrary()?,
        },
        5 => Message::Confirmed {
            block,
            tag: u.arbitrary()?,
        },
        6 => Message::Commit { block },
        7 => Message::CommitAck { block },
        8 => Message::Abort {
            block,
            sessions: list(u, |u| u.int_in_range(0..=12))?,
            reason: *u.choose(&[
                AbortReason::NoSecretBits,
                AbortReason::Reconciliation,
                AbortReason::Restart,
                AbortReason::Refused,
                AbortReason::PlantRefused,
            ])?,
        },
        9 => Message::AbortAck { block },
        11 => Message::SyndromeAsk {
            block,
            round: u.int_in_range(0..=4)?,
            syndrome_bits: if u.arbitrary()? {
                u.int_in_range(0..=600)?
            } else {
                u.arbitrary()?
            },
            bhattacharyya: u.arbitrary()?,
        },
        12 => Message::Syndrome {
            block,
            round: u.int_in_range(0..=4)?,
            syndrome: list(u, |u| u.arbitrary())?,
        },
        _ => Message::Reject {
            block,
            reason: *u.choose(&[
                RejectReason::UnknownBlock,
                RejectReason::TagMismatch,
                RejectReason::LengthMismatch,
                RejectReason::Busy,
                RejectReason::BadQuestions,
            ])?,
        },
    })
}

fuzz_target!(|data: &[u8]| {
    let ldpc = data.first().is_some_and(|b| b & 1 == 1);
    let settings = Settings {
        block_bits: 256,
        sample_bits: 20,
        epsilon: 1e-3,
        schedule: CascadeSchedule::BICONF,
        assumption: Assumption::IndependentErrors { error_rate: 0.5 },
        reconciliation: if ldpc {
            ReconciliationMethod::Ldpc(LdpcSettings::DEFAULT)
        } else {
            ReconciliationMethod::Cascade
        },
    };
    let mut robot = RobotPost::new(settings.clone(), [1; 32]).unwrap();
    let mut controller = ControllerPost::new(settings, [2; 32]).unwrap();
    for id in 0..6 {
        let bits = BitString::from_bools(&vec![id % 2 == 0; 100]);
        robot
            .handle_input(RobotInput::Session {
                id,
                bits: bits.clone(),
            })
            .unwrap();
        controller
            .handle_input(ControllerInput::Session {
                id,
                bits,
                separations: Vec::new(),
                samples: Vec::new(),
                llrs: vec![if id % 2 == 0 { -3.0 } else { 3.0 }; 100],
            })
            .unwrap();
    }
    let mut u = Unstructured::new(data.get(1..).unwrap_or_default());
    while !u.is_empty() {
        let Ok(m) = message(&mut u) else { break };
        let to_robot = u.arbitrary::<bool>().unwrap_or(true);
        if to_robot {
            robot.handle_input(RobotInput::Frame(m)).unwrap();
            while let Some(output) = robot.poll_output() {
                assert!(
                    !matches!(output, Output::KeyCommitted(_)),
                    "the robot committed a key from arbitrary messages"
                );
            }
        } else {
            controller.handle_input(ControllerInput::Frame(m)).unwrap();
            if u.arbitrary::<bool>().unwrap_or(false) {
                controller.handle_input(ControllerInput::Timeout).unwrap();
            }
            while let Some(output) = controller.poll_output() {
                assert!(
                    !matches!(output, Output::KeyCommitted(_)),
                    "the controller committed a key from arbitrary messages"
                );
            }
        }
    }
});
