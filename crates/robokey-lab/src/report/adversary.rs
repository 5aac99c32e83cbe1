//! Renders an eavesdropping campaign ([`Campaign`], docs/threat-model.md): each strategy's
//! windowed error rate against the controller's, her parameter error over time, how long
//! she needs to match the controller, and her disagreement with `K_c` per session — as CSV,
//! `summary.json`, markdown and figures.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use robokey::config::EveStrategy;

use crate::adversary::{Campaign, PeriodRecord, StrategyRun, windowed_error_rates};
use crate::error::LabError;
use crate::output::write;
use crate::plot::{LineChart, Panel, Panels, Series, SeriesStyle};

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
    let level =
        |label: String, y: f64| Series::reference(label, vec![(1.0, y), (periods_heard as f64, y)]);

    // One panel per strategy, each with the line she is measured against (the
    // controller's rate, the tolerance): six step lines in one chart lie on top of each
    // other, while the question each answers is whether she matches him. The reference
    // beneath, hers on top in a colour that stands out from it.
    let panels = |title: String, y_label: &str, hers: Vec<Series>, against: Series| Panels {
        title,
        x_label: "periods heard".into(),
        y_label: y_label.into(),
        panels: hers
            .into_iter()
            .map(|eve| Panel {
                title: eve.label.clone(),
                series: vec![
                    Series {
                        color: Some(3),
                        ..against.clone()
                    },
                    Series {
                        color: Some(1),
                        ..Series::new("Eve", eve.points, SeriesStyle::Line)
                    },
                ],
            })
            .collect(),
        log_y: false,
    };
    let controller: Vec<(f64, f64)> = rates
        .first()
        .map(|first| first.iter().map(|r| (r.0 as f64, r.2)).collect())
        .unwrap_or_default();
    let tolerance = campaign.config.eve.match_tolerance_pp;
    let mut files = Vec::new();
    for (name, figure) in [
        (
            "eve-error-rate",
            panels(
                format!("Bit error rate over the last {window} periods"),
                "error rate (%)",
                per_strategy(|r| r.1),
                Series::new("controller", controller, SeriesStyle::Dashed),
            ),
        ),
        (
            "eve-excess-error",
            panels(
                format!("Her error rate minus the controller's, last {window} periods"),
                "excess error rate (percentage points)",
                per_strategy(|r| r.1 - r.2),
                level(format!("tolerance ({tolerance} pp)"), tolerance),
            ),
        ),
    ] {
        if figure
            .panels
            .iter()
            .flat_map(|p| &p.series)
            .any(|s| !s.points.is_empty())
        {
            let base = dir.join(name);
            files.extend(figure.save(&base).map_err(|e| LabError::Plot {
                path: base.clone(),
                message: e.to_string(),
            })?);
        }
    }
    let learners: Vec<&StrategyRun> = campaign
        .runs
        .iter()
        .filter(|r| matches!(r.strategy, EveStrategy::Identify | EveStrategy::Transcript))
        .collect();
    let mut parameters: Vec<Series> = learners
        .iter()
        .flat_map(|run| {
            let name = run.strategy.name();
            // Her guess before the first period heard (period 0), then after each period.
            let error_of = |label: String, style, start: f64, pick: fn(&PeriodRecord) -> f64| {
                let after = run
                    .periods
                    .iter()
                    .map(|p| (p.period as f64, 100.0 * pick(p).abs()));
                let points = std::iter::once((0.0, 100.0 * start.abs()))
                    .chain(after)
                    .collect();
                line(label, points, style)
            };
            [
                error_of(format!("{name}: r"), SeriesStyle::Line, run.start[0], |p| {
                    p.r_error
                }),
                error_of(
                    format!("{name}: D"),
                    SeriesStyle::Dashed,
                    run.start[1],
                    |p| p.d_error,
                ),
            ]
        })
        .collect();
    if !learners.is_empty() {
        // Where each learner starts: her guess before the first period (period 0).
        let mut starts: Vec<(f64, f64)> = Vec::new();
        for run in &learners {
            for error in &run.start[..2] {
                let point = (0.0, 100.0 * error.abs());
                if !starts.contains(&point) {
                    starts.push(point);
                }
            }
        }
        parameters.push(Series::new(
            "start: her guess before period 1",
            starts,
            SeriesStyle::Markers,
        ));
        parameters.push(level("1 %".into(), 1.0));
    }
    let charts = [(
        "eve-parameters",
        "Identified wheel geometry: |relative error|".to_owned(),
        "relative error (%, log scale)",
        parameters,
        true,
    )];
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

/// Renders `campaign` into `dir`: `periods.csv` and `sessions.csv` (campaign 0),
/// `campaigns.csv`, `summary.json`, `report.md` and the figures (`eve-error-rate`,
/// `eve-excess-error`, `eve-parameters`); returns the files.
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
