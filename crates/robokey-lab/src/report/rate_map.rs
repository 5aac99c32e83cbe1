//! Renders the rate map ([`crate::secrecy::rate_map`]): `private-rates-table.csv` (one typed
//! row per point), `private-rates.md` (the table) and the figure
//! `private-rates.{svg,png,pdf,csv}` (the CSV of what it draws) — secret bits per step against
//! J_x, one series per alphabet, each point's limit beside it in its colour, and the
//! 1.1 × protocol-off line.

use std::path::{Path, PathBuf};

use super::private::save;
use crate::csv_field::quoted;
use crate::error::LabError;
use crate::output::write;
use crate::plot::{LineChart, Series, SeriesStyle};
use crate::secrecy::rate_map::{RateMap, RatePoint};

/// The tracking cost the maps allow: this many times protocol off's J_x.
pub const TRACKING_ALLOWANCE: f64 = 1.1;

/// The file stem of the map's figure and tables.
pub const RATES_STEM: &str = "private-rates";

/// `private-rates-table.csv`: one line per point.
#[must_use]
pub fn rates_csv(map: &RateMap) -> String {
    let mut out = String::from(
        "point,levels,dimensions,delta_v,delta_omega,secret_bits,realised_bits,leak_ec,\
         secret_bits_per_step,limit_per_step,ratio,margin_v,margin_omega,snr_controller_v,\
         snr_eve_v,snr_controller_omega,snr_eve_omega,kept_fraction,steps_per_doublet,jx_mm,\
         jx_off_mm\n",
    );
    for p in &map.points {
        out.push_str(&format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            quoted(&p.point),
            p.levels,
            p.dimensions,
            p.delta[0],
            p.delta[1],
            p.secret_bits,
            p.realised_bits,
            p.leak_ec,
            p.secret_bits_per_step,
            p.limit_per_step,
            finite_or_empty(p.ratio()),
            p.margin[0],
            p.margin[1],
            p.snr[0][0],
            p.snr[0][1],
            p.snr[1][0],
            p.snr[1][1],
            p.kept_fraction,
            p.steps_per_doublet,
            p.jx_mm,
            p.jx_off_mm,
        ));
    }
    out
}

fn finite_or_empty(x: f64) -> String {
    if x.is_finite() {
        x.to_string()
    } else {
        String::new()
    }
}

/// The map's markdown: what the limit is (the figure at `figure`, relative to the
/// markdown), then [`rates_table`].
#[must_use]
pub fn rates_markdown(map: &RateMap, figure: &str) -> String {
    format!(
        "\n### Secret rate against tracking cost, beside each alphabet's limit\n\n\
         ![rate map]({figure})\n\n\
         Against the camera eavesdropper (the strongest of private sensing); ℓ is sized under \
         the stated assumption ({}), her realised bound beside it. The limit is \
         Σ_dims C × kept fraction ÷ steps per doublet, with C = I(X; Y_c) − I(X; Y_e) the \
         alphabet's secrecy margin per doublet and dimension through the controller's and the \
         stated camera's Gaussian views on a straight doublet (SNR (d/2)² of their binary \
         separations).\n\n{}",
        map.assumption,
        rates_table(map),
    )
}

/// The protocol-off reference, then one row per point: alphabet, Δ, leak_EC, ℓ ≤ her
/// realised bound, the rate, its limit and their ratio, the margins, J_x.
#[must_use]
pub fn rates_table(map: &RateMap) -> String {
    let allowed = TRACKING_ALLOWANCE * map.jx_off_mm();
    let mut md = format!(
        "J_x with the protocol off: {:.2} mm; {TRACKING_ALLOWANCE}× that is {allowed:.2} mm.\n\n\
         | alphabet | Δv m/s | Δω rad/s | leak_EC | ℓ ≤ her realised | secret bits/step | limit | rate/limit | C_v / C_ω bit | J_x mm |\n\
         |---|---|---|---|---|---|---|---|---|---|\n",
        map.jx_off_mm(),
    );
    for p in &map.points {
        md.push_str(&rate_row(p, allowed));
    }
    md
}

fn rate_row(p: &RatePoint, allowed: f64) -> String {
    let ratio = p.ratio();
    format!(
        "| {} | {} | {} | {} | {} ≤ {} | {:.3} | {:.3} | {} | {:.3} / {:.3} | {:.2}{} |\n",
        p.alphabet(),
        p.delta[0],
        if p.dimensions == 2 {
            p.delta[1].to_string()
        } else {
            "–".into()
        },
        p.leak_ec,
        p.secret_bits,
        p.realised_bits,
        p.secret_bits_per_step,
        p.limit_per_step,
        if ratio.is_finite() {
            format!("{ratio:.2}")
        } else {
            "–".into()
        },
        p.margin[0],
        p.margin[1],
        p.jx_mm,
        if p.jx_mm > allowed { " (over)" } else { "" },
    )
}

