//! The world-aware eavesdroppers' window smoother (docs/world.md, "The window smoother").
//!
//! With correlated noise, lag, delay or slip, a camera filming between the instants, or
//! motion noise below the controller's sensor noise, the controller's boundary samples no
//! longer screen a doublet from its neighbours. For doublet `j` Eve takes the doublets
//! `j − W … j + W` (fewer at the session's ends or where commands are missing) and everything
//! she observed over them: the boundary samples the commands carry (noise
//! `world.controller_std`, timing error `world.jitter`), and — the `camera` adversary — every
//! frame of her camera; and the boundary samples of `reach` doublets beyond each side (their
//! bits Gaussian like the lead's in her decision, known given the others), a forward and a
//! backward pass over the samples that pin the window's boundaries. Her model is the world's, linearised about the
//! noise-free path she simulates with the world's own code:
//!
//! - the pose at the window's start is the controller's sample there, off by its noise;
//! - each step's noise is a latent vector: the AR(1) innovation `e_k` (carrying `w_{k−1}`
//!   between steps when ρ ≠ 0) and each wheel's slip `z`;
//! - the means are the simulated path under the nominal inputs, plus each doublet's bit
//!   effect; the doublet's own bits are hypotheses (with the slip's covariance of that
//!   pattern), the window's other bits are summed over exactly, and the bits of the
//!   doublets before the window — which still act through the lag and the delay — are
//!   Gaussian with their exact second moment.
//!
//! `ln p(y | h) = ln Σ_s exp(−½·(r_h − G·s)ᵀΣ_h⁻¹(r_h − G·s)) − ½·ln det Σ_h`, from the Gram
//! matrix of a [`GramFilter`] pass per covariance. Calibrated like the per-doublet view (the
//! tests check it on non-default worlds) and deterministic.

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector, Matrix3, Matrix3xX, Vector3};

use super::doublet::{DoubletInputs, Perturbation, sign};
use super::gram_filter::{GramFilter, ln_sum_exp};
use super::likelihood::{BitEvidence, chained_llrs};
use super::product::product_to;
use super::window::{Instant, Window, WindowRun, WindowWorld, pose_at};
use crate::config::Config;
use crate::model::{Pose, Unicycle, WheelSpeeds};
use crate::protocol::SessionPlan;
use crate::world::{Camera, Frame, SubStep, WorldModel, sinc};

/// What a command revealed about its step.
#[derive(Clone, Copy, Debug)]
pub struct Commanded {
    /// The controller's sample `y_c(k)` it was computed from.
    pub sample: Pose,
    /// The inputs of the doublet it starts, if it starts one.
    pub inputs: Option<DoubletInputs>,
}

/// Everything an eavesdropper recorded of a session so far.
#[derive(Clone, Copy, Debug)]
pub struct Recorded<'a> {
    /// The session's public plan.
    pub plan: &'a SessionPlan,
    /// What the commands revealed, by step.
    pub commands: &'a BTreeMap<u32, Commanded>,
    /// Her camera at the sample instants, by step (a camera at the instants).
    pub camera: &'a BTreeMap<u32, Pose>,
    /// Her frames in time order (a camera filming between the instants).
    pub frames: &'a [Frame],
}

/// Default half-width `W` of the window, in doublets each side: the information per bit has
/// converged by then on the worlds of docs/world.md (measured there).
pub const DEFAULT_HALF_WIDTH: u32 = 2;

/// The window smoother of one session's world.
#[derive(Clone, Debug)]
pub struct WindowSmoother {
    eve: WindowWorld,
    perturbation: Perturbation,
    half_width: u32,
    /// Doublets each side beyond the window whose boundary samples she also takes
    /// ([`WorldModel::sample_reach`]): their bits Gaussian in her own decision, known given
    /// the others.
    reach: u32,
    /// Doublets before the window whose bits still act on it (lag, delay).
    lead: u32,
    sample_time: f64,
}

/// One observation in the window: when, what she saw, its noise.
struct Observation {
    instant: Instant,
    value: Pose,
    noise_inverse: Matrix3<f64>,
}

/// A window simulated under every bit pattern of its carrying doublets.
struct Simulated {
    /// Its first doublet (of the samples' reach).
    first: u32,
    /// The doublets whose bits are summed over exactly: the window proper.
    exact: (u32, u32),
    /// Its steps.
    steps: usize,
    /// The nominal run (no bits).
    nominal: WindowRun,
    /// Each carrying doublet's runs, one per bit pattern.
    runs: Vec<Vec<Perturbed>>,
    /// The carrying doublets and their positions among the simulated ones.
    carrying: Vec<(u32, usize)>,
    /// The target's index among the carrying.
    target: usize,
}

/// Doublet `j`'s evidence, on her own and given the other doublets' true bits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Judged {
    /// From what she recorded alone: her decision.
    pub own: BitEvidence,
    /// Given also the true bits of every other doublet acting on the window (when known):
    /// `P(b_j | view, b_{≠j})`; with multilevel symbols each bit's LLR also given the true
    /// bits before it in its doublet, so that they sum to her surprisal of the symbols.
    /// Over a block, `Σ_j H(B_j | E, B_{≠j}) ≤ H(B | E)`: her uncertainty counted this way
    /// errs on her side.
    pub given_others: Option<BitEvidence>,
}

/// Another carrying doublet acting on the window, and its effect columns with the sign
/// recipe of each (which of its bits multiply: v, ω, or both).
struct Other {
    doublet: u32,
    in_window: bool,
    columns: Vec<(usize, Vec<usize>)>,
}

/// An observation sequence run through the Gram filter: its value at each observation, and
/// the offset its state takes on entering each window step (where the path restarts).
struct Column {
    values: Vec<Vector3<f64>>,
    shifts: Vec<Vector3<f64>>,
}

/// The window's run under one doublet's bit pattern: its steps from `from` on simulated
/// (`part`, as many steps as it has), the nominal run's elsewhere — read from the nominal run
/// rather than copied.
struct Perturbed {
    from: usize,
    part: WindowRun,
    /// Per window step, as [`WindowRun::jumps`].
    jumps: Vec<Pose>,
}

impl Perturbed {
    /// A run of the whole window.
    fn whole(mut run: WindowRun) -> Self {
        Self {
            from: 0,
            jumps: std::mem::take(&mut run.jumps),
            part: run,
        }
    }

    /// The run holding window step `step`, and the step's index in it.
    fn source<'a>(&'a self, nominal: &'a WindowRun, step: usize) -> (&'a WindowRun, usize) {
        match step.checked_sub(self.from) {
            Some(i) if i < self.part.poses.len() => (&self.part, i),
            _ => (nominal, step),
        }
    }

    /// Window step `step`'s pose updates.
    fn updates<'a>(&'a self, nominal: &'a WindowRun, step: usize) -> &'a [SubStep] {
        let (run, i) = self.source(nominal, step);
        &run.updates[i]
    }

    /// The pose at an observation.
    fn at(&self, nominal: &WindowRun, instant: Instant) -> Pose {
        pose_at(
            nominal.poses.len(),
            |step| {
                let (run, i) = self.source(nominal, step);
                &run.poses[i]
            },
            instant,
        )
    }
}

/// A run's deviation from the nominal one: at each observation, and in its jump where each
/// window step restarts.
struct Deviation {
    values: Vec<Vector3<f64>>,
    jumps: Vec<Vector3<f64>>,
}

impl Deviation {
    /// `run − nominal` at the observations (the nominal poses there given as `bases`) and
    /// in the jumps.
    fn of(
        run: &Perturbed,
        nominal: &WindowRun,
        observations: &[Observation],
        bases: &[Pose],
    ) -> Self {
        Self {
            values: observations
                .iter()
                .zip(bases)
                .map(|(o, base)| run.at(nominal, o.instant) - base)
                .collect(),
            jumps: run
                .jumps
                .iter()
                .zip(&nominal.jumps)
                .map(|(jump, base)| jump - base)
                .collect(),
        }
    }
}

impl Column {
    /// The column of a combination of runs, `Σ w·(run − nominal)` over `weights` in order
    /// (from zero) at each of the `observations`, its shifts the negated combination of the
    /// jumps over the window's `steps`.
    fn derived(weights: &[(&Deviation, f64)], observations: usize, steps: usize) -> Self {
        Self {
            values: (0..observations)
                .map(|o| weights.iter().map(|(d, w)| d.values[o] * *w).sum())
                .collect(),
            shifts: (0..steps)
                .map(|s| {
                    -weights
                        .iter()
                        .map(|(d, w)| d.jumps[s] * *w)
                        .sum::<Vector3<f64>>()
                })
                .collect(),
        }
    }

    fn subtract(&mut self, other: &Self) {
        for (a, b) in self.values.iter_mut().zip(&other.values) {
            *a -= b;
        }
        for (a, b) in self.shifts.iter_mut().zip(&other.shifts) {
            *a -= b;
        }
    }
}

/// A column whose sign is summed over: which of the enumerated bits multiply it.
struct NuisanceColumn {
    column: usize,
    bits: Vec<usize>,
}

/// The most bits of the window's other doublets a multilevel likelihood sums over exactly
/// (`2^8` patterns, a binary two-dimension window's `±2` doublets): beyond, the farther
/// doublets' symbols are moment-matched.
const MULTILEVEL_EXACT_BITS: usize = 8;

