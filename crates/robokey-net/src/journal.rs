//! An append-only file of checksummed records that survives crashes: each record is
//! `length u32 | checksum [8] | payload`, big-endian, the checksum the first 8 bytes of
//! SHA-256(payload). Appends are made durable (`fsync`) before they return. A crash in the
//! middle of an append leaves a torn tail: reading stops at the first record that is
//! incomplete or fails its checksum, and the file is cut back to the records before it.
//! The whole file can be rewritten atomically (compaction) to drop what is no longer needed.

use std::fs::{File, OpenOptions};
use std::io::{Read as _, Write as _};
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};
use zeroize::Zeroizing;

use crate::error::NetError;
use crate::secret_file;

/// Largest record payload (bytes): a pool session of 2²⁰ bits serialised is about 300 kB.
pub const MAX_RECORD_BYTES: usize = 16 << 20;

const HEADER: usize = 4 + 8;

/// An open journal, positioned at its end.
#[derive(Debug)]
pub struct Journal {
    path: PathBuf,
    file: File,
}

/// What reading a journal found.
#[derive(Debug)]
pub struct Contents {
    /// The payloads of the intact records, in order (zeroized when dropped: they may hold
    /// raw key bits).
    pub records: Vec<Zeroizing<Vec<u8>>>,
    /// Bytes cut from the end: a torn or corrupt tail.
    pub torn_bytes: u64,
}

impl Journal {
    /// Opens (creating, mode 0600) the journal at `path`, reads its intact records and cuts a
    /// torn tail.
    ///
    /// # Errors
    /// The file cannot be opened, read or cut.
    pub fn open(path: &Path) -> Result<(Self, Contents), NetError> {
        let mut options = OpenOptions::new();
        options.read(true).append(true).create(true);
        #[cfg(unix)]
        std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
        let mut file = options
            .open(path)
            .map_err(NetError::io(format!("open {}", path.display())))?;
        let mut bytes = Zeroizing::new(Vec::new());
        file.read_to_end(&mut bytes)
            .map_err(NetError::io(format!("read {}", path.display())))?;
        let (records, intact) = parse(&bytes);
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
        };
        Ok((
            journal,
            Contents {
                records,
                torn_bytes,
            },
        ))
    }

    /// Appends one record durably.
    ///
    /// # Errors
    /// The payload exceeds [`MAX_RECORD_BYTES`], or the write or `fsync` fails.
    pub fn append(&mut self, payload: &[u8]) -> Result<(), NetError> {
        let record = frame(payload, &self.path)?;
        self.file
            .write_all(&record)
            .and_then(|()| self.file.sync_data())
            .map_err(NetError::io(format!("append to {}", self.path.display())))
    }

    /// Replaces the whole journal by `payloads`, atomically, and goes on appending to it.
    ///
    /// # Errors
    /// A payload exceeds [`MAX_RECORD_BYTES`], or a step of the replacement fails (the old
    /// journal is then intact).
    pub fn rewrite(&mut self, payloads: &[Zeroizing<Vec<u8>>]) -> Result<(), NetError> {
        let mut text = Zeroizing::new(Vec::new());
        for payload in payloads {
            text.extend_from_slice(&frame(payload, &self.path)?);
        }
        secret_file::replace(&self.path, &text)?;
        self.file = OpenOptions::new()
            .append(true)
            .open(&self.path)
            .map_err(NetError::io(format!("open {}", self.path.display())))?;
        Ok(())
    }
}

/// `length | checksum | payload`.
fn frame(payload: &[u8], path: &Path) -> Result<Zeroizing<Vec<u8>>, NetError> {
    if payload.len() > MAX_RECORD_BYTES {
        return Err(NetError::Store {
            path: path.display().to_string(),
            message: format!(
                "a record of {} bytes exceeds the {MAX_RECORD_BYTES}-byte bound",
                payload.len()
            ),
        });
    }
    let mut record = Zeroizing::new(Vec::with_capacity(HEADER + payload.len()));
    record.extend_from_slice(&(payload.len() as u32).to_be_bytes());
    record.extend_from_slice(&checksum(payload));
    record.extend_from_slice(payload);
    Ok(record)
}

