//! The variable-degree profile of a code fitted to its rate and channel.
//!
//! Variables have degree 2, 3 or [`HIGH_DEGREE`]; checks have the nearly constant degree
//! d_c = E/m that the edge count E fixes. The edge fraction on degree-2 variables, λ₂, sits
//! below the stability bound of belief propagation, λ₂ · (d_c − 1) < 1/B, with B the
//! Bhattacharyya parameter of the controller's channel, E[2√(p(1 − p))] over its bits
//! (Richardson–Urbanke, "Modern Coding Theory" §4.9), and at most [`MAX_DEGREE2_EDGES`];
//! λ₃ = [`DEGREE3_EDGES`]; the rest of the edges go to degree [`HIGH_DEGREE`]. The constants
//! were chosen by the block failure rate they measured at f = 1.2 on 10⁵-bit blocks at
//! Q = 0.78 % and 2 % (docs/postprocessing.md).

/// The largest variable degree.
pub const HIGH_DEGREE: usize = 20;

/// Share of the stability bound that λ₂ uses.
const STABILITY_MARGIN: f64 = 0.85;

/// Largest λ₂ at any rate.
const MAX_DEGREE2_EDGES: f64 = 0.30;

/// Edge fraction on degree-3 variables.
const DEGREE3_EDGES: f64 = 0.35;

/// Fractions of *variables* of degree 2, 3 and `HIGH_DEGREE` (they sum to 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DegreeProfile {
    /// Variables of degree 2.
    pub degree2: f64,
    /// Variables of degree 3.
    pub degree3: f64,
    /// Variables of degree `HIGH_DEGREE`.
    pub high: f64,
}

impl DegreeProfile {
    /// The profile for an m × n syndrome code (0 < m ≤ n) on a channel with Bhattacharyya
    /// parameter `bhattacharyya` ∈ (0, 1].
    #[must_use]
    pub fn for_channel(block: usize, syndrome: usize, bhattacharyya: f64) -> Self {
        let ratio = (syndrome as f64 / block.max(1) as f64).clamp(1e-6, 1.0);
        let b = bhattacharyya.clamp(1e-6, 1.0);
        // λ₂ depends on d_c, which depends on the mean variable degree: a few fixed-point steps.
        let mut degree2_edges = MAX_DEGREE2_EDGES;
        for _ in 0..8 {
            let check_degree = Self::from_edges(degree2_edges).mean_degree() / ratio;
            let bound = 1.0 / (b * (check_degree - 1.0).max(1.0));
            degree2_edges = (STABILITY_MARGIN * bound).min(MAX_DEGREE2_EDGES);
        }
        Self::from_edges(degree2_edges)
    }

    /// Node fractions from edge fractions λ₂, λ₃ = [`DEGREE3_EDGES`], λ_high = the rest:
    /// variables of degree d ∝ λ_d / d.
    fn from_edges(degree2_edges: f64) -> Self {
        let high_edges = 1.0 - degree2_edges - DEGREE3_EDGES;
        let (a, b, c) = (
            degree2_edges / 2.0,
            DEGREE3_EDGES / 3.0,
            high_edges / HIGH_DEGREE as f64,
        );
        let total = a + b + c;
        Self {
            degree2: a / total,
            degree3: b / total,
            high: c / total,
        }
    }

    /// Mean variable degree.
    #[must_use]
    pub fn mean_degree(&self) -> f64 {
        2.0 * self.degree2 + 3.0 * self.degree3 + HIGH_DEGREE as f64 * self.high
    }

    /// The degree of each of `n` variables: the degree-2 ones first, then degree 3, then high
    /// (the construction shuffles them).
    #[must_use]
    pub fn variable_degrees(&self, n: usize) -> Vec<u32> {
        let twos = ((self.degree2 * n as f64).round() as usize).min(n);
        let threes = ((self.degree3 * n as f64).round() as usize).min(n - twos);
        (0..n)
            .map(|v| {
                if v < twos {
                    2
                } else if v < twos + threes {
                    3
                } else {
                    HIGH_DEGREE as u32
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn node_fractions_sum_to_one_and_degree2_edges_respect_stability() {
        for (m, b) in [(4_000, 0.05), (4_000, 0.2), (30_000, 0.5), (90_000, 0.9)] {
            let n = 100_000;
            let profile = DegreeProfile::for_channel(n, m, b);
            let sum = profile.degree2 + profile.degree3 + profile.high;
            assert!((sum - 1.0).abs() < 1e-12, "{profile:?}");
            let lambda2 = 2.0 * profile.degree2 / profile.mean_degree();
            let dc = profile.mean_degree() * n as f64 / m as f64;
            assert!(lambda2 * (dc - 1.0) * b < 1.0, "{profile:?}");
            assert!(lambda2 <= MAX_DEGREE2_EDGES + 1e-12, "{profile:?}");
        }
    }

    #[test]
    fn degrees_follow_the_fractions() {
        let profile = DegreeProfile::for_channel(10_000, 3_000, 0.3);
        let degrees = profile.variable_degrees(10_000);
        let twos = degrees.iter().filter(|&&d| d == 2).count() as f64 / 1e4;
        assert!((twos - profile.degree2).abs() < 1e-3);
        assert_eq!(degrees.len(), 10_000);
    }
}
