//! The world resolved (docs/world.md): every physical parameter of the plant and of the
//! sensors around it, from `[world]`, its preset and, for what neither sets, the parties'
//! configuration.

use super::config::{Integration, WorldConfig};
use crate::config::Config;

/// Eve's camera: the world's real one, or the one the parties state (`eve.*`, the key's
/// statement: docs/threat-model.md).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Camera {
    /// One frame at each sample instant, std `[m, m, rad]`.
    Instants {
        /// Noise std of each frame.
        std: [f64; 3],
    },
    /// Frames at `fps` with a random phase per session, filming the motion between the
    /// instants; each frame's noise is white with std `frame_std`.
    Frames {
        /// Frames per second.
        fps: f64,
        /// Noise std of each frame `[m, m, rad]`.
        frame_std: [f64; 3],
    },
}

/// `σ_e = σ_f / √(2fT/3)`: the per-instant noise a camera of `fps` frames per second with
/// per-frame noise `σ_f` is worth for a doublet's amplitude at sample time `T` (docs/world.md
/// derives it: a least-squares fit of the triangle the bit draws between the boundaries).
#[must_use]
pub fn per_instant_std(frame_std: f64, fps: f64, sample_time: f64) -> f64 {
    frame_std / (2.0 * fps * sample_time / 3.0).sqrt()
}

/// The inverse of [`per_instant_std`]: the per-frame noise worth `σ_e` per instant.
#[must_use]
pub fn per_frame_std(instant_std: f64, fps: f64, sample_time: f64) -> f64 {
    instant_std * (2.0 * fps * sample_time / 3.0).sqrt()
}

/// Every physical parameter of a world, resolved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldModel {
    /// Additive motion noise std per step `[m, m, rad]`.
    pub process_std: [f64; 3],
    /// AR(1) correlation of the motion noise between steps.
    pub process_rho: f64,
    /// Per-wheel multiplicative slip std (fraction of the wheel's travel per step).
    pub slip_std: f64,
    /// Each wheel's first-order lag τ (s; 0: instantaneous).
    pub lag: f64,
    /// Transport delay before a command acts (s).
    pub delay: f64,
    /// How the unicycle is integrated over a period.
    pub integration: Integration,
    /// Wheel-speed command resolution (rad/s; 0: none).
    pub command_quantum: f64,
    /// Encoder resolution (rad; 0: none).
    pub encoder_quantum: f64,
    /// Std of the sample instants' timing error (s).
    pub jitter: f64,
    /// The controller's sensor noise std `[m, m, rad]`.
    pub controller_std: [f64; 3],
    /// Eve's camera.
    pub camera: Camera,
}

/// Most sub-steps the continuous plant takes per sample period.
pub const MAX_SUBSTEPS: usize = 256;

/// Most doublets each side beyond the eavesdroppers' window whose boundary samples they take
/// ([`WorldModel::sample_reach`]).
pub const MAX_SAMPLE_REACH: u32 = 24;

impl WorldModel {
    /// The world the parties of `config` believe in: their motion noise, controller sensor
    /// and Eve's stated camera at the instants; no correlation, slip, lag, delay, quanta or
    /// jitter; the Euler map.
    #[must_use]
    pub fn ideal(config: &Config) -> Self {
        Self {
            process_std: config.noise.process_std,
            process_rho: 0.0,
            slip_std: 0.0,
            lag: 0.0,
            delay: 0.0,
            integration: Integration::Euler,
            command_quantum: 0.0,
            encoder_quantum: 0.0,
            jitter: 0.0,
            controller_std: config.sensing.controller_std,
            camera: config.camera_statement(),
        }
    }

