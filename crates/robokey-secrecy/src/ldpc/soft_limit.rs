//! The soft limit of reconciliation, H(X | L) = Σᵢ h₂(1/(1 + e^{|Lᵢ|})) bits for calibrated
//! LLRs Lᵢ, and the syndrome length a design efficiency f and finite-length term c ask for.

use super::{LdpcError, MAX_BLOCK_BITS};
use crate::entropy::binary_entropy;

/// Probability that the hard decision of a calibrated LLR is wrong: 1/(1 + e^{|L|}).
#[must_use]
pub fn bit_error_probability(llr: f64) -> f64 {
    1.0 / (1.0 + llr.abs().exp())
}

/// Σᵢ h₂(1/(1 + e^{|Lᵢ|})) in bits: what the robot must at least disclose for the controller
/// to recover its bits (Slepian–Wolf), given calibrated LLRs.
#[must_use]
pub fn soft_limit_bits(llrs: &[f64]) -> f64 {
    llrs.iter()
        .map(|&l| binary_entropy(bit_error_probability(l)))
        .sum()
}

/// The channel's Bhattacharyya parameter B = (1/n) Σᵢ 2√(pᵢ(1 − pᵢ)), pᵢ = 1/(1 + e^{|Lᵢ|}),
/// rounded up to a multiple of 2⁻¹⁰ (so that it travels as a 10-bit integer); 1 for no bits.
/// It depends on the LLRs' magnitudes only, not on the bits.
#[must_use]
pub fn bhattacharyya(llrs: &[f64]) -> f64 {
    if llrs.is_empty() {
        return 1.0;
    }
    let mean = llrs
        .iter()
        .map(|&l| {
            let p = bit_error_probability(l);
            2.0 * (p * (1.0 - p)).sqrt()
        })
        .sum::<f64>()
        / llrs.len() as f64;
    ((mean * 1024.0).ceil() / 1024.0).clamp(1.0 / 1024.0, 1.0)
}

/// m = min(n, max(1, ⌈f · H + c · √H⌉)) with H = Σᵢ h₂(1/(1 + e^{|Lᵢ|})): the syndrome bits
/// for design efficiency f ∈ [1, 10] and finite-length term c ∈ [0, 100] on an n-bit block
/// with LLRs `llrs` (an efficiency of f + c/√H against the soft limit).
pub fn syndrome_length(
    llrs: &[f64],
    efficiency: f64,
    finite_length: f64,
) -> Result<usize, LdpcError> {
    let n = llrs.len();
    if n == 0 || n > MAX_BLOCK_BITS {
        return Err(LdpcError::BlockLength(n));
    }
    if !(1.0..=10.0).contains(&efficiency) {
        return Err(LdpcError::Efficiency(efficiency));
    }
    if !(0.0..=100.0).contains(&finite_length) {
        return Err(LdpcError::FiniteLength(finite_length));
    }
    if let Some(i) = llrs.iter().position(|l| l.is_nan()) {
        return Err(LdpcError::NanLlr(i));
    }
    let soft = soft_limit_bits(llrs);
    let m = (efficiency * soft + finite_length * soft.sqrt()).ceil() as usize;
    Ok(m.clamp(1, n))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_soft_limit_of_a_bsc_is_n_h_q() {
        let q: f64 = 0.05;
        let l = ((1.0 - q) / q).ln();
        let llrs = vec![l; 1000];
        let want = 1000.0 * binary_entropy(q);
        assert!((soft_limit_bits(&llrs) - want).abs() < 1e-9);
        assert_eq!(
            syndrome_length(&llrs, 1.1, 0.0).unwrap(),
            (1.1 * want).ceil() as usize
        );
        // c · √H more: 2 · √(1000 h₂(0.05)) ≈ 39.9 bits.
        assert_eq!(
            syndrome_length(&llrs, 1.1, 2.0).unwrap(),
            (1.1 * want + 2.0 * want.sqrt()).ceil() as usize
        );
    }

    #[test]
    fn the_bhattacharyya_parameter_of_a_bsc_is_2_sqrt_pq() {
        let q: f64 = 0.1;
        let l = ((1.0 - q) / q).ln();
        let b = bhattacharyya(&[l, -l, l]);
        assert!((0.6..0.6 + 1.0 / 1024.0).contains(&b), "{b}");
        assert_eq!(bhattacharyya(&[0.0]), 1.0);
    }

    #[test]
    fn sizes_out_of_range_are_refused() {
        assert_eq!(
            syndrome_length(&[], 1.1, 0.0),
            Err(LdpcError::BlockLength(0))
        );
        assert_eq!(
            syndrome_length(&[1.0], 0.9, 0.0),
            Err(LdpcError::Efficiency(0.9))
        );
        assert_eq!(
            syndrome_length(&[1.0], 1.1, -1.0),
            Err(LdpcError::FiniteLength(-1.0))
        );
        assert_eq!(
            syndrome_length(&[1.0, f64::NAN], 1.1, 0.0),
            Err(LdpcError::NanLlr(1))
        );
        // An LLR of 0 (no information) asks for the whole bit, never more than n.
        assert_eq!(syndrome_length(&[0.0; 10], 2.0, 2.0).unwrap(), 10);
    }
}
