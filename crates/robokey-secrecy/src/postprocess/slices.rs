//! Multilevel slices (docs/postprocessing.md, "Multilevel slices"): a session of symbols of
//! `m = log₂ levels` bits is reconciled slice by slice, slice `s` holding the bits at place
//! `s` of every symbol's label. Each slice is its own pool entry and its own block, under an
//! ID both sides derive from the session's ([`slice_id`]), so the robot, which holds every
//! slice's reference bits from the start, needs nothing more on the wire. The controller
//! pools slice 0; once a block of slices is reconciled, the endpoint hands the shell the
//! robot's bits of it ([`Output::SliceReconciled`](super::Output::SliceReconciled)), the
//! shell computes the next slice's LLRs given them and answers
//! [`ControllerInput::NextSlices`](super::ControllerInput::NextSlices), and those entries
//! form the next block. A block that fails reconciliation ends its sessions' later slices.

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::SessionSamples;
use crate::bitstring::BitString;

/// Most slices per symbol: 8 levels, 3 bits.
pub const MAX_SLICES: usize = 3;

/// Most key bits per doublet (two dimensions of 8 levels): 2⁶ = 64 patterns.
pub const MAX_KEY_BITS: usize = 6;

/// How a session's bits fall into slices: bit `i` of a session (`key_bits` per doublet) is
/// at place `(i mod key_bits) mod slices` of its symbol's label.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Slicing {
    /// Key bits per doublet (a multiple of `slices`, at most [`MAX_KEY_BITS`]).
    pub key_bits: u8,
    /// Slices per symbol, `log₂ levels` (1 to [`MAX_SLICES`]).
    pub slices: u8,
}

impl Slicing {
    /// The slicing of doublets of `key_bits` bits, symbols of `slices` bits.
    ///
    /// # Errors
    /// `slices` outside 1 to 3, or `key_bits` not a multiple of it up to 6 (named).
    pub fn new(key_bits: usize, slices: usize) -> Result<Self, String> {
        if !(1..=MAX_SLICES).contains(&slices) {
            return Err(format!("slices {slices} (allowed: 1 to {MAX_SLICES})"));
        }
        if !(1..=MAX_KEY_BITS).contains(&key_bits) || !key_bits.is_multiple_of(slices) {
            return Err(format!(
                "key bits per doublet {key_bits} (allowed: a multiple of the {slices} slices, \
                 1 to {MAX_KEY_BITS})"
            ));
        }
        Ok(Self {
            key_bits: key_bits as u8,
            slices: slices as u8,
        })
    }

    /// The slice of bit `i` of a session.
    #[must_use]
    pub fn slice_of(&self, i: usize) -> usize {
        (i % usize::from(self.key_bits)) % usize::from(self.slices)
    }

    /// The entries of `all` (one per bit of a session) in slice `slice`, in order.
    #[must_use]
    pub fn pick<T: Copy>(&self, all: &[T], slice: usize) -> Vec<T> {
        all.iter()
            .enumerate()
            .filter(|&(i, _)| self.slice_of(i) == slice)
            .map(|(_, &x)| x)
            .collect()
    }

    /// Bit patterns per doublet, `2^key_bits`.
    #[must_use]
    pub fn patterns(&self) -> usize {
        1 << self.key_bits
    }
}

/// The pool ID of slice `slice` of session `session`: the session's own for slice 0 (binary
/// sessions keep their IDs), else the first 4 bytes, big-endian, of
/// SHA-256("robokey/slice-id/v1" ‖ session u32 ‖ slice u8). Both sides derive it; a
/// collision with another pooled ID is refused as a duplicate, as between session IDs.
#[must_use]
pub fn slice_id(session: u32, slice: usize) -> u32 {
    if slice == 0 {
        return session;
    }
    let digest = Sha256::new()
        .chain_update(b"robokey/slice-id/v1")
        .chain_update(session.to_be_bytes())
        .chain_update([slice as u8])
        .finalize();
    u32::from_be_bytes([digest[0], digest[1], digest[2], digest[3]])
}

