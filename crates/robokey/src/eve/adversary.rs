//! The eavesdropper of every strategy (docs/threat-model.md): one observer-based listener whose
//! capabilities the strategy switches on — likelihood decisions, online identification of
//! `r` and `D`, and the confirmation tag as a key oracle.

use super::identify::WheelIdentifier;
use super::tag_search::{TagMatch, is_key_tag, search_key};
use super::{Eavesdropper, ModelErrors};
use crate::code::{BlockCode, SoftDecoded};
use crate::config::{Config, EveStrategy};
use crate::model::{DiffDrive, WheelSpeeds};
use crate::observer::{Observer, ObserverParams, log_likelihood_ratio};
use crate::protocol::{
    Agreed, Closing, FateLedger, KeyBits, Message, OdometryPlan, SessionMessage, SessionPlan,
    StepDecision, StepDecoder, TAG_BYTES, controller::observer_params,
};

/// The learning strategies' starting model is worth one period at this wheel speed
/// (rad/s): a weak prior, which the first periods of data outweigh.
const PRIOR_SPEED: f64 = 1.0;

/// Where her wheel model comes from.
#[derive(Clone, Debug)]
enum WheelModel {
    /// Fixed for good (oracle, mismatch, soft).
    Fixed(DiffDrive),
    /// Identified online from what she hears (identify, transcript).
    Learned(Box<WheelIdentifier>),
}

impl WheelModel {
    fn drive(&self) -> DiffDrive {
        match self {
            Self::Fixed(drive) => *drive,
            Self::Learned(identifier) => identifier.drive(),
        }
    }
}

/// What she holds about the session she is listening to.
#[derive(Debug)]
struct Session {
    agreed: Agreed,
    plan: OdometryPlan,
    /// Complete codewords of the session.
    codewords: u32,
    decoder: StepDecoder,
    fates: FateLedger,
    /// Per step: her hard decision (`None`: erased or undecided).
    bits: Vec<Option<u8>>,
    /// Per step: `ln p(·|1) − ln p(·|0)` (0 when erased; unused by the hard strategies).
    llrs: Vec<f64>,
    /// Per codeword: her decoded message and its reliability.
    decoded: Vec<SoftDecoded>,
    /// Confirmation tags already tried.
    tags_tried: Vec<[u8; TAG_BYTES]>,
    /// The key behind the last confirmation tag she matched.
    verified: Option<TagMatch>,
}

/// An eavesdropper following [`EveStrategy`].
#[derive(Debug)]
pub struct Eve {
    strategy: EveStrategy,
    observer: ObserverParams,
    model: WheelModel,
    /// Her starting wheel model, the fallback while the learned one is not physical.
    start: DiffDrive,
    errors: ModelErrors,
    max_flips: u32,
    session: Option<Session>,
}

impl Eve {
    /// Eve of `strategy` with her starting relative model `errors` on r, D, W, V (the
    /// learning strategies start from them and improve).
    #[must_use]
    pub fn new(config: &Config, strategy: EveStrategy, errors: ModelErrors) -> Self {
        let drive = DiffDrive {
            wheel_radius: config.robot.r * (1.0 + errors.r),
            axle_length: config.robot.axle_length * (1.0 + errors.d),
        };
        let model = match strategy {
            // The private mode's strategies know the model: on odometry they are the oracle.
            EveStrategy::Oracle
            | EveStrategy::Mismatch
            | EveStrategy::Soft
            | EveStrategy::Camera
            | EveStrategy::Commands => WheelModel::Fixed(drive),
            EveStrategy::Identify | EveStrategy::Transcript => {
                WheelModel::Learned(Box::new(WheelIdentifier::new(
                    drive,
                    PRIOR_SPEED,
                    config.robot.wheel_limit,
                    config.robot.sample_time,
                )))
            }
        };
        Self {
            strategy,
            observer: ObserverParams {
                w_var: config.observer.w_var * (1.0 + errors.w),
                v_var: config.observer.v_var * (1.0 + errors.v),
                ..observer_params(config)
            },
            model,
            start: drive,
            errors,
            max_flips: config.eve.max_flips,
            session: None,
        }
    }

