//! The agreement terms: what both sides must hold equal before a session starts, their digest
//! (carried in `Hello` and `HelloAck`), and how a difference is named.

use robokey_secrecy::postprocess::ReconciliationMethod;

use crate::config::{Config, SensingMode};
use crate::world::Camera;

/// The terms both endpoints must agree on (T, wheel geometry r and D, code, n_c, k_c, key
/// budget, Δ, trajectory, protocol on/off; in private sensing also the mode, the bits per
/// doublet, the turn gate, Eve's stated camera — per instant, or in frames when so stated —,
/// the motion noise the key's assumption names, the prior lag that shapes the doublet and
/// the stated command quantum (each when not 0); the `[postprocess]` table, which sizes
/// the final keys), as `field = value` lines in a fixed order. The robot checks every
/// command against the agreed Δ, r and D. Not agreed: what only the controller uses
/// (its gains, its sensor's `sensing.controller_std`: the separations it computes with it
/// are carried to the robot with each block).
#[must_use]
pub fn agreement_terms(config: &Config) -> String {
    let code = &config.code;
    let traj = &config.trajectory;
    let built = code.build();
    let private = match config.sensing.mode {
        SensingMode::Odometry => String::new(),
        SensingMode::Private => format!(
            "sensing.mode = private\nprotocol.bits_per_doublet = {}\n{}protocol.max_turn_rate = {}\n\
             eve.camera_std = {:?}\n{}noise.process_std = {:?}\n{}{}{}",
            config.protocol.bits_per_doublet,
            alphabet_terms(config),
            config.protocol.max_turn_rate,
            config.eve.camera_std,
            camera_frames_terms(config),
            config.noise.process_std,
            prior_lag_terms(config),
            command_quantum_terms(config),
            sizing_terms(config),
        ),
    };
    // What sizes and labels the final keys both stores hold.
    let post = &config.postprocess;
    let assumed = post
        .assumed_eve_error
        .map_or_else(|| "none".to_owned(), |p| p.to_string());
    format!(
        "robot.T = {}\nrobot.r = {}\nrobot.D = {}\nprotocol.enabled = {}\nprotocol.delta_v = {}\nprotocol.delta_omega = {}\n\
         code.kind = {:?}\ncode.n_c = {}\ncode.k_c = {}\ncode.accept_max_distance = {}\n\
         code.key_bits = {}\ntrajectory.waypoints = {:?}\ntrajectory.side_time = {}\n\
         trajectory.laps = {}\n{private}postprocess.block_bits = {}\n\
         postprocess.sample_bits = {}\npostprocess.epsilon = {}\n\
         postprocess.assumed_eve_error = {assumed}\n{}",
        config.robot.sample_time,
        config.robot.r,
        config.robot.axle_length,
        config.protocol.enabled,
        config.protocol.delta_v,
        config.delta_omega(),
        code.kind,
        built.n(),
        built.k(),
        code.accept_max_distance,
        code.key_bits,
        traj.waypoints,
        traj.side_time,
        traj.laps,
        post.block_bits,
        post.sample_bits,
        post.epsilon,
        reconciliation_terms(config),
    )
}

/// The reconciliation's lines, `postprocess.reconciliation = ldpc` and `ldpc.code =` the
/// code's construction version and settings (absent with Cascade, so that its terms stay as they
/// were): both sides must run the same protocol and build the same codes.
fn reconciliation_terms(config: &Config) -> String {
    match crate::post_settings::reconciliation_method(config.postprocess.reconciliation) {
        ReconciliationMethod::Ldpc(settings) => format!(
            "postprocess.reconciliation = {}\nldpc.code = {}\n",
            config.postprocess.reconciliation.name(),
            settings.agreement_term()
        ),
        _ => String::new(),
    }
}

/// The camera stated in frames, when it is: `eve.camera_fps` and `eve.camera_frame_std`
/// lines (absent otherwise, so that a per-instant statement's terms stay as they were).
fn camera_frames_terms(config: &Config) -> String {
    match config.camera_statement() {
        Camera::Instants { .. } => String::new(),
        Camera::Frames { fps, frame_std } => {
            format!("eve.camera_fps = {fps}\neve.camera_frame_std = {frame_std:?}\n")
        }
    }
}

/// The alphabet's lines, `protocol.levels` and `protocol.labeling` (absent with binary
/// doublets, so that their terms stay as they were): both sides must read a doublet's
/// amplitude as the same label bits.
fn alphabet_terms(config: &Config) -> String {
    let protocol = &config.protocol;
    if protocol.levels == 2 {
        String::new()
    } else {
        format!(
            "protocol.levels = {}\nprotocol.labeling = {}\n",
            protocol.levels,
            protocol.labeling.name()
        )
    }
}

/// The doublet's shape when it is three steps: a `private.prior_lag` line (absent at 0, so
/// that the two-step doublet's terms stay as they were).
fn prior_lag_terms(config: &Config) -> String {
    if config.private.is_default() {
        String::new()
    } else {
        format!("private.prior_lag = {}\n", config.private.prior_lag)
    }
}

