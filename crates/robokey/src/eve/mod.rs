//! Eavesdroppers: strategies behind one interface, fed the same message stream as the
//! endpoints (a simulated session or a capture). See SECRECY.md §6.

mod mismatch;

pub use mismatch::{ModelErrors, PaperEve};

use rand::Rng;

use crate::config::{Config, EveStrategy};
use crate::protocol::{KeyBits, Message, SessionPlan, StepDecision};

/// A passive eavesdropper: she hears every message in order and never sends.
pub trait Eavesdropper: std::fmt::Debug + Send {
    /// Observes one message; returns her decision when a measurement decided a step.
    fn observe(&mut self, message: &Message) -> Option<StepDecision>;

    /// Her key `K_a`: her decoded messages of the codewords acked so far.
    fn key(&self) -> KeyBits;
}

/// The eavesdropper a configuration asks for; her random draws (model errors) come from
/// `rng` (the `eve` stream of the run).
pub fn build<R: Rng + ?Sized>(
    config: &Config,
    plan: &SessionPlan,
    rng: &mut R,
) -> Box<dyn Eavesdropper> {
    match config.eve.strategy {
        EveStrategy::Mismatch => {
            let errors = ModelErrors::draw(config.eve.alpha, config.eve.draw, rng);
            Box::new(PaperEve::new(config, plan, errors))
        }
        EveStrategy::Oracle => Box::new(PaperEve::new(config, plan, ModelErrors::default())),
    }
}
