//! Information reconciliation by Cascade, with exact leak accounting.
//!
//! Alice holds the reference key, Bob the noisy one. Bob drives the protocol
//! ([`CascadeBob`], a state machine without I/O) and learns Alice's parities only by asking:
//! in memory through a [`ParityOracle`], over a network through [`CascadeAlice`], which
//! answers compact [`BlockQuery`]s from the same public permutations. Parities Bob infers (a
//! sub-block's from its parent's and sibling's, or any parity he has already been told) are
//! not asked again.
//!
//! **Leak.** Every answered question publishes Alice's parity of the set, and Bob's next
//! move publishes whether his own parity of it differs (he searches the block or he does
//! not), hence his parity too: the transcript is a function of those 2 bits per question and
//! the public randomness, so H_min^ε(X | E, transcript) ≥ H_min^ε(X | E) − 2·questions.
//! [`Reconciliation::leak`] charges both sides; [`Reconciliation::alice_parities`] alone is
//! the convention of the efficiency literature. Parities inferred from earlier ones (the
//! right half of a searched block, a block re-checked after a cascaded flip, the BICONF
//! complement) are functions of bits already charged and cost nothing more.
//!
//! Conventions follow brunorijsman/cascade-cpp (which reproduces Martinez-Mateo et al.,
//! "Demystifying the Information Reconciliation Protocol Cascade", arXiv 1407.3257):
//! pass 1 is unshuffled, later passes use fresh random permutations; blocks are consecutive
//! runs of the (shuffled) key with a shorter last block; a binary search asks the left half
//! (⌊size/2⌋ bits) and infers the right; sub-block parities learnt in earlier searches are
//! reused; a corrected bit cascades into the top-level block containing it in every other
//! Cascade pass; Bob batches all pending questions into one message. A BICONF round asks the
//! parity of a random half (⌊n/2⌋ bits), infers its complement's from the whole-key parity
//! (known since pass 1), and binary-searches whichever disagrees, without cascading.
//!
//! Two differences from cascade-cpp's counting, both of which only remove parities Bob
//! already knows: a question still pending is not asked a second time (cascade-cpp repeats
//! it when a block is queued twice), and the BICONF complement's parity is inferred, not
//! asked. With cascade-cpp's counting restored (a test-only switch) this implementation
//! reproduces the published efficiency table (docs/secrecy.md) within ±3 standard errors.

mod alice;
mod bob;

use rand::Rng;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::bitstring::BitString;
pub use alice::CascadeAlice;
pub use bob::{BlockQuery, CascadeBob, CascadeStep};

/// Errors of reconciliation.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ReconcileError {
    /// Alice's and Bob's keys differ in length.
    #[error("key lengths differ: Alice {alice}, Bob {bob}")]
    LengthMismatch {
        /// Alice's key length.
        alice: usize,
        /// Bob's key length.
        bob: usize,
    },
    /// The key is empty.
    #[error("the key is empty")]
    EmptyKey,
    /// The estimated error rate is outside [0, ½] or NaN.
    #[error("estimated error rate {0} must lie in [0, 0.5]")]
    InvalidErrorRate(f64),
    /// The schedule has no Cascade pass, a zero first-block factor or growth.
    #[error("invalid Cascade schedule: {0}")]
    InvalidSchedule(&'static str),
    /// The parity oracle gave a wrong number of answers, refused, or its answers cannot come
    /// from one key (Bob corrected more bits than the key has).
    #[error("the parity oracle's answers are inconsistent")]
    OracleInconsistent,
}

/// Alice's side of reconciliation: answers Bob's parity questions.
pub trait ParityOracle {
    /// Alice's parity of the key bits at each position set, in order (one message round
    /// trip); `None` if she cannot answer (e.g. a position out of range).
    fn parities(&mut self, queries: &[&[usize]]) -> Option<Vec<bool>>;
}

/// In-memory Alice: answers from her key and counts the parities she revealed.
#[derive(Debug)]
pub struct KeyParities<'a> {
    key: &'a BitString,
    revealed: u64,
}

impl<'a> KeyParities<'a> {
    /// Alice answering from `key`.
    #[must_use]
    pub fn new(key: &'a BitString) -> Self {
        Self { key, revealed: 0 }
    }

