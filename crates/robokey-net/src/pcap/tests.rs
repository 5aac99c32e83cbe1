use std::borrow::Cow;

use pcap_parser::pcapng::{EnhancedPacketBlock, InterfaceDescriptionBlock, SectionHeaderBlock};

use super::*;

/// A file name of its own for each call (the tests run in parallel).
fn temp(name: &str) -> std::path::PathBuf {
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    std::env::temp_dir().join(format!("robokey-pcap-{}-{call}-{name}", std::process::id()))
}

fn address(text: &str) -> SocketAddr {
    text.parse().unwrap()
}

/// Three datagrams of two peers, one of them over IPv6.
fn datagrams() -> Vec<Datagram> {
    let datagram = |source: &str, destination: &str, payload: &[u8]| Datagram {
        source: address(source),
        destination: address(destination),
        payload: payload.to_vec(),
    };
    vec![
        datagram("127.0.0.1:4000", "127.0.0.2:5000", b"hello"),
        datagram("127.0.0.2:5000", "127.0.0.1:4000", &[1, 2, 3]),
        datagram("[::1]:4000", "[::1]:5000", &[0; 1400]),
    ]
}

/// The relay's capture of [`datagrams`]: its bytes.
fn relay_capture() -> Vec<u8> {
    let path = temp("relay.pcap");
    let mut writer = PcapWriter::create(&path).unwrap();
    for d in datagrams() {
        writer.write(d.source, d.destination, &d.payload).unwrap();
    }
    drop(writer);
    let bytes = std::fs::read(&path).unwrap();
    std::fs::remove_file(&path).unwrap();
    bytes
}

/// The IP packets of a relay capture (LINKTYPE_RAW records after the 24-byte header).
fn packets(capture: &[u8]) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    let mut at = 24;
    while at < capture.len() {
        let length = u32::from_le_bytes(capture[at + 8..at + 12].try_into().unwrap()) as usize;
        out.push(capture[at + 16..at + 16 + length].to_vec());
        at += 16 + length;
    }
    out
}

fn read_bytes(name: &str, bytes: &[u8]) -> Result<Capture, NetError> {
    let path = temp(name);
    std::fs::write(&path, bytes).unwrap();
    let capture = read(&path);
    std::fs::remove_file(&path).unwrap();
    capture
}

/// A pcap file of `link` whose records are `packets` with `frame` around each.
fn legacy(link: Linktype, packets: &[Vec<u8>], frame: impl Fn(&[u8]) -> Vec<u8>) -> Vec<u8> {
    let mut header = PcapHeader::new();
    header.snaplen = SNAPLEN;
    header.network = link;
    let mut bytes = header.to_vec_raw().unwrap();
    for packet in packets {
        let data = frame(packet);
        let length = data.len() as u32;
        let record = pcap_parser::LegacyPcapBlock {
            ts_sec: 1,
            ts_usec: 2,
            caplen: length,
            origlen: length,
            data: &data,
        };
        bytes.extend(record.to_vec_raw().unwrap());
    }
    bytes
}

/// Ethernet II around an IP packet, with an 802.1Q VLAN tag.
fn ethernet(packet: &[u8]) -> Vec<u8> {
    let ethertype: u16 = if packet[0] >> 4 == 4 { 0x0800 } else { 0x86DD };
    let mut frame = vec![0x02, 0, 0, 0, 0, 1, 0x02, 0, 0, 0, 0, 2];
    frame.extend([0x81, 0x00, 0x00, 0x07]); // VLAN 7
    frame.extend(ethertype.to_be_bytes());
    frame.extend_from_slice(packet);
    frame
}

/// A Linux cooked (SLL) header around an IP packet.
fn cooked(packet: &[u8]) -> Vec<u8> {
    let protocol: u16 = if packet[0] >> 4 == 4 { 0x0800 } else { 0x86DD };
    let mut frame = vec![0, 0, 0, 1, 0, 6, 0, 0, 0, 0, 0, 0, 0, 0];
    frame.extend(protocol.to_be_bytes());
    frame.extend_from_slice(packet);
    frame
}

