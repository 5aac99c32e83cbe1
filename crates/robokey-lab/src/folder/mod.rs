//! A sweep folder: its files (`runs.csv`, `summary.json`, `manifest.json`,
//! `config.resolved.toml`, `traces/`), the interruptible sweep that writes them, reading a
//! complete folder back, and `merge` of shard folders.

pub mod layout;
pub mod load;
pub mod manifest;
pub mod merge;
pub mod rows;
pub mod summary;
pub mod sweep;
