//! `robokey eve`: every eavesdropper strategy fed the same simulated sessions in order, so
//! that what the learning ones learn carries over (docs/threat-model.md). Reports each one's windowed
//! error rate against the controller's, her parameter error over time, how long she needs
//! to match the controller, and her disagreement with `K_c` per session.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use robokey::Config;
use robokey::config::{EveStrategy, SensingMode};
use robokey::eve::{Eavesdropper, Eve, starting_errors};
use robokey::protocol::{KeyBits, Message, Outcome, SessionPlan, StepDecision};
use robokey::rng::{Purpose, stream};
use serde::Serialize;

use crate::error::LabError;
use crate::files::write;
use crate::plot::{LineChart, Series, SeriesStyle};
use crate::sessions::{Heard, SessionBank};

/// One decided period, as one strategy saw it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PeriodRecord {
    /// Session index.
    pub session: u32,
    /// Step within the session.
    pub step: u32,
    /// Periods heard since her first session began (`session·N + step + 1`).
    pub period: u64,
    /// The applied bit.
    pub bit: u8,
    /// The controller's decision.
    pub controller: u8,
    /// Her decision.
    pub eve: u8,
    /// Her relative error on r after this period (fraction).
    pub r_error: f64,
    /// Her relative error on D after this period (fraction).
    pub d_error: f64,
}

/// One session, as one strategy ended it.
#[derive(Clone, Debug, PartialEq, Serialize)]
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
#[derive(Clone, Debug, Serialize)]
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

/// Error rates (%) over the last `window` decided periods, for her and the controller, at
/// every period from the first full window on.
#[must_use]
pub fn windowed_error_rates(periods: &[PeriodRecord], window: usize) -> Vec<(u64, f64, f64)> {
    if window == 0 || periods.len() < window {
        return Vec::new();
    }
    let (mut eve, mut controller) = (0usize, 0usize);
    let mut rates = Vec::with_capacity(periods.len() + 1 - window);
    for (i, p) in periods.iter().enumerate() {
        eve += usize::from(p.eve != p.bit);
        controller += usize::from(p.controller != p.bit);
        if i >= window {
            let old = &periods[i - window];
            eve -= usize::from(old.eve != old.bit);
            controller -= usize::from(old.controller != old.bit);
        }
        if i + 1 >= window {
            let pct = |count: usize| 100.0 * count as f64 / window as f64;
            rates.push((p.period, pct(eve), pct(controller)));
        }
    }
    rates
}

/// The first period from which every windowed error rate of hers is within `tolerance_pp`
/// percentage points above the controller's (`None`: the last window is not).
#[must_use]
pub fn match_period(periods: &[PeriodRecord], window: usize, tolerance_pp: f64) -> Option<u64> {
    let rates = windowed_error_rates(periods, window);
    let within = |&(_, eve, controller): &(u64, f64, f64)| eve - controller <= tolerance_pp + 1e-9;
    let first_after_last_miss = rates.iter().rposition(|r| !within(r)).map_or(0, |i| i + 1);
    rates.get(first_after_last_miss).map(|&(period, ..)| period)
}

/// The result of `robokey eve` in simulation.
#[derive(Debug)]
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

/// One campaign ([`run_campaigns`] with one).
///
/// # Errors
/// A session aborted.
pub fn run_campaign(config: &Config, strategies: &[EveStrategy]) -> Result<Campaign, LabError> {
    run_campaigns(config, strategies, 1)
}

fn percent(value: Option<f64>) -> String {
    value.map_or_else(|| "–".into(), |v| format!("{v:.2}"))
}

/// `periods.csv`: every decided period of every strategy with both windowed error rates.
#[must_use]
pub fn periods_csv(campaign: &Campaign) -> String {
    let window = campaign.config.eve.window as usize;
    let mut csv = String::from(
        "strategy,session,step,period,bit,controller,eve,eve_window_error_pct,controller_window_error_pct,r_error_pct,d_error_pct\n",
    );
    for run in &campaign.runs {
        let rates = windowed_error_rates(&run.periods, window);
        let offset = run.periods.len() + 1 - rates.len().max(1);
        for (i, p) in run.periods.iter().enumerate() {
            let rate = i.checked_sub(offset).and_then(|j| rates.get(j));
            let _ = writeln!(
                csv,
                "{},{},{},{},{},{},{},{},{},{:.4},{:.4}",
                run.strategy.name(),
                p.session,
                p.step,
                p.period,
                p.bit,
                p.controller,
                p.eve,
                rate.map_or(String::new(), |r| format!("{:.2}", r.1)),
                rate.map_or(String::new(), |r| format!("{:.2}", r.2)),
                100.0 * p.r_error,
                100.0 * p.d_error,
            );
        }
    }
    csv
}