/// What the controller keeps of a multilevel session for its later slices: its view's
/// likelihoods, its bits' Eve separations and the robot's bits of the slices reconciled so
/// far.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StagedSession {
    /// The session's ID (slice 0's pool ID).
    pub session: u32,
    /// The slice this entry holds.
    pub slice: u8,
    /// How its bits fall into slices.
    pub slicing: Slicing,
    /// `ln p(view | h)` of every bit pattern `h` of every doublet, `2^key_bits` per doublet,
    /// each doublet's largest at 0, in steps of [`super::LLR_QUANTUM`] nat
    /// ([`super::quantise_llr`]: toward zero, so at most ≈ 128 nats below the largest).
    pub likelihoods: Vec<i16>,
    /// The Eve separation of every bit of the session, in order.
    pub separations: Vec<f64>,
    /// The robot's bits of the session at the positions of the slices below `slice` (as
    /// reconciled), 0 elsewhere.
    pub known: BitString,
    /// What the controller keeps of the session's doublets for the block's estimate of the
    /// plant on whole symbols (docs/estimation.md, "Multilevel symbols"; empty when nothing
    /// is kept; journals written before it read without).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub samples: SessionSamples,
}

impl StagedSession {
    /// Bits of the session (all slices).
    #[must_use]
    pub fn bits(&self) -> usize {
        self.known.len()
    }

    /// Bits of its slice.
    #[must_use]
    pub fn slice_bits(&self) -> usize {
        (0..self.bits())
            .filter(|&i| self.slicing.slice_of(i) == usize::from(self.slice))
            .count()
    }

    /// Whether a slice follows this one.
    #[must_use]
    pub fn has_next(&self) -> bool {
        self.slice + 1 < self.slicing.slices
    }

    /// The pool IDs of the slices after this one.
    pub fn later_ids(&self) -> impl Iterator<Item = u32> + '_ {
        (usize::from(self.slice) + 1..usize::from(self.slicing.slices))
            .map(|s| slice_id(self.session, s))
    }

    /// The entry for the next slice once `robot` (the robot's bits of this slice, in order)
    /// is reconciled.
    #[must_use]
    pub fn advanced(&self, robot: &BitString) -> Self {
        let mut known = self.known.clone();
        let mut next = (0..robot.len()).map(|j| robot.get(j) == Some(true));
        for i in 0..known.len() {
            if self.slicing.slice_of(i) == usize::from(self.slice) {
                let _ = known.set(i, next.next() == Some(true));
            }
        }
        Self {
            slice: self.slice + 1,
            known,
            ..self.clone()
        }
    }

    /// Checks the sizes: whole doublets, one separation per bit in [0, 10⁶], one likelihood
    /// per pattern per doublet, no kept doublets or one per doublet, a slice below the
    /// slices.
    ///
    /// # Errors
    /// What is wrong, named.
    pub fn check(&self) -> Result<(), String> {
        let key_bits = usize::from(self.slicing.key_bits);
        Slicing::new(key_bits, usize::from(self.slicing.slices))?;
        if self.slice >= self.slicing.slices {
            return Err(format!(
                "slice {} (allowed: 0 to {})",
                self.slice,
                self.slicing.slices - 1
            ));
        }
        let bits = self.bits();
        if bits == 0 || !bits.is_multiple_of(key_bits) || bits > super::MAX_SESSION_BITS {
            return Err(format!(
                "{bits} bits (allowed: whole doublets of {key_bits}, up to {})",
                super::MAX_SESSION_BITS
            ));
        }
        if self.separations.len() != bits {
            return Err(format!(
                "{} separations for its {bits} bits",
                self.separations.len()
            ));
        }
        if let Some(d) = self.separations.iter().find(|d| !(0.0..=1e6).contains(*d)) {
            return Err(format!("Eve separation {d} (allowed: 0 to 10^6)"));
        }
        let expected = bits / key_bits * self.slicing.patterns();
        if self.likelihoods.len() != expected {
            return Err(format!(
                "{} likelihoods for its {} doublets of {} patterns",
                self.likelihoods.len(),
                bits / key_bits,
                self.slicing.patterns()
            ));
        }
        if !self.samples.is_empty() && self.samples.len() != bits / key_bits {
            return Err(format!(
                "{} kept doublets for its {} doublets (allowed: none, or one per doublet)",
                self.samples.len(),
                bits / key_bits
            ));
        }
        Ok(())
    }
}

/// One reconciled block's multilevel sessions, each advanced to its next slice
/// ([`StagedSession::advanced`]): the shell computes their LLRs and answers with them.
#[derive(Clone, Debug, PartialEq)]
pub struct ReconciledSlices {
    /// The block reconciled.
    pub block: u64,
    /// Its sessions with a slice after the block's, advanced to it.
    pub sessions: Vec<StagedSession>,
}

