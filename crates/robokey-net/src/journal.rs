//! An append-only file of authenticated records that survives crashes and refuses what its
//! writer did not write (docs/postprocessing.md, "The store").
//!
//! The file: a line `robokey-journal-v2 OWNER` (the store's role and pairing fingerprint,
//! for a clear refusal of another store's journal), a random 16-byte file id, then records
//! `length u32 | header tag [8] | payload | tag [16]`, big-endian, where under the store's
//! journal key K ([`crate::store_keys`])
//!
//! - header tag = HMAC(K, "header" ‖ file id ‖ length), first 8 bytes: a length can be
//!   trusted before its payload is read;
//! - tag = HMAC(K, "record" ‖ file id ‖ index u64 ‖ length ‖ payload), first 16 bytes: a
//!   record cannot be forged, edited, moved, dropped from the middle or taken from another
//!   file (a rewrite draws a new file id) without the pairing secret.
//!
//! Appends are made durable (`fsync`) before they return. A crash in the middle of one
//! leaves a **torn tail**: bytes after the last intact record that are no complete record
//! and are followed by no intact record header. It is cut, once the first record proved the
//! file is this store's. Anything else that fails — a damaged record with an intact one
//! after it, a first record that does not authenticate, another owner line — is
//! **corruption**: the file is kept as it is and the error names the offset. (A damaged
//! *last* record is indistinguishable from an unfinished append and is cut like one.) The
//! whole file can be rewritten atomically (compaction). The file is opened without following
//! links and refused if another user owns it or others may access it
//! ([`crate::owned_file`]).

use std::collections::HashMap;
use std::fs::{File, OpenOptions};
use std::io::{Read as _, Write as _};
use std::path::{Path, PathBuf};

use zeroize::Zeroizing;

use crate::error::NetError;
use crate::owned_file::{self, ANY_ACCESS_BY_OTHERS};
use crate::secret_file;
use crate::store_keys::StoreMac;

/// Largest record payload (bytes): a pool session of 2²⁰ bits serialised is about 300 kB.
pub const MAX_RECORD_BYTES: usize = 16 << 20;

const VERSION: &str = "robokey-journal-v2";
const FILE_ID: usize = 16;
const HEADER: usize = 4 + 8;
const TAG: usize = 16;

/// An open journal, positioned at its end.
#[derive(Debug)]
pub struct Journal {
    path: PathBuf,
    file: File,
    mac: StoreMac,
    owner: String,
    file_id: [u8; FILE_ID],
    /// The index of the next record.
    next: u64,
}

/// What reading a journal found.
#[derive(Debug)]
pub struct Contents {
    /// The payloads of the intact records, in order (zeroized when dropped: they may hold
    /// raw key bits).
    pub records: Vec<Zeroizing<Vec<u8>>>,
    /// Bytes cut from the end: a torn tail.
    pub torn_bytes: u64,
}