fn checksum(payload: &[u8]) -> [u8; 8] {
    let digest = Sha256::digest(payload);
    let mut sum = [0; 8];
    sum.copy_from_slice(&digest[..8]);
    sum
}

/// The intact records of `bytes` and the length they span.
fn parse(bytes: &[u8]) -> (Vec<Zeroizing<Vec<u8>>>, usize) {
    let mut records = Vec::new();
    let mut at = 0;
    while let Some(header) = bytes.get(at..at + HEADER) {
        let length = u32::from_be_bytes([header[0], header[1], header[2], header[3]]) as usize;
        if length > MAX_RECORD_BYTES {
            break;
        }
        let Some(payload) = bytes.get(at + HEADER..at + HEADER + length) else {
            break;
        };
        if checksum(payload)[..] != header[4..] {
            break;
        }
        records.push(Zeroizing::new(payload.to_vec()));
        at += HEADER + length;
    }
    (records, at)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    fn payloads(contents: &Contents) -> Vec<Vec<u8>> {
        contents.records.iter().map(|r| r.to_vec()).collect()
    }

    #[test]
    fn records_survive_reopening_and_a_torn_tail_is_cut_at_every_byte() {
        let dir = tempdir("journal");
        let path = dir.join("journal");
        let written: Vec<Vec<u8>> = vec![b"one".to_vec(), vec![7; 1000], Vec::new(), b"4".to_vec()];
        let (mut journal, contents) = Journal::open(&path).unwrap();
        assert!(contents.records.is_empty());
        for payload in &written {
            journal.append(payload).unwrap();
        }
        drop(journal);
        let whole = std::fs::read(&path).unwrap();
        let (_, contents) = Journal::open(&path).unwrap();
        assert_eq!(payloads(&contents), written);
        assert_eq!(contents.torn_bytes, 0);
        // A crash during the last append, at every byte: the earlier records are intact.
        let last = whole.len() - (HEADER + 1);
        for cut in last..whole.len() {
            std::fs::write(&path, &whole[..cut]).unwrap();
            let (mut journal, contents) = Journal::open(&path).unwrap();
            assert_eq!(payloads(&contents), written[..3], "cut at {cut}");
            assert_eq!(contents.torn_bytes, (cut - last) as u64);
            assert_eq!(std::fs::metadata(&path).unwrap().len(), last as u64);
            // Appending goes on after the cut.
            journal.append(b"again").unwrap();
            drop(journal);
            let (_, contents) = Journal::open(&path).unwrap();
            assert_eq!(contents.records.last().unwrap().as_slice(), b"again");
        }
    }

    #[test]
    fn a_flipped_byte_ends_the_intact_records_and_a_rewrite_replaces_them() {
        let dir = tempdir("journal-flip");
        let path = dir.join("journal");
        let (mut journal, _) = Journal::open(&path).unwrap();
        journal.append(b"first").unwrap();
        journal.append(b"second").unwrap();
        drop(journal);
        let mut bytes = std::fs::read(&path).unwrap();
        let n = bytes.len();
        bytes[n - 1] ^= 1;
        std::fs::write(&path, &bytes).unwrap();
        let (mut journal, contents) = Journal::open(&path).unwrap();
        assert_eq!(payloads(&contents), vec![b"first".to_vec()]);
        assert_eq!(contents.torn_bytes, (HEADER + 6) as u64);
        journal
            .rewrite(&[Zeroizing::new(b"only".to_vec())])
            .unwrap();
        journal.append(b"then").unwrap();
        drop(journal);
        let (_, contents) = Journal::open(&path).unwrap();
        assert_eq!(
            payloads(&contents),
            vec![b"only".to_vec(), b"then".to_vec()]
        );
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt as _;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode();
            assert_eq!(mode & 0o777, 0o600);
        }
    }

    /// A fresh folder under the target's temporary directory.
    pub(crate) fn tempdir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("robokey-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }
}
