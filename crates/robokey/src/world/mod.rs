//! The world apart from the configuration (docs/world.md): the true physics of the robot and
//! of the sensors around it. The parties' configuration says what they believe; the world is
//! what is — the plant with its noise, slip, lag, delay and resolutions, the controller's
//! sensor as it really is, and Eve's real camera. With no `[world]` table it is the parties'
//! own model, number for number.

mod actuator;
mod camera;
mod config;
mod model;
mod motion;
mod plant;
mod preset;
mod scene;
mod sensor;

pub use actuator::{Actuator, MAX_PENDING, Piece, lagged, quantise};
pub use camera::{Frame, FrameCamera};
pub use config::{
    Integration, MAX_CAMERA_FPS, MAX_JITTER_FRACTION, MAX_SLIP_STD, MAX_WORLD_SECONDS, WorldConfig,
    WorldFieldError, WorldPreset,
};
pub use model::{
    Camera, MAX_SAMPLE_REACH, MAX_SUBSTEPS, WorldModel, per_frame_std, per_instant_std,
};
pub use motion::{Motion, StepNoise, SubStep, sinc};
pub use plant::{Noise, PlantStreams, WorldPlant};
pub use scene::{Observed, Scene};
pub use sensor::InstantSensor;
