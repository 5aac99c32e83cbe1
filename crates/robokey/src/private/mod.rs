//! Private sensing (docs/private-sensing.md): the controller decides from its own pose
//! sensor, the robot sends no pose, and each key bit rides on a doublet (`+s·Δ` then
//! `−s·Δ`, or with a prior lag `+s·Δ`, `−(1 + a)·s·Δ`, `+a·s·Δ`) whose commands come from the
//! doublet's boundary samples. An eavesdropper films
//! the robot with her own, noisier camera: the wiretap assumption that makes a secret key
//! possible.

pub(crate) mod controller;
pub mod decision;
mod dgemm;
pub mod doublet;
pub mod eve;
pub mod gram_filter;
pub mod likelihood;
mod lu;
pub mod plan;
mod product;
pub(crate) mod robot;
pub mod smoother;
pub mod window;

use serde::Serialize;

use crate::config::EveStrategy;
use crate::protocol::KeyBits;

pub(crate) use controller::PrivateController;
pub use decision::DoubletDecision;
pub use doublet::{CommandRounding, DoubletInputs, Perturbation};
pub use eve::{DoubletEavesdropper, Eavesdroppers, EveDoublet};
pub use likelihood::{
    BitEvidence, DoubletModel, DoubletView, PoseObservation, doublet_model, doublet_model_with,
};
pub use plan::PrivatePlan;
pub(crate) use robot::PrivateRobot;
pub use smoother::{DEFAULT_HALF_WIDTH, WindowSmoother};

/// Which input a bit rides on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BitKind {
    /// `±Δv` (the first bit of every doublet).
    V,
    /// `±Δω` (the second, with two bits per doublet).
    Omega,
}

impl BitKind {
    /// In the order they ride in a doublet.
    pub const ALL: [Self; 2] = [Self::V, Self::Omega];
}

/// One key bit of a private session and what every party made of it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DoubletBit {
    /// The doublet's first step `Lj` (`L` steps per doublet).
    pub step: u32,
    /// Which input it rides on.
    pub kind: BitKind,
    /// The robot's bit.
    pub bit: u8,
    /// The doublet's public nominal turn rate (rad/s).
    pub turn_rate: f64,
    /// The controller's LLR `ln P(view|0) − ln P(view|1)`: with `protocol.levels > 2`, given
    /// the robot's bits of its symbol's lower slices, as multistage reconciliation decodes
    /// it ([`likelihood::staged_llrs`]).
    pub controller: f64,
    /// The camera Eve's LLR.
    pub camera: f64,
    /// The commands Eve's LLR; none when the simulation did not judge her
    /// ([`Eavesdroppers::Camera`]).
    pub commands: Option<f64>,
    /// The bit's separation `d` under the camera Eve's model (her LLR ~ N(±d²/2, d²)).
    pub camera_separation: f64,
    /// The camera Eve's separation as the controller can compute it — her stated camera
    /// noise, the controller's own samples for the path — which sizes the key: never from
    /// her realised view.
    pub assumed_separation: f64,
    /// Its separation under the commands Eve's model: the residual leak the model predicts;
    /// none when she was not judged.
    pub commands_separation: Option<f64>,
}

/// What the controller saw of one carrying doublet, kept for the block's estimate of the
/// motion noise (docs/estimation.md). Key material: never printed.
#[derive(Clone, Copy, PartialEq)]
pub struct DoubletSamples {
    /// Doublet index j.
    pub doublet: u32,
    /// Its public inputs.
    pub inputs: DoubletInputs,
    /// The controller's samples `y(Lj), y(Lj+1), y(Lj+L)` (start, after the first step, end).
    pub samples: [crate::model::Pose; 3],
    /// The bit pattern the doublet carried, `v | ω << 1`: the robot's bits, which
    /// reconciliation gives the controller.
    pub pattern: usize,
    /// A three-step doublet's sample after its second step and its entry speed (`None`
    /// with two steps, and where the pool kept only the three samples above).
    pub late: Option<LateSample>,
}

