//! The controller's block-time computations (docs/estimation.md, "In the agents"), as a job
//! that holds everything it reads: the estimate of the plant or the commands check after
//! reconciliation, a multilevel block's estimate on whole symbols, the LLRs recomputed before
//! LDPC. [`BlockComputation::run`] is pure, so a shell may run it where it likes — inline, as
//! the simulator's pairs do, or on a worker thread while its loop keeps answering the network
//! (the agents: an estimate with slip in it takes seconds) — and hand back the [`Computed`].

use robokey_secrecy::postprocess::{
    EstimateOutcome, EstimateRequest, LlrAnswer, LlrRequest, SlicesEstimateRequest,
};

use super::slices::slice_estimates;
use crate::Config;
use crate::config::Sizing;
use crate::estimate::{BlockEstimate, check_request, estimate_request, llr_answer};

/// A computation post-processing asks for, with the parties' configuration it reads.
#[derive(Clone, Debug)]
pub struct BlockComputation {
    config: Config,
    request: Request,
}

/// What is asked.
#[derive(Clone, Debug)]
enum Request {
    /// After reconciliation: the estimate of the plant (measured sizing) or the commands check
    /// alone (configured sizing).
    Estimate(EstimateRequest),
    /// Before LDPC: the block's LLRs from the kept samples.
    Llrs(Box<LlrRequest>),
    /// A multilevel block on whole symbols, once its last slice is reconciled.
    Slices(Box<SlicesEstimateRequest>),
}

/// The answer to a [`BlockComputation`], for the link to hand its endpoint.
#[derive(Clone, Debug)]
pub struct Computed {
    pub(crate) block: u64,
    pub(crate) answer: Answer,
}

/// What a computation found.
#[derive(Clone, Debug)]
pub(crate) enum Answer {
    /// The block's published outcome, with the estimate behind it (measured sizing; none for
    /// the commands check alone).
    Estimate {
        estimate: Option<BlockEstimate>,
        outcome: EstimateOutcome,
    },
    /// The recomputed LLRs, or why the pooled ones stay (the block's report records either).
    Llrs(LlrAnswer),
    /// One outcome per slice, with the estimates behind them (measured sizing).
    Slices {
        estimates: Vec<BlockEstimate>,
        outcomes: Vec<EstimateOutcome>,
    },
}

impl BlockComputation {
    pub(crate) fn estimate(config: &Config, request: EstimateRequest) -> Self {
        Self {
            config: config.clone(),
            request: Request::Estimate(request),
        }
    }

    pub(crate) fn llrs(config: &Config, request: Box<LlrRequest>) -> Self {
        Self {
            config: config.clone(),
            request: Request::Llrs(request),
        }
    }

    pub(crate) fn slices(config: &Config, request: Box<SlicesEstimateRequest>) -> Self {
        Self {
            config: config.clone(),
            request: Request::Slices(request),
        }
    }

    /// The block it is for.
    #[must_use]
    pub fn block(&self) -> u64 {
        match &self.request {
            Request::Estimate(request) => request.block,
            Request::Llrs(request) => request.block,
            Request::Slices(request) => request.block,
        }
    }

    /// What it computes, in words (for the agent's output).
    #[must_use]
    pub fn describe(&self) -> &'static str {
        let measured = self.config.sizing() == Sizing::Measured;
        match (&self.request, measured) {
            (Request::Estimate(_), true) => "the estimate of the plant",
            (Request::Slices(_), true) => "the estimate of the plant on whole symbols",
            (Request::Estimate(_) | Request::Slices(_), false) => "the commands check",
            (Request::Llrs(_), _) => "the LLRs from the kept samples",
        }
    }

    /// Computes it: the simulator's functions on the kept samples and the robot's bits
    /// (`estimate::block`, `estimate::commands_check`, `estimate::block_llrs`,
    /// `slices::slice_estimates`), at ε_est = `postprocess.epsilon`.
    #[must_use]
    pub fn run(self) -> Computed {
        let config = &self.config;
        let epsilon = config.postprocess.epsilon;
        let measured = config.sizing() == Sizing::Measured;
        let block = self.block();
        let answer = match self.request {
            Request::Estimate(request) if measured => {
                let estimate = estimate_request(config, &request, epsilon);
                let outcome = estimate.outcome();
                Answer::Estimate {
                    estimate: Some(estimate),
                    outcome,
                }
            }
            Request::Estimate(request) => Answer::Estimate {
                estimate: None,
                outcome: check_request(config, &request, epsilon),
            },
            // The recomputed LLRs, or why the prior's stay (the block's report says).
            Request::Llrs(request) => {
                Answer::Llrs(llr_answer(config, &request, config.llr_model()))
            }
            Request::Slices(request) if measured => {
                let estimates =
                    slice_estimates(config, &request.sessions, &request.disclosed, epsilon);
                let outcomes = estimates.iter().map(BlockEstimate::outcome).collect();
                Answer::Slices {
                    estimates,
                    outcomes,
                }
            }
            Request::Slices(request) => {
                // The commands check on whole symbols, its verdict for every slice.
                let whole = EstimateRequest {
                    block: request.block,
                    sessions: request
                        .sessions
                        .iter()
                        .map(|s| (s.session, s.samples.clone(), s.known.clone()))
                        .collect(),
                    disclosed: request.disclosed.iter().sum(),
                };
                let verdict = check_request(config, &whole, epsilon);
                Answer::Slices {
                    estimates: Vec::new(),
                    outcomes: vec![verdict; request.disclosed.len()],
                }
            }
        };
        Computed { block, answer }
    }
}

impl Computed {
    /// The block it answers for.
    #[must_use]
    pub fn block(&self) -> u64 {
        self.block
    }
}