impl Journal {
    /// Opens the journal at `path`, written under `mac` by `owner` (role and pairing
    /// fingerprint), reads its records and cuts a torn tail; `None` if there is none.
    ///
    /// # Errors
    /// The file is a link, not a regular file, another user's or accessible to others; it
    /// belongs to another owner or does not authenticate; a record before the tail is damaged
    /// (the offset named); a read or the cut fails. Nothing is changed on error.
    pub fn open(
        path: &Path,
        mac: &StoreMac,
        owner: &str,
    ) -> Result<Option<(Self, Contents)>, NetError> {
        let mut options = OpenOptions::new();
        options.read(true).append(true);
        let mut file = match owned_file::open(path, &mut options, "journal") {
            Ok(file) => file,
            Err(NetError::Io { error, .. }) if error.kind() == std::io::ErrorKind::NotFound => {
                return Ok(None);
            }
            Err(error) => return Err(error),
        };
        owned_file::check_file(&file, path, "journal", ANY_ACCESS_BY_OTHERS)?;
        let mut bytes = Zeroizing::new(Vec::new());
        file.read_to_end(&mut bytes)
            .map_err(NetError::io(format!("read {}", path.display())))?;
        let corrupt = |offset: usize, message: String| NetError::Store {
            path: path.display().to_string(),
            message: format!("offset {offset}: {message}; the file was left as it is"),
        };
        let first_line = preamble(owner);
        let Some(rest) = bytes.strip_prefix(first_line.as_bytes()) else {
            let found = bytes.split(|&b| b == b'\n').next().unwrap_or_default();
            let found = String::from_utf8_lossy(&found[..found.len().min(80)]).into_owned();
            return Err(match found.strip_prefix(&format!("{VERSION} ")) {
                Some(other) => NetError::Usage(format!(
                    "journal {} belongs to `{other}`, not to `{owner}` (role and pairing \
                     fingerprint): each agent and pairing has its own store",
                    path.display()
                )),
                None => corrupt(
                    0,
                    format!(
                        "not a {VERSION} journal (it begins {found:?}: another program's \
                         file, or an older robokey's unauthenticated journal)"
                    ),
                ),
            });
        };
        let start = first_line.len() + FILE_ID;
        let Some(file_id) = rest.get(..FILE_ID) else {
            return Err(corrupt(first_line.len(), "the file id is cut short".into()));
        };
        let file_id: [u8; FILE_ID] = file_id.try_into().expect("FILE_ID bytes");
        let parsed = parse(&bytes[start..], mac, &file_id)
            .map_err(|(offset, message)| corrupt(start + offset, message))?;
        if parsed.records.is_empty() {
            return Err(corrupt(
                start,
                "the first record does not authenticate under this pairing and role (another \
                 pairing's or role's journal, or damaged)"
                    .into(),
            ));
        }
        let intact = start + parsed.intact;
        let torn_bytes = (bytes.len() - intact) as u64;
        if torn_bytes > 0 {
            file.set_len(intact as u64)
                .and_then(|()| file.sync_all())
                .map_err(NetError::io(format!(
                    "cut the torn tail of {}",
                    path.display()
                )))?;
        }
        let journal = Self {
            path: path.to_owned(),
            file,
            mac: mac.clone(),
            owner: owner.to_owned(),
            file_id,
            next: parsed.records.len() as u64,
        };
        Ok(Some((
            journal,
            Contents {
                records: parsed.records,
                torn_bytes,
            },
        )))
    }

    /// Creates the journal at `path` holding `payloads` (atomically; an existing file of
    /// that name is replaced).
    ///
    /// # Errors
    /// As [`Self::rewrite`].
    pub fn create(
        path: &Path,
        mac: &StoreMac,
        owner: &str,
        payloads: &[Zeroizing<Vec<u8>>],
    ) -> Result<Self, NetError> {
        let (file, file_id) = write_whole(path, mac, owner, payloads)?;
        Ok(Self {
            path: path.to_owned(),
            file,
            mac: mac.clone(),
            owner: owner.to_owned(),
            file_id,
            next: payloads.len() as u64,
        })
    }

    /// Appends one record durably.
    ///
    /// # Errors
    /// The payload exceeds [`MAX_RECORD_BYTES`], or the write or `fsync` fails.
    pub fn append(&mut self, payload: &[u8]) -> Result<(), NetError> {
        let record = frame(&self.mac, &self.file_id, self.next, payload, &self.path)?;
        self.file
            .write_all(&record)
            .and_then(|()| self.file.sync_data())
            .map_err(NetError::io(format!("append to {}", self.path.display())))?;
        self.next += 1;
        Ok(())
    }

    /// Replaces the whole journal by `payloads`, atomically, and goes on appending to it.
    ///
    /// # Errors
    /// A payload exceeds [`MAX_RECORD_BYTES`], or a step of the replacement fails (the old
    /// journal is then intact).
    pub fn rewrite(&mut self, payloads: &[Zeroizing<Vec<u8>>]) -> Result<(), NetError> {
        let (file, file_id) = write_whole(&self.path, &self.mac, &self.owner, payloads)?;
        self.file = file;
        self.file_id = file_id;
        self.next = payloads.len() as u64;
        Ok(())
    }
}

/// The first line of a journal of `owner`.
fn preamble(owner: &str) -> String {
    format!("{VERSION} {owner}\n")
}

