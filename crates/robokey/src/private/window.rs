//! A window of doublets as Eve simulates it (docs/world.md, "The window smoother"): the
//! world's own actuator and motion, noise-free, from the controller's sample at the window's
//! start, under the public nominal inputs and any bit pattern — the means her likelihood
//! compares her observations with, and the path it is linearised about.

use crate::model::{DiffDrive, Pose, Unicycle};
use crate::world::{Actuator, Motion, Piece, StepNoise, SubStep, WorldModel};

/// When Eve observed the pose, within the window.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Instant {
    /// At the sample instant `k0 + step` (the start of that window step, or the window's end).
    Sample(usize),
    /// A frame during window step `step`, between its pose updates `update` and `update + 1`
    /// at `fraction` of the way.
    Frame {
        /// Window step.
        step: usize,
        /// Index of the pose update it falls in.
        update: usize,
        /// How far into it (0 to 1).
        fraction: f64,
    },
}

/// The world's motion as Eve runs it over a window.
#[derive(Clone, Debug)]
pub struct WindowWorld {
    /// Wheel geometry (the agreed one).
    pub drive: DiffDrive,
    /// The motors' limit (rad/s).
    pub wheel_limit: f64,
    /// The world.
    pub world: WorldModel,
    /// The world's motion.
    pub motion: Motion,
}

impl WindowWorld {
    /// The world's motion for wheel geometry `drive`, the motors' limit (rad/s) and sample
    /// time `T` (s).
    #[must_use]
    pub fn new(world: &WorldModel, drive: DiffDrive, wheel_limit: f64, sample_time: f64) -> Self {
        Self {
            drive,
            wheel_limit,
            world: *world,
            motion: Motion::new(drive, sample_time, world),
        }
    }
}

/// One window: its steps' public inputs and where it starts.
#[derive(Clone, Debug)]
pub struct Window {
    /// Steps simulated before the window for the wheels' state only (their pose is not).
    pub lead: usize,
    /// The nominal input of every simulated step, lead first (m/s, rad/s).
    pub inputs: Vec<Unicycle>,
    /// The input acting before the first simulated step (none: the robot was at rest).
    pub before: Option<Unicycle>,
    /// The pose the window starts from: the controller's sample at its first instant.
    pub start: Pose,
    /// Per window step, the pose its path restarts from, if any: the controller's samples
    /// at the doublets' boundaries, so that the path Eve linearises about never strays
    /// from where the robot was (the noise's effect stays small).
    pub anchors: Vec<Option<Pose>>,
}

/// A simulated window: each step's pose updates and the pose at every observation.
#[derive(Clone, Debug)]
pub struct WindowRun {
    /// Per window step: the pose before each update and after the last.
    pub poses: Vec<Vec<Pose>>,
    /// Per window step: each update's offset from the step's start (s), the first 0.
    pub offsets: Vec<Vec<f64>>,
    /// Per window step: its pose updates.
    pub updates: Vec<Vec<SubStep>>,
    /// Per window step: how far the path had got from the anchor it restarts from there,
    /// `path − anchor` (zero where it does not restart).
    pub jumps: Vec<Pose>,
}

impl WindowRun {
    /// The pose at an observation.
    #[must_use]
    pub fn at(&self, instant: Instant) -> Pose {
        pose_at(self.poses.len(), |step| &self.poses[step], instant)
    }

    /// The pose's rate over the update that ends at window instant `step` (m/s, m/s,
    /// rad/s): what moves a jittered sample there.
    #[must_use]
    pub fn velocity_before(&self, step: usize) -> Pose {
        let poses = &self.poses[step - 1];
        let offsets = &self.offsets[step - 1];
        let n = poses.len() - 1;
        (poses[n] - poses[n - 1]) / (offsets[n] - offsets[n - 1])
    }

    /// Where a frame `offset` seconds into window step `step` falls among its updates.
    #[must_use]
    pub fn locate(&self, step: usize, offset: f64) -> Instant {
        let offsets = &self.offsets[step];
        let update = offsets
            .windows(2)
            .position(|w| offset < w[1])
            .unwrap_or(offsets.len() - 2);
        let (t0, t1) = (offsets[update], offsets[update + 1]);
        Instant::Frame {
            step,
            update,
            fraction: ((offset - t0) / (t1 - t0)).clamp(0.0, 1.0),
        }
    }
}

