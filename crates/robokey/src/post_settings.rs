//! The post-processing settings a configuration implies: the same in the agents and in the
//! simulator, so that both size keys under the same stated assumption about Eve
//! (docs/postprocessing.md, docs/secrecy.md).

use robokey_secrecy::cascade::CascadeSchedule;
use robokey_secrecy::postprocess::{Assumption, Settings};

use crate::config::{CameraStatement, Config, SensingMode};

/// Why the odometry mode yields no secret bit against an eavesdropper who learns the model.
pub const ODOMETRY_ZERO: &str = "zero by structure: in odometry mode everything the controller \
    decides from is public except r and D, which an eavesdropper learns from the traffic (the \
    identifying Eve within about one session); she then decides as the controller does, so \
    I(B; controller | Eve) = 0 and no post-processing yields a secret bit";

/// Private sensing's statement about Eve for `config`: her camera noise at least
/// `eve.camera_std` per instant (or her frames, `eve.camera_fps` and `eve.camera_frame_std`),
/// the true motion noise, the exact model, the controller's boundary samples hers; her view
/// of each bit at most as informative as a Gaussian LLR of `separation`.
#[must_use]
pub fn camera_assumption(config: &Config, separation: f64) -> Assumption {
    let mm = |x: f64| 1e3 * x;
    let w = &config.noise.process_std;
    let camera = match config.camera_statement() {
        CameraStatement::PerInstant { .. } => format!(
            "{} (her effective noise after her own filtering)",
            config.camera_statement().describe()
        ),
        frames @ CameraStatement::Frames { .. } => {
            let e = config.modelled_camera_std();
            format!(
                "{}, any phase (worth {:.2} mm, {:.2} mm, {:.2} mrad per sample instant)",
                frames.describe(),
                mm(e[0]),
                mm(e[1]),
                mm(e[2]),
            )
        }
    };
    Assumption::GaussianViews {
        separation,
        statement: format!(
            "Eve's camera noise ≥ {camera}, motion noise {} mm, {} mm, {} mrad per step, \
             exact model, the controller's boundary samples known to her",
            mm(w[0]),
            mm(w[1]),
            mm(w[2]),
        ),
    }
}

/// The assumption that sizes the agents' keys: private sensing's camera statement (each
/// block's separation computed by the controller from its samples); in odometry mode none
/// (ℓ = 0, [`ODOMETRY_ZERO`]) unless `postprocess.assumed_eve_error` states a restricted one.
#[must_use]
pub fn assumption(config: &Config) -> Assumption {
    match (config.sensing.mode, config.postprocess.assumed_eve_error) {
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
