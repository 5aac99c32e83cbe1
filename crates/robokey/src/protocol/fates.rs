//! Codeword fates (accept/reject acks) and their reliable delivery (docs/protocol.md).

/// Fates of up to 64 consecutive codewords starting at `first`, carried by a command.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FateWindow {
    /// Index of the first codeword covered (the robot's fate cursor as last echoed).
    pub first: u32,
    /// Number of codewords covered (≤ 64).
    pub count: u8,
    /// Bit j = codeword `first + j` accepted.
    pub accepted: u64,
}

impl FateWindow {
    /// Largest number of fates one window carries.
    pub const CAPACITY: u32 = 64;

    /// The fates it carries, as `(codeword index, accepted)`; indices past `u32::MAX`
    /// (a window from a peer that starts near the end of the range) are left out.
    pub fn iter(&self) -> impl Iterator<Item = (u32, bool)> + '_ {
        (0..u32::from(self.count.min(64)))
            .map_while(|j| Some((self.first.checked_add(j)?, self.accepted >> j & 1 == 1)))
    }
}

/// Known fates of a session's codewords, with the contiguous cursor.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FateLedger {
    fates: Vec<Option<bool>>,
    cursor: u32,
}

impl FateLedger {
    /// A ledger for `codewords` codewords, all unknown.
    #[must_use]
    pub fn new(codewords: u32) -> Self {
        Self {
            fates: vec![None; codewords as usize],
            cursor: 0,
        }
    }

    /// Records a fate the first time it is learned (later reports are ignored); indices
    /// beyond the session are ignored.
    pub fn record(&mut self, index: u32, accepted: bool) {
        if let Some(slot) = self.fates.get_mut(index as usize) {
            slot.get_or_insert(accepted);
        }
        while self
            .fates
            .get(self.cursor as usize)
            .is_some_and(Option::is_some)
        {
            self.cursor += 1;
        }
    }

    /// First codeword whose fate is unknown.
    #[must_use]
    pub fn cursor(&self) -> u32 {
        self.cursor
    }

    /// The fate of codeword `index`, if known.
    #[must_use]
    pub fn get(&self, index: u32) -> Option<bool> {
        self.fates.get(index as usize).copied().flatten()
    }

    /// Number of codewords in the session.
    #[must_use]
    pub fn len(&self) -> u32 {
        self.fates.len() as u32
    }

    /// Whether the session has no codewords.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.fates.is_empty()
    }

    /// Whether every fate is known.
    #[must_use]
    pub fn is_complete(&self) -> bool {
        self.cursor == self.len()
    }

    /// The window of fates from `first` that a command carries (at most 64, stopping at
    /// the first unknown fate).
    #[must_use]
    pub fn window(&self, first: u32) -> FateWindow {
        let mut window = FateWindow {
            first,
            ..FateWindow::default()
        };
        for j in 0..FateWindow::CAPACITY {
            match first.checked_add(j).and_then(|index| self.get(index)) {
                Some(accepted) => {
                    window.accepted |= u64::from(accepted) << j;
                    window.count += 1;
                }
                None => break,
            }
        }
        window
    }

    /// The key of a session: the lowest `k` bits (LSB first) of `messages[i]` for every
    /// accepted codeword i, in order. `messages` holds one message per codeword.
    #[must_use]
    pub fn accepted_key(&self, messages: &[u64], k: usize) -> super::KeyBits {
        let mut key = super::KeyBits::default();
        for (index, message) in messages.iter().enumerate().take(self.fates.len()) {
            if self.fates[index] == Some(true) {
                key.extend((0..k).map(|j| (message >> j & 1) as u8));
            }
        }
        key
    }

    /// The complete bitmap (unknown fates count as rejected).
    #[must_use]
    pub fn bitmap(&self) -> Vec<u64> {
        let mut words = vec![0u64; self.fates.len().div_ceil(64)];
        for (i, fate) in self.fates.iter().enumerate() {
            if *fate == Some(true) {
                words[i / 64] |= 1 << (i % 64);
            }
        }
        words
    }
}

/// Whether bit `index` of a `Finish` bitmap is set (bit `i % 64` of word `i / 64`).
pub(crate) fn bitmap_bit(bitmap: &[u64], index: u32) -> bool {
    bitmap
        .get(index as usize / 64)
        .is_some_and(|w| w >> (index % 64) & 1 == 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_round_trip_and_cursor_is_contiguous() {
        let mut ledger = FateLedger::new(70);
        ledger.record(1, true);
        assert_eq!(ledger.cursor(), 0);
        ledger.record(0, false);
        ledger.record(1, false); // ignored: first report wins
        assert_eq!(ledger.cursor(), 2);
        for i in 2..70 {
            ledger.record(i, i % 3 == 0);
        }
        let window = ledger.window(2);
        assert_eq!(window.count, 64);
        let mut copy = FateLedger::new(70);
        copy.record(0, false);
        copy.record(1, true);
        for (i, accepted) in window.iter().chain(ledger.window(66).iter()) {
            copy.record(i, accepted);
        }
        assert!(copy.is_complete());
        assert_eq!(copy.get(1), Some(true));
        assert_eq!(copy.bitmap()[0] >> 2, ledger.bitmap()[0] >> 2);
        assert_eq!(copy.bitmap()[1], ledger.bitmap()[1]);
    }

    /// Found by the `robot_endpoint` fuzz target: `first + j` overflowed (a panic in debug
    /// builds) for a command's window that starts near `u32::MAX`.
    #[test]
    fn windows_at_the_end_of_the_index_range_do_not_overflow() {
        let window = FateWindow {
            first: u32::MAX - 3,
            count: 64,
            accepted: u64::MAX,
        };
        let indices: Vec<u32> = window.iter().map(|(i, _)| i).collect();
        assert_eq!(
            indices,
            [u32::MAX - 3, u32::MAX - 2, u32::MAX - 1, u32::MAX]
        );
        let mut ledger = FateLedger::new(3);
        for (index, accepted) in window.iter() {
            ledger.record(index, accepted);
        }
        assert_eq!(ledger.cursor(), 0);
        assert_eq!(ledger.window(u32::MAX).count, 0);
    }
}
