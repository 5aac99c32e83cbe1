//! LDPC reconciliation inside the endpoints (docs/postprocessing.md, "LDPC"): the controller
//! chooses m and B from its kept LLRs and asks; the robot, whose bits are the reference,
//! builds the same code from the block's public randomness and answers with the syndrome of
//! each round's new checks; the controller decodes on its LLRs and asks for a feedback round
//! while the syndrome is not met and rounds are left. Both sides charge the same leak: every
//! syndrome bit sent plus [`LdpcSettings::round_count_bits`].

use super::{MAX_SYNDROME_BITS, Message, RejectReason};
use crate::bitstring::BitString;
use crate::ldpc::{BlockCode, LdpcSettings, SyndromeDecoder, bhattacharyya, syndrome_length};

/// What reconciliation left the controller with, whichever method ran.
pub(super) struct Reconciled {
    /// The controller's bits after correction (the tags tell whether they are the robot's).
    pub(super) corrected: BitString,
    /// leak_EC (bits).
    pub(super) leak: u64,
    /// Cascade questions answered, or LDPC syndrome bits sent.
    pub(super) questions: u64,
    /// LDPC: the rounds used.
    pub(super) ldpc_rounds: Option<u32>,
}

/// B in 1024ths, as `SyndromeAsk` carries it ([`bhattacharyya`] is a multiple of 2⁻¹⁰ in
/// [2⁻¹⁰, 1]).
fn bhattacharyya_steps(b: f64) -> u16 {
    (b * 1024.0).round().clamp(1.0, 1024.0) as u16
}

/// The controller's side of one block.
pub(super) struct SyndromeDecoding {
    settings: LdpcSettings,
    decoder: SyndromeDecoder,
    codes: BlockCode,
    llrs: Vec<f64>,
    /// The current code's syndrome: every bit received, each split check's turned into its
    /// remainder's ([`BlockCode::receive`]).
    syndrome: Vec<bool>,
    first_checks: u32,
    bhattacharyya: u16,
    iterations: u32,
}

/// What a received syndrome leads to.
pub(super) enum DecodingStep {
    /// Decoding failed and a feedback round is left: ask for it.
    Ask(Message),
    /// The syndrome is met.
    Done(Reconciled),
}

impl SyndromeDecoding {
    /// Starts on the kept positions' LLRs (`llrs`, Lᵢ = ln P(xᵢ = 0)/P(xᵢ = 1)); `seed` is
    /// the block's public LDPC seed. Returns the decoding and round 1's request.
    ///
    /// # Errors
    /// Why the code cannot be built (a block over the LDPC bound, no bits).
    pub(super) fn start(
        settings: LdpcSettings,
        llrs: Vec<f64>,
        seed: [u8; 32],
        block: u64,
    ) -> Result<(Self, Message), String> {
        let decoder = SyndromeDecoder::new(settings.max_iterations).map_err(|e| e.to_string())?;
        let m = syndrome_length(&llrs, settings.efficiency, settings.finite_length)
            .map_err(|e| e.to_string())?;
        let steps = bhattacharyya_steps(bhattacharyya(&llrs));
        let codes = BlockCode::first(llrs.len(), m, f64::from(steps) / 1024.0, seed, &settings)
            .map_err(|e| e.to_string())?;
        let decoding = Self {
            settings,
            decoder,
            codes,
            llrs,
            syndrome: Vec::new(),
            first_checks: m as u32,
            bhattacharyya: steps,
            iterations: 0,
        };
        let ask = decoding.ask(block);
        Ok((decoding, ask))
    }

    /// The request of the current round.
    fn ask(&self, block: u64) -> Message {
        Message::SyndromeAsk {
            block,
            round: self.codes.rounds(),
            syndrome_bits: self.first_checks,
            bhattacharyya: self.bhattacharyya,
        }
    }

    /// The round awaited.
    pub(super) fn round(&self) -> u32 {
        self.codes.rounds()
    }