/// What the controller needs estimated once a multilevel block's last slice is reconciled,
/// its lower slices' blocks held reconciled (docs/postprocessing.md, "Multilevel slices"):
/// the block's sessions advanced past their last slice — `known` holds the robot's bits of
/// every slice, `samples` what the controller kept of each doublet — and the bits each
/// slice's block disclosed in its sample. The shell estimates the plant on whole symbols,
/// sizes each slice from that one estimate and answers
/// [`ControllerInput::SliceEstimates`](super::ControllerInput::SliceEstimates).
#[derive(Clone, Debug, PartialEq)]
pub struct SlicesEstimateRequest {
    /// The last slice's block number.
    pub block: u64,
    /// The sessions, in block order, advanced past their last slice (key material).
    pub sessions: Vec<StagedSession>,
    /// Bits disclosed by each slice's block, slice 0 first.
    pub disclosed: Vec<u64>,
}

/// A slice of a multilevel session as the controller pools it: its decisions and LLRs of
/// the slice's bits, given the lower slices' reconciled bits.
#[derive(Clone, Debug)]
pub struct SliceInput {
    /// The controller's decisions of the slice's bits, in order.
    pub bits: BitString,
    /// Their LLRs (empty where Cascade reconciles).
    pub llrs: Vec<f64>,
    /// The session's staged material, at this slice.
    pub staged: StagedSession,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cascade::CascadeSchedule;
    use crate::postprocess::{
        Assumption, BlockReport, ControllerInput, ControllerPost, EstimateOutcome, EstimateRefusal,
        FinalKey, KeptDoublet, Message, Output, ReconciliationMethod, RobotInput, RobotPost,
        Settings,
    };
    use rand::rngs::ChaCha8Rng;
    use rand::{RngExt, SeedableRng};

    /// Two dimensions of 4 levels: 4 key bits per doublet, 2 slices.
    const SLICING: Slicing = Slicing {
        key_bits: 4,
        slices: 2,
    };

    /// Sessions of 400 doublets: the robot's bits, and the controller's first slice with
    /// errors at 3 %.
    fn sessions(rng: &mut ChaCha8Rng) -> Vec<(BitString, BitString)> {
        (0..6)
            .map(|_| {
                let robot = BitString::random(1_600, rng);
                let own: Vec<bool> = (0..1_600)
                    .filter(|&i| SLICING.slice_of(i) == 0)
                    .map(|i| (robot.get(i) == Some(true)) != (rng.random::<f64>() < 0.03))
                    .collect();
                (robot, BitString::from_bools(&own))
            })
            .collect()
    }

    /// Session `session`'s first slice, with a kept doublet per doublet when `whole` (the
    /// block sized on whole symbols).
    fn staged(session: u32, whole: bool) -> StagedSession {
        let kept = |doublet| KeptDoublet {
            doublet,
            inputs: [[0.0; 2]; 2],
            samples: [[0.0; 3]; 3],
            late: None,
        };
        StagedSession {
            session,
            slice: 0,
            slicing: SLICING,
            likelihoods: vec![0; 400 * SLICING.patterns()],
            separations: vec![0.5; 1_600],
            known: BitString::zeros(1_600),
            samples: if whole {
                (0..400).map(kept).collect()
            } else {
                Vec::new()
            },
        }
    }

    /// What an in-memory run gives.
    struct Ran {
        /// Each side's keys, in the order committed.
        controller: Vec<FinalKey>,
        robot: Vec<FinalKey>,
        /// The blocks whose next slices the shell computed.
        reconciled: Vec<u64>,
        /// Keys the controller had committed when each block was estimated on whole
        /// symbols.
        keys_at_estimates: Vec<usize>,
        /// Each side's reports of blocks ended.
        controller_reports: Vec<BlockReport>,
        robot_reports: Vec<BlockReport>,
        robot_post: RobotPost,
    }

    /// How the shell answers a block sized on whole symbols (each slice's outcome), or
    /// `None`: sessions pooled without samples, each slice keyed as it reconciles.
    type Estimates = Option<fn(&SlicesEstimateRequest) -> Vec<EstimateOutcome>>;

    fn bits_of(all: &BitString, slice: usize) -> BitString {
        let bools: Vec<bool> = (0..all.len()).map(|i| all.get(i) == Some(true)).collect();
        BitString::from_bools(&SLICING.pick(&bools, slice))
    }

