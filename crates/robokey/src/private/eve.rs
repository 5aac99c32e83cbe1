//! The private-sensing eavesdroppers (docs/private-sensing.md, "Adversaries") on what they
//! can record: the frames on the network and, for the `camera` adversary, her own camera.
//! The simulator feeds them its transcript and camera samples; `robokey eve --capture` a
//! relay capture and the world's camera log. Same code, same decisions.

use std::collections::{BTreeMap, VecDeque};

use super::doublet::DoubletInputs;
use super::likelihood::{BitEvidence, DoubletModel, DoubletView, PoseObservation, doublet_model};
use crate::config::Config;
use crate::model::Pose;
use crate::protocol::{Closing, KeyBits, Message, SessionMessage, SessionPlan};

/// What both eavesdroppers make of one carrying doublet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EveDoublet {
    /// Doublet index j.
    pub doublet: u32,
    /// Its public inputs.
    pub inputs: DoubletInputs,
    /// The `camera` adversary's evidence: her camera at each step of the doublet, fused with
    /// the controller's boundary samples the commands carry.
    pub camera: BitEvidence,
    /// The `commands` adversary's evidence: the boundary samples alone.
    pub commands: BitEvidence,
}

/// What a command revealed about its step.
#[derive(Clone, Copy, Debug)]
struct Commanded {
    /// The controller's sample `y_c(k)`.
    sample: Pose,
    /// The inputs of the doublet it starts, if it starts one.
    inputs: Option<DoubletInputs>,
}

/// The `camera` and `commands` eavesdroppers of one session: exact model, every frame, and
/// her camera (`eve.camera_std`, her effective noise per sample instant).
#[derive(Debug)]
pub struct DoubletEavesdropper {
    plan: SessionPlan,
    model: DoubletModel,
    controller_std: [f64; 3],
    camera_std: [f64; 3],
    /// What the commands revealed, by step (pruned below the last decided doublet).
    commands: BTreeMap<u32, Commanded>,
    /// Her camera, by step (pruned likewise).
    camera: BTreeMap<u32, Pose>,
    /// Each doublet's decision `v | ω << 1` under each view, once decided.
    decided: Vec<Option<[u64; 2]>>,
    /// The kept doublets, once a `Finish` was heard.
    kept: Option<Vec<u64>>,
    ready: VecDeque<EveDoublet>,
}

impl DoubletEavesdropper {
    /// The eavesdroppers of a validated private-sensing configuration.
    #[must_use]
    pub fn new(config: &Config) -> Self {
        let plan = SessionPlan::from_config(config, 0);
        Self {
            decided: vec![None; plan.units() as usize],
            model: doublet_model(config),
            controller_std: config.sensing.controller_std,
            camera_std: config.eve.camera_std,
            commands: BTreeMap::new(),
            camera: BTreeMap::new(),
            kept: None,
            ready: VecDeque::new(),
            plan,
        }
    }

    /// A frame as heard on the network: commands reveal the controller's boundary samples
    /// and the doublets' inputs, the `Finish` which doublets were kept.
    pub fn observe(&mut self, message: &Message) {
        match message {
            Message::Session(SessionMessage::DoubletCommand {
                step,
                sample,
                first,
                second,
                ..
            }) if *step <= self.plan.agreed.steps => {
                let inputs = second
                    .filter(|_| self.plan.starts_doublet(*step))
                    .map(|second| DoubletInputs {
                        first: (*first).into(),
                        second: second.into(),
                    });
                self.commands.entry(*step).or_insert(Commanded {
                    sample: (*sample).into(),
                    inputs,
                });
                self.try_decide(*step);
            }
            Message::Closing(Closing::Finish { codewords, bitmap })
                if *codewords == self.plan.units() =>
            {
                self.kept.get_or_insert_with(|| bitmap.clone());
            }
            _ => {}
        }
    }

    /// Her camera's sample `y_e(k)`.
    pub fn film(&mut self, step: u32, pose: Pose) {
        if step <= self.plan.agreed.steps && pose.iter().all(|v| v.is_finite()) {
            self.camera.entry(step).or_insert(pose);
            self.try_decide(step);
        }
    }

    /// The next doublet decided, in the order the data completed them.
    pub fn poll(&mut self) -> Option<EveDoublet> {
        self.ready.pop_front()
    }

    /// An eavesdropper's key: her decisions on the kept doublets, `[v, ω]` each (a kept
    /// doublet she could not decide counts as 0); empty before a `Finish` was heard.
    /// `camera` picks the `camera` adversary's decisions, else the `commands` one's.
    #[must_use]
    pub fn key(&self, camera: bool) -> KeyBits {
        let bits = self.plan.bits_per_unit();
        let mut key = KeyBits::default();
        let Some(kept) = &self.kept else {
            return key;
        };
        for (j, decided) in self.decided.iter().enumerate() {
            if kept.get(j / 64).is_some_and(|w| w >> (j % 64) & 1 == 1) {
                let word = decided.map_or(0, |d| d[usize::from(!camera)]);
                key.extend((0..bits).map(|i| (word >> i & 1) as u8));
            }
        }
        key
    }

    /// Decides the doublets that step `step`'s data may have completed (`step` is the
    /// start, middle or end of at most two).
    fn try_decide(&mut self, step: u32) {
        // The earlier doublet first: deciding one prunes what lies before its start.
        for j in [(step / 2).wrapping_sub(1), step / 2] {
            if let Some(doublet) = self.decide(j) {
                self.ready.push_back(doublet);
                // Nothing before this doublet's start is needed any more.
                self.commands = self.commands.split_off(&(2 * j));
                self.camera = self.camera.split_off(&(2 * j));
            }
        }
    }

    fn decide(&mut self, j: u32) -> Option<EveDoublet> {
        if self.decided.get(j as usize)?.is_some() {
            return None;
        }
        let k = 2 * j;
        let start = self.commands.get(&k)?;
        let inputs = start.inputs.filter(|i| self.plan.carries(i))?;
        let end = self.commands.get(&(k + 2))?;
        let filmed = [
            *self.camera.get(&k)?,
            *self.camera.get(&(k + 1))?,
            *self.camera.get(&(k + 2))?,
        ];
        let c = |pose: Pose| PoseObservation::new(pose, self.controller_std);
        let e = |i: usize| PoseObservation::new(filmed[i], self.camera_std);
        let camera = self.model.evidence(
            &inputs,
            &DoubletView {
                start: c(start.sample).fuse(&e(0)),
                middle: Some(e(1)),
                end: Some(c(end.sample).fuse(&e(2))),
            },
        );
        let commands = self.model.evidence(
            &inputs,
            &DoubletView {
                start: c(start.sample),
                middle: None,
                end: Some(c(end.sample)),
            },
        );
        self.decided[j as usize] = Some([camera.bits(), commands.bits()]);
        Some(EveDoublet {
            doublet: j,
            inputs,
            camera,
            commands,
        })
    }
}
