//! Seeded random streams, one per purpose and replicate (docs/experiments.md).

use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use sha2::{Digest, Sha256};

/// What a random stream is used for. Each purpose has its own seed, so changing how much
/// one consumer draws never shifts another's numbers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Purpose {
    /// The robot's key bits.
    Key,
    /// Plant process noise ζ.
    Process,
    /// Odometry measurement noise η.
    Measurement,
    /// The eavesdropper's model-error draws.
    Eve,
    /// The eavesdropper's camera noise (private sensing).
    Camera,
    /// Channel faults (loss, duplication, …).
    Channel,
    /// Public randomness (nonces, hash seeds, permutations).
    Public,
    /// The world's wheel slip (docs/world.md).
    Slip,
    /// The world's sample-instant timing errors.
    Jitter,
    /// The phase of Eve's camera frames in the world.
    CameraPhase,
}

impl Purpose {
    /// The ASCII label hashed into the seed.
    #[must_use]
    pub fn label(self) -> &'static str {
        match self {
            Self::Key => "key",
            Self::Process => "process",
            Self::Measurement => "measurement",
            Self::Eve => "eve",
            Self::Camera => "camera",
            Self::Channel => "channel",
            Self::Public => "public",
            Self::Slip => "slip",
            Self::Jitter => "jitter",
            Self::CameraPhase => "camera-phase",
        }
    }
}

/// `ChaCha8Rng::from_seed(SHA-256("robokey v1" ‖ seed_le ‖ purpose))` on stream `replicate`.
#[must_use]
pub fn stream(seed: u64, purpose: Purpose, replicate: u64) -> ChaCha8Rng {
    let digest = Sha256::new()
        .chain_update(b"robokey v1")
        .chain_update(seed.to_le_bytes())
        .chain_update(purpose.label().as_bytes())
        .finalize();
    let mut rng = ChaCha8Rng::from_seed(digest.into());
    rng.set_stream(replicate);
    rng
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;
    use rand_distr::{Distribution, StandardNormal};

    /// Golden values: a dependency bump that changes any stream or the normal sampler
    /// must fail here, loudly.
    #[test]
    fn streams_match_their_golden_snapshot() {
        let purposes = [
            Purpose::Key,
            Purpose::Process,
            Purpose::Measurement,
            Purpose::Eve,
            Purpose::Channel,
            Purpose::Public,
        ];
        let firsts: Vec<u64> = purposes
            .iter()
            .map(|&p| stream(2023, p, 0).random::<u64>())
            .collect();
        let replicate_three = stream(2023, Purpose::Process, 3).random::<u64>();
        let normal: f64 = StandardNormal.sample(&mut stream(2023, Purpose::Process, 0));
        let uniform: f64 = stream(2023, Purpose::Eve, 1).random_range(-1.0..=1.0);
        let got = format!("{firsts:?} {replicate_three} {normal:.15} {uniform:.15}");
        assert_eq!(got, GOLDEN);
    }

    const GOLDEN: &str = "[729749689729058726, 730856062635404807, 15564333758528298319, 9955940089970783458, 14294734039507841548, 15922314554794741420] 11900236959501027440 -2.787913217768115 0.522152846291382";
}
