//! `summary.json`: per point, for each metric of [`METRICS`], the count of runs where it is
//! defined and its median, quartiles, min, max and mean — computed from the rows, so a single
//! sweep and a merge of its shards write the same bytes.

use serde_json::{Map, Value, json};

use super::rows::Rows;
use crate::experiment::{Experiment, value_text};
use crate::metric_table::METRICS;
use crate::stats::Summary;

/// `summary.json` of a complete folder's rows.
#[must_use]
pub fn summary_json(experiment: &Experiment, rows: &Rows) -> String {
    let mut values = vec![vec![Vec::new(); METRICS.len()]; experiment.points.len()];
    for row in rows.values() {
        for (column, metric) in values[row.point].iter_mut().zip(&METRICS) {
            column.extend(metric.value(&row.metrics).as_f64());
        }
    }
    let points: Vec<Value> = experiment
        .points
        .iter()
        .zip(values)
        .enumerate()
        .map(|(i, (point, columns))| {
            let params: Map<String, Value> = point
                .params
                .iter()
                .map(|(f, v)| (f.clone(), toml_to_json(v)))
                .collect();
            let metrics: Map<String, Value> = METRICS
                .iter()
                .zip(columns)
                .map(|(metric, column)| {
                    let summary =
                        Summary::of(&column).map_or_else(|| json!({ "count": 0 }), |s| json!(s));
                    (metric.column.to_owned(), summary)
                })
                .collect();
            json!({ "point": i, "params": params, "metrics": metrics })
        })
        .collect();
    let summary = json!({
        "experiment": experiment.name,
        "replicates": experiment.replicates(),
        "runs": rows.len(),
        "statistics": "per metric over the runs where it is defined: count, median, quartiles (linear interpolation between order statistics), min, max, mean",
        "points": points,
    });
    serde_json::to_string_pretty(&summary).expect("JSON serializes") + "\n"
}

/// A TOML value as JSON.
#[must_use]
pub fn toml_to_json(value: &toml::Value) -> Value {
    match value {
        toml::Value::Float(x) => json!(x),
        toml::Value::Integer(i) => json!(i),
        toml::Value::Boolean(b) => json!(b),
        other => json!(value_text(other)),
    }
}