/// [`MULTILEVEL_EXACT_BITS`].
#[cfg(not(test))]
fn multilevel_exact_bits() -> usize {
    MULTILEVEL_EXACT_BITS
}

/// [`MULTILEVEL_EXACT_BITS`], or the cap a test of the moment-matching sets on its thread.
#[cfg(test)]
fn multilevel_exact_bits() -> usize {
    tests::exact_bits().unwrap_or(MULTILEVEL_EXACT_BITS)
}

/// How the other doublets' bits enter a likelihood: known (their effect taken off the
/// residual), summed over exactly (the window's), or Gaussian (the lead's; and the window's
/// beyond the exact sum's budget, moment-matched).
struct Treatment {
    /// The residual as a combination of the columns, without the hypothesis' own.
    residual: DVector<f64>,
    nuisance: Vec<NuisanceColumn>,
    nuisance_bits: usize,
    /// The lead's columns: folded into the likelihood and the separation.
    gaussian: Vec<usize>,
    /// The window's columns beyond the exact sum's budget, lead's first: folded into the
    /// likelihood; known in the separation, as the exactly summed ones are.
    folded: Vec<usize>,
}

impl Treatment {
    /// `known(o)`: the pattern of doublet `o` when known; the unknown ones of the window
    /// summed over exactly nearest `target` first while their bits total at most
    /// `exact_bits`, the rest of the window moment-matched (each Walsh coefficient of its
    /// symbols a unit Gaussian: they have mean 0, variance 1 and no correlation).
    fn new(
        others: &[Other],
        known: impl Fn(&Other) -> Option<usize>,
        columns: usize,
        target: u32,
        exact_bits: usize,
    ) -> Self {
        let mut residual = DVector::zeros(columns);
        residual[0] = 1.0;
        let mut treatment = Self {
            residual,
            nuisance: Vec::new(),
            nuisance_bits: 0,
            gaussian: Vec::new(),
            folded: Vec::new(),
        };
        let bits_of = |other: &Other| {
            other
                .columns
                .iter()
                .filter_map(|(_, recipe)| recipe.iter().max())
                .max()
                .map_or(0, |b| b + 1)
        };
        let mut nearest: Vec<&Other> = others
            .iter()
            .filter(|o| o.in_window && known(o).is_none())
            .collect();
        nearest.sort_by_key(|o| o.doublet.abs_diff(target));
        let mut budget = exact_bits;
        let exact: Vec<u32> = nearest
            .into_iter()
            .take_while(|o| {
                let fits = bits_of(o) <= budget;
                budget = budget.saturating_sub(bits_of(o));
                fits
            })
            .map(|o| o.doublet)
            .collect();
        for other in others {
            match known(other) {
                Some(pattern) => {
                    for (column, recipe) in &other.columns {
                        treatment.residual[*column] -= pattern_sign(pattern, recipe);
                    }
                }
                None if other.in_window && !exact.contains(&other.doublet) => treatment
                    .folded
                    .extend(other.columns.iter().map(|(column, _)| *column)),
                None if other.in_window => {
                    let first_bit = treatment.nuisance_bits;
                    let mut width = 0;
                    for (column, recipe) in &other.columns {
                        width = width.max(recipe.iter().max().map_or(0, |b| b + 1));
                        treatment.nuisance.push(NuisanceColumn {
                            column: *column,
                            bits: recipe.iter().map(|b| first_bit + b).collect(),
                        });
                    }
                    treatment.nuisance_bits += width;
                }
                None => treatment
                    .gaussian
                    .extend(other.columns.iter().map(|(column, _)| *column)),
            }
        }
        if !treatment.folded.is_empty() {
            treatment
                .folded
                .splice(0..0, treatment.gaussian.iter().copied());
        }
        treatment
    }

    /// The columns integrated as unit Gaussians in the likelihood.
    fn integrated(&self) -> &[usize] {
        if self.folded.is_empty() {
            &self.gaussian
        } else {
            &self.folded
        }
    }

    /// `ln p(y | h)` up to a constant common to all hypotheses, `h` the hypothesis' column.
    fn log_likelihood(&self, gram: &DMatrix<f64>, log_det: f64, hypothesis: usize) -> f64 {
        let mut residual = self.residual.clone();
        residual[hypothesis] -= 1.0;
        log_likelihood(
            gram,
            log_det,
            &residual,
            &self.nuisance,
            self.nuisance_bits,
            self.integrated(),
        )
    }
}

/// The slip latents of one window step: each wheel's mean speed per update, and its
/// half-differences under the bits of the step's doublet (when another doublet's).
#[derive(Clone, Debug)]
struct SlipProfile {
    mean: Vec<WheelSpeeds>,
    bit_effects: Vec<Vec<WheelSpeeds>>,
}

impl WindowSmoother {
    /// The smoother of `config`'s sessions in `world`, `half_width` doublets each side and
    /// the boundary samples of `reach` doublets beyond them.
    #[must_use]
    pub fn new(config: &Config, world: &WorldModel, half_width: u32, reach: u32) -> Self {
        let t = config.robot.sample_time;
        let memory = world.delay + world.lag * 1e4_f64.ln();
        let perturbation = Perturbation::of(config);
        Self {
            eve: WindowWorld::new(
                world,
                crate::model::DiffDrive {
                    wheel_radius: config.robot.r,
                    axle_length: config.robot.axle_length,
                },
                config.robot.wheel_limit,
                t,
            ),
            half_width,
            reach,
            lead: (memory / (f64::from(perturbation.steps()) * t)).ceil() as u32,
            perturbation,
            sample_time: t,
        }
    }

    /// Doublets each side of the window.
    #[must_use]
    pub fn half_width(&self) -> u32 {
        self.half_width
    }

    /// Doublets each side beyond the window whose boundary samples she also takes.
    #[must_use]
    pub fn reach(&self) -> u32 {
        self.reach
    }

    /// Doublets before a window whose bits still act on it.
    #[must_use]
    pub fn lead(&self) -> u32 {
        self.lead
    }

    /// `L`, the steps per doublet.
    fn length(&self) -> u32 {
        self.perturbation.steps()
    }

    /// The offset doublet step `s` (0 to `L − 1`) adds for the first step's `offset`; none
    /// beyond the doublet.
    fn step_offset(&self, s: usize, offset: Unicycle) -> Unicycle {
        self.perturbation
            .step_offsets(offset)
            .get(s)
            .filter(|_| s < self.length() as usize)
            .copied()
            .unwrap_or_else(Unicycle::zeros)
    }

    /// The doublets `(first, last)` of doublet `j`'s window given what is recorded: at most
    /// `W` each side, contiguous known commands, and the sample at the last one's end.
    #[must_use]
    pub fn window_of(&self, j: u32, rec: &Recorded<'_>) -> Option<(u32, u32)> {
        self.span_of(j, j, self.half_width, rec)
    }

    /// The doublets `(first, last)` around `from … to` extended by at most `each` each side
    /// over contiguous known commands, ending where the sample at the last one's end is.
    fn span_of(&self, from: u32, to: u32, each: u32, rec: &Recorded<'_>) -> Option<(u32, u32)> {
        let l = self.length();
        let inputs = |i: u32| rec.commands.get(&(l * i)).and_then(|c| c.inputs);
        inputs(from)?;
        let doublets = rec.plan.units();
        let mut first = from;
        while first > 0 && from - first < each && inputs(first - 1).is_some() {
            first -= 1;
        }
        let mut last = to;
        while last + 1 < doublets && last - to < each && inputs(last + 1).is_some() {
            last += 1;
        }
        while !rec.commands.contains_key(&(l * last + l)) {
            if last == from {
                return None;
            }
            last -= 1;
        }
        Some((first, last))
    }

