//! `robokey config`: the resolved configuration as TOML with each field's unit and meaning
//! as a comment (the fields as docs/experiments.md, "Configuration", documents them).

use robokey::Config;

/// Unit and meaning of every configuration field, by dotted path.
const FIELDS: &[(&str, &str)] = &[
    ("robot.T", "s: sample time T"),
    ("robot.r", "m: wheel radius"),
    ("robot.D", "m: axle length"),
    ("robot.wheel_limit", "rad/s: the plant's wheel speed limit"),
    (
        "robot.command_quantum",
        "rad/s: the stated resolution each wheel's command rounds to (0: none; ≤ 1)",
    ),
    (
        "noise.process_std",
        "[m, m, rad] per step: true process noise std",
    ),
    (
        "noise.measurement_std",
        "[m, m, rad] per step: true odometry noise std",
    ),
    (
        "sensing.mode",
        "\"odometry\" (the paper's) or \"private\": what the controller decides from",
    ),
    (
        "sensing.controller_std",
        "[m, m, rad]: the controller's own pose sensor std (private mode)",
    ),
    ("trajectory.waypoints", "m: corners of the reference path"),
    ("trajectory.side_time", "s: time per segment"),
    ("trajectory.laps", "laps of the path"),
    ("controller.kp", "1/s²: proportional gain"),
    ("controller.kd", "1/s: derivative gain"),
    ("controller.xi_eps", "m/s: ξ guard"),
    (
        "controller.wheel_limit",
        "rad/s: the controller's wheel limit (rhombus clip)",
    ),
    (
        "controller.feedback",
        "\"measurement\" or \"estimate\": the pose fed back",
    ),
    (
        "observer.variant",
        "\"corrected\" or \"paper\": algebra variant",
    ),
    ("observer.m", "unknown inputs, 1 or 2"),
    ("observer.W_var", "design process variance (W = W_var·I)"),
    (
        "observer.V_var",
        "design measurement variance (V = V_var·I)",
    ),
    (
        "protocol.enabled",
        "false: nominal commands only, no key (the J_x baseline)",
    ),
    ("protocol.delta_v", "m/s: Δv"),
    (
        "protocol.delta_omega",
        "rad/s: Δω (private mode: the second bit of a doublet)",
    ),
    (
        "protocol.bits_per_doublet",
        "dimensions a doublet carries, 1 (v) or 2 (v and ω) (private mode)",
    ),
    (
        "protocol.levels",
        "amplitude levels per dimension, 2, 4 or 8: log₂ levels key bits each, mean power \
         that of ±Δ (private mode)",
    ),
    (
        "protocol.labeling",
        "\"natural\" or \"gray\": which bits label which amplitude, levels > 2",
    ),
    (
        "protocol.max_turn_rate",
        "rad/s: doublets turning faster carry no bit (private mode)",
    ),
    ("code.kind", "\"repetition\" or \"hamming74\""),
    ("code.n_c", "codeword length"),
    (
        "code.accept_max_distance",
        "largest Hamming distance to a codeword that is accepted",
    ),
    ("code.key_bits", "bits: key budget, 0 = none"),
    ("eve.enabled", "whether an eavesdropper listens"),
    ("eve.strategy", "her strategy (docs/threat-model.md)"),
    (
        "eve.alpha",
        "fraction: largest relative model error α (mismatch, soft)",
    ),
    (
        "eve.draw",
        "\"independent\" or \"common\": how her errors are drawn",
    ),
    (
        "eve.initial_error",
        "fraction: her starting error on r and D (identify, transcript)",
    ),
    (
        "eve.max_flips",
        "least-reliable codewords transcript flips per tag search",
    ),
    ("eve.sessions", "sessions `robokey eve` simulates"),
    (
        "eve.window",
        "steps: window of the error rates `robokey eve` reports",
    ),
    (
        "eve.match_tolerance_pp",
        "percentage points: when she matches the controller",
    ),
    (
        "eve.camera_std",
        "[m, m, rad]: her camera's std per sample instant (private mode)",
    ),
    (
        "eve.camera_fps",
        "frames/s: her camera in camera terms, with eve.camera_frame_std (private mode)",
    ),
    (
        "eve.camera_frame_std",
        "[m, m, rad]: noise of each of her frames, white (private mode)",
    ),
    (
        "eve.smoother_window",
        "doublets each side of the private eavesdroppers' window smoother (docs/world.md)",
    ),
    ("run.seed", "master seed of every random stream"),
    ("run.replicates", "runs per configuration (sweep point)"),
    (
        "postprocess.block_bits",
        "bits: the agents' controller proposes a block once its pool holds this many",
    ),
    (
        "postprocess.sample_bits",
        "bits: largest sample disclosed to estimate the error rate",
    ),
    (
        "postprocess.epsilon",
        "ε per term: final keys are 4ε-secret under the stated assumption",
    ),
    (
        "postprocess.assumed_eve_error",
        "odometry mode: restricted assumption (Eve never learns the model); keys need --allow-restricted",
    ),
    (
        "postprocess.sizing",
        "\"configured\" or \"measured\" (private sensing) — what sizes the agents' keys; unset, it follows sensing.mode: measured under private sensing, configured in odometry mode (multilevel slices sized together on whole symbols; robokey secrecy keeps its own default, configured; docs/estimation.md)",
    ),
    (
        "postprocess.reconciliation",
        "\"cascade\" (default) or \"ldpc\" (private sensing: one-way syndromes decoded on the controller's LLRs; docs/postprocessing.md)",
    ),
    (
        "world.preset",
        "the named world whose values fill the fields left out (docs/world.md)",
    ),
    (
        "world.process_std",
        "[m, m, rad] per step: the true motion noise std",
    ),
    ("world.process_rho", "AR(1) correlation of the motion noise"),
    (
        "world.slip_std",
        "fraction: per-wheel slip std (travel × (1 + σ·z) per step)",
    ),
    ("world.lag", "s: each wheel's first-order time constant"),
    ("world.delay", "s: transport delay before a command acts"),
    (
        "world.integration",
        "\"euler\" (the parties' map) or \"continuous\"",
    ),
    (
        "world.command_quantum",
        "rad/s: wheel-speed command resolution",
    ),
    ("world.encoder_quantum", "rad: encoder resolution"),
    (
        "world.jitter",
        "s: std of the sample instants' timing error",
    ),
    (
        "world.controller_std",
        "[m, m, rad]: the controller's sensor as it really is",
    ),
    ("world.camera_fps", "frames/s of Eve's real camera"),
    (
        "world.camera_frame_std",
        "[m, m, rad]: the noise of each of her frames",
    ),
];