    /// Takes the robot's syndrome of the current round's new checks and decodes.
    ///
    /// # Errors
    /// A syndrome of the wrong length, or decoding failed after the last round: failed
    /// reconciliation, said with its figures.
    pub(super) fn accept(&mut self, block: u64, syndrome: &[bool]) -> Result<DecodingStep, String> {
        if syndrome.len() != self.codes.round_checks() {
            return Err(format!(
                "the robot's syndrome of round {} has {} bits, the round has {} checks",
                self.round(),
                syndrome.len(),
                self.codes.round_checks()
            ));
        }
        self.codes
            .receive(&mut self.syndrome, syndrome)
            .map_err(|e| e.to_string())?;
        let decoded = self
            .decoder
            .decode_within(
                self.codes.code(),
                &self.llrs,
                &BitString::from_bools(&self.syndrome),
                self.settings.iterations_in_round(self.round()),
            )
            .map_err(|e| e.to_string())?;
        self.iterations += decoded.iterations;
        if decoded.converged {
            let sent = self.syndrome.len() as u64;
            return Ok(DecodingStep::Done(Reconciled {
                corrected: decoded.bits,
                leak: sent + self.settings.round_count_bits(),
                questions: sent,
                ldpc_rounds: Some(self.round()),
            }));
        }
        if self.codes.extend() {
            Ok(DecodingStep::Ask(self.ask(block)))
        } else {
            Err(format!(
                "failed reconciliation: LDPC decoding did not meet the syndrome after {} \
                 round(s) ({} syndrome bits, {} belief-propagation iterations)",
                self.round(),
                self.syndrome.len(),
                self.iterations
            ))
        }
    }
}

/// The robot's side of one block: the code, once asked.
pub(super) struct SyndromeEncoding {
    codes: Option<BlockCode>,
    first_checks: u32,
    bhattacharyya: u16,
}

impl SyndromeEncoding {
    /// Nothing asked yet.
    pub(super) fn new() -> Self {
        Self {
            codes: None,
            first_checks: 0,
            bhattacharyya: 0,
        }
    }

    /// Syndrome bits sent so far.
    pub(super) fn sent(&self) -> u64 {
        self.codes
            .as_ref()
            .map_or(0, |c| c.code().syndrome_bits() as u64)
    }

    /// The syndrome of round `round`'s new checks of `reference` (the robot's kept bits),
    /// `round` being the next one. Sizes are checked before any work: m ∈ 1..=n, B ∈
    /// 1..=1024, the same m and B in every round, at most 1 + the agreed feedback rounds.
    ///
    /// # Errors
    /// [`RejectReason::BadQuestions`] for anything an honest controller does not ask.
    pub(super) fn answer(
        &mut self,
        round: u32,
        first_checks: u32,
        bhattacharyya: u16,
        reference: &BitString,
        seed: [u8; 32],
        settings: &LdpcSettings,
    ) -> Result<Vec<bool>, RejectReason> {
        match &mut self.codes {
            None => {
                let n = reference.len();
                if round != 1
                    || first_checks == 0
                    || first_checks as usize > n.min(MAX_SYNDROME_BITS)
                    || !(1..=1024).contains(&bhattacharyya)
                {
                    return Err(RejectReason::BadQuestions);
                }
                let b = f64::from(bhattacharyya) / 1024.0;
                let codes = BlockCode::first(n, first_checks as usize, b, seed, settings)
                    .map_err(|_| RejectReason::BadQuestions)?;
                self.codes = Some(codes);
                self.first_checks = first_checks;
                self.bhattacharyya = bhattacharyya;
            }
            Some(codes) => {
                if round != codes.rounds() + 1
                    || first_checks != self.first_checks
                    || bhattacharyya != self.bhattacharyya
                    || !codes.extend()
                {
                    return Err(RejectReason::BadQuestions);
                }
            }
        }
        let codes = self.codes.as_ref().ok_or(RejectReason::BadQuestions)?;
        codes
            .round_syndrome(reference)
            .map_err(|_| RejectReason::BadQuestions)
    }
}
