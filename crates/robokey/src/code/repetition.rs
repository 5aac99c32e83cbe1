//! The repetition code: one message bit sent `n` times.

use super::{BlockCode, Decoded, low_mask};

/// Repetition code `(n, 1)`, `1 ≤ n ≤ 64`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Repetition {
    n: usize,
}

impl Repetition {
    /// A repetition code of length `n`; `None` unless `1 ≤ n ≤ 64`.
    #[must_use]
    pub fn new(n: usize) -> Option<Self> {
        (1..=64).contains(&n).then_some(Self { n })
    }
}

impl BlockCode for Repetition {
    fn n(&self) -> usize {
        self.n
    }

    fn k(&self) -> usize {
        1
    }

    fn encode(&self, message: u64) -> u64 {
        if message & 1 == 1 {
            low_mask(self.n)
        } else {
            0
        }
    }

    fn decode(&self, word: u64) -> Decoded {
        let ones = (word & low_mask(self.n)).count_ones();
        let zeros = self.n as u32 - ones;
        // Ties (even n) go to the lowest message index, 0.
        if ones > zeros {
            Decoded {
                message: 1,
                distance: zeros,
            }
        } else {
            Decoded {
                message: 0,
                distance: ones,
            }
        }
    }

    fn name(&self) -> String {
        format!("repetition({})", self.n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ties_go_to_zero_and_lengths_are_checked() {
        let code = Repetition::new(4).unwrap();
        assert_eq!(
            code.decode(0b0011),
            Decoded {
                message: 0,
                distance: 2
            }
        );
        assert!(Repetition::new(0).is_none());
        assert!(Repetition::new(65).is_none());
        assert_eq!(Repetition::new(64).unwrap().encode(1), u64::MAX);
    }
}
