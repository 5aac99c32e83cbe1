//! The agents' randomness: a ChaCha20 stream seeded from the operating system's CSPRNG.

use crate::error::NetError;

/// A ChaCha20 generator seeded from the operating system's CSPRNG: the robot's key source
/// in deployment, the handshake's nonces, session ids and the stores' file ids.
///
/// # Errors
/// The OS generator is unavailable (an I/O failure of the machine, not a usage error).
pub fn os_rng() -> Result<rand::rngs::ChaCha20Rng, NetError> {
    use rand::SeedableRng;
    rand::rngs::ChaCha20Rng::try_from_rng(&mut rand::rngs::SysRng)
        .map_err(|e| NetError::io("the OS random generator")(std::io::Error::other(e.to_string())))
}
