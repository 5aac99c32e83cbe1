//! The world is a process too (docs/sensors.md): the plant the robot drives — the simulated
//! backend, or the Khepera IV emulator — also serves what the outside sees of it, from the
//! true pose at every sample instant: the controller's motion capture (`sensing.controller_std`)
//! and Eve's camera (`eve.camera_std`), each on its own TCP socket with its own random stream.

use std::net::SocketAddr;

use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use robokey::Config;
use robokey::model::Pose;
use robokey::rng::{Purpose, stream};

use crate::error::NetError;
use crate::pose_stream::{PoseSample, PoseServer};

/// `N(0, diag(std)²)`, drawn x, y, θ in order.
pub(crate) fn gaussian(rng: &mut ChaCha8Rng, std: &Pose) -> Pose {
    Pose::new(
        StandardNormal.sample(rng),
        StandardNormal.sample(rng),
        StandardNormal.sample(rng),
    )
    .component_mul(std)
}

/// Where the world serves its sensor streams, and their noise.
#[derive(Clone, Debug, PartialEq)]
pub struct SensorOptions {
    /// The controller's motion capture: TCP address (port 0: any), or not served.
    pub mocap: Option<SocketAddr>,
    /// Eve's camera: TCP address (port 0: any), or not served.
    pub camera: Option<SocketAddr>,
    /// Motion-capture noise std (m, m, rad): `sensing.controller_std`.
    pub mocap_std: [f64; 3],
    /// Camera noise std (m, m, rad): `eve.camera_std`.
    pub camera_std: [f64; 3],
    /// Seed of the noise streams: with the simulator's seed, a lockstep session draws the
    /// simulator's numbers.
    pub seed: u64,
}

impl SensorOptions {
    /// The streams of `config`'s noise and seed, served at these addresses.
    #[must_use]
    pub fn of(config: &Config, mocap: Option<SocketAddr>, camera: Option<SocketAddr>) -> Self {
        Self {
            mocap,
            camera,
            mocap_std: config.sensing.controller_std,
            camera_std: config.eve.camera_std,
            seed: config.run.seed,
        }
    }
}

/// One noisy stream: a server, its noise and its random stream.
#[derive(Debug)]
struct NoisyStream {
    server: PoseServer,
    std: Pose,
    purpose: Purpose,
    noise: ChaCha8Rng,
}

/// The world's sensors: each draws its noise from the simulator's stream for its purpose —
/// motion capture from "measurement" (the controller's sensor in private sensing), the
/// camera from "camera" — replicate `r` of the seed for the world's session `r`.
#[derive(Debug)]
pub struct WorldSensors {
    seed: u64,
    streams: Vec<NoisyStream>,
}

impl WorldSensors {
    /// Binds the streams of `options`; the first session is replicate 0.
    ///
    /// # Errors
    /// An address cannot be bound.
    pub fn serve(options: &SensorOptions) -> Result<Self, NetError> {
        let mut streams = Vec::new();
        for (address, std, purpose) in [
            (options.mocap, options.mocap_std, Purpose::Measurement),
            (options.camera, options.camera_std, Purpose::Camera),
        ] {
            if let Some(address) = address {
                streams.push(NoisyStream {
                    server: PoseServer::bind(address)?,
                    std: Pose::from(std),
                    purpose,
                    noise: stream(options.seed, purpose, 0),
                });
            }
        }
        Ok(Self {
            seed: options.seed,
            streams,
        })
    }

    /// One line saying where the streams are, e.g. `world: motion capture on
    /// 127.0.0.1:7400, camera on 127.0.0.1:7401`.
    #[must_use]
    pub fn describe(&self) -> String {
        let parts: Vec<String> = self
            .streams
            .iter()
            .map(|s| {
                let name = match s.purpose {
                    Purpose::Camera => "camera",
                    _ => "motion capture",
                };
                format!("{name} on {}", s.server.address())
            })
            .collect();
        format!("world: {}", parts.join(", "))
    }

    /// Starts session `replicate`: reseeds each noise from its stream's replicate.
    pub fn begin_session(&mut self, replicate: u64) {
        for s in &mut self.streams {
            s.noise = stream(self.seed, s.purpose, replicate);
        }
    }

    /// Ends the session's streams: their clients read end of file (a recorder stops), and
    /// later clients get only the next session's samples.
    pub fn end_session(&mut self) {
        for s in &self.streams {
            s.server.end_session();
        }
    }

    /// Serves what each sensor sees of the true pose `pose` at sample instant `step`.
    pub fn publish(&mut self, step: u32, pose: &Pose) {
        for s in &mut self.streams {
            let sample = PoseSample {
                step,
                pose: pose + gaussian(&mut s.noise, &s.std),
            };
            s.server.publish(&sample);
        }
    }
}