    /// Her starting relative model errors.
    #[must_use]
    pub fn errors(&self) -> ModelErrors {
        self.errors
    }

    fn soft(&self) -> bool {
        !matches!(self.strategy, EveStrategy::Oracle | EveStrategy::Mismatch)
    }

    /// The wheel model to decide with: the learned one once it is physical, else her start.
    fn current_drive(&self) -> DiffDrive {
        let drive = self.model.drive();
        let physical = |x: f64| x.is_finite() && x > 0.0;
        if physical(drive.wheel_radius) && physical(drive.axle_length) {
            drive
        } else {
            self.start
        }
    }

    fn on_command(&mut self, step: u32, u0: WheelSpeeds, u1: WheelSpeeds) {
        // A fixed model is her start, which her decoder already holds.
        let learned = if let WheelModel::Learned(identifier) = &mut self.model {
            identifier.on_command(step, u0, u1);
            Some(self.current_drive())
        } else {
            None
        };
        let Some(session) = self.session.as_mut().filter(|s| step < s.agreed.steps) else {
            return;
        };
        if let Some(drive) = learned {
            session.decoder.set_drive(drive);
        }
        let drive = session.decoder.drive();
        // She never sees uU: her nominal is H_a·(u0D + u1D)/2.
        let nominal = drive.to_unicycle((u0 + u1) / 2.0);
        session.decoder.on_command(step, nominal, u0, u1);
    }

    /// Settles step `step` (a decision or an erasure) and decodes the codeword it completes.
    fn settle(&mut self, step: u32, bit: Option<u8>, llr: f64) {
        let soft = self.soft();
        let Some(session) = self.session.as_mut() else {
            return;
        };
        let Some(slot) = session.bits.get_mut(step as usize) else {
            return;
        };
        *slot = bit;
        session.llrs[step as usize] = llr;
        let code = &session.plan.code;
        let n = code.n() as u32;
        let index = step / n;
        if step % n + 1 != n || index >= session.codewords {
            return;
        }
        let steps = (index * n) as usize..((index + 1) * n) as usize;
        session.decoded[index as usize] = if soft {
            code.decode_soft(&session.llrs[steps])
        } else {
            let word = session.bits[steps]
                .iter()
                .enumerate()
                .fold(0u64, |w, (j, b)| w | u64::from(b.unwrap_or(0) & 1) << j);
            hard_decoded(code.as_ref(), word)
        };
    }

    /// Tests the key behind a confirmation tag, and learns from it when found.
    fn on_confirm(&mut self, tag: &[u8; TAG_BYTES]) {
        if self.strategy != EveStrategy::Transcript {
            return;
        }
        let Some(session) = self.session.as_mut() else {
            return;
        };
        // Both sides send a tag; when they differ (keys differ) the later match wins, which
        // is normally the controller's: it answers the robot's FinishAck.
        if session.tags_tried.contains(tag) || !session.fates.is_complete() {
            return;
        }
        // The peer's tag over a key she already recovered: nothing new.
        if let Some(found) = &session.verified {
            let key = session
                .fates
                .accepted_key(&found.messages, session.plan.code.k());
            if is_key_tag(&session.agreed.confirmer, &key, tag) {
                return;
            }
        }
        session.tags_tried.push(*tag);
        let Some(found) = search_key(
            &session.agreed.confirmer,
            session.plan.code.k(),
            &session.fates,
            &session.decoded,
            tag,
            self.max_flips,
        ) else {
            return;
        };
        // The accepted codewords' bits are now labels for the identification.
        let (plan, fates) = (&session.plan, &session.fates);
        let n = plan.code.n() as u32;
        let bit_of = |step: u32| {
            let index = step / n;
            (fates.get(index) == Some(true)).then(|| {
                let word = plan.code.encode(found.messages[index as usize]);
                (word >> (step % n) & 1) as u8
            })
        };
        if let WheelModel::Learned(identifier) = &mut self.model {
            identifier.learn_bits(bit_of);
        }
        session.verified = Some(found);
    }
}

