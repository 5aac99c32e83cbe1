//! Syndrome decoding by log-domain sum-product belief propagation, layered (check by check).
//!
//! Each variable v keeps its posterior Λᵥ = Lᵥ + Σ_c r_{c→v}. Visiting check c with syndrome
//! bit s_c, every edge's incoming message is q_{v→c} = Λᵥ − r_{c→v}; the outgoing one is
//! r_{c→v} = (−1)^{s_c} · Π_{w≠v} sgn q_{w→c} · φ(Σ_{w≠v} φ(|q_{w→c}|)) with
//! φ(x) = −ln tanh(x/2) = ln(1 + e^{−x}) − ln(1 − e^{−x}) (its own inverse), and Λᵥ is
//! updated at once (Hocevar's layered schedule, which converges in about half the iterations
//! of flooding). After each pass over the checks the hard decisions `x̂ᵥ = [Λᵥ < 0]` are tested
//! against the syndrome; decoding stops when they meet it or after the iteration cap.

use super::code::{ParityCheck, bit};
use super::{LdpcError, MAX_ITERATIONS};
use crate::bitstring::BitString;

/// Magnitudes below this are raised to it before φ (φ(10⁻⁹) ≈ 21.4), keeping sums finite.
const SMALLEST_MAGNITUDE: f64 = 1e-9;

/// LLRs are clipped to ±this (a bit-error probability of e⁻⁴⁰ ≈ 4·10⁻¹⁸).
const LARGEST_LLR: f64 = 40.0;

/// φ is tabulated on [0, [`TABLE_END`]) in steps of 1/[`TABLE_STEPS_PER_UNIT`], linearly
/// interpolated (error < 10⁻³ where used), and computed exactly below [`TABLE_FROM`].
const TABLE_STEPS_PER_UNIT: f64 = 256.0;
/// End of the φ table (φ(20) ≈ 4·10⁻⁹; beyond it φ(x) ≈ 2e^{−x} is exact to 10⁻¹⁷).
const TABLE_END: f64 = 20.0;
/// Below this φ is computed exactly (its curvature, ≈ 1/x², defeats the table).
const TABLE_FROM: f64 = 0.0625;

/// Belief propagation with an iteration cap.
#[derive(Debug, Clone, PartialEq)]
pub struct SyndromeDecoder {
    max_iterations: u32,
    /// φ(k / [`TABLE_STEPS_PER_UNIT`]) for k = 0, 1, … up to [`TABLE_END`].
    table: Vec<f64>,
}

/// What the decoder found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Decoded {
    /// The hard decisions after the last iteration.
    pub bits: BitString,
    /// Whether they meet the syndrome (if not, the block has failed).
    pub converged: bool,
    /// Iterations run.
    pub iterations: u32,
}

impl SyndromeDecoder {
    /// A decoder running at most `max_iterations` ∈ 1..=[`MAX_ITERATIONS`] passes.
    pub fn new(max_iterations: u32) -> Result<Self, LdpcError> {
        if max_iterations == 0 || max_iterations > MAX_ITERATIONS {
            return Err(LdpcError::Iterations(max_iterations));
        }
        let entries = (TABLE_END * TABLE_STEPS_PER_UNIT) as usize + 2;
        let table = (0..entries)
            .map(|k| phi(k as f64 / TABLE_STEPS_PER_UNIT))
            .collect();
        Ok(Self {
            max_iterations,
            table,
        })
    }

    /// The bits x̂ with H·x̂ = `syndrome` most likely under the LLRs
    /// Lᵥ = ln P(xᵥ = 0)/P(xᵥ = 1), within the decoder's iteration cap.
    pub fn decode(
        &self,
        code: &ParityCheck,
        llrs: &[f64],
        syndrome: &BitString,
    ) -> Result<Decoded, LdpcError> {
        self.decode_within(code, llrs, syndrome, self.max_iterations)
    }

