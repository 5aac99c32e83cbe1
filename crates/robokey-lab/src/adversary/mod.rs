//! `robokey eve` and the adversary section of `reproduce`: eavesdropping campaigns computed
//! ([`campaign`], [`window`]) and kept in their folder ([`stage`]);
//! [`crate::report::adversary`] renders them.

pub mod campaign;
pub mod period;
pub mod stage;
pub mod window;

pub use campaign::{
    Campaign, MODEL_TOLERANCE, SessionRecord, StrategyRun, eavesdropper, listen, overhear,
    run_campaigns, run_campaigns_with,
};
pub use period::PeriodRecord;
pub use window::{match_period, windowed_error_rates};