    /// The evidence on doublet `j`'s bits from everything recorded over its window, of the
    /// `camera` adversary (with her camera) and, when `judge_commands`, of the `commands` one
    /// (from the commands alone) — each her own (the window's other bits unknown) and, when
    /// `truth` tells the true bits of every other doublet that acts on the window, given
    /// those. None when `j` carries no bits or its own commands are not recorded.
    #[must_use]
    pub fn evidence(
        &self,
        j: u32,
        rec: &Recorded<'_>,
        truth: &dyn Fn(u32) -> Option<u64>,
        judge_commands: bool,
    ) -> Option<(Judged, Option<Judged>)> {
        let exact = self.window_of(j, rec)?;
        let (first, last) = self.span_of(exact.0, exact.1, self.reach, rec)?;
        let l = self.length();
        let inputs = |i: u32| rec.commands.get(&(l * i)).and_then(|c| c.inputs);
        if !rec.plan.carries(&inputs(j)?) {
            return None;
        }
        let mut lead_first = first;
        while lead_first > 0 && first - lead_first < self.lead && inputs(lead_first - 1).is_some() {
            lead_first -= 1;
        }
        let before = match lead_first {
            0 => None,
            i => Some(inputs(i - 1).map_or_else(|| inputs(i).expect("known").first, |d| d.second)),
        };
        let doublets: Vec<(u32, DoubletInputs)> = (lead_first..=last)
            .map(|i| (i, inputs(i).expect("a window's commands are known")))
            .collect();
        // A three-step doublet holds its second nominal input through its third step.
        let window = Window {
            lead: (l * (first - lead_first)) as usize,
            inputs: doublets
                .iter()
                .flat_map(|(_, d)| (0..l).map(|s| if s == 0 { d.first } else { d.second }))
                .collect(),
            before,
            start: rec.commands[&(l * first)].sample,
            anchors: (0..l * (last - first + 1))
                .map(|s| (s > 0 && s % l == 0).then(|| rec.commands[&(l * first + s)].sample))
                .collect(),
        };
        let carrying: Vec<(u32, usize)> = doublets
            .iter()
            .enumerate()
            .filter(|(_, (_, d))| rec.plan.carries(d))
            .map(|(position, (i, _))| (*i, position))
            .collect();
        let nominal = self.eve.run(&window, |_| Unicycle::zeros());
        let patterns = self.perturbation.patterns();
        // Each carrying doublet's runs, one per bit pattern: those of the samples' reach
        // simulated only where their bits act, and — in a world whose wheels remember no
        // earlier input (no lag, no delay: no lead doublets), where that is the same
        // arithmetic as the whole run — the window's too; the window's and the lead's
        // simulated whole otherwise.
        let memoryless = self.lead == 0;
        let runs: Vec<Vec<Perturbed>> = carrying
            .iter()
            .map(|&(i, position)| {
                (0..patterns)
                    .map(|h| {
                        let offset = self.perturbation.offset(h);
                        if i >= first && (memoryless || !(exact.0..=exact.1).contains(&i)) {
                            return self.run_near(&window, &nominal, position, offset);
                        }
                        let at = l as usize * position;
                        Perturbed::whole(self.eve.run(&window, |step| match step.checked_sub(at) {
                            Some(s) => self.step_offset(s, offset),
                            None => Unicycle::zeros(),
                        }))
                    })
                    .collect()
            })
            .collect();
        let target = carrying
            .iter()
            .position(|&(i, _)| i == j)
            .expect("j carries");
        let window = Simulated {
            first,
            exact,
            steps: (l * (last - first + 1)) as usize,
            nominal,
            runs,
            carrying,
            target,
        };
        let camera = self.judge(rec, &window, true, truth);
        let commands = judge_commands.then(|| self.judge(rec, &window, false, truth));
        Some((camera, commands))
    }

    /// The run of `window` with simulated doublet `position` (lead doublets counted, at or
    /// after the window's first sample) perturbed by its steps' offsets for `offset`
    /// ([`Perturbation::step_offsets`]), simulated only
    /// where the perturbation acts — from the world's actuator memory (`lead` doublets)
    /// before it to `lead + 1` doublets after it, the next boundary's restart included —
    /// and the nominal run elsewhere. Without lag or delay it is the whole run's arithmetic,
    /// bit for bit: each doublet restarts from its anchor, and wheels without memory enter the
    /// stretch as they would in the whole run. With them the wheels entering the stretch are
    /// settled on the input before it (the memory the lead bounds).
    fn run_near(
        &self,
        window: &Window,
        nominal: &WindowRun,
        position: usize,
        offset: Unicycle,
    ) -> Perturbed {
        let lead = self.lead as usize;
        let l = self.length() as usize;
        let from = position.saturating_sub(lead);
        let to = (position + lead + 2).min(window.inputs.len() / l);
        let start_step = l * position - window.lead;
        let end_step = l * to - window.lead;
        let stretch = Window {
            lead: l * (position - from),
            inputs: window.inputs[l * from..l * to].to_vec(),
            before: match from {
                0 => window.before,
                _ => Some(window.inputs[l * from - 1]),
            },
            start: match start_step {
                0 => window.start,
                s => window.anchors[s].unwrap_or(nominal.poses[s][0]),
            },
            anchors: std::iter::once(None)
                .chain(window.anchors[start_step + 1..end_step].iter().copied())
                .collect(),
        };
        let perturbed = stretch.lead;
        let part = self
            .eve
            .run(&stretch, |step| match step.checked_sub(perturbed) {
                Some(s) => self.step_offset(s, offset),
                None => Unicycle::zeros(),
            });
        // The nominal run's jumps, the stretch's own where its doublets restart.
        let mut jumps = nominal.jumps.clone();
        for (jump, &own) in jumps[start_step..end_step]
            .iter_mut()
            .zip(&part.jumps)
            .skip(1)
        {
            *jump = own;
        }
        Perturbed {
            from: start_step,
            part,
            jumps,
        }
    }

    /// One adversary's evidence on the window's target doublet from her observations over it.
    fn judge(
        &self,
        rec: &Recorded<'_>,
        window: &Simulated,
        camera: bool,
        truth: &dyn Fn(u32) -> Option<u64>,
    ) -> Judged {
        let Simulated {
            first,
            exact,
            steps,
            nominal,
            runs,
            carrying,
            target,
        } = window;
        let (first, steps, target) = (*first, *steps, *target);
        let patterns = self.perturbation.patterns();
        // Her camera over the window proper; the boundary samples over the whole reach.
        let l = self.length();
        let filmed =
            camera.then(|| (l * (exact.0 - first)) as usize..=(l * (exact.1 - first + 1)) as usize);
        let observations = self.observations(rec, nominal, l * first, steps, &filmed);
        // Columns: the residual, the target's hypotheses, the window's other bits, the lead's.
        // A column is a combination of runs, relative to the nominal one: each run's
        // deviation from it taken once, each column its weighted sum.
        let observed = observations.len();
        let bases: Vec<Pose> = observations.iter().map(|o| nominal.at(o.instant)).collect();
        let deviations: Vec<Vec<Deviation>> = runs
            .iter()
            .map(|patterns| {
                patterns
                    .iter()
                    .map(|run| Deviation::of(run, nominal, &observations, &bases))
                    .collect()
            })
            .collect();
        let mean_of = |c: usize| -> Vec<(&Deviation, f64)> {
            deviations[c]
                .iter()
                .map(|deviation| (deviation, 1.0 / patterns as f64))
                .collect()
        };
        // The residual about the nominal path and the other doublets' mean effects.
        let mut residual = Column {
            values: observations
                .iter()
                .zip(&bases)
                .map(|(o, base)| o.value - base)
                .collect(),
            shifts: nominal.jumps.clone(),
        };
        for c in (0..carrying.len()).filter(|&c| c != target) {
            residual.subtract(&Column::derived(&mean_of(c), observed, steps));
        }
        let mut columns: Vec<Column> = vec![residual];
        for deviation in &deviations[target] {
            columns.push(Column::derived(&[(deviation, 1.0)], observed, steps));
        }
        let mut others: Vec<Other> = Vec::new();
        for (c, &(i, _)) in carrying.iter().enumerate() {
            if c == target {
                continue;
            }
            let mut other = Other {
                doublet: i,
                in_window: (exact.0..=exact.1).contains(&i),
                columns: Vec::new(),
            };
            for recipe in walsh_recipes(self.perturbation.key_bits()) {
                let weights: Vec<(&Deviation, f64)> = deviations[c]
                    .iter()
                    .enumerate()
                    .map(|(h, deviation)| (deviation, pattern_sign(h, &recipe) / patterns as f64))
                    .collect();
                columns.push(Column::derived(&weights, observed, steps));
                other.columns.push((columns.len() - 1, recipe));
            }
            others.push(other);
        }
        // One Gram filter pass per covariance: with slip, per hypothesis of the target and
        // per what is known of the other doublets (their slip's variance follows their bits).
        let grams_with = |known: &dyn Fn(usize) -> Option<usize>| -> Vec<(DMatrix<f64>, f64)> {
            let slips: Vec<Vec<SlipProfile>> = (0..self.covariance_runs(patterns))
                .map(|h| {
                    self.slip_profiles(nominal, runs, carrying, target, h, known, first, steps)
                })
                .collect();
            self.filter(nominal, &observations, &columns, &slips, steps)
        };
        let evidence_under = |treatment: &Treatment, grams: &[(DMatrix<f64>, f64)]| {
            let gram_of = |h: usize| &grams[h.min(grams.len() - 1)];
            let ll: Vec<f64> = (0..patterns)
                .map(|h| {
                    let (gram, log_det) = gram_of(h);
                    treatment.log_likelihood(gram, *log_det, 1 + h)
                })
                .collect();
            let distance = |a: usize, b: usize| {
                let (gram, _) = gram_of(a);
                separation(gram, 1 + a, 1 + b, &treatment.gaussian)
            };
            (self.bit_evidence(&ll, distance), ll)
        };
        let unknown = grams_with(&|_| None);
        let j = carrying[target].0;
        let exact_bits = if self.perturbation.levels > 2 {
            multilevel_exact_bits()
        } else {
            usize::MAX
        };
        let treatment = Treatment::new(&others, |_| None, columns.len(), j, exact_bits);
        let own = evidence_under(&treatment, &unknown).0;
        let pattern_of = |i: u32| truth(i).map(|b| self.perturbation.pattern(b));
        // A multilevel symbol's bits are judged in a chain, each given the true ones before
        // it (her realised bound is then on the symbols); binary bits as they are.
        let chained = self.perturbation.levels > 2;
        let revealed =
            others.iter().all(|o| truth(o.doublet).is_some()) && (!chained || truth(j).is_some());
        let given_others = revealed.then(|| {
            let treatment = Treatment::new(&others, |o| pattern_of(o.doublet), columns.len(), j, 0);
            let (evidence, ll) = if self.eve.world.slip_std > 0.0 {
                let known = |c: usize| pattern_of(carrying[c].0);
                evidence_under(&treatment, &grams_with(&known))
            } else {
                evidence_under(&treatment, &unknown)
            };
            match truth(j).filter(|_| chained) {
                Some(word) => BitEvidence {
                    llr: chained_llrs(&ll, &self.perturbation, word),
                    ..evidence
                },
                None => evidence,
            }
        });
        #[cfg(test)]
        tests::seen(
            &self.perturbation,
            &tests::Seen {
                camera,
                doublet: j,
                own,
                given_others,
                others: &others,
                columns: columns.len(),
                grams: &unknown,
                truth,
            },
        );
        Judged { own, given_others }
    }