/// The pose at an observation of a run of `steps` window steps whose poses at step `k`
/// (before each update and after the last) are `poses(k)`: a sample's the step's first (the
/// last step's last at the window's end), a frame's interpolated within its update.
pub fn pose_at<'a>(steps: usize, poses: impl Fn(usize) -> &'a [Pose], instant: Instant) -> Pose {
    match instant {
        Instant::Sample(step) if step < steps => poses(step)[0],
        Instant::Sample(step) => *poses(step - 1).last().expect("a step has its end pose"),
        Instant::Frame {
            step,
            update,
            fraction,
        } => {
            let poses = poses(step);
            poses[update] + (poses[update + 1] - poses[update]) * fraction
        }
    }
}

impl WindowWorld {
    /// Simulates `window` with `offset(i)` added to the nominal input of simulated step `i`
    /// (lead steps first): the wheels from the lead steps on, the pose from the window's
    /// start.
    pub fn run(&self, window: &Window, offset: impl Fn(usize) -> Unicycle) -> WindowRun {
        let w = &self.world;
        let mut actuator = Actuator::new(w.lag, w.delay, w.command_quantum, self.wheel_limit);
        if let Some(before) = window.before {
            // Settled on the input before: the delay line flushed, the lag died out.
            actuator.apply(self.drive.to_wheels(before));
            actuator.advance(
                w.delay + 40.0 * w.lag + self.motion.sample_time,
                &mut Vec::new(),
            );
        }
        let steps = window.inputs.len() - window.lead;
        let mut run = WindowRun {
            poses: Vec::with_capacity(steps),
            offsets: Vec::with_capacity(steps),
            updates: Vec::with_capacity(steps),
            jumps: Vec::with_capacity(steps),
        };
        let mut pose = window.start;
        let mut pieces: Vec<Piece> = Vec::new();
        let mut trail = Vec::new();
        for (i, input) in window.inputs.iter().enumerate() {
            actuator.apply(self.drive.to_wheels(input + offset(i)));
            pieces.clear();
            actuator.advance(self.motion.sample_time, &mut pieces);
            if i < window.lead {
                continue;
            }
            let mut jump = Pose::zeros();
            if let Some(Some(anchor)) = window.anchors.get(i - window.lead) {
                jump = pose - anchor;
                pose = *anchor;
            }
            run.jumps.push(jump);
            trail.clear();
            let mut updates = Vec::with_capacity(pieces.len());
            let end = self.motion.integrate(
                pose,
                &pieces,
                &StepNoise::NONE,
                &mut trail,
                Some(&mut updates),
            );
            let mut poses = Vec::with_capacity(trail.len() + 1);
            let mut offsets = Vec::with_capacity(trail.len() + 1);
            poses.push(pose);
            offsets.push(0.0);
            for &(t, p) in &trail {
                offsets.push(t);
                poses.push(p);
            }
            run.poses.push(poses);
            run.offsets.push(offsets);
            run.updates.push(updates);
            pose = end;
        }
        run
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Config;

    /// Noise-free, Eve's run of a window is the plant's motion: same poses at the instants.
    #[test]
    fn a_window_run_is_the_plants_motion_without_noise() {
        let config = Config::from_toml(
            "[world]\npreset = \"khepera-iv\"\nprocess_std = [0.0, 0.0, 0.0]\nslip_std = 0.0\n",
            "t",
        )
        .unwrap();
        let world = config.world_model();
        let drive = DiffDrive {
            wheel_radius: 0.021,
            axle_length: 0.1047,
        };
        let inputs: Vec<Unicycle> = (0..12)
            .map(|k| Unicycle::new(0.05 + 0.003 * f64::from(k), 0.2 - 0.04 * f64::from(k)))
            .collect();
        let mut plant = crate::world::WorldPlant::new(
            &world,
            drive,
            38.0,
            0.2,
            crate::world::PlantStreams {
                process: crate::rng::stream(1, crate::rng::Purpose::Process, 0),
                slip: crate::rng::stream(1, crate::rng::Purpose::Slip, 0),
            },
            false,
        );
        let mut poses = vec![plant.pose()];
        for u in &inputs {
            plant.apply(drive.to_wheels(*u));
            plant.step();
            poses.push(plant.pose());
        }
        let eve = WindowWorld::new(&world, drive, 38.0, 0.2);
        let window = Window {
            lead: 0,
            inputs: inputs.clone(),
            before: None,
            start: Pose::zeros(),
            anchors: Vec::new(),
        };
        let run = eve.run(&window, |_| Unicycle::zeros());
        for (k, pose) in poses.iter().enumerate() {
            assert!(
                (run.at(Instant::Sample(k)) - pose).norm() < 1e-15,
                "step {k}"
            );
        }
    }
}