/// BSD loopback (LINKTYPE_NULL): the address family in host order, then the packet.
fn loopback(packet: &[u8]) -> Vec<u8> {
    let family: u32 = if packet[0] >> 4 == 4 { 2 } else { 30 };
    let mut frame = family.to_le_bytes().to_vec();
    frame.extend_from_slice(packet);
    frame
}

/// A pcapng file: two interfaces (raw IP, then Ethernet), each packet on the one `on_ethernet`
/// picks, with a comment option.
fn pcapng(packets: &[Vec<u8>], on_ethernet: impl Fn(usize) -> bool) -> Vec<u8> {
    let mut section = SectionHeaderBlock {
        block_type: 0,
        block_len1: 0,
        bom: 0,
        major_version: 0,
        minor_version: 0,
        section_len: -1,
        options: Vec::new(),
        block_len2: 0,
    };
    let mut bytes = section.to_vec().unwrap();
    for link in [Linktype::RAW, Linktype::ETHERNET] {
        let mut interface = InterfaceDescriptionBlock {
            block_type: 0,
            block_len1: 0,
            linktype: link,
            reserved: 0,
            snaplen: 262_144,
            options: Vec::new(),
            block_len2: 0,
            if_tsresol: 6,
            if_tsoffset: 0,
        };
        bytes.extend(interface.to_vec().unwrap());
    }
    for (i, packet) in packets.iter().enumerate() {
        let data = if on_ethernet(i) {
            ethernet(packet)
        } else {
            packet.clone()
        };
        let mut block = EnhancedPacketBlock {
            block_type: 0,
            block_len1: 0,
            if_id: u32::from(on_ethernet(i)),
            ts_high: 0,
            ts_low: i as u32,
            caplen: data.len() as u32,
            origlen: data.len() as u32,
            data: &data,
            options: vec![pcap_parser::PcapNGOption {
                code: pcap_parser::OptionCode::Comment,
                len: 3,
                value: Cow::Borrowed(b"hi\0\0"),
            }],
            block_len2: 0,
        };
        bytes.extend(block.to_vec().unwrap());
    }
    bytes
}

#[test]
fn written_datagrams_read_back_with_valid_ip_and_udp_checksums() {
    let bytes = relay_capture();
    let capture = read_bytes("written.pcap", &bytes).unwrap();
    assert_eq!(capture.datagrams, datagrams());
    assert!(capture.shortfalls.is_empty(), "{:?}", capture.shortfalls);
    for packet in packets(&bytes) {
        let sliced = SlicedPacket::from_ip(&packet).unwrap();
        let Some(TransportSlice::Udp(udp)) = &sliced.transport else {
            panic!("not UDP");
        };
        let checksum = match &sliced.net {
            Some(NetSlice::Ipv4(ip)) => {
                let header = ip.header().to_header();
                assert_eq!(header.header_checksum, header.calc_header_checksum());
                udp.to_header()
                    .calc_checksum_ipv4(&header, udp.payload())
                    .unwrap()
            }
            Some(NetSlice::Ipv6(ip)) => udp
                .to_header()
                .calc_checksum_ipv6(&ip.header().to_header(), udp.payload())
                .unwrap(),
            _ => panic!("not IP"),
        };
        assert_eq!(udp.checksum(), checksum, "UDP checksum verifies");
    }
}

