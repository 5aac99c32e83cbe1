//! The columns of a trace ([`TraceRow`], docs/experiments.md "`trace.csv`") declared once with
//! their units, meanings and typed values, for the columnar outputs (`trace.parquet`, the
//! Python package's tables); the names are [`TraceRow::COLUMNS`] and the values those
//! `trace.csv` writes.

use robokey::sim::TraceRow;

use crate::table::{Cell, Column, Values};

/// One trace column's value in a row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TraceValue {
    /// A real number, or undefined.
    Real(Option<f64>),
    /// A step index or a bit, or undefined.
    Count(Option<u64>),
}

/// How a column is read from a row.
#[derive(Clone, Copy)]
enum Read {
    /// A real number every row defines.
    Required(fn(&TraceRow) -> f64),
    /// A real number, or undefined.
    Real(fn(&TraceRow) -> Option<f64>),
    /// A count every row defines.
    Count(fn(&TraceRow) -> u64),
    /// A bit, or undefined.
    Bit(fn(&TraceRow) -> Option<u8>),
}

/// One column of a trace.
#[derive(Clone, Copy)]
pub struct TraceColumn {
    /// Its name, as in `trace.csv`.
    pub name: &'static str,
    /// The unit of its values (empty for steps and bits).
    pub unit: &'static str,
    /// What it holds (docs/experiments.md, "`trace.csv`").
    pub meaning: &'static str,
    read: Read,
}

impl std::fmt::Debug for TraceColumn {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TraceColumn")
            .field("name", &self.name)
            .field("unit", &self.unit)
            .finish_non_exhaustive()
    }
}

impl From<TraceValue> for Cell {
    fn from(value: TraceValue) -> Self {
        match value {
            TraceValue::Real(x) => Self::Real(x),
            TraceValue::Count(n) => Self::Count(n),
        }
    }
}

impl TraceColumn {
    /// Its value in `row`.
    #[must_use]
    pub fn value(&self, row: &TraceRow) -> TraceValue {
        match self.read {
            Read::Required(get) => TraceValue::Real(Some(get(row))),
            Read::Real(get) => TraceValue::Real(get(row)),
            Read::Count(get) => TraceValue::Count(Some(get(row))),
            Read::Bit(get) => TraceValue::Count(get(row).map(u64::from)),
        }
    }
}

/// Component `$i` of the vector `$field` (an array every row has, or an `Option` of one).
macro_rules! column {
    ($name:literal, $unit:literal, $meaning:literal, required $field:ident[$i:literal]) => {
        TraceColumn {
            name: $name,
            unit: $unit,
            meaning: $meaning,
            read: Read::Required(|r| r.$field[$i]),
        }
    };
    ($name:literal, $unit:literal, $meaning:literal, optional $field:ident[$i:literal]) => {
        TraceColumn {
            name: $name,
            unit: $unit,
            meaning: $meaning,
            read: Read::Real(|r| r.$field.map(|v| v[$i])),
        }
    };
    ($name:literal, $meaning:literal, bit $field:ident) => {
        TraceColumn {
            name: $name,
            unit: "",
            meaning: $meaning,
            read: Read::Bit(|r| r.$field),
        }
    };
}

