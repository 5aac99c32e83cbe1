//! A UDP socket under the session layer: every datagram in goes through the side's
//! [`ControllerChannel`] or [`RobotChannel`], which authenticates it or drops and counts
//! it; every message out is sealed under the side's session key (`docs/wire.md`).

use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use crate::error::{NetError, is_wait_over};
use crate::session::STOP_POLL;
use rand::rngs::ChaCha20Rng;
use robokey::interrupt::Interrupt;
use robokey::protocol::Message;
use robokey::protocol::auth::{
    ChannelCounts, Confirmer, ControllerChannel, Delivery, RejectionCounts, RobotChannel,
};

/// Receive buffer (bytes): the largest UDP payload. A longer frame cannot cross UDP.
const DATAGRAM_BYTES: usize = 65_536;

/// Frame counters of one endpoint.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct FrameCounts {
    /// Datagrams sent.
    pub sent: u64,
    /// Authenticated, fresh session frames received.
    pub received: u64,
    /// Of those, received out of order within the replay window.
    pub reordered: u64,
}

/// The session layer of one side.
#[derive(Debug)]
enum Side {
    /// The controller.
    Controller(ControllerChannel<SocketAddr>),
    /// The robot, with its generator of `nonce_r`.
    Robot(Box<RobotChannel<SocketAddr>>, ChaCha20Rng),
}

/// An authenticated framed UDP endpoint talking to one peer.
#[derive(Debug)]
pub struct Transport {
    socket: UdpSocket,
    side: Side,
    sent: u64,
    buffer: Vec<u8>,
    interrupt: Interrupt,
}

impl Transport {
    /// The controller's transport: binds `local`, talks to the channel's robot.
    ///
    /// # Errors
    /// The address cannot be bound.
    pub fn controller(
        local: SocketAddr,
        channel: ControllerChannel<SocketAddr>,
    ) -> Result<Self, NetError> {
        Ok(Self {
            socket: bind(local)?,
            side: Side::Controller(channel),
            sent: 0,
            buffer: vec![0; DATAGRAM_BYTES],
            interrupt: Interrupt::new(),
        })
    }

    /// The robot's transport: listens on `local`; `rng` draws its handshake nonces.
    ///
    /// # Errors
    /// The address cannot be bound.
    pub fn robot(
        local: SocketAddr,
        channel: RobotChannel<SocketAddr>,
        rng: ChaCha20Rng,
    ) -> Result<Self, NetError> {
        Ok(Self {
            socket: bind(local)?,
            side: Side::Robot(Box::new(channel), rng),
            sent: 0,
            buffer: vec![0; DATAGRAM_BYTES],
            interrupt: Interrupt::new(),
        })
    }

    /// Makes receives fail with [`NetError::Interrupted`] within 50 ms of a stop request.
    #[must_use]
    pub fn with_interrupt(mut self, interrupt: Interrupt) -> Self {
        self.interrupt = interrupt;
        self
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

    /// The peer's address, once known (the robot learns it when the session binds).
    #[must_use]
    pub fn peer(&self) -> Option<SocketAddr> {
        match &self.side {
            Side::Controller(channel) => Some(channel.robot()),
            Side::Robot(channel, _) => channel.bound().map(|(peer, _)| peer),
        }
    }

    /// The session id: the controller's own; the robot's once bound.
    #[must_use]
    pub fn session(&self) -> Option<u32> {
        match &self.side {
            Side::Controller(channel) => Some(channel.session()),
            Side::Robot(channel, _) => channel.bound().map(|(_, session)| session),
        }
    }

    /// The session's confirmer, once keyed.
    #[must_use]
    pub fn confirmer(&self) -> Option<Confirmer> {
        match &self.side {
            Side::Controller(channel) => channel.confirmer(),
            Side::Robot(channel, _) => channel.confirmer(),
        }
    }

    /// Counters of the frames sent and received.
    #[must_use]
    pub fn counts(&self) -> FrameCounts {
        let channel = self.channel_counts();
        FrameCounts {
            sent: self.sent,
            received: channel.accepted,
            reordered: channel.reordered,
        }
    }

    /// Datagrams dropped, by reason.
    #[must_use]
    pub fn rejected(&self) -> RejectionCounts {
        self.channel_counts().rejected
    }

    fn channel_counts(&self) -> ChannelCounts {
        match &self.side {
            Side::Controller(channel) => channel.counts(),
            Side::Robot(channel, _) => channel.counts(),
        }
    }

    fn send_bytes(&mut self, bytes: &[u8], to: SocketAddr) -> Result<(), NetError> {
        self.socket
            .send_to(bytes, to)
            .map_err(NetError::io(format!("send to {to}")))?;
        self.sent += 1;
        Ok(())
    }

    /// Controller: sends (or repeats) the Hello.
    ///
    /// # Errors
    /// The socket fails.
    pub fn send_hello(&mut self) -> Result<(), NetError> {
        if let Side::Controller(channel) = &self.side {
            let (hello, robot) = (channel.hello().to_vec(), channel.robot());
            self.send_bytes(&hello, robot)?;
        }
        Ok(())
    }

    /// Seals a message under the session key and sends it to the peer (no-op before the
    /// session is keyed and, at the robot, bound).
    ///
    /// # Errors
    /// The socket fails.
    pub fn send(&mut self, message: Message) -> Result<(), NetError> {
        let sealed = match &mut self.side {
            Side::Controller(channel) => {
                let robot = channel.robot();
                channel.seal(message).map(|bytes| (bytes, robot))
            }
            Side::Robot(channel, _) => {
                let peer = channel.bound().map(|(peer, _)| peer);
                channel.seal(message).zip(peer)
            }
        };
        match sealed {
            Some((bytes, to)) => self.send_bytes(&bytes, to),
            None => Ok(()),
        }
    }

    /// Waits until `deadline` for the next delivery of the session layer. Rejected
    /// datagrams are counted and skipped; the robot's answers to Hellos are sent here.
    ///
    /// # Errors
    /// The socket fails, or a stop was requested (timeouts are `Ok(None)`).
    pub fn recv_until(&mut self, deadline: Instant) -> Result<Option<Delivery>, NetError> {
        loop {
            if let Some(signal) = self.interrupt.signal() {
                return Err(NetError::Interrupted(signal));
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(None);
            }
            let wait = (deadline - now).clamp(Duration::from_micros(100), STOP_POLL);
            self.socket
                .set_read_timeout(Some(wait))
                .map_err(NetError::io("set socket timeout"))?;
            let (len, from) = match self.socket.recv_from(&mut self.buffer) {
                Ok(x) => x,
                // A timeout or a signal (EINTR): the loop looks at the deadline and the stop request.
                Err(e) if is_wait_over(&e) => continue,
                // A previous send to a closed port (ICMP unreachable) surfaces here.
                Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => continue,
                Err(e) => return Err(NetError::io("receive")(e)),
            };
            let bytes = &self.buffer[..len];
            let delivery = match &mut self.side {
                Side::Controller(channel) => channel.on_datagram(from, bytes),
                Side::Robot(channel, rng) => channel.on_datagram(from, bytes, rng),
            };
            match delivery {
                Ok(Delivery::Answer { bytes, refused }) => {
                    self.send_bytes(&bytes, from)?;
                    if let Some(reason) = refused {
                        return Ok(Some(Delivery::Refused(reason)));
                    }
                }
                Ok(delivery) => return Ok(Some(delivery)),
                Err(_) => {}
            }
        }
    }
}

fn bind(local: SocketAddr) -> Result<UdpSocket, NetError> {
    UdpSocket::bind(local).map_err(NetError::io(format!("bind UDP {local}")))
}
