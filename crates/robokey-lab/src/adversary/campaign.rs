//! Eavesdropping campaigns: every eavesdropper strategy fed the same simulated sessions in
//! order, so that what the learning ones learn carries over (docs/threat-model.md). For each
//! one: every decided period with her model error, and per session her disagreement with
//! `K_c`; when she matched the controller and when she identified the model.

use rayon::prelude::*;
use robokey::Config;
use robokey::config::{EveStrategy, SensingMode};
use robokey::eve::{Eavesdropper, Eve, starting_errors};
use robokey::protocol::{KeyBits, Message, Outcome, SessionPlan, StepDecision};
use robokey::rng::{Purpose, stream};
use serde::{Deserialize, Serialize};

use super::period::PeriodRecord;
use super::window::match_period;
use crate::error::LabError;
use crate::run::sessions::{Heard, SessionBank};

/// One session, as one strategy ended it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SessionRecord {
    /// Session index.
    pub session: u32,
    /// Bits of `K_c`.
    pub key_bits: usize,
    /// Share of `K_c` she got wrong (%), when it has bits.
    pub disagreement_pct: Option<f64>,
    /// Codewords she flipped to match the confirmation tag, when she verified her key.
    pub tag_flips: Option<u32>,
    /// How the session ended for the controller.
    pub confirmed: bool,
}

/// Everything one strategy did over the sessions of one campaign.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StrategyRun {
    /// The strategy.
    pub strategy: EveStrategy,
    /// The campaign (independent sessions and starting errors).
    pub campaign: u32,
    /// Her starting relative errors (r, D, W, V).
    pub start: [f64; 4],
    /// Every period with a known bit that both she and the controller decided.
    #[serde(skip)]
    pub periods: Vec<PeriodRecord>,
    /// Per session.
    pub sessions: Vec<SessionRecord>,
    /// The first period from which her windowed error rate stays within the tolerance of
    /// the controller's (`None`: not by the end).
    pub match_period: Option<u64>,
    /// Sessions heard until her r and D stay within 1 % of the truth at every later
    /// session's end (0: from the start; `None`: not by the end).
    pub sessions_to_model: Option<u32>,
}

/// A model is "identified" once within this relative error of the truth on r and D.
pub const MODEL_TOLERANCE: f64 = 0.01;

/// Eve's starting point for `strategy` under `config` in campaign `campaign`: her errors
/// drawn from the `eve` stream of that replicate, so every consumer of the same config
/// meets the same Eve.
#[must_use]
pub fn eavesdropper(config: &Config, strategy: EveStrategy, campaign: u32) -> Eve {
    let mut config = config.clone();
    config.eve.strategy = Some(strategy);
    let seed = config.run.seed;
    let errors = starting_errors(
        &config,
        &mut stream(seed, Purpose::Eve, u64::from(campaign)),
    );
    Eve::new(&config, strategy, errors)
}

/// Feeds `eve` one session (session id `index`) and returns her key; calls `on_decision`
/// with every step she decided.
pub fn overhear(
    eve: &mut Eve,
    config: &Config,
    index: u32,
    transcript: &[Message],
    on_decision: impl FnMut(&Eve, &StepDecision),
) -> KeyBits {
    robokey::eve::hear(
        eve,
        &SessionPlan::from_config(config, index),
        transcript,
        on_decision,
    )
}

/// Feeds one strategy, as campaign `campaign` draws her, every session in order.
#[must_use]
pub fn listen(
    config: &Config,
    strategy: EveStrategy,
    campaign: u32,
    heard: Heard<'_>,
) -> StrategyRun {
    let mut eve = eavesdropper(config, strategy, campaign);
    let errors = eve.errors();
    let model_error = |eve: &Eve| {
        let model = eve.model();
        (
            model.wheel_radius / config.robot.r - 1.0,
            model.axle_length / config.robot.axle_length - 1.0,
        )
    };
    let within = |(r, d): (f64, f64)| r.abs().max(d.abs()) < MODEL_TOLERANCE;
    let mut identified_from = within((errors.r, errors.d)).then_some(0);
    let mut periods = Vec::new();
    let mut sessions = Vec::new();
    let mut elapsed = 0u64;
    for (index, (replicate, run, transcript)) in heard.iter().enumerate() {
        let index = index as u32;
        let steps = &run.steps;
        let k_a = overhear(&mut eve, config, replicate, transcript, |eve, decision| {
            let step = decision.step;
            let logged = steps.get(step as usize);
            if let (Some(eve_bit), Some(logged)) = (decision.bit, logged)
                && let (Some(bit), Some(controller)) = (logged.bit, logged.bhat)
            {
                let (r_error, d_error) = model_error(eve);
                periods.push(PeriodRecord {
                    session: index,
                    step,
                    period: elapsed + u64::from(step) + 1,
                    bit,
                    controller,
                    eve: eve_bit,
                    r_error,
                    d_error,
                });
            }
        });
        elapsed += steps.len() as u64;
        let k_c = &run.keys.controller;
        let wrong = k_c.iter().zip(k_a.iter()).filter(|(c, a)| c != a).count()
            + k_c.len().abs_diff(k_a.len());
        sessions.push(SessionRecord {
            session: index,
            key_bits: k_c.len(),
            disagreement_pct: (!k_c.is_empty()).then(|| 100.0 * wrong as f64 / k_c.len() as f64),
            tag_flips: eve.verified(),
            confirmed: run.controller_outcome == Some(Outcome::Confirmed),
        });
        identified_from = match (within(model_error(&eve)), identified_from) {
            (true, None) => Some(index + 1),
            (true, kept) => kept,
            (false, _) => None,
        };
    }
    let match_period = match_period(
        &periods,
        config.eve.window as usize,
        config.eve.match_tolerance_pp,
    );
    StrategyRun {
        strategy,
        campaign,
        start: [errors.r, errors.d, errors.w, errors.v],
        periods,
        sessions,
        match_period,
        sessions_to_model: identified_from,
    }
}

