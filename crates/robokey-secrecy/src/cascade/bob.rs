//! Bob's side of Cascade as a state machine without I/O: it emits batches of parity
//! questions ([`CascadeStep::Ask`]) and resumes when Alice's answers come back, so the same
//! code runs against an in-memory oracle and across a network.

use std::collections::VecDeque;

use rand::Rng;
use rand::seq::SliceRandom;
use serde::{Deserialize, Serialize};

use super::{Cascade, ReconcileError, Reconciliation};
use crate::bitstring::BitString;

/// One question: Alice's parity of the shuffled positions `start..end` of permutation
/// number `permutation` (0 is the identity of pass 1; every later pass and every BICONF round
/// draws the next permutation from the shared public generator, in that order).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct BlockQuery {
    /// Permutation number.
    pub permutation: u32,
    /// First shuffled position.
    pub start: u32,
    /// One past the last shuffled position.
    pub end: u32,
}

/// What Bob needs next.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CascadeStep {
    /// Alice's parities of these blocks, in order (one message round trip).
    Ask(Vec<BlockQuery>),
    /// Reconciliation is over.
    Done(Reconciliation),
}

/// A block: shuffled positions start..end of one pass, with Alice's parity once known.
#[derive(Debug)]
struct Block {
    pass: usize,
    start: usize,
    end: usize,
    parent: Option<usize>,
    left: Option<usize>,
    right: Option<usize>,
    correct_parity: Option<bool>,
    asked: bool,
}

/// A pass: its permutation (shuffled index → key index) and Bob's key in shuffled order.
#[derive(Debug)]
struct Pass {
    number: u32,
    permutation: Vec<usize>,
    inverse: Vec<usize>,
    shuffled: BitString,
    block_size: usize,
    top: Vec<usize>,
    cascade_target: bool,
}

/// Where Bob is in the schedule.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Cascade pass `pass` (1-based).
    Cascade(u32),
    /// A BICONF round that started when Bob had flipped `flipped_before` bits; its passes and
    /// blocks are dropped at `checkpoint` when it ends.
    Biconf {
        flipped_before: u32,
        checkpoint: (usize, usize),
    },
    /// Finished.
    Done,
}

/// Bob reconciling his key with Alice's: [`CascadeBob::start`], then
/// [`CascadeBob::answer`] with Alice's parities for each [`CascadeStep::Ask`].
/// `rng` is the public generator both sides share (it draws the permutations only).
pub struct CascadeBob<R> {
    cascade: Cascade,
    rng: R,
    key: BitString,
    passes: Vec<Pass>,
    blocks: Vec<Block>,
    ask_queue: Vec<(usize, bool)>,
    try_queue: VecDeque<(usize, bool)>,
    /// Asked and not yet answered.
    pending: Vec<(usize, bool)>,
    /// Tried once the pending answers are in (a BICONF complement whose parity needs them).
    deferred: Vec<(usize, bool)>,
    phase: Phase,
    permutations: u32,
    rounds: u32,
    streak: u32,
    /// Questions Alice answered.
    answered: u64,
    messages: u32,
    flipped: u32,
}

impl<R> std::fmt::Debug for CascadeBob<R> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CascadeBob")
            .field("n", &self.key.len())
            .field("phase", &self.phase)
            .field("answered", &self.answered)
            .finish_non_exhaustive()
    }
}

impl<R: Rng> CascadeBob<R> {
    /// Starts reconciling `key` (Bob's) under `cascade`; returns Bob and his first questions.
    ///
    /// # Errors
    /// [`ReconcileError::EmptyKey`].
    pub fn start(
        cascade: Cascade,
        key: BitString,
        rng: R,
    ) -> Result<(Self, CascadeStep), ReconcileError> {
        if key.is_empty() {
            return Err(ReconcileError::EmptyKey);
        }
        let mut bob = Self {
            cascade,
            rng,
            key,
            passes: Vec::new(),
            blocks: Vec::new(),
            ask_queue: Vec::new(),
            try_queue: VecDeque::new(),
            pending: Vec::new(),
            deferred: Vec::new(),
            phase: Phase::Cascade(1),
            permutations: 0,
            rounds: 0,
            streak: 0,
            answered: 0,
            messages: 0,
            flipped: 0,
        };
        bob.start_cascade_pass(1);
        let step = bob.run()?;
        Ok((bob, step))
    }

