//! Captures written by the tools people record with read as the relay's own. The files in
//! `tests/captures/` hold one short paired lockstep session (`--set trajectory.laps=1 --set
//! trajectory.side_time=2`, 40 steps) through a clean relay, recorded at once, inside a
//! network namespace, by:
//!
//! - `relay-after-faults.pcap`: `robokey relay --capture … --capture-after-faults`
//!   (LINKTYPE_RAW);
//! - `dumpcap-lo.pcapng`: `dumpcap -i lo -f "udp port 47000"` (Wireshark 4.0: pcapng,
//!   Ethernet);
//! - `tcpdump-lo.pcap`: `tcpdump -i lo -w … "udp port 47000"` (tcpdump 4.99: pcap,
//!   Ethernet);
//! - `tcpdump-any.pcap`: `tcpdump -i any -w … "udp port 47000"` (pcap, Linux cooked v2),
//!
//! where 47000 is the robot agent's port, so every tool saw the datagrams the relay
//! delivered and the robot's replies.

use std::path::{Path, PathBuf};

use robokey_net::pcap::{Capture, read};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/captures")
        .join(name)
}

fn capture(name: &str) -> Capture {
    read(&fixture(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

#[test]
fn dumpcap_and_tcpdump_captures_hold_the_datagrams_of_the_relays() {
    let relay = capture("relay-after-faults.pcap");
    assert_eq!(relay.datagrams.len(), 91);
    assert!(relay.shortfalls.is_empty(), "{:?}", relay.shortfalls);
    for name in ["dumpcap-lo.pcapng", "tcpdump-lo.pcap", "tcpdump-any.pcap"] {
        let other = capture(name);
        assert!(
            other.shortfalls.is_empty(),
            "{name}: {:?}",
            other.shortfalls
        );
        // The same payloads in the same order, to and from the robot; the relay records the
        // controller's address as the other end, the tools the relay's.
        let robot_side = |capture: &Capture| -> Vec<(String, Vec<u8>)> {
            let robot = "127.0.0.1:47000".parse().unwrap();
            capture
                .datagrams
                .iter()
                .map(|d| {
                    let direction = if d.destination == robot { "to" } else { "from" };
                    assert!(d.source == robot || d.destination == robot, "{d:?}");
                    (direction.to_owned(), d.payload.clone())
                })
                .collect()
        };
        assert_eq!(robot_side(&other), robot_side(&relay), "{name}");
    }
}

#[test]
fn a_dumpcap_capture_cut_short_gives_the_datagrams_before_the_cut() {
    let whole = std::fs::read(fixture("dumpcap-lo.pcapng")).unwrap();
    let all = capture("dumpcap-lo.pcapng").datagrams;
    let path = std::env::temp_dir().join(format!("robokey-cut-{}.pcapng", std::process::id()));
    std::fs::write(&path, &whole[..whole.len() * 2 / 3]).unwrap();
    let cut = read(&path).unwrap();
    std::fs::remove_file(&path).unwrap();
    assert!(cut.datagrams.len() > 50, "{}", cut.datagrams.len());
    assert_eq!(cut.datagrams, all[..cut.datagrams.len()]);
    assert_eq!(cut.shortfalls.len(), 1);
    assert!(
        cut.shortfalls[0].contains("the file ends inside a block")
            && cut.shortfalls[0].contains(&format!("its {} datagrams", cut.datagrams.len())),
        "{}",
        cut.shortfalls[0]
    );
}
