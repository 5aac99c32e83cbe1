//! The columns of `secrecy.csv` (one row per point and adversary) declared once with their
//! units, meanings and typed values: `secrecy.csv` is rendered from them
//! ([`crate::report::secrecy::secrecy_csv`]), and so is `secrecy.parquet` ([`secrecy_columns`]).

use super::{Block, PointSecrecy, Rate};
use crate::table::{Cell, Column, Values};

/// One value of a `secrecy.csv` row.
#[derive(Clone, Debug, PartialEq)]
pub enum SecrecyValue {
    /// A real number, or undefined (an empty cell).
    Real(Option<f64>),
    /// A count.
    Count(u64),
    /// A flag.
    Flag(bool),
    /// A name, written unquoted (it holds no comma).
    Name(String),
    /// A text, written quoted.
    Text(String),
}

impl From<SecrecyValue> for Cell {
    fn from(value: SecrecyValue) -> Self {
        match value {
            SecrecyValue::Real(x) => Self::Real(x),
            SecrecyValue::Count(n) => Self::Count(Some(n)),
            SecrecyValue::Flag(b) => Self::Flag(Some(b)),
            SecrecyValue::Name(t) | SecrecyValue::Text(t) => Self::Text(t),
        }
    }
}

/// One column of `secrecy.csv`.
#[derive(Clone, Copy)]
pub struct SecrecyColumn {
    /// Its name, the CSV header's.
    pub name: &'static str,
    /// The unit of its values (empty for counts without one, flags and text).
    pub unit: &'static str,
    /// What it holds (docs/secrecy.md, "Output files").
    pub meaning: &'static str,
    /// Its value in a row.
    pub value: fn(&PointSecrecy) -> SecrecyValue,
}

impl std::fmt::Debug for SecrecyColumn {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SecrecyColumn")
            .field("name", &self.name)
            .field("unit", &self.unit)
            .finish_non_exhaustive()
    }
}

/// The sum of `field` over the row's blocks.
fn total(r: &PointSecrecy, field: fn(&Block) -> u64) -> SecrecyValue {
    SecrecyValue::Count(r.blocks.iter().map(field).sum())
}

/// The sum of `field` over the row's blocks, as a real.
fn real_total(r: &PointSecrecy, field: fn(&Block) -> f64) -> SecrecyValue {
    SecrecyValue::Real(Some(r.blocks.iter().map(field).sum()))
}

/// A part of an error rate, undefined without the rate.
fn rate(rate: Option<Rate>, part: fn(Rate) -> f64) -> SecrecyValue {
    SecrecyValue::Real(rate.map(part))
}

/// A column declaration.
macro_rules! column {
    ($name:literal, $unit:literal, $meaning:literal, $value:expr) => {
        SecrecyColumn {
            name: $name,
            unit: $unit,
            meaning: $meaning,
            value: $value,
        }
    };
}

