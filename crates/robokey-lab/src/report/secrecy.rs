//! Renders the secrecy stage of a sweep folder ([`Secrecy`]): `secrecy.csv`, `secrecy.md`
//! (with the private-sensing section and map, and `turn-rates.csv`, when the sweep has one)
//! and the figures.

use std::path::{Path, PathBuf};

use super::private::{PrivateRow, map_markdown, private_markdown, turn_rates_csv, write_map};
use super::rate_map::write_rates;
use crate::csv_field::quoted;
use crate::error::LabError;
use crate::experiment::{Experiment, axis_label, param_label, param_number};
use crate::output::write;
use crate::parquet_table::{TableFormat, write_parquet};
use crate::plot::{LineChart, Series, SeriesStyle};
use crate::secrecy::pipeline::H_MIN_BINOMIAL;
use crate::secrecy::rate_map::rate_map;
use crate::secrecy::table::{SECRECY_COLUMNS, SecrecyValue, secrecy_columns};
use crate::secrecy::{Block, PointSecrecy, Pooling, Rate, Secrecy};

/// Sums a block field over a row's blocks.
fn total(r: &PointSecrecy, field: fn(&Block) -> u64) -> u64 {
    r.blocks.iter().map(field).sum()
}

/// `secrecy.csv`: one row per point and adversary, the columns of [`SECRECY_COLUMNS`].
#[must_use]
pub fn secrecy_csv(results: &[PointSecrecy]) -> String {
    let names: Vec<&str> = SECRECY_COLUMNS.iter().map(|c| c.name).collect();
    let mut out = names.join(",") + "\n";
    for r in results {
        let cells: Vec<String> = SECRECY_COLUMNS
            .iter()
            .map(|c| match (c.value)(r) {
                SecrecyValue::Real(x) => x.map_or_else(String::new, |x| x.to_string()),
                SecrecyValue::Count(n) => n.to_string(),
                SecrecyValue::Flag(b) => b.to_string(),
                SecrecyValue::Name(name) => name,
                SecrecyValue::Text(text) => quoted(&text),
            })
            .collect();
        out.push_str(&cells.join(","));
        out.push('\n');
    }
    out
}

fn percent(x: &Option<Rate>) -> String {
    x.map_or("–".into(), |x| {
        format!(
            "{:.2} [{:.2}, {:.2}]",
            100.0 * x.rate,
            100.0 * x.low,
            100.0 * x.high
        )
    })
}

