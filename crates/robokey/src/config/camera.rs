//! Eve's camera as the key is sized against it (docs/threat-model.md, docs/world.md): stated
//! per sample instant (`eve.camera_std`), or in camera terms — frames per second and noise
//! per frame (`eve.camera_fps`, `eve.camera_frame_std`). The statement is a [`Camera`], the
//! same description as the world's real camera.

use crate::world::Camera;

/// Eve's camera as a key's statement: `eve.camera_std` per instant, or in frames.
impl Camera {
    /// The per-instant noise `[m, m, rad]` Eve's modelled view uses at sample time `T`
    /// (s): the statement itself, or for frames `σ_f / √E`, `E` = [`triangle_energy`] at
    /// the phase that favours her most.
    #[must_use]
    pub fn per_instant_std(&self, sample_time: f64) -> [f64; 3] {
        match *self {
            Self::Instants { std } => std,
            Self::Frames { fps, frame_std } => {
                let energy = best_phase_energy(fps, sample_time);
                frame_std.map(|s| s / energy.sqrt())
            }
        }
    }

    /// The statement in words, in mm and mrad, e.g. `8 mm, 8 mm, 8 mrad per sample instant`
    /// or `16 mm, 16 mm, 16 mrad per frame at 30 frames/s`.
    #[must_use]
    pub fn describe(&self) -> String {
        match self {
            Self::Instants { std } => format!("{} per sample instant", millimetres(*std)),
            Self::Frames { fps, frame_std } => {
                format!("{} per frame at {fps} frames/s", millimetres(*frame_std))
            }
        }
    }
}

/// A pose's standard deviations (m, m, rad) for people: "a mm, b mm, c mrad".
#[must_use]
pub fn millimetres(std: [f64; 3]) -> String {
    format!(
        "{} mm, {} mm, {} mrad",
        1e3 * std[0],
        1e3 * std[1],
        1e3 * std[2]
    )
}

/// `E(φ) = Σ_m h(t_m)²` over frames `t_m = φ + m/f` inside a doublet `[0, 2T]`, with `h` the
/// unit triangle the bit draws in position (0 at the boundaries, 1 at the mid instant T):
/// the least-squares amplitude from those frames, the boundaries known, has the variance
/// `σ_f²/E` of one mid-instant sample of noise `σ_f/√E`. For many frames `E → 2fT/3`.
#[must_use]
pub fn triangle_energy(fps: f64, sample_time: f64, phase: f64) -> f64 {
    let interval = 1.0 / fps;
    let end = 2.0 * sample_time;
    let mut energy = 0.0;
    let mut t = phase.rem_euclid(interval);
    while t < end {
        let h = 1.0 - (t - sample_time).abs() / sample_time;
        energy += h * h;
        t += interval;
    }
    energy
}

/// The largest [`triangle_energy`] over the frames' phase. Between the phases at which a
/// frame crosses 0, T or 2T each term is a convex quadratic of the phase, so the largest
/// lies at one of them: a frame at 0, at T or at 2T.
#[must_use]
pub fn best_phase_energy(fps: f64, sample_time: f64) -> f64 {
    [0.0, sample_time, 2.0 * sample_time]
        .into_iter()
        .map(|phase| triangle_energy(fps, sample_time, phase))
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_at_the_mid_instant_at_an_integer_frame_count_per_step() {
        // 30 frames/s, T = 0.2 s: 6 frames per step, one at T: 1 + 2·Σ(1 − m/6)², m = 1…5.
        let expected = 1.0 + 2.0 * (25.0 + 16.0 + 9.0 + 4.0 + 1.0) / 36.0;
        assert!((best_phase_energy(30.0, 0.2) - expected).abs() < 1e-12);
    }

    #[test]
    fn many_frames_tend_to_the_continuous_camera() {
        // E → 2fT/3 (docs/world.md); the worst phase adds at most one frame's worth.
        for fps in [60.0, 240.0, 1000.0] {
            let continuous = 2.0 * fps * 0.2 / 3.0;
            let energy = best_phase_energy(fps, 0.2);
            assert!(
                energy >= continuous && energy < continuous + 0.5,
                "{fps}: {energy}"
            );
        }
    }

    #[test]
    fn the_best_phase_beats_every_other_phase() {
        for fps in [2.0, 7.0, 13.3, 30.0] {
            let best = best_phase_energy(fps, 0.2);
            for i in 0..1000 {
                let phase = f64::from(i) / 1000.0 / fps;
                assert!(
                    triangle_energy(fps, 0.2, phase) <= best + 1e-12,
                    "{fps} {phase}"
                );
            }
        }
    }

    #[test]
    fn a_slow_camera_is_worth_its_one_frame_at_the_mid_instant() {
        // 5 frames/s at T = 0.2 s: one frame per step; at the mid instant it is one sample.
        let statement = Camera::Frames {
            fps: 5.0,
            frame_std: [0.004; 3],
        };
        assert!((statement.per_instant_std(0.2)[0] - 0.004).abs() < 1e-15);
        assert_eq!(
            statement.describe(),
            "4 mm, 4 mm, 4 mrad per frame at 5 frames/s"
        );
    }
}