/// Every column of `secrecy.csv`, in its order.
pub static SECRECY_COLUMNS: [SecrecyColumn; 37] = [
    column!(
        "point",
        "",
        "the grid point's parameters, `field = value, …`",
        |r| { SecrecyValue::Text(r.point.clone()) }
    ),
    column!("adversary", "", "the eavesdropper", |r| {
        SecrecyValue::Name(r.adversary.clone())
    }),
    column!(
        "adversary_class",
        "",
        "her class: strongest, learning or restricted",
        |r| { SecrecyValue::Name(r.adversary_class.name().to_owned()) }
    ),
    column!(
        "pooling",
        "",
        "which sessions were pooled into blocks",
        |r| { SecrecyValue::Name(r.pooling.name().to_owned()) }
    ),
    column!("sessions", "", "sessions simulated", |r| {
        SecrecyValue::Count(u64::from(r.sessions))
    }),
    column!(
        "sessions_pooled",
        "",
        "sessions pooled into the blocks",
        |r| { SecrecyValue::Count(u64::from(r.sessions_pooled)) }
    ),
    column!(
        "steps",
        "",
        "robot steps over the sessions simulated",
        |r| { SecrecyValue::Count(r.steps) }
    ),
    column!(
        "p_c",
        "fraction",
        "the controller's bit error rate over applied bits",
        |r| { rate(r.p_c, |x| x.rate) }
    ),
    column!(
        "p_c_low",
        "fraction",
        "p_c's 95 % interval, lower end",
        |r| { rate(r.p_c, |x| x.low) }
    ),
    column!(
        "p_c_high",
        "fraction",
        "p_c's 95 % interval, upper end",
        |r| { rate(r.p_c, |x| x.high) }
    ),
    column!(
        "p_e",
        "fraction",
        "Eve's bit error rate over applied bits",
        |r| { rate(r.p_e, |x| x.rate) }
    ),
    column!(
        "p_e_low",
        "fraction",
        "p_e's 95 % interval, lower end",
        |r| { rate(r.p_e, |x| x.low) }
    ),
    column!(
        "p_e_high",
        "fraction",
        "p_e's 95 % interval, upper end",
        |r| { rate(r.p_e, |x| x.high) }
    ),
    column!(
        "info_advantage",
        "bit/step",
        "plug-in I(B;B̂c) − I(B;B̂a)",
        |r| SecrecyValue::Real(r.information_advantage.map(|x| x[0]))
    ),
    column!(
        "info_advantage_low",
        "bit/step",
        "info_advantage's 95 % bootstrap interval, lower end",
        |r| SecrecyValue::Real(r.information_advantage.map(|x| x[1]))
    ),
    column!(
        "info_advantage_high",
        "bit/step",
        "info_advantage's 95 % bootstrap interval, upper end",
        |r| SecrecyValue::Real(r.information_advantage.map(|x| x[2]))
    ),
    column!(
        "info_conditional",
        "bit/step",
        "plug-in I(B;B̂c|B̂a)",
        |r| { SecrecyValue::Real(r.information_conditional.map(|x| x[0])) }
    ),
    column!("raw_bits", "bit", "accepted (raw) key bits", |r| {
        SecrecyValue::Count(r.raw_bits)
    }),
    column!(
        "raw_bits_per_step",
        "bit/step",
        "raw agreed bits per robot step",
        |r| { SecrecyValue::Real(Some(r.raw_bits_per_step)) }
    ),
    column!(
        "eve_error_accepted",
        "fraction",
        "Eve's error rate on accepted bits (her ŝa against K_c)",
        |r| rate(r.eve_error_accepted, |x| x.rate)
    ),
    column!(
        "eve_error_accepted_high",
        "fraction",
        "eve_error_accepted's 95 % interval, upper end",
        |r| rate(r.eve_error_accepted, |x| x.high)
    ),
    column!(
        "acceptance_p",
        "",
        "p-value of the exact binomial test of P(s = 1 | accepted) = ½",
        |r| SecrecyValue::Real(r.acceptance_independence_p)
    ),
    column!("blocks", "", "privacy-amplification blocks", |r| {
        SecrecyValue::Count(r.blocks.len() as u64)
    }),
    column!(
        "q_estimate",
        "fraction",
        "the first block's error-rate estimate for reconciliation",
        |r| SecrecyValue::Real(r.q_estimate)
    ),
    column!(
        "messages",
        "",
        "reconciliation messages over the blocks",
        |r| { total(r, |b| u64::from(b.messages)) }
    ),
    column!(
        "leak_ec",
        "bit",
        "bits disclosed by error correction over the blocks",
        |r| { total(r, |b| b.leak_ec) }
    ),
    column!(
        "leak_confirmation",
        "bit",
        "bits disclosed by confirmation over the blocks",
        |r| total(r, |b| b.leak_confirmation)
    ),
    column!(
        "h_min",
        "bit",
        "smooth min-entropy of the blocks under the stated assumption",
        |r| real_total(r, |b| b.h_min)
    ),
    column!(
        "secret_bits",
        "bit",
        "secret key length ℓ over the blocks, under the stated assumption",
        |r| { SecrecyValue::Count(r.secret_bits) }
    ),
    column!(
        "secret_bits_per_step",
        "bit/step",
        "secret bits per robot step (every session simulated until the last one pooled)",
        |r| SecrecyValue::Real(Some(r.secret_bits_per_step))
    ),
    column!(
        "secret_bits_per_second",
        "bit/s",
        "secret bits per second",
        |r| { SecrecyValue::Real(Some(r.secret_bits_per_second)) }
    ),
    column!(
        "realised_h_min",
        "bit",
        "smooth min-entropy of the blocks in this adversary's realised view",
        |r| real_total(r, |b| b.realised.h_min)
    ),
    column!(
        "realised_secret_bits",
        "bit",
        "ℓ this adversary's realised view would support (the diagnostic)",
        |r| SecrecyValue::Count(r.realised_secret_bits)
    ),
    column!(
        "assumption_exceeds_realised",
        "",
        "whether the assumption credits more than this adversary's realised view supports",
        |r| SecrecyValue::Flag(r.assumption_exceeds_realised)
    ),
    column!("zero_reason", "", "why ℓ = 0 (empty when ℓ > 0)", |r| {
        SecrecyValue::Text(r.zero_reason.clone().unwrap_or_default())
    }),
    column!(
        "assumption",
        "",
        "the stated assumption that sizes the key",
        |r| { SecrecyValue::Text(r.assumption.clone()) }
    ),
    column!(
        "structural_zero",
        "",
        "why the configuration yields no secret key whatever this adversary gives (empty if it does)",
        |r| SecrecyValue::Text(r.structural_zero.clone().unwrap_or_default())
    ),
];

/// The columns of `secrecy.csv` for `results`, typed.
#[must_use]
pub fn secrecy_columns(results: &[PointSecrecy]) -> Vec<Column> {
    SECRECY_COLUMNS
        .iter()
        .map(|column| {
            // Without a row, the type does not matter: a column of no text.
            let kind = results
                .first()
                .map_or(Cell::Text(String::new()), |r| (column.value)(r).into());
            let values = Values::of_cells(&kind, results.iter().map(|r| (column.value)(r).into()));
            Column::new(column.name, column.unit, column.meaning, values)
        })
        .collect()
}
