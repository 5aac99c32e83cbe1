//! A conservative quantile of the standard normal's upper tail, for the estimate's tests.

/// `z` with `P[N(0,1) > z] ≤ p` (p ≤ ½): from the tail bound `P[N > z] ≤ e^(−z²/2)/2`,
/// `z = √(2 ln(1/(2p)))` — a little wider than the exact quantile, never narrower.
pub(super) fn normal_upper_quantile(p: f64) -> f64 {
    (2.0 * (0.5 / p).ln()).max(0.0).sqrt()
}
