//! Each slice of a multilevel block sized under measured per-wheel slip (docs/estimation.md,
//! "Per-wheel slip" and "Multilevel symbols"). The slip path bounds the block's bits through
//! their pairs of Gaussians (`worst_case::slip_pairs`): at each point of σ²'s grid,
//! `H_min^ε ≥ max_λ (Σᵢ −ln Eᵢ[e^(−λS)] − ln(1/ε))/λ` over the kept bits, the least over the
//! points published as one Gaussian-equivalent separation. A slice is a key of its own, its
//! bits those at one place of every symbol's label; the bound is a sum over bits, so a
//! slice's is the same sum over its own bits alone, under the block's one region (its ε_est
//! event shared by every slice). The exponents each bit's pairs give at the block's λ are
//! evaluated once, for the block's bound, and kept partitioned by slice
//! ([`ChernoffExponents::split`]): each slice is then sized with its own sample removed
//! without a moment evaluated again.

use std::fmt;

use robokey_secrecy::covariance_pair::ChernoffExponents;
use robokey_secrecy::postprocess::SEPARATION_QUANTUM;
use robokey_secrecy::view_profile::gaussian_separation_within;

use super::worst_case::MAX_PUBLISHED_SEPARATION;

/// Each slice's bits' exponents at each point of σ²'s grid the block was sized at: what
/// sizes the slices of a multilevel block whose estimate measured slip.
#[derive(Clone, Default, PartialEq)]
pub struct SlipSlices {
    /// Per point of σ²'s grid, per slice, its bits' exponents at the block's λ.
    points: Vec<Vec<ChernoffExponents>>,
}

impl fmt::Debug for SlipSlices {
    /// The counts (the exponents themselves are many).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let bits: Vec<usize> = self
            .points
            .first()
            .map(|slices| slices.iter().map(ChernoffExponents::bits).collect())
            .unwrap_or_default();
        write!(
            f,
            "SlipSlices {{ points: {}, bits per slice: {bits:?} }}",
            self.points.len()
        )
    }
}

impl SlipSlices {
    /// Keeps one point of σ²'s grid: its `slices`' exponents, one part per slice.
    pub fn push(&mut self, slices: Vec<ChernoffExponents>) {
        self.points.push(slices);
    }

    /// Each point's slices' exponents, for the tests' own bounds over them.
    #[cfg(test)]
    pub(crate) fn points(&self) -> &[Vec<ChernoffExponents>] {
        &self.points
    }

    /// Slices held (none before a point is kept).
    #[must_use]
    pub fn slices(&self) -> usize {
        self.points.first().map_or(0, Vec::len)
    }

    /// Bits of `slice` (0 for a slice not held).
    #[must_use]
    pub fn bits(&self, slice: usize) -> usize {
        self.points
            .first()
            .and_then(|slices| slices.get(slice))
            .map_or(0, ChernoffExponents::bits)
    }

    /// Slice `slice`'s published separation at ε = `epsilon` (ε_est and the smoothing ε), its
    /// own sample's `disclosed` bits taken away (the worst choice): the least over the points
    /// of its bits' bound, as one Gaussian-equivalent separation ([`equivalent_separation`]).
    ///
    /// # Errors
    /// The slice is not held, or the bound has no answer at ε, naming it.
    pub fn separation(&self, slice: usize, disclosed: u64, epsilon: f64) -> Result<f64, String> {
        if slice >= self.slices() || self.points.is_empty() {
            return Err(format!(
                "slice {slice} of {} (allowed: the block's slices)",
                self.slices()
            ));
        }
        let mut least = f64::INFINITY;
        for slices in &self.points {
            let bound = slices[slice]
                .smooth_min_entropy(disclosed, epsilon)
                .map_err(|e| e.to_string())?;
            least = least.min(bound.h_min);
        }
        let kept = (self.bits(slice) as u64).saturating_sub(disclosed);
        equivalent_separation(kept, least, epsilon)
    }
}

/// The smallest Gaussian separation on the published grid (2⁻⁸) whose bound over `kept` bits
/// is no larger than `h_min` (bits) at ε = `epsilon`, at most [`MAX_PUBLISHED_SEPARATION`]:
/// what a block or a slice sized through pairs of Gaussians publishes, from which the robot
/// recomputes ℓ as from any block.
///
/// # Errors
/// ε outside (0, 1), named.
pub fn equivalent_separation(kept: u64, h_min: f64, epsilon: f64) -> Result<f64, String> {
    let largest_micros = (MAX_PUBLISHED_SEPARATION * 1e6) as u64;
    let micros = gaussian_separation_within(kept, h_min, largest_micros, epsilon)
        .map_err(|e| e.to_string())?;
    Ok(((micros * 256 / 1_000_000) as f64 * SEPARATION_QUANTUM).min(MAX_PUBLISHED_SEPARATION))
}
