//! Small linear codes given by a generator matrix, decoded by a full lookup table.

use super::{BlockCode, Decoded, low_mask};

/// Largest codeword length a lookup-table code accepts (table of `2^n` entries).
pub const MAX_TABLE_BITS: usize = 16;

/// A linear `(n, k)` code from generator rows, with a precomputed nearest-codeword table.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GeneratorCode {
    name: String,
    n: usize,
    rows: Vec<u64>,
    table: Vec<Decoded>,
}

impl GeneratorCode {
    /// Builds a code from rows written as strings of `0`/`1` (bit `j` = character `j`).
    /// `None` when rows are empty, of unequal length, longer than `MAX_TABLE_BITS`, or
    /// contain other characters.
    #[must_use]
    pub fn from_rows(name: &str, rows: &[&str]) -> Option<Self> {
        let n = rows.first()?.len();
        if n == 0 || n > MAX_TABLE_BITS || rows.len() > n {
            return None;
        }
        let rows: Vec<u64> = rows
            .iter()
            .map(|row| {
                (row.len() == n).then_some(())?;
                row.chars()
                    .enumerate()
                    .try_fold(0u64, |acc, (j, c)| match c {
                        '0' => Some(acc),
                        '1' => Some(acc | 1 << j),
                        _ => None,
                    })
            })
            .collect::<Option<_>>()?;
        let mut code = Self {
            name: name.to_owned(),
            n,
            rows,
            table: Vec::new(),
        };
        code.table = (0..1u64 << n)
            .map(|word| {
                (0..1u64 << code.rows.len())
                    .map(|message| Decoded {
                        message,
                        distance: (code.encode(message) ^ word).count_ones(),
                    })
                    .min_by_key(|d| (d.distance, d.message))
                    .expect("at least one codeword")
            })
            .collect();
        Some(code)
    }
}

impl BlockCode for GeneratorCode {
    fn n(&self) -> usize {
        self.n
    }

    fn k(&self) -> usize {
        self.rows.len()
    }

    fn encode(&self, message: u64) -> u64 {
        self.rows
            .iter()
            .enumerate()
            .filter(|(i, _)| message >> i & 1 == 1)
            .fold(0, |word, (_, row)| word ^ row)
    }

    fn decode(&self, word: u64) -> Decoded {
        self.table[(word & low_mask(self.n)) as usize]
    }

    fn name(&self) -> String {
        self.name.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn malformed_generators_are_rejected() {
        assert!(GeneratorCode::from_rows("x", &[]).is_none());
        assert!(GeneratorCode::from_rows("x", &["101", "10"]).is_none());
        assert!(GeneratorCode::from_rows("x", &["1a1"]).is_none());
        assert!(GeneratorCode::from_rows("x", &["1"; 3]).is_none());
    }
}
