//! What a virtual link does to a datagram: latency with jitter, loss, duplication, extra
//! delay that reorders, corruption (docs/protocol.md, "The virtual network").

use std::time::Duration;

use rand::{Rng, RngExt};

use crate::protocol::Message;

/// The faults of one direction of a virtual link. The default is lossless with no latency:
/// what the simulator runs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LinkFaults {
    /// Fixed one-way latency.
    pub latency: Duration,
    /// Uniform extra latency in `[0, jitter]` per datagram.
    pub jitter: Duration,
    /// Probability that a datagram is lost.
    pub loss: f64,
    /// Probability that a datagram arrives twice (the copy with its own delay).
    pub duplicate: f64,
    /// Probability that a datagram is held back by up to [`LinkFaults::reorder_delay`],
    /// arriving after later ones.
    pub reorder: f64,
    /// How long a reordered datagram is held back at most.
    pub reorder_delay: Duration,
    /// Probability that a datagram is corrupted on the way ([`Datagram::corrupt`]).
    pub corrupt: f64,
}

impl LinkFaults {
    /// Whether the link delivers every datagram at once, in order: the simulator's link.
    #[must_use]
    pub fn is_ideal(&self) -> bool {
        *self == Self::default()
    }

    /// What happens to one datagram: the delays after which its copies arrive (none when
    /// lost; two when duplicated), each with whether it arrives corrupted.
    pub fn fate<R: Rng + ?Sized>(&self, rng: &mut R) -> Vec<(Duration, bool)> {
        if rng.random_bool(self.loss.clamp(0.0, 1.0)) {
            return Vec::new();
        }
        let copies = if rng.random_bool(self.duplicate.clamp(0.0, 1.0)) {
            2
        } else {
            1
        };
        (0..copies)
            .map(|_| {
                let mut delay = self.latency + self.jitter.mul_f64(rng.random::<f64>());
                if rng.random_bool(self.reorder.clamp(0.0, 1.0)) {
                    delay += self.reorder_delay.mul_f64(rng.random::<f64>());
                }
                (delay, rng.random_bool(self.corrupt.clamp(0.0, 1.0)))
            })
            .collect()
    }
}

/// What a virtual link carries.
pub trait Datagram: Clone {
    /// The datagram as a corrupted link delivers it, or `None` when nothing of it would
    /// reach the peer's endpoint.
    fn corrupt<R: Rng + ?Sized>(self, rng: &mut R) -> Option<Self>;
}

impl Datagram for Vec<u8> {
    /// One bit flipped: the session layer's MAC must reject it.
    fn corrupt<R: Rng + ?Sized>(mut self, rng: &mut R) -> Option<Self> {
        if self.is_empty() {
            return Some(self);
        }
        let bit = rng.random_range(0..self.len() * 8);
        self[bit / 8] ^= 1 << (bit % 8);
        Some(self)
    }
}

impl Datagram for Message {
    /// Messages that bypass the session layer have no MAC to catch a flipped bit: the
    /// corrupted datagram is the one the MAC would have dropped, so it is lost.
    fn corrupt<R: Rng + ?Sized>(self, _rng: &mut R) -> Option<Self> {
        None
    }
}
