//! Captures. The relay writes pcap with LINKTYPE_RAW and real IPv4 or IPv6 and UDP headers,
//! so Wireshark and tshark open its captures directly. The eavesdroppers read what
//! tcpdump, dumpcap and Wireshark write too: pcap or pcapng (pcap-parser), with raw IP,
//! Ethernet (VLAN tags included), Linux cooked (SLL, SLL2) or BSD loopback framing, IPv4
//! or IPv6 (etherparse). A capture cut short, e.g. by a recorder that was killed, is read
//! up to its last whole packet, and the reader says so.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::net::{IpAddr, SocketAddr};
use std::path::Path;
use std::time::{SystemTime, UNIX_EPOCH};

use etherparse::{NetSlice, PacketBuilder, SlicedPacket, TransportSlice};
use pcap_parser::data::{PacketData, get_packetdata};
use pcap_parser::pcapng::Block;
use pcap_parser::traits::PcapNGPacketBlock;
use pcap_parser::{Linktype, PcapBlockOwned, PcapError, PcapHeader, ToVec, create_reader};

use crate::error::NetError;

/// The relay's link type: each packet begins with an IPv4 or IPv6 header.
const LINKTYPE: Linktype = Linktype::RAW;
/// Largest packet the relay records (bytes): the largest UDP datagram with its headers.
const SNAPLEN: u32 = 65_535;
/// Time to live written into the relay's IPv4 headers (and IPv6 hop limit).
const HOPS: u8 = 64;

/// One captured UDP datagram.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Datagram {
    /// Sender.
    pub source: SocketAddr,
    /// Receiver.
    pub destination: SocketAddr,
    /// UDP payload: one robokey frame.
    pub payload: Vec<u8>,
}

/// The UDP datagrams of a capture, and what of it could not be used.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Capture {
    /// Every whole UDP datagram, in the order captured.
    pub datagrams: Vec<Datagram>,
    /// What was left out, one sentence each (a cut-off end, packets cut by the snap
    /// length, link types robokey does not read); empty when everything was used.
    pub shortfalls: Vec<String>,
}

/// Writes datagrams to a pcap file, flushing each one (a killed relay leaves a valid file).
#[derive(Debug)]
pub struct PcapWriter {
    out: BufWriter<File>,
}

impl PcapWriter {
    /// Creates the file and writes the pcap header (microseconds, LINKTYPE_RAW).
    ///
    /// # Errors
    /// The file cannot be created.
    pub fn create(path: &Path) -> Result<Self, NetError> {
        let file = File::create(path)
            .map_err(NetError::io(format!("create capture {}", path.display())))?;
        let mut out = BufWriter::new(file);
        let mut header = PcapHeader::new();
        header.snaplen = SNAPLEN;
        header.network = LINKTYPE;
        let bytes = header.to_vec_raw().map_err(|e| NetError::Capture {
            path: path.display().to_string(),
            message: format!("cannot encode the pcap header: {e:?}"),
        })?;
        out.write_all(&bytes)
            .and_then(|()| out.flush())
            .map_err(NetError::io(format!("write {}", path.display())))?;
        Ok(Self { out })
    }

    /// Appends one UDP datagram stamped now, with IP and UDP headers and checksums
    /// (IPv4 when both ends are IPv4, else IPv6 with IPv4 ends mapped).
    ///
    /// # Errors
    /// The file cannot be written, or the payload does not fit one IP packet.
    pub fn write(
        &mut self,
        source: SocketAddr,
        destination: SocketAddr,
        payload: &[u8],
    ) -> Result<(), NetError> {
        let builder = match (source.ip(), destination.ip()) {
            (IpAddr::V4(from), IpAddr::V4(to)) => {
                PacketBuilder::ipv4(from.octets(), to.octets(), HOPS)
            }
            (from, to) => PacketBuilder::ipv6(ipv6_octets(from), ipv6_octets(to), HOPS),
        }
        .udp(source.port(), destination.port());
        let mut packet = Vec::with_capacity(builder.size(payload.len()));
        builder
            .write(&mut packet, payload)
            .map_err(|e| NetError::Capture {
                path: "the relay's capture".into(),
                message: format!("a {}-byte datagram cannot be recorded: {e}", payload.len()),
            })?;
        let now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default();
        let length = packet.len() as u32;
        let record = pcap_parser::LegacyPcapBlock {
            ts_sec: now.as_secs() as u32,
            ts_usec: now.subsec_micros(),
            caplen: length,
            origlen: length,
            data: &packet,
        };
        let bytes = record.to_vec_raw().map_err(|e| NetError::Capture {
            path: "the relay's capture".into(),
            message: format!("cannot encode a pcap record: {e:?}"),
        })?;
        self.out
            .write_all(&bytes)
            .and_then(|()| self.out.flush())
            .map_err(NetError::io("write capture"))
    }
}

fn ipv6_octets(address: IpAddr) -> [u8; 16] {
    match address {
        IpAddr::V4(v4) => v4.to_ipv6_mapped().octets(),
        IpAddr::V6(v6) => v6.octets(),
    }
}

/// What [`read`] has found so far.
#[derive(Default)]
struct Tally {
    datagrams: Vec<Datagram>,
    /// Packets the snap length cut short (caplen < original length).
    cut: usize,
    /// Packets of link types robokey cannot read, by link type.
    unreadable: std::collections::BTreeMap<i32, usize>,
}

