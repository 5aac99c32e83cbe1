//! Running an experiment's grid: which runs a shard does, the runs in parallel and
//! deterministic, and the physical sessions that every eavesdropper of a configuration
//! shares.

pub mod grid;
pub mod row;
pub mod sessions;
pub mod shard;

pub use grid::{run_experiment, with_jobs};
pub use row::RunRow;
pub use shard::Shard;
