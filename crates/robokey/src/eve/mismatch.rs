//! The paper's eavesdropper (SPEC §7): she hears every message, knows `r, D, W, V` up to
//! relative errors, runs the same observer and decodes every codeword. With zero errors she
//! is the oracle Eve (SECRECY §6.1).

use rand::{Rng, RngExt};

use super::Eavesdropper;
use crate::config::{Config, Draw};
use crate::model::{DiffDrive, Pose};
use crate::observer::{Observer, ObserverParams};
use crate::protocol::{
    CodewordAssembler, FateLedger, KeyBits, Message, SessionPlan, StepDecision, StepDecoder,
    controller::observer_params,
};

/// Eve's relative model errors (fractions: 0.1 = 10 %).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ModelErrors {
    /// Error on the wheel radius `r`.
    pub r: f64,
    /// Error on the axle length `D`.
    pub d: f64,
    /// Error on the process covariance `W`.
    pub w: f64,
    /// Error on the measurement covariance `V`.
    pub v: f64,
}

impl ModelErrors {
    /// Draws `e = α·u`, `u ~ U[−1, 1]`, in the order r, D, W, V (one draw for all with
    /// [`Draw::Common`]).
    pub fn draw<R: Rng + ?Sized>(alpha: f64, draw: Draw, rng: &mut R) -> Self {
        let mut next = || alpha * rng.random_range(-1.0..=1.0);
        match draw {
            Draw::Independent => Self {
                r: next(),
                d: next(),
                w: next(),
                v: next(),
            },
            Draw::Common => {
                let e = next();
                Self {
                    r: e,
                    d: e,
                    w: e,
                    v: e,
                }
            }
        }
    }
}

/// The paper's eavesdropper, fed every message of a session in order.
#[derive(Debug)]
pub struct PaperEve {
    drive: DiffDrive,
    steps: u32,
    code: std::sync::Arc<dyn crate::code::BlockCode>,
    decoder: StepDecoder,
    assembler: CodewordAssembler,
    fates: FateLedger,
    decoded: Vec<u64>,
    errors: ModelErrors,
}

impl PaperEve {
    /// Eve for a session of `plan` under `config`, with her model errors.
    #[must_use]
    pub fn new(config: &Config, plan: &SessionPlan, errors: ModelErrors) -> Self {
        let drive = DiffDrive {
            wheel_radius: config.robot.r * (1.0 + errors.r),
            axle_length: config.robot.axle_length * (1.0 + errors.d),
        };
        let params = ObserverParams {
            w_var: config.observer.w_var * (1.0 + errors.w),
            v_var: config.observer.v_var * (1.0 + errors.v),
            ..observer_params(config)
        };
        let observer = Observer::new(&params).expect("validated observer.m");
        Self {
            drive,
            steps: plan.steps,
            code: plan.code.clone(),
            decoder: StepDecoder::new(drive, observer, plan.delta, true),
            assembler: CodewordAssembler::new(plan.code.n() as u32, plan.codewords()),
            fates: FateLedger::new(plan.codewords()),
            decoded: vec![0; plan.codewords() as usize],
            errors,
        }
    }

    /// Her model errors.
    #[must_use]
    pub fn errors(&self) -> ModelErrors {
        self.errors
    }

    /// Her current state estimate.
    #[must_use]
    pub fn state(&self) -> Pose {
        self.decoder.state()
    }

    fn push(&mut self, step: u32, bit: Option<u8>) {
        if let Some(received) = self.assembler.push(step, bit) {
            self.decoded[received.index as usize] = self.code.decode(received.word).message;
        }
    }
}

impl Eavesdropper for PaperEve {
    /// Observes one message; returns her decision when a measurement decided a step.
    fn observe(&mut self, message: &Message) -> Option<StepDecision> {
        match message {
            Message::Command {
                step,
                u0,
                u1,
                fates,
            } => {
                if *step < self.steps {
                    let (u0, u1) = ((*u0).into(), (*u1).into());
                    // She never sees uU: her nominal is H_a·(u0D + u1D)/2.
                    let nominal = self.drive.to_unicycle((u0 + u1) / 2.0);
                    self.decoder.on_command(*step, nominal, u0, u1);
                }
                for (index, accepted) in fates.iter() {
                    self.fates.record(index, accepted);
                }
                None
            }
            Message::Measurement {
                step,
                y,
                applied_step,
                ..
            } => {
                let measured = self
                    .decoder
                    .on_measurement(*step, &Pose::from(*y), *applied_step)
                    .ok()??;
                for gap in measured.missing {
                    self.push(gap, None);
                }
                let decision = measured.decision?;
                self.push(decision.step, decision.bit);
                Some(decision)
            }
            Message::Finish { codewords, bitmap } => {
                for index in 0..*codewords {
                    let accepted = bitmap
                        .get(index as usize / 64)
                        .is_some_and(|w| w >> (index % 64) & 1 == 1);
                    self.fates.record(index, accepted);
                }
                None
            }
            _ => None,
        }
    }

    /// Her key `K_a`: the decoded messages of the codewords acked so far.
    fn key(&self) -> KeyBits {
        self.fates.accepted_key(&self.decoded, self.code.k())
    }
}
