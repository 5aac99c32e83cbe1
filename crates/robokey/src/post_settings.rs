//! The post-processing settings a configuration implies: the same in the agents and in the
//! simulator, so that both size keys under the same stated assumption about Eve
//! (docs/postprocessing.md, docs/secrecy.md).

use robokey_secrecy::cascade::CascadeSchedule;
use robokey_secrecy::ldpc::LdpcSettings;
use robokey_secrecy::postprocess::{Assumption, ReconciliationMethod, Settings};
use serde::{Deserialize, Serialize};

use crate::config::camera::millimetres;
use crate::config::{Config, Reconciliation, SensingMode, Sizing};
use crate::estimate::ESTIMATE_LEAK_BITS;
use crate::private::Perturbation;
use crate::world::Camera;

/// Why the odometry mode yields no secret bit against an eavesdropper who learns the model.
pub const ODOMETRY_ZERO: &str = "zero by structure: in odometry mode everything the controller \
    decides from is public except r and D, which an eavesdropper learns from the traffic (the \
    identifying Eve within about one session); she then decides as the controller does, so \
    I(B; controller | Eve) = 0 and no post-processing yields a secret bit";

/// Eve's camera as a key's assumption states it: per instant (her effective noise after her
/// own filtering), or her frames with what they are worth per instant.
#[must_use]
pub fn camera_words(config: &Config) -> String {
    let statement = config.camera_statement();
    match statement {
        Camera::Instants { .. } => format!(
            "{} (her effective noise after her own filtering)",
            statement.describe()
        ),
        Camera::Frames { .. } => {
            let e = config.modelled_camera_std().map(|x| 1e3 * x);
            format!(
                "{}, any phase (worth {:.2} mm, {:.2} mm, {:.2} mrad per sample instant)",
                statement.describe(),
                e[0],
                e[1],
                e[2],
            )
        }
    }
}

/// The plant's model class a private-sensing key rests on: white Gaussian motion noise of
/// `noise.process_std` per step as configured, or (`postprocess.sizing = "measured"`) a 3×3
/// stationary covariance and its AR(1) correlation between steps the controller measures per
/// block, at the worst case of their (1 − ε_est) region, with per-wheel slip measured beside
/// them and sized where the estimate sees it, and the controller's sample-timing jitter
/// measured per block; no lag or delay, the Euler map; with `private.prior_lag` τ > 0, the
/// doublets shaped in three steps for a first-order actuator lag of τ (the stated prior),
/// which measured sizing measures per block (and no slip or jitter); with
/// `robot.command_quantum` q > 0, each wheel's command rounded to q (stated).
#[must_use]
pub fn plant_words(config: &Config) -> String {
    let class = plant_class_words(config);
    match config.robot.command_quantum {
        0.0 => class,
        quantum => format!(
            "{class}; each wheel's speed command rounded to {quantum} rad/s \
             (robot.command_quantum, stated)"
        ),
    }
}

/// [`plant_words`] without the command quantum.
fn plant_class_words(config: &Config) -> String {
    // What the motion words leave out of the class: the configured noise is white.
    let (motion, correlation) = match config.sizing() {
        Sizing::Configured => (
            format!(
                "white Gaussian motion noise {} per step as configured (not measured)",
                millimetres(config.noise.process_std)
            ),
            "correlation, ",
        ),
        Sizing::Measured => (
            format!(
                "Gaussian motion noise measured by the controller per block (a 3×3 stationary \
                 covariance in the robot's frame and its AR(1) correlation between steps, \
                 ρ ≥ −0.5, sized at the worst case of their (1 − ε_est) region, ε_est = {:e}; \
                 the controller sensor's calibration {} stated)",
                config.postprocess.epsilon,
                millimetres(config.sensing.controller_std)
            ),
            "",
        ),
        Sizing::World => (
            "Gaussian motion noise and its AR(1) correlation those of the simulated world, \
             known (a lab comparison, not a robot's)"
                .to_owned(),
            "",
        ),
    };
    if config.private.is_default() && config.sizing() != Sizing::Measured {
        format!("{motion}, no {correlation}slip, lag or delay, the Euler map")
    } else if config.private.is_default() {
        format!(
            "{motion}, per-wheel slip measured with it per block and, where the estimate sees \
             it, sized with it (each bit's view then two Gaussians with covariances of their \
             own; above 50 % refused), the controller's sample-timing jitter measured per \
             block (each sample's noise R + j²·uuᵀ at its public rate u; its interval's upper end \
             bounds the motion noise, its lower end Eve's view; above a tenth of \
             robot.T refused), no lag or delay, the Euler map"
        )
    } else if config.sizing() == Sizing::Measured {
        format!(
            "{motion}, no slip or sample-timing jitter, the Euler map; three-step doublets \
             shaped for a prior actuator \
             lag of {} ms (private.prior_lag), the wheels' first-order lag measured per block \
             and sized over its (1 − ε_est/3) interval (a dead time read as the lag that \
             explains it)",
            config.private.prior_lag * 1e3
        )
    } else {
        format!(
            "{motion}, no {correlation}slip or delay, the Euler map; three-step doublets shaped \
             for a first-order actuator lag of {} ms (private.prior_lag, stated, not measured)",
            config.private.prior_lag * 1e3
        )
    }
}