/// The stated command quantum's line, `robot.command_quantum = q` (absent at 0, so that the
/// terms stay as they were): it shapes every pattern's means, hence Eve's modelled view and ℓ.
fn command_quantum_terms(config: &Config) -> String {
    if config.robot.command_quantum == 0.0 {
        String::new()
    } else {
        format!("robot.command_quantum = {}\n", config.robot.command_quantum)
    }
}

/// The measured plant's line, `postprocess.sizing = measured` (absent with the configured
/// physics, so that its terms stay as they were): it sizes and labels the keys. The
/// resolved [`Config::sizing`], so that an unset field and its explicit value agree.
fn sizing_terms(config: &Config) -> String {
    let sizing = config.sizing();
    if sizing.is_configured() {
        String::new()
    } else {
        format!("postprocess.sizing = {}\n", sizing.name())
    }
}

/// SHA-256 of the [`agreement_terms`].
#[must_use]
pub fn config_digest(config: &Config) -> [u8; 32] {
    use sha2::Digest;
    sha2::Sha256::digest(agreement_terms(config).as_bytes()).into()
}

/// What a side holds where its terms have no line for `key`: the value whose line the terms
/// omit so that older terms stay as they were, or what the line does not apply to.
fn omitted(key: &str) -> &'static str {
    match key {
        "sensing.mode" => "odometry",
        "protocol.bits_per_doublet"
        | "protocol.max_turn_rate"
        | "eve.camera_std"
        | "noise.process_std" => "none (odometry mode)",
        "protocol.levels" => "2",
        "protocol.labeling" => "none (binary doublets)",
        "eve.camera_fps" | "eve.camera_frame_std" => "none (a per-instant camera)",
        "private.prior_lag" | "robot.command_quantum" => "0",
        "postprocess.sizing" => "configured",
        "postprocess.reconciliation" => "cascade",
        "ldpc.code" => "none (Cascade)",
        _ => "(missing)",
    }
}