/// What a three-step doublet keeps beyond its start, first-step and end samples: the
/// controller's sample `y(3j+2)` after the shape's second step, where the bit's travel
/// through the lag is largest, and the wheels' nominal speed at the doublet's start
/// through the prior lag, with which the online decision took it (docs/estimation.md,
/// "The lag" and "Causality").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LateSample {
    /// `y(3j+2)` (m, m, rad).
    pub sample: crate::model::Pose,
    /// The wheels' nominal speed at the doublet's start under `private.prior_lag` (m/s,
    /// rad/s): [`DoubletView::entry`] of the online decision.
    pub entry: crate::model::Unicycle,
}

/// Reading the `commands` eavesdropper's evidence from a run that did not judge her is a
/// caller's error: it simulates for the eavesdroppers it reads.
const NOT_JUDGED: &str = "the run was simulated with the commands eavesdropper judged";

impl DoubletBit {
    /// The LLR of a private-mode eavesdropper (`camera` for any other strategy).
    ///
    /// # Panics
    /// For the `commands` one, when the simulation did not judge her ([`Eavesdroppers`]).
    #[must_use]
    pub fn llr_of(&self, strategy: EveStrategy) -> f64 {
        match strategy {
            EveStrategy::Commands => self.commands.expect(NOT_JUDGED),
            _ => self.camera,
        }
    }

    /// The model separation of a private-mode eavesdropper.
    ///
    /// # Panics
    /// As [`Self::llr_of`].
    #[must_use]
    pub fn separation_of(&self, strategy: EveStrategy) -> f64 {
        match strategy {
            EveStrategy::Commands => self.commands_separation.expect(NOT_JUDGED),
            _ => self.camera_separation,
        }
    }
}

/// What a private session carried, beyond the keys.
#[derive(Clone, Default, PartialEq)]
pub struct PrivateRun {
    /// Doublets commanded.
    pub doublets: u32,
    /// Doublets the turn gate left without a bit.
    pub gated: u32,
    /// Every bit carried, in order.
    pub bits: Vec<DoubletBit>,
    /// The controller's samples of every carrying doublet, in order.
    pub controller_samples: Vec<DoubletSamples>,
    /// The `camera` eavesdropper's key, when Eve listened (key material: never printed).
    pub camera_key: Option<KeyBits>,
    /// The `commands` eavesdropper's key, when Eve listened and the simulation judged her
    /// (key material: never printed). With [`Self::camera_key`], one simulation judging
    /// [`Eavesdroppers::Both`] serves an analysis of either, whichever the configuration
    /// names (the run's `keys.eve` is that one's).
    pub commands_key: Option<KeyBits>,
}

impl PrivateRun {
    /// An empty run whose bits and samples are sized for a session of `steps` steps under
    /// `plan`, so that they are not copied as they grow: at most `⌊N / L⌋` carrying
    /// doublets, each with `key_bits` bits.
    #[must_use]
    pub fn sized_for(plan: &PrivatePlan, steps: u32) -> Self {
        let doublets = (steps / plan.steps_per_doublet()) as usize;
        Self {
            bits: Vec::with_capacity(doublets * plan.perturbation.key_bits()),
            controller_samples: Vec::with_capacity(doublets),
            ..Self::default()
        }
    }

    /// The key of a private-mode eavesdropper (`camera` for any other strategy); none when
    /// Eve did not listen or, for the `commands` one, was not judged.
    #[must_use]
    pub fn eve_key(&self, strategy: EveStrategy) -> Option<&KeyBits> {
        match strategy {
            EveStrategy::Commands => self.commands_key.as_ref(),
            _ => self.camera_key.as_ref(),
        }
    }
}

impl std::fmt::Debug for PrivateRun {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // The controller's samples are key material: never printed.
        f.debug_struct("PrivateRun")
            .field("doublets", &self.doublets)
            .field("gated", &self.gated)
            .field("bits", &self.bits)
            .finish()
    }
}
