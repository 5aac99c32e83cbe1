//! The private-sensing eavesdroppers (docs/private-sensing.md, "Adversaries"; docs/world.md)
//! on what they can record: the frames on the network and, for the `camera` adversary, her
//! own camera. They know the world: its motion noise, its controller sensor, its camera. The
//! simulator feeds them its transcript and camera; `robokey eve --capture` a relay capture
//! and the world's camera log. Same code, same decisions.
//!
//! Where the world lets a doublet's boundary samples screen it from its neighbours (white
//! noise of at least the controller's sensor noise over a doublet, the Euler map, no lag,
//! delay, slip, quanta or jitter, a camera at the instants), each doublet is decided from the
//! samples around it; elsewhere by the [`WindowSmoother`] over `±2` doublets and, below the
//! sensor noise, the boundary samples of [`crate::world::WorldModel::sample_reach`] doublets
//! beyond; when `eve.smoother_window` asks for it, over exactly `±W` doublets.

use std::collections::{BTreeMap, VecDeque};

use super::doublet::{CommandRounding, DoubletInputs};
use super::likelihood::{
    BitEvidence, DoubletModel, DoubletView, PoseObservation, doublet_model_with,
};
use super::smoother::{Commanded, DEFAULT_HALF_WIDTH, Recorded, WindowSmoother};
use crate::config::{Config, EveStrategy};
use crate::model::Pose;
use crate::protocol::{Closing, KeyBits, Message, SessionMessage, SessionPlan};
use crate::world::{Camera, Frame};

/// Whose judgement of each doublet a [`DoubletEavesdropper`] computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Eavesdroppers {
    /// The `camera` and the `commands` eavesdroppers'.
    Both,
    /// The `camera` eavesdropper's alone, for a caller that never reads the `commands` one's
    /// (her evidence, decisions and key are then not computed: none, never zeros).
    Camera,
}

impl Eavesdroppers {
    /// What a caller that reads only `strategy`'s evidence, decisions and key needs judged.
    #[must_use]
    pub fn reading(strategy: EveStrategy) -> Self {
        match strategy {
            EveStrategy::Commands => Self::Both,
            _ => Self::Camera,
        }
    }
}

/// What the eavesdroppers make of one carrying doublet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EveDoublet {
    /// Doublet index j.
    pub doublet: u32,
    /// Its public inputs.
    pub inputs: DoubletInputs,
    /// The `camera` adversary's evidence: her camera, fused with the controller's boundary
    /// samples the commands carry.
    pub camera: BitEvidence,
    /// The `commands` adversary's evidence: the boundary samples alone; none when she is not
    /// judged ([`Eavesdroppers::Camera`]).
    pub commands: Option<BitEvidence>,
    /// The `camera` adversary's evidence given also the true bits of every other doublet
    /// acting on its window (revealed for this measurement, never to decide with): her view
    /// of each bit as if she knew the rest of the block, which errs on her side — the sum
    /// over a block of `H(B_j | E, B_{≠j})` is at most `H(B | E)`. Where doublets are
    /// screened it is `camera`; none when those bits were not revealed.
    pub camera_given_others: Option<BitEvidence>,
    /// The same for the `commands` adversary (none also when she is not judged).
    pub commands_given_others: Option<BitEvidence>,
}

impl EveDoublet {
    /// The `camera` adversary's evidence (`camera`) or the `commands` one's: her own and, when
    /// the other bits were revealed, given them; none when she was not judged.
    #[must_use]
    pub fn of(&self, camera: bool) -> Option<(BitEvidence, Option<BitEvidence>)> {
        if camera {
            Some((self.camera, self.camera_given_others))
        } else {
            Some((self.commands?, self.commands_given_others))
        }
    }
}

/// How the eavesdroppers weigh what they recorded.
#[derive(Debug)]
enum View {
    /// Each doublet from its own samples (a world where they screen it).
    PerDoublet {
        model: DoubletModel,
        controller_std: [f64; 3],
        camera_std: [f64; 3],
    },
    /// Each doublet from a window of its neighbours, in order.
    Window {
        smoother: Box<WindowSmoother>,
        /// Seconds between her frames, when she films between the instants.
        frame_interval: Option<f64>,
    },
}