    /// `config`'s world: each field from `[world]`, else from its preset, else the parties'.
    #[must_use]
    pub fn of(config: &Config) -> Self {
        let ideal = Self::ideal(config);
        let Some(table) = &config.world else {
            return ideal;
        };
        let preset = table.preset.map(|p| p.values()).unwrap_or_default();
        let w = table.over(&preset);
        let camera = match (w.camera_fps, w.camera_frame_std) {
            (None, None) => ideal.camera,
            (None, Some(std)) => Camera::Instants { std },
            (Some(fps), frame_std) => Camera::Frames {
                fps,
                frame_std: frame_std.unwrap_or_else(|| match config.camera_statement() {
                    Camera::Frames {
                        fps: stated,
                        frame_std,
                    } if stated == fps => frame_std,
                    _ => config
                        .modelled_camera_std()
                        .map(|s| per_frame_std(s, fps, config.robot.sample_time)),
                }),
            },
        };
        Self {
            process_std: w.process_std.unwrap_or(ideal.process_std),
            process_rho: w.process_rho.unwrap_or(ideal.process_rho),
            slip_std: w.slip_std.unwrap_or(ideal.slip_std),
            lag: w.lag.unwrap_or(ideal.lag),
            delay: w.delay.unwrap_or(ideal.delay),
            integration: w.integration.unwrap_or(ideal.integration),
            command_quantum: w.command_quantum.unwrap_or(ideal.command_quantum),
            encoder_quantum: w.encoder_quantum.unwrap_or(ideal.encoder_quantum),
            jitter: w.jitter.unwrap_or(ideal.jitter),
            controller_std: w.controller_std.unwrap_or(ideal.controller_std),
            camera,
        }
    }

    /// The world as a `[world]` table with every field explicit (and `preset` kept as the
    /// record of where the values came from).
    #[must_use]
    pub fn to_table(&self, preset: Option<super::WorldPreset>) -> WorldConfig {
        let (camera_fps, camera_frame_std) = match self.camera {
            Camera::Instants { std } => (None, Some(std)),
            Camera::Frames { fps, frame_std } => (Some(fps), Some(frame_std)),
        };
        WorldConfig {
            preset,
            process_std: Some(self.process_std),
            process_rho: Some(self.process_rho),
            slip_std: Some(self.slip_std),
            lag: Some(self.lag),
            delay: Some(self.delay),
            integration: Some(self.integration),
            command_quantum: Some(self.command_quantum),
            encoder_quantum: Some(self.encoder_quantum),
            jitter: Some(self.jitter),
            controller_std: Some(self.controller_std),
            camera_fps,
            camera_frame_std,
        }
    }

    /// Whether a doublet's boundary samples screen it from its neighbours, so that Eve's
    /// per-doublet view is her whole view's worth (docs/world.md, "Eavesdroppers"): white
    /// motion noise at least the controller's sensor noise over a doublet
    /// (`2·σ_w² ≥ σ_c²` on every axis: [`Self::sample_reach`] is 0), no slip, lag, delay,
    /// quanta or jitter, the Euler map, a camera at the instants. Otherwise the
    /// eavesdroppers smooth over a window of doublets.
    #[must_use]
    pub fn screens_doublets(&self) -> bool {
        self.sample_reach() == 0
            && self.process_rho == 0.0
            && self.slip_std == 0.0
            && self.lag == 0.0
            && self.delay == 0.0
            && self.command_quantum == 0.0
            && self.jitter == 0.0
            && self.integration == Integration::Euler
            && matches!(self.camera, Camera::Instants { .. })
    }

    /// Doublets each side whose boundary samples still pin a doublet's boundaries better
    /// than its own samples do: 0 where the motion noise over a doublet is at least the
    /// controller's sensor noise on every axis (`2·σ_w² ≥ σ_c²`), else
    /// `⌈3·max_i σ_c,i / (√2·σ_w,i)⌉` capped at [`MAX_SAMPLE_REACH`]. Over a chain of
    /// boundary samples (noise σ_c) joined by the noise of a doublet (variance `q = 2σ_w²`)
    /// the smoother's weights fall by `λ = 1 + r/2 − √(r + r²/4)` per doublet, `r = q/σ_c²`,
    /// over about `1/(1 − λ) ≈ σ_c/(√2·σ_w)` doublets; three such lengths leave
    /// `λ^(2n) ≲ e⁻⁶` of the information (docs/world.md).
    #[must_use]
    pub fn sample_reach(&self) -> u32 {
        let ratio = self
            .process_std
            .iter()
            .zip(&self.controller_std)
            .map(|(w, c)| c / (2.0_f64.sqrt() * w))
            .fold(0.0_f64, f64::max);
        if ratio <= 1.0 {
            0
        } else {
            (3.0 * ratio).ceil().min(f64::from(MAX_SAMPLE_REACH)) as u32
        }
    }

