//! A simulated robot behind the agent: the simulator's world (its `[world]`, the parties'
//! model without one) with the simulator's random streams, so a clean lockstep session
//! reproduces `robokey run` bit for bit. Its world may also serve the sensor streams
//! (private sensing).

use robokey::config::SensingMode;
use robokey::model::{Pose, WheelSpeeds};

use crate::backend::Backend;
use crate::world::WorldProcess;

/// The robot of a world: odometry in odometry mode, its true pose in private sensing (the
/// robot sends no pose there; the `measurement` stream is the controller's sensor's).
#[derive(Debug)]
pub struct SimBackend {
    world: WorldProcess,
    sensing: SensingMode,
    /// The next sample instant.
    step: u32,
}

impl SimBackend {
    /// The robot of `world`, whose sensors are those of `sensing`.
    #[must_use]
    pub fn new(world: WorldProcess, sensing: SensingMode) -> Self {
        Self {
            world,
            sensing,
            step: 0,
        }
    }

    /// The true pose (m, m, rad).
    #[must_use]
    pub fn pose(&self) -> Pose {
        self.world.plant().pose()
    }
}

impl Backend for SimBackend {
    fn sample(&mut self) -> Result<Pose, crate::error::NetError> {
        if self.step > 0 {
            self.world.step();
        }
        self.step += 1;
        let observed = self.world.sample();
        Ok(match self.sensing {
            SensingMode::Odometry => observed.measured,
            SensingMode::Private => observed.pose,
        })
    }

    fn set_wheels(&mut self, wheels: WheelSpeeds) -> Result<(), crate::error::NetError> {
        self.world.apply(wheels);
        Ok(())
    }

    fn stop(&mut self) {
        self.world.apply(WheelSpeeds::zeros());
    }
}
