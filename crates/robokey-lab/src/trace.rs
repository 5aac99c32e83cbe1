//! `trace.csv` and `metrics.json` of one run.

use std::fmt::Write as _;

use robokey::metrics::{MetricValue, Metrics};
use robokey::private::PrivateRun;
use robokey::sim::TraceRow;

/// `trace.csv`: N + 1 rows with exactly the columns of docs/experiments.md; undefined cells empty.
#[must_use]
pub fn trace_csv(rows: &[TraceRow]) -> String {
    let mut out = TraceRow::COLUMNS.join(",");
    out.push('\n');
    for r in rows {
        let cells: Vec<String> = [
            vec![r.k.to_string(), r.t.to_string()],
            floats(Some(&r.reference)),
            floats(Some(&r.pose)),
            floats(Some(&r.measurement)),
            floats_or_empty(r.nominal.as_ref(), 2),
            floats_or_empty(r.u0.as_ref(), 2),
            floats_or_empty(r.u1.as_ref(), 2),
            vec![opt(r.bit)],
            floats_or_empty(r.dhat.as_ref(), 2),
            floats_or_empty(r.xhat.as_ref(), 3),
            vec![opt(r.bhat), opt(r.bhat_eve), opt(r.bit_omega)],
            floats_or_empty(r.camera.as_ref(), 3),
        ]
        .concat();
        out.push_str(&cells.join(","));
        out.push('\n');
    }
    out
}

fn floats(values: Option<&[f64]>) -> Vec<String> {
    values.map_or_else(Vec::new, |v| v.iter().map(f64::to_string).collect())
}

fn floats_or_empty<const N: usize>(values: Option<&[f64; N]>, n: usize) -> Vec<String> {
    values.map_or_else(|| vec![String::new(); n], |v| floats(Some(v)))
}

fn opt<T: ToString>(value: Option<T>) -> String {
    value.map_or_else(String::new, |v| v.to_string())
}

/// A metric value as a CSV cell (empty when undefined).
#[must_use]
pub fn csv_cell(value: MetricValue) -> String {
    match value {
        MetricValue::Real(x) => opt(x),
        MetricValue::Count(n) => opt(n),
        MetricValue::Flag(b) => opt(b),
    }
}

/// A metric value as JSON (`null` when undefined).
#[must_use]
pub fn json_value(value: MetricValue) -> serde_json::Value {
    match value {
        MetricValue::Real(x) => x.map_or(serde_json::Value::Null, serde_json::Value::from),
        MetricValue::Count(n) => n.map_or(serde_json::Value::Null, serde_json::Value::from),
        MetricValue::Flag(b) => b.map_or(serde_json::Value::Null, serde_json::Value::from),
    }
}

/// The metrics as a JSON object in column order.
#[must_use]
pub fn metrics_json(metrics: &Metrics) -> serde_json::Map<String, serde_json::Value> {
    Metrics::names()
        .into_iter()
        .zip(metrics.values().into_iter().map(json_value))
        .collect()
}

/// A human-readable metrics table for the terminal.
#[must_use]
pub fn metrics_table(metrics: &Metrics, private: Option<&PrivateRun>) -> String {
    let mut out = String::new();
    let show = |x: Option<f64>, unit: &str| {
        x.map_or_else(|| "undefined".to_owned(), |x| format!("{x:.3}{unit}"))
    };
    if let Some(p) = private {
        let rows = [
            (
                "doublets",
                format!("{} ({} without a bit: turn-gated)", p.doublets, p.gated),
            ),
            ("raw key bits", p.bits.len().to_string()),
            (
                "controller BER",
                show(metrics.ber_controller.map(|x| 100.0 * x), " %"),
            ),
            ("Eve BER", show(metrics.ber_eve.map(|x| 100.0 * x), " %")),
            ("J_x", show(Some(1000.0 * metrics.jx), " mm")),
            (
                "raw keys equal",
                metrics.key_match.map_or("undefined".into(), |b| {
                    format!("{b} (post-processing reconciles them: robokey secrecy)")
                }),
            ),
        ];
        for (name, value) in rows {
            let _ = writeln!(out, "  {name:<18} {value}");
        }
        return out;
    }
    let rows = [
        (
            "codewords sent",
            metrics.codewords_sent.map_or("-".into(), |n| n.to_string()),
        ),
        (
            "accepted",
            metrics.accepted.map_or("-".into(), |n| n.to_string()),
        ),
        ("accepted %", show(metrics.accepted_pct, " %")),
        ("correct %", show(metrics.correct_pct, " %")),
        (
            "controller BER",
            show(metrics.ber_controller.map(|x| 100.0 * x), " %"),
        ),
        ("Eve BER", show(metrics.ber_eve.map(|x| 100.0 * x), " %")),
        ("J_x", show(Some(1000.0 * metrics.jx), " mm")),
        ("Eve disagreement", show(metrics.eve_disagreement_pct, " %")),
        (
            "K_c = K_r",
            metrics
                .key_match
                .map_or("undefined".into(), |b| b.to_string()),
        ),
    ];
    for (name, value) in rows {
        let _ = writeln!(out, "  {name:<18} {value}");
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trace_has_n_plus_one_rows_and_exact_columns() {
        let run = robokey::sim::simulate(&robokey::Config::default(), 0, true).unwrap();
        let csv = trace_csv(&run.trace);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines.len(), 1 + 1021);
        // docs/experiments.md's 24 columns, then b_omega and Eve's camera (private sensing).
        assert_eq!(lines[0].split(',').count(), 28);
        assert!(lines[0].ends_with(",b_omega,eve_x,eve_y,eve_theta"));
        assert!(lines.iter().all(|l| l.split(',').count() == 28));
        assert!(lines[1..].iter().all(|l| l.ends_with(",,,,")));
        // Row 0 has no decision; the last row has no nominal command and no bit.
        let first: Vec<&str> = lines[1].split(',').collect();
        assert_eq!(first[22], "");
        let last: Vec<&str> = lines[1021].split(',').collect();
        assert_eq!((last[10], last[16]), ("", ""));
        assert_eq!(last[12], "0");
    }

    #[test]
    fn a_private_trace_has_the_camera_and_both_bits() {
        let config = robokey::Config::from_toml(
            "[sensing]\nmode = \"private\"\n[protocol]\nbits_per_doublet = 2\n",
            "test",
        )
        .unwrap();
        let run = robokey::sim::simulate(&config, 0, true).unwrap();
        let csv = trace_csv(&run.trace);
        let rows: Vec<Vec<&str>> = csv
            .lines()
            .skip(1)
            .map(|l| l.split(',').collect())
            .collect();
        assert!(rows.iter().all(|r| r.len() == 28 && !r[25].is_empty()));
        // Both steps of a doublet carry its two bits; the decision is on its second step.
        let doublets_with_bits = run.private.unwrap().bits.len() / 2;
        let carried = rows.iter().filter(|r| !r[16].is_empty()).count();
        assert_eq!(carried, 2 * doublets_with_bits);
        assert!(rows.iter().all(|r| r[16].is_empty() == r[24].is_empty()));
        let decided = rows.iter().filter(|r| !r[22].is_empty()).count();
        assert_eq!(decided, doublets_with_bits);
    }
}
