//! The prior a block's estimate names (docs/estimation.md, "Causality"): what the parties
//! decide from online — the motion noise `noise.process_std` behind each doublet's
//! likelihood, and `private.prior_lag`, which shapes the doublets — before any block's
//! estimate exists. Under private sensing no key's length rests on it; a prior far from the
//! robot costs bits, and a lag left unstated gets the block refused. The first blocks at the
//! defaults are the calibration run; what their estimate measured is the prior to state on
//! both agents (`robokey prior`).

use super::BlockEstimate;
use crate::Config;
use crate::config::SensingMode;

/// One field of the prior and the value the estimate names for it.
#[derive(Clone, Debug, PartialEq)]
pub struct PriorChange {
    /// The configuration field (`noise.process_std`, `private.prior_lag`).
    pub field: &'static str,
    /// Its value in the parties' configuration.
    pub stated: String,
    /// The value the estimate names.
    pub measured: String,
    /// What measured it, in words (the point estimate and its interval).
    pub why: String,
}

/// The prior named by `estimate` (a controller's block estimate under measured sizing) for
/// parties configured as `config`: `config` in private sensing with the fields it measured
/// set, and each change. The motion noise: the point estimate `√Q̂` (m, m, rad; the
/// likelihood's, not the region's worst case, which only sizes the key). The lag: `τ̂` where
/// the block measured one — a two-step block refused for it, or a three-step block whose
/// interval excludes 0 — and 0 where a three-step block's interval reaches 0 (two-step
/// doublets then carry more bits a session; a lag they cannot model is refused, naming it).
/// What the estimate did not measure (the noise of a block refused before it, a two-step
/// block's lag it saw none of) stays as stated.
#[must_use]
pub fn measured_prior(config: &Config, estimate: &BlockEstimate) -> (Config, Vec<PriorChange>) {
    let mut prior = config.clone();
    let mut changes = Vec::new();
    if config.sensing.mode != SensingMode::Private {
        // Only private sensing estimates the plant.
        changes.push(PriorChange {
            field: "sensing.mode",
            stated: "\"odometry\"".into(),
            measured: "\"private\"".into(),
            why: "the controller estimates the plant under private sensing alone".into(),
        });
        prior.sensing.mode = SensingMode::Private;
    }
    let std = estimate.point_std_mm;
    if std.iter().all(|s| s.is_finite() && *s > 0.0) {
        // To a micrometre (a microradian): finer than any interval resolves.
        let measured = std.map(|s| (s * 1e3).round() / 1e6);
        let [low_x, low_y, low_theta] = estimate.lower_std_mm;
        changes.push(PriorChange {
            field: "noise.process_std",
            stated: meters(config.noise.process_std),
            measured: meters(measured),
            why: format!(
                "√Q̂ {:.3} mm, {:.3} mm, {:.3} mrad over {} doublets (the region's lowest \
                 {low_x:.3} mm, {low_y:.3} mm, {low_theta:.3} mrad sized the key)",
                std[0], std[1], std[2], estimate.doublets
            ),
        });
        prior.noise.process_std = measured;
    }
    let lag = match (estimate.unmodelled_lag.as_deref().copied(), estimate.lag) {
        (Some([tau, low, high]), _) => Some((
            tau,
            format!(
                "the two-step block was refused for an actuator lag τ̂ {tau:.4} s [{low:.4}, \
                 {high:.4}]: three-step doublets shaped for it"
            ),
        )),
        (None, Some([tau, low, high])) if low > 0.0 => Some((
            tau,
            format!("τ̂ {tau:.4} s [{low:.4}, {high:.4}] measured by the three-step block"),
        )),
        (None, Some([tau, low, high])) => Some((
            0.0,
            format!(
                "τ̂ {tau:.4} s [{low:.4}, {high:.4}]: no lag told apart from none, so \
                 two-step doublets, which carry more bits a session (a lag they cannot model \
                 is refused, naming it)"
            ),
        )),
        (None, None) => None,
    };
    if let Some((tau, why)) = lag {
        // Four decimals, as the refusal names it and the interval resolves it.
        let tau = (tau * 1e4).round() / 1e4;
        changes.push(PriorChange {
            field: "private.prior_lag",
            stated: format!("{}", config.private.prior_lag),
            measured: format!("{tau}"),
            why,
        });
        prior.private.prior_lag = tau;
    }
    (prior, changes)
}

