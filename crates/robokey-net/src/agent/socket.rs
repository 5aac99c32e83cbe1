//! An agent's UDP socket and its clock: datagrams in until a deadline (or a stop request),
//! best-effort datagrams out, and the core's [`Time`] measured from the agent's start.

use std::net::{IpAddr, SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use robokey::interrupt::Interrupt;
use robokey::protocol::Time;
use serde::Serialize;

use crate::error::{NetError, is_wait_over};

/// Longest a blocking wait (a receive, a sleep) lasts before it looks at the stop request
/// again.
pub const STOP_POLL: Duration = Duration::from_millis(50);

/// Receive buffer (bytes): the largest UDP payload. A longer frame cannot cross UDP.
const DATAGRAM_BYTES: usize = 65_536;

/// What the socket did, for the report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct SocketCounts {
    /// Datagrams sent.
    pub sent: u64,
    /// Datagrams that could not be sent (best effort: each is lost, like a dropped one).
    pub unsent: u64,
    /// Datagrams from a source that cannot be a peer (port 0, an unspecified, broadcast or
    /// multicast address), dropped unread and never answered.
    pub impossible_source: u64,
}

/// A datagram as received: its source, when it came, its bytes.
pub type Received<'a> = (SocketAddr, Time, &'a [u8]);

/// A bound UDP socket with the agent's clock.
#[derive(Debug)]
pub struct Socket {
    socket: UdpSocket,
    buffer: Vec<u8>,
    epoch: Instant,
    interrupt: Interrupt,
    counts: SocketCounts,
}

impl Socket {
    /// Binds `local`; receives end within 50 ms of a stop request on `interrupt`.
    ///
    /// # Errors
    /// The address cannot be bound.
    pub fn bind(local: SocketAddr, interrupt: Interrupt) -> Result<Self, NetError> {
        Ok(Self {
            socket: UdpSocket::bind(local).map_err(NetError::io(format!("bind UDP {local}")))?,
            buffer: vec![0; DATAGRAM_BYTES],
            epoch: Instant::now(),
            interrupt,
            counts: SocketCounts::default(),
        })
    }

    /// The bound address.
    ///
    /// # Errors
    /// The OS cannot tell.
    pub fn local_addr(&self) -> Result<SocketAddr, NetError> {
        self.socket
            .local_addr()
            .map_err(NetError::io("local address"))
    }

    /// The time since the agent started.
    #[must_use]
    pub fn now(&self) -> Time {
        Time::from_duration(self.epoch.elapsed())
    }

    /// What the socket did so far.
    #[must_use]
    pub fn counts(&self) -> SocketCounts {
        self.counts
    }

    /// Sends `bytes` to `to`, best effort: a datagram the OS refuses is counted and lost, as
    /// one the network drops would be.
    pub fn send(&mut self, to: SocketAddr, bytes: &[u8]) {
        match self.socket.send_to(bytes, to) {
            Ok(_) => self.counts.sent += 1,
            Err(_) => self.counts.unsent += 1,
        }
    }

    /// Waits until `deadline` (on the agent's clock) for a datagram from a source that can be
    /// a peer: its source, when it came, and its bytes; `None` at the deadline.
    ///
    /// # Errors
    /// The socket fails, or a stop was requested.
    pub fn recv_until(&mut self, deadline: Time) -> Result<Option<Received<'_>>, NetError> {
        loop {
            if let Some(signal) = self.interrupt.signal() {
                return Err(NetError::Interrupted(signal));
            }
            let left = deadline.saturating_since(self.now());
            if left.is_zero() {
                return Ok(None);
            }
            self.socket
                .set_read_timeout(Some(left.clamp(Duration::from_micros(100), STOP_POLL)))
                .map_err(NetError::io("set socket timeout"))?;
            let (len, from) = match self.socket.recv_from(&mut self.buffer) {
                Ok(received) => received,
                // A timeout or a signal (EINTR): look at the deadline and the stop request.
                Err(e) if is_wait_over(&e) => continue,
                // A previous send to a closed port (ICMP unreachable) surfaces here.
                Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => continue,
                Err(e) => return Err(NetError::io("receive")(e)),
            };
            if !can_be_peer(from) {
                self.counts.impossible_source += 1;
                continue;
            }
            let now = self.now();
            return Ok(Some((from, now, &self.buffer[..len])));
        }
    }
}

/// Whether a datagram's source can be a peer to answer: not port 0, and not an unspecified,
/// broadcast or multicast address (an answer there fails, or reaches others).
#[must_use]
pub fn can_be_peer(source: SocketAddr) -> bool {
    let ip_ok = match source.ip() {
        IpAddr::V4(ip) => !(ip.is_unspecified() || ip.is_broadcast() || ip.is_multicast()),
        IpAddr::V6(ip) => !(ip.is_unspecified() || ip.is_multicast()),
    };
    source.port() != 0 && ip_ok
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sources_that_cannot_be_a_peer_are_named() {
        for bad in [
            "127.0.0.1:0",
            "0.0.0.0:5000",
            "255.255.255.255:5000",
            "224.0.0.1:5000",
            "[::]:5000",
            "[ff02::1]:5000",
        ] {
            assert!(!can_be_peer(bad.parse().unwrap()), "{bad}");
        }
        for good in ["127.0.0.1:5000", "[::1]:5000", "10.0.0.2:40000"] {
            assert!(can_be_peer(good.parse().unwrap()), "{good}");
        }
    }

    /// A datagram the OS refuses (to port 0, or to a broadcast address without
    /// `SO_BROADCAST`) is counted and lost, never an error that ends the agent.
    #[test]
    fn sends_are_best_effort() {
        let mut socket = Socket::bind("127.0.0.1:0".parse().unwrap(), Interrupt::new()).unwrap();
        socket.send("127.0.0.1:0".parse().unwrap(), b"x");
        socket.send("255.255.255.255:5000".parse().unwrap(), b"x");
        let counts = socket.counts();
        assert_eq!((counts.sent, counts.unsent), (0, 2));
    }
}