/// Writes a whole journal under a fresh file id; returns the new file, open at its end.
fn write_whole(
    path: &Path,
    mac: &StoreMac,
    owner: &str,
    payloads: &[Zeroizing<Vec<u8>>],
) -> Result<(File, [u8; FILE_ID]), NetError> {
    let mut file_id = [0_u8; FILE_ID];
    rand::RngExt::fill(&mut crate::random::os_rng()?, &mut file_id[..]);
    let mut text = Zeroizing::new(preamble(owner).into_bytes());
    text.extend_from_slice(&file_id);
    for (index, payload) in payloads.iter().enumerate() {
        text.extend_from_slice(&frame(mac, &file_id, index as u64, payload, path)?);
    }
    Ok((secret_file::replace(path, &text)?, file_id))
}

/// `length | header tag | payload | tag` of record `index`.
fn frame(
    mac: &StoreMac,
    file_id: &[u8; FILE_ID],
    index: u64,
    payload: &[u8],
    path: &Path,
) -> Result<Zeroizing<Vec<u8>>, NetError> {
    if payload.len() > MAX_RECORD_BYTES {
        return Err(NetError::Store {
            path: path.display().to_string(),
            message: format!(
                "a record of {} bytes exceeds the {MAX_RECORD_BYTES}-byte bound",
                payload.len()
            ),
        });
    }
    let length = (payload.len() as u32).to_be_bytes();
    let mut record = Zeroizing::new(Vec::with_capacity(HEADER + payload.len() + TAG));
    record.extend_from_slice(&length);
    record.extend_from_slice(&header_tag(mac, file_id, length));
    record.extend_from_slice(payload);
    record.extend_from_slice(&record_tag(mac, file_id, index, length, payload)[..TAG]);
    Ok(record)
}

fn header_tag(mac: &StoreMac, file_id: &[u8; FILE_ID], length: [u8; 4]) -> [u8; 8] {
    let tag = mac.tag(&[b"header", file_id, &length]);
    tag[..8].try_into().expect("8 bytes")
}

fn record_tag(
    mac: &StoreMac,
    file_id: &[u8; FILE_ID],
    index: u64,
    length: [u8; 4],
    payload: &[u8],
) -> [u8; 32] {
    mac.tag(&[b"record", file_id, &index.to_be_bytes(), &length, payload])
}

/// The intact records of a journal's record area and the bytes they span.
struct Parsed {
    records: Vec<Zeroizing<Vec<u8>>>,
    intact: usize,
}

/// Reads records until the first that fails; what follows it must be a torn tail (no
/// intact record header after it), or it is corruption: `(offset, what)`.
fn parse(bytes: &[u8], mac: &StoreMac, file_id: &[u8; FILE_ID]) -> Result<Parsed, (usize, String)> {
    let mut records = Vec::new();
    let mut at = 0;
    let failure = loop {
        let Some(header) = bytes.get(at..at + HEADER) else {
            break None;
        };
        let length: [u8; 4] = header[..4].try_into().expect("4 bytes");
        if header[4..] != header_tag(mac, file_id, length) {
            break Some("its header does not authenticate");
        }
        let size = u32::from_be_bytes(length) as usize;
        if size > MAX_RECORD_BYTES {
            break Some("its length exceeds the record bound");
        }
        let Some(body) = bytes.get(at + HEADER..at + HEADER + size + TAG) else {
            break None;
        };
        let (payload, tag) = body.split_at(size);
        let expected = record_tag(mac, file_id, records.len() as u64, length, payload);
        if !bool::from(subtle::ConstantTimeEq::ct_eq(tag, &expected[..TAG])) {
            break Some("it does not authenticate (damaged, forged, moved or from another file)");
        }
        records.push(Zeroizing::new(payload.to_vec()));
        at += HEADER + size + TAG;
    };
    match failure {
        Some(what) if intact_header_after(bytes, at, mac, file_id) => Err((
            at,
            format!(
                "record {} is damaged — {what} — and intact records follow it",
                records.len()
            ),
        )),
        _ => Ok(Parsed {
            records,
            intact: at,
        }),
    }
}

