//! The world is a process too (docs/sensors.md, docs/world.md): the plant the robot drives —
//! the simulated backend, the Khepera IV or the ROS 2 emulator — is a [`Scene`] of the
//! configuration's `[world]` (the parties' own model without one), and it serves what the
//! outside sees of it: the controller's motion capture and Eve's camera, each on its own TCP
//! socket, each noise from the simulator's stream for its purpose, replicate `r` of the seed
//! for the world's session `r`.

use std::net::SocketAddr;

use robokey::Config;
use robokey::config::SensingMode;
use robokey::model::WheelSpeeds;
use robokey::rng::stream;
use robokey::world::{Camera, Frame, Observed, Scene, WorldPlant};

use crate::error::NetError;
use crate::pose_stream::{PoseSample, PoseServer};

/// Where the world serves its sensor streams (none: not served).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamAddresses {
    /// The controller's motion capture: TCP address (port 0: any).
    pub mocap: Option<SocketAddr>,
    /// Eve's camera: TCP address (port 0: any).
    pub camera: Option<SocketAddr>,
}

impl StreamAddresses {
    /// Whether any stream is served.
    #[must_use]
    pub fn any(&self) -> bool {
        self.mocap.is_some() || self.camera.is_some()
    }
}

/// Eve's camera stream: samples at the instants, or frames between them.
#[derive(Debug)]
enum CameraServer {
    Instants(PoseServer<PoseSample>),
    Frames(PoseServer<Frame>),
}

/// A world of one robot, session after session.
#[derive(Debug)]
pub struct WorldProcess {
    config: Config,
    sensing: SensingMode,
    scene: Scene,
    mocap: Option<PoseServer<PoseSample>>,
    camera: Option<CameraServer>,
    /// The next sample instant of the session.
    step: u32,
}

impl WorldProcess {
    /// The world of `config` (its `[world]`, noise drawn from `run.seed`), its sensors those
    /// of `sensing` (private: the controller's motion capture and Eve's camera; odometry: the
    /// robot's odometry), the streams bound at `addresses`; the first session is replicate 0.
    ///
    /// # Errors
    /// An address cannot be bound.
    pub fn new(
        config: &Config,
        sensing: SensingMode,
        addresses: &StreamAddresses,
    ) -> Result<Self, NetError> {
        let camera = match addresses.camera {
            None => None,
            Some(address) => Some(match config.world_model().camera {
                Camera::Instants { .. } => CameraServer::Instants(PoseServer::bind(address)?),
                Camera::Frames { .. } => CameraServer::Frames(PoseServer::bind(address)?),
            }),
        };
        Ok(Self {
            scene: session_scene(config, sensing, 0),
            mocap: addresses.mocap.map(PoseServer::bind).transpose()?,
            camera,
            config: config.clone(),
            sensing,
            step: 0,
        })
    }

    /// One line saying where the streams are, e.g. `world: motion capture on
    /// 127.0.0.1:7400, camera on 127.0.0.1:7401`; none when none is served.
    #[must_use]
    pub fn describe(&self) -> Option<String> {
        let mut parts = Vec::new();
        if let Some(server) = &self.mocap {
            parts.push(format!("motion capture on {}", server.address()));
        }
        match &self.camera {
            Some(CameraServer::Instants(server)) => {
                parts.push(format!("camera on {}", server.address()));
            }
            Some(CameraServer::Frames(server)) => {
                parts.push(format!("camera (frames) on {}", server.address()));
            }
            None => {}
        }
        (!parts.is_empty()).then(|| format!("world: {}", parts.join(", ")))
    }

    /// Starts session `replicate`: a robot at rest at the origin, every noise from its
    /// stream's replicate.
    pub fn begin_session(&mut self, replicate: u64) {
        self.scene = session_scene(&self.config, self.sensing, replicate);
        self.step = 0;
    }

    /// Ends the session's streams: their clients read end of file (a recorder stops), and
    /// later clients get only the next session's samples.
    pub fn end_session(&mut self) {
        if let Some(server) = &self.mocap {
            server.end_session();
        }
        match &self.camera {
            Some(CameraServer::Instants(server)) => server.end_session(),
            Some(CameraServer::Frames(server)) => server.end_session(),
            None => {}
        }
    }

    /// The robot's plant.
    #[must_use]
    pub fn plant(&self) -> &WorldPlant {
        self.scene.plant()
    }

    /// The wheels are commanded these speeds from now on (rad/s, right first).
    pub fn apply(&mut self, wheels: WheelSpeeds) {
        self.scene.apply(wheels);
    }

    /// One whole sample period.
    pub fn step(&mut self) {
        self.scene.step();
    }

    /// `duration` seconds of motion.
    pub fn advance(&mut self, duration: f64) {
        self.scene.advance(duration);
    }

    /// The sensors at this sample instant, served on their streams (the motion capture's
    /// sample, Eve's camera at the instant or her frames since the last one).
    pub fn sample(&mut self) -> Observed {
        let observed = self.scene.observe();
        let step = self.step;
        if let Some(server) = &self.mocap {
            server.publish(&PoseSample {
                step,
                pose: observed.measured,
            });
        }
        match &self.camera {
            Some(CameraServer::Instants(server)) => {
                if let Some(pose) = observed.filmed {
                    server.publish(&PoseSample { step, pose });
                }
            }
            Some(CameraServer::Frames(server)) => {
                for frame in &observed.frames {
                    server.publish(frame);
                }
            }
            None => {}
        }
        self.step = self.step.saturating_add(1);
        observed
    }
}

/// The scene of session `replicate` of `config`'s world.
fn session_scene(config: &Config, sensing: SensingMode, replicate: u64) -> Scene {
    let seed = config.run.seed;
    Scene::new(config, sensing, |purpose| stream(seed, purpose, replicate))
}