/// The configuration as `robokey config` prints it: `to_toml`'s text, each field followed by
/// its unit and meaning as a comment (still valid TOML that loads to the same configuration).
#[must_use]
pub fn annotated_toml(config: &Config) -> String {
    let mut section = String::new();
    let mut out = String::new();
    for line in config.to_toml().lines() {
        if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            section = name.to_owned();
        }
        out.push_str(line);
        if let Some((key, _)) = line.split_once(" = ")
            && let Some(doc) = doc(&format!("{section}.{key}"))
        {
            out.push_str("  # ");
            out.push_str(doc);
        }
        out.push('\n');
    }
    out
}

/// The unit and meaning of a field.
#[must_use]
pub fn doc(field: &str) -> Option<&'static str> {
    FIELDS.iter().find(|(f, _)| *f == field).map(|(_, d)| *d)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The dotted paths of a table's leaves.
    fn leaves(table: &toml::Table, prefix: &str, out: &mut Vec<String>) {
        for (key, value) in table {
            match value {
                toml::Value::Table(inner) => leaves(inner, &format!("{prefix}{key}."), out),
                _ => out.push(format!("{prefix}{key}")),
            }
        }
    }

    #[test]
    fn every_field_is_documented_and_every_documented_field_exists() {
        let mut config = Config::default();
        // Printed only when set.
        config.postprocess.assumed_eve_error = Some(0.2);
        config.robot.command_quantum = 0.0323;
        config.postprocess.sizing = Some(robokey::config::Sizing::Measured);
        config.postprocess.reconciliation = robokey::config::Reconciliation::Ldpc;
        config.protocol.levels = 4;
        config.protocol.labeling = robokey::config::Labeling::Gray;
        config.eve.smoother_window = Some(2);
        config.eve.camera_fps = Some(30.0);
        config.eve.camera_frame_std = Some([0.016; 3]);
        config.world = Some(robokey::world::WorldConfig {
            preset: Some(robokey::world::WorldPreset::KheperaIv),
            camera_fps: Some(30.0),
            ..Default::default()
        });
        let mut fields = Vec::new();
        leaves(&config.to_toml().parse().unwrap(), "", &mut fields);
        let documented: Vec<&str> = FIELDS.iter().map(|(f, _)| *f).collect();
        assert_eq!(fields, documented);
        assert!(FIELDS.iter().all(|(_, d)| !d.is_empty()));
    }

    #[test]
    fn the_annotated_toml_loads_to_the_same_configuration() {
        let config = Config::from_toml("[sensing]\nmode = \"private\"\n", "test").unwrap();
        let text = annotated_toml(&config);
        assert!(text.contains("T = 0.2  # s: sample time T\n"), "{text}");
        assert!(text.contains("delta_v = 0.035  # m/s: Δv\n"), "{text}");
        let again = Config::from_toml(&text, "annotated").unwrap();
        assert_eq!(again.to_toml(), config.to_toml());
    }
}
