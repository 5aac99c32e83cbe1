//! The secrecy limit of a doublet's alphabet (docs/private-sensing.md, "Maps"): per doublet
//! and dimension, the margin `C = I(X; Y_c) − I(X; Y_e)` of a symbol `X` of unit mean power
//! seen by the controller as `Y_c = X + N_c` and by Eve as `Y_e = X + N_e`, Gaussian noises of
//! variance `1/snr_c` and `1/snr_e`. Through a one-way code from the robot, no scheme that
//! draws its symbols from the alphabet uniformly keeps more secret bits per symbol than `C`
//! against an Eve whose view is degraded.
//!
//! A party whose view separates the binary symbols `±1` by a Mahalanobis distance `d` sees the
//! symbol at `snr = (d/2)²` ([`snr_of_separation`]): its sufficient statistic is a scalar
//! Gaussian whose mean moves by `d` between `−1` and `+1`.
//!
//! Accuracy: the Gaussian-weighted integral of [`mutual_information`] is taken by the
//! trapezoid rule on `z ∈ [−10, 10]` with a step of at most half the narrowest bend of the
//! integrand; the integrand is analytic in a strip of that width, so the rule's error is
//! below `e^{−4π²}` ≈ 10⁻¹⁷ relative, and the truncated tails weigh below 10⁻²¹: every
//! figure is exact to ≈ 10⁻¹² bit (rounding), checked against closed forms in the tests.

/// A symbol alphabet of unit mean power.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Alphabet {
    /// `levels` equiprobable amplitudes `(levels − 1 − 2i)/√E`, `E = (levels² − 1)/3`
    /// (binary: `±1`).
    Pam {
        /// Amplitudes: 2, 4, 8, … (at least 2).
        levels: u8,
    },
    /// A standard Gaussian input: the capacity-achieving one at every SNR.
    Gaussian,
}

impl Alphabet {
    /// The alphabet's amplitudes, of unit mean square (empty for the Gaussian).
    #[must_use]
    pub fn amplitudes(self) -> Vec<f64> {
        match self {
            Self::Pam { levels } => {
                let levels = f64::from(levels.max(2));
                let mean_square = (levels * levels - 1.0) / 3.0;
                (0..levels as usize)
                    .map(|i| (levels - 1.0 - 2.0 * i as f64) / mean_square.sqrt())
                    .collect()
            }
            Self::Gaussian => Vec::new(),
        }
    }
}

/// Half-width of the grid of the standard normal variable `z`.
const Z_MAX: f64 = 10.0;
/// The largest trapezoid step over `z`.
const MAX_STEP: f64 = 0.25;

/// The SNR at which a view sees a unit-power symbol when it separates the binary symbols
/// `±1` by the Mahalanobis distance `separation`: `(d/2)²`.
#[must_use]
pub fn snr_of_separation(separation: f64) -> f64 {
    (separation / 2.0).powi(2)
}

/// `I(X; X + N)` in bits for `X` from `alphabet` (uniform, unit mean power) and `N ~ N(0,
/// 1/snr)`; 0 for `snr ≤ 0` or a non-finite one. The Gaussian: `½·log₂(1 + snr)`. PAM with
/// amplitudes `xᵢ`, `δᵢⱼ = (xᵢ − xⱼ)·√snr`:
/// `I = log₂ L − (1/L)·Σᵢ E_z[log₂ Σⱼ e^{−δᵢⱼ²/2 − δᵢⱼ·z}]`, `z ~ N(0, 1)`.
#[must_use]
pub fn mutual_information(alphabet: Alphabet, snr: f64) -> f64 {
    if !(snr.is_finite() && snr > 0.0) {
        return 0.0;
    }
    let amplitudes = match alphabet {
        Alphabet::Gaussian => return 0.5 * snr.ln_1p() / std::f64::consts::LN_2,
        Alphabet::Pam { .. } => alphabet.amplitudes(),
    };
    let scale = snr.sqrt();
    // The integrand bends where two terms of the sum cross, over a width `1/δ` of z for the
    // closest amplitudes `δ` apart.
    let closest = (amplitudes[0] - amplitudes[1]).abs() * scale;
    let step = MAX_STEP.min(0.5 / closest);
    let nodes = (Z_MAX / step).ceil() as i64;
    let step = Z_MAX / nodes as f64;
    let mut total = 0.0;
    for &x in &amplitudes {
        let deltas: Vec<f64> = amplitudes.iter().map(|&y| (x - y) * scale).collect();
        let mut sum = 0.0;
        for k in -nodes..=nodes {
            let z = k as f64 * step;
            let exponents = deltas.iter().map(|&d| -0.5 * d * d - d * z);
            let largest = exponents.clone().fold(f64::NEG_INFINITY, f64::max);
            let log_sum = largest + exponents.map(|e| (e - largest).exp()).sum::<f64>().ln();
            sum += (-0.5 * z * z).exp() * log_sum;
        }
        total += sum * step / (2.0 * std::f64::consts::PI).sqrt();
    }
    let levels = amplitudes.len() as f64;
    levels.log2() - total / levels / std::f64::consts::LN_2
}