/// The two assumptions a private-sensing key rests on, written in its record.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct KeyBasis {
    /// Eve's camera ([`camera_words`]).
    pub camera: String,
    /// The plant's model class ([`plant_words`]).
    pub plant: String,
}

/// What `config`'s keys rest on: in private sensing its camera statement and plant model
/// class; none in odometry mode (its keys rest on `postprocess.assumed_eve_error`, a
/// restricted assumption, or do not exist).
#[must_use]
pub fn key_basis(config: &Config) -> Option<KeyBasis> {
    (config.sensing.mode == SensingMode::Private).then(|| KeyBasis {
        camera: camera_words(config),
        plant: plant_words(config),
    })
}

/// Private sensing's statement about Eve for `config`: her camera noise at least
/// `eve.camera_std` per instant (or her frames, `eve.camera_fps` and `eve.camera_frame_std`),
/// the true motion noise, the exact model, the controller's boundary samples hers; her view
/// of each bit at most as informative as a Gaussian LLR of `separation`.
#[must_use]
pub fn camera_assumption(config: &Config, separation: f64) -> Assumption {
    Assumption::GaussianViews {
        separation,
        statement: format!(
            "Eve's camera noise ≥ {}, motion noise {} per step, exact model, the controller's \
             boundary samples known to her",
            camera_words(config),
            millimetres(config.noise.process_std),
        ),
    }
}

/// Private sensing's statement about Eve with the plant measured (docs/estimation.md): her
/// camera noise at least `eve.camera_std`, the exact model and the controller's boundary
/// samples hers, the motion noise the controller estimates per block from its own samples
/// (Gaussian, a 3×3 stationary covariance in the robot's frame and AR(1) correlation
/// ρ ≥ −½ between steps; the sensor's calibration
/// `sensing.controller_std` stated); her view of each bit at most as informative as a
/// Gaussian LLR of `separation` at the worst case of the estimate's (1 − `estimation_epsilon`)
/// region; the published outcome of the estimate charged [`ESTIMATE_LEAK_BITS`] — per slice
/// of a multilevel block, each slice's key for all `m = log₂ protocol.levels` slices'
/// outcomes (`estimate_leak`).
#[must_use]
pub fn measured_camera_assumption(
    config: &Config,
    separation: f64,
    estimation_epsilon: f64,
) -> Assumption {
    plant_sized_assumption(
        config,
        separation,
        estimation_epsilon,
        "motion noise measured by the controller per block",
    )
}

/// [`measured_camera_assumption`] for `robokey secrecy --sizing world`: the motion noise and
/// its correlation are the simulated world's, known to the parties, sized and charged as
/// the measured sizing is (a lab comparison; no robot knows its world).
#[must_use]
pub fn world_camera_assumption(
    config: &Config,
    separation: f64,
    estimation_epsilon: f64,
) -> Assumption {
    plant_sized_assumption(
        config,
        separation,
        estimation_epsilon,
        "motion noise and its correlation those of the simulated world, known to the parties \
         (--sizing world: a pair configured with the true world, sized and charged as measured \
         sizing is, its region the world's values alone)",
    )
}

/// The statement of [`measured_camera_assumption`] with `motion` saying where the motion
/// noise comes from.
fn plant_sized_assumption(
    config: &Config,
    separation: f64,
    estimation_epsilon: f64,
    motion: &str,
) -> Assumption {
    Assumption::MeasuredViews {
        separation,
        statement: format!(
            "Eve's camera noise ≥ {}, {motion} \
             (Gaussian, 3×3 in the robot's frame, AR(1)-correlated between steps with ρ ≥ −0.5, \
             the controller sensor's calibration {} stated), exact model, the controller's \
             boundary samples known to her",
            camera_words(config),
            millimetres(config.sensing.controller_std),
        ),
        estimation_epsilon,
        estimate_leak: estimate_leak(config),
    }
}

