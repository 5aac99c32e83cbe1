//! Alice's side of Cascade: answers Bob's [`BlockQuery`]s from her key and the public
//! permutations, which she draws from the same generator in the same order as Bob.

use rand::Rng;
use rand::seq::SliceRandom;

use super::{BlockQuery, CascadeSchedule, ReconcileError};
use crate::bitstring::BitString;

/// Alice answering Cascade questions over a network. Keeps the permutations of the Cascade
/// passes (later passes cascade back into them) and of the latest BICONF round only.
pub struct CascadeAlice<R> {
    key: BitString,
    rng: R,
    cascade_passes: u32,
    /// Permutation k for k < `cascade_passes`.
    kept: Vec<Vec<usize>>,
    /// The latest BICONF permutation and its number.
    latest: Option<(u32, Vec<usize>)>,
    /// Permutations drawn so far.
    drawn: u32,
    revealed: u64,
}

impl<R> std::fmt::Debug for CascadeAlice<R> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CascadeAlice")
            .field("n", &self.key.len())
            .field("drawn", &self.drawn)
            .field("revealed", &self.revealed)
            .finish_non_exhaustive()
    }
}

impl<R: Rng> CascadeAlice<R> {
    /// Alice with `key` under `schedule`; `rng` is the public generator Bob also holds.
    #[must_use]
    pub fn new(key: BitString, schedule: CascadeSchedule, rng: R) -> Self {
        Self {
            key,
            rng,
            cascade_passes: schedule.passes,
            kept: Vec::new(),
            latest: None,
            drawn: 0,
            revealed: 0,
        }
    }

    /// Parities revealed so far.
    #[must_use]
    pub fn revealed(&self) -> u64 {
        self.revealed
    }

    /// Her parities of `queries`, in order. A question may name any kept permutation or the
    /// next one to draw (Bob never skips one), so an answer costs at most one new
    /// permutation: a peer cannot make her draw a million. The blocks of one round span at
    /// most (passes + 2)·n positions (an honest round asks one pass's top blocks and halves
    /// of blocks in the others), so a round costs her O(n).
    ///
    /// # Errors
    /// [`ReconcileError::OracleInconsistent`] for a permutation she dropped or that lies
    /// ahead, a range outside the key, or a round spanning more than (passes + 2)·n.
    pub fn answer(&mut self, queries: &[BlockQuery]) -> Result<Vec<bool>, ReconcileError> {
        let n = self.key.len();
        let span: u64 = queries
            .iter()
            .map(|q| u64::from(q.end.saturating_sub(q.start)))
            .sum();
        if span > (u64::from(self.cascade_passes) + 2) * n as u64 {
            return Err(ReconcileError::OracleInconsistent);
        }
        queries
            .iter()
            .map(|q| {
                let (start, end) = (q.start as usize, q.end as usize);
                if start >= end || end > n {
                    return Err(ReconcileError::OracleInconsistent);
                }
                if q.permutation == self.drawn {
                    self.draw();
                }
                let permutation = self
                    .permutation(q.permutation)
                    .ok_or(ReconcileError::OracleInconsistent)?;
                let parity = permutation[start..end]
                    .iter()
                    .fold(false, |acc, &i| acc ^ (self.key.get(i) == Some(true)));
                self.revealed += 1;
                Ok(parity)
            })
            .collect()
    }

    fn permutation(&self, number: u32) -> Option<&[usize]> {
        if number < self.cascade_passes {
            return self.kept.get(number as usize).map(Vec::as_slice);
        }
        match &self.latest {
            Some((latest, perm)) if *latest == number => Some(perm),
            _ => None,
        }
    }

    /// Draws the next permutation (the identity first), as Bob does.
    fn draw(&mut self) {
        let mut perm: Vec<usize> = (0..self.key.len()).collect();
        if self.drawn > 0 {
            perm.shuffle(&mut self.rng);
        }
        if self.drawn < self.cascade_passes {
            self.kept.push(perm);
        } else {
            self.latest = Some((self.drawn, perm));
        }
        self.drawn += 1;
    }
}
