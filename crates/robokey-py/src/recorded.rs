//! Reading what the network agents recorded, with robokey-net's own readers: a capture's
//! frames (as `robokey frames` lists them) and a key store's listing (as `robokey keys
//! list --json` gives it) — never key bits.

use std::path::PathBuf;

use pyo3::prelude::*;
use robokey_net::frame_listing::{ListedFrame, list_frames};
use robokey_net::key_listing::ListedKey;
use robokey_net::pairing::read_pairing;
use robokey_net::pcap::read as read_pcap;
use robokey_net::post_store::open_keys;

use crate::errors::net_error;

/// A frame as handed to Python: index, type, session, seq, step, numbers, error.
type FrameRow = (
    usize,
    Option<u8>,
    Option<u32>,
    Option<u32>,
    Option<u32>,
    Vec<f64>,
    Option<String>,
);

/// Every datagram of a pcap or pcapng capture parsed as a robokey frame (MACs unchecked),
/// and what of the capture could not be used (one sentence each, as `robokey frames` warns).
#[pyfunction]
pub fn read_capture(py: Python<'_>, path: PathBuf) -> PyResult<(Vec<FrameRow>, Vec<String>)> {
    let capture = py.detach(|| read_pcap(&path)).map_err(net_error)?;
    let rows = list_frames(&capture.datagrams)
        .into_iter()
        .map(|f: ListedFrame| {
            (
                f.index,
                f.frame_type,
                f.session,
                f.seq,
                f.step,
                f.numbers,
                f.error,
            )
        })
        .collect();
    Ok((rows, capture.shortfalls))
}

/// A key store's listing as `robokey keys list --json` prints it (key files verified under
/// the pairing, never their bits), and the pairing file's warning when `insecure` let a
/// pairing file open to others through.
#[pyfunction]
#[pyo3(signature = (store, pairing, insecure_pairing_file = false))]
pub fn list_keys(
    py: Python<'_>,
    store: PathBuf,
    pairing: PathBuf,
    insecure_pairing_file: bool,
) -> PyResult<(String, Option<String>)> {
    py.detach(|| {
        let (secret, warning) = read_pairing(&pairing, insecure_pairing_file)?;
        let keys = open_keys(&store, &secret)?.list()?;
        let listed: Vec<ListedKey> = keys.iter().map(ListedKey::from).collect();
        Ok((listed, warning))
    })
    .map_err(net_error)
    .and_then(|(listed, warning)| {
        let json = serde_json::to_string_pretty(&listed)
            .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
        Ok((json, warning))
    })
}
