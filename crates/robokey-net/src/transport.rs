//! A UDP socket that speaks frames: numbers what it sends, drops what does not decode,
//! belongs to another session, or was seen before (docs/protocol.md, docs/wire.md).

use std::collections::{HashSet, VecDeque};
use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use robokey::protocol::Message;
use robokey::protocol::wire::{Frame, decode, encode};

use crate::error::NetError;

/// How many recent sequence numbers are remembered for duplicate detection.
const REMEMBERED: usize = 4096;

/// Frame counters of one endpoint.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct FrameCounts {
    /// Frames sent.
    pub sent: u64,
    /// Valid frames received and delivered.
    pub received: u64,
    /// Datagrams that did not decode (corrupt, truncated, foreign).
    pub corrupt: u64,
    /// Valid frames dropped as duplicates.
    pub duplicates: u64,
    /// Valid frames of another session.
    pub foreign: u64,
}

/// A framed UDP endpoint talking to one peer.
#[derive(Debug)]
pub struct Transport {
    socket: UdpSocket,
    peer: Option<SocketAddr>,
    session: Option<u32>,
    next_seq: u32,
    seen: HashSet<u32>,
    seen_order: VecDeque<u32>,
    /// Counters for the session report.
    pub counts: FrameCounts,
}

impl Transport {
    /// Binds `local`; `peer` is learned from the first valid frame when `None`.
    ///
    /// # Errors
    /// The address cannot be bound.
    pub fn bind(local: SocketAddr, peer: Option<SocketAddr>) -> Result<Self, NetError> {
        let socket = UdpSocket::bind(local).map_err(NetError::io(format!("bind UDP {local}")))?;
        Ok(Self {
            socket,
            peer,
            session: None,
            next_seq: 0,
            seen: HashSet::new(),
            seen_order: VecDeque::new(),
            counts: FrameCounts::default(),
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

    /// Fixes the session id: frames of other sessions are dropped from now on.
    pub fn set_session(&mut self, session: u32) {
        self.session = Some(session);
    }

    /// The peer, once known.
    #[must_use]
    pub fn peer(&self) -> Option<SocketAddr> {
        self.peer
    }

    /// Sends a message in a new frame (no-op before the peer is known).
    ///
    /// # Errors
    /// The socket fails.
    pub fn send(&mut self, message: Message) -> Result<(), NetError> {
        let Some(peer) = self.peer else { return Ok(()) };
        let frame = Frame {
            session: self.session.unwrap_or(0),
            seq: self.next_seq,
            message,
        };
        self.next_seq = self.next_seq.wrapping_add(1);
        self.socket
            .send_to(&encode(&frame), peer)
            .map_err(NetError::io(format!("send to {peer}")))?;
        self.counts.sent += 1;
        Ok(())
    }

    /// Waits until `deadline` for the next valid, new frame of this session; returns its
    /// session id and message.
    ///
    /// # Errors
    /// The socket fails (timeouts are `Ok(None)`).
    pub fn recv_until(&mut self, deadline: Instant) -> Result<Option<(u32, Message)>, NetError> {
        let mut buffer = [0u8; 65_536];
        loop {
            let now = Instant::now();
            if now >= deadline {
                return Ok(None);
            }
            let wait = (deadline - now).max(Duration::from_micros(100));
            self.socket
                .set_read_timeout(Some(wait))
                .map_err(NetError::io("set socket timeout"))?;
            let (len, from) = match self.socket.recv_from(&mut buffer) {
                Ok(x) => x,
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    return Ok(None);
                }
                // A previous send to a closed port (ICMP unreachable) surfaces here.
                Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => continue,
                Err(e) => return Err(NetError::io("receive")(e)),
            };
            let Ok(frame) = decode(&buffer[..len]) else {
                self.counts.corrupt += 1;
                continue;
            };
            if self.session.is_some_and(|s| s != frame.session) {
                self.counts.foreign += 1;
                continue;
            }
            if !self.seen.insert(frame.seq) {
                self.counts.duplicates += 1;
                continue;
            }
            self.seen_order.push_back(frame.seq);
            if self.seen_order.len() > REMEMBERED
                && let Some(old) = self.seen_order.pop_front()
            {
                self.seen.remove(&old);
            }
            self.peer.get_or_insert(from);
            self.counts.received += 1;
            return Ok(Some((frame.session, frame.message)));
        }
    }
}