    /// Number of parities revealed so far.
    #[must_use]
    pub fn revealed(&self) -> u64 {
        self.revealed
    }
}

impl ParityOracle for KeyParities<'_> {
    fn parities(&mut self, queries: &[&[usize]]) -> Option<Vec<bool>> {
        let answers = queries
            .iter()
            .map(|q| self.key.parity_of(q))
            .collect::<Option<Vec<_>>>()?;
        self.revealed += answers.len() as u64;
        Some(answers)
    }
}

/// Reconciles Bob's noisy key with Alice's reference key.
pub trait Reconciler {
    /// Bob's corrected key and the exact leak. `rng` supplies the public randomness
    /// (permutations, BICONF subsets).
    fn reconcile<R: Rng + ?Sized>(
        &self,
        alice: &BitString,
        bob: &BitString,
        rng: &mut R,
    ) -> Result<Reconciliation, ReconcileError>;
}

/// Outcome of one reconciliation.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reconciliation {
    /// Bob's key after correction (equal to Alice's unless errors remain undetected).
    pub corrected: BitString,
    /// leak_EC: every public bit that depends on the keys, both sides' parities
    /// (= 2 · [`Self::alice_parities`]).
    pub leak: u64,
    /// Parities Alice revealed (the convention of Cascade's efficiency tables).
    pub alice_parities: u64,
    /// Cascade passes run.
    pub cascade_passes: u32,
    /// BICONF rounds run.
    pub biconf_rounds: u32,
    /// Question messages Bob sent (each answered by one message from Alice).
    pub messages: u32,
    /// Bits Bob flipped.
    pub flipped: u32,
}

/// A Cascade schedule: passes, first block size k1 = ⌈factor/Q⌉, growth per pass, and the
/// BICONF error-free streak that ends it (0 = no BICONF).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CascadeSchedule {
    /// Number of Cascade passes.
    pub passes: u32,
    /// k1 = ⌈first_block_factor / Q⌉.
    pub first_block_factor: f64,
    /// Block size multiplier from one pass to the next.
    pub growth: usize,
    /// BICONF rounds continue until this many in a row find no error (0: none).
    pub biconf_streak: u32,
    /// BICONF also searches the complement of the random half (its parity is inferred from
    /// the whole-key parity, so it costs no extra leak).
    pub biconf_complement: bool,
}

impl CascadeSchedule {
    /// Original Cascade (Brassard–Salvail): 4 passes, k1 = ⌈0.73/Q⌉, doubling.
    pub const ORIGINAL: Self = Self {
        passes: 4,
        first_block_factor: 0.73,
        growth: 2,
        biconf_streak: 0,
        biconf_complement: false,
    };
    /// "biconf" (Demystifying's Cascade mod. (1)): 2 passes, k1 = ⌈0.92/Q⌉, ×3, then BICONF
    /// on a random half and its complement until 10 rounds in a row find no error (more beyond
    /// 2¹⁴ bits: [`CascadeSchedule::biconf_streak_for`]).
    pub const BICONF: Self = Self {
        passes: 2,
        first_block_factor: 0.92,
        growth: 3,
        biconf_streak: 10,
        biconf_complement: true,
    };
}

/// Keys up to this length (bits) end BICONF after the schedule's streak; longer ones need
/// one error-free round more per doubling (see [`CascadeSchedule::biconf_streak_for`]).
pub const BICONF_STREAK_CALIBRATED_BITS: usize = 1 << 14;

impl CascadeSchedule {
    /// BICONF rounds in a row that must find no error before an n-bit key is declared
    /// reconciled: the schedule's streak s, plus ⌈log₂(n / 2¹⁴)⌉ when n > 2¹⁴ (0 without
    /// BICONF).
    ///
    /// Errors left after the Cascade passes come in pairs (the whole-key parity agrees), and
    /// a BICONF round finds a pair with probability ½, so BICONF stops with r errors left with
    /// probability ≈ (r/2)·2⁻ˢ. r grows in proportion to n: the fixed streak of 10, tuned on
    /// 10⁴-bit keys, left a 10⁶-bit key at Q = 4.7 % unreconciled in 1 block of 20; one round
    /// more per doubling of n keeps the chance of stopping early where it was at 2¹⁴ bits.
    #[must_use]
    pub fn biconf_streak_for(&self, n: usize) -> u32 {
        if self.biconf_streak == 0 || n <= BICONF_STREAK_CALIBRATED_BITS {
            return self.biconf_streak;
        }
        let doublings = (n as f64 / BICONF_STREAK_CALIBRATED_BITS as f64)
            .log2()
            .ceil() as u32;
        self.biconf_streak + doublings
    }
}