/// Every column of a trace, in `trace.csv`'s order.
pub static TRACE_COLUMNS: [TraceColumn; 28] = [
    TraceColumn {
        name: "k",
        unit: "",
        meaning: "step k",
        read: Read::Count(|r| u64::from(r.k)),
    },
    TraceColumn {
        name: "t",
        unit: "s",
        meaning: "time k·T",
        read: Read::Required(|r| r.t),
    },
    column!("ref_x", "m", "reference position at k, x", required reference[0]),
    column!("ref_y", "m", "reference position at k, y", required reference[1]),
    column!("px", "m", "true pose x(k), x", required pose[0]),
    column!("py", "m", "true pose x(k), y", required pose[1]),
    column!("theta", "rad", "true pose x(k), heading", required pose[2]),
    column!("meas_x", "m", "odometry y(k), x", required measurement[0]),
    column!("meas_y", "m", "odometry y(k), y", required measurement[1]),
    column!("meas_theta", "rad", "odometry y(k), heading", required measurement[2]),
    column!("v_nom", "m/s", "clipped nominal command uU(k), linear speed", optional nominal[0]),
    column!("omega_nom", "rad/s", "clipped nominal command uU(k), turn rate", optional nominal[1]),
    column!("u0_r", "rad/s", "wheel command for bit 0 sent at k, right wheel", optional u0[0]),
    column!("u0_l", "rad/s", "wheel command for bit 0 sent at k, left wheel", optional u0[1]),
    column!("u1_r", "rad/s", "wheel command for bit 1 sent at k, right wheel", optional u1[0]),
    column!("u1_l", "rad/s", "wheel command for bit 1 sent at k, left wheel", optional u1[1]),
    column!("b", "the bit b(k) applied on [k, k+1)", bit bit),
    column!("dhat_v", "m/s", "the controller's estimate d̂(k−1) from y(k), linear speed", optional dhat[0]),
    column!("dhat_omega", "rad/s", "the controller's estimate d̂(k−1) from y(k), turn rate", optional dhat[1]),
    column!("xhat_x", "m", "the controller's state estimate x̂(k), x", optional xhat[0]),
    column!("xhat_y", "m", "the controller's state estimate x̂(k), y", optional xhat[1]),
    column!("xhat_theta", "rad", "the controller's state estimate x̂(k), heading", optional xhat[2]),
    column!("bhat", "the controller's decision b̂(k−1)", bit bhat),
    column!("bhat_eve", "Eve's decision b̂(k−1)", bit bhat_eve),
    column!("b_omega", "private sensing only: the ω bit", bit bit_omega),
    column!("eve_x", "m", "private sensing only: Eve's camera sample, x", optional camera[0]),
    column!("eve_y", "m", "private sensing only: Eve's camera sample, y", optional camera[1]),
    column!("eve_theta", "rad", "private sensing only: Eve's camera sample, heading", optional camera[2]),
];

/// Collects a trace's rows into its columns ([`TRACE_COLUMNS`]) as they come.
#[derive(Default)]
pub struct TraceColumns {
    values: Vec<Vec<TraceValue>>,
}

impl TraceColumns {
    /// Takes one row.
    pub fn push(&mut self, row: &TraceRow) {
        if self.values.is_empty() {
            self.values = TRACE_COLUMNS.iter().map(|_| Vec::new()).collect();
        }
        for (column, values) in TRACE_COLUMNS.iter().zip(&mut self.values) {
            values.push(column.value(row));
        }
    }

    /// The columns, with their units and meanings.
    #[must_use]
    pub fn into_columns(self) -> Vec<Column> {
        let mut values = self.values;
        values.resize_with(TRACE_COLUMNS.len(), Vec::new);
        TRACE_COLUMNS
            .iter()
            .zip(values)
            .map(|(column, values)| {
                let values = Values::of_cells(
                    &column.value(&TraceRow::default()).into(),
                    values.into_iter().map(Cell::from),
                );
                Column::new(column.name, column.unit, column.meaning, values)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::TraceCsv;

    #[test]
    fn the_columns_are_those_trace_csv_writes() {
        let names: Vec<&str> = TRACE_COLUMNS.iter().map(|c| c.name).collect();
        assert_eq!(names, TraceRow::COLUMNS);
        let private =
            robokey::Config::from_toml("[sensing]\nmode = \"private\"\n", "test").unwrap();
        for config in [robokey::Config::default(), private] {
            let trace = robokey::sim::simulate(&config, 0, true).unwrap().trace;
            let mut csv = TraceCsv::new(Vec::new()).unwrap();
            for row in &trace {
                csv.write(row).unwrap();
            }
            let text = String::from_utf8(csv.finish().unwrap()).unwrap();
            for (row, line) in trace.iter().zip(text.lines().skip(1)) {
                let cells: Vec<String> = TRACE_COLUMNS
                    .iter()
                    .map(|c| match c.value(row) {
                        TraceValue::Real(x) => x.map_or_else(String::new, |x| x.to_string()),
                        TraceValue::Count(n) => n.map_or_else(String::new, |n| n.to_string()),
                    })
                    .collect();
                assert_eq!(cells.join(","), line);
            }
        }
    }
}