    /// Both endpoints in memory, each message through `tamper`; the shell answers
    /// every reconciled slice with the robot's bits of the next one (checking that the
    /// endpoint handed it the robot's bits of the reconciled one). Returns both sides' keys,
    /// the blocks reconciled and the robot.
    fn run(estimates: Estimates, next_fits: bool, tamper: impl Fn(&mut Message)) -> Ran {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let pool = sessions(&mut rng);
        let settings = Settings {
            block_bits: 2_000,
            sample_bits: 100,
            epsilon: 1e-6,
            schedule: CascadeSchedule::BICONF,
            assumption: match estimates {
                None => Assumption::IndependentErrors { error_rate: 0.3 },
                Some(_) => Assumption::MeasuredViews {
                    separation: 0.0,
                    statement: "test".into(),
                    estimation_epsilon: 1e-6,
                    estimate_leak: 34.0,
                },
            },
            reconciliation: ReconciliationMethod::Cascade,
        };
        let mut controller = ControllerPost::new(settings.clone(), [1; 32]).unwrap();
        let mut robot = RobotPost::new(settings, [2; 32]).unwrap();
        for (id, (reference, own)) in pool.iter().enumerate() {
            for slice in 0..2 {
                robot
                    .handle_input(RobotInput::Session {
                        id: slice_id(id as u32, slice),
                        bits: bits_of(reference, slice),
                    })
                    .unwrap();
            }
            controller
                .handle_input(ControllerInput::StagedSession(SliceInput {
                    bits: own.clone(),
                    llrs: Vec::new(),
                    staged: staged(id as u32, estimates.is_some()),
                }))
                .unwrap();
        }
        let (mut keys, mut reconciled) = ((Vec::new(), Vec::new()), Vec::new());
        let (mut keys_at_estimates, mut reports) = (Vec::new(), (Vec::new(), Vec::new()));
        loop {
            let mut to_robot = Vec::new();
            while let Some(output) = controller.poll_output() {
                match output {
                    Output::Transmit(m) => to_robot.push(m),
                    Output::KeyCommitted(key) => keys.0.push(key),
                    Output::BlockEnded(report) => reports.0.push(report),
                    Output::SlicesEstimateNeeded(r) => {
                        // Every slice's robot bits, every session's kept doublets.
                        for next in &r.sessions {
                            assert_eq!(next.known, pool[next.session as usize].0);
                            assert_eq!(next.samples.len(), 400);
                        }
                        assert_eq!(r.disclosed.len(), 2);
                        keys_at_estimates.push(keys.0.len());
                        let outcomes = estimates.expect("sized on whole symbols")(&r);
                        controller
                            .handle_input(ControllerInput::SliceEstimates {
                                block: r.block,
                                outcomes,
                            })
                            .unwrap();
                    }
                    Output::SliceReconciled(r) => {
                        reconciled.push(r.block);
                        let slices = r
                            .sessions
                            .iter()
                            .map(|next| {
                                let reference = &pool[next.session as usize].0;
                                for i in (0..1_600).filter(|&i| SLICING.slice_of(i) == 0) {
                                    assert_eq!(next.known.get(i), reference.get(i), "bit {i}");
                                }
                                // A shell's slice that does not fit: one bit too few.
                                let mut bits = bits_of(reference, 1);
                                if !next_fits {
                                    bits = BitString::from_bools(&vec![false; bits.len() - 1]);
                                }
                                SliceInput {
                                    bits,
                                    llrs: Vec::new(),
                                    staged: next.clone(),
                                }
                            })
                            .collect();
                        let pooled = controller.handle_input(ControllerInput::NextSlices {
                            block: r.block,
                            slices,
                        });
                        assert_eq!(pooled.is_ok(), next_fits, "{pooled:?}");
                    }
                    _ => {}
                }
            }
            let mut to_controller = Vec::new();
            for mut m in to_robot.drain(..) {
                tamper(&mut m);
                robot.handle_input(RobotInput::Frame(m)).unwrap();
            }
            while let Some(output) = robot.poll_output() {
                match output {
                    Output::Transmit(mut m) => {
                        tamper(&mut m);
                        to_controller.push(m);
                    }
                    Output::KeyCommitted(key) => keys.1.push(key),
                    Output::BlockEnded(report) => reports.1.push(report),
                    _ => {}
                }
            }
            if to_controller.is_empty() {
                break;
            }
            for m in to_controller {
                controller.handle_input(ControllerInput::Frame(m)).unwrap();
            }
        }
        Ran {
            controller: keys.0,
            robot: keys.1,
            reconciled,
            keys_at_estimates,
            controller_reports: reports.0,
            robot_reports: reports.1,
            robot_post: robot,
        }
    }

