//! `robokey threat` (docs/threat-model.md, "Eve's camera"): what a camera of Eve's leaves of
//! the key at a configuration — its per-instant equivalent, the secret rate a key has when
//! it is sized against that camera from the configured physics (`robokey secrecy`'s default
//! sizing; the agents' default under private sensing is the measured plant), and the
//! break-even camera where that rate reaches zero. Each rate is `robokey secrecy`'s for one
//! point: the configuration's
//! sessions simulated, one block of `postprocess.block_bits` raw bits through the agents'
//! post-processing (complete pooling) at `postprocess.epsilon` per term.

use robokey::Config;
use robokey::config::{EveStrategy, SensingMode};
use robokey::world::Camera;
use serde::Serialize;

use crate::error::LabError;
use crate::experiment::{Experiment, Mode, Point, SecrecyDefaults};
use crate::secrecy::{Pooling, SecrecyOptions, analyze, default_max_sessions};

/// The break-even search's range of per-instant camera noise (m, m, rad).
pub const BREAK_EVEN_RANGE: [f64; 2] = [0.000_25, 0.064];
/// The search stops once the bracket's upper end is within this factor of its lower end.
pub const BREAK_EVEN_RESOLUTION: f64 = 1.02;

/// One camera's figures at the configuration.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CameraThreat {
    /// The camera in words (`eve.camera_std` per instant, or frames).
    pub statement: String,
    /// Its per-instant equivalent, the noise Eve's modelled view uses (mm, mm, mrad).
    pub per_instant_mm: [f64; 3],
    /// Raw bits in the block.
    pub raw_bits: u64,
    /// Final key bits ℓ of the block sized against this camera.
    pub secret_bits: u64,
    /// Secret bits per step of robot time (every session simulated until the block filled).
    pub bits_per_step: f64,
    /// Secret bits per second.
    pub bits_per_second: f64,
    /// Why ℓ is 0, if it is.
    pub zero_reason: Option<String>,
}

/// Where the rate reaches zero as Eve's camera improves (per-instant noise, the same number
/// of mm, mm and mrad, as the private-sensing map sweeps it).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum BreakEven {
    /// The rate is zero at `zero_at_mm` and positive at `positive_at_mm`.
    Between {
        /// Per-instant noise with no secret bit (mm).
        zero_at_mm: f64,
        /// Per-instant noise with secret bits (mm).
        positive_at_mm: f64,
    },
    /// Even the best camera of the search leaves secret bits.
    Below {
        /// The search's best camera (mm).
        mm: f64,
    },
    /// Even the worst camera of the search leaves none.
    Above {
        /// The search's worst camera (mm).
        mm: f64,
    },
}

/// What `robokey threat` prints.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Threat {
    /// Sample time T (s).
    pub sample_time: f64,
    /// Raw bits per block.
    pub block_bits: u32,
    /// ε per term.
    pub epsilon: f64,
    /// The cameras asked about, in order.
    pub cameras: Vec<CameraThreat>,
    /// The break-even camera.
    pub break_even: BreakEven,
}

/// The figures of each of `cameras` at `config` (evaluated in private sensing) and the
/// break-even camera. Deterministic: a pure function of its arguments.
///
/// # Errors
/// A camera makes the configuration invalid (named field, value, range), or a session
/// aborts.
pub fn threat(config: &Config, cameras: &[Camera]) -> Result<Threat, LabError> {
    let mut base = config.clone();
    base.sensing.mode = SensingMode::Private;
    let cameras = cameras
        .iter()
        .map(|camera| camera_threat(&base, *camera))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Threat {
        sample_time: base.robot.sample_time,
        block_bits: base.postprocess.block_bits,
        epsilon: base.postprocess.epsilon,
        cameras,
        break_even: break_even(&base)?,
    })
}

/// `config` stating `camera`.
fn stating(config: &Config, camera: Camera) -> Result<Config, LabError> {
    let mut config = config.clone();
    let eve = &mut config.eve;
    match camera {
        Camera::Instants { std } => {
            eve.camera_std = std;
            (eve.camera_fps, eve.camera_frame_std) = (None, None);
        }
        Camera::Frames { fps, frame_std } => {
            eve.camera_std = robokey::config::DEFAULT_CAMERA_STD;
            (eve.camera_fps, eve.camera_frame_std) = (Some(fps), Some(frame_std));
        }
    }
    config.validate()?;
    Ok(config)
}

