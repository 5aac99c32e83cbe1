//! A user-space faulty network between controller and robot (Linux netem is not available
//! here): loss, duplication, reordering, delay with jitter and corruption, seeded; and a
//! capture of every datagram for the eavesdropper.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::net::{SocketAddr, UdpSocket};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use rand::RngExt;
use rand::rngs::ChaCha8Rng;
use robokey::interrupt::Interrupt;
use robokey::rng::{Purpose, stream};
use serde::Serialize;

use crate::agent::socket::STOP_POLL;
use crate::error::{NetError, is_wait_over};
use crate::pcap::PcapWriter;

/// Fault probabilities (per datagram) and delays.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Faults {
    /// Probability of dropping a datagram.
    pub loss: f64,
    /// Probability of delivering it twice.
    pub duplicate: f64,
    /// Probability of holding it back so that later datagrams overtake it.
    pub reorder: f64,
    /// Probability of flipping one bit.
    pub corrupt: f64,
    /// Mean one-way delay.
    pub delay: Duration,
    /// Uniform jitter ± around the delay.
    pub jitter: Duration,
}

/// Options of the relay.
#[derive(Clone, Debug)]
pub struct RelayOptions {
    /// Where the controller sends to.
    pub listen: SocketAddr,
    /// The robot agent.
    pub forward: SocketAddr,
    /// Faults applied in both directions.
    pub faults: Faults,
    /// Seed of the fault streams.
    pub seed: u64,
    /// Capture file.
    pub capture: Option<PathBuf>,
    /// Record datagrams as delivered (after faults) instead of as sent.
    pub capture_after_faults: bool,
    /// Exit after this long without traffic (once traffic has started).
    pub idle_exit: Option<Duration>,
    /// A stop request (SIGINT, SIGTERM): the relay returns its statistics within 50 ms.
    pub interrupt: Interrupt,
}

/// What the relay did, per direction.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct DirectionStats {
    /// Datagrams received from the sender.
    pub received: u64,
    /// Dropped.
    pub lost: u64,
    /// Extra copies sent.
    pub duplicated: u64,
    /// Held back.
    pub reordered: u64,
    /// Bit-flipped.
    pub corrupted: u64,
    /// Delivered (including duplicates).
    pub delivered: u64,
}

/// Relay statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct RelayStats {
    /// Controller → robot.
    pub to_robot: DirectionStats,
    /// Robot → controller.
    pub to_controller: DirectionStats,
}

/// A datagram waiting for its delivery time.
#[derive(Debug, PartialEq, Eq, PartialOrd, Ord)]
struct Pending {
    due: Instant,
    order: u64,
    to_robot: bool,
    bytes: Vec<u8>,
}

/// Applies the fault model to one datagram; returns the copies to deliver and their delays.
fn apply_faults(
    faults: &Faults,
    rng: &mut ChaCha8Rng,
    bytes: &[u8],
    stats: &mut DirectionStats,
) -> Vec<(Duration, Vec<u8>)> {
    // Every draw is made for every datagram so that the streams stay aligned.
    let (lose, dup, reorder, corrupt, jitter): (f64, f64, f64, f64, f64) = (
        rng.random(),
        rng.random(),
        rng.random(),
        rng.random(),
        rng.random(),
    );
    let flip_at: usize = rng.random_range(0..bytes.len().max(1) * 8);
    stats.received += 1;
    if lose < faults.loss {
        stats.lost += 1;
        return Vec::new();
    }
    let mut payload = bytes.to_vec();
    if corrupt < faults.corrupt && !payload.is_empty() {
        payload[flip_at / 8] ^= 1 << (flip_at % 8);
        stats.corrupted += 1;
    }
    let base = faults.delay.as_secs_f64() + faults.jitter.as_secs_f64() * (2.0 * jitter - 1.0);
    let mut delay = Duration::from_secs_f64(base.max(0.0));
    if reorder < faults.reorder {
        delay += faults.delay * 2 + Duration::from_millis(15);
        stats.reordered += 1;
    }
    let mut copies = vec![(delay, payload.clone())];
    if dup < faults.duplicate {
        copies.push((delay + Duration::from_millis(1), payload));
        stats.duplicated += 1;
    }
    copies
}

/// Coarsest a socket receive timeout may be (the kernel rounds it up to its tick).
const TIMEOUT_GRAIN: Duration = Duration::from_millis(5);

/// Sleep between non-blocking receives while a delivery is due within [`TIMEOUT_GRAIN`].
const PRECISE_SLEEP: Duration = Duration::from_micros(100);