/// `sessions.csv`: per campaign, strategy and session, her disagreement with `K_c`.
#[must_use]
pub fn sessions_csv(campaign: &Campaign) -> String {
    let mut csv = String::from(
        "campaign,strategy,session,key_bits,disagreement_pct,tag_flips,controller_confirmed\n",
    );
    for run in &campaign.all {
        for s in &run.sessions {
            let _ = writeln!(
                csv,
                "{},{},{},{},{},{},{}",
                run.campaign,
                run.strategy.name(),
                s.session,
                s.key_bits,
                s.disagreement_pct
                    .map_or(String::new(), |d| format!("{d:.4}")),
                s.tag_flips.map_or(String::new(), |f| f.to_string()),
                s.confirmed,
            );
        }
    }
    csv
}

/// How long a strategy took to match the controller, in words.
fn match_text(run: &StrategyRun, campaign: &Campaign) -> String {
    let window = u64::from(campaign.config.eve.window);
    let per_session = f64::from(campaign.steps_per_session);
    let seconds = campaign.config.robot.sample_time;
    match run.match_period {
        Some(p) if p <= window => format!("≤ {window} (first window)"),
        Some(p) => format!(
            "{p} ({:.0} s, {:.2} sessions)",
            p as f64 * seconds,
            p as f64 / per_session
        ),
        None => format!("not within {} sessions", campaign.runs[0].sessions.len()),
    }
}

/// `report.md` of `robokey eve`.
#[must_use]
pub fn campaign_markdown(campaign: &Campaign) -> String {
    format!(
        "# Eavesdroppers over {} sessions\n\n{}{}",
        campaign.config.eve.sessions,
        campaign_body(campaign, ""),
        campaigns_summary(campaign, "##")
    )
}

