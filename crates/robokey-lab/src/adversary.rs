//! `robokey eve`: every eavesdropper strategy fed the same simulated sessions in order, so
//! that what the learning ones learn carries over (SECRECY §6). Reports each one's windowed
//! error rate against the controller's, her parameter error over time, how long she needs
//! to match the controller, and her disagreement with `K_c` per session.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use robokey::Config;
use robokey::config::EveStrategy;
use robokey::eve::{Eavesdropper, Eve, starting_errors};
use robokey::protocol::{KeyBits, Message, Outcome, SessionPlan};
use robokey::rng::{Purpose, stream};
use robokey::sim::{RunOutput, simulate_transcript};
use serde::Serialize;

use crate::error::LabError;
use crate::files::write;
use crate::plot::{LineChart, Series, SeriesStyle};
use crate::runner::progress_bar;

/// One simulated session: what happened, and every message in the order Eve heard it.
#[derive(Debug)]
pub struct HeardSession {
    /// The run (true bits, the controller's decisions, the keys).
    pub run: RunOutput,
    /// The messages.
    pub transcript: Vec<Message>,
}

/// Simulates sessions `0..sessions` of `config` (replicate = session id), in parallel.
///
/// # Errors
/// A session aborted.
pub fn simulate_sessions(config: &Config, sessions: u32) -> Result<Vec<HeardSession>, LabError> {
    let bar = progress_bar(sessions as usize, "sessions");
    let heard = (0..sessions)
        .into_par_iter()
        .map(|session| {
            let (run, transcript) = simulate_transcript(config, session)?;
            bar.inc(1);
            Ok(HeardSession { run, transcript })
        })
        .collect();
    bar.finish_and_clear();
    heard
}

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

/// Everything one strategy did over the sessions.
#[derive(Clone, Debug, Serialize)]
pub struct StrategyRun {
    /// The strategy.
    pub strategy: EveStrategy,
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
}

/// Eve's starting point for `strategy` under `config`: her errors drawn from the `eve`
/// stream of replicate 0, so every consumer of the same config meets the same Eve.
#[must_use]
pub fn eavesdropper(config: &Config, strategy: EveStrategy) -> Eve {
    let mut config = config.clone();
    config.eve.strategy = strategy;
    let errors = starting_errors(&config, &mut stream(config.run.seed, Purpose::Eve, 0));
    Eve::new(&config, strategy, errors)
}

/// Feeds `eve` one session (session id `index`) and returns her key; calls `on_decision`
/// with every step she decided.
pub fn overhear(
    eve: &mut Eve,
    config: &Config,
    index: u32,
    transcript: &[Message],
    mut on_decision: impl FnMut(&Eve, u32, Option<u8>),
) -> KeyBits {
    eve.begin_session(&SessionPlan::from_config(config, index));
    for message in transcript {
        if let Some(decision) = eve.observe(message) {
            on_decision(eve, decision.step, decision.bit);
        }
    }
    eve.key()
}