/// `[x, y, θ]` as the configuration writes it (m, m, rad).
fn meters([x, y, theta]: [f64; 3]) -> String {
    format!("[{x}, {y}, {theta}]")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An estimate of `std_mm` with `lag` (three-step) or `unmodelled` (a refused two-step
    /// block) as given.
    fn estimate(
        std_mm: [f64; 3],
        lag: Option<[f64; 3]>,
        unmodelled: Option<[f64; 3]>,
    ) -> BlockEstimate {
        let three =
            |x: [f64; 3]| format!("[{:?}, {:?}, {:?}]", x[0], x[1], x[2]).replace("NaN", "nan");
        let mut text = format!(
            "doublets = 2212\npoint_std_mm = {}\nlower_std_mm = [0.84, 0.89, 0.83]\n\
             correlation = 0.02\ncorrelation_interval = [-0.1, 0.12]\nepsilon = 1e-6\n\
             separation = 1.4\nlargest = 1.6\n",
            three(std_mm)
        );
        if let Some(lag) = lag {
            text += &format!("lag = {}\n", three(lag));
        }
        if let Some(lag) = unmodelled {
            text += &format!("unmodelled_lag = {}\n", three(lag));
        }
        toml::from_str(&text).unwrap()
    }

    /// The parties at their defaults in private sensing.
    fn private() -> Config {
        let mut config = Config::default();
        config.sensing.mode = crate::config::SensingMode::Private;
        config
    }

    #[test]
    fn a_measured_block_names_its_point_noise_and_lag() {
        let config = private();
        let (prior, changes) = measured_prior(
            &config,
            &estimate([0.963, 1.011, 0.951], Some([0.04966, 0.0476, 0.0517]), None),
        );
        assert_eq!(prior.noise.process_std, [0.963e-3, 1.011e-3, 0.951e-3]);
        assert_eq!(prior.private.prior_lag, 0.0497);
        assert_eq!(changes.len(), 2);
        assert_eq!(changes[0].stated, "[0.004, 0.004, 0.004]");
        assert_eq!(changes[0].measured, "[0.000963, 0.001011, 0.000951]");
        assert_eq!(changes[1].measured, "0.0497");
    }

    #[test]
    fn a_lag_refused_two_step_block_names_the_lag_and_keeps_the_noise() {
        let config = private();
        let refused = estimate([f64::NAN; 3], None, Some([0.0498, 0.0446, 0.0551]));
        let (prior, changes) = measured_prior(&config, &refused);
        assert_eq!(prior.noise.process_std, config.noise.process_std);
        assert_eq!(prior.private.prior_lag, 0.0498);
        assert_eq!(changes.len(), 1);
        assert!(changes[0].why.contains("refused"), "{}", changes[0].why);
        assert!(prior.doublet_settle().is_some(), "three-step doublets");
    }

    #[test]
    fn a_lag_interval_reaching_zero_goes_back_to_two_step_doublets() {
        let mut config = private();
        config.private.prior_lag = 0.05;
        let (prior, changes) = measured_prior(
            &config,
            &estimate([4.0, 4.0, 4.0], Some([0.004, 0.0, 0.012]), None),
        );
        assert_eq!(prior.private.prior_lag, 0.0);
        assert!(prior.doublet_settle().is_none());
        assert_eq!(changes[1].stated, "0.05");
    }

    #[test]
    fn odometry_parties_are_told_to_sense_privately() {
        let (prior, changes) = measured_prior(&Config::default(), &estimate([4.0; 3], None, None));
        assert_eq!(prior.sensing.mode, SensingMode::Private);
        assert_eq!(changes[0].field, "sensing.mode");
    }

    #[test]
    fn a_two_step_block_without_lag_leaves_the_lag_as_stated() {
        let config = private();
        let (prior, changes) = measured_prior(&config, &estimate([4.0; 3], None, None));
        assert_eq!(prior.private.prior_lag, 0.0);
        assert_eq!(changes.len(), 1);
    }
}