    /// What the parties of `config` believe of the world: [`Self::ideal`] with the lag they
    /// state, `private.prior_lag` (s; 0 unless their doublets are three steps), and the
    /// command resolution they state, `robot.command_quantum` (rad/s; 0: none). Beliefs
    /// only: an absent `world.lag` or `world.command_quantum` is still 0 ([`Self::of`]).
    fn believed(config: &Config) -> Self {
        Self {
            lag: config.private.prior_lag,
            command_quantum: config.robot.command_quantum,
            ..Self::ideal(config)
        }
    }

    /// The world's parameters that differ from what the parties of `config` believe
    /// (their motion noise, controller sensor, Eve's stated camera, `private.prior_lag` and
    /// `robot.command_quantum`; the other fields' belief is none of them), as
    /// `world.FIELD = VALUE (parties: VALUE)`,
    /// in the order of the table. Empty when the world is what they believe.
    #[must_use]
    pub fn differences(&self, config: &Config) -> Vec<String> {
        let ours = self.to_table(None);
        let theirs = Self::believed(config).to_table(None);
        let text = |table: &WorldConfig| -> Vec<(String, String)> {
            toml::to_string(table)
                .expect("a world always serializes")
                .lines()
                .filter_map(|l| l.split_once(" = "))
                .map(|(k, v)| (k.to_owned(), v.to_owned()))
                .collect()
        };
        let theirs = text(&theirs);
        text(&ours)
            .into_iter()
            .filter(|(k, v)| !theirs.iter().any(|(tk, tv)| tk == k && tv == v))
            .map(|(k, v)| {
                let parties = theirs
                    .iter()
                    .find(|(tk, _)| *tk == k)
                    .map_or("none", |(_, tv)| tv.as_str());
                format!("world.{k} = {v} (parties: {parties})")
            })
            .collect()
    }