    /// Each slice's outcome: slice 0 at separation 0.5, slice 1 at 1 (grid steps of 2⁻⁸).
    fn sized(r: &SlicesEstimateRequest) -> Vec<EstimateOutcome> {
        assert_eq!(r.disclosed, vec![100, 100]);
        vec![Ok(128), Ok(256)]
    }

    /// The block's estimate refuses it.
    fn refused(_: &SlicesEstimateRequest) -> Vec<EstimateOutcome> {
        vec![Err(EstimateRefusal("the test refuses".into())); 2]
    }

    /// Sized on whole symbols: slice 0's block is held reconciled (no key) until slice 1's
    /// is reconciled and the block estimated; then both are keyed, each from its own
    /// outcome (the robot recomputing ℓ from what was carried), the same on both sides.
    #[test]
    fn held_slices_are_keyed_after_the_blocks_estimate() {
        let ran = run(Some(sized), true, |_| {});
        assert_eq!(ran.controller, ran.robot);
        assert_eq!(ran.reconciled, vec![0, 2]);
        // No key of a block before its estimate: none at the first, two at the second.
        assert_eq!(ran.keys_at_estimates, vec![0, 2]);
        let blocks: Vec<u64> = ran.controller.iter().map(|k| k.block).collect();
        assert_eq!(blocks, vec![0, 1, 2, 3]);
        // Each slice from its own published separation, as both sides sized it.
        let steps: Vec<Option<u32>> = ran
            .robot_reports
            .iter()
            .map(|r| r.separation_steps)
            .collect();
        assert_eq!(steps, vec![Some(128), Some(256), Some(128), Some(256)]);
        assert!(ran.robot_post.snapshot().pool.is_empty());
    }

    /// A block the estimate refuses writes no key of any slice on either side, names the
    /// refusal in every slice's report on both sides, and spends its sessions.
    #[test]
    fn a_refused_multilevel_block_writes_no_key() {
        let ran = run(Some(refused), true, |_| {});
        assert!(ran.controller.is_empty() && ran.robot.is_empty());
        assert_eq!(ran.keys_at_estimates, vec![0, 0]);
        for reports in [&ran.controller_reports, &ran.robot_reports] {
            assert_eq!(reports.len(), 4, "{reports:?}");
            for report in reports {
                let why = report.reason.as_deref().unwrap_or_default();
                assert!(why.contains("block refused"), "{why}");
                assert_eq!(report.length, 0);
            }
        }
        assert!(
            ran.controller_reports[0]
                .reason
                .as_deref()
                .unwrap()
                .contains("the test refuses")
        );
        let snapshot = ran.robot_post.snapshot();
        assert!(snapshot.pool.is_empty() && snapshot.prepared.is_none());
    }

    /// No next slice of held slices can be pooled (the shell's do not fit): the held block
    /// ends refused, no key on either side, the robot dropping what it holds; the next
    /// sessions' block fares the same, and nothing stays pooled.
    #[test]
    fn held_slices_without_a_next_slice_end_the_block() {
        let ran = run(Some(sized), false, |_| {});
        assert!(ran.controller.is_empty() && ran.robot.is_empty());
        assert!(ran.keys_at_estimates.is_empty());
        for report in &ran.controller_reports {
            let why = report.reason.as_deref().unwrap_or_default();
            assert!(why.contains("no next slice"), "{why}");
        }
        assert_eq!(ran.controller_reports.len(), 2);
        let snapshot = ran.robot_post.snapshot();
        assert!(snapshot.pool.is_empty(), "{:?}", snapshot.pool);
    }

    /// A held slice's tag changed in flight as it is confirmed: the block ends without a key
    /// of any slice on either side; the next sessions' block is keyed.
    #[test]
    fn a_tampered_held_slice_ends_the_block() {
        let ran = run(Some(sized), true, |m| {
            if let Message::Confirmed { block: 0, tag } = m {
                tag[0] ^= 1;
            }
        });
        assert_eq!(ran.controller, ran.robot);
        let blocks: Vec<u64> = ran.controller.iter().map(|k| k.block).collect();
        assert_eq!(blocks, vec![2, 3]);
        assert!(ran.robot_post.snapshot().pool.is_empty());
    }