/// Feeds one strategy every session in order.
#[must_use]
pub fn listen(config: &Config, strategy: EveStrategy, heard: &[HeardSession]) -> StrategyRun {
    let mut eve = eavesdropper(config, strategy);
    let errors = eve.errors();
    let truth = (config.robot.r, config.robot.axle_length);
    let mut periods = Vec::new();
    let mut sessions = Vec::new();
    let mut elapsed = 0u64;
    for (index, session) in heard.iter().enumerate() {
        let index = index as u32;
        let steps = &session.run.steps;
        let k_a = overhear(
            &mut eve,
            config,
            index,
            &session.transcript,
            |eve, step, bit| {
                let logged = steps.get(step as usize);
                if let (Some(eve_bit), Some(logged)) = (bit, logged)
                    && let (Some(bit), Some(controller)) = (logged.bit, logged.bhat)
                {
                    let model = eve.model();
                    periods.push(PeriodRecord {
                        session: index,
                        step,
                        period: elapsed + u64::from(step) + 1,
                        bit,
                        controller,
                        eve: eve_bit,
                        r_error: model.wheel_radius / truth.0 - 1.0,
                        d_error: model.axle_length / truth.1 - 1.0,
                    });
                }
            },
        );
        elapsed += steps.len() as u64;
        let k_c = &session.run.keys.controller;
        let wrong = k_c.iter().zip(k_a.iter()).filter(|(c, a)| c != a).count()
            + k_c.len().abs_diff(k_a.len());
        sessions.push(SessionRecord {
            session: index,
            key_bits: k_c.len(),
            disagreement_pct: (!k_c.is_empty()).then(|| 100.0 * wrong as f64 / k_c.len() as f64),
            tag_flips: eve.verified(),
            confirmed: session.run.controller_outcome == Some(Outcome::Confirmed),
        });
    }
    let match_period = match_period(
        &periods,
        config.eve.window as usize,
        config.eve.match_tolerance_pp,
    );
    StrategyRun {
        strategy,
        start: [errors.r, errors.d, errors.w, errors.v],
        periods,
        sessions,
        match_period,
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
    /// One run per strategy, in the order asked.
    pub runs: Vec<StrategyRun>,
    /// Periods `N` of one session.
    pub steps_per_session: u32,
}

/// Simulates `config.eve.sessions` sessions and feeds them to every strategy (strategies
/// in parallel, each one's sessions in order).
///
/// # Errors
/// A session aborted.
pub fn run_campaign(config: &Config, strategies: &[EveStrategy]) -> Result<Campaign, LabError> {
    let heard = simulate_sessions(config, config.eve.sessions)?;
    let runs = strategies
        .par_iter()
        .map(|&strategy| listen(config, strategy, &heard))
        .collect();
    Ok(Campaign {
        config: config.clone(),
        runs,
        steps_per_session: SessionPlan::from_config(config, 0).steps,
    })
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

/// `sessions.csv`: per strategy and session, her disagreement with `K_c`.
#[must_use]
pub fn sessions_csv(campaign: &Campaign) -> String {
    let mut csv =
        String::from("strategy,session,key_bits,disagreement_pct,tag_flips,controller_confirmed\n");
    for run in &campaign.runs {
        for s in &run.sessions {
            let _ = writeln!(
                csv,
                "{},{},{},{},{},{}",
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
        "# Eavesdroppers over {} sessions\n\n{}",
        campaign.config.eve.sessions,
        campaign_body(campaign, "")
    )
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
        config.protocol.delta_omega,
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
    if let Some((pct, name, session)) = worst {
        let _ = writeln!(
            md,
            "\nThe largest disagreement of any strategy with any session's K_c is {pct:.2} % ({name}, session {}). \
             A session makes one key: an eavesdropper who matches the controller within a session hears that key, \
             and every later one, as well as the controller does.",
            session + 1
        );
    }
    let _ = write!(
        md,
        "\n![error rates]({figures}eve-error-rate.svg)\n\n![parameter error]({figures}eve-parameters.svg)\n"
    );
    md
}

fn chart(base: &Path, chart: &LineChart) -> Result<Vec<PathBuf>, LabError> {
    chart.save(base).map_err(|e| LabError::Plot {
        path: base.to_path_buf(),
        message: e.to_string(),
    })
}

/// Writes `periods.csv`, `sessions.csv`, `summary.json`, `report.md` and the figures
/// `eve-error-rate` and `eve-parameters` into `dir`; returns the files.
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
    });
    let mut files = vec![
        write(&dir.join("periods.csv"), periods_csv(campaign))?,
        write(&dir.join("sessions.csv"), sessions_csv(campaign))?,
        write(
            &dir.join("summary.json"),
            serde_json::to_string_pretty(&summary).expect("JSON serializes") + "\n",
        )?,
        write(&dir.join("report.md"), campaign_markdown(campaign))?,
    ];
    let window = campaign.config.eve.window as usize;
    let mut series: Vec<Series> = campaign
        .runs
        .iter()
        .map(|run| Series {
            label: run.strategy.name().into(),
            points: windowed_error_rates(&run.periods, window)
                .iter()
                .map(|&(period, eve, _)| (period as f64, eve))
                .collect(),
            style: SeriesStyle::Line,
        })
        .collect();
    if let Some(run) = campaign.runs.first() {
        series.push(Series {
            label: "controller".into(),
            points: windowed_error_rates(&run.periods, window)
                .iter()
                .map(|&(period, _, controller)| (period as f64, controller))
                .collect(),
            style: SeriesStyle::Dashed,
        });
    }
    files.extend(chart(
        &dir.join("eve-error-rate"),
        &LineChart {
            title: format!("Bit error rate over the last {window} periods"),
            x_label: "periods heard".into(),
            y_label: "error rate (%)".into(),
            series,
            equal_aspect: false,
        },
    )?);
    let learners: Vec<&StrategyRun> = campaign
        .runs
        .iter()
        .filter(|r| matches!(r.strategy, EveStrategy::Identify | EveStrategy::Transcript))
        .collect();
    let parameter_series = learners
        .iter()
        .flat_map(|run| {
            let name = run.strategy.name();
            [
                Series {
                    label: format!("{name}: |r error|"),
                    points: run
                        .periods
                        .iter()
                        .map(|p| (p.period as f64, 100.0 * p.r_error.abs()))
                        .collect(),
                    style: SeriesStyle::Line,
                },
                Series {
                    label: format!("{name}: |D error|"),
                    points: run
                        .periods
                        .iter()
                        .map(|p| (p.period as f64, 100.0 * p.d_error.abs()))
                        .collect(),
                    style: SeriesStyle::Dashed,
                },
            ]
        })
        .collect::<Vec<_>>();
    if !parameter_series.is_empty() {
        files.extend(chart(
            &dir.join("eve-parameters"),
            &LineChart {
                title: "Identified wheel geometry: relative error".into(),
                x_label: "periods heard".into(),
                y_label: "relative error (%)".into(),
                series: parameter_series,
                equal_aspect: false,
            },
        )?);
    }
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
        let heard = simulate_sessions(&config, 10).unwrap();
        let run = listen(&config, EveStrategy::Identify, &heard);
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
