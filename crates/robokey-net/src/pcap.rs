//! pcap files with LINKTYPE_RAW and synthetic IPv4/UDP headers, so Wireshark and tshark
//! open relay captures directly.

use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::net::{Ipv4Addr, SocketAddr};
use std::path::Path;
use std::time::{SystemTime, UNIX_EPOCH};

use crate::error::NetError;

/// LINKTYPE_RAW: packets begin with an IPv4 or IPv6 header.
const LINKTYPE_RAW: u32 = 101;
const MAGIC: u32 = 0xA1B2_C3D4;
const IPV4_HEADER: usize = 20;
const UDP_HEADER: usize = 8;

/// One captured UDP datagram.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Datagram {
    /// Capture time (µs since the Unix epoch).
    pub micros: u64,
    /// Sender.
    pub source: SocketAddr,
    /// Receiver.
    pub destination: SocketAddr,
    /// UDP payload: one robokey frame.
    pub payload: Vec<u8>,
}

/// Writes datagrams to a pcap file, flushing each one (a killed relay leaves a valid file).
#[derive(Debug)]
pub struct PcapWriter {
    out: BufWriter<File>,
    ip_id: u16,
}

fn ipv4(addr: SocketAddr) -> Ipv4Addr {
    match addr {
        SocketAddr::V4(a) => *a.ip(),
        // IPv6 peers are recorded as 0.0.0.0 with their ports.
        SocketAddr::V6(a) => a.ip().to_ipv4_mapped().unwrap_or(Ipv4Addr::UNSPECIFIED),
    }
}

fn checksum(header: &[u8]) -> u16 {
    let mut sum: u32 = header
        .chunks(2)
        .map(|c| u32::from(u16::from_be_bytes([c[0], *c.get(1).unwrap_or(&0)])))
        .sum();
    while sum > 0xFFFF {
        sum = (sum & 0xFFFF) + (sum >> 16);
    }
    !(sum as u16)
}

impl PcapWriter {
    /// Creates the file and writes the global header.
    ///
    /// # Errors
    /// The file cannot be created.
    pub fn create(path: &Path) -> Result<Self, NetError> {
        let file = File::create(path)
            .map_err(NetError::io(format!("create capture {}", path.display())))?;
        let mut out = BufWriter::new(file);
        let mut header = Vec::with_capacity(24);
        header.extend_from_slice(&MAGIC.to_le_bytes());
        header.extend_from_slice(&2u16.to_le_bytes());
        header.extend_from_slice(&4u16.to_le_bytes());
        header.extend_from_slice(&0i32.to_le_bytes());
        header.extend_from_slice(&0u32.to_le_bytes());
        header.extend_from_slice(&65_535u32.to_le_bytes());
        header.extend_from_slice(&LINKTYPE_RAW.to_le_bytes());
        out.write_all(&header)
            .and_then(|()| out.flush())
            .map_err(NetError::io(format!("write {}", path.display())))?;
        Ok(Self { out, ip_id: 0 })
    }

    /// Appends one UDP datagram stamped now.
    ///
    /// # Errors
    /// The file cannot be written.
    pub fn write(
        &mut self,
        source: SocketAddr,
        destination: SocketAddr,
        payload: &[u8],
    ) -> Result<(), NetError> {
        let now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default();
        let total = IPV4_HEADER + UDP_HEADER + payload.len();
        let mut ip = [0u8; IPV4_HEADER];
        ip[0] = 0x45;
        ip[2..4].copy_from_slice(&(total as u16).to_be_bytes());
        ip[4..6].copy_from_slice(&self.ip_id.to_be_bytes());
        ip[6] = 0x40; // don't fragment
        ip[8] = 64;
        ip[9] = 17; // UDP
        ip[12..16].copy_from_slice(&ipv4(source).octets());
        ip[16..20].copy_from_slice(&ipv4(destination).octets());
        let sum = checksum(&ip);
        ip[10..12].copy_from_slice(&sum.to_be_bytes());
        self.ip_id = self.ip_id.wrapping_add(1);
        let mut record = Vec::with_capacity(16 + total);
        record.extend_from_slice(&(now.as_secs() as u32).to_le_bytes());
        record.extend_from_slice(&now.subsec_micros().to_le_bytes());
        record.extend_from_slice(&(total as u32).to_le_bytes());
        record.extend_from_slice(&(total as u32).to_le_bytes());
        record.extend_from_slice(&ip);
        record.extend_from_slice(&source.port().to_be_bytes());
        record.extend_from_slice(&destination.port().to_be_bytes());
        record.extend_from_slice(&((UDP_HEADER + payload.len()) as u16).to_be_bytes());
        record.extend_from_slice(&0u16.to_be_bytes()); // no UDP checksum
        record.extend_from_slice(payload);
        self.out
            .write_all(&record)
            .and_then(|()| self.out.flush())
            .map_err(NetError::io("write capture"))
    }
}

