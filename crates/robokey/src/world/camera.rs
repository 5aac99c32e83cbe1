//! Eve's real camera (docs/world.md, "Eve's camera"): frames at a fixed rate with a random
//! phase per session, each the true pose at its instant plus white noise, filming the motion
//! between the sample instants.

use rand::RngExt;
use rand::rngs::ChaCha8Rng;

use super::plant::Noise;
use crate::model::Pose;

/// One frame of Eve's camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// When it was taken (s since the session began).
    pub time: f64,
    /// The pose she measured (m, m, rad).
    pub pose: Pose,
}

/// A camera filming at `fps` frames per second.
#[derive(Debug)]
pub struct FrameCamera {
    interval: f64,
    phase: f64,
    /// Index of the next frame.
    next: u64,
    noise: Noise,
}

impl FrameCamera {
    /// Frames at `fps` (frames/s) with noise `noise` and a phase drawn uniformly in one frame
    /// interval from `phase`.
    pub fn new(fps: f64, noise: Noise, mut phase: ChaCha8Rng) -> Self {
        let interval = 1.0 / fps;
        Self {
            interval,
            phase: phase.random::<f64>() * interval,
            next: 0,
            noise,
        }
    }

    /// The time of frame `m` (s).
    fn time(&self, m: u64) -> f64 {
        self.phase + m as f64 * self.interval
    }

    /// The frames taken over a stretch of the plant's trail (poses with their times, the
    /// first the last one of the previous stretch): each pose between two points of the
    /// trail is on the straight line between them (the motion's updates are short).
    pub fn film(&mut self, trail: &[(f64, Pose)], frames: &mut Vec<Frame>) {
        let mut segment = 0;
        while segment + 1 < trail.len() {
            let time = self.time(self.next);
            let (t0, p0) = trail[segment];
            let (t1, p1) = trail[segment + 1];
            if time >= t1 {
                segment += 1;
                continue;
            }
            if time >= t0 {
                let fraction = (time - t0) / (t1 - t0);
                let pose = p0 + (p1 - p0) * fraction;
                frames.push(Frame {
                    time,
                    pose: pose + self.noise.draw(),
                });
            }
            self.next += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{Purpose, stream};

    #[test]
    fn frames_fall_on_the_trail_at_their_rate() {
        let mut camera = FrameCamera::new(
            30.0,
            Noise::new(stream(1, Purpose::Camera, 0), [0.0; 3]),
            stream(1, Purpose::CameraPhase, 0),
        );
        let line = |t: f64| Pose::new(2.0 * t, -t, 0.5 * t);
        let mut frames = Vec::new();
        let trail: Vec<(f64, Pose)> = (0..=10)
            .map(|i| (0.1 * f64::from(i), line(0.1 * f64::from(i))))
            .collect();
        camera.film(&trail[..4], &mut frames);
        camera.film(&trail[3..], &mut frames);
        assert_eq!(frames.len(), 30);
        assert!(frames[0].time < 1.0 / 30.0);
        for (m, frame) in frames.iter().enumerate() {
            assert!((frame.time - (frames[0].time + m as f64 / 30.0)).abs() < 1e-12);
            assert!((frame.pose - line(frame.time)).norm() < 1e-12);
        }
    }
}
