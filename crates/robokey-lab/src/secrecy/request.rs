//! What a caller asks of a secrecy analysis — the adversaries, ε, the block size, how many
//! blocks, the pooling, the disclosed sample, the most sessions, the assumption — checked
//! against the allowed ranges and resolved, against the sweep's `[secrecy]` table and its
//! sensing mode, into [`SecrecyOptions`]. `robokey secrecy` and the Python package ask through
//! it, so both refuse and default alike.

use robokey::config::{EveStrategy, SensingMode};

use super::options::{
    LlrModel, MAX_SESSIONS, Reconciliation, SecrecyOptions, Sizing, default_adversaries,
    default_max_sessions,
};
use super::pipeline::Pooling;
use crate::experiment::{Experiment, MAX_BLOCK_BITS, MIN_BLOCK_BITS};

/// An analysis as asked; `None` and an empty list take the defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct SecrecyRequest {
    /// Adversaries (none: [`default_adversaries`] of the sweep's sensing mode).
    pub adversaries: Vec<EveStrategy>,
    /// ε per term (none: the sweep's `[secrecy] epsilon`, else 10⁻⁶).
    pub epsilon: Option<f64>,
    /// Least pooled raw bits per block (none: the sweep's `[secrecy] block_bits`, else 10⁴).
    pub block_bits: Option<u64>,
    /// Blocks to fill per point.
    pub blocks: usize,
    /// Which sessions are pooled (none: confirmed in odometry mode, complete in private
    /// sensing).
    pub pooling: Option<Pooling>,
    /// Largest sample disclosed to estimate the error rate.
    pub sample_bits: usize,
    /// Most sessions simulated per point and adversary (none: [`default_max_sessions`] of the
    /// block size and blocks).
    pub max_sessions: Option<u32>,
    /// Eve's least independent error rate that sizes the key (none: no assumption).
    pub assumed_eve_error: Option<f64>,
    /// What sizes private sensing's key (none: the sweep's `[secrecy] sizing`, else
    /// configured).
    pub sizing: Option<Sizing>,
    /// How `complete` pooling reconciles (none: the sweep's `[secrecy] reconciliation`, else
    /// Cascade).
    pub reconciliation: Option<Reconciliation>,
    /// LDPC: which model the controller's LLRs are computed with (none: each point's
    /// `postprocess.llrs`, else following the sizing).
    pub llrs: Option<LlrModel>,
}

impl Default for SecrecyRequest {
    fn default() -> Self {
        let options = SecrecyOptions::default();
        Self {
            adversaries: Vec::new(),
            epsilon: None,
            block_bits: None,
            blocks: options.blocks,
            pooling: None,
            sample_bits: options.sample_bits,
            max_sessions: None,
            assumed_eve_error: None,
            sizing: None,
            reconciliation: None,
            llrs: None,
        }
    }
}

/// An option of [`SecrecyRequest`], named as each caller names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RequestOption {
    /// [`SecrecyRequest::epsilon`].
    Epsilon,
    /// [`SecrecyRequest::block_bits`].
    BlockBits,
    /// [`SecrecyRequest::blocks`].
    Blocks,
    /// [`SecrecyRequest::max_sessions`].
    MaxSessions,
    /// [`SecrecyRequest::assumed_eve_error`].
    AssumedEveError,
    /// [`SecrecyRequest::llrs`].
    Llrs,
}

impl RequestOption {
    /// Its command-line flag, e.g. `--eps`.
    #[must_use]
    pub fn flag(self) -> &'static str {
        match self {
            Self::Epsilon => "--eps",
            Self::BlockBits => "--block",
            Self::Blocks => "--blocks",
            Self::MaxSessions => "--max-sessions",
            Self::AssumedEveError => "--assume-eve-error",
            Self::Llrs => "--llrs",
        }
    }

    /// Its keyword argument in the Python package, e.g. `epsilon`.
    #[must_use]
    pub fn keyword(self) -> &'static str {
        match self {
            Self::Epsilon => "epsilon",
            Self::BlockBits => "block_bits",
            Self::Blocks => "blocks",
            Self::MaxSessions => "max_sessions",
            Self::AssumedEveError => "assume_eve_error",
            Self::Llrs => "llrs",
        }
    }
}

/// An option out of its allowed range.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OptionError {
    /// The option.
    pub option: RequestOption,
    /// Its value.
    pub value: String,
    /// What is allowed.
    pub allowed: String,
}

impl OptionError {
    /// The message, the option named as the caller wrote it (`--eps 2`, `epsilon=2`).
    #[must_use]
    pub fn message(&self, written: &str) -> String {
        format!("{written} is not allowed (allowed: {})", self.allowed)
    }
}