#[test]
fn every_framing_tcpdump_and_wireshark_write_gives_the_same_datagrams() {
    let packets = packets(&relay_capture());
    let framings: Vec<(&str, Vec<u8>)> = vec![
        ("raw", legacy(Linktype::RAW, &packets, <[u8]>::to_vec)),
        ("ethernet", legacy(Linktype::ETHERNET, &packets, ethernet)),
        ("cooked", legacy(Linktype::LINUX_SLL, &packets, cooked)),
        ("loopback", legacy(Linktype::NULL, &packets, loopback)),
        ("pcapng", pcapng(&packets, |i| i % 2 == 1)),
    ];
    for (name, bytes) in framings {
        let capture = read_bytes(name, &bytes).unwrap();
        assert_eq!(capture.datagrams, datagrams(), "{name}");
        assert!(
            capture.shortfalls.is_empty(),
            "{name}: {:?}",
            capture.shortfalls
        );
    }
}

#[test]
fn a_capture_cut_anywhere_gives_its_whole_packets_and_says_where_it_ends() {
    let packets = packets(&relay_capture());
    for (name, bytes) in [
        ("pcap", legacy(Linktype::ETHERNET, &packets, ethernet)),
        ("pcapng", pcapng(&packets, |_| true)),
    ] {
        let whole = read_bytes(name, &bytes).unwrap();
        // Where each block ends: the file is whole up to there. Before the first packet: the
        // pcap header, or the section and its two interfaces.
        let length_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
        let mut at = if name == "pcap" { 24 } else { 0 };
        let mut ends = Vec::new();
        while at < bytes.len() {
            at += if name == "pcap" {
                16 + length_at(at + 8) as usize
            } else {
                length_at(at + 4) as usize
            };
            ends.push(at);
        }
        let first_packet = if name == "pcap" { 24 } else { ends[2] };
        ends.retain(|&end| end > first_packet);
        ends.insert(0, first_packet);
        assert_eq!(
            ends.len(),
            packets.len() + 1,
            "{name}: the blocks were walked"
        );
        for cut in first_packet..bytes.len() {
            let capture = read_bytes(name, &bytes[..cut]).unwrap();
            let whole_packets = ends.iter().filter(|&&end| end <= cut).count() - 1;
            assert_eq!(
                capture.datagrams,
                whole.datagrams[..whole_packets],
                "{name} cut at {cut}"
            );
            if ends.contains(&cut) {
                assert!(capture.shortfalls.is_empty(), "{name} cut at {cut}");
            } else {
                assert_eq!(capture.shortfalls.len(), 1, "{name} cut at {cut}");
                assert!(
                    capture.shortfalls[0].starts_with(&format!(
                        "the file ends inside a block at byte {} of {cut}",
                        ends[whole_packets]
                    )),
                    "{name} cut at {cut}: {}",
                    capture.shortfalls[0]
                );
            }
        }
        assert!(read_bytes(name, &bytes[..10]).is_err(), "{name}: no header");
    }
}

#[test]
fn packets_cut_by_the_snap_length_are_counted_and_left_out() {
    let packets = packets(&relay_capture());
    let mut bytes = legacy(Linktype::RAW, &packets[..1], <[u8]>::to_vec);
    let cut = &packets[1][..20];
    bytes.extend(
        pcap_parser::LegacyPcapBlock {
            ts_sec: 1,
            ts_usec: 2,
            caplen: cut.len() as u32,
            origlen: packets[1].len() as u32,
            data: cut,
        }
        .to_vec_raw()
        .unwrap(),
    );
    let capture = read_bytes("snapped", &bytes).unwrap();
    assert_eq!(capture.datagrams, datagrams()[..1]);
    assert_eq!(capture.shortfalls.len(), 1);
    assert!(
        capture.shortfalls[0].starts_with("1 packets were cut short by the capture's snap length"),
        "{:?}",
        capture.shortfalls
    );
}

#[test]
fn what_is_not_a_capture_is_an_error_naming_the_file() {
    let error = read_bytes("garbage", b"garbage, and more than a header's worth of it")
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("garbage") && error.contains("not a pcap or pcapng file"),
        "{error}"
    );
    let error = read_bytes("empty", b"").unwrap_err().to_string();
    assert!(
        error.contains("shorter than a pcap or pcapng header"),
        "{error}"
    );
}