/// A markdown section for `report.md`: the structural verdict first, then one row per
/// point and adversary (strongest first), each naming whom it holds against.
#[must_use]
pub fn secrecy_markdown(secrecy: &Secrecy) -> String {
    let results = &secrecy.results;
    let mut md = String::new();
    if let Some(reason) = results.iter().find_map(|r| r.structural_zero.as_deref()) {
        md.push_str(&format!(
            "**Secret key rate: 0.** The configuration yields no secret key, {reason}. \
             Figures against a restricted adversary hold only if nobody learns r and D.\n\n"
        ));
    }
    if let Some(first) = results.first().filter(|r| r.structural_zero.is_none()) {
        md.push_str(&format!(
            "Key length from the stated assumption: {}.\n\n",
            first.assumption
        ));
    }
    md.push_str(
        "The realised columns are a diagnostic from each adversary's own view (approximation), \
         never what sizes the key.\n\n",
    );
    md.push_str(
        "| point | adversary (class) | p_c % | p_e % | raw bits/step | Eve wrong on raw-key bits % | messages | leak_EC | leak_conf | secret bits/step (assumption) | realised H_min | realised ℓ | why zero |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in results {
        let realised: f64 = r.blocks.iter().map(|b| b.realised.h_min).sum();
        let warning = if r.assumption_exceeds_realised {
            " **the assumption credits more than this adversary's realised view supports**"
        } else {
            ""
        };
        md.push_str(&format!(
            "| {} | {} ({}) | {} | {} | {:.4} | {} | {} | {} | {} | {:.5} | {:.2} | {}{} | {} |\n",
            r.point,
            r.adversary,
            r.adversary_class.name(),
            percent(&r.p_c),
            percent(&r.p_e),
            r.raw_bits_per_step,
            percent(&r.eve_error_accepted),
            total(r, |b| u64::from(b.messages)),
            total(r, |b| b.leak_ec),
            total(r, |b| b.leak_confirmation),
            r.secret_bits_per_step,
            realised,
            r.realised_secret_bits,
            warning,
            r.zero_reason.as_deref().unwrap_or("")
        ));
    }
    let pooling = match secrecy.pooling {
        Pooling::Confirmed => {
            "sessions whose key tags matched (today's agents), each pooled session's two directional 128-bit key tags charged, nothing reconciled".to_owned()
        }
        Pooling::Complete if secrecy.reconciliation.is_cascade() => {
            "every completed session, through the post-processing endpoints the agents run: error rate from a disclosed random sample removed from the key, Cascade (biconf) with both sides' parities charged, the block confirmed by two 64-bit tags and committed in two phases".to_owned()
        }
        Pooling::Complete => format!(
            "every completed session, through the post-processing endpoints the agents run: error rate from a disclosed random sample removed from the key, one-way LDPC (the robot's syndrome decoded on the controller's LLRs; {}, split checks in the feedback rounds; H the soft limit) with every syndrome bit and 4 bits for the rounds charged, the block confirmed by two 64-bit tags and committed in two phases",
            robokey_secrecy::ldpc::LdpcSettings::DEFAULT.agreement_term()
        ),
    };
    let mut held: Vec<String> = Vec::new();
    for r in results {
        let line = format!("{} = {}", r.adversary, r.holds_against);
        if !held.contains(&line) {
            held.push(line);
        }
    }
    let method = results
        .iter()
        .find_map(|r| r.blocks.first())
        .map_or(H_MIN_BINOMIAL, |b| b.realised.h_min_method.as_str());
    let p_of = if method == H_MIN_BINOMIAL {
        ", with Eve's error p taken as the one-sided Clopper–Pearson lower bound at level 1 − ε_PE"
    } else {
        ""
    };
    md.push_str(&format!(
        "\nPooling: {pooling}; blocks of at least {} raw bits (whole sessions). Realised H_min: {method}{p_of}. {} = {:e} (the key is {:e}-secret). p_c, p_e: 95 % Clopper–Pearson intervals over applied bits. Whom each row holds against: {}. See docs/secrecy.md.\n",
        secrecy.block_bits,
        secrecy.epsilon_terms(),
        secrecy.epsilon,
        secrecy.epsilon_total(),
        held.join("; "),
    ));
    let rows = private_rows(results);
    if !rows.is_empty() {
        md.push('\n');
        md.push_str(&private_markdown(&rows));
    }
    md
}

/// The rows of `results` that carry private-sensing figures.
fn private_rows(results: &[PointSecrecy]) -> Vec<PrivateRow<'_>> {
    results
        .iter()
        .filter_map(|r| {
            Some(PrivateRow {
                point: &r.point,
                adversary: &r.adversary,
                figures: r.private.as_ref()?,
            })
        })
        .collect()
}

/// Adds `point` to the series labelled `label`, starting it (with `style` and palette
/// colour `color`) if new.
fn push_point(
    series: &mut Vec<Series>,
    label: String,
    point: (f64, f64),
    (style, color): (SeriesStyle, Option<usize>),
) {
    match series.iter_mut().find(|s| s.label == label) {
        Some(s) => s.points.push(point),
        None => series.push(Series {
            color,
            ..Series::new(label, vec![point], style)
        }),
    }
}

/// One key-length curve: a setting of the other axes, the adversaries that give it, its
/// points.
struct KeyCurve {
    setting: String,
    adversaries: Vec<String>,
    points: Vec<(f64, f64)>,
}

/// `label`, followed by `, setting` when there is one.
fn with_setting(label: &str, setting: &str) -> String {
    if setting.is_empty() {
        label.to_owned()
    } else {
        format!("{label}, {setting}")
    }
}

