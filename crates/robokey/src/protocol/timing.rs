//! Time as an input (docs/protocol.md, "Timing"): the core never reads a clock. Every input
//! carries `now`, a [`Time`] the shell measures from an epoch of its choosing (the agent's
//! start, or a virtual network's zero); every endpoint says when it next needs to be woken
//! (`poll_timeout`), and the shell calls it back then.

use std::time::Duration;

/// A point in time: the [`Duration`] since the shell's epoch.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Time(Duration);

impl Time {
    /// The epoch.
    pub const ZERO: Self = Self(Duration::ZERO);

    /// The time `since` the epoch.
    #[must_use]
    pub const fn from_duration(since: Duration) -> Self {
        Self(since)
    }

    /// The duration since the epoch.
    #[must_use]
    pub const fn since_epoch(self) -> Duration {
        self.0
    }

    /// How long after `earlier` this is (zero when it is not later).
    #[must_use]
    pub fn saturating_since(self, earlier: Self) -> Duration {
        self.0.saturating_sub(earlier.0)
    }
}

impl std::ops::Add<Duration> for Time {
    type Output = Self;

    fn add(self, rhs: Duration) -> Self {
        Self(self.0.saturating_add(rhs))
    }
}

/// How the robot's clock runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pace {
    /// Sample `k` at `t₀ + k·T`; a command is late after `T·deadline_fraction`.
    Realtime,
    /// A virtual clock for tests over real sockets: sample `k + 1` as soon as command `k` is
    /// applied, or `step_timeout` after sample `k` when it is missing.
    Lockstep,
}

/// The timers of a session (docs/protocol.md, "Timing").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timing {
    /// How the robot's clock runs.
    pub pace: Pace,
    /// Lockstep: how long the robot waits for a command before treating it as missing.
    pub step_timeout: Duration,
    /// Realtime: a command is late after this fraction of `T`.
    pub deadline_fraction: f64,
    /// A side that hears no valid frame for this long aborts.
    pub silence_timeout: Duration,
    /// How long the robot, lingering with a post-processing block in flight, waits for the
    /// controller's next request: longer than the silence timeout, because that request may
    /// follow the controller's block-time estimate of the plant (seconds for a multilevel
    /// block of 10⁴ bits). Without a block in flight the robot waits the quiet time.
    pub block_timeout: Duration,
}

impl Timing {
    /// Default silence timeout: 2 s.
    pub const DEFAULT_SILENCE: Duration = Duration::from_secs(2);

    /// Default block timeout: 30 s, about six times the longest multilevel block-time
    /// estimate measured on a loaded 2-core machine (5 s, 10⁴-bit blocks, 4 levels).
    pub const DEFAULT_BLOCK: Duration = Duration::from_secs(30);

    /// The defaults for a pace: deadline `T/2`, lockstep timeout 50 ms, silence `silence`,
    /// block timeout [`Self::DEFAULT_BLOCK`].
    #[must_use]
    pub fn new(pace: Pace, silence_timeout: Duration) -> Self {
        Self {
            pace,
            step_timeout: Duration::from_millis(50),
            deadline_fraction: 0.5,
            silence_timeout,
            block_timeout: Self::DEFAULT_BLOCK,
        }
    }

    /// Interval between retransmissions (Hello, Ready, Finish, Confirm, post-processing, the
    /// robot's last report) and between courtesy replies: 30 ms lockstep, 100 ms realtime.
    #[must_use]
    pub fn retransmit_interval(&self) -> Duration {
        match self.pace {
            Pace::Lockstep => Duration::from_millis(30),
            Pace::Realtime => Duration::from_millis(100),
        }
    }

    /// How long a side that needs nothing more waits for the peer's `Done` while nothing
    /// arrives that it must answer: ten retransmission intervals.
    #[must_use]
    pub fn linger_quiet(&self) -> Duration {
        self.retransmit_interval() * 10
    }
}

impl Default for Timing {
    /// Realtime, with the default silence timeout.
    fn default() -> Self {
        Self::new(Pace::Realtime, Self::DEFAULT_SILENCE)
    }
}

/// The earliest of two optional deadlines.
#[must_use]
pub fn earliest(a: Option<Time>, b: Option<Time>) -> Option<Time> {
    match (a, b) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_adds_and_measures() {
        let t = Time::ZERO + Duration::from_millis(250);
        assert_eq!(t.since_epoch(), Duration::from_millis(250));
        assert_eq!(t.saturating_since(Time::ZERO), Duration::from_millis(250));
        assert_eq!(Time::ZERO.saturating_since(t), Duration::ZERO);
        assert_eq!(earliest(Some(t), None), Some(t));
        assert_eq!(earliest(Some(t), Some(Time::ZERO)), Some(Time::ZERO));
        assert_eq!(earliest(None, None), None);
    }
}