/// Runs the relay until it has been idle for `idle_exit` (forever without it) or a stop is
/// requested. One socket carries both directions: the controller sends to it, the robot
/// answers it, and the sender's address tells the direction. One thread blocks in `recv`
/// until the next datagram or the next delivery due, whichever comes first (within 5 ms of
/// a delivery, short sleeps between non-blocking receives keep its time): no hand-over
/// between threads, no polling while idle.
///
/// # Errors
/// The socket or the capture file fails.
pub fn run_relay(options: &RelayOptions) -> Result<RelayStats, NetError> {
    let socket = UdpSocket::bind(options.listen)
        .map_err(NetError::io(format!("bind UDP {}", options.listen)))?;
    let relay_addr = socket.local_addr().map_err(NetError::io("local address"))?;
    println!(
        "relay listening on {relay_addr}, forwarding to {}",
        options.forward
    );
    let mut capture = options
        .capture
        .as_deref()
        .map(PcapWriter::create)
        .transpose()?;
    let mut rngs = [
        stream(options.seed, Purpose::Channel, 0),
        stream(options.seed, Purpose::Channel, 1),
    ];
    let mut stats = RelayStats::default();
    let mut queue: BinaryHeap<Reverse<Pending>> = BinaryHeap::new();
    let mut controller: Option<SocketAddr> = None;
    let mut last_traffic: Option<Instant> = None;
    let mut order = 0u64;
    let mut buffer = vec![0u8; 65_536];
    loop {
        if options.interrupt.is_requested() {
            return Ok(stats);
        }
        // A socket timeout is only as fine as the kernel's tick (4 ms here): a delivery due
        // sooner is waited for with short sleeps between non-blocking receives.
        let until_due = queue
            .peek()
            .map(|Reverse(p)| p.due.saturating_duration_since(Instant::now()));
        let precise = until_due.is_some_and(|d| d < TIMEOUT_GRAIN);
        socket
            .set_nonblocking(precise)
            .map_err(NetError::io("set the relay's socket mode"))?;
        if !precise {
            let wait = until_due.map_or(STOP_POLL, |d| {
                (d - TIMEOUT_GRAIN).clamp(Duration::from_micros(1), STOP_POLL)
            });
            socket
                .set_read_timeout(Some(wait))
                .map_err(NetError::io("set the relay's receive timeout"))?;
        }
        match socket.recv_from(&mut buffer) {
            Ok((len, from)) => {
                last_traffic = Some(Instant::now());
                let to_robot = from != options.forward;
                // The latest controller-side sender is the controller: consecutive sessions
                // (each controller on a new port) can share one relay.
                if to_robot {
                    controller = Some(from);
                }
                if let Some(controller_addr) = controller {
                    let (source, destination) = if to_robot {
                        (controller_addr, options.forward)
                    } else {
                        (options.forward, controller_addr)
                    };
                    if let (Some(pcap), false) = (capture.as_mut(), options.capture_after_faults) {
                        pcap.write(source, destination, &buffer[..len])?;
                    }
                    let direction = if to_robot {
                        &mut stats.to_robot
                    } else {
                        &mut stats.to_controller
                    };
                    let now = Instant::now();
                    for (delay, bytes) in apply_faults(
                        &options.faults,
                        &mut rngs[usize::from(!to_robot)],
                        &buffer[..len],
                        direction,
                    ) {
                        order += 1;
                        queue.push(Reverse(Pending {
                            due: now + delay,
                            order,
                            to_robot,
                            bytes,
                        }));
                    }
                }
            }
            Err(e) if precise && e.kind() == std::io::ErrorKind::WouldBlock => {
                std::thread::sleep(until_due.unwrap_or_default().min(PRECISE_SLEEP));
            }
            // A previous send to a closed port (ICMP unreachable) surfaces here too.
            Err(e) if is_wait_over(&e) || e.kind() == std::io::ErrorKind::ConnectionRefused => {}
            Err(e) => return Err(NetError::io("relay receive")(e)),
        }
        while queue
            .peek()
            .is_some_and(|Reverse(p)| p.due <= Instant::now())
        {
            let Some(Reverse(pending)) = queue.pop() else {
                break;
            };
            let Some(controller_addr) = controller else {
                continue;
            };
            let (source, destination) = if pending.to_robot {
                (controller_addr, options.forward)
            } else {
                (options.forward, controller_addr)
            };
            // A peer that is gone is not the relay's failure.
            let _ = socket.send_to(&pending.bytes, destination);
            if let (Some(pcap), true) = (capture.as_mut(), options.capture_after_faults) {
                pcap.write(source, destination, &pending.bytes)?;
            }
            let direction = if pending.to_robot {
                &mut stats.to_robot
            } else {
                &mut stats.to_controller
            };
            direction.delivered += 1;
        }
        if let (Some(idle), Some(last)) = (options.idle_exit, last_traffic)
            && queue.is_empty()
            && last.elapsed() >= idle
        {
            return Ok(stats);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fault_rates_follow_their_probabilities() {
        let faults = Faults {
            loss: 0.1,
            duplicate: 0.05,
            reorder: 0.05,
            corrupt: 0.01,
            ..Faults::default()
        };
        let mut rng = stream(1, Purpose::Channel, 0);
        let mut stats = DirectionStats::default();
        let n = 20_000;
        for _ in 0..n {
            apply_faults(&faults, &mut rng, &[0u8; 40], &mut stats);
        }
        // Binomial rates within 4.5 standard errors.
        let check = |count: u64, p: f64, of: f64| {
            let se = (p * (1.0 - p) / of).sqrt();
            assert!(
                (count as f64 / of - p).abs() < 4.5 * se,
                "{count} of {of} vs p = {p}"
            );
        };
        check(stats.lost, 0.1, f64::from(n));
        let kept = f64::from(n) - stats.lost as f64;
        check(stats.duplicated, 0.05, kept);
        check(stats.corrupted, 0.01, kept);
    }
}
