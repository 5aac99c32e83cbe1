//! The final keys of a store (`DIR/keys/`): one file per key, `ID.key`, JSON, mode 0600,
//! written all or nothing (docs/postprocessing.md, "Key store"). Both agents name a key by
//! the same ID, so an application finds the same key on the robot and on the controller.

use std::path::{Path, PathBuf};

use robokey_secrecy::postprocess::FinalKey;
use serde::{Deserialize, Serialize};
use zeroize::Zeroize;

use crate::error::NetError;
use crate::secret_file;

/// One final key as stored. Its `Debug` omits the bits.
#[derive(Clone, PartialEq, Serialize, Deserialize)]
pub struct StoredKey {
    /// The ID both sides share (16 hex digits).
    pub id: String,
    /// `robot` or `controller`: whose store.
    pub role: String,
    /// The post-processing block it came from.
    pub block: u64,
    /// Its length ℓ (bits).
    pub bits: usize,
    /// The key, hex, most significant bit first; the last byte zero-padded.
    pub hex: String,
    /// Secret against the assumption except with probability `epsilon`.
    pub epsilon: f64,
    /// The assumption about Eve it is secret under.
    pub assumption: String,
    /// Whether that assumption is restricted (an operator's statement about an Eve who never
    /// learns the model), not a physical one.
    pub restricted: bool,
    /// When it was committed (UTC, RFC 3339).
    pub created: String,
    /// The sessions whose raw bits it came from.
    pub sessions: Vec<u32>,
}

impl std::fmt::Debug for StoredKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StoredKey")
            .field("id", &self.id)
            .field("role", &self.role)
            .field("block", &self.block)
            .field("bits", &self.bits)
            .field("restricted", &self.restricted)
            .finish_non_exhaustive()
    }
}

impl Drop for StoredKey {
    fn drop(&mut self) {
        self.hex.zeroize();
    }
}

impl StoredKey {
    /// The stored form of `key`, committed now by `role`.
    #[must_use]
    pub fn new(key: &FinalKey, role: &str, restricted: bool) -> Self {
        let mut hex = String::with_capacity(key.key.len().div_ceil(4));
        let mut bytes = vec![0_u8; key.key.len().div_ceil(8)];
        for i in 0..key.key.len() {
            if key.key.get(i) == Some(true) {
                bytes[i / 8] |= 0x80 >> (i % 8);
            }
        }
        for byte in &bytes {
            hex.push_str(&format!("{byte:02x}"));
        }
        bytes.zeroize();
        Self {
            id: key.id.clone(),
            role: role.to_owned(),
            block: key.block,
            bits: key.key.len(),
            hex,
            epsilon: key.epsilon,
            assumption: key.assumption.clone(),
            restricted,
            created: utc_now(),
            sessions: key.sessions.clone(),
        }
    }
}

/// The key folder of a store.
#[derive(Clone, Debug)]
pub struct KeyStore {
    dir: PathBuf,
}

impl KeyStore {
    /// The key folder of the store at `store` (`store/keys`), created (0700) if missing.
    ///
    /// # Errors
    /// The folder cannot be created.
    pub fn create(store: &Path) -> Result<Self, NetError> {
        let dir = store.join("keys");
        create_private_dir(&dir)?;
        Ok(Self { dir })
    }

    /// The key folder of an existing store.
    ///
    /// # Errors
    /// `store` is not a store (no `keys` folder).
    pub fn open(store: &Path) -> Result<Self, NetError> {
        let dir = store.join("keys");
        if !dir.is_dir() {
            return Err(NetError::Usage(format!(
                "{} is not a key store (no keys/ folder; agents create it with --store)",
                store.display()
            )));
        }
        Ok(Self { dir })
    }

    fn path(&self, id: &str) -> PathBuf {
        self.dir.join(format!("{id}.key"))
    }

    /// Writes `key` unless a key of its ID is stored already (a recovery that writes a
    /// committed key again changes nothing).
    ///
    /// # Errors
    /// The write fails.
    pub fn write(&self, key: &StoredKey) -> Result<(), NetError> {
        let path = self.path(&key.id);
        if path.exists() {
            return Ok(());
        }
        let mut text = serde_json::to_vec_pretty(key).expect("a key always serialises");
        text.push(b'\n');
        let written = secret_file::write_new(&path, &text);
        text.zeroize();
        written
    }

    /// Every stored key, by block then ID: the same order in both agents' stores (creation
    /// times differ between the sides, and after a crash).
    ///
    /// # Errors
    /// The folder or a key file cannot be read, or a key file is malformed (named).
    pub fn list(&self) -> Result<Vec<StoredKey>, NetError> {
        let entries = std::fs::read_dir(&self.dir)
            .map_err(NetError::io(format!("read {}", self.dir.display())))?;
        let mut keys = Vec::new();
        for entry in entries {
            let path = entry
                .map_err(NetError::io(format!("read {}", self.dir.display())))?
                .path();
            if path.extension().is_some_and(|e| e == "key") {
                keys.push(read_key(&path)?);
            }
        }
        keys.sort_by(|a, b| (a.block, &a.id).cmp(&(b.block, &b.id)));
        Ok(keys)
    }