    /// Runs of the Gram filter needed: one per hypothesis when the slip's covariance depends
    /// on the bits, else one.
    fn covariance_runs(&self, patterns: usize) -> usize {
        if self.eve.world.slip_std > 0.0 {
            patterns
        } else {
            1
        }
    }

    /// What she observed over the window, in window-step order: the boundary samples, and
    /// her camera (if she has one) over the window steps `filmed`.
    fn observations(
        &self,
        rec: &Recorded<'_>,
        nominal: &WindowRun,
        k0: u32,
        steps: usize,
        filmed: &Option<std::ops::RangeInclusive<usize>>,
    ) -> Vec<Observation> {
        let world = &self.eve.world;
        let t = self.sample_time;
        let inverse_of =
            |std: [f64; 3]| Matrix3::from_diagonal(&Vector3::from(std.map(|s| 1.0 / (s * s))));
        let controller =
            Matrix3::from_diagonal(&Vector3::from(world.controller_std.map(|s| s * s)));
        let mut out = Vec::new();
        for step in 0..=steps {
            let k = k0 + step as u32;
            if step > 0
                && k.is_multiple_of(self.length())
                && let Some(c) = rec.commands.get(&k)
            {
                let v = nominal.velocity_before(step);
                let noise = controller + v * v.transpose() * world.jitter.powi(2);
                out.push(Observation {
                    instant: Instant::Sample(step),
                    value: c.sample,
                    noise_inverse: noise.try_inverse().unwrap_or_else(Matrix3::zeros),
                });
            }
            let Some(filmed) = filmed.as_ref().filter(|f| f.contains(&step)) else {
                continue;
            };
            match world.camera {
                Camera::Instants { std } => {
                    if let Some(pose) = rec.camera.get(&k) {
                        out.push(Observation {
                            instant: Instant::Sample(step),
                            value: *pose,
                            noise_inverse: inverse_of(std),
                        });
                    }
                }
                Camera::Frames { frame_std, .. } => {
                    if step == *filmed.end() {
                        continue;
                    }
                    let start = f64::from(k) * t;
                    let from = rec.frames.partition_point(|f| f.time < start);
                    for frame in rec.frames[from..].iter().take_while(|f| f.time < start + t) {
                        out.push(Observation {
                            instant: nominal.locate(step, frame.time - start),
                            value: frame.pose,
                            noise_inverse: inverse_of(frame_std),
                        });
                    }
                }
            }
        }
        out
    }

    /// Each window step's slip profile: the target's steps under hypothesis `h`, other
    /// carrying doublets' steps under their pattern where `known` tells it, else at their
    /// mean with the bits' half-differences, the rest at the nominal path.
    #[allow(
        clippy::too_many_arguments,
        reason = "the window's pieces, each used once"
    )]
    fn slip_profiles(
        &self,
        nominal: &WindowRun,
        runs: &[Vec<Perturbed>],
        carrying: &[(u32, usize)],
        target: usize,
        h: usize,
        known: &dyn Fn(usize) -> Option<usize>,
        first: u32,
        steps: usize,
    ) -> Vec<SlipProfile> {
        let wheels = |updates: &[SubStep]| -> Vec<WheelSpeeds> {
            updates.iter().map(|u| u.wheels).collect()
        };
        (0..steps)
            .map(|step| {
                let doublet = first + step as u32 / self.length();
                let owner = carrying.iter().position(|&(i, _)| i == doublet);
                match owner {
                    Some(c) if c == target => SlipProfile {
                        mean: wheels(runs[c][h].updates(nominal, step)),
                        bit_effects: Vec::new(),
                    },
                    Some(c) if known(c).is_some() => SlipProfile {
                        mean: wheels(runs[c][known(c).expect("known")].updates(nominal, step)),
                        bit_effects: Vec::new(),
                    },
                    Some(c) => {
                        let patterns = runs[c].len();
                        let average = |recipe: &[usize]| -> Vec<WheelSpeeds> {
                            let mut sum =
                                vec![WheelSpeeds::zeros(); runs[c][0].updates(nominal, step).len()];
                            for (p, run) in runs[c].iter().enumerate() {
                                for (s, w) in sum.iter_mut().zip(wheels(run.updates(nominal, step)))
                                {
                                    *s += w * pattern_sign(p, recipe) / patterns as f64;
                                }
                            }
                            sum
                        };
                        let bits = self.perturbation.key_bits();
                        SlipProfile {
                            mean: average(&[]),
                            bit_effects: (0..bits).map(|b| average(&[b])).collect(),
                        }
                    }
                    None => SlipProfile {
                        mean: wheels(&nominal.updates[step]),
                        bit_effects: Vec::new(),
                    },
                }
            })
            .collect()
    }

    /// One pass of the Gram filter over the window per slip profile sequence in `slips` (one
    /// per covariance), its Gram matrix and log-determinant each. The passes are the same
    /// arithmetic up to the first step whose profiles differ, so they run as one up to it.
    fn filter(
        &self,
        nominal: &WindowRun,
        observations: &[Observation],
        columns: &[Column],
        slips: &[Vec<SlipProfile>],
        steps: usize,
    ) -> Vec<(DMatrix<f64>, f64)> {
        let shared = (0..=steps)
            .take_while(|&step| {
                let first = slips[0].get(step);
                slips[1..]
                    .iter()
                    .all(|other| same_profile(first, other.get(step)))
            })
            .count();
        let mut pass = Pass::start(self, nominal, columns);
        for step in 0..shared {
            if !pass.step(self, nominal, observations, columns, step, &slips[0]) {
                break;
            }
        }
        slips
            .iter()
            .map(|slip| {
                let mut own = pass.clone();
                for step in shared..=steps {
                    if !own.step(self, nominal, observations, columns, step, slip) {
                        break;
                    }
                }
                own.filter.finish()
            })
            .collect()
    }

    /// The pose's deviation at each update boundary of a step as a linear map of the step's
    /// state `[δx_k, w_{k−1}?, e_k, z?, z'…]`, and the step's noise `w_k` likewise, into
    /// `out` (its storage kept from step to step). Each pose map is
    /// `(A·pose + D·noise) + B·speeds`, every product rounded as `nalgebra`'s `*`.
    #[allow(
        clippy::too_many_arguments,
        reason = "the step's pieces, each used once"
    )]
    fn tangents(
        &self,
        updates: &[SubStep],
        slip: &SlipProfile,
        dim: usize,
        base: usize,
        correlated: bool,
        slipping: bool,
        out: &mut Tangents,
    ) {
        let world = &self.eve.world;
        let t = self.sample_time;
        let rho = world.process_rho;
        // w_k = ρ·w_{k−1} + √(1−ρ²)·S·e_k.
        let noise = zeroed(&mut out.noise, 3, dim);
        let scale = if correlated {
            (1.0 - rho * rho).sqrt()
        } else {
            1.0
        };
        for i in 0..3 {
            if correlated {
                noise[(i, 3 + i)] = rho;
            }
            noise[(i, base + i)] = scale * world.process_std[i];
        }
        let drive = self.eve.drive;
        let h_matrix = drive.h();
        let count = updates.len() + 1;
        out.poses.truncate(count);
        out.poses.resize_with(count, || Matrix3xX::zeros(dim));
        let first = &mut out.poses[0];
        if first.ncols() != dim {
            *first = Matrix3xX::zeros(dim);
        }
        first.fill(0.0);
        first.fill_diagonal(1.0);
        for (u, update) in updates.iter().enumerate() {
            let (a, b, d) = jacobians(update, t);
            // (δv, δω) per slip latent: σ·H·e_i·ω̄_i, and per bit effect σ·H·e_i·Δω̄_i.
            let speeds = zeroed(&mut out.speeds, 2, dim);
            if slipping {
                let sigma = world.slip_std;
                for wheel in 0..2 {
                    let column = h_matrix.column(wheel);
                    let mean = slip.mean[u][wheel];
                    speeds
                        .column_mut(base + 3 + wheel)
                        .copy_from(&(column * (sigma * mean)));
                    for (e, effect) in slip.bit_effects.iter().enumerate() {
                        let c = base + 5 + 2 * e + wheel;
                        speeds
                            .column_mut(c)
                            .copy_from(&(column * (sigma * effect[u][wheel])));
                    }
                }
            }
            let (done, later) = out.poses.split_at_mut(u + 1);
            let next = &mut later[0];
            if next.ncols() != dim {
                *next = Matrix3xX::zeros(dim);
            }
            product_to(&a, &done[u], next);
            let term = shaped3(&mut out.term, dim);
            product_to(&d, &out.noise, term);
            *next += &*term;
            product_to(&b, &out.speeds, term);
            *next += &*term;
        }
    }

    /// The LLR and separation of each bit from the hypotheses' log-likelihoods and their
    /// pairwise distances, as [`super::likelihood::DoubletModel::evidence`] forms them.
    fn bit_evidence(&self, ll: &[f64], distance: impl Fn(usize, usize) -> f64) -> BitEvidence {
        super::likelihood::bit_evidence(ll, &self.perturbation, distance)
    }
}