/// Cascade with a schedule and the estimated error rate Q that sets its block sizes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cascade {
    schedule: CascadeSchedule,
    error_rate: f64,
    /// cascade-cpp's counting: repeat pending questions, ask the BICONF complement.
    cascade_cpp_counting: bool,
}

impl Cascade {
    /// Cascade with `schedule` for estimated error rate `error_rate` ∈ [0, ½].
    pub fn new(schedule: CascadeSchedule, error_rate: f64) -> Result<Self, ReconcileError> {
        if !(0.0..=0.5).contains(&error_rate) {
            return Err(ReconcileError::InvalidErrorRate(error_rate));
        }
        if schedule.passes == 0 {
            return Err(ReconcileError::InvalidSchedule("no Cascade pass"));
        }
        let factor = schedule.first_block_factor;
        if factor.is_nan() || factor <= 0.0 || schedule.growth == 0 {
            return Err(ReconcileError::InvalidSchedule(
                "block sizes must be positive",
            ));
        }
        Ok(Self {
            schedule,
            error_rate,
            cascade_cpp_counting: false,
        })
    }

    /// The same protocol with cascade-cpp's leak counting (pending questions repeated, BICONF
    /// complement asked): over-counts, for validation against its published efficiencies.
    #[cfg(test)]
    fn with_cascade_cpp_counting(self) -> Self {
        Self {
            cascade_cpp_counting: true,
            ..self
        }
    }

    /// Original Cascade for estimated error rate Q.
    pub fn original(error_rate: f64) -> Result<Self, ReconcileError> {
        Self::new(CascadeSchedule::ORIGINAL, error_rate)
    }

    /// Cascade "biconf" for estimated error rate Q.
    pub fn biconf(error_rate: f64) -> Result<Self, ReconcileError> {
        Self::new(CascadeSchedule::BICONF, error_rate)
    }

    /// The schedule.
    #[must_use]
    pub fn schedule(&self) -> CascadeSchedule {
        self.schedule
    }

    /// Top-level block size of pass `pass` (1-based) for an n-bit key:
    /// min(n, ⌈factor/Q⌉·growth^(pass−1)); the whole key when Q = 0 or k1 > n.
    #[must_use]
    pub fn block_size(&self, pass: u32, n: usize) -> usize {
        let k1 = (self.schedule.first_block_factor / self.error_rate).ceil();
        // k1 = ∞ when Q = 0.
        if k1 >= n as f64 {
            return n.max(1);
        }
        let mut k = (k1 as usize).max(1);
        for _ in 1..pass {
            k = k.saturating_mul(self.schedule.growth);
        }
        k.min(n)
    }

    /// Runs Cascade as Bob with key `bob`, asking Alice through `oracle`; `rng` is the
    /// public generator that draws the permutations.
    pub fn reconcile_with<O: ParityOracle + ?Sized, R: Rng + ?Sized>(
        &self,
        oracle: &mut O,
        bob: &BitString,
        rng: &mut R,
    ) -> Result<Reconciliation, ReconcileError> {
        let (mut machine, mut step) = CascadeBob::start(*self, bob.clone(), rng)?;
        loop {
            match step {
                CascadeStep::Done(outcome) => return Ok(outcome),
                CascadeStep::Ask(queries) => {
                    let answers = {
                        let sets = queries
                            .iter()
                            .map(|q| machine.positions(q))
                            .collect::<Option<Vec<_>>>()
                            .ok_or(ReconcileError::OracleInconsistent)?;
                        oracle
                            .parities(&sets)
                            .ok_or(ReconcileError::OracleInconsistent)?
                    };
                    step = machine.answer(&answers)?;
                }
            }
        }
    }
}