    /// [`Self::decode`] with at most `iterations` passes (never more than the decoder's cap).
    pub fn decode_within(
        &self,
        code: &ParityCheck,
        llrs: &[f64],
        syndrome: &BitString,
        iterations: u32,
    ) -> Result<Decoded, LdpcError> {
        let cap = iterations.min(self.max_iterations);
        if llrs.len() != code.block() {
            return Err(LdpcError::Length {
                what: "LLRs",
                got: llrs.len(),
                expected: code.block(),
            });
        }
        if syndrome.len() != code.syndrome_bits() {
            return Err(LdpcError::Length {
                what: "syndrome",
                got: syndrome.len(),
                expected: code.syndrome_bits(),
            });
        }
        if let Some(i) = llrs.iter().position(|l| l.is_nan()) {
            return Err(LdpcError::NanLlr(i));
        }
        let flips = syndrome.words();
        let mut posterior: Vec<f64> = llrs
            .iter()
            .map(|l| l.clamp(-LARGEST_LLR, LARGEST_LLR))
            .collect();
        let mut messages = vec![0.0_f64; code.edges()];
        let mut incoming: Vec<f64> = Vec::new();
        let mut magnitudes: Vec<f64> = Vec::new();
        let mut iterations = 0;
        let mut converged = meets(code, &posterior, flips);
        while !converged && iterations < cap {
            iterations += 1;
            let mut edge = 0;
            for c in 0..code.syndrome_bits() {
                let check = code.check(c);
                let outgoing = &mut messages[edge..edge + check.len()];
                edge += check.len();
                incoming.clear();
                magnitudes.clear();
                let mut negative = bit(flips, c);
                let mut sum = 0.0;
                for (&v, &r) in check.iter().zip(outgoing.iter()) {
                    let q = posterior[v as usize] - r;
                    negative ^= q < 0.0;
                    let phi_q = self.phi(q.abs());
                    sum += phi_q;
                    incoming.push(q);
                    magnitudes.push(phi_q);
                }
                for (k, &v) in check.iter().enumerate() {
                    let q = incoming[k];
                    let magnitude = self.phi((sum - magnitudes[k]).max(0.0)).min(LARGEST_LLR);
                    let r = if negative ^ (q < 0.0) {
                        -magnitude
                    } else {
                        magnitude
                    };
                    outgoing[k] = r;
                    posterior[v as usize] = q + r;
                }
            }
            converged = meets(code, &posterior, flips);
        }
        let decisions: Vec<bool> = posterior.iter().map(|&l| l < 0.0).collect();
        Ok(Decoded {
            bits: BitString::from_bools(&decisions),
            converged,
            iterations,
        })
    }
}

impl SyndromeDecoder {
    /// φ(x) from the table, exactly below [`TABLE_FROM`], 2e^{−x} beyond [`TABLE_END`].
    fn phi(&self, x: f64) -> f64 {
        if x < TABLE_FROM {
            phi(x)
        } else if x >= TABLE_END {
            2.0 * (-x).exp()
        } else {
            let at = x * TABLE_STEPS_PER_UNIT;
            let k = at as usize;
            let w = at - k as f64;
            self.table[k] + w * (self.table[k + 1] - self.table[k])
        }
    }
}

/// φ(x) = −ln tanh(x/2) for x ≥ 0, with x raised to [`SMALLEST_MAGNITUDE`].
fn phi(x: f64) -> f64 {
    let e = (-x.max(SMALLEST_MAGNITUDE)).exp();
    e.ln_1p() - (-e).ln_1p()
}

/// Whether the hard decisions of `posterior` meet the syndrome (packed in `flips`).
fn meets(code: &ParityCheck, posterior: &[f64], flips: &[u64]) -> bool {
    (0..code.syndrome_bits()).all(|c| {
        !code
            .check(c)
            .iter()
            .fold(bit(flips, c), |p, &v| p ^ (posterior[v as usize] < 0.0))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tabulated_phi_is_within_a_thousandth_of_the_exact_one() {
        let decoder = SyndromeDecoder::new(1).unwrap();
        for k in 0..4_000 {
            let x = f64::from(k) * 0.00731;
            let (table, exact) = (decoder.phi(x), phi(x));
            assert!((table - exact).abs() < 1e-3 * exact.max(1.0), "{x}");
        }
    }

    #[test]
    fn phi_is_its_own_inverse() {
        for x in [0.01, 0.5, 1.0, 3.0, 10.0] {
            assert!((phi(phi(x)) - x).abs() < 1e-9 * x.max(1.0), "{x}");
        }
    }

    #[test]
    fn a_noisy_copy_is_corrected_at_a_generous_rate() {
        let n = 20_000;
        let (x, llrs, errors) = super::super::test_block::bsc_block(n, 0.03, 11);
        assert!(errors > 400, "{errors}");
        // m = 1.5 · n · h(0.03) ≈ 0.29 n: far above the limit.
        let code = ParityCheck::build(n, 5_900, 0.3, [2; 32]).unwrap();
        let decoded = SyndromeDecoder::new(100)
            .unwrap()
            .decode(&code, &llrs, &code.syndrome(&x).unwrap())
            .unwrap();
        assert!(decoded.converged);
        assert_eq!(decoded.bits, x);
    }

    #[test]
    fn lengths_and_caps_are_checked() {
        assert_eq!(SyndromeDecoder::new(0), Err(LdpcError::Iterations(0)));
        assert!(SyndromeDecoder::new(MAX_ITERATIONS + 1).is_err());
        let code = ParityCheck::build(100, 10, 0.3, [0; 32]).unwrap();
        let decoder = SyndromeDecoder::new(10).unwrap();
        assert!(matches!(
            decoder.decode(&code, &[0.0; 99], &BitString::zeros(10)),
            Err(LdpcError::Length { what: "LLRs", .. })
        ));
        assert!(matches!(
            decoder.decode(&code, &[0.0; 100], &BitString::zeros(9)),
            Err(LdpcError::Length {
                what: "syndrome",
                ..
            })
        ));
    }
}
