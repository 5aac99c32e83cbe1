//! Trend tests against the paper's claims, in words: Spearman's ρ over all runs with a
//! two-sided permutation p-value, read as agreeing, contradicting or not reproducing.

use crate::stats::{TrendTest, spearman_permutation_test};

/// Permutations of the trend tests.
const PERMUTATIONS: usize = 9_999;
/// Seed of the trend tests' permutations.
const TREND_SEED: u64 = 2023;

pub(crate) fn trend(pairs: &[(f64, f64)]) -> TrendTest {
    let (x, y): (Vec<f64>, Vec<f64>) = pairs.iter().copied().unzip();
    spearman_permutation_test(&x, &y, PERMUTATIONS, TREND_SEED)
}

/// How a trend test reads against the paper's claim of a rising (`+1`) or falling (`−1`)
/// trend.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Reading {
    /// The metric is the same everywhere.
    Constant,
    /// No trend at the 1 % level.
    NoTrend,
    /// A significant trend the way the paper says.
    Agrees,
    /// A significant trend the other way.
    Contradicts,
}

fn reading(test: &TrendTest, expected_sign: f64) -> Reading {
    match test.rho {
        None => Reading::Constant,
        Some(_) if test.p_value >= 0.01 => Reading::NoTrend,
        Some(rho) if rho * expected_sign > 0.0 => Reading::Agrees,
        Some(_) => Reading::Contradicts,
    }
}

/// The permutation p-value, or its floor when no permutation did as well.
fn p_text(test: &TrendTest) -> String {
    let floor = 1.0 / (1 + test.permutations) as f64;
    if test.p_value <= floor * (1.0 + 1e-9) {
        format!("p ≤ {floor:.0e}")
    } else {
        format!("p = {:.3}", test.p_value)
    }
}

fn rises(test: &TrendTest) -> &'static str {
    if test.rho.unwrap_or(0.0) > 0.0 {
        "rises"
    } else {
        "falls"
    }
}

/// A sentence for a trend test against the paper's claim of a rising (`+1`) or falling
/// (`−1`) trend.
pub(crate) fn trend_sentence(
    what: &str,
    against: &str,
    test: &TrendTest,
    paper: &str,
    expected_sign: f64,
) -> String {
    let p = p_text(test);
    let p = if p.starts_with("p ≤") {
        format!("{p}, the smallest attainable")
    } else {
        p
    };
    let stats = format!(
        "Spearman ρ = {:.2}, permutation {p}, {} permutations",
        test.rho.unwrap_or(0.0),
        test.permutations
    );
    match reading(test, expected_sign) {
        Reading::Constant => format!(
            "{what} is the same at every {against} value, so it shows no trend: the paper's claim that {paper} does **not** reproduce here."
        ),
        Reading::NoTrend => format!(
            "{what} shows no significant trend with {against} ({stats}): the paper's claim that {paper} does **not** reproduce here."
        ),
        Reading::Agrees => format!(
            "{what} {} with {against} ({stats}): this agrees with the paper, which says {paper}.",
            rises(test)
        ),
        Reading::Contradicts => format!(
            "{what} {} with {against} ({stats}): this contradicts the paper, which says {paper}.",
            rises(test)
        ),
    }
}

/// The same finding as [`trend_sentence`], in one line for the terminal.
pub(crate) fn trend_line(
    what: &str,
    against: &str,
    test: &TrendTest,
    expected_sign: f64,
) -> String {
    let stats = || format!("ρ = {:.2}, {}", test.rho.unwrap_or(0.0), p_text(test));
    match reading(test, expected_sign) {
        Reading::Constant => {
            format!("{what}: the same at every {against}; the paper's trend does not reproduce")
        }
        Reading::NoTrend => format!(
            "{what}: no significant trend with {against} ({}); the paper's trend does not reproduce",
            stats()
        ),
        Reading::Agrees => format!(
            "{what} {} with {against} ({}): agrees with the paper",
            rises(test),
            stats()
        ),
        Reading::Contradicts => format!(
            "{what} {} with {against} ({}): contradicts the paper",
            rises(test),
            stats()
        ),
    }
}