impl Tally {
    /// Takes the UDP datagram of one captured packet (its `data` as captured, `original`
    /// bytes long on the wire), if it holds one.
    fn packet(&mut self, link: Linktype, data: &[u8], original: usize) {
        if data.len() < original {
            self.cut += 1;
            return;
        }
        let sliced = match get_packetdata(data, link, data.len()) {
            Some(PacketData::L2(frame)) => SlicedPacket::from_ethernet(frame),
            Some(PacketData::L3(_, packet)) => SlicedPacket::from_ip(packet),
            Some(PacketData::L4(..) | PacketData::Unsupported(_)) => {
                *self.unreadable.entry(link.0).or_default() += 1;
                return;
            }
            None => return,
        };
        let Ok(SlicedPacket {
            net: Some(net),
            transport: Some(TransportSlice::Udp(udp)),
            ..
        }) = sliced
        else {
            return; // not UDP (ARP, TCP, a fragment): not a robokey frame
        };
        let (source, destination): (IpAddr, IpAddr) = match &net {
            NetSlice::Ipv4(ip) => (
                ip.header().source_addr().into(),
                ip.header().destination_addr().into(),
            ),
            NetSlice::Ipv6(ip) => (
                ip.header().source_addr().into(),
                ip.header().destination_addr().into(),
            ),
            NetSlice::Arp(_) => return,
        };
        self.datagrams.push(Datagram {
            source: SocketAddr::new(source, udp.source_port()),
            destination: SocketAddr::new(destination, udp.destination_port()),
            payload: udp.payload().to_vec(),
        });
    }

    fn into_capture(self, cut_off: Option<String>) -> Capture {
        let mut shortfalls: Vec<String> = cut_off.into_iter().collect();
        if self.cut > 0 {
            shortfalls.push(format!(
                "{} packets were cut short by the capture's snap length and are left out \
                 (record with the whole packet: tcpdump -s 0, the default of dumpcap)",
                self.cut
            ));
        }
        for (link, count) in self.unreadable {
            shortfalls.push(format!(
                "{count} packets of link type {link} are left out (readable: raw IP, \
                 Ethernet, Linux cooked, BSD loopback)"
            ));
        }
        Capture {
            datagrams: self.datagrams,
            shortfalls,
        }
    }
}

/// Reads every UDP datagram of a pcap or pcapng file. A file that ends inside a block is
/// read up to its last whole block, and [`Capture::shortfalls`] says where it was cut.
///
/// # Errors
/// The file cannot be read, is not pcap or pcapng, or is malformed before its end.
pub fn read(path: &Path) -> Result<Capture, NetError> {
    let bad = |message: String| NetError::Capture {
        path: path.display().to_string(),
        message,
    };
    let bytes =
        std::fs::read(path).map_err(NetError::io(format!("read capture {}", path.display())))?;
    // The whole file fits the reader's buffer, so an incomplete block is a cut-off end.
    let mut reader = match create_reader(bytes.len().max(64), bytes.as_slice()) {
        Ok(reader) => reader,
        Err(PcapError::Eof | PcapError::Incomplete(_)) => {
            return Err(bad("shorter than a pcap or pcapng header".into()));
        }
        Err(e) => return Err(bad(format!("not a pcap or pcapng file ({e})"))),
    };
    let mut tally = Tally::default();
    let mut legacy_link = None;
    let mut interfaces: Vec<Linktype> = Vec::new();
    let mut at = 0; // bytes consumed
    let cut_off = loop {
        let (length, block) = match reader.next() {
            Ok(next) => next,
            Err(PcapError::Eof) => break None,
            // The reader asks for more (or a larger buffer than the whole file) only when no
            // whole block is left.
            Err(
                PcapError::Incomplete(_) | PcapError::UnexpectedEof | PcapError::BufferTooSmall,
            ) if at == bytes.len() => break None,
            Err(
                PcapError::Incomplete(_) | PcapError::UnexpectedEof | PcapError::BufferTooSmall,
            ) => {
                break Some(format!(
                    "the file ends inside a block at byte {at} of {} (a capture cut short): \
                     its {} datagrams before it are used",
                    bytes.len(),
                    tally.datagrams.len()
                ));
            }
            Err(e) => {
                return Err(bad(format!("malformed at byte {at}: {e}")));
            }
        };
        match block {
            PcapBlockOwned::LegacyHeader(header) => legacy_link = Some(header.network),
            PcapBlockOwned::Legacy(record) => tally.packet(
                legacy_link.unwrap_or(LINKTYPE),
                record.data,
                record.origlen as usize,
            ),
            PcapBlockOwned::NG(Block::SectionHeader(_)) => interfaces.clear(),
            PcapBlockOwned::NG(Block::InterfaceDescription(interface)) => {
                interfaces.push(interface.linktype);
            }
            PcapBlockOwned::NG(Block::EnhancedPacket(packet)) => {
                let Some(&link) = interfaces.get(packet.if_id as usize) else {
                    return Err(bad(format!(
                        "a packet at byte {at} names interface {}, which no interface \
                         description block before it describes",
                        packet.if_id
                    )));
                };
                tally.packet(link, packet.packet_data(), packet.orig_len() as usize);
            }
            PcapBlockOwned::NG(Block::SimplePacket(packet)) => {
                let link = interfaces.first().copied().unwrap_or(LINKTYPE);
                tally.packet(link, packet.packet_data(), packet.orig_len() as usize);
            }
            PcapBlockOwned::NG(_) => {} // statistics, name resolution, comments
        }
        reader.consume(length);
        at += length;
    };
    Ok(tally.into_capture(cut_off))
}

#[cfg(test)]
mod tests;