    /// Alice's parities for the last [`CascadeStep::Ask`], in its order.
    ///
    /// # Errors
    /// [`ReconcileError::OracleInconsistent`] when nothing was asked, the count differs, or
    /// the answers cannot come from one key.
    pub fn answer(&mut self, parities: &[bool]) -> Result<CascadeStep, ReconcileError> {
        if self.pending.is_empty() || parities.len() != self.pending.len() {
            return Err(ReconcileError::OracleInconsistent);
        }
        self.answered += parities.len() as u64;
        for (&(block, right), &parity) in self.pending.iter().zip(parities) {
            self.blocks[block].correct_parity = Some(parity);
            self.try_queue.push_back((block, right));
        }
        self.pending.clear();
        self.try_queue.extend(self.deferred.drain(..));
        self.run()
    }

    /// The key positions of a question (the permutation's slice), for in-memory oracles.
    #[must_use]
    pub fn positions(&self, query: &BlockQuery) -> Option<&[usize]> {
        let pass = self.passes.iter().find(|p| p.number == query.permutation)?;
        pass.permutation
            .get(query.start as usize..query.end as usize)
    }

    /// Works until Alice must answer or reconciliation is over.
    fn run(&mut self) -> Result<CascadeStep, ReconcileError> {
        loop {
            let cascade = matches!(self.phase, Phase::Cascade(_));
            while let Some((block, right)) = self.try_queue.pop_front() {
                self.try_correct(block, right, cascade)?;
            }
            if !self.ask_queue.is_empty() {
                self.pending = std::mem::take(&mut self.ask_queue);
                self.messages += 1;
                let queries = self
                    .pending
                    .iter()
                    .map(|&(b, _)| {
                        let blk = &self.blocks[b];
                        BlockQuery {
                            permutation: self.passes[blk.pass].number,
                            start: blk.start as u32,
                            end: blk.end as u32,
                        }
                    })
                    .collect();
                return Ok(CascadeStep::Ask(queries));
            }
            if !self.advance()? {
                return Ok(CascadeStep::Done(self.outcome()));
            }
        }
    }

    /// Moves to the next pass or BICONF round; false when the schedule is over.
    fn advance(&mut self) -> Result<bool, ReconcileError> {
        let schedule = self.cascade.schedule();
        match self.phase {
            Phase::Cascade(pass) if pass < schedule.passes => {
                self.phase = Phase::Cascade(pass + 1);
                self.start_cascade_pass(pass + 1);
                return Ok(true);
            }
            Phase::Cascade(_) => {}
            Phase::Biconf {
                flipped_before,
                checkpoint,
            } => {
                // Without cascading, the round created blocks only in its own pass.
                self.restore(checkpoint);
                self.streak = if self.flipped > flipped_before {
                    0
                } else {
                    self.streak + 1
                };
            }
            Phase::Done => return Ok(false),
        }
        let streak = schedule.biconf_streak_for(self.key.len());
        if self.streak >= streak {
            self.phase = Phase::Done;
            return Ok(false);
        }
        // Each round that corrects flips a wrong bit: an honest Alice needs at most
        // (n + 1)·streak rounds.
        let n = self.key.len() as u64;
        if u64::from(self.rounds) >= (n + 1).saturating_mul(u64::from(streak)) {
            return Err(ReconcileError::OracleInconsistent);
        }
        self.rounds += 1;
        self.phase = Phase::Biconf {
            flipped_before: self.flipped,
            checkpoint: self.checkpoint(),
        };
        self.start_biconf_round(
            schedule.biconf_complement,
            self.cascade.cascade_cpp_counting,
        );
        Ok(true)
    }

