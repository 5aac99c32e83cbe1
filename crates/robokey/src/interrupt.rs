//! A request to stop, set asynchronously (by a signal handler in the shells) and polled by
//! long-running loops: sweeps between runs, agents between frames.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

/// A shared stop request carrying the number of the signal that made it (0: none yet).
///
/// Clones share one flag. The shells register it with the operating system; the core only
/// reads it.
#[derive(Clone, Debug, Default)]
pub struct Interrupt(Arc<AtomicUsize>);

impl Interrupt {
    /// A request that nothing has made yet.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// The flag a signal handler stores its signal number into.
    #[must_use]
    pub fn flag(&self) -> Arc<AtomicUsize> {
        Arc::clone(&self.0)
    }

    /// Requests a stop, as signal `signal` would (tests; 2 is SIGINT).
    pub fn request(&self, signal: usize) {
        self.0.store(signal, Ordering::SeqCst);
    }

    /// The signal that requested a stop, if any.
    #[must_use]
    pub fn signal(&self) -> Option<usize> {
        match self.0.load(Ordering::SeqCst) {
            0 => None,
            signal => Some(signal),
        }
    }

    /// Whether a stop was requested.
    #[must_use]
    pub fn is_requested(&self) -> bool {
        self.signal().is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clones_share_the_request() {
        let interrupt = Interrupt::new();
        let seen_by_a_loop = interrupt.clone();
        assert!(!seen_by_a_loop.is_requested());
        interrupt.request(15);
        assert_eq!(seen_by_a_loop.signal(), Some(15));
    }
}