/// A hard decision as a decoded message with no reliability information.
fn hard_decoded(code: &dyn BlockCode, word: u64) -> SoftDecoded {
    let message = code.decode(word).message;
    SoftDecoded {
        message,
        runner_up: message,
        margin: 0.0,
    }
}

impl Eavesdropper for Eve {
    fn begin_session(&mut self, plan: &SessionPlan) {
        if let WheelModel::Learned(identifier) = &mut self.model {
            identifier.begin_session();
        }
        // She decodes command pairs: a private session gives her nothing to decode.
        let Some(odometry) = plan.odometry() else {
            self.session = None;
            return;
        };
        let drive = self.current_drive();
        let observer = Observer::new(&self.observer).expect("validated observer.m");
        let codewords = plan.units();
        let empty = hard_decoded(odometry.code.as_ref(), 0);
        let steps = plan.agreed.steps as usize;
        self.session = Some(Session {
            agreed: plan.agreed.clone(),
            plan: odometry.clone(),
            codewords,
            decoder: StepDecoder::new(drive, observer, odometry.delta, true).weighing(),
            fates: FateLedger::new(codewords),
            bits: vec![None; steps],
            llrs: vec![0.0; steps],
            decoded: vec![empty; codewords as usize],
            tags_tried: Vec::new(),
            verified: None,
        });
    }

    fn observe(&mut self, message: &Message) -> Option<StepDecision> {
        match message {
            Message::Session(SessionMessage::Command {
                step,
                u0,
                u1,
                fates,
            }) => {
                self.on_command(*step, (*u0).into(), (*u1).into());
                let session = self.session.as_mut()?;
                for (index, accepted) in fates.iter() {
                    session.fates.record(index, accepted);
                }
                None
            }
            Message::Session(SessionMessage::Measurement {
                step,
                y,
                applied_step,
                ..
            }) => {
                let y = (*y).into();
                let measured = self.session.as_mut().and_then(|session| {
                    session
                        .decoder
                        .on_measurement(*step, &y, *applied_step)
                        .ok()?
                });
                let mut decision = measured.as_ref().and_then(|m| m.decision);
                // The soft strategies decide by likelihood; the hard ones keep the decoder's bit.
                let llr = decision.filter(|_| self.soft()).and_then(|d| {
                    let [d0, d1] = d.hypotheses?;
                    Some(log_likelihood_ratio(&d.estimate, &d0, &d1))
                });
                if let (Some(decision), Some(llr)) = (decision.as_mut(), llr) {
                    decision.bit = Some(u8::from(llr > 0.0));
                }
                if let WheelModel::Learned(identifier) = &mut self.model {
                    let decided = decision.and_then(|d| d.bit);
                    identifier.on_measurement(*step, &y, *applied_step, decided);
                }
                for gap in measured?.missing {
                    self.settle(gap, None, 0.0);
                }
                let decision = decision?;
                self.settle(decision.step, decision.bit, llr.unwrap_or(0.0));
                Some(decision)
            }
            Message::Closing(Closing::Finish { codewords, bitmap }) => {
                let session = self.session.as_mut()?;
                for index in 0..(*codewords).min(session.fates.len()) {
                    let accepted = bitmap
                        .get(index as usize / 64)
                        .is_some_and(|w| w >> (index % 64) & 1 == 1);
                    session.fates.record(index, accepted);
                }
                None
            }
            Message::Closing(Closing::Confirm { key_tag, .. }) => {
                self.on_confirm(key_tag);
                None
            }
            _ => None,
        }
    }

    fn key(&self) -> KeyBits {
        let Some(session) = &self.session else {
            return KeyBits::default();
        };
        let k = session.plan.code.k();
        match &session.verified {
            Some(found) => session.fates.accepted_key(&found.messages, k),
            None => {
                let messages: Vec<u64> = session.decoded.iter().map(|d| d.message).collect();
                session.fates.accepted_key(&messages, k)
            }
        }
    }

    fn model(&self) -> DiffDrive {
        self.current_drive()
    }

    fn verified(&self) -> Option<u32> {
        self.session.as_ref()?.verified.as_ref().map(|m| m.flips)
    }
}