    fn outcome(&self) -> Reconciliation {
        Reconciliation {
            corrected: self.key.clone(),
            leak: 2 * self.answered,
            alice_parities: self.answered,
            cascade_passes: self.cascade.schedule().passes,
            biconf_rounds: self.rounds,
            messages: self.messages,
            flipped: self.flipped,
        }
    }

    /// The next permutation of the shared sequence (identity first).
    fn next_permutation(&mut self) -> (u32, Vec<usize>) {
        let mut perm: Vec<usize> = (0..self.key.len()).collect();
        if self.permutations > 0 {
            perm.shuffle(&mut self.rng);
        }
        self.permutations += 1;
        (self.permutations - 1, perm)
    }

    /// Adds a pass over the next permutation with Bob's bits in shuffled order; returns its
    /// index.
    fn add_pass(&mut self, block_size: usize, cascade_target: bool) -> usize {
        let (number, permutation) = self.next_permutation();
        let n = permutation.len();
        let mut inverse = vec![0; n];
        let mut shuffled = BitString::zeros(n);
        for (s, &k) in permutation.iter().enumerate() {
            inverse[k] = s;
            if self.key.get(k) == Some(true) {
                let _ = shuffled.flip(s);
            }
        }
        self.passes.push(Pass {
            number,
            permutation,
            inverse,
            shuffled,
            block_size,
            top: Vec::new(),
            cascade_target,
        });
        self.passes.len() - 1
    }

    /// Cascade pass `number`: top blocks of its block size (the last shorter), parities
    /// queued.
    fn start_cascade_pass(&mut self, number: u32) {
        let n = self.key.len();
        let block_size = self.cascade.block_size(number, n);
        let pass = self.add_pass(block_size, true);
        let mut start = 0;
        while start < n {
            let end = start.saturating_add(block_size).min(n);
            let id = self.new_block(pass, start, end, None);
            self.passes[pass].top.push(id);
            self.queue_ask(id, false);
            start = end;
        }
    }

    /// A BICONF round: the parity of the first ⌊n/2⌋ shuffled bits is asked; with
    /// `complement`, the rest is searched too, its parity inferred as whole-key parity ⊕ the
    /// half's once that is answered (or asked, with `ask_complement`).
    fn start_biconf_round(&mut self, complement: bool, ask_complement: bool) {
        let n = self.key.len();
        let half = (n / 2).max(1);
        let pass = self.add_pass(half, false);
        let whole_parity = self.whole_key_parity();
        if !complement || half == n {
            let chosen = self.new_block(pass, 0, half, None);
            self.queue_ask(chosen, false);
            return;
        }
        let whole = self.new_block(pass, 0, n, None);
        let chosen = self.child(whole, true);
        let rest = self.child(whole, false);
        self.queue_ask(chosen, false);
        match whole_parity {
            Some(p) if !ask_complement => {
                self.blocks[whole].correct_parity = Some(p);
                self.deferred.push((rest, false));
            }
            _ => self.queue_ask(rest, false),
        }
    }

    /// Alice's whole-key parity: the XOR of her pass-1 top-block parities, once known.
    fn whole_key_parity(&self) -> Option<bool> {
        let first = self.passes.first()?;
        first
            .top
            .iter()
            .try_fold(false, |acc, &b| Some(acc ^ self.blocks[b].correct_parity?))
    }

    fn new_block(&mut self, pass: usize, start: usize, end: usize, parent: Option<usize>) -> usize {
        self.blocks.push(Block {
            pass,
            start,
            end,
            parent,
            left: None,
            right: None,
            correct_parity: None,
            asked: false,
        });
        self.blocks.len() - 1
    }

    fn checkpoint(&self) -> (usize, usize) {
        (self.passes.len(), self.blocks.len())
    }