/// Names the terms on which two [`agreement_terms`] texts differ, e.g.
/// `robot.T: robot has 0.25, controller has 0.2`; a side without a line has
/// [`omitted`]'s value.
#[must_use]
pub fn terms_difference(ours: &str, theirs: &str, we: &str, they: &str) -> String {
    let parse = |text: &str| -> Vec<(String, String)> {
        text.lines()
            .filter_map(|l| l.split_once(" = "))
            .map(|(k, v)| (k.to_owned(), v.to_owned()))
            .collect()
    };
    let (ours, theirs) = (parse(ours), parse(theirs));
    let mut differences: Vec<String> = ours
        .iter()
        .filter_map(|(key, value)| {
            let peer = theirs
                .iter()
                .find(|(k, _)| k == key)
                .map_or(omitted(key), |(_, v)| v.as_str());
            (peer != value).then(|| format!("{key}: {we} has {value}, {they} has {peer}"))
        })
        .collect();
    differences.extend(
        theirs
            .iter()
            .filter(|(k, _)| !ours.iter().any(|(o, _)| o == k))
            .map(|(k, v)| format!("{k}: {we} has {}, {they} has {v}", omitted(k))),
    );
    if differences.is_empty() {
        "the configuration digests differ".to_owned()
    } else {
        differences.join("; ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robokey_secrecy::ldpc::LdpcSettings;

    #[test]
    fn differences_are_named() {
        let a = Config::default();
        let mut b = Config::default();
        b.robot.sample_time = 0.25;
        b.controller.kp = 2.0; // controller-only: not part of the terms
        assert_ne!(config_digest(&a), config_digest(&b));
        let text = terms_difference(
            &agreement_terms(&a),
            &agreement_terms(&b),
            "robot",
            "controller",
        );
        assert_eq!(text, "robot.T: robot has 0.2, controller has 0.25");
        b.robot.sample_time = 0.2;
        assert_eq!(config_digest(&a), config_digest(&b));
    }

    /// Every line the terms can omit — those of a configuration with every optional term set
    /// that the default configuration's terms lack — names what its absence holds.
    #[test]
    fn every_omitted_line_names_its_value() {
        let mut every = private();
        every.protocol.levels = 4;
        every.eve.camera_fps = Some(30.0);
        every.eve.camera_frame_std = Some([0.016; 3]);
        every.private.prior_lag = 0.05;
        every.robot.command_quantum = 0.1;
        every.postprocess.reconciliation = crate::config::Reconciliation::Ldpc;
        let default = agreement_terms(&Config::default());
        let keys = |terms: &str| -> Vec<String> {
            terms
                .lines()
                .filter_map(|l| l.split_once(" = ").map(|(k, _)| k.to_owned()))
                .collect()
        };
        let omissible: Vec<String> = keys(&agreement_terms(&every))
            .into_iter()
            .filter(|k| !keys(&default).contains(k))
            .collect();
        assert_eq!(omissible.len(), 14, "{omissible:?}");
        for key in &omissible {
            assert_ne!(omitted(key), "(missing)", "{key}");
        }
    }

    /// The terms on which `a` (the robot's) and `b` (the controller's) differ.
    fn difference(a: &Config, b: &Config) -> String {
        terms_difference(
            &agreement_terms(a),
            &agreement_terms(b),
            "robot",
            "controller",
        )
    }

    /// The default configuration in private sensing.
    fn private() -> Config {
        let mut config = Config::default();
        config.sensing.mode = SensingMode::Private;
        config
    }

    /// The alphabet is agreed: binary doublets' terms are as they were, a 4-level robot and
    /// a binary controller are told apart by name.
    #[test]
    fn the_alphabet_is_a_term() {
        let binary = private();
        assert!(!agreement_terms(&binary).contains("levels"));
        let mut four = private();
        four.protocol.levels = 4;
        assert_eq!(
            difference(&four, &binary),
            "protocol.levels: robot has 4, controller has 2; protocol.labeling: robot has natural, \
             controller has none (binary doublets)"
        );
    }

    #[test]
    fn the_prior_lag_is_agreed_and_its_default_leaves_the_terms_unchanged() {
        let a = private();
        let two_steps = agreement_terms(&a);
        assert!(!two_steps.contains("prior_lag"), "{two_steps}");
        let mut b = a.clone();
        b.private.prior_lag = 0.05;
        assert_eq!(
            difference(&a, &b),
            "private.prior_lag: robot has 0, controller has 0.05"
        );
        let mut c = b.clone();
        c.private.prior_lag = 0.1;
        assert_eq!(
            difference(&b, &c),
            "private.prior_lag: robot has 0.05, controller has 0.1"
        );
    }

    #[test]
    fn the_camera_stated_in_frames_is_agreed_and_a_per_instant_one_unchanged() {
        let a = private();
        let per_instant = agreement_terms(&a);
        assert!(!per_instant.contains("camera_fps"), "{per_instant}");
        let mut b = a.clone();
        b.eve.camera_fps = Some(30.0);
        b.eve.camera_frame_std = Some([0.016; 3]);
        let mut c = b.clone();
        c.eve.camera_fps = Some(60.0);
        assert_eq!(
            difference(&b, &c),
            "eve.camera_fps: robot has 30, controller has 60"
        );
        assert_eq!(
            difference(&a, &b),
            "eve.camera_fps: robot has none (a per-instant camera), controller has 30; \
             eve.camera_frame_std: robot has none (a per-instant camera), controller has \
             [0.016, 0.016, 0.016]"
        );
    }

    /// The terms carry the resolved sizing: an unset field agrees with its explicit value
    /// (measured under private sensing, configured in odometry mode), the configured
    /// physics' terms keep no sizing line, and a differing effective sizing is named.
    #[test]
    fn the_resolved_sizing_is_agreed_and_a_configured_one_unchanged() {
        use crate::config::Sizing;
        let with = |mode, sizing| {
            let mut config = Config::default();
            config.sensing.mode = mode;
            config.postprocess.sizing = sizing;
            agreement_terms(&config)
        };
        let configured = with(SensingMode::Private, Some(Sizing::Configured));
        assert!(!configured.contains("sizing"), "{configured}");
        let unset = with(SensingMode::Private, None);
        assert_eq!(unset, with(SensingMode::Private, Some(Sizing::Measured)));
        assert_eq!(
            terms_difference(&configured, &unset, "robot", "controller"),
            "postprocess.sizing: robot has configured, controller has measured"
        );
        let odometry = with(SensingMode::Odometry, None);
        assert!(!odometry.contains("sizing"), "{odometry}");
        assert_eq!(
            odometry,
            with(SensingMode::Odometry, Some(Sizing::Configured))
        );
    }

    #[test]
    fn ldpc_reconciliation_is_agreed_and_cascade_unchanged() {
        let mut a = Config::default();
        a.sensing.mode = SensingMode::Private;
        let cascade = agreement_terms(&a);
        assert!(!cascade.contains("reconciliation"), "{cascade}");
        let mut b = a.clone();
        b.postprocess.reconciliation = crate::config::Reconciliation::Ldpc;
        let ldpc = agreement_terms(&b);
        let settings = LdpcSettings::DEFAULT.agreement_term();
        assert_eq!(
            terms_difference(&cascade, &ldpc, "robot", "controller"),
            format!(
                "postprocess.reconciliation: robot has cascade, controller has ldpc; \
                 ldpc.code: robot has none (Cascade), controller has {settings}"
            )
        );
        assert_eq!(
            settings,
            "v1, syndrome 1.09·H + 2·√H, 200 iterations (50 before a feedback round), \
             8 rounds of max(0.04·m, 2·√m)"
        );
        // A binary whose LDPC codes differ (another construction or settings) is named.
        let other = ldpc.replace("ldpc.code = v1,", "ldpc.code = v9,");
        assert_eq!(
            terms_difference(&other, &ldpc, "robot", "controller"),
            format!(
                "ldpc.code: robot has v9{}, controller has {settings}",
                &settings["v1".len()..],
            )
        );
    }
}