/// Writes `private-rates-table.csv`, `private-rates.md` and the figure into `dir`.
///
/// # Errors
/// A file cannot be written.
pub fn write_rates(dir: &Path, map: &RateMap) -> Result<Vec<PathBuf>, LabError> {
    let mut files = vec![
        write(&dir.join(format!("{RATES_STEM}-table.csv")), rates_csv(map))?,
        write(
            &dir.join(format!("{RATES_STEM}.md")),
            rates_markdown(map, &format!("{RATES_STEM}.svg")),
        )?,
    ];
    let mut alphabets: Vec<(u8, u8)> = map
        .points
        .iter()
        .map(|p| (p.dimensions, p.levels))
        .collect();
    alphabets.dedup();
    let mut series = Vec::new();
    for (i, &(dimensions, levels)) in alphabets.iter().enumerate() {
        let of: Vec<&RatePoint> = map
            .points
            .iter()
            .filter(|p| (p.dimensions, p.levels) == (dimensions, levels))
            .collect();
        let mut rates: Vec<(f64, f64)> = of
            .iter()
            .map(|p| (p.jx_mm, p.secret_bits_per_step))
            .collect();
        rates.sort_by(|a, b| a.0.total_cmp(&b.0));
        let name = of[0].alphabet();
        series.push(Series {
            color: Some(i),
            ..Series::new(name.clone(), rates, SeriesStyle::Line)
        });
        series.push(Series {
            color: Some(i),
            ..Series::new(
                format!("limit, {name}"),
                of.iter().map(|p| (p.jx_mm, p.limit_per_step)).collect(),
                SeriesStyle::Markers,
            )
        });
    }
    let top = map
        .points
        .iter()
        .map(|p| p.limit_per_step.max(p.secret_bits_per_step))
        .fold(0.0, f64::max);
    let allowed = TRACKING_ALLOWANCE * map.jx_off_mm();
    series.push(Series::reference(
        format!("{TRACKING_ALLOWANCE}× protocol off's J_x ({allowed:.2} mm)"),
        vec![(allowed, 0.0), (allowed, top)],
    ));
    let chart = LineChart {
        title: "Secret bits per step against tracking cost, each alphabet beside its limit".into(),
        x_label: "tracking error Jₓ (mm)".into(),
        y_label: "secret bits per robot step".into(),
        series,
        equal_aspect: false,
        log_y: false,
    };
    files.extend(save(&chart, &dir.join(RATES_STEM))?);
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(levels: u8, rate: f64, limit: f64, jx: f64) -> RatePoint {
        RatePoint {
            point: format!("protocol.levels = {levels}"),
            levels,
            dimensions: 2,
            delta: [0.035, 0.035],
            secret_bits: 40_000,
            realised_bits: 44_000,
            leak_ec: 25_000,
            secret_bits_per_step: rate,
            jx_mm: jx,
            jx_off_mm: 12.0,
            kept_fraction: 0.9,
            steps_per_doublet: 2,
            snr: [[5.0, 0.7], [4.0, 0.6]],
            margin: [0.9, 0.8],
            limit_per_step: limit,
        }
    }

    #[test]
    fn rows_say_rate_limit_and_whether_tracking_is_over() {
        let map = RateMap {
            points: vec![point(2, 0.5, 0.55, 13.0), point(4, 0.7, 0.0, 13.5)],
            assumption: "camera 8 mm".into(),
        };
        let md = rates_markdown(&map, "private-rates.svg");
        assert!(md.contains("1.1× that is 13.20 mm"), "{md}");
        assert!(
            md.contains(
                "| 2-level, 2 dims | 0.035 | 0.035 | 25000 | 40000 ≤ 44000 | 0.500 | 0.550 | 0.91 |"
            ),
            "{md}"
        );
        assert!(md.contains("| 0.700 | 0.000 | – |"), "{md}");
        assert!(md.contains("13.50 (over) |"), "{md}");
        let csv = rates_csv(&map);
        let mut reader = csv::Reader::from_reader(csv.as_bytes());
        let rows: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
        assert_eq!(rows.len(), 2);
        assert_eq!(&rows[1][10], "", "no ratio without a limit");
        let ratio: f64 = rows[0][10].parse().unwrap();
        assert!((ratio - 0.5 / 0.55).abs() < 1e-12);
    }
}
