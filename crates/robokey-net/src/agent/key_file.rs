//! The raw session key file (`--key-out`): written when, and only when, the peer confirmed
//! the session, all or nothing, mode 0600, never over an existing file; and read back.

use std::path::{Path, PathBuf};

use robokey::protocol::Outcome;

use super::report::{Ending, SessionReport};
use crate::error::NetError;

/// Records how the session ended in `report` (its outcome; the key's length and the units it
/// kept, `bits_per_unit` bits each) and writes the key to `key_out` when (and only when) the
/// peer confirmed it — in private sensing the raw bits, once the peer confirmed the kept
/// doublets. A key that cannot be written ends the run as failed, with the reason.
pub fn conclude(
    report: &mut SessionReport,
    outcome: &Outcome,
    key: &[u8],
    key_out: Option<&PathBuf>,
    bits_per_unit: usize,
) {
    report.set_outcome(outcome);
    report.key_bits = key.len();
    report.accepted = (key.len() / bits_per_unit.max(1)) as u32;
    let written = match outcome {
        Outcome::Confirmed => Some(vec![
            "raw: not secret against an eavesdropper who learns the model",
            "confirmed by the peer's directional key tag",
        ]),
        Outcome::Kept => Some(vec![
            "raw private-sensing bits of the kept doublets, in order (v, then ω with two bits per \
             doublet): the robot's are the reference, the controller's differ where it erred; \
             not a key until reconciled and amplified over a block (docs/postprocessing.md)",
            "kept positions confirmed by the peer's session tag",
        ]),
        _ => None,
    };
    if let (Some(mut labels), Some(path)) = (written, key_out) {
        if report.is_unauthenticated() {
            labels.push("passive adversary only: the session was not authenticated");
        }
        match write_key_file(path, key, &labels) {
            Ok(()) => report.key_file = Some(path.display().to_string()),
            Err(error) => {
                report.ending = Ending::Failed;
                report.reason = Some(format!("the key was confirmed but not written: {error}"));
            }
        }
    }
}

/// Writes a confirmed key (`bits` of 0/1) as hex of the bit-packed key (bit i of the key =
/// bit i % 8 of byte i / 8), followed by comment lines saying what it is (`labels`): all or
/// nothing, mode 0600, never over an existing file ([`crate::secret_file`]).
///
/// # Errors
/// The file exists or cannot be written.
pub fn write_key_file(path: &Path, bits: &[u8], labels: &[&str]) -> Result<(), NetError> {
    let mut packed = zeroize::Zeroizing::new(vec![0u8; bits.len().div_ceil(8)]);
    for (i, bit) in bits.iter().enumerate() {
        packed[i / 8] |= (bit & 1) << (i % 8);
    }
    // Sized up front: a growing buffer would leave copies of the key in freed memory.
    let labels_len: usize = labels.iter().map(|l| l.len() + 3).sum();
    let mut text = zeroize::Zeroizing::new(String::with_capacity(
        64 + 2 * packed.len() + 1 + labels_len,
    ));
    text.push_str(&format!("robokey-key-v1 bits={}\n", bits.len()));
    for byte in packed.iter() {
        text.push(char::from(b"0123456789abcdef"[usize::from(byte >> 4)]));
        text.push(char::from(b"0123456789abcdef"[usize::from(byte & 15)]));
    }
    text.push('\n');
    for label in labels {
        text.push_str(&format!("# {label}\n"));
    }
    crate::secret_file::write_new(path, text.as_bytes())
}

/// Reads a key file written by [`write_key_file`] back into bits.
///
/// # Errors
/// The file cannot be read or is malformed.
pub fn read_key_file(path: &Path) -> Result<zeroize::Zeroizing<Vec<u8>>, NetError> {
    let bad = |why: &str| {
        NetError::Usage(format!(
            "{}: not a robokey key file ({why})",
            path.display()
        ))
    };
    let text = crate::secret_file::read(path, "key file")?;
    let mut lines = text.lines();
    let bits: usize = lines
        .next()
        .and_then(|l| l.strip_prefix("robokey-key-v1 bits="))
        .and_then(|n| n.parse().ok())
        .ok_or_else(|| bad("header"))?;
    let hex = lines.next().unwrap_or("");
    if hex.len() != bits.div_ceil(8) * 2 || !hex.is_ascii() {
        return Err(bad("length"));
    }
    let mut out = zeroize::Zeroizing::new(Vec::with_capacity(bits));
    for i in 0..bits {
        let byte =
            u8::from_str_radix(&hex[i / 8 * 2..i / 8 * 2 + 2], 16).map_err(|_| bad("hex"))?;
        out.push(byte >> (i % 8) & 1);
    }
    Ok(out)
}
