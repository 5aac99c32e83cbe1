//! Polyline references with cubic zero-velocity segments (docs/model.md), like MATLAB's
//! `cubicpolytraj` with zero velocity at every waypoint.

use nalgebra::Vector2;

/// Reference position (m), velocity (m/s) and acceleration (m/s²) at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReferencePoint {
    /// Position `(xr, yr)` (m).
    pub position: Vector2<f64>,
    /// Velocity `(ẋr, ẏr)` (m/s).
    pub velocity: Vector2<f64>,
    /// Acceleration `(ẍr, ÿr)` (m/s²).
    pub acceleration: Vector2<f64>,
}

/// A reference that visits its waypoints in order, one segment per `segment_time`,
/// stopping at each; after the last waypoint it holds still.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    points: Vec<Vector2<f64>>,
    segment_time: f64,
}

impl Trajectory {
    /// Builds the reference through `waypoints` (m), `segment_time` (s) per segment,
    /// repeated `laps` times. Later laps skip their first waypoint when the polyline is
    /// closed (last = first); otherwise the robot drives back to the start between laps.
    /// Returns `None` for fewer than two waypoints, a non-positive or non-finite segment
    /// time, or zero laps.
    #[must_use]
    pub fn new(waypoints: &[[f64; 2]], segment_time: f64, laps: u32) -> Option<Self> {
        if waypoints.len() < 2 || !(segment_time > 0.0 && segment_time.is_finite()) || laps == 0 {
            return None;
        }
        let lap: Vec<Vector2<f64>> = waypoints.iter().map(|p| Vector2::new(p[0], p[1])).collect();
        let closed = lap.first() == lap.last();
        let mut points = lap.clone();
        for _ in 1..laps {
            points.extend_from_slice(if closed { &lap[1..] } else { &lap });
        }
        Some(Self {
            points,
            segment_time,
        })
    }

    /// The paper's 1 m square, 17 s per side, 3 laps (204 s).
    #[must_use]
    pub fn paper_square() -> Self {
        Self::new(&SQUARE, 17.0, 3).expect("the built-in square is valid")
    }

    /// Total duration (s).
    #[must_use]
    pub fn duration(&self) -> f64 {
        (self.points.len() - 1) as f64 * self.segment_time
    }

    /// Number of commands `N = ⌊duration / T⌋` at sample time `T` (s).
    #[must_use]
    pub fn steps(&self, sample_time: f64) -> usize {
        (self.duration() / sample_time + 1e-9).floor() as usize
    }

    /// The reference at time `t` (s). Segments are right-continuous: at a waypoint time the
    /// next segment applies.
    ///
    /// Inlined, so that a caller who reads only the position does not compute the rest.
    #[must_use]
    #[inline]
    pub fn at(&self, t: f64) -> ReferencePoint {
        let segments = self.points.len() - 1;
        // The segment is `⌊t/T_s + 10⁻⁹⌋`: for a non-negative argument the truncating cast
        // is that floor (`floor` itself is a library call on baseline x86-64), and a NaN
        // falls on segment 0 either way.
        let scaled = t / self.segment_time + 1e-9;
        let index = scaled as usize;
        if scaled < 0.0 || index >= segments {
            let hold = if scaled < 0.0 {
                self.points[0]
            } else {
                self.points[segments]
            };
            return ReferencePoint {
                position: hold,
                velocity: Vector2::zeros(),
                acceleration: Vector2::zeros(),
            };
        }
        let (start, end) = (self.points[index], self.points[index + 1]);
        let ts = self.segment_time;
        let s = ((t - index as f64 * ts) / ts).clamp(0.0, 1.0);
        let delta = end - start;
        ReferencePoint {
            position: start + delta * (3.0 * s * s - 2.0 * s * s * s),
            velocity: delta * (6.0 * (s - s * s) / ts),
            acceleration: delta * ((6.0 - 12.0 * s) / (ts * ts)),
        }
    }
}

/// The paper's square, (0,0) → (1,0) → (1,1) → (0,1) → (0,0) (m).
pub const SQUARE: [[f64; 2]; 5] = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_each_waypoint_at_its_time_with_zero_velocity() {
        let traj = Trajectory::paper_square();
        assert_eq!(traj.steps(0.2), 1020);
        for (i, p) in traj.points.iter().enumerate() {
            let r = traj.at(i as f64 * 17.0);
            assert!((r.position - p).norm() < 1e-12, "waypoint {i}");
            assert!(r.velocity.norm() < 1e-12, "velocity at waypoint {i}");
        }
        assert_eq!(traj.points.len(), 13);
    }

    #[test]
    fn matches_the_cubic_between_waypoints() {
        let traj = Trajectory::paper_square();
        // Second side, (1,0) → (1,1), starting at t = 17 s.
        for &s in &[0.1, 0.25, 0.5, 0.9] {
            let r = traj.at(17.0 + s * 17.0);
            let q = 3.0 * s * s - 2.0 * s * s * s;
            assert!((r.position - Vector2::new(1.0, q)).norm() < 1e-12);
            assert!((r.velocity.y - 6.0 * (s - s * s) / 17.0).abs() < 1e-12);
            assert!((r.acceleration.y - (6.0 - 12.0 * s) / 289.0).abs() < 1e-12);
        }
        // Peak speed mid-side: 1.5 m / 17 s = 0.0882 m/s.
        assert!((traj.at(8.5).velocity.norm() - 1.5 / 17.0).abs() < 1e-12);
    }

    #[test]
    fn holds_still_after_the_end_and_rejects_bad_input() {
        let traj = Trajectory::paper_square();
        let end = traj.at(500.0);
        assert_eq!(end.position, Vector2::new(0.0, 0.0));
        assert_eq!(end.velocity, Vector2::zeros());
        assert!(Trajectory::new(&[[0.0, 0.0]], 17.0, 1).is_none());
        assert!(Trajectory::new(&SQUARE, 0.0, 1).is_none());
        assert!(Trajectory::new(&SQUARE, 17.0, 0).is_none());
    }

    #[test]
    fn open_polylines_drive_back_between_laps() {
        let traj = Trajectory::new(&[[0.0, 0.0], [1.0, 0.0]], 10.0, 2).unwrap();
        assert_eq!(traj.duration(), 30.0);
        assert!((traj.at(20.0).position - Vector2::new(0.0, 0.0)).norm() < 1e-12);
    }
}
