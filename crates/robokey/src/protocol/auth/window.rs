//! The anti-replay sliding window of DTLS (RFC 6347 §4.1.2.6) and IPsec (RFC 4303 §3.4.3):
//! the highest sequence number accepted, and a 64-bit bitmap of the 64 numbers below it.

use super::Rejection;

/// Width of the window (sequence numbers).
pub const WINDOW: u32 = 64;

/// How an accepted sequence number relates to the ones before it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Freshness {
    /// Above every number accepted so far.
    InOrder,
    /// Below the highest accepted number, within the window and not seen: benign
    /// reordering.
    Reordered,
}

/// One direction's replay window. Check with [`Self::check`] before spending a MAC, and
/// [`Self::accept`] only after the frame verified.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReplayWindow {
    /// Highest accepted sequence number, if any.
    highest: Option<u32>,
    /// Bit i = `highest − i` accepted (bit 0 is `highest` itself).
    seen: u64,
}

impl ReplayWindow {
    /// Whether `seq` would be fresh.
    ///
    /// # Errors
    /// [`Rejection::Replayed`] (already accepted) or [`Rejection::BehindWindow`] (64 or more
    /// below the highest accepted number).
    pub fn check(&self, seq: u32) -> Result<Freshness, Rejection> {
        let Some(highest) = self.highest else {
            return Ok(Freshness::InOrder);
        };
        if seq > highest {
            return Ok(Freshness::InOrder);
        }
        let behind = highest - seq;
        if behind >= WINDOW {
            Err(Rejection::BehindWindow)
        } else if self.seen >> behind & 1 == 1 {
            Err(Rejection::Replayed)
        } else {
            Ok(Freshness::Reordered)
        }
    }

    /// Records `seq` as accepted (after [`Self::check`] and the MAC passed).
    pub fn accept(&mut self, seq: u32) {
        match self.highest {
            Some(highest) if seq <= highest => {
                let behind = highest - seq;
                if behind < WINDOW {
                    self.seen |= 1 << behind;
                }
            }
            Some(highest) => {
                let shift = seq - highest;
                self.seen = if shift >= WINDOW {
                    0
                } else {
                    self.seen << shift
                };
                self.seen |= 1;
                self.highest = Some(seq);
            }
            None => {
                self.seen = 1;
                self.highest = Some(seq);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn in_order_reordered_replayed_and_behind() {
        let mut w = ReplayWindow::default();
        for seq in [1, 2, 5] {
            assert_eq!(w.check(seq), Ok(Freshness::InOrder));
            w.accept(seq);
        }
        assert_eq!(w.check(4), Ok(Freshness::Reordered));
        w.accept(4);
        assert_eq!(w.check(4), Err(Rejection::Replayed));
        assert_eq!(w.check(5), Err(Rejection::Replayed));
        assert_eq!(w.check(3), Ok(Freshness::Reordered));
        w.accept(100);
        assert_eq!(w.check(36), Err(Rejection::BehindWindow));
        assert_eq!(w.check(37), Ok(Freshness::Reordered));
        assert_eq!(w.check(5), Err(Rejection::BehindWindow));
    }

    proptest! {
        /// Against a set of everything accepted: a number is accepted at most once, and
        /// every number within 64 of the highest that was never accepted is still fresh.
        #[test]
        fn matches_a_reference_set(seqs in proptest::collection::vec(0u32..300, 1..200)) {
            let mut w = ReplayWindow::default();
            let mut accepted = std::collections::BTreeSet::new();
            for seq in seqs {
                let highest = accepted.iter().next_back().copied();
                let expected = match highest {
                    None => Ok(Freshness::InOrder),
                    Some(h) if seq > h => Ok(Freshness::InOrder),
                    Some(h) if h - seq >= WINDOW => Err(Rejection::BehindWindow),
                    Some(_) if accepted.contains(&seq) => Err(Rejection::Replayed),
                    Some(_) => Ok(Freshness::Reordered),
                };
                prop_assert_eq!(w.check(seq), expected);
                if expected.is_ok() {
                    w.accept(seq);
                    accepted.insert(seq);
                }
            }
        }
    }
}