    /// Drops the passes and blocks created after `checkpoint` (a finished BICONF round).
    fn restore(&mut self, (passes, blocks): (usize, usize)) {
        self.passes.truncate(passes);
        self.blocks.truncate(blocks);
    }

    fn queue_ask(&mut self, block: usize, correct_right_sibling: bool) {
        // cascade-cpp's counting repeats a question that is still pending.
        if self.cascade.cascade_cpp_counting || !self.blocks[block].asked {
            self.blocks[block].asked = true;
            self.ask_queue.push((block, correct_right_sibling));
        }
    }

    fn current_parity(&self, block: usize) -> bool {
        let b = &self.blocks[block];
        self.passes[b.pass]
            .shuffled
            .range_parity(b.start, b.end)
            .unwrap_or(false)
    }

    /// Alice's parity of `block` if known or inferable as parent ⊕ sibling.
    fn correct_parity(&mut self, block: usize) -> Option<bool> {
        if let Some(p) = self.blocks[block].correct_parity {
            return Some(p);
        }
        let parent = self.blocks[block].parent?;
        let (l, r) = (self.blocks[parent].left?, self.blocks[parent].right?);
        let sibling = if l == block { r } else { l };
        let inferred = self.blocks[parent].correct_parity? ^ self.blocks[sibling].correct_parity?;
        self.blocks[block].correct_parity = Some(inferred);
        Some(inferred)
    }

    /// Binary search for one error in `block` (or, if it has even error parity and
    /// `correct_right_sibling`, in its right sibling). Returns bits flipped (0 or 1).
    fn try_correct(
        &mut self,
        mut block: usize,
        mut correct_right_sibling: bool,
        cascade: bool,
    ) -> Result<u32, ReconcileError> {
        loop {
            let Some(correct) = self.correct_parity(block) else {
                self.queue_ask(block, correct_right_sibling);
                return Ok(0);
            };
            if self.current_parity(block) == correct {
                if !correct_right_sibling {
                    return Ok(0);
                }
                let Some(parent) = self.blocks[block].parent else {
                    return Ok(0);
                };
                block = self.child(parent, false);
                correct_right_sibling = false;
                continue;
            }
            let b = &self.blocks[block];
            if b.end - b.start == 1 {
                let (pass, position) = (b.pass, b.start);
                let key_index = self.passes[pass].permutation[position];
                self.flip(key_index, pass, cascade)?;
                return Ok(1);
            }
            block = self.child(block, true);
            correct_right_sibling = true;
        }
    }

    /// Left (⌊size/2⌋ bits) or right sub-block of `parent`, created on first use.
    fn child(&mut self, parent: usize, left: bool) -> usize {
        let p = &self.blocks[parent];
        if let Some(c) = if left { p.left } else { p.right } {
            return c;
        }
        let (pass, start, end) = (p.pass, p.start, p.end);
        let mid = start + (end - start) / 2;
        let (s, e) = if left { (start, mid) } else { (mid, end) };
        let id = self.new_block(pass, s, e, Some(parent));
        if left {
            self.blocks[parent].left = Some(id);
        } else {
            self.blocks[parent].right = Some(id);
        }
        id
    }

    /// Flips key bit `key_index` everywhere; with `cascade`, queues the top-level block that
    /// contains it in every other Cascade pass.
    fn flip(
        &mut self,
        key_index: usize,
        from_pass: usize,
        cascade: bool,
    ) -> Result<(), ReconcileError> {
        self.flipped += 1;
        if self.flipped as usize > self.key.len() {
            return Err(ReconcileError::OracleInconsistent);
        }
        let _ = self.key.flip(key_index);
        for (q, pass) in self.passes.iter_mut().enumerate() {
            let s = pass.inverse[key_index];
            let _ = pass.shuffled.flip(s);
            if cascade && q != from_pass && pass.cascade_target {
                self.try_queue
                    .push_back((pass.top[s / pass.block_size], false));
            }
        }
        Ok(())
    }
}