/// The `camera` and `commands` eavesdroppers of one session: the world's model, every frame
/// on the network, and her camera.
#[derive(Debug)]
pub struct DoubletEavesdropper {
    plan: SessionPlan,
    view: View,
    /// Whose judgements are computed.
    judged: Eavesdroppers,
    /// What the commands revealed, by step (pruned below what is still needed).
    commands: BTreeMap<u32, Commanded>,
    /// Her camera at the instants, by step (pruned likewise).
    camera: BTreeMap<u32, Pose>,
    /// Her frames between the instants, in time order (pruned likewise).
    frames: Vec<Frame>,
    /// Each doublet's decision `v | ω << 1` by the `camera` and (when judged) the `commands`
    /// eavesdropper, once decided.
    decided: Vec<Option<(u64, Option<u64>)>>,
    /// The kept doublets, once a `Finish` was heard.
    kept: Option<Vec<u64>>,
    ready: VecDeque<EveDoublet>,
    /// The window view: the next doublet to decide.
    next: u32,
    /// No more data will come: decide what is left with what there is.
    finished: bool,
    /// The robot's true bits of each doublet, where revealed (a measurement: see
    /// [`EveDoublet::camera_given_others`]).
    truth: Vec<Option<u64>>,
}

impl DoubletEavesdropper {
    /// The eavesdroppers of a validated private-sensing configuration, in its world, judging
    /// each doublet for those `judged` names.
    #[must_use]
    pub fn new(config: &Config, judged: Eavesdroppers) -> Self {
        let plan = SessionPlan::from_config(config, 0);
        let world = config.world_model();
        let view = match (world.camera, config.eve.smoother_window) {
            (Camera::Instants { std }, None) if world.screens_doublets() => View::PerDoublet {
                // Her model's lag and rounding are the world's (none where doublets are
                // screened).
                model: DoubletModel {
                    lag: world.lag,
                    rounding: CommandRounding::new(config.robot.drive(), world.command_quantum),
                    ..doublet_model_with(config, world.process_std)
                },
                controller_std: world.controller_std,
                camera_std: std,
            },
            (camera, half_width) => View::Window {
                // A window asked for is exactly ±W doublets; else ±2 and the boundary
                // samples as far as they still pin the window's (the motion noise's reach).
                smoother: Box::new(match half_width {
                    Some(w) => WindowSmoother::new(config, &world, w, 0),
                    None => WindowSmoother::new(
                        config,
                        &world,
                        DEFAULT_HALF_WIDTH,
                        world.sample_reach(),
                    ),
                }),
                frame_interval: match camera {
                    Camera::Frames { fps, .. } => Some(1.0 / fps),
                    Camera::Instants { .. } => None,
                },
            },
        };
        Self {
            decided: vec![None; plan.units() as usize],
            view,
            judged,
            commands: BTreeMap::new(),
            camera: BTreeMap::new(),
            frames: Vec::new(),
            kept: None,
            ready: VecDeque::new(),
            next: 0,
            finished: false,
            truth: vec![None; plan.units() as usize],
            plan,
        }
    }