/// The result of `robokey eve` in simulation.
#[derive(Clone, Debug, PartialEq)]
pub struct Campaign {
    /// The configuration.
    pub config: Config,
    /// Campaign 0: one run per strategy, in the order asked, with every period.
    pub runs: Vec<StrategyRun>,
    /// Every campaign's runs (campaign-major, strategies in order), without their periods.
    pub all: Vec<StrategyRun>,
    /// Periods `N` of one session.
    pub steps_per_session: u32,
}

impl Campaign {
    /// Independent campaigns run.
    #[must_use]
    pub fn campaigns(&self) -> u32 {
        self.all.iter().map(|r| r.campaign + 1).max().unwrap_or(0)
    }
}

/// Runs `campaigns` independent campaigns: campaign c simulates the sessions (replicates)
/// `c·S … c·S + S − 1`, `S = eve.sessions`, and feeds them in order to every strategy, her
/// starting errors drawn from the `eve` stream of replicate c. Runs in parallel;
/// deterministic.
///
/// # Errors
/// A strategy of private sensing (they decide from doublets, not from odometry: see
/// `secrecy::private::eavesdroppers`), a private-sensing config, or a session aborted.
pub fn run_campaigns(
    config: &Config,
    strategies: &[EveStrategy],
    campaigns: u32,
) -> Result<Campaign, LabError> {
    run_campaigns_with(config, strategies, campaigns, &mut SessionBank::new())
}

/// [`run_campaigns`] on the sessions of `bank` (simulating those it lacks).
///
/// # Errors
/// As [`run_campaigns`].
pub fn run_campaigns_with(
    config: &Config,
    strategies: &[EveStrategy],
    campaigns: u32,
    bank: &mut SessionBank,
) -> Result<Campaign, LabError> {
    if let Some(s) = strategies
        .iter()
        .find(|s| s.mode() != SensingMode::Odometry || config.sensing.mode != SensingMode::Odometry)
    {
        return Err(LabError::SensingMode(format!(
            "eavesdropping campaigns follow the odometry mode's learning eavesdroppers; the {} \
             eavesdropper in sensing.mode = {} does not apply (allowed: oracle, mismatch, soft, \
             identify, transcript in odometry mode)",
            s.name(),
            config.sensing.mode.name()
        )));
    }
    let per = config.eve.sessions;
    let heard = bank.heard(config, campaigns.saturating_mul(per))?;
    let jobs: Vec<(u32, EveStrategy)> = (0..campaigns)
        .flat_map(|c| strategies.iter().map(move |&s| (c, s)))
        .collect();
    let mut all: Vec<StrategyRun> = jobs
        .par_iter()
        .map(|&(c, strategy)| {
            let sessions = heard.slice((c * per) as usize..((c + 1) * per) as usize);
            listen(config, strategy, c, sessions)
        })
        .collect();
    let runs = all[..strategies.len().min(all.len())].to_vec();
    for run in &mut all {
        run.periods = Vec::new();
    }
    Ok(Campaign {
        config: config.clone(),
        runs,
        all,
        steps_per_session: SessionPlan::from_config(config, 0).agreed.steps,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The largest of her relative errors on r and D at the end of each session.
    fn end_of_session_errors(run: &StrategyRun) -> Vec<f64> {
        let mut ends = vec![f64::NAN; run.sessions.len()];
        for p in &run.periods {
            ends[p.session as usize] = p.r_error.abs().max(p.d_error.abs());
        }
        ends
    }

    #[test]
    fn the_identifying_eve_learns_r_and_d_to_one_percent_in_two_sessions() {
        let config = Config::default();
        let mut bank = SessionBank::new();
        let heard = bank.heard(&config, 10).unwrap();
        let run = listen(&config, EveStrategy::Identify, 0, heard);
        assert!(run.start[..2].iter().all(|e| (e.abs() - 0.4).abs() < 1e-12));
        let ends = end_of_session_errors(&run);
        // Seed 2023: 2.2 % after the first session, within 1 % from the second on.
        assert!(ends[0] > 0.01, "{ends:?}");
        assert!(ends[1..].iter().all(|&e| e < 0.01), "{ends:?}");
        // What she learned makes her keys the controller's.
        assert!(
            run.sessions[1..]
                .iter()
                .all(|s| s.disagreement_pct.is_some_and(|d| d < 1.0)),
            "{:?}",
            run.sessions
        );
    }

    #[test]
    fn strategies_do_not_depend_on_the_worker_count() {
        let mut config = Config::default();
        config.eve.sessions = 2;
        let strategies = [EveStrategy::Soft, EveStrategy::Transcript];
        let one = crate::run::with_jobs(1, || run_campaigns(&config, &strategies, 2))
            .unwrap()
            .unwrap();
        let two = crate::run::with_jobs(2, || run_campaigns(&config, &strategies, 2))
            .unwrap()
            .unwrap();
        assert_eq!(one.campaigns(), 2);
        assert_eq!(one, two);
    }
}