/// One camera's figures: `robokey secrecy` of `config` stating it, against the camera Eve.
fn camera_threat(config: &Config, camera: Camera) -> Result<CameraThreat, LabError> {
    let config = stating(config, camera)?;
    let post = &config.postprocess;
    let options = SecrecyOptions {
        adversaries: vec![EveStrategy::Camera],
        epsilon: post.epsilon,
        block_bits: post.block_bits as usize,
        pooling: Pooling::Complete,
        sample_bits: post.sample_bits as usize,
        max_sessions: default_max_sessions(post.block_bits as usize, 1),
        ..SecrecyOptions::default()
    };
    let experiment = Experiment {
        name: String::new(),
        axes: Vec::new(),
        mode: Mode::Cartesian,
        traces: false,
        points: vec![Point {
            params: Vec::new(),
            config: config.clone(),
        }],
        secrecy: SecrecyDefaults::default(),
    };
    let point = analyze(&experiment, &options)?
        .into_iter()
        .next()
        .expect("one point, one adversary: one result");
    Ok(CameraThreat {
        statement: camera.describe(),
        per_instant_mm: config.modelled_camera_std().map(|s| 1e3 * s),
        raw_bits: point.raw_bits,
        secret_bits: point.secret_bits,
        bits_per_step: point.secret_bits_per_step,
        bits_per_second: point.secret_bits_per_second,
        zero_reason: point.zero_reason,
    })
}

/// Bisects the per-instant camera noise (geometrically, over [`BREAK_EVEN_RANGE`]) for the
/// noise where the rate reaches zero, to [`BREAK_EVEN_RESOLUTION`].
fn break_even(config: &Config) -> Result<BreakEven, LabError> {
    let positive = |noise: f64| -> Result<bool, LabError> {
        let camera = Camera::Instants { std: [noise; 3] };
        Ok(camera_threat(config, camera)?.secret_bits > 0)
    };
    let [mut zero, mut secret] = BREAK_EVEN_RANGE;
    if positive(zero)? {
        return Ok(BreakEven::Below { mm: 1e3 * zero });
    }
    if !positive(secret)? {
        return Ok(BreakEven::Above { mm: 1e3 * secret });
    }
    while secret / zero > BREAK_EVEN_RESOLUTION {
        let middle = (zero * secret).sqrt();
        if positive(middle)? {
            secret = middle;
        } else {
            zero = middle;
        }
    }
    Ok(BreakEven::Between {
        zero_at_mm: 1e3 * zero,
        positive_at_mm: 1e3 * secret,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn private(toml: &str) -> Config {
        Config::from_toml(&format!("[sensing]\nmode = \"private\"\n{toml}"), "test").unwrap()
    }

    #[test]
    fn frames_of_16_mm_at_30_fps_are_worth_the_measured_8_mm_per_instant() {
        // docs/world.md measured the camera Eve with 16 mm frames at 30 frames/s: 0.366
        // bits per bit, exactly as with 8 mm per instant. The worst phase (a frame at the
        // mid instant, 6 frames per step) is worth 16/√4.056 = 7.94 mm, within 1 %.
        let config = private("");
        let frames = Camera::Frames {
            fps: 30.0,
            frame_std: [0.016; 3],
        };
        let mm = stating(&config, frames).unwrap().modelled_camera_std()[0] * 1e3;
        assert!((mm - 8.0).abs() < 0.08 && mm < 8.0, "{mm}");
    }

    #[test]
    fn the_break_even_lies_in_the_maps_bracket() {
        // docs/private-sensing.md: at motion noise 2 mm the map's break-even camera lies
        // between 2.5 and 3 mm per instant.
        let config = private("[noise]\nprocess_std = [0.002, 0.002, 0.002]\n");
        match break_even(&config).unwrap() {
            BreakEven::Between {
                zero_at_mm,
                positive_at_mm,
            } => {
                assert!(zero_at_mm >= 2.5 && positive_at_mm <= 3.0 * BREAK_EVEN_RESOLUTION);
                assert!(positive_at_mm / zero_at_mm <= BREAK_EVEN_RESOLUTION);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_better_camera_leaves_fewer_secret_bits_and_an_equivalent_statement_the_same() {
        let config = private("");
        let per_instant = |mm: f64| Camera::Instants {
            std: [mm * 1e-3; 3],
        };
        let eight = camera_threat(&config, per_instant(8.0)).unwrap();
        let four = camera_threat(&config, per_instant(4.0)).unwrap();
        assert!(eight.secret_bits > four.secret_bits, "{eight:?} {four:?}");
        assert!((eight.bits_per_second - eight.bits_per_step / 0.2).abs() < 1e-12);
        // 5 frames/s at T = 0.2 s: the worst phase puts one frame at each mid instant.
        let slow = Camera::Frames {
            fps: 5.0,
            frame_std: [0.008; 3],
        };
        let frames = camera_threat(&config, slow).unwrap();
        assert!(
            frames
                .per_instant_mm
                .iter()
                .all(|mm| (mm - 8.0).abs() < 1e-9)
        );
        assert_eq!(frames.secret_bits, eight.secret_bits);
    }

    #[test]
    fn a_camera_out_of_range_is_named() {
        let frames = Camera::Frames {
            fps: 0.0,
            frame_std: [0.008; 3],
        };
        let error = threat(&private(""), &[frames]).unwrap_err().to_string();
        assert!(error.contains("eve.camera_fps"), "{error}");
    }
}
