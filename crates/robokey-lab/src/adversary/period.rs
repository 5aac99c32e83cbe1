//! One decided period, as an eavesdropper and the controller saw it.

use serde::{Deserialize, Serialize};

/// One decided period, as one strategy saw it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PeriodRecord {
    /// Session index.
    pub session: u32,
    /// Step within the session.
    pub step: u32,
    /// Periods heard since her first session began (`session·N + step + 1`).
    pub period: u64,
    /// The applied bit.
    pub bit: u8,
    /// The controller's decision.
    pub controller: u8,
    /// Her decision.
    pub eve: u8,
    /// Her relative error on r after this period (fraction).
    pub r_error: f64,
    /// Her relative error on D after this period (fraction).
    pub d_error: f64,
}
