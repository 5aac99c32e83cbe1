//! A table column by column — each column's name, unit, meaning and typed values — as robokey
//! writes it to Parquet ([`crate::parquet_table`]) and hands it to Python. The columns come from
//! the declarations the CSV files are written from ([`crate::metric_table::METRICS`],
//! [`crate::trace_table::TRACE_COLUMNS`], [`crate::secrecy::table::SECRECY_COLUMNS`]), so a
//! column's name, unit and values are the CSV's.

/// One value of a column, typed: what the column declarations ([`crate::metric_table`],
/// [`crate::trace_table`], [`crate::secrecy::table`]) give for a row.
#[derive(Clone, Debug, PartialEq)]
pub enum Cell {
    /// A real number, or undefined.
    Real(Option<f64>),
    /// A non-negative integer, or undefined.
    Count(Option<u64>),
    /// A flag, or undefined.
    Flag(Option<bool>),
    /// Text.
    Text(String),
}

impl Cell {
    /// As a real number (counts and flags as numbers, flags 0/1), if defined.
    #[must_use]
    pub fn real(self) -> Option<f64> {
        match self {
            Self::Real(x) => x,
            Self::Count(n) => n.map(|n| n as f64),
            Self::Flag(b) => b.map(|b| f64::from(u8::from(b))),
            Self::Text(_) => None,
        }
    }

    /// As a count, if it is a defined one.
    #[must_use]
    pub fn count(self) -> Option<u64> {
        match self {
            Self::Count(n) => n,
            _ => None,
        }
    }

    /// As a flag, if it is a defined one.
    #[must_use]
    pub fn flag(self) -> Option<bool> {
        match self {
            Self::Flag(b) => b,
            _ => None,
        }
    }

    /// As text (empty unless it is text).
    #[must_use]
    pub fn text(self) -> String {
        match self {
            Self::Text(t) => t,
            _ => String::new(),
        }
    }
}

/// The values of one column.
#[derive(Clone, Debug, PartialEq)]
pub enum Values {
    /// Real numbers, or undefined.
    Reals(Vec<Option<f64>>),
    /// Non-negative integers, or undefined.
    Counts(Vec<Option<u64>>),
    /// Signed integers.
    Integers(Vec<i64>),
    /// Flags, or undefined.
    Flags(Vec<Option<bool>>),
    /// Text.
    Texts(Vec<String>),
}

impl Values {
    /// The column of `cells`, all of the type of `kind` (any value of the column).
    #[must_use]
    pub fn of_cells(kind: &Cell, cells: impl Iterator<Item = Cell>) -> Self {
        match kind {
            Cell::Real(_) => Self::Reals(cells.map(Cell::real).collect()),
            Cell::Count(_) => Self::Counts(cells.map(Cell::count).collect()),
            Cell::Flag(_) => Self::Flags(cells.map(Cell::flag).collect()),
            Cell::Text(_) => Self::Texts(cells.map(Cell::text).collect()),
        }
    }

    /// How many rows.
    #[must_use]
    pub fn len(&self) -> usize {
        match self {
            Self::Reals(v) => v.len(),
            Self::Counts(v) => v.len(),
            Self::Integers(v) => v.len(),
            Self::Flags(v) => v.len(),
            Self::Texts(v) => v.len(),
        }
    }

    /// Whether there is no row.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Row `row`'s value as its CSV cell: empty when undefined, numbers in their shortest
    /// round-trip form, flags `true`/`false`, text as it is (before CSV quoting); `None` past
    /// the last row.
    #[must_use]
    pub fn cell(&self, row: usize) -> Option<String> {
        fn text(value: Option<impl ToString>) -> String {
            value.map_or_else(String::new, |v| v.to_string())
        }
        Some(match self {
            Self::Reals(v) => text(*v.get(row)?),
            Self::Counts(v) => text(*v.get(row)?),
            Self::Integers(v) => v.get(row)?.to_string(),
            Self::Flags(v) => text(*v.get(row)?),
            Self::Texts(v) => v.get(row)?.clone(),
        })
    }
}

/// One named column with its unit and what it means (either may be empty).
#[derive(Clone, Debug, PartialEq)]
pub struct Column {
    /// Its name, the CSV header's.
    pub name: String,
    /// The unit of its values (empty for counts, flags and text).
    pub unit: String,
    /// What it holds (may be empty).
    pub description: String,
    /// Its values, one per row.
    pub values: Values,
}

impl Column {
    /// A column named `name` in `unit`, meaning `description`.
    #[must_use]
    pub fn new(name: &str, unit: &str, description: &str, values: Values) -> Self {
        Self {
            name: name.to_owned(),
            unit: unit.to_owned(),
            description: description.to_owned(),
            values,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_are_written_as_csv_writes_them() {
        let reals = Values::Reals(vec![Some(0.035), None, Some(1.0)]);
        assert_eq!(reals.len(), 3);
        assert_eq!(reals.cell(0).as_deref(), Some("0.035"));
        assert_eq!(reals.cell(1).as_deref(), Some(""));
        assert_eq!(reals.cell(2).as_deref(), Some("1"));
        assert_eq!(reals.cell(3), None);
        assert_eq!(
            Values::Flags(vec![Some(true)]).cell(0).as_deref(),
            Some("true")
        );
        assert_eq!(Values::Integers(vec![-3]).cell(0).as_deref(), Some("-3"));
        assert_eq!(Values::Counts(vec![None]).cell(0).as_deref(), Some(""));
        assert!(Values::Texts(Vec::new()).is_empty());
        let cells = [Cell::Count(Some(2)), Cell::Count(None)];
        assert_eq!(
            Values::of_cells(&Cell::Real(None), cells.iter().cloned()),
            Values::Reals(vec![Some(2.0), None])
        );
        assert_eq!(
            Values::of_cells(&Cell::Count(None), cells.into_iter()),
            Values::Counts(vec![Some(2), None])
        );
    }
}