    /// Sub-steps per period of length `sample_time` (s) of the continuous plant: at most
    /// 25 ms each and at most a quarter of the lag, capped at [`MAX_SUBSTEPS`]; 1 for the
    /// Euler map.
    #[must_use]
    pub fn substeps(&self, sample_time: f64) -> usize {
        match self.integration {
            Integration::Euler => 1,
            Integration::Continuous => {
                let mut longest = 0.025_f64.min(sample_time);
                if self.lag > 0.0 {
                    longest = longest.min(self.lag / 4.0);
                }
                ((sample_time / longest).ceil() as usize).clamp(1, MAX_SUBSTEPS)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::WorldPreset;

    fn with_world(text: &str) -> Config {
        Config::from_toml(text, "test").unwrap()
    }

    #[test]
    fn absent_fields_are_the_presets_then_the_parties() {
        let config = Config::default();
        assert_eq!(WorldModel::of(&config), WorldModel::ideal(&config));
        let world = WorldModel::of(&with_world(
            "[world]\npreset = \"khepera-iv\"\nlag = 0.05\n",
        ));
        assert_eq!(world.lag, 0.05);
        assert_eq!(world.delay, 0.01);
        assert_eq!(world.controller_std, config.sensing.controller_std);
        assert!(!world.screens_doublets());
        assert!(WorldModel::ideal(&config).screens_doublets());
        let diff = world.differences(&config);
        assert!(
            diff.iter().any(|d| d.starts_with("world.lag = 0.05")),
            "{diff:?}"
        );
        assert!(
            diff.iter().all(|d| !d.contains("controller_std")),
            "{diff:?}"
        );
        assert!(WorldModel::ideal(&config).differences(&config).is_empty());
    }

    #[test]
    fn the_parties_stated_lag_is_their_belief_in_the_differences() {
        let private = |prior: f64, world: &str| {
            with_world(&format!(
                "[sensing]\nmode = \"private\"\n[private]\nprior_lag = {prior}\n[world]\n{world}"
            ))
        };
        let differences = |config: &Config| WorldModel::of(config).differences(config);
        let stated = private(0.05, "lag = 0.05\n");
        assert_eq!(differences(&stated), Vec::<String>::new());
        let wrong = private(0.05, "lag = 0.1\n");
        assert_eq!(differences(&wrong), ["world.lag = 0.1 (parties: 0.05)"]);
        let unstated = private(0.0, "lag = 0.05\n");
        assert_eq!(differences(&unstated), ["world.lag = 0.05 (parties: 0.0)"]);
        // The prior is a belief: an absent world.lag stays 0, which differs from it.
        let lagless = private(0.05, "jitter = 0.0\n");
        assert_eq!(WorldModel::of(&lagless).lag, 0.0);
        assert_eq!(differences(&lagless), ["world.lag = 0.0 (parties: 0.05)"]);
    }

    #[test]
    fn the_parties_stated_command_quantum_is_their_belief_in_the_differences() {
        let stating = |quantum: f64, world: &str| {
            with_world(&format!(
                "[sensing]\nmode = \"private\"\n[robot]\ncommand_quantum = {quantum}\n\
                 [world]\n{world}"
            ))
        };
        let differences = |config: &Config| WorldModel::of(config).differences(config);
        let stated = stating(0.1, "command_quantum = 0.1\n");
        assert_eq!(differences(&stated), Vec::<String>::new());
        let wrong = stating(0.0323, "command_quantum = 0.1\n");
        assert_eq!(
            differences(&wrong),
            ["world.command_quantum = 0.1 (parties: 0.0323)"]
        );
        let unstated = stating(0.0, "command_quantum = 0.1\n");
        assert_eq!(
            differences(&unstated),
            ["world.command_quantum = 0.1 (parties: 0.0)"]
        );
        // A belief: an absent world.command_quantum stays 0, which differs from it.
        let exact = stating(0.1, "jitter = 0.0\n");
        assert_eq!(WorldModel::of(&exact).command_quantum, 0.0);
        assert_eq!(
            differences(&exact),
            ["world.command_quantum = 0.0 (parties: 0.1)"]
        );
    }

    #[test]
    fn a_camera_at_fps_without_its_frame_noise_is_worth_the_stated_camera() {
        let config = with_world("[world]\ncamera_fps = 30.0\n");
        let Camera::Frames { fps, frame_std } = WorldModel::of(&config).camera else {
            panic!("frames")
        };
        assert_eq!(fps, 30.0);
        // 8 mm per instant ⇔ 16 mm per frame at 30 fps (T = 0.2 s).
        assert!((frame_std[0] - 0.016).abs() < 1e-12, "{frame_std:?}");
        assert!((per_instant_std(frame_std[0], fps, 0.2) - 0.008).abs() < 1e-15);
    }

    #[test]
    fn the_resolved_table_reads_back_as_the_same_world() {
        for preset in WorldPreset::ALL {
            let config = with_world(&format!("[world]\npreset = \"{preset}\"\njitter = 0.001\n"));
            let world = WorldModel::of(&config);
            let mut back = config.clone();
            back.world = Some(world.to_table(Some(preset)));
            assert_eq!(WorldModel::of(&back), world, "{preset}");
        }
    }

    #[test]
    fn doublets_are_screened_only_above_the_sensor_noise() {
        let mut world = WorldModel::ideal(&Config::default());
        assert_eq!(world.sample_reach(), 0);
        // √2·0.36 mm ≥ 0.5 mm: screened.
        world.process_std = [0.000_36; 3];
        assert_eq!(world.sample_reach(), 0);
        assert!(world.screens_doublets());
        // 0.5 / (√2·0.15) = 2.36 doublets, three times over.
        world.process_std = [0.000_15; 3];
        assert_eq!(world.sample_reach(), 8);
        assert!(!world.screens_doublets());
        world.process_std = [0.0; 3];
        assert_eq!(world.sample_reach(), MAX_SAMPLE_REACH);
    }

    #[test]
    fn substeps_follow_the_lag_and_are_capped() {
        let mut world = WorldModel::ideal(&Config::default());
        assert_eq!(world.substeps(0.2), 1);
        world.integration = Integration::Continuous;
        assert_eq!(world.substeps(0.2), 8);
        world.lag = 0.02;
        assert_eq!(world.substeps(0.2), 40);
        world.lag = 1e-6;
        assert_eq!(world.substeps(0.2), MAX_SUBSTEPS);
    }
}