    /// The key `id`.
    ///
    /// # Errors
    /// No such key (a usage error naming it), or its file is unreadable or malformed.
    pub fn get(&self, id: &str) -> Result<StoredKey, NetError> {
        read_key(&self.existing(id)?)
    }

    /// Deletes the key `id` durably.
    ///
    /// # Errors
    /// No such key, or the removal fails.
    pub fn delete(&self, id: &str) -> Result<(), NetError> {
        let path = self.existing(id)?;
        std::fs::remove_file(&path)
            .and_then(|()| std::fs::File::open(&self.dir)?.sync_all())
            .map_err(NetError::io(format!("delete {}", path.display())))
    }

    fn existing(&self, id: &str) -> Result<PathBuf, NetError> {
        let valid = id.len() == 16 && id.bytes().all(|b| b.is_ascii_hexdigit());
        let path = self.path(id);
        if !valid || !path.is_file() {
            return Err(NetError::Usage(format!(
                "no key {id:?} in {} (IDs are 16 hex digits; `robokey keys list` shows them)",
                self.dir.display()
            )));
        }
        Ok(path)
    }
}

fn read_key(path: &Path) -> Result<StoredKey, NetError> {
    let text = secret_file::read(path, "key")?;
    serde_json::from_str(&text).map_err(|e| NetError::Store {
        path: path.display().to_string(),
        message: format!("not a robokey key file: {e}"),
    })
}

/// Creates `dir` (and its parents) readable by its owner only, if missing.
pub(crate) fn create_private_dir(dir: &Path) -> Result<(), NetError> {
    let mut builder = std::fs::DirBuilder::new();
    builder.recursive(true);
    #[cfg(unix)]
    std::os::unix::fs::DirBuilderExt::mode(&mut builder, 0o700);
    builder
        .create(dir)
        .map_err(NetError::io(format!("create {}", dir.display())))
}

/// Now, UTC, as `YYYY-MM-DDTHH:MM:SSZ`.
fn utc_now() -> String {
    let seconds = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    utc(seconds)
}

/// `seconds` after the Unix epoch as `YYYY-MM-DDTHH:MM:SSZ` (the proleptic Gregorian
/// calendar; H. Hinnant's `civil_from_days`).
fn utc(seconds: u64) -> String {
    let days = (seconds / 86_400) as i64;
    let second_of_day = seconds % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let day_of_era = z.rem_euclid(146_097);
    let year_of_era =
        (day_of_era - day_of_era / 1460 + day_of_era / 36_524 - day_of_era / 146_096) / 365;
    let day_of_year = day_of_era - (365 * year_of_era + year_of_era / 4 - year_of_era / 100);
    let mp = (5 * day_of_year + 2) / 153;
    let day = day_of_year - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = year_of_era + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z",
        second_of_day / 3600,
        second_of_day / 60 % 60,
        second_of_day % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use robokey_secrecy::BitString;

    #[test]
    fn dates_are_civil() {
        assert_eq!(utc(0), "1970-01-01T00:00:00Z");
        assert_eq!(utc(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(utc(1_795_000_000), "2026-11-18T11:06:40Z");
    }

    #[test]
    fn keys_are_written_once_listed_got_and_deleted_by_id() {
        let dir = crate::journal::tests::tempdir("keystore");
        let store = KeyStore::create(&dir).unwrap();
        let final_key = FinalKey {
            id: "00112233aabbccdd".into(),
            block: 3,
            key: BitString::from_bools(&[
                true, false, true, true, false, false, false, false, true,
            ]),
            sessions: vec![7, 9],
            epsilon: 4e-6,
            assumption: "stated".into(),
        };
        let key = StoredKey::new(&final_key, "robot", false);
        assert_eq!(key.hex, "b080");
        store.write(&key).unwrap();
        // A second write of the same ID keeps the first.
        let mut other = key.clone();
        other.hex = "ffff".into();
        store.write(&other).unwrap();
        assert_eq!(store.get(&key.id).unwrap(), key);
        assert_eq!(store.list().unwrap(), vec![key.clone()]);
        for bad in ["nope", "00112233aabbccde", "../keys/x"] {
            let error = store.get(bad).unwrap_err().to_string();
            assert!(error.contains("no key"), "{error}");
        }
        store.delete(&key.id).unwrap();
        assert!(store.list().unwrap().is_empty());
        assert!(store.delete(&key.id).is_err());
    }
}