impl Reconciler for Cascade {
    fn reconcile<R: Rng + ?Sized>(
        &self,
        alice: &BitString,
        bob: &BitString,
        rng: &mut R,
    ) -> Result<Reconciliation, ReconcileError> {
        if alice.len() != bob.len() {
            return Err(ReconcileError::LengthMismatch {
                alice: alice.len(),
                bob: bob.len(),
            });
        }
        self.reconcile_with(&mut KeyParities::new(alice), bob, rng)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::entropy::binary_entropy;
    use rand::rngs::ChaCha8Rng;
    use rand::{Rng, SeedableRng};

    #[test]
    fn the_biconf_streak_grows_by_one_per_doubling_beyond_the_calibrated_length() {
        let biconf = CascadeSchedule::BICONF;
        assert_eq!(biconf.biconf_streak_for(10_000), 10);
        assert_eq!(biconf.biconf_streak_for(BICONF_STREAK_CALIBRATED_BITS), 10);
        assert_eq!(
            biconf.biconf_streak_for(BICONF_STREAK_CALIBRATED_BITS + 1),
            11
        );
        // 10⁶ / 2¹⁴ ≈ 61: six doublings.
        assert_eq!(biconf.biconf_streak_for(1_000_000), 16);
        assert_eq!(CascadeSchedule::ORIGINAL.biconf_streak_for(1_000_000), 0);
    }

    /// Alice that records every question and answer.
    struct Recording<'a> {
        key: &'a BitString,
        transcript: Vec<(Vec<usize>, bool)>,
    }