/// The secrecy margin `I(X; Y_c) − I(X; Y_e)` (bits per symbol) of `alphabet` for a
/// controller at `snr_controller` and an Eve at `snr_eve` (negative when Eve sees better).
#[must_use]
pub fn secrecy_margin(alphabet: Alphabet, snr_controller: f64, snr_eve: f64) -> f64 {
    mutual_information(alphabet, snr_controller) - mutual_information(alphabet, snr_eve)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gaussian_llr;

    const BINARY: Alphabet = Alphabet::Pam { levels: 2 };

    /// Binary ±1 through Gaussian noise is BPSK: its information is the LLR form
    /// `1 − E[log₂(1 + e^{−L})]`, `L ~ N(d²/2, d²)`, computed by [`gaussian_llr`] on its own
    /// grid, and 0.4859 bit at 0 dB (the BI-AWGN capacity at Es/σ² = 1).
    #[test]
    fn binary_is_bpsk_through_awgn() {
        for d in [0.1, 0.5, 1.0, 2.0, 3.3, 5.0, 8.0, 12.0] {
            let direct = mutual_information(BINARY, snr_of_separation(d));
            let llr_form = gaussian_llr::information(d);
            assert!(
                (direct - llr_form).abs() < 1e-9,
                "d {d}: {direct} vs {llr_form}"
            );
        }
        assert!((mutual_information(BINARY, 1.0) - 0.485_94).abs() < 5e-6);
    }

    /// Nothing beats a Gaussian input at the same power; every zero-mean input of unit power
    /// reaches `½·log₂(1 + snr)` to first order as the SNR falls (they differ by O(snr²));
    /// an alphabet of L amplitudes tends to log₂ L as the noise vanishes.
    #[test]
    fn the_gaussian_limit_bounds_and_is_reached_at_low_snr() {
        for levels in [2, 4, 8] {
            let pam = Alphabet::Pam { levels };
            for snr in [0.01, 0.1, 0.5, 1.0, 3.0, 10.0, 100.0, 1e4] {
                let gaussian = mutual_information(Alphabet::Gaussian, snr);
                let i = mutual_information(pam, snr);
                assert!(
                    i <= gaussian + 1e-12,
                    "{levels}-PAM at {snr}: {i} > {gaussian}"
                );
                assert!(i > 0.0);
            }
            let snr = 1e-3;
            let gap = mutual_information(Alphabet::Gaussian, snr) - mutual_information(pam, snr);
            assert!((0.0..snr * snr).contains(&gap), "{levels}-PAM: {gap}");
            let high = mutual_information(pam, 1e6);
            assert!((high - f64::from(levels).log2()).abs() < 1e-9, "{high}");
        }
        let (c, e) = (5.85, 0.68);
        let margin = secrecy_margin(Alphabet::Gaussian, c, e);
        assert!((margin - 0.5 * ((1.0 + c) / (1.0 + e)).log2()).abs() < 1e-15);
    }

    /// The figures of the defaults' views (N_c = 8.375 mm², N_e = 72.1 mm², amplitude
    /// ΔT = 7 mm): binary 0.600 bit at ΔT, at most 0.643 near 0.8·ΔT; 4-PAM and 8-PAM of the
    /// same power ≈ 0.94 and ≈ 0.96 as quoted (computed: 0.930 and 0.953); a Gaussian ≈ 1.0.
    #[test]
    fn the_defaults_margins_are_the_quoted_ones() {
        let (nc, ne, a) = (8.375, 72.1, 7.0);
        let at = |alphabet: Alphabet, k: f64| {
            let power = (k * a) * (k * a);
            secrecy_margin(alphabet, power / nc, power / ne)
        };
        assert!(
            (at(BINARY, 1.0) - 0.600).abs() < 5e-4,
            "{}",
            at(BINARY, 1.0)
        );
        let (peak, k) = (60..=100)
            .map(|i| f64::from(i) / 100.0)
            .map(|k| (at(BINARY, k), k))
            .fold((0.0, 0.0), |best, x| if x.0 > best.0 { x } else { best });
        assert!((peak - 0.643).abs() < 0.005, "peak {peak} at {k}");
        assert!((0.75..=0.85).contains(&k), "peak at {k}");
        let four = at(Alphabet::Pam { levels: 4 }, 1.0);
        let eight = at(Alphabet::Pam { levels: 8 }, 1.0);
        assert!(
            (four - 0.930).abs() < 5e-4 && (four - 0.94).abs() < 0.015,
            "{four}"
        );
        assert!(
            (eight - 0.953).abs() < 5e-4 && (eight - 0.96).abs() < 0.01,
            "{eight}"
        );
        assert!((at(Alphabet::Gaussian, 1.0) - 1.0).abs() < 0.02);
    }

    #[test]
    fn nothing_is_learnt_through_no_signal() {
        for snr in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert_eq!(mutual_information(BINARY, snr), 0.0);
        }
        assert_eq!(snr_of_separation(4.0), 4.0);
    }
}
