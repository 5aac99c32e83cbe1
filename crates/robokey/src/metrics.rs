//! Metrics of one run (docs/experiments.md).

/// The outcome of one simulated run. `None` = undefined (nothing accepted, no Eve, or
/// protocol off), written as an empty CSV cell / JSON `null`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Metrics {
    /// Complete codewords sent.
    pub codewords_sent: Option<u64>,
    /// Codewords accepted.
    pub accepted: Option<u64>,
    /// accepted / sent · 100.
    pub accepted_pct: Option<f64>,
    /// Share (%) of accepted key bits where `K_c = K_r`.
    pub correct_pct: Option<f64>,
    /// Fraction of applied bits the controller decided wrongly.
    pub ber_controller: Option<f64>,
    /// Fraction of applied bits Eve decided wrongly.
    pub ber_eve: Option<f64>,
    /// Mean tracking error `J_x` (m) over k = 1…N on the true pose.
    pub jx: f64,
    /// Share (%) of key positions where `K_a ≠ K_c`.
    pub eve_disagreement_pct: Option<f64>,
    /// Whether `K_c = K_r`.
    pub key_match: Option<bool>,
    /// Joint counts over applied bits of `(b, b̂c, b̂a)`, index `4b + 2b̂c + b̂a`.
    pub n_bce: Option<[u64; 8]>,
    /// Joint counts over accepted message bits of `(s, ŝc, ŝa)`, index `4s + 2ŝc + ŝa`.
    pub n_acc: Option<[u64; 8]>,
}

/// One metric value, typed for CSV and JSON.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MetricValue {
    /// A real number, or undefined.
    Real(Option<f64>),
    /// A count, or undefined.
    Count(Option<u64>),
    /// A flag, or undefined.
    Flag(Option<bool>),
}

impl MetricValue {
    /// As a real number (flags as 0/1), if defined.
    #[must_use]
    pub fn as_f64(self) -> Option<f64> {
        match self {
            Self::Real(x) => x,
            Self::Count(n) => n.map(|n| n as f64),
            Self::Flag(b) => b.map(|b| f64::from(u8::from(b))),
        }
    }
}

/// Names of the joint-count columns, `n_bce_000` … `n_acc_111`.
fn count_names(prefix: &str) -> impl Iterator<Item = String> + '_ {
    (0..8).map(move |i| format!("{prefix}_{}{}{}", i >> 2 & 1, i >> 1 & 1, i & 1))
}

impl Metrics {
    /// Names of all metrics in column order: the list of docs/experiments.md, then the 16 joint counts.
    #[must_use]
    pub fn names() -> Vec<String> {
        [
            "codewords_sent",
            "accepted",
            "accepted_pct",
            "correct_pct",
            "ber_controller",
            "ber_eve",
            "jx",
            "eve_disagreement_pct",
            "key_match",
        ]
        .into_iter()
        .map(str::to_owned)
        .chain(count_names("n_bce"))
        .chain(count_names("n_acc"))
        .collect()
    }

    /// Values in the order of [`Metrics::names`].
    #[must_use]
    pub fn values(&self) -> Vec<MetricValue> {
        let counts =
            |table: Option<[u64; 8]>| (0..8).map(move |i| MetricValue::Count(table.map(|t| t[i])));
        [
            MetricValue::Count(self.codewords_sent),
            MetricValue::Count(self.accepted),
            MetricValue::Real(self.accepted_pct),
            MetricValue::Real(self.correct_pct),
            MetricValue::Real(self.ber_controller),
            MetricValue::Real(self.ber_eve),
            MetricValue::Real(Some(self.jx)),
            MetricValue::Real(self.eve_disagreement_pct),
            MetricValue::Flag(self.key_match),
        ]
        .into_iter()
        .chain(counts(self.n_bce))
        .chain(counts(self.n_acc))
        .collect()
    }
}