    /// Slice 0 of three sessions, then their slice 1 as the next block, then the same for
    /// the next three: four keys, the same on both sides, slice 1's under the slice IDs.
    #[test]
    fn each_slice_is_keyed_after_the_one_below_it() {
        let Ran {
            controller,
            robot,
            reconciled,
            ..
        } = run(None, true, |_| {});
        assert_eq!(reconciled, vec![0, 2]);
        assert_eq!(controller, robot);
        let blocks: Vec<(u64, Vec<u32>)> = controller
            .iter()
            .map(|k| (k.block, k.sessions.clone()))
            .collect();
        let ids = |range: std::ops::Range<u32>, slice| -> Vec<u32> {
            range.map(|s| slice_id(s, slice)).collect()
        };
        assert_eq!(
            blocks,
            vec![
                (0, ids(0..3, 0)),
                (1, ids(0..3, 1)),
                (2, ids(3..6, 0)),
                (3, ids(3..6, 1)),
            ]
        );
    }

    /// A slice block's sessions reordered in flight: the robot's bits would be concatenated
    /// in another order, so the controller refuses the block (no key on either side) and
    /// the next sessions go on.
    #[test]
    fn a_reordered_slice_block_is_refused() {
        let Ran {
            controller,
            robot,
            reconciled,
            ..
        } = run(None, true, |m| {
            if let Message::Propose {
                block: 1, sessions, ..
            } = m
            {
                sessions.reverse();
            }
        });
        assert_eq!(controller, robot);
        assert_eq!(reconciled, vec![0, 2]);
        let blocks: Vec<u64> = controller.iter().map(|k| k.block).collect();
        assert_eq!(blocks, vec![0, 2, 3]);
    }

    /// A tag changed in flight ends the block as failed reconciliation: its sessions' later
    /// slices end with it (never proposed, dropped from the robot's pool), and the next
    /// sessions go on.
    #[test]
    fn a_tampered_tag_ends_the_blocks_later_slices() {
        let Ran {
            controller,
            robot,
            reconciled,
            robot_post,
            ..
        } = run(None, true, |m| {
            if let Message::Confirmed { block: 0, tag } = m {
                tag[0] ^= 1;
            }
        });
        assert_eq!(controller, robot);
        assert_eq!(reconciled, vec![1]);
        let blocks: Vec<u64> = controller.iter().map(|k| k.block).collect();
        assert_eq!(blocks, vec![1, 2]);
        let pooled: Vec<u32> = robot_post
            .snapshot()
            .pool
            .iter()
            .map(|(id, _)| *id)
            .collect();
        assert!(pooled.is_empty(), "{pooled:?}");
    }

    #[test]
    fn slices_take_each_symbols_bits_by_place() {
        // Two dimensions of 4 levels: v's label in bits 0–1, ω's in 2–3.
        let slicing = Slicing::new(4, 2).unwrap();
        let all: Vec<usize> = (0..8).collect();
        assert_eq!(slicing.pick(&all, 0), vec![0, 2, 4, 6]);
        assert_eq!(slicing.pick(&all, 1), vec![1, 3, 5, 7]);
        assert!(Slicing::new(5, 2).is_err() && Slicing::new(6, 4).is_err());
    }

    #[test]
    fn slice_ids_keep_the_first_and_differ_for_the_others() {
        assert_eq!(slice_id(7, 0), 7);
        assert_ne!(slice_id(7, 1), slice_id(7, 2));
        assert_ne!(slice_id(7, 1), slice_id(8, 1));
        assert_eq!(slice_id(7, 1), slice_id(7, 1));
    }

    #[test]
    fn advancing_fills_the_reconciled_slice_and_checks_sizes() {
        let slicing = Slicing::new(2, 2).unwrap();
        let staged = StagedSession {
            session: 3,
            slice: 0,
            slicing,
            likelihoods: vec![0; 3 * 4],
            separations: vec![1.0; 6],
            known: BitString::zeros(6),
            samples: SessionSamples::new(),
        };
        assert_eq!(staged.check(), Ok(()));
        assert_eq!(staged.slice_bits(), 3);
        let next = staged.advanced(&BitString::from_bools(&[true, false, true]));
        assert_eq!(next.slice, 1);
        let known: Vec<bool> = (0..6).map(|i| next.known.get(i) == Some(true)).collect();
        assert_eq!(known, vec![true, false, false, false, true, false]);
        assert!(!next.has_next() && next.later_ids().next().is_none());
        assert_eq!(staged.later_ids().collect::<Vec<_>>(), vec![slice_id(3, 1)]);
        let short = StagedSession {
            likelihoods: vec![0; 5],
            ..staged
        };
        assert!(short.check().unwrap_err().contains("likelihoods"));
    }
}