/// A step's linear maps: the pose deviation at each update boundary, and `w_k`; with the
/// work space that forms them (`(δv, δω)` per latent, and one product).
#[derive(Clone, Default)]
struct Tangents {
    poses: Vec<Matrix3xX<f64>>,
    noise: DMatrix<f64>,
    speeds: DMatrix<f64>,
    term: Matrix3xX<f64>,
}

/// `m` as a `rows × columns` matrix of zeros, its storage kept when it has that shape.
fn zeroed(m: &mut DMatrix<f64>, rows: usize, columns: usize) -> &mut DMatrix<f64> {
    if m.shape() == (rows, columns) {
        m.fill(0.0);
    } else {
        *m = DMatrix::zeros(rows, columns);
    }
    m
}

/// `m` as a `3 × columns` matrix of unspecified values, its storage kept when it has that
/// shape.
fn shaped3(m: &mut Matrix3xX<f64>, columns: usize) -> &mut Matrix3xX<f64> {
    if m.ncols() != columns {
        *m = Matrix3xX::zeros(columns);
    }
    m
}

/// Two steps' slip profiles (absent past the window's last instant) are the same bit for bit.
fn same_profile(a: Option<&SlipProfile>, b: Option<&SlipProfile>) -> bool {
    let same = |x: &[WheelSpeeds], y: &[WheelSpeeds]| {
        x.len() == y.len()
            && x.iter().zip(y).all(|(p, q)| {
                p.iter()
                    .zip(q.iter())
                    .all(|(u, v)| u.to_bits() == v.to_bits())
            })
    };
    match (a, b) {
        (None, None) => true,
        (Some(a), Some(b)) => {
            same(&a.mean, &b.mean)
                && a.bit_effects.len() == b.bit_effects.len()
                && a.bit_effects
                    .iter()
                    .zip(&b.bit_effects)
                    .all(|(x, y)| same(x, y))
        }
        _ => false,
    }
}

/// A Gram filter pass over a window, between steps: the filter, the next observation, and
/// the state's dimension between steps.
#[derive(Clone)]
struct Pass {
    filter: GramFilter,
    next: usize,
    base: usize,
    work: PassWork,
}

/// Work space of `Pass::step`, overwritten by each step: the columns' values at an
/// observation, the observation maps of a sample and of a frame, the step's tangents and
/// its transition.
#[derive(Clone, Default)]
struct PassWork {
    values: Vec<Vector3<f64>>,
    sample_map: Matrix3xX<f64>,
    frame_map: Matrix3xX<f64>,
    tangents: Tangents,
    transition: DMatrix<f64>,
}

impl Pass {
    /// The filter at the window's start: the start pose, the controller's sample, off by its
    /// noise and timing error; with correlated noise, the noise carried into the window.
    fn start(smoother: &WindowSmoother, nominal: &WindowRun, columns: &[Column]) -> Self {
        let world = &smoother.eve.world;
        let correlated = world.process_rho != 0.0;
        let first_speed = nominal.velocity_before(1);
        let mut start = Matrix3::from_diagonal(&Vector3::from(world.controller_std.map(|s| s * s)))
            + first_speed * first_speed.transpose() * world.jitter.powi(2);
        start = (start + start.transpose()) * 0.5;
        let q = Matrix3::from_diagonal(&Vector3::from(world.process_std.map(|s| s * s)));
        let base = if correlated { 6 } else { 3 };
        let mut cov = DMatrix::zeros(base, base);
        cov.view_mut((0, 0), (3, 3)).copy_from(&start);
        if correlated {
            cov.view_mut((3, 3), (3, 3)).copy_from(&q);
        }
        Self {
            filter: GramFilter::new(cov, columns.len()),
            next: 0,
            base,
            work: PassWork::default(),
        }
    }

    /// Window step `step`: the shift of the means where the path restarts, the
    /// observations at its start, then — unless it is the window's end (no profile in
    /// `slips`) — the step's noise and slip latents, the frames within it and the transition
    /// to its end. Returns whether the window goes on.
    #[allow(
        clippy::too_many_arguments,
        reason = "the window's pieces, each used once"
    )]
    fn step(
        &mut self,
        smoother: &WindowSmoother,
        nominal: &WindowRun,
        observations: &[Observation],
        columns: &[Column],
        step: usize,
        slips: &[SlipProfile],
    ) -> bool {
        let world = &smoother.eve.world;
        let correlated = world.process_rho != 0.0;
        let slipping = world.slip_std > 0.0;
        let (filter, base, work) = (&mut self.filter, self.base, &mut self.work);
        // `slips` holds one profile per window step: `step < slips.len()` is a step within.
        if step > 0
            && step < slips.len()
            && columns.iter().any(|c| c.shifts[step] != Vector3::zeros())
        {
            let mut offsets = DMatrix::zeros(filter.dim(), columns.len());
            for (c, column) in columns.iter().enumerate() {
                offsets
                    .view_mut((0, c), (3, 1))
                    .copy_from(&column.shifts[step]);
            }
            filter.shift(&offsets);
        }
        // Observations at the instant that starts this step (or ends the window): `F = [I 0]`.
        while self.next < observations.len()
            && matches!(observations[self.next].instant, Instant::Sample(s) if s == step)
        {
            let f = &mut work.sample_map;
            if f.ncols() != filter.dim() {
                *f = Matrix3xX::zeros(filter.dim());
                f.fill_diagonal(1.0);
            }
            let values = values_at(&mut work.values, columns, self.next);
            filter.observe(f, &observations[self.next].noise_inverse, values);
            self.next += 1;
        }
        // `slips` holds one profile per step: none past the window's last instant.
        let Some(slip) = slips.get(step) else {
            return false;
        };
        let effects = if slipping { slip.bit_effects.len() } else { 0 };
        let extra = 3 + if slipping { 2 + 2 * effects } else { 0 };
        filter.augment(extra);
        let dim = filter.dim();
        let tangents = &mut work.tangents;
        smoother.tangents(
            &nominal.updates[step],
            slip,
            dim,
            base,
            correlated,
            slipping,
            tangents,
        );
        // A frame's observation map, reused for every frame of the step.
        let frame_map = &mut work.frame_map;
        while self.next < observations.len() {
            let Instant::Frame {
                step: s,
                update,
                fraction,
            } = observations[self.next].instant
            else {
                break;
            };
            if s != step {
                break;
            }
            // F = (1 − f)·F_u + f·F_{u+1}, element by element.
            let (before, after) = (&tangents.poses[update], &tangents.poses[update + 1]);
            if frame_map.shape() != before.shape() {
                *frame_map = Matrix3xX::zeros(before.ncols());
            }
            frame_map.zip_zip_apply(before, after, |out, a, b| {
                *out = a * (1.0 - fraction) + b * fraction;
            });
            let values = values_at(&mut work.values, columns, self.next);
            filter.observe(frame_map, &observations[self.next].noise_inverse, values);
            self.next += 1;
        }
        let l = zeroed(&mut work.transition, base, dim);
        l.view_mut((0, 0), (3, dim))
            .copy_from(tangents.poses.last().expect("an end"));
        if correlated {
            l.view_mut((3, 0), (3, dim)).copy_from(&tangents.noise);
        }
        filter.transition(l);
        true
    }
}

/// The columns' values at observation `o`, in `buffer` (its storage kept from observation to
/// observation).
fn values_at<'a>(
    buffer: &'a mut Vec<Vector3<f64>>,
    columns: &[Column],
    o: usize,
) -> &'a [Vector3<f64>] {
    buffer.clear();
    buffer.extend(columns.iter().map(|c| c.values[o]));
    buffer
}