/// Reads every IPv4/UDP datagram of a LINKTYPE_RAW pcap file (other packets are skipped).
///
/// # Errors
/// The file cannot be read, or is not a little- or big-endian microsecond pcap of
/// LINKTYPE_RAW.
pub fn read(path: &Path) -> Result<Vec<Datagram>, NetError> {
    let bad = |message: String| NetError::Capture {
        path: path.display().to_string(),
        message,
    };
    let mut bytes = Vec::new();
    File::open(path)
        .and_then(|mut f| f.read_to_end(&mut bytes))
        .map_err(NetError::io(format!("read capture {}", path.display())))?;
    if bytes.len() < 24 {
        return Err(bad("shorter than a pcap header".into()));
    }
    let little = match u32::from_le_bytes(bytes[0..4].try_into().expect("4 bytes")) {
        MAGIC => true,
        m if m.swap_bytes() == MAGIC => false,
        m => {
            return Err(bad(format!(
                "not a microsecond pcap file (magic 0x{m:08x})"
            )));
        }
    };
    let u32_at = |b: &[u8], at: usize| {
        let word: [u8; 4] = b[at..at + 4].try_into().expect("4 bytes");
        if little {
            u32::from_le_bytes(word)
        } else {
            u32::from_be_bytes(word)
        }
    };
    let link = u32_at(&bytes, 20);
    if link != LINKTYPE_RAW {
        return Err(bad(format!(
            "link type {link}, expected {LINKTYPE_RAW} (raw IP)"
        )));
    }
    let mut out = Vec::new();
    let mut at = 24;
    while at + 16 <= bytes.len() {
        let (seconds, micros, length) = (
            u32_at(&bytes, at),
            u32_at(&bytes, at + 4),
            u32_at(&bytes, at + 8) as usize,
        );
        let start = at + 16;
        let Some(packet) = bytes.get(start..start + length) else {
            return Err(bad(format!(
                "record at byte {at} runs past the end of the file"
            )));
        };
        at = start + length;
        if packet.len() < IPV4_HEADER + UDP_HEADER || packet[0] >> 4 != 4 || packet[9] != 17 {
            continue;
        }
        let ihl = usize::from(packet[0] & 0x0F) * 4;
        let Some(udp) = packet.get(ihl..) else {
            continue;
        };
        if udp.len() < UDP_HEADER {
            continue;
        }
        let ip = |o: usize| Ipv4Addr::new(packet[o], packet[o + 1], packet[o + 2], packet[o + 3]);
        let port = |o: usize| u16::from_be_bytes([udp[o], udp[o + 1]]);
        out.push(Datagram {
            micros: u64::from(seconds) * 1_000_000 + u64::from(micros),
            source: SocketAddr::from((ip(12), port(0))),
            destination: SocketAddr::from((ip(16), port(2))),
            payload: udp[UDP_HEADER..].to_vec(),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn written_datagrams_read_back_with_valid_ip_checksums() {
        let path = std::env::temp_dir().join(format!("robokey-pcap-{}.pcap", std::process::id()));
        let (a, b): (SocketAddr, SocketAddr) = (
            "127.0.0.1:4000".parse().unwrap(),
            "127.0.0.2:5000".parse().unwrap(),
        );
        let mut writer = PcapWriter::create(&path).unwrap();
        writer.write(a, b, b"hello").unwrap();
        writer.write(b, a, &[1, 2, 3]).unwrap();
        drop(writer);
        let datagrams = read(&path).unwrap();
        assert_eq!(datagrams.len(), 2);
        assert_eq!(
            (
                datagrams[0].source,
                datagrams[0].destination,
                datagrams[0].payload.as_slice()
            ),
            (a, b, &b"hello"[..])
        );
        assert_eq!(datagrams[1].payload, vec![1, 2, 3]);
        let raw = std::fs::read(&path).unwrap();
        assert_eq!(
            checksum(&raw[24 + 16..24 + 16 + 20]),
            0,
            "IPv4 header checksum verifies"
        );
        std::fs::write(&path, b"garbage").unwrap();
        assert!(read(&path).is_err());
        std::fs::remove_file(&path).unwrap();
    }
}