/// The figure of secret bits per robot step, or none without a numeric axis.
///
/// x is the axis with the most values (the first of those), in the units people read; one
/// series per setting of the other axes that vary. Drawn once per setting what is the same
/// for every adversary — the raw agreed bits, and in private sensing the key length, which
/// the stated assumption sizes whoever listens — and per adversary what differs: her key
/// length in the odometry scheme (adversaries giving the same curve share one series), her
/// realised ℓ (from her own view, a diagnostic) in private sensing.
fn bits_per_step_chart(experiment: &Experiment, secrecy: &Secrecy) -> Option<LineChart> {
    let results = &secrecy.results;
    let values = |axis: usize| {
        let mut values: Vec<String> = experiment
            .points
            .iter()
            .filter_map(|p| p.params.get(axis).map(|(_, v)| v.to_string()))
            .collect();
        values.sort();
        values.dedup();
        values.len()
    };
    let axis = (0..experiment.axes.len()).rev().max_by_key(|&a| values(a));
    let varying: Vec<usize> = (0..experiment.axes.len())
        .filter(|&a| Some(a) != axis && values(a) > 1)
        .collect();
    let x_of = |r: &PointSecrecy| {
        let (field, value) = experiment.points[r.point_index].params.get(axis?)?;
        param_number(field, value)
    };
    let setting = |r: &PointSecrecy| {
        let params = &experiment.points[r.point_index].params;
        varying
            .iter()
            .filter_map(|&a| params.get(a).map(|(f, v)| param_label(f, v)))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let per_step =
        |bits: u64, r: &PointSecrecy| (r.used_steps > 0).then(|| bits as f64 / r.used_steps as f64);
    let assumed = results.iter().any(|r| r.private.is_some());
    // Key length: per setting, the adversaries whose curves coincide named together.
    let mut contexts: Vec<String> = Vec::new();
    for r in results.iter().filter(|r| x_of(r).is_some()) {
        let context = setting(r);
        if !contexts.contains(&context) {
            contexts.push(context);
        }
    }
    // With several settings, each has one colour (its key length, realised ℓ and raw bits
    // told apart by line and marker); with one, every series has its own.
    let colour = |context: &str| {
        (contexts.len() > 1)
            .then(|| contexts.iter().position(|c| c == context))
            .flatten()
    };
    let mut keys: Vec<KeyCurve> = Vec::new();
    for context in contexts.clone() {
        let mut by_adversary: Vec<Series> = Vec::new();
        for r in results.iter().filter(|r| setting(r) == context) {
            if let Some(x) = x_of(r) {
                let adversary = format!("{} ({})", r.adversary, r.adversary_class.name());
                let point = (x, r.secret_bits_per_step);
                push_point(
                    &mut by_adversary,
                    adversary,
                    point,
                    (SeriesStyle::Line, None),
                );
            }
        }
        for curve in by_adversary {
            match keys
                .iter_mut()
                .find(|k| k.setting == context && k.points == curve.points)
            {
                Some(k) => k.adversaries.push(curve.label),
                None => keys.push(KeyCurve {
                    setting: context.clone(),
                    adversaries: vec![curve.label],
                    points: curve.points,
                }),
            }
        }
    }
    let mut series: Vec<Series> = keys
        .into_iter()
        .map(|k| {
            let label = if assumed {
                "key length ℓ from the stated assumption (sizes the key, whoever listens)"
                    .to_owned()
            } else {
                format!("vs {} Eve", k.adversaries.join(", "))
            };
            Series {
                color: colour(&k.setting),
                ..Series::new(
                    with_setting(&label, &k.setting),
                    k.points,
                    SeriesStyle::Line,
                )
            }
        })
        .collect();
    if assumed {
        for r in results {
            let (Some(x), Some(y)) = (x_of(r), per_step(r.realised_secret_bits, r)) else {
                continue;
            };
            let label = format!(
                "realised ℓ from {} Eve's own view (diagnostic)",
                r.adversary
            );
            let context = setting(r);
            push_point(
                &mut series,
                with_setting(&label, &context),
                (x, y),
                (SeriesStyle::Markers, colour(&context)),
            );
        }
    }
    for r in results
        .iter()
        .filter(|r| r.adversary == results[0].adversary)
    {
        if let Some(x) = x_of(r) {
            let context = setting(r);
            push_point(
                &mut series,
                with_setting("raw agreed bits", &context),
                (x, r.raw_bits_per_step),
                (SeriesStyle::Dashed, colour(&context)),
            );
        }
    }
    series
        .iter()
        .any(|s| !s.points.is_empty())
        .then(|| LineChart {
            title: format!(
                "Secret bits per robot step (ε = {:e}, blocks of {} bits)",
                4.0 * secrecy.epsilon,
                secrecy.block_bits
            ),
            x_label: axis.map_or_else(
                || "point".to_owned(),
                |a| axis_label(&experiment.axes[a].field),
            ),
            y_label: "bits per robot step".into(),
            series,
            equal_aspect: false,
            log_y: false,
        })
}

/// Renders `secrecy` (of `experiment`'s points) into `dir`: `secrecy.csv` (or, in
/// `format` Parquet, `secrecy.parquet`), `secrecy.md`, the figure
/// `secrecy-bits-per-step.{svg,png,pdf,csv}`, and in private sensing the map's figures,
/// `turn-rates.csv` and, over a `protocol.*` axis, the rate map (`private-rates.*`); returns
/// the files.
///
/// # Errors
/// A file cannot be written.
pub fn write_secrecy(
    dir: &Path,
    experiment: &Experiment,
    secrecy: &Secrecy,
    format: TableFormat,
) -> Result<Vec<PathBuf>, LabError> {
    std::fs::create_dir_all(dir).map_err(crate::error::io_at(dir))?;
    let results = &secrecy.results;
    let map = secrecy.map.as_ref();
    let table = match format {
        TableFormat::Csv => write(&dir.join("secrecy.csv"), secrecy_csv(results))?,
        TableFormat::Parquet => write_parquet(
            &dir.join("secrecy.parquet"),
            &secrecy_columns(results),
            &[
                ("robokey.epsilon", secrecy.epsilon.to_string()),
                ("robokey.block_bits", secrecy.block_bits.to_string()),
                ("robokey.pooling", secrecy.pooling.name().to_owned()),
            ],
        )?,
    };
    let mut files = vec![
        table,
        write(
            &dir.join("secrecy.md"),
            secrecy_markdown(secrecy)
                + &map.map_or_else(String::new, |m| {
                    map_markdown(m, secrecy.block_bits, secrecy.epsilon)
                })
                + &super::world::over_claim_markdown(&super::world::over_claims(
                    experiment, results,
                )),
        )?,
    ];
    if let Some(map) = map {
        files.extend(write_map(dir, map, secrecy.block_bits, secrecy.epsilon)?);
    }
    if let Some(rates) = rate_map(experiment, results) {
        files.extend(write_rates(dir, &rates)?);
    }
    files.extend(super::world::write_over_claims(dir, experiment, results)?);
    let rows = private_rows(results);
    if !rows.is_empty() {
        files.push(write(&dir.join("turn-rates.csv"), turn_rates_csv(&rows))?);
    }
    if let Some(chart) = bits_per_step_chart(experiment, secrecy) {
        let base = dir.join("secrecy-bits-per-step");
        files.extend(chart.save(&base).map_err(|e| LabError::Plot {
            path: base.clone(),
            message: e.to_string(),
        })?);
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use robokey::config::EveStrategy;

    use super::*;
    use crate::run::sessions::SessionBank;
    use crate::secrecy::SecrecyOptions;

    #[test]
    fn reports_lead_with_the_verdict_and_the_strongest_adversary() {
        let experiment =
            Experiment::from_table("t", "[run]\nreplicates = 1\n".parse().unwrap(), "t.toml")
                .unwrap();
        let options = SecrecyOptions {
            adversaries: vec![EveStrategy::Mismatch, EveStrategy::Oracle],
            block_bits: 500,
            bootstrap: 50,
            ..SecrecyOptions::default()
        };
        let secrecy = Secrecy::compute(&experiment, &options, &mut SessionBank::new()).unwrap();
        let md = secrecy_markdown(&secrecy);
        assert!(md.starts_with("**Secret key rate: 0.**"), "{md}");
        let row = |adversary: &str| md.find(&format!("| {adversary} |")).unwrap();
        assert!(
            row("oracle (strongest)") < row("mismatch (restricted)"),
            "{md}"
        );
        let csv = secrecy_csv(&secrecy.results);
        assert_eq!(csv.lines().count(), 3);
        assert!(
            csv.lines()
                .nth(1)
                .unwrap()
                .starts_with("\"\",oracle,strongest,")
        );
        // secrecy.parquet's columns are secrecy.csv's, cell for cell.
        let columns = secrecy_columns(&secrecy.results);
        let mut reader = csv::Reader::from_reader(csv.as_bytes());
        let header: Vec<&str> = columns.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(reader.headers().unwrap().iter().collect::<Vec<_>>(), header);
        for (row, record) in reader.records().enumerate() {
            let cells: Vec<String> = columns
                .iter()
                .map(|c| c.values.cell(row).unwrap())
                .collect();
            assert_eq!(record.unwrap().iter().collect::<Vec<_>>(), cells);
        }
        let unit = |name: &str| {
            columns
                .iter()
                .find(|c| c.name == name)
                .unwrap()
                .unit
                .as_str()
        };
        assert_eq!((unit("secret_bits"), unit("p_e")), ("bit", "fraction"));
    }
}
