//! Eavesdroppers: strategies behind one interface, fed the same message stream as the
//! endpoints (simulated sessions or a capture). See docs/threat-model.md and docs/secrecy.md.

mod adversary;
mod identify;
mod mismatch;
mod tag_search;

pub use adversary::Eve;
pub use identify::WheelIdentifier;
pub use mismatch::ModelErrors;
pub use tag_search::{TagMatch, search_key};

use rand::{Rng, RngExt};

use crate::config::{Config, EveStrategy};
use crate::model::DiffDrive;
use crate::protocol::{KeyBits, Message, SessionPlan, StepDecision};

/// A passive eavesdropper: she hears every message in order and never sends. What she
/// learns about the robot carries over from one session to the next.
pub trait Eavesdropper: std::fmt::Debug + Send {
    /// Starts listening to a new session.
    fn begin_session(&mut self, plan: &SessionPlan);

    /// Observes one message; returns her decision when a measurement decided a step.
    fn observe(&mut self, message: &Message) -> Option<StepDecision>;

    /// Her key `K_a` of the current session: her messages of the codewords acked so far.
    fn key(&self) -> KeyBits;

    /// Her current wheel model (m).
    fn model(&self) -> DiffDrive;

    /// Codewords she flipped to match the session's confirmation tag, once she has
    /// verified her key against it.
    fn verified(&self) -> Option<u32>;
}

/// Eve's starting relative model errors for `config`'s strategy, drawn from `rng` (the
/// `eve` stream): none for the oracle; up to α on r, D, W, V for `mismatch` and `soft`;
/// `initial_error` on r and D with random signs for the learning strategies.
pub fn starting_errors<R: Rng + ?Sized>(config: &Config, rng: &mut R) -> ModelErrors {
    let eve = &config.eve;
    match config.eve_strategy() {
        // The private mode's eavesdroppers know the model exactly.
        EveStrategy::Oracle | EveStrategy::Camera | EveStrategy::Commands => ModelErrors::default(),
        EveStrategy::Mismatch | EveStrategy::Soft => ModelErrors::draw(eve.alpha, eve.draw, rng),
        EveStrategy::Identify | EveStrategy::Transcript => {
            let mut signed = || {
                if rng.random_bool(0.5) {
                    eve.initial_error
                } else {
                    -eve.initial_error
                }
            };
            ModelErrors {
                r: signed(),
                d: signed(),
                w: 0.0,
                v: 0.0,
            }
        }
    }
}

/// The eavesdropper a configuration asks for, her starting errors drawn from `rng`.
pub fn build<R: Rng + ?Sized>(config: &Config, rng: &mut R) -> Box<dyn Eavesdropper> {
    let errors = starting_errors(config, rng);
    Box::new(Eve::new(config, config.eve_strategy(), errors))
}

/// Feeds `eve` one session's messages in order, as session `plan.session`, and returns her
/// key; `on_decision` sees her after every step she decided.
pub fn hear<E: Eavesdropper + ?Sized>(
    eve: &mut E,
    plan: &SessionPlan,
    transcript: &[Message],
    mut on_decision: impl FnMut(&E, &StepDecision),
) -> KeyBits {
    eve.begin_session(plan);
    for message in transcript {
        if let Some(decision) = eve.observe(message) {
            on_decision(eve, &decision);
        }
    }
    eve.key()
}