/// What a key sized from the measured plant is charged for the published outcomes of its
/// block's estimate (bits): [`ESTIMATE_LEAK_BITS`] for the one outcome of a binary block. A
/// multilevel block's `m = log₂ protocol.levels` slices each publish the equivalent
/// separation of their own bits under the block's one estimate, and that estimate depends
/// on every slice's bits (the residuals subtract whole symbols): each slice's key is charged
/// all m outcomes, `m·log₂(2¹⁶ + 2)` bits.
fn estimate_leak(config: &Config) -> f64 {
    ESTIMATE_LEAK_BITS * Perturbation::of(config).bits_per_symbol() as f64
}

/// The assumption that sizes the agents' keys: private sensing's camera statement (each
/// block's separation computed by the controller from its samples; with
/// `postprocess.sizing = "measured"` at the worst case of the plant it measures per block,
/// ε_est = `postprocess.epsilon`); in odometry mode none (ℓ = 0, [`ODOMETRY_ZERO`]) unless
/// `postprocess.assumed_eve_error` states a restricted one.
#[must_use]
pub fn assumption(config: &Config) -> Assumption {
    match (config.sensing.mode, config.postprocess.assumed_eve_error) {
        (SensingMode::Private, _) if config.sizing() == Sizing::Measured => {
            measured_camera_assumption(config, 0.0, config.postprocess.epsilon)
        }
        (SensingMode::Private, _) => camera_assumption(config, 0.0),
        (SensingMode::Odometry, Some(error_rate)) => Assumption::IndependentErrors { error_rate },
        (SensingMode::Odometry, None) => Assumption::NoSecrecy {
            reason: ODOMETRY_ZERO.to_owned(),
        },
    }
}

/// The agents' post-processing settings for a validated `config`.
#[must_use]
pub fn post_settings(config: &Config) -> Settings {
    let post = &config.postprocess;
    Settings {
        block_bits: post.block_bits as usize,
        sample_bits: post.sample_bits as usize,
        epsilon: post.epsilon,
        schedule: CascadeSchedule::BICONF,
        assumption: assumption(config),
        reconciliation: reconciliation_method(config.postprocess.reconciliation),
    }
}