/// Whether an intact record header (one whose header tag verifies and whose record fits in
/// the file) begins anywhere after `failed`: then the failure is not a torn tail.
fn intact_header_after(
    bytes: &[u8],
    failed: usize,
    mac: &StoreMac,
    file_id: &[u8; FILE_ID],
) -> bool {
    let mut tags: HashMap<[u8; 4], [u8; 8]> = HashMap::new();
    (failed + 1..bytes.len().saturating_sub(HEADER + TAG)).any(|at| {
        let length: [u8; 4] = bytes[at..at + 4].try_into().expect("4 bytes");
        let size = u32::from_be_bytes(length) as usize;
        // Most offsets fail here, before any MAC: the length must fit in the file.
        if at + HEADER + size + TAG > bytes.len() || bytes[at + 4..at + HEADER] == [0; 8] {
            return false;
        }
        let expected = *tags
            .entry(length)
            .or_insert_with(|| header_tag(mac, file_id, length));
        bytes[at + 4..at + HEADER] == expected
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use robokey::protocol::auth::PairingSecret;

    pub(crate) fn mac(seed: u8) -> StoreMac {
        StoreMac::derive(&PairingSecret::from_bytes(&[seed; 32]), "journal", "robot")
    }

    fn payloads(contents: &Contents) -> Vec<Vec<u8>> {
        contents.records.iter().map(|r| r.to_vec()).collect()
    }

    fn create(path: &Path, written: &[Vec<u8>]) -> Journal {
        let records: Vec<_> = written.iter().map(|p| Zeroizing::new(p.clone())).collect();
        Journal::create(path, &mac(1), "robot f", &records).unwrap()
    }

    fn open(path: &Path) -> Result<(Journal, Contents), NetError> {
        Journal::open(path, &mac(1), "robot f").map(|j| j.expect("a journal"))
    }

    #[test]
    fn records_survive_reopening_and_a_torn_tail_is_cut_at_every_byte() {
        let dir = tempdir("journal");
        let path = dir.join("journal");
        assert!(Journal::open(&path, &mac(1), "robot f").unwrap().is_none());
        let written: Vec<Vec<u8>> =
            vec![b"one".to_vec(), vec![7; 1000], b"x".to_vec(), b"4".to_vec()];
        let mut journal = create(&path, &written[..1]);
        for payload in &written[1..] {
            journal.append(payload).unwrap();
        }
        drop(journal);
        let whole = std::fs::read(&path).unwrap();
        let (_, contents) = open(&path).unwrap();
        assert_eq!(payloads(&contents), written);
        assert_eq!(contents.torn_bytes, 0);
        // A crash during the last append, at every byte, with the unwritten rest missing or
        // zero-filled: the earlier records are intact.
        let last = whole.len() - (HEADER + 1 + TAG);
        for cut in last..whole.len() {
            for zero_filled in [false, true] {
                let mut torn = whole[..cut].to_vec();
                if zero_filled {
                    torn.resize(whole.len(), 0);
                    // The file id is random, so the tag's missing bytes are zero one time in
                    // 256 per byte: then zero-filling rebuilds the intact record, no tear.
                    if torn == whole {
                        continue;
                    }
                }
                std::fs::write(&path, &torn).unwrap();
                let (mut journal, contents) = open(&path).unwrap();
                assert_eq!(payloads(&contents), written[..3], "cut at {cut}");
                assert_eq!(contents.torn_bytes, (torn.len() - last) as u64);
                assert_eq!(std::fs::metadata(&path).unwrap().len(), last as u64);
                // Appending goes on after the cut.
                journal.append(b"again").unwrap();
                drop(journal);
                let (_, contents) = open(&path).unwrap();
                assert_eq!(contents.records.last().unwrap().as_slice(), b"again");
            }
        }
    }

    /// A flipped bit in any record but the last is corruption: the file is kept byte for
    /// byte and the error names the offset. In the last, it is a torn append, cut.
    #[test]
    fn a_flipped_bit_before_the_tail_fails_closed_naming_the_offset() {
        let dir = tempdir("journal-flip");
        let path = dir.join("journal");
        let written: Vec<Vec<u8>> = vec![b"first".to_vec(), vec![3; 300], b"third".to_vec()];
        drop(create(&path, &written));
        let whole = std::fs::read(&path).unwrap();
        let start = preamble("robot f").len() + FILE_ID;
        let second = start + HEADER + 5 + TAG;
        let third = second + HEADER + 300 + TAG;
        for at in start..whole.len() {
            let mut bytes = whole.clone();
            bytes[at] ^= 0x10;
            std::fs::write(&path, &bytes).unwrap();
            let opened = open(&path);
            if at >= third {
                let (_, contents) = opened.unwrap();
                assert_eq!(payloads(&contents), written[..2], "flip at {at}");
            } else {
                let error = opened.unwrap_err().to_string();
                let offset = if at < second { start } else { second };
                assert!(
                    error.contains(&format!("offset {offset}:")),
                    "flip at {at}: {error}"
                );
                assert_eq!(
                    std::fs::read(&path).unwrap(),
                    bytes,
                    "flip at {at}: changed"
                );
            }
        }
    }

    #[test]
    fn another_key_owner_or_format_is_refused_and_left_untouched() {
        let dir = tempdir("journal-other");
        let path = dir.join("journal");
        drop(create(&path, &[b"header".to_vec()]));
        let mut bytes = std::fs::read(&path).unwrap();
        bytes.extend_from_slice(b"torn");
        std::fs::write(&path, &bytes).unwrap();
        let error = Journal::open(&path, &mac(2), "robot f")
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("does not authenticate under this pairing"),
            "{error}"
        );
        let error = Journal::open(&path, &mac(1), "controller g")
            .unwrap_err()
            .to_string();
        assert!(error.contains("belongs to `robot f`"), "{error}");
        std::fs::write(&path, b"\0\0\0\x05old checksummed journal").unwrap();
        let error = open(&path).unwrap_err().to_string();
        assert!(
            error.contains("offset 0: not a robokey-journal-v2"),
            "{error}"
        );
        assert_eq!(
            std::fs::read(&path).unwrap(),
            b"\0\0\0\x05old checksummed journal"
        );
        std::fs::write(&path, &bytes).unwrap();
        let (_, contents) = open(&path).unwrap();
        assert_eq!(contents.torn_bytes, 4);
    }

    /// A link planted at the journal's name is refused; its target keeps every byte.
    #[test]
    fn a_link_at_the_journal_is_refused_and_its_target_kept() {
        let dir = tempdir("journal-link");
        let path = dir.join("journal");
        let victim = dir.join("victim");
        std::fs::write(&victim, b"precious").unwrap();
        std::os::unix::fs::symlink(&victim, &path).unwrap();
        let error = open(&path).unwrap_err().to_string();
        assert!(error.contains("symbolic link"), "{error}");
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
    }

    #[test]
    fn a_rewrite_replaces_the_records_under_a_new_file_id() {
        let dir = tempdir("journal-rewrite");
        let path = dir.join("journal");
        let mut journal = create(&path, &[b"a".to_vec(), b"b".to_vec()]);
        let old = std::fs::read(&path).unwrap();
        journal
            .rewrite(&[Zeroizing::new(b"only".to_vec())])
            .unwrap();
        journal.append(b"then").unwrap();
        drop(journal);
        let (_, contents) = open(&path).unwrap();
        assert_eq!(
            payloads(&contents),
            vec![b"only".to_vec(), b"then".to_vec()]
        );
        // Records of the old file spliced onto the new one do not authenticate there: a
        // tail of foreign bytes, cut and never adopted.
        let mut spliced = std::fs::read(&path).unwrap();
        let start = preamble("robot f").len() + FILE_ID;
        spliced.extend_from_slice(&old[start..]);
        std::fs::write(&path, &spliced).unwrap();
        let (_, contents) = open(&path).unwrap();
        assert_eq!(
            payloads(&contents),
            vec![b"only".to_vec(), b"then".to_vec()]
        );
        assert_eq!(contents.torn_bytes, (old.len() - start) as u64);
        use std::os::unix::fs::PermissionsExt as _;
        let mode = std::fs::metadata(&path).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o600);
    }

    /// A fresh folder under the target's temporary directory, mode 0700.
    pub(crate) fn tempdir(name: &str) -> PathBuf {
        use std::os::unix::fs::PermissionsExt as _;
        let dir = std::env::temp_dir().join(format!("robokey-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700)).unwrap();
        dir
    }
}