impl SecrecyRequest {
    /// Checks every option against its allowed range.
    ///
    /// # Errors
    /// The first option out of range.
    pub fn validate(&self) -> Result<(), OptionError> {
        let refuse = |option, value: String, allowed: &str| {
            Err(OptionError {
                option,
                value,
                allowed: allowed.to_owned(),
            })
        };
        if let Some(eps) = self.epsilon
            && !(eps > 0.0 && eps < 1.0)
        {
            return refuse(RequestOption::Epsilon, eps.to_string(), "(0, 1)");
        }
        if let Some(block) = self.block_bits
            && !(MIN_BLOCK_BITS..=MAX_BLOCK_BITS).contains(&block)
        {
            return refuse(
                RequestOption::BlockBits,
                block.to_string(),
                &format!("{MIN_BLOCK_BITS} to {MAX_BLOCK_BITS} bits"),
            );
        }
        if !(1..=1_000).contains(&self.blocks) {
            return refuse(RequestOption::Blocks, self.blocks.to_string(), "1 to 1000");
        }
        if let Some(max) = self.max_sessions
            && !(1..=MAX_SESSIONS).contains(&max)
        {
            return refuse(
                RequestOption::MaxSessions,
                max.to_string(),
                &format!("1 to {MAX_SESSIONS}"),
            );
        }
        if let Some(p) = self.assumed_eve_error
            && !(p > 0.0 && p <= 0.5)
        {
            return refuse(RequestOption::AssumedEveError, p.to_string(), "(0, 0.5]");
        }
        Ok(())
    }