    /// Reveals doublet `j`'s true bit word (the robot's draws, `v | ω << m`) — never to
    /// decide with: to measure her view of each bit given the rest of the block
    /// ([`EveDoublet::camera_given_others`]).
    pub fn reveal(&mut self, j: u32, word: u64) {
        if let Some(slot) = self.truth.get_mut(j as usize) {
            *slot = Some(word);
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

    /// Her camera's sample `y_e(k)` at sample instant `k`.
    pub fn film(&mut self, step: u32, pose: Pose) {
        if step <= self.plan.agreed.steps && pose.iter().all(|v| v.is_finite()) {
            self.camera.entry(step).or_insert(pose);
            self.try_decide(step);
        }
    }

    /// One frame of her camera filming between the instants (frames come in time order; a
    /// frame older than the last is ignored).
    pub fn film_frame(&mut self, frame: Frame) {
        let end = f64::from(self.plan.agreed.steps) * self.plan.agreed.sample_time;
        let in_order = self.frames.last().is_none_or(|last| frame.time > last.time);
        let valid = frame.time.is_finite() && frame.time >= 0.0 && frame.time <= end;
        if in_order && valid && frame.pose.iter().all(|v| v.is_finite()) {
            self.frames.push(frame);
            self.try_decide(self.plan.agreed.steps);
        }
    }

    /// No more data will come: decides every doublet left with what was recorded.
    pub fn finish(&mut self) {
        self.finished = true;
        self.try_decide(self.plan.agreed.steps);
    }

    /// The next doublet decided, in the order the data completed them.
    pub fn poll(&mut self) -> Option<EveDoublet> {
        self.ready.pop_front()
    }

    /// An eavesdropper's key: her decisions on the kept doublets, `[v, ω]` each (a kept
    /// doublet she could not decide counts as 0); empty before a `Finish` was heard.
    /// `camera` picks the `camera` adversary's decisions, else the `commands` one's: none
    /// when she is not judged.
    #[must_use]
    pub fn key(&self, camera: bool) -> Option<KeyBits> {
        if !camera && self.judged == Eavesdroppers::Camera {
            return None;
        }
        let bits = self.plan.bits_per_unit();
        let mut key = KeyBits::default();
        let Some(kept) = &self.kept else {
            return Some(key);
        };
        for (j, decided) in self.decided.iter().enumerate() {
            if kept.get(j / 64).is_some_and(|w| w >> (j % 64) & 1 == 1) {
                let word = decided
                    .and_then(|(camera_word, commands_word)| {
                        if camera {
                            Some(camera_word)
                        } else {
                            commands_word
                        }
                    })
                    .unwrap_or(0);
                key.extend((0..bits).map(|i| (word >> i & 1) as u8));
            }
        }
        Some(key)
    }

    /// `L`, the steps per doublet.
    fn doublet_steps(&self) -> u32 {
        self.plan.steps_per_doublet()
    }

    /// Decides the doublets that the data of step `step` may have completed.
    fn try_decide(&mut self, step: u32) {
        if let View::PerDoublet { .. } = self.view {
            // `step` is the start, a middle or the end of at most two; the earlier first:
            // deciding one prunes what lies before its start.
            let length = self.doublet_steps();
            for j in [(step / length).wrapping_sub(1), step / length] {
                if let Some(doublet) = self.decide_alone(j) {
                    self.ready.push_back(doublet);
                    self.commands = self.commands.split_off(&(length * j));
                    self.camera = self.camera.split_off(&(length * j));
                }
            }
            return;
        }
        let doublets = self.plan.units();
        while self.next < doublets && (self.finished || self.window_complete(self.next)) {
            let j = self.next;
            self.next += 1;
            if let Some(doublet) = self.decide_in_window(j) {
                self.ready.push_back(doublet);
            }
        }
        self.prune();
    }

    /// Whether everything doublet `j`'s full window needs has been recorded: the commands
    /// of its doublets, of those whose boundary samples it reaches, and of the one after,
    /// and her camera up to that instant.
    fn window_complete(&self, j: u32) -> bool {
        let View::Window {
            smoother,
            frame_interval,
        } = &self.view
        else {
            return false;
        };
        let doublets = self.plan.units();
        let length = self.doublet_steps();
        let last = (j + smoother.half_width() + smoother.reach()).min(doublets.saturating_sub(1));
        let end = length * last + length;
        let commands = (j..=last).all(|i| self.commands.contains_key(&(length * i)))
            && self.commands.contains_key(&end);
        let filmed = match frame_interval {
            None => self.camera.contains_key(&end),
            Some(interval) => {
                let until = f64::from(end) * self.plan.agreed.sample_time;
                self.frames
                    .last()
                    .is_some_and(|f| f.time + interval >= until - 1e-9)
            }
        };
        commands && filmed
    }

    /// Drops what no undecided doublet's window needs.
    fn prune(&mut self) {
        let View::Window { smoother, .. } = &self.view else {
            return;
        };
        let back = smoother.half_width() + smoother.reach() + smoother.lead() + 1;
        let keep = self.doublet_steps() * self.next.saturating_sub(back);
        self.commands = self.commands.split_off(&keep);
        self.camera = self.camera.split_off(&keep);
        let from = f64::from(keep) * self.plan.agreed.sample_time;
        let stale = self.frames.partition_point(|f| f.time < from);
        self.frames.drain(..stale);
    }

    fn decide_in_window(&mut self, j: u32) -> Option<EveDoublet> {
        let View::Window { smoother, .. } = &self.view else {
            return None;
        };
        let recorded = Recorded {
            plan: &self.plan,
            commands: &self.commands,
            camera: &self.camera,
            frames: &self.frames,
        };
        let inputs = self.commands.get(&(self.doublet_steps() * j))?.inputs?;
        let truth = &self.truth;
        let revealed = |i: u32| truth.get(i as usize).copied().flatten();
        let judge_commands = self.judged == Eavesdroppers::Both;
        let (camera, commands) = smoother.evidence(j, &recorded, &revealed, judge_commands)?;
        self.decided[j as usize] = Some((camera.own.bits(), commands.map(|c| c.own.bits())));
        Some(EveDoublet {
            doublet: j,
            inputs,
            camera: camera.own,
            commands: commands.map(|c| c.own),
            camera_given_others: camera.given_others,
            commands_given_others: commands.and_then(|c| c.given_others),
        })
    }

    fn decide_alone(&mut self, j: u32) -> Option<EveDoublet> {
        let View::PerDoublet {
            model,
            controller_std,
            camera_std,
        } = &self.view
        else {
            return None;
        };
        if self.decided.get(j as usize)?.is_some() {
            return None;
        }
        let length = self.doublet_steps();
        let k = length * j;
        let start = self.commands.get(&k)?;
        let inputs = start.inputs.filter(|i| self.plan.carries(i))?;
        let end = self.commands.get(&(k + length))?;
        let mut filmed = [Pose::zeros(); 4];
        for (i, slot) in filmed.iter_mut().enumerate().take(length as usize + 1) {
            *slot = *self.camera.get(&(k + i as u32))?;
        }
        let last = length as usize;
        let c = |pose: Pose| PoseObservation::new(pose, *controller_std);
        let e = |i: usize| PoseObservation::new(filmed[i], *camera_std);
        let camera_view = DoubletView {
            start: c(start.sample).fuse(&e(0)),
            middle: Some(e(1)),
            late: (last == 3).then(|| e(2)),
            end: Some(c(end.sample).fuse(&e(last))),
            entry: None,
        };
        let commands_view = DoubletView {
            start: c(start.sample),
            middle: None,
            late: None,
            end: Some(c(end.sample)),
            entry: None,
        };
        let camera = model.evidence(&inputs, &camera_view);
        let commands =
            (self.judged == Eavesdroppers::Both).then(|| model.evidence(&inputs, &commands_view));
        self.decided[j as usize] = Some((camera.bits(), commands.map(|c| c.bits())));
        // A multilevel symbol's bits are judged in a chain, each given the true ones before
        // it, so that her realised bound is on the symbols; a binary doublet's bits as they
        // are.
        let truth = self.truth.get(j as usize).copied().flatten();
        let chained = model.perturbation.levels > 2;
        let given = |own: BitEvidence, view: &DoubletView| {
            if !chained {
                return Some(own);
            }
            truth.map(|word| BitEvidence {
                llr: model.chain_llrs(&inputs, view, word),
                separation: own.separation,
            })
        };
        let camera_given_others = given(camera, &camera_view);
        let commands_given_others = commands.and_then(|own| given(own, &commands_view));
        Some(EveDoublet {
            doublet: j,
            inputs,
            camera,
            commands,
            camera_given_others,
            commands_given_others,
        })
    }
}