    impl ParityOracle for Recording<'_> {
        fn parities(&mut self, queries: &[&[usize]]) -> Option<Vec<bool>> {
            let answers: Vec<bool> = queries
                .iter()
                .map(|q| self.key.parity_of(q))
                .collect::<Option<_>>()?;
            for (q, &a) in queries.iter().zip(&answers) {
                self.transcript.push((q.to_vec(), a));
            }
            Some(answers)
        }
    }

    /// Alice's key and Bob's copy with exactly `errors` flipped positions.
    fn keys(n: usize, errors: usize, rng: &mut ChaCha8Rng) -> (BitString, BitString) {
        let alice = BitString::random(n, rng);
        let mut bob = alice.clone();
        for i in rand::seq::index::sample(rng, n, errors) {
            bob.flip(i).unwrap();
        }
        (alice, bob)
    }

    #[test]
    fn block_sizes_follow_the_schedules() {
        let o = Cascade::original(0.01).unwrap();
        assert_eq!(
            (1..=4).map(|p| o.block_size(p, 1000)).collect::<Vec<_>>(),
            [73, 146, 292, 584]
        );
        let b = Cascade::biconf(0.02).unwrap();
        assert_eq!((b.block_size(1, 1000), b.block_size(2, 1000)), (46, 138));
        // k1 > n, and Q = 0: one block of the whole key.
        assert_eq!(Cascade::original(0.001).unwrap().block_size(1, 345), 345);
        assert_eq!(Cascade::original(0.0).unwrap().block_size(3, 345), 345);
        assert!(Cascade::original(0.6).is_err());
        assert!(Cascade::original(f64::NAN).is_err());
    }

    #[test]
    fn error_free_keys_leak_one_parity_per_top_block() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let (alice, bob) = keys(1000, 0, &mut rng);
        let r = Cascade::original(0.01)
            .unwrap()
            .reconcile(&alice, &bob, &mut rng)
            .unwrap();
        // ⌈1000/73⌉ + ⌈1000/146⌉ + ⌈1000/292⌉ + ⌈1000/584⌉ = 14 + 7 + 4 + 2.
        assert_eq!((r.alice_parities, r.messages, r.flipped), (27, 4, 0));
        assert_eq!(r.leak, 2 * 27);
        let r = Cascade::biconf(0.01)
            .unwrap()
            .reconcile(&alice, &bob, &mut rng)
            .unwrap();
        // ⌈1000/92⌉ + ⌈1000/276⌉ + 10 BICONF rounds of one parity.
        assert_eq!((r.alice_parities, r.biconf_rounds), (11 + 4 + 10, 10));
        assert_eq!(r.corrected, alice);
    }

    /// Worked by hand. Alice 1011, Bob 1001 (bit 2 wrong), one pass, one block of 4 bits.
    /// Q1: parity of {0,1,2,3}: Alice 1, Bob 0 → they differ, Bob searches (his parity is
    /// public). Q2: left half {0,1}: Alice 1, Bob 1 → equal, so the error is on the right,
    /// whose parities (Alice 0, Bob 1) follow from Q1 and Q2 (not asked, not charged). Q3:
    /// {2}: Alice 1, Bob 0 → Bob flips bit 2 (public). Three questions: Alice revealed 3
    /// parities, Bob 3, leak 6.
    #[test]
    fn leak_of_a_case_worked_by_hand() {
        let alice = BitString::from_bools(&[true, false, true, true]);
        let bob = BitString::from_bools(&[true, false, false, true]);
        let one_pass = CascadeSchedule {
            passes: 1,
            first_block_factor: 1.0,
            growth: 1,
            biconf_streak: 0,
            biconf_complement: false,
        };
        let mut oracle = Recording {
            key: &alice,
            transcript: Vec::new(),
        };
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let r = Cascade::new(one_pass, 0.0)
            .unwrap()
            .reconcile_with(&mut oracle, &bob, &mut rng)
            .unwrap();
        let asked: Vec<(Vec<usize>, bool)> = vec![
            (vec![0, 1, 2, 3], true),
            (vec![0, 1], true),
            (vec![2], true),
        ];
        assert_eq!(oracle.transcript, asked);
        assert_eq!((r.alice_parities, r.leak, r.flipped), (3, 6, 1));
        assert_eq!(r.corrected, alice);
    }

    /// Over a network Alice answers compact questions from her own copy of the public
    /// generator: the outcome is exactly the in-memory one.
    #[test]
    fn alice_over_the_network_answers_as_the_oracle() {
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        for (schedule, n, errors) in [
            (CascadeSchedule::BICONF, 2_000, 40),
            (CascadeSchedule::ORIGINAL, 1_500, 75),
            (CascadeSchedule::BICONF, 700, 0),
        ] {
            let (alice, bob) = keys(n, errors, &mut rng);
            let cascade = Cascade::new(schedule, errors.max(1) as f64 / n as f64).unwrap();
            let seed = rng.next_u64();
            let expected = cascade
                .reconcile(&alice, &bob, &mut ChaCha8Rng::seed_from_u64(seed))
                .unwrap();
            let mut remote =
                CascadeAlice::new(alice.clone(), schedule, ChaCha8Rng::seed_from_u64(seed));
            let (mut machine, mut step) =
                CascadeBob::start(cascade, bob.clone(), ChaCha8Rng::seed_from_u64(seed)).unwrap();
            let outcome = loop {
                match step {
                    CascadeStep::Done(outcome) => break outcome,
                    CascadeStep::Ask(queries) => {
                        step = machine.answer(&remote.answer(&queries).unwrap()).unwrap();
                    }
                }
            };
            assert_eq!(outcome, expected);
            assert_eq!(remote.revealed(), outcome.alice_parities);
            assert_eq!(outcome.corrected, alice);
        }
    }

    #[test]
    fn alice_refuses_questions_no_honest_bob_asks() {
        let key = BitString::zeros(100);
        let schedule = CascadeSchedule::BICONF;
        let mut alice = CascadeAlice::new(key, schedule, ChaCha8Rng::seed_from_u64(1));
        let q = |permutation, start, end| BlockQuery {
            permutation,
            start,
            end,
        };
        // A permutation ahead of the next one, an empty or out-of-range block.
        for bad in [q(1, 0, 10), q(0, 5, 5), q(0, 90, 101)] {
            assert_eq!(
                alice.answer(&[bad]),
                Err(ReconcileError::OracleInconsistent)
            );
        }
        // A round that makes her read the key more than (passes + 2) times.
        assert_eq!(
            alice.answer(&[q(0, 0, 100); 5]),
            Err(ReconcileError::OracleInconsistent)
        );
        // Permutations 0 and 1 (the Cascade passes) stay; BICONF rounds replace each other.
        for p in 0..4 {
            assert!(alice.answer(&[q(p, 0, 50)]).is_ok());
        }
        assert!(alice.answer(&[q(1, 0, 50)]).is_ok());
        assert!(alice.answer(&[q(2, 0, 50)]).is_err());
        // Bob refuses answers he did not ask for.
        let (mut bob, _) = CascadeBob::start(
            Cascade::biconf(0.01).unwrap(),
            BitString::zeros(100),
            ChaCha8Rng::seed_from_u64(1),
        )
        .unwrap();
        assert_eq!(bob.answer(&[]), Err(ReconcileError::OracleInconsistent));
    }

    #[test]
    fn single_errors_are_always_corrected() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let alice = BitString::random(130, &mut rng);
        for i in 0..alice.len() {
            let mut bob = alice.clone();
            bob.flip(i).unwrap();
            let r = Cascade::original(0.02)
                .unwrap()
                .reconcile(&alice, &bob, &mut rng)
                .unwrap();
            assert_eq!(r.corrected, alice, "error at {i}");
            assert_eq!(r.flipped, 1);
        }
    }

    #[test]
    fn leak_counts_both_sides_of_every_question() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for (schedule, q) in [
            (CascadeSchedule::ORIGINAL, 0.05),
            (CascadeSchedule::BICONF, 0.02),
        ] {
            for _ in 0..50 {
                let (alice, bob) = keys(1000, (1000.0 * q) as usize, &mut rng);
                let mut oracle = Recording {
                    key: &alice,
                    transcript: Vec::new(),
                };
                let cascade = Cascade::new(schedule, q).unwrap();
                let r = cascade.reconcile_with(&mut oracle, &bob, &mut rng).unwrap();
                assert_eq!(r.alice_parities, oracle.transcript.len() as u64);
                assert_eq!(r.leak, 2 * r.alice_parities);
                // Every answer is Alice's parity of the asked positions.
                for (q, a) in &oracle.transcript {
                    assert_eq!(alice.parity_of(q), Some(*a));
                }
                // No block is asked twice; the only repeats are single bits asked again in a
                // later pass (the cascade-cpp convention, which counts them: conservative).
                let mut sets: Vec<Vec<usize>> = oracle
                    .transcript
                    .iter()
                    .map(|(q, _)| {
                        let mut s = q.clone();
                        s.sort_unstable();
                        s
                    })
                    .collect();
                sets.sort();
                assert!(sets.windows(2).all(|w| w[0] != w[1] || w[0].len() == 1));
                // The reported key is Bob's key with exactly `flipped` bits changed.
                assert_eq!(
                    r.corrected.hamming_distance(&bob).unwrap(),
                    r.flipped as usize
                );
            }
        }
    }

    /// Frames left wrong over 400 seeded runs stay rare (measured over 4000 runs: BICONF
    /// ≤ 0.15 % at n = 345 and 1000; original ≤ 0.9 % at n = 1000, Q ≥ 2 %). Original Cascade
    /// at n = 345, Q ≤ 2 % is not among them: with 3–7 errors it leaves a hidden pair in
    /// 8–15 % of frames, which only the confirmation tag catches.
    #[test]
    fn small_error_counts_are_corrected_in_most_runs() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let cases = [
            (CascadeSchedule::BICONF, 345, 0.01),
            (CascadeSchedule::BICONF, 345, 0.05),
            (CascadeSchedule::BICONF, 1000, 0.02),
            (CascadeSchedule::ORIGINAL, 1000, 0.02),
            (CascadeSchedule::ORIGINAL, 1000, 0.05),
            (CascadeSchedule::ORIGINAL, 345, 0.10),
        ];
        for (schedule, n, q) in cases {
            let cascade = Cascade::new(schedule, q).unwrap();
            let errors = (n as f64 * q).round() as usize;
            let failures = (0..400)
                .filter(|_| {
                    let (alice, bob) = keys(n, errors, &mut rng);
                    cascade.reconcile(&alice, &bob, &mut rng).unwrap().corrected != alice
                })
                .count();
            assert!(
                failures <= 8,
                "{schedule:?} n={n} Q={q}: {failures}/400 frames wrong"
            );
        }
    }

    #[test]
    fn invalid_input_is_an_error() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let c = Cascade::original(0.05).unwrap();
        assert!(matches!(
            c.reconcile(&BitString::zeros(10), &BitString::zeros(11), &mut rng),
            Err(ReconcileError::LengthMismatch { .. })
        ));
        assert_eq!(
            c.reconcile(&BitString::zeros(0), &BitString::zeros(0), &mut rng),
            Err(ReconcileError::EmptyKey)
        );
        // An oracle that always answers "1" cannot come from one key.
        struct Liar;
        impl ParityOracle for Liar {
            fn parities(&mut self, queries: &[&[usize]]) -> Option<Vec<bool>> {
                Some(vec![true; queries.len()])
            }
        }
        let bob = BitString::zeros(200);
        let out = Cascade::biconf(0.05)
            .unwrap()
            .reconcile_with(&mut Liar, &bob, &mut rng);
        assert_eq!(out, Err(ReconcileError::OracleInconsistent));
    }

    /// Mean efficiency f = leak/(n·h(Q)) over `runs` seeded runs with exactly round(Q·n)
    /// errors, and its standard error (sample standard deviation / √runs).
    fn efficiency(cascade: Cascade, n: usize, q: f64, runs: usize, seed: u64) -> (f64, f64) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let errors = (q * n as f64).round() as usize;
        let norm = n as f64 * binary_entropy(q);
        let fs: Vec<f64> = (0..runs)
            .map(|_| {
                let (alice, bob) = keys(n, errors, &mut rng);
                cascade
                    .reconcile(&alice, &bob, &mut rng)
                    .unwrap()
                    .alice_parities as f64
                    / norm
            })
            .collect();
        let mean = fs.iter().sum::<f64>() / runs as f64;
        let var = fs.iter().map(|f| (f - mean).powi(2)).sum::<f64>() / (runs - 1) as f64;
        (mean, (var / runs as f64).sqrt())
    }

    /// Published reference efficiencies (docs/secrecy.md) (cascade-cpp study data), n = 1000.
    const REFERENCE: [(&str, CascadeSchedule, [f64; 4]); 2] = [
        (
            "original",
            CascadeSchedule::ORIGINAL,
            [1.160, 1.184, 1.195, 1.215],
        ),
        (
            "biconf",
            CascadeSchedule::BICONF,
            [1.385, 1.277, 1.202, 1.185],
        ),
    ];
    const ERROR_RATES: [f64; 4] = [0.01, 0.02, 0.05, 0.10];

    /// With cascade-cpp's counting, f must match the table within ±3 SE; our own counting
    /// (which drops parities Bob already knows) must not leak more. 2 × 2000 seeded runs per
    /// point: ~3.5 s with the workspace's optimised test profile.
    #[test]
    fn efficiency_matches_cascade_reference() {
        let runs = 2000;
        let mut report = String::new();
        let mut failures = Vec::new();
        for (k, (name, schedule, reference)) in REFERENCE.iter().enumerate() {
            for (j, (&q, &f_ref)) in ERROR_RATES.iter().zip(reference).enumerate() {
                let seed = 1000 + (k * 10 + j) as u64;
                let cascade = Cascade::new(*schedule, q).unwrap();
                let (f_cpp, se_cpp) =
                    efficiency(cascade.with_cascade_cpp_counting(), 1000, q, runs, seed);
                let (f_own, se_own) = efficiency(cascade, 1000, q, runs, seed);
                let z = (f_cpp - f_ref) / se_cpp;
                report += &format!(
                    "{name:8} Q={q:4}: cascade-cpp counting f = {f_cpp:.4} ± {se_cpp:.4} \
                     (table {f_ref:.3}, z = {z:+.2}); own counting f = {f_own:.4} ± {se_own:.4}\n"
                );
                if z.abs() > 3.0 {
                    failures.push(format!("{name} Q={q}: z = {z:+.2}"));
                }
                let z_own = (f_own - f_cpp) / (se_own.powi(2) + se_cpp.powi(2)).sqrt();
                if z_own > 3.0 {
                    failures.push(format!(
                        "{name} Q={q}: own counting leaks more (z = {z_own:+.2})"
                    ));
                }
            }
        }
        println!("{report}");
        assert!(failures.is_empty(), "{failures:?}\n{report}");
    }
}