/// The Jacobians of one pose update at its nominal path: `A = ∂x⁺/∂x`, `B = ∂x⁺/∂(v, ω)`
/// and `D = ∂x⁺/∂w` (`w` the period's noise, a velocity error `w/T`).
fn jacobians(update: &SubStep, t: f64) -> (Matrix3<f64>, nalgebra::Matrix3x2<f64>, Matrix3<f64>) {
    let h = update.duration;
    let (v, omega) = (update.speeds.x, update.speeds.y);
    let theta = update.start.z;
    if update.euler {
        let (sin, cos) = theta.sin_cos();
        let a = Matrix3::new(1.0, 0.0, -h * v * sin, 0.0, 1.0, h * v * cos, 0.0, 0.0, 1.0);
        let b = nalgebra::Matrix3x2::new(h * cos, 0.0, h * sin, 0.0, 0.0, h);
        (a, b, Matrix3::identity() * (h / t))
    } else {
        let half = h * omega / 2.0;
        let (c, dc) = sinc(half);
        let (sin, cos) = (theta + half).sin_cos();
        let a = Matrix3::new(
            1.0,
            0.0,
            -h * v * c * sin,
            0.0,
            1.0,
            h * v * c * cos,
            0.0,
            0.0,
            1.0,
        );
        let half_h = h / 2.0;
        let b = nalgebra::Matrix3x2::new(
            h * c * cos,
            h * v * half_h * (dc * cos - c * sin),
            h * c * sin,
            h * v * half_h * (dc * sin + c * cos),
            0.0,
            h,
        );
        let d = Matrix3::new(
            h / t,
            0.0,
            b[(0, 1)] / t,
            0.0,
            h / t,
            b[(1, 1)] / t,
            0.0,
            0.0,
            h / t,
        );
        (a, b, d)
    }
}

/// The sign recipes of a doublet's `bits` key bits: every non-empty subset, by its mask
/// (binary two dimensions: v, ω, v·ω). A function of the pattern is exactly its mean plus
/// `Σ_S c_S·Π_{b∈S} s_b` (the Walsh–Hadamard expansion), so an other doublet's effect is its
/// mean run and one column per recipe.
fn walsh_recipes(bits: usize) -> impl Iterator<Item = Vec<usize>> {
    (1..1usize << bits).map(move |mask| (0..bits).filter(|b| mask >> b & 1 == 1).collect())
}

/// `Π s_b` over the bits `recipe` of pattern `h` (`s = +1` for bit 0): the sign a
/// pattern gives an effect column.
fn pattern_sign(h: usize, recipe: &[usize]) -> f64 {
    recipe.iter().map(|&b| sign(((h >> b) & 1) as u8)).product()
}

/// `ln p(y | h)` up to a constant common to all hypotheses: `residual` the residual under
/// `h` as a combination of the columns, the `nuisance` columns' bits summed over, the
/// `gaussian` columns' integrated as unit Gaussians.
fn log_likelihood(
    gram: &DMatrix<f64>,
    log_det: f64,
    residual: &DVector<f64>,
    nuisance: &[NuisanceColumn],
    nuisance_bits: usize,
    gaussian: &[usize],
) -> f64 {
    let g = |a: usize, b: usize| gram[(a, b)];
    let toward = gram * residual;
    let rr = residual.dot(&toward);
    let (fold, gaussian_log_det) = Fold::new(gram, gaussian);
    let n = nuisance.len();
    let b_gaussian = DVector::from_iterator(gaussian.len(), gaussian.iter().map(|&p| toward[p]));
    let rr = rr - fold.quadratic(&b_gaussian, &b_gaussian);
    let b: Vec<f64> = nuisance
        .iter()
        .map(|c| toward[c.column] - fold.quadratic(&fold.cross(gram, c.column), &b_gaussian))
        .collect();
    // `C_{L,a}` and `M·C_{L,b}` once per column: `c_ab = g_ab − C_{L,a}ᵀ·M·C_{L,b}`.
    let crosses: Vec<DVector<f64>> = nuisance
        .iter()
        .map(|a| fold.cross(gram, a.column))
        .collect();
    let folded: Vec<Option<DVector<f64>>> = crosses.iter().map(|x| fold.apply(x)).collect();
    let c: Vec<Vec<f64>> = nuisance
        .iter()
        .zip(&crosses)
        .map(|(a, cross_a)| {
            nuisance
                .iter()
                .zip(&folded)
                .map(|(b, folded_b)| {
                    g(a.column, b.column) - folded_b.as_ref().map_or(0.0, |m| cross_a.dot(m))
                })
                .collect()
        })
        .collect();
    let terms = DVector::from_iterator(
        1 << nuisance_bits,
        (0..1usize << nuisance_bits).map(|pattern| {
            let u: Vec<f64> = nuisance
                .iter()
                .map(|col| pattern_sign(pattern, &col.bits))
                .collect();
            let mut q = rr;
            for a in 0..n {
                q -= 2.0 * u[a] * b[a];
                for bb in 0..n {
                    q += u[a] * c[a][bb] * u[bb];
                }
            }
            -0.5 * q
        }),
    );
    ln_sum_exp(&terms) - 0.5 * log_det - 0.5 * gaussian_log_det
}

/// The lead's Gaussian bits integrated out: `M = (C_LL + I)⁻¹` and `ln det(C_LL + I)`.
struct Fold {
    inverse: DMatrix<f64>,
    lead: Vec<usize>,
}

impl Fold {
    fn new(gram: &DMatrix<f64>, lead: &[usize]) -> (Self, f64) {
        let n = lead.len();
        let m = DMatrix::from_fn(n, n, |a, b| {
            gram[(lead[a], lead[b])] + f64::from(u8::from(a == b))
        });
        let lu = m.lu();
        let log_det = if n == 0 { 0.0 } else { lu.determinant().ln() };
        let inverse = lu.try_inverse().unwrap_or_else(|| DMatrix::zeros(n, n));
        (
            Self {
                inverse,
                lead: lead.to_vec(),
            },
            log_det,
        )
    }

    /// `C_{L,a}`: the Gram entries between the lead's columns and column `a`.
    fn cross(&self, gram: &DMatrix<f64>, a: usize) -> DVector<f64> {
        DVector::from_iterator(self.lead.len(), self.lead.iter().map(|&p| gram[(p, a)]))
    }

    /// `M·y`; none without lead columns (the quadratic forms are then 0).
    fn apply(&self, y: &DVector<f64>) -> Option<DVector<f64>> {
        (!self.lead.is_empty()).then(|| &self.inverse * y)
    }

    /// `xᵀ·M·y`.
    fn quadratic(&self, x: &DVector<f64>, y: &DVector<f64>) -> f64 {
        if self.lead.is_empty() {
            0.0
        } else {
            x.dot(&(&self.inverse * y))
        }
    }
}

