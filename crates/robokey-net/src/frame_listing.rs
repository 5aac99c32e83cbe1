//! A capture's robokey frames as `robokey frames` lists them (MACs unchecked): one
//! entry per UDP datagram, its header fields and the numbers it carries, or why it does not
//! decode. Nothing here is secret: the frames are what an eavesdropper sees on the network.

use robokey::protocol::wire::decode;
use robokey::protocol::{Message, SessionMessage};
use serde::Serialize;

use crate::pcap::Datagram;

/// One datagram of a capture, parsed as a robokey frame.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ListedFrame {
    /// The datagram's position in the capture (1 for the first).
    pub index: usize,
    /// The frame's type byte (byte 3 of the header); None when it does not decode.
    pub frame_type: Option<u8>,
    /// The session number; None when it does not decode.
    pub session: Option<u32>,
    /// The sequence number; None when it does not decode.
    pub seq: Option<u32>,
    /// The control step k (header bytes 12..16); None when it does not decode.
    pub step: Option<u32>,
    /// The numbers a session frame carries, in wire order: a measurement's y, a command's
    /// u0 then u1, a doublet command's sample, first and second; empty for other frames.
    pub numbers: Vec<f64>,
    /// Why the datagram does not decode as a robokey frame; None when it does.
    pub error: Option<String>,
}

/// Every datagram of a capture as a listed frame, in capture order.
pub fn list_frames(datagrams: &[Datagram]) -> Vec<ListedFrame> {
    datagrams
        .iter()
        .enumerate()
        .map(|(i, datagram)| listed(i + 1, &datagram.payload))
        .collect()
}

/// One datagram's payload as a listed frame.
fn listed(index: usize, bytes: &[u8]) -> ListedFrame {
    let frame = match decode(bytes) {
        Ok(frame) => frame,
        Err(e) => {
            return ListedFrame {
                index,
                frame_type: None,
                session: None,
                seq: None,
                step: None,
                numbers: Vec::new(),
                error: Some(e.to_string()),
            };
        }
    };
    let numbers: Vec<f64> = match &frame.message {
        Message::Session(SessionMessage::Measurement { y, .. }) => y.to_vec(),
        Message::Session(SessionMessage::Command { u0, u1, .. }) => {
            u0.iter().chain(u1).copied().collect()
        }
        Message::Session(SessionMessage::DoubletCommand {
            sample,
            first,
            second,
            ..
        }) => sample
            .iter()
            .chain(first)
            .chain(second.iter().flatten())
            .copied()
            .collect(),
        _ => Vec::new(),
    };
    // A decoded frame has its whole header: the type at byte 3, the step at bytes 12..16.
    ListedFrame {
        index,
        frame_type: Some(bytes[3]),
        session: Some(frame.session),
        seq: Some(frame.seq),
        step: Some(u32::from_be_bytes([
            bytes[12], bytes[13], bytes[14], bytes[15],
        ])),
        numbers,
        error: None,
    }
}