    /// The options for `experiment`: what was asked, else the sweep's `[secrecy]` table, else
    /// the defaults of its sensing mode.
    ///
    /// # Errors
    /// LLRs other than the prior's asked for where the resolved reconciliation is Cascade,
    /// which reconciles the controller's hard decisions and reads no LLRs (as the
    /// configuration refuses `postprocess.llrs = "measured"` with Cascade).
    pub fn options(&self, experiment: &Experiment) -> Result<SecrecyOptions, OptionError> {
        let defaults = SecrecyOptions::default();
        let mode = experiment.points[0].config.sensing.mode;
        let block_bits = self
            .block_bits
            .or(experiment.secrecy.block_bits)
            .map_or(defaults.block_bits, |b| b as usize);
        let reconciliation = self
            .reconciliation
            .or(experiment.secrecy.reconciliation)
            .unwrap_or(defaults.reconciliation);
        if let Some(llrs) = self.llrs
            && !llrs.is_prior()
            && reconciliation == Reconciliation::Cascade
        {
            return Err(OptionError {
                option: RequestOption::Llrs,
                value: llrs.name().to_owned(),
                allowed: format!(
                    "prior with reconciliation cascade ({}): Cascade reconciles the \
                     controller's hard decisions, made online with the prior, and reads no \
                     LLRs; reconciliation ldpc decodes on them",
                    if self.reconciliation.is_some() {
                        "asked for"
                    } else if experiment.secrecy.reconciliation.is_some() {
                        "the sweep's [secrecy] reconciliation"
                    } else {
                        "the default"
                    }
                ),
            });
        }
        Ok(SecrecyOptions {
            adversaries: if self.adversaries.is_empty() {
                default_adversaries(mode)
            } else {
                self.adversaries.clone()
            },
            epsilon: self
                .epsilon
                .or(experiment.secrecy.epsilon)
                .unwrap_or(defaults.epsilon),
            block_bits,
            pooling: self.pooling.unwrap_or(match mode {
                SensingMode::Odometry => Pooling::Confirmed,
                SensingMode::Private => Pooling::Complete,
            }),
            sample_bits: self.sample_bits,
            assumed_eve_error: self.assumed_eve_error,
            blocks: self.blocks,
            max_sessions: self
                .max_sessions
                .unwrap_or_else(|| default_max_sessions(block_bits, self.blocks)),
            sizing: self
                .sizing
                .or(experiment.secrecy.sizing)
                .unwrap_or(defaults.sizing),
            reconciliation,
            llrs: self.llrs,
            ..defaults
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn experiment(text: &str) -> Experiment {
        Experiment::from_table("", text.parse().unwrap(), "t.toml").unwrap()
    }

    #[test]
    fn unset_options_take_the_sweeps_table_then_the_modes_defaults() {
        let odometry = experiment("[secrecy]\nblock_bits = 2000\n");
        let options = SecrecyRequest::default().options(&odometry).unwrap();
        assert_eq!(options.block_bits, 2000);
        assert_eq!(options.epsilon, 1e-6);
        assert_eq!(options.pooling, Pooling::Confirmed);
        assert_eq!(
            options.adversaries,
            default_adversaries(SensingMode::Odometry)
        );
        assert_eq!(options.max_sessions, default_max_sessions(2000, 1));
        assert_eq!(
            (options.reconciliation, options.sizing),
            (Reconciliation::Cascade, Sizing::Configured)
        );
        let private = experiment("[sensing]\nmode = \"private\"\n");
        let asked = SecrecyRequest {
            block_bits: Some(5000),
            max_sessions: Some(7),
            ..SecrecyRequest::default()
        };
        let options = asked.options(&private).unwrap();
        assert_eq!((options.block_bits, options.max_sessions), (5000, 7));
        assert_eq!(options.pooling, Pooling::Complete);
        assert_eq!(
            options.adversaries,
            default_adversaries(SensingMode::Private)
        );
    }

    #[test]
    fn the_sweeps_reconciliation_and_sizing_are_defaults_the_request_overrides() {
        let stated = experiment(
            "[sensing]\nmode = \"private\"\n[secrecy]\nreconciliation = \"ldpc\"\n\
             sizing = \"measured\"\n",
        );
        let options = SecrecyRequest::default().options(&stated).unwrap();
        assert_eq!(
            (options.reconciliation, options.sizing),
            (Reconciliation::Ldpc, Sizing::Measured)
        );
        let asked = SecrecyRequest {
            reconciliation: Some(Reconciliation::Cascade),
            sizing: Some(Sizing::World),
            ..SecrecyRequest::default()
        };
        let options = asked.options(&stated).unwrap();
        assert_eq!(
            (options.reconciliation, options.sizing),
            (Reconciliation::Cascade, Sizing::World)
        );
    }

    #[test]
    fn llrs_other_than_the_priors_are_refused_where_cascade_reconciles() {
        let private = experiment("[sensing]\nmode = \"private\"\n");
        let measured = SecrecyRequest {
            llrs: Some(LlrModel::Measured),
            ..SecrecyRequest::default()
        };
        let e = measured.options(&private).unwrap_err();
        assert_eq!(
            e.message(&format!("{} {}", e.option.flag(), e.value)),
            "--llrs measured is not allowed (allowed: prior with reconciliation cascade (the \
             default): Cascade reconciles the controller's hard decisions, made online with the \
             prior, and reads no LLRs; reconciliation ldpc decodes on them)"
        );
        let world = SecrecyRequest {
            llrs: Some(LlrModel::World),
            reconciliation: Some(Reconciliation::Cascade),
            ..SecrecyRequest::default()
        };
        let e = world.options(&private).unwrap_err();
        assert_eq!((e.option, e.value.as_str()), (RequestOption::Llrs, "world"));
        assert!(e.allowed.contains("(asked for)"), "{}", e.allowed);
        let stated =
            experiment("[sensing]\nmode = \"private\"\n[secrecy]\nreconciliation = \"cascade\"\n");
        let e = measured.options(&stated).unwrap_err();
        assert!(
            e.allowed.contains("(the sweep's [secrecy] reconciliation)"),
            "{}",
            e.allowed
        );
        // The prior, and any model where LDPC decodes, are what they say.
        let prior = SecrecyRequest {
            llrs: Some(LlrModel::Prior),
            ..SecrecyRequest::default()
        };
        assert_eq!(prior.options(&private).unwrap().llrs, Some(LlrModel::Prior));
        let ldpc = SecrecyRequest {
            reconciliation: Some(Reconciliation::Ldpc),
            ..measured.clone()
        };
        assert_eq!(
            ldpc.options(&private).unwrap().llrs,
            Some(LlrModel::Measured)
        );
        let sweeps_ldpc =
            experiment("[sensing]\nmode = \"private\"\n[secrecy]\nreconciliation = \"ldpc\"\n");
        assert_eq!(
            measured.options(&sweeps_ldpc).unwrap().llrs,
            Some(LlrModel::Measured)
        );
    }

    #[test]
    fn options_out_of_range_name_themselves_for_each_caller() {
        let refused = |request: SecrecyRequest| request.validate().unwrap_err();
        let e = refused(SecrecyRequest {
            epsilon: Some(1.0),
            ..SecrecyRequest::default()
        });
        assert_eq!(
            e.message(&format!("{} {}", e.option.flag(), e.value)),
            "--eps 1 is not allowed (allowed: (0, 1))"
        );
        assert_eq!(e.option.keyword(), "epsilon");
        let e = refused(SecrecyRequest {
            max_sessions: Some(0),
            ..SecrecyRequest::default()
        });
        assert_eq!(
            (e.option, e.allowed.as_str()),
            (RequestOption::MaxSessions, "1 to 1000000")
        );
        let e = refused(SecrecyRequest {
            assumed_eve_error: Some(0.6),
            ..SecrecyRequest::default()
        });
        assert_eq!(e.option.flag(), "--assume-eve-error");
        assert!(SecrecyRequest::default().validate().is_ok());
    }
}