/// The distance between hypotheses `a` and `b` (columns of the Gram matrix) under `a`'s
/// covariance, the lead's bits folded into it.
fn separation(gram: &DMatrix<f64>, a: usize, b: usize, lead: &[usize]) -> f64 {
    let (fold, _) = Fold::new(gram, lead);
    let dd = gram[(a, a)] - 2.0 * gram[(a, b)] + gram[(b, b)];
    let d_lead = fold.cross(gram, b) - fold.cross(gram, a);
    (dd - fold.quadratic(&d_lead, &d_lead)).max(0.0).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::private::doublet::{Labeling, MAX_BITS};
    use std::cell::{Cell, RefCell};

    /// What [`WindowSmoother::judge`] hands a collecting test about one judgement.
    pub(super) struct Seen<'a> {
        pub(super) camera: bool,
        pub(super) doublet: u32,
        pub(super) own: BitEvidence,
        pub(super) given_others: Option<BitEvidence>,
        pub(super) others: &'a [Other],
        pub(super) columns: usize,
        /// The Gram matrices and log-determinants with the other bits unknown.
        pub(super) grams: &'a [(DMatrix<f64>, f64)],
        pub(super) truth: &'a dyn Fn(u32) -> Option<u64>,
    }

    /// One judgement a test collected.
    #[derive(Clone, Copy, Debug)]
    struct Collected {
        camera: bool,
        doublet: u32,
        /// Her own LLRs (the window's other symbols unknown): her decision.
        own: [f64; MAX_BITS],
        /// The doublet's true bit word, when revealed.
        word: Option<u64>,
        /// The camera adversary's joint check, in a world without slip.
        joint: Option<JointCheck>,
    }

    /// The window's block (the target and the other doublets of the window proper), every
    /// doublet beyond it known: her exact joint surprisal of the block's true symbols
    /// against the sum of the realised bound's terms (nats).
    #[derive(Clone, Copy, Debug)]
    struct JointCheck {
        /// `−ln P(B_block | view, rest)`, over every pattern of the block.
        joint: f64,
        /// `Σ_{i ∈ block} −ln P(B_i | view, B_{block ∖ i}, rest)`.
        chained: f64,
        /// The target's term from the enumeration.
        target_table: f64,
        /// The target's term from the chained LLRs the realised bound uses:
        /// `Σ_b ln(1 + e^{∓L_b})`.
        target_realised: f64,
    }

    thread_local! {
        /// The multilevel exact-sum cap this thread's test set (none: the smoother's own).
        static EXACT_BITS: Cell<Option<usize>> = const { Cell::new(None) };
        /// The judgements this thread's test collects (none: it does not collect).
        static COLLECTED: RefCell<Option<Vec<Collected>>> = const { RefCell::new(None) };
    }

    /// The exact-sum cap this thread's test set.
    pub(super) fn exact_bits() -> Option<usize> {
        EXACT_BITS.with(Cell::get)
    }

    /// Keeps a judgement when this thread's test collects them.
    pub(super) fn seen(perturbation: &Perturbation, seen: &Seen<'_>) {
        COLLECTED.with(|collected| {
            if let Some(list) = collected.borrow_mut().as_mut() {
                list.push(Collected {
                    camera: seen.camera,
                    doublet: seen.doublet,
                    own: seen.own.llr,
                    word: (seen.truth)(seen.doublet),
                    joint: if seen.camera {
                        joint_check(perturbation, seen)
                    } else {
                        None
                    },
                });
            }
        });
    }

    /// `ln(1 + e^{∓L})`: the surprisal an LLR gives `bit` (nats).
    fn bit_surprisal(llr: f64, bit: u64) -> f64 {
        let toward = if bit == 0 { llr } else { -llr };
        (-toward).exp().ln_1p()
    }

    /// `Σ_b ln(1 + e^{∓L_b})` of `word`'s key bits: the surprisal the LLRs give it (nats).
    fn surprisal_of(llr: &[f64; MAX_BITS], word: u64, key_bits: usize) -> f64 {
        (0..key_bits)
            .map(|i| bit_surprisal(llr[i], word >> i & 1))
            .sum()
    }

    /// The joint check of a judgement: every pattern of the block enumerated through the
    /// smoother's own likelihood (one Gram filter pass: no slip), the doublets beyond the
    /// block at their true patterns. None with slip or where a truth is unknown.
    fn joint_check(perturbation: &Perturbation, seen: &Seen<'_>) -> Option<JointCheck> {
        let [(gram, log_det)] = seen.grams else {
            return None;
        };
        let given = seen.given_others?;
        let word = (seen.truth)(seen.doublet)?;
        let pattern_of = |i: u32| (seen.truth)(i).map(|w| perturbation.pattern(w));
        let truth_j = perturbation.pattern(word);
        let block: Vec<u32> = seen
            .others
            .iter()
            .filter(|o| o.in_window)
            .map(|o| o.doublet)
            .collect();
        if seen.others.iter().any(|o| pattern_of(o.doublet).is_none()) {
            return None;
        }
        let true_block: Vec<usize> = block
            .iter()
            .map(|&i| pattern_of(i))
            .collect::<Option<_>>()?;
        let patterns = perturbation.patterns();
        let stride = |k: usize| patterns.pow(k as u32);
        // `table[a][h]`: the block's other doublets at assignment `a` (digit `k` doublet
        // `block[k]`'s pattern), the target at hypothesis `h`.
        let table: Vec<Vec<f64>> = (0..stride(block.len()))
            .map(|a| {
                let known = |o: &Other| match block.iter().position(|&i| i == o.doublet) {
                    Some(k) => Some(a / stride(k) % patterns),
                    None => pattern_of(o.doublet),
                };
                let treatment = Treatment::new(seen.others, known, seen.columns, seen.doublet, 0);
                (0..patterns)
                    .map(|h| treatment.log_likelihood(gram, *log_det, 1 + h))
                    .collect()
            })
            .collect();
        let lse = |values: Vec<f64>| ln_sum_exp(&DVector::from_vec(values));
        let truth_a: usize = true_block
            .iter()
            .enumerate()
            .map(|(k, p)| p * stride(k))
            .sum();
        let at_truth = table[truth_a][truth_j];
        let joint = lse(table.iter().flatten().copied().collect()) - at_truth;
        let target_table = lse(table[truth_a].clone()) - at_truth;
        let neighbours: f64 = (0..block.len())
            .map(|k| {
                let base = truth_a - true_block[k] * stride(k);
                lse((0..patterns)
                    .map(|p| table[base + p * stride(k)][truth_j])
                    .collect())
                    - at_truth
            })
            .sum();
        Some(JointCheck {
            joint,
            chained: target_table + neighbours,
            target_table,
            target_realised: surprisal_of(&given.llr, word, perturbation.key_bits()),
        })
    }

    /// Session `replicate` of `config` simulated with the multilevel exact sum capped at
    /// `exact_bits` (none: the smoother's own cap): every judgement of the window smoother.
    fn judgements(config: &Config, replicate: u32, exact_bits: Option<usize>) -> Vec<Collected> {
        EXACT_BITS.with(|cap| cap.set(exact_bits));
        COLLECTED.with(|collected| *collected.borrow_mut() = Some(Vec::new()));
        crate::sim::simulate(config, replicate, false).expect("the session runs");
        EXACT_BITS.with(|cap| cap.set(None));
        COLLECTED.with(|collected| collected.borrow_mut().take().unwrap_or_default())
    }

    /// The non-screened worlds of the checks: correlated (ρ = 0.9), and lagged (50 ms, 1 mm of
    /// motion noise, three-step doublets as the parties shape them for that lag).
    const WORLDS: [&str; 2] = [
        "[world]\nprocess_rho = 0.9\n",
        "[private]\nprior_lag = 0.05\n[world]\nlag = 0.05\nprocess_std = [0.001, 0.001, 0.001]\n",
    ];

    /// Four levels on two dimensions (4 key bits a doublet) in `world`, a window of ±1
    /// doublet.
    fn multilevel_in(world: &str) -> Config {
        Config::from_toml(
            &format!(
                "[sensing]\nmode = \"private\"\n[protocol]\nbits_per_doublet = 2\nlevels = 4\n\
                 [eve]\nsmoother_window = 1\n{world}"
            ),
            "test",
        )
        .expect("a valid configuration")
    }

    /// Mean and standard error of `values`.
    fn mean_and_error(values: &[f64]) -> (f64, f64) {
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let variance = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (mean, (variance / n).sqrt())
    }

    /// In a world whose wheels remember no earlier input, a doublet's run simulated only
    /// where its bits act is the whole window's run, bit for bit, at every position and
    /// pattern (the smoother takes it for the window's doublets there); with a lag the
    /// smoother has lead doublets and simulates the window's whole.
    #[test]
    fn a_memoryless_worlds_stretch_is_the_whole_run_bit_for_bit() {
        let config = Config::from_toml(
            "[sensing]\nmode = \"private\"\n[world]\nprocess_std = [0.002, 0.002, 0.002]\n\
             slip_std = 0.1\n",
            "test",
        )
        .expect("a valid configuration");
        let smoother = WindowSmoother::new(&config, &config.world_model(), 2, 1);
        assert_eq!(smoother.lead(), 0);
        let lagging = Config::from_toml("[world]\nlag = 0.05\n", "test").expect("valid");
        assert!(WindowSmoother::new(&lagging, &lagging.world_model(), 2, 1).lead() > 0);
        let l = smoother.length() as usize;
        let doublets = 7;
        let inputs: Vec<Unicycle> = (0..doublets * l)
            .map(|k| Unicycle::new(0.05 + 0.004 * (k % 5) as f64, 0.3 - 0.07 * (k % 4) as f64))
            .collect();
        let pose = |k: usize| Pose::new(0.01 * k as f64, 0.002 * k as f64, 0.05 * k as f64);
        let window = Window {
            lead: 0,
            inputs,
            before: Some(Unicycle::new(0.04, 0.1)),
            start: pose(0),
            anchors: (0..doublets * l)
                .map(|s| (s > 0 && s % l == 0).then(|| pose(s) + Pose::new(1e-4, -2e-4, 3e-3)))
                .collect(),
        };
        let nominal = smoother.eve.run(&window, |_| Unicycle::zeros());
        // Every pose, offset, update and jump of a run, step by step (each step read from
        // the run that holds it).
        let bits = |steps: &[(&WindowRun, usize)], jumps: &[Pose]| -> Vec<u64> {
            let poses = steps
                .iter()
                .flat_map(|&(run, i)| &run.poses[i])
                .chain(jumps);
            let offsets = steps.iter().flat_map(|&(run, i)| &run.offsets[i]);
            let updates = steps
                .iter()
                .flat_map(|&(run, i)| &run.updates[i])
                .flat_map(|u| {
                    [
                        u.duration, u.wheels.x, u.wheels.y, u.speeds.x, u.speeds.y, u.start.x,
                        u.start.y, u.start.z,
                    ]
                });
            poses
                .flat_map(|p| p.iter().copied().collect::<Vec<_>>())
                .chain(offsets.copied())
                .chain(updates)
                .map(f64::to_bits)
                .collect()
        };
        for position in 0..doublets {
            for h in 0..smoother.perturbation.patterns() {
                let offset = smoother.perturbation.offset(h);
                let at = l * position;
                let whole = smoother
                    .eve
                    .run(&window, |step| match step.checked_sub(at) {
                        Some(s) => smoother.step_offset(s, offset),
                        None => Unicycle::zeros(),
                    });
                let near = smoother.run_near(&window, &nominal, position, offset);
                let steps = 0..nominal.poses.len();
                let near_steps: Vec<_> = steps.clone().map(|s| near.source(&nominal, s)).collect();
                let whole_steps: Vec<_> = steps.map(|s| (&whole, s)).collect();
                assert_eq!(
                    bits(&near_steps, &near.jumps),
                    bits(&whole_steps, &whole.jumps),
                    "doublet {position}, pattern {h}"
                );
            }
        }
    }

    /// The recipes expand every function of a doublet's pattern exactly — its mean plus one
    /// coefficient per recipe, `c_S = mean_h f(h)·Π_{b∈S} s_b(h)` — so a known neighbour's
    /// effect is taken off exactly at any alphabet; binary keeps its order (v, ω, v·ω).
    #[test]
    fn the_walsh_recipes_expand_every_function_of_the_pattern() {
        assert_eq!(walsh_recipes(1).collect::<Vec<_>>(), vec![vec![0]]);
        assert_eq!(
            walsh_recipes(2).collect::<Vec<_>>(),
            vec![vec![0], vec![1], vec![0, 1]]
        );
        for bits in 1..=6 {
            let patterns = 1usize << bits;
            let f = |h: usize| (1.7 * h as f64 + 0.3).sin() + 0.01 * (h * h) as f64;
            let mean = (0..patterns).map(f).sum::<f64>() / patterns as f64;
            let coefficients: Vec<(Vec<usize>, f64)> = walsh_recipes(bits)
                .map(|recipe| {
                    let c = (0..patterns)
                        .map(|h| f(h) * pattern_sign(h, &recipe))
                        .sum::<f64>()
                        / patterns as f64;
                    (recipe, c)
                })
                .collect();
            assert_eq!(coefficients.len(), patterns - 1);
            for h in 0..patterns {
                let expanded = mean
                    + coefficients
                        .iter()
                        .map(|(recipe, c)| c * pattern_sign(h, recipe))
                        .sum::<f64>();
                assert!((expanded - f(h)).abs() < 1e-12, "{bits} bits, pattern {h}");
            }
        }
    }

    /// The realised bound's per-bit terms are the exact symbol posterior: for any pattern
    /// log-likelihoods, the chain LLRs given the true bits before each sum to the surprisal
    /// `Σᵢ ln(1 + e^{∓Lᵢ}) = −ln P(word | view)` of the true symbols, enumerated over all
    /// `levels^dims` patterns (4 and 8 levels, one and two dimensions, both labelings).
    #[test]
    fn the_chained_bits_sum_to_the_exact_symbol_surprisal() {
        for (levels, dims, labeling) in [
            (4, 2, Labeling::Natural),
            (4, 1, Labeling::Gray),
            (8, 2, Labeling::Gray),
        ] {
            let perturbation = Perturbation {
                levels,
                bits_per_doublet: dims,
                labeling,
                ..Perturbation::binary(Unicycle::new(0.035, 0.035), dims, None)
            };
            let patterns = perturbation.patterns();
            let ll: Vec<f64> = (0..patterns)
                .map(|h| 3.0 * (0.9 * h as f64 + 0.4).cos())
                .collect();
            let total = ll.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let normaliser = total + ll.iter().map(|l| (l - total).exp()).sum::<f64>().ln();
            for word in 0..patterns {
                let llr = chained_llrs(&ll, &perturbation, word as u64);
                let surprisal: f64 = (0..perturbation.key_bits())
                    .map(|i| {
                        let signed = if word >> i & 1 == 0 { llr[i] } else { -llr[i] };
                        (-signed).exp().ln_1p()
                    })
                    .sum();
                let exact = normaliser - ll[word];
                assert!(
                    (surprisal - exact).abs() < 1e-9,
                    "{levels} levels, {dims} dims, word {word}: {surprisal} vs {exact}"
                );
            }
        }
    }

    /// The moment-matched decision against the exact sum on the same recorded sessions
    /// (replicates 0 and 1 of each of [`WORLDS`], ≈ 3,000 key bits each). Capped at 4 bits,
    /// one of the target's two neighbours — at distance 1, nearer than the default window's
    /// moment-matched doublets at distance 2 — has its symbol's 15 Walsh coefficients
    /// integrated as unit Gaussians; at 8 bits both are summed exactly. The exact posterior
    /// is the Bayes one, so for each key bit of the camera adversary's own decisions: her
    /// mean surprisal of the true bit with the approximation is not below the exact one's by
    /// more than 3 standard errors of the paired differences (a proper score: its expectation
    /// is the Kullback–Leibler divergence, ≥ 0), and her errors with the approximation are
    /// no fewer than with the exact sum by more than `3·√discordant` (the paired count
    /// difference's standard deviation at equal error rates is at most √discordant).
    #[test]
    fn the_moment_matched_neighbours_do_not_beat_the_exact_sum() {
        for world in WORLDS {
            let config = multilevel_in(world);
            let key_bits = 4;
            let (mut differences, mut shifts) = (Vec::new(), Vec::new());
            let (mut errors_approximate, mut errors_exact, mut discordant) =
                (0_usize, 0_usize, 0_usize);
            let camera = |list: Vec<Collected>| -> BTreeMap<u32, Collected> {
                list.into_iter()
                    .filter(|c| c.camera)
                    .map(|c| (c.doublet, c))
                    .collect()
            };
            for replicate in 0..2 {
                let approximate = camera(judgements(&config, replicate, Some(4)));
                let exact = camera(judgements(&config, replicate, Some(8)));
                assert_eq!(approximate.len(), exact.len(), "{world} {replicate}");
                for (doublet, a) in &approximate {
                    let e = &exact[doublet];
                    let Some(word) = e.word else { continue };
                    let pairs = a.own.iter().zip(&e.own).take(key_bits);
                    for (i, (&la, &le)) in pairs.enumerate() {
                        let bit = word >> i & 1;
                        let wrong = |llr: f64| (llr < 0.0) != (bit == 1);
                        let (wa, we) = (wrong(la), wrong(le));
                        errors_approximate += usize::from(wa);
                        errors_exact += usize::from(we);
                        discordant += usize::from(wa != we);
                        differences.push(bit_surprisal(la, bit) - bit_surprisal(le, bit));
                        shifts.push((la - le).abs());
                    }
                }
            }
            let bits = differences.len();
            assert!(bits > 2_000, "{world}: {bits}");
            let (mean, error) = mean_and_error(&differences);
            shifts.sort_by(f64::total_cmp);
            let at = |q: f64| shifts[((bits - 1) as f64 * q) as usize];
            println!(
                "{}: {bits} bits: errors {errors_approximate} moment-matched, {errors_exact} exact, \
             {discordant} discordant; surprisal difference {mean:.2e} ± {error:.2e} nats per \
             bit; |ΔL| median {:.4}, 99th percentile {:.4}, largest {:.4}",
                world.replace('\n', " "),
                at(0.5),
                at(0.99),
                at(1.0)
            );
            assert!(mean >= -3.0 * error, "{world}: {mean} ± {error}");
            assert!(
                errors_approximate as f64 >= errors_exact as f64 - 3.0 * (discordant as f64).sqrt(),
                "{world}: {errors_approximate} vs {errors_exact}, {discordant} discordant"
            );
        }
    }

    /// Her realised bound against her exact joint posterior over several doublets' symbols
    /// (replicates 0 and 1 of each of [`WORLDS`]): for each doublet the camera
    /// adversary judges, its window's block — the doublet and its ±1 neighbours — enumerated
    /// over all `16³` patterns through the smoother's own likelihood, the doublets beyond at
    /// their true symbols. The target's realised term (its chained LLRs, given the others and
    /// its bits before) is the enumeration's conditional to 10⁻⁶ nats; summed over the
    /// block, the realised terms `Σ_i −ln P(B_i | view, B_{≠i})` are not above the exact
    /// joint surprisal `−ln P(B_block | view)`: on average (conditioning never raises the
    /// expected surprisal) within 3 standard errors, and at ε = 0.05 the realised sums'
    /// ε-quantile is not above the joint's, taken at its upper 3σ order statistic.
    #[test]
    fn the_realised_terms_do_not_exceed_the_exact_joint_surprisal() {
        for world in WORLDS {
            let config = multilevel_in(world);
            let checks: Vec<JointCheck> = (0..2)
                .flat_map(|replicate| judgements(&config, replicate, None))
                .filter_map(|c| c.joint)
                .collect();
            let count = checks.len();
            assert!(count > 500, "{world}: {count}");
            for check in &checks {
                assert!(
                    (check.target_table - check.target_realised).abs() < 1e-6,
                    "{world}: {check:?}"
                );
            }
            let gaps: Vec<f64> = checks.iter().map(|c| c.joint - c.chained).collect();
            let (mean, error) = mean_and_error(&gaps);
            let sorted = |f: fn(&JointCheck) -> f64| {
                let mut values: Vec<f64> = checks.iter().map(f).collect();
                values.sort_by(f64::total_cmp);
                values
            };
            let (joint, chained) = (sorted(|c| c.joint), sorted(|c| c.chained));
            let (m, epsilon) = (count as f64, 0.05);
            let point = (m * epsilon) as usize;
            let high = ((m * epsilon + 3.0 * (m * epsilon * (1.0 - epsilon)).sqrt()).ceil()
                as usize)
                .min(count - 1);
            let mean_of = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
            println!(
                "{}: {count} blocks: joint − realised {mean:.2e} ± {error:.2e} nats; mean joint {:.3}, \
             mean realised {:.3}; ε-quantiles: realised {:.4}, joint {:.4} (upper order \
             statistic {:.4}); realised above joint in {} blocks",
                world.replace('\n', " "),
                mean_of(&joint),
                mean_of(&chained),
                chained[point],
                joint[point],
                joint[high],
                gaps.iter().filter(|g| **g < 0.0).count()
            );
            assert!(mean >= -3.0 * error, "{world}: {mean} ± {error}");
            assert!(
                chained[point] <= joint[high],
                "{world}: {} > {}",
                chained[point],
                joint[high]
            );
        }
    }
}
