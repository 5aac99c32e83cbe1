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
