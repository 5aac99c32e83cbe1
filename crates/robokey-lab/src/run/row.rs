//! One finished run.

use robokey::Metrics;

/// One finished run: its place in the grid and its metrics, a row of `runs.csv` (its swept
/// values are its point's, [`crate::experiment::Point::params`]).
#[derive(Clone, Debug, PartialEq)]
pub struct RunRow {
    /// Run index = point · replicates + replicate.
    pub run: usize,
    /// Grid point.
    pub point: usize,
    /// Replicate within the point.
    pub replicate: u32,
    /// The run's metrics.
    pub metrics: Metrics,
}