/// Median and range of some values, e.g. `1067 (225–5094)`.
fn median_range(mut values: Vec<f64>, digits: usize) -> String {
    if values.is_empty() {
        return "–".into();
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    let median = if n % 2 == 1 {
        values[n / 2]
    } else {
        f64::midpoint(values[n / 2 - 1], values[n / 2])
    };
    format!(
        "{median:.digits$} ({:.digits$}–{:.digits$})",
        values[0],
        values[n - 1]
    )
}

/// Over every campaign (when there are several): per strategy, how often and how fast she
/// matched the controller and identified the model, and her disagreement with `K_c`.
#[must_use]
pub fn campaigns_summary(campaign: &Campaign, heading: &str) -> String {
    let count = campaign
        .all
        .iter()
        .map(|r| r.campaign + 1)
        .max()
        .unwrap_or(0);
    if count < 2 {
        return String::new();
    }
    let mut md = format!(
        "\n{heading} Over {count} independent campaigns\n\nCampaign c hears sessions c·{n} … c·{n} + {last} \
         (replicates of seed {seed}); her starting errors are drawn anew for each. Medians (min–max) over the \
         campaigns where the event happened.\n\n\
         | strategy | matched the controller | periods to match | sessions to r, D within 1 % | disagreement with K_c, first session (mean %) | later sessions (mean %) | keys verified by tag |\n\
         |---|---|---|---|---|---|---|\n",
        n = campaign.config.eve.sessions,
        last = campaign.config.eve.sessions - 1,
        seed = campaign.config.run.seed,
    );
    for strategy in campaign.runs.iter().map(|r| r.strategy) {
        let runs: Vec<&StrategyRun> = campaign
            .all
            .iter()
            .filter(|r| r.strategy == strategy)
            .collect();
        let matched: Vec<f64> = runs
            .iter()
            .filter_map(|r| r.match_period.map(|p| p as f64))
            .collect();
        let modelled: Vec<f64> = runs
            .iter()
            .filter_map(|r| r.sessions_to_model.map(f64::from))
            .collect();
        let mean = |values: Vec<f64>| {
            (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64)
        };
        let disagreement = |first: bool| {
            mean(
                runs.iter()
                    .flat_map(|r| r.sessions.iter())
                    .filter(|s| (s.session == 0) == first)
                    .filter_map(|s| s.disagreement_pct)
                    .collect(),
            )
        };
        let sessions: usize = runs.iter().map(|r| r.sessions.len()).sum();
        let verified = runs
            .iter()
            .flat_map(|r| r.sessions.iter())
            .filter(|s| s.tag_flips.is_some())
            .count();
        let _ = writeln!(
            md,
            "| {} | {}/{count} | {} | {} ({}/{count}) | {} | {} | {verified}/{sessions} |",
            strategy.name(),
            matched.len(),
            median_range(matched, 0),
            median_range(modelled.clone(), 0),
            modelled.len(),
            percent(disagreement(true)),
            percent(disagreement(false)),
        );
    }
    md
}

/// `campaigns.csv`: one row per campaign and strategy.
#[must_use]
pub fn campaigns_csv(campaign: &Campaign) -> String {
    let mut csv = String::from(
        "campaign,strategy,start_r_error_pct,start_d_error_pct,match_period,sessions_to_model,mean_disagreement_pct,keys_verified\n",
    );
    for run in &campaign.all {
        let disagreements: Vec<f64> = run
            .sessions
            .iter()
            .filter_map(|s| s.disagreement_pct)
            .collect();
        let _ = writeln!(
            csv,
            "{},{},{:.2},{:.2},{},{},{},{}",
            run.campaign,
            run.strategy.name(),
            100.0 * run.start[0],
            100.0 * run.start[1],
            run.match_period.map_or(String::new(), |p| p.to_string()),
            run.sessions_to_model
                .map_or(String::new(), |s| s.to_string()),
            if disagreements.is_empty() {
                String::new()
            } else {
                format!(
                    "{:.4}",
                    disagreements.iter().sum::<f64>() / disagreements.len() as f64
                )
            },
            run.sessions
                .iter()
                .filter(|s| s.tag_flips.is_some())
                .count(),
        );
    }
    csv
}

/// The setting, the table, the figures (under `figures`) and what they mean.
#[must_use]
pub fn campaign_body(campaign: &Campaign, figures: &str) -> String {
    let config = &campaign.config;
    let eve = &config.eve;
    let mut md = format!(
        "Δv = {} m/s, Δω = {} rad/s, code {}, seed {}; {} periods of T = {} s per session. Error rates are over \
         the last {} decided periods; Eve matches the controller once hers stays within {} percentage points of \
         the controller's. Every strategy hears the same {} sessions in the same order; each one after `mismatch` \
         adds a capability to the one before.\n\n",
        config.protocol.delta_v,
        config.delta_omega(),
        config.code.build().name(),
        config.run.seed,
        campaign.steps_per_session,
        config.robot.sample_time,
        eve.window,
        eve.match_tolerance_pp,
        eve.sessions,
    );
    md.push_str(
        "| strategy | start error r, D (%) | end error r, D (%) | error rate, last window (%) | controller's (%) | periods to match | disagreement with K_c per session (%) | keys verified by tag |\n|---|---|---|---|---|---|---|---|\n",
    );
    for run in &campaign.runs {
        let rates = windowed_error_rates(&run.periods, eve.window as usize);
        let last = rates.last();
        let end = run.periods.last();
        let disagreements: Vec<String> = run
            .sessions
            .iter()
            .map(|s| percent(s.disagreement_pct))
            .collect();
        let verified = run
            .sessions
            .iter()
            .filter(|s| s.tag_flips.is_some())
            .count();
        let _ = writeln!(
            md,
            "| {} | {:+.1}, {:+.1} | {}, {} | {} | {} | {} | {} | {}/{} |",
            run.strategy.name(),
            100.0 * run.start[0],
            100.0 * run.start[1],
            end.map_or("–".into(), |p| format!("{:+.2}", 100.0 * p.r_error)),
            end.map_or("–".into(), |p| format!("{:+.2}", 100.0 * p.d_error)),
            percent(last.map(|r| r.1)),
            percent(last.map(|r| r.2)),
            match_text(run, campaign),
            disagreements.join(", "),
            verified,
            run.sessions.len(),
        );
    }
    let worst = campaign
        .runs
        .iter()
        .flat_map(|run| {
            run.sessions
                .iter()
                .filter_map(move |s| Some((s.disagreement_pct?, run.strategy.name(), s.session)))
        })
        .max_by(|a, b| a.0.total_cmp(&b.0));
    let _ = writeln!(
        md,
        "\n{} A session makes one key: an eavesdropper who matches the controller within a session hears that \
         key, and every later one, as well as the controller does.",
        match worst {
            Some((pct, name, session)) if pct > 0.0 => format!(
                "The largest disagreement of any strategy with any session's K_c is {pct:.2} % ({name}, session {}).",
                session + 1
            ),
            Some(_) => "No strategy disagrees with any session's K_c on a single bit.".to_owned(),
            None => "No session accepted a codeword.".to_owned(),
        }
    );
    let _ = write!(
        md,
        "\n![error rates]({figures}eve-error-rate.svg)\n\n![excess error]({figures}eve-excess-error.svg)\n\n\
         ![parameter error]({figures}eve-parameters.svg)\n"
    );
    md
}

/// `eve-error-rate` (every strategy and the controller), `eve-excess-error` (hers minus
/// the controller's, with the tolerance) and, for the learning strategies,
/// `eve-parameters` (relative errors on r and D, logarithmic).
fn figures(dir: &Path, campaign: &Campaign) -> Result<Vec<PathBuf>, LabError> {
    let window = campaign.config.eve.window as usize;
    let rates: Vec<Vec<(u64, f64, f64)>> = campaign
        .runs
        .iter()
        .map(|run| windowed_error_rates(&run.periods, window))
        .collect();
    let line = |label: String, points: Vec<(f64, f64)>, style| Series::new(label, points, style);
    let per_strategy = |value: fn(&(u64, f64, f64)) -> f64| -> Vec<Series> {
        campaign
            .runs
            .iter()
            .zip(&rates)
            .map(|(run, rates)| {
                let points = rates.iter().map(|r| (r.0 as f64, value(r))).collect();
                line(run.strategy.name().into(), points, SeriesStyle::Line)
            })
            .collect()
    };
    // A horizontal reference line at `y` across the periods heard.
    let periods_heard = campaign
        .runs
        .first()
        .map_or(0, |run| run.periods.last().map_or(0, |p| p.period));
    let level = |label: String, y: f64| {
        let points = vec![(1.0, y), (periods_heard as f64, y)];
        line(label, points, SeriesStyle::Dashed)
    };

    let mut error_rate = per_strategy(|r| r.1);
    if let Some(first) = rates.first() {
        let points = first.iter().map(|r| (r.0 as f64, r.2)).collect();
        error_rate.push(line("controller".into(), points, SeriesStyle::Dashed));
    }
    let mut excess = per_strategy(|r| r.1 - r.2);
    let tolerance = campaign.config.eve.match_tolerance_pp;
    excess.push(level(format!("tolerance ({tolerance} pp)"), tolerance));
    let learners: Vec<&StrategyRun> = campaign
        .runs
        .iter()
        .filter(|r| matches!(r.strategy, EveStrategy::Identify | EveStrategy::Transcript))
        .collect();
    let mut parameters: Vec<Series> = learners
        .iter()
        .flat_map(|run| {
            let name = run.strategy.name();
            let error_of = |pick: fn(&PeriodRecord) -> f64| {
                run.periods
                    .iter()
                    .map(|p| (p.period as f64, 100.0 * pick(p).abs()))
                    .collect()
            };
            [
                line(
                    format!("{name}: r"),
                    error_of(|p| p.r_error),
                    SeriesStyle::Line,
                ),
                line(
                    format!("{name}: D"),
                    error_of(|p| p.d_error),
                    SeriesStyle::Dashed,
                ),
            ]
        })
        .collect();
    if !learners.is_empty() {
        parameters.push(level("1 %".into(), 1.0));
    }
    let charts = [
        (
            "eve-error-rate",
            format!("Bit error rate over the last {window} periods"),
            "error rate (%)",
            error_rate,
            false,
        ),
        (
            "eve-excess-error",
            format!("Her error rate minus the controller's, last {window} periods"),
            "excess error rate (percentage points)",
            excess,
            false,
        ),
        (
            "eve-parameters",
            "Identified wheel geometry: |relative error|".to_owned(),
            "relative error (%, log scale)",
            parameters,
            true,
        ),
    ];
    let mut files = Vec::new();
    for (name, title, y_label, series, log_y) in charts {
        if series.iter().all(|s| s.points.is_empty()) {
            continue;
        }
        files.extend(chart(
            &dir.join(name),
            &LineChart {
                title,
                x_label: "periods heard".into(),
                y_label: y_label.into(),
                series,
                equal_aspect: false,
                log_y,
            },
        )?);
    }
    Ok(files)
}

fn chart(base: &Path, chart: &LineChart) -> Result<Vec<PathBuf>, LabError> {
    chart.save(base).map_err(|e| LabError::Plot {
        path: base.to_path_buf(),
        message: e.to_string(),
    })
}

/// Writes `periods.csv` and `sessions.csv` (campaign 0), `campaigns.csv`, `summary.json`,
/// `report.md` and the figures (see [`figures`]) into `dir`; returns the files.
///
/// # Errors
/// A file cannot be written.
pub fn write_campaign(dir: &Path, campaign: &Campaign) -> Result<Vec<PathBuf>, LabError> {
    std::fs::create_dir_all(dir).map_err(crate::error::io_at(dir))?;
    let summary = serde_json::json!({
        "sessions": campaign.config.eve.sessions,
        "window": campaign.config.eve.window,
        "match_tolerance_pp": campaign.config.eve.match_tolerance_pp,
        "steps_per_session": campaign.steps_per_session,
        "strategies": campaign.runs,
        "campaigns": campaign.all,
    });
    let mut files = vec![
        write(&dir.join("periods.csv"), periods_csv(campaign))?,
        write(&dir.join("sessions.csv"), sessions_csv(campaign))?,
        write(&dir.join("campaigns.csv"), campaigns_csv(campaign))?,
        write(
            &dir.join("summary.json"),
            serde_json::to_string_pretty(&summary).expect("JSON serializes") + "\n",
        )?,
        write(&dir.join("report.md"), campaign_markdown(campaign))?,
    ];
    files.extend(figures(dir, campaign)?);
    Ok(files)
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
        let one = crate::runner::with_jobs(1, || run_campaign(&config, &strategies))
            .unwrap()
            .unwrap();
        let two = crate::runner::with_jobs(2, || run_campaign(&config, &strategies))
            .unwrap()
            .unwrap();
        assert_eq!(periods_csv(&one), periods_csv(&two));
        assert_eq!(sessions_csv(&one), sessions_csv(&two));
    }

    fn period(period: u64, eve_wrong: bool, controller_wrong: bool) -> PeriodRecord {
        PeriodRecord {
            session: 0,
            step: period as u32 - 1,
            period,
            bit: 1,
            controller: u8::from(!controller_wrong),
            eve: u8::from(!eve_wrong),
            r_error: 0.0,
            d_error: 0.0,
        }
    }

    #[test]
    fn windows_and_the_match_period() {
        // Eve is wrong on periods 1–4, the controller on 2; windows of 4.
        let periods: Vec<PeriodRecord> = (1..=10).map(|p| period(p, p <= 4, p == 2)).collect();
        let rates = windowed_error_rates(&periods, 4);
        assert_eq!(rates.len(), 7);
        assert_eq!(rates[0], (4, 100.0, 25.0));
        assert_eq!(rates[1], (5, 75.0, 25.0));
        assert_eq!(rates[4], (8, 0.0, 0.0));
        // Windows ending at 4–7 hold one of her errors more than the controller's or worse;
        // from 8 on they are equal.
        assert_eq!(match_period(&periods, 4, 0.5), Some(8));
        assert_eq!(match_period(&periods, 4, 25.0), Some(7));
        assert_eq!(match_period(&periods, 4, 100.0), Some(4));
        let late: Vec<PeriodRecord> = (1..=10).map(|p| period(p, p == 10, false)).collect();
        assert_eq!(match_period(&late, 4, 0.5), None);
        assert!(windowed_error_rates(&periods, 11).is_empty());
    }
}