/// The endpoints' reconciliation for `postprocess.reconciliation`: Cascade, or LDPC with
/// the library's settings ([`LdpcSettings::DEFAULT`]).
#[must_use]
pub fn reconciliation_method(reconciliation: Reconciliation) -> ReconciliationMethod {
    match reconciliation {
        Reconciliation::Cascade => ReconciliationMethod::Cascade,
        Reconciliation::Ldpc => ReconciliationMethod::Ldpc(LdpcSettings::DEFAULT),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_give_valid_settings_in_both_modes() {
        let mut config = Config::default();
        assert!(post_settings(&config).check().is_ok());
        assert!(matches!(assumption(&config), Assumption::NoSecrecy { .. }));
        config.postprocess.assumed_eve_error = Some(0.2);
        assert!(assumption(&config).is_restricted());
        config.postprocess.assumed_eve_error = None;
        config.sensing.mode = SensingMode::Private;
        let private = post_settings(&config);
        assert!(private.check().is_ok());
        assert!(!private.assumption.is_restricted());
        assert!(
            private
                .assumption
                .describe()
                .contains("camera noise ≥ 8 mm")
        );
    }

    /// A key sized from the measured plant is charged the published outcomes of its block's
    /// estimate: one for binary doublets, one per slice — `m·log₂(2¹⁶ + 2)` bits — for each
    /// slice of a multilevel block (every outcome depends on every slice's bits).
    #[test]
    fn a_measured_key_is_charged_every_slices_published_outcome() {
        let charged = |levels: u8| {
            let mut config = Config::default();
            config.sensing.mode = SensingMode::Private;
            config.protocol.levels = levels;
            match measured_camera_assumption(&config, 1.0, 1e-6) {
                Assumption::MeasuredViews { estimate_leak, .. } => estimate_leak,
                other => panic!("{other:?}"),
            }
        };
        assert_eq!(charged(2), ESTIMATE_LEAK_BITS);
        assert_eq!(charged(4), 2.0 * ESTIMATE_LEAK_BITS);
        assert_eq!(charged(8), 3.0 * ESTIMATE_LEAK_BITS);
    }

    #[test]
    fn a_private_keys_basis_names_the_camera_and_the_plant() {
        let mut config = Config::default();
        assert_eq!(key_basis(&config), None);
        config.sensing.mode = SensingMode::Private;
        config.postprocess.sizing = Some(Sizing::Configured);
        let basis = key_basis(&config).unwrap();
        assert_eq!(
            basis.camera,
            "8 mm, 8 mm, 8 mrad per sample instant (her effective noise after her own filtering)"
        );
        assert!(
            basis
                .plant
                .starts_with("white Gaussian motion noise 4 mm, 4 mm, 4 mrad")
        );
        config.eve.camera_fps = Some(30.0);
        config.eve.camera_frame_std = Some([0.016; 3]);
        let basis = key_basis(&config).unwrap();
        assert_eq!(
            basis.camera,
            "16 mm, 16 mm, 16 mrad per frame at 30 frames/s, any phase (worth 7.95 mm, 7.95 mm, \
             7.95 mrad per sample instant)"
        );
        assert!(
            camera_assumption(&config, 1.0)
                .describe()
                .contains(&basis.camera)
        );
        assert!(basis.plant.contains("no correlation, slip, lag or delay"));
        config.private.prior_lag = 0.05;
        let shaped = key_basis(&config).unwrap().plant;
        assert!(
            shaped.contains("three-step doublets shaped for a first-order actuator lag of 50 ms"),
            "{shaped}"
        );
        // Unset under private sensing, the sizing is the measured one.
        config.postprocess.sizing = None;
        let measured = key_basis(&config).unwrap().plant;
        assert!(
            measured.contains("the wheels' first-order lag measured per block"),
            "{measured}"
        );
        // Two-step doublets sized from the measured plant: slip is in the class, measured and
        // sized where seen (under three-step doublets it is refused, so not in their class).
        config.private = Config::default().private;
        let measured = key_basis(&config).unwrap().plant;
        assert!(
            measured.contains("per-wheel slip measured with it per block and, where the estimate sees it, sized with it")
                && measured.ends_with("no lag or delay, the Euler map"),
            "{measured}"
        );
    }

    /// Private sensing's default: the key rests on the measured plant, as with an explicit
    /// `sizing = "measured"`.
    #[test]
    fn a_measured_plant_sizes_and_labels_the_agents_keys() {
        let mut config = Config::default();
        config.sensing.mode = SensingMode::Private;
        let mut explicit = config.clone();
        explicit.postprocess.sizing = Some(Sizing::Measured);
        assert_eq!(
            assumption(&config).describe(),
            assumption(&explicit).describe()
        );
        assert_eq!(key_basis(&config), key_basis(&explicit));
        let settings = post_settings(&config);
        assert!(settings.check().is_ok());
        assert!(settings.assumption.is_measured());
        assert_eq!(
            settings.assumption.epsilon_terms(1e-6).last(),
            Some(&("ε_est", 1e-6))
        );
        assert!(
            key_basis(&config)
                .unwrap()
                .plant
                .starts_with("Gaussian motion noise measured by the controller")
        );
        let error = Config::from_toml("[postprocess]\nsizing = \"measured\"\n", "test")
            .unwrap_err()
            .to_string();
        assert!(error.contains("postprocess.sizing"), "{error}");
        // The simulated world's own physics is a lab comparison: no robot knows it.
        let error = Config::from_toml(
            "[sensing]\nmode = \"private\"\n[postprocess]\nsizing = \"world\"\n",
            "test",
        )
        .unwrap_err()
        .to_string();
        assert!(
            error.contains("postprocess.sizing") && error.contains("no robot knows"),
            "{error}"
        );
    }

    #[test]
    fn out_of_range_fields_are_named() {
        for (toml, field) in [
            ("[postprocess]\nblock_bits = 10\n", "postprocess.block_bits"),
            (
                "[postprocess]\nsample_bits = 2000000\n",
                "postprocess.sample_bits",
            ),
            ("[postprocess]\nepsilon = 0.5\n", "postprocess.epsilon"),
            (
                "[postprocess]\nassumed_eve_error = 0.7\n",
                "postprocess.assumed_eve_error",
            ),
            (
                "[sensing]\nmode = \"private\"\n[postprocess]\nassumed_eve_error = 0.2\n",
                "postprocess.assumed_eve_error",
            ),
        ] {
            let error = Config::from_toml(toml, "test").unwrap_err().to_string();
            assert!(error.contains(field), "{toml}: {error}");
        }
    }
}
