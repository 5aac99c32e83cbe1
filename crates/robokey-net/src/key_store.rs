//! The final keys of a store (`DIR/keys/`): one file per key, `ID.key`, mode 0600, written
//! all or nothing (docs/postprocessing.md, "Key store"). Both agents name a key by the same
//! ID, so an application finds the same key on the robot and on the controller.
//!
//! A key file is the key's JSON with a last field `mac`: HMAC-SHA256 under the store's
//! key-file key ([`crate::store_keys`], derived from the pairing secret and the role) over
//! `"robokey key file v2" ‖` the JSON before that field, exactly as written. A file that
//! does not verify — planted, edited, another pairing's or role's — is refused by name and
//! never reported as a commit; so is any name that exists already (a file, a link, a dangling
//! link) when a key is written, unless it is this very key. A key is `pending` while the peer
//! has not acknowledged it, and only a `settled` key is delivered: cut into slices, each taken
//! once ([`slices`], docs/keys.md), its taken bits erased from the file. A file with taken
//! slices is sealed under another MAC domain, so that a robokey that predates slices refuses
//! it rather than read its erased bits as a key.
//!
//! Every change to `keys/` — an agent writing, settling or removing a key, a slice taken by
//! `robokey keys take` or `robokey kme`, `keys delete` — holds the folder's lock
//! ([`KeyStore::lock`], `flock` on the folder itself) for that one change: an agent and a key
//! server on the same store never interleave their changes to a file, and two takers never
//! take the same slice.

use std::fs::OpenOptions;
use std::io::Read as _;
use std::path::{Path, PathBuf};

use robokey::post_settings::KeyBasis;
use robokey_secrecy::postprocess::{FinalKey, KeyReconciliation};
use serde::{Deserialize, Serialize};
use zeroize::{Zeroize, Zeroizing};

use crate::error::NetError;
use crate::key_slice::Span;
use crate::owned_file::{self, ANY_ACCESS_BY_OTHERS};
use crate::secret_file;
use crate::store_keys::StoreMac;

pub mod slices;

/// Domain of a key file's MAC.
const MAC_DOMAIN: &[u8] = b"robokey key file v2";
/// Domain of the MAC of a key file from which slices were taken.
const SLICED_MAC_DOMAIN: &[u8] = b"robokey key file v3 with taken slices";
/// What separates a key file's JSON from its MAC.
const MAC_FIELD: &str = ",\n  \"mac\": \"";
/// Longest ID an error message quotes in full.
const QUOTED_ID: usize = 24;

/// Whether a key may be delivered to applications.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum KeyStatus {
    /// Both sides committed it: deliverable.
    Settled,
    /// Committed or prepared here, not yet acknowledged by the peer (the reason): withheld
    /// until the acknowledgement or a later session settles it.
    Pending(String),
}

/// What a store writes in every key's record besides the key: whether its assumption is
/// restricted, and what it rests on.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct KeyLabels {
    /// The assumption is restricted (an operator's statement about an Eve who never learns
    /// the model), not a physical one.
    pub restricted: bool,
    /// Private sensing: Eve's camera and the plant's model class.
    pub basis: Option<KeyBasis>,
}

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
    /// Private sensing: the two assumptions it rests on, Eve's camera and the plant's model
    /// class (absent in odometry mode and in records written before they were stated).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub basis: Option<KeyBasis>,
    /// How its block was reconciled (`cascade` or `ldpc`) and leak_EC (absent in records
    /// written before they were stated).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reconciliation: Option<KeyReconciliation>,
    /// When it was committed (UTC, RFC 3339).
    pub created: String,
    /// The sessions whose raw bits it came from.
    pub sessions: Vec<u32>,
    /// Settled, or pending and why.
    pub status: KeyStatus,
    /// The slices taken from it, by offset: their bits are erased (zero) in `hex`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub taken: Vec<Span>,
}

impl std::fmt::Debug for StoredKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StoredKey")
            .field("id", &self.id)
            .field("role", &self.role)
            .field("block", &self.block)
            .field("bits", &self.bits)
            .field("restricted", &self.restricted)
            .field("status", &self.status)
            .field("taken", &self.taken)
            .finish_non_exhaustive()
    }
}

impl Drop for StoredKey {
    fn drop(&mut self) {
        self.hex.zeroize();
    }
}

impl StoredKey {
    /// The stored form of `key`, committed (or prepared) now by `role`, resting on `basis`.
    #[must_use]
    pub fn new(key: &FinalKey, role: &str, labels: &KeyLabels, status: KeyStatus) -> Self {
        let mut bytes = Zeroizing::new(vec![0_u8; key.key.len().div_ceil(8)]);
        for i in 0..key.key.len() {
            if key.key.get(i) == Some(true) {
                bytes[i / 8] |= 0x80 >> (i % 8);
            }
        }
        // Hex without data-dependent branches or table look-ups (base16ct): it is the key.
        let hex = base16ct::lower::encode_string(&bytes);
        Self {
            id: key.id.clone(),
            role: role.to_owned(),
            block: key.block,
            bits: key.key.len(),
            hex,
            epsilon: key.epsilon,
            assumption: key.assumption.clone(),
            restricted: labels.restricted,
            basis: labels.basis.clone(),
            reconciliation: key.reconciliation.clone(),
            created: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
            sessions: key.sessions.clone(),
            status,
            taken: Vec::new(),
        }
    }

    /// Whether it may be delivered.
    #[must_use]
    pub fn is_settled(&self) -> bool {
        self.status == KeyStatus::Settled
    }

    /// Whether `other` is the same key (ID, block, sessions, bits), whatever its status and
    /// the slices taken from either (their bits are left out of the comparison).
    fn same_key(&self, other: &Self) -> bool {
        let erased = [self.taken.as_slice(), other.taken.as_slice()].concat();
        (&self.id, self.block, &self.sessions) == (&other.id, other.block, &other.sessions)
            && self.erased_hex(&erased) == other.erased_hex(&erased)
    }
}

/// What [`KeyStore::store`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stored {
    /// The file was written.
    Written,
    /// This key was stored already, as settled as asked or more.
    Present,
    /// This key was stored pending and is now settled.
    Settled,
}

/// The key folder of a store, for one role and pairing.
#[derive(Clone, Debug)]
pub struct KeyStore {
    dir: PathBuf,
    mac: StoreMac,
    role: String,
}

impl KeyStore {
    /// The key folder of the store at `store` (`store/keys`), created (0700) if missing;
    /// `mac` is the store's key-file key for `role`.
    ///
    /// # Errors
    /// The folder cannot be created, or it is a link, another user's or writable by others.
    pub fn create(store: &Path, mac: &StoreMac, role: &str) -> Result<Self, NetError> {
        let dir = store.join("keys");
        create_private_dir(&dir)?;
        Self::open(store, mac, role)
    }

    /// The key folder of an existing store.
    ///
    /// # Errors
    /// `store` is not a store (no `keys` folder), or a folder is a link, another user's or
    /// writable by others.
    pub fn open(store: &Path, mac: &StoreMac, role: &str) -> Result<Self, NetError> {
        let dir = store.join("keys");
        owned_file::check_folder(store, "store")?;
        if std::fs::symlink_metadata(&dir).is_err() {
            return Err(NetError::Usage(format!(
                "{} is not a key store (no keys/ folder; agents create it with --store)",
                store.display()
            )));
        }
        owned_file::check_inner_folder(&dir, "key folder")?;
        Ok(Self {
            dir,
            mac: mac.clone(),
            role: role.to_owned(),
        })
    }

    /// `robot` or `controller`: whose store.
    #[must_use]
    pub fn role(&self) -> &str {
        &self.role
    }

    fn path(&self, id: &str) -> PathBuf {
        self.dir.join(format!("{id}.key"))
    }

    /// Stores `key`: writes its file if its name is free; if this very key is stored
    /// already, leaves it (settling it if it was pending and `key` is settled). Never writes
    /// over anything else.
    ///
    /// # Errors
    /// The name is taken by a link, a file that does not verify, or another key (named: it
    /// is then not reported as committed); a write fails.
    pub fn store(&self, key: &StoredKey) -> Result<Stored, NetError> {
        let _lock = self.lock()?;
        let path = self.path(&key.id);
        let text = self.seal(key)?;
        if secret_file::create(&path, &text)? {
            return Ok(Stored::Written);
        }
        let existing = self.read(&path, &key.id).map_err(|error| NetError::Store {
            path: path.display().to_string(),
            message: format!(
                "the name of key {} is taken by something this store did not write ({error}): \
                 refusing to report the key as committed; remove it, and the agent writes \
                 the key from its journal when it next opens the store",
                key.id
            ),
        })?;
        if !existing.same_key(key) {
            return Err(NetError::Store {
                path: path.display().to_string(),
                message: format!("holds another key under the ID {}", key.id),
            });
        }
        if key.is_settled() && !existing.is_settled() {
            secret_file::replace(&path, &text)?;
            return Ok(Stored::Settled);
        }
        Ok(Stored::Present)
    }

    /// Gives the stored key `id` the status `status`, replacing its file atomically.
    ///
    /// # Errors
    /// No such key (a usage error), it does not verify, or the write fails.
    pub fn restate(&self, id: &str, status: KeyStatus) -> Result<(), NetError> {
        let _lock = self.lock()?;
        let mut key = self.get(id)?;
        key.status = status;
        secret_file::replace(&self.path(id), &self.seal(&key)?)?;
        Ok(())
    }

    /// Removes the pending key `id` (its block was aborted before the peer committed).
    ///
    /// # Errors
    /// The key is settled, does not verify, or the removal fails.
    pub fn remove_pending(&self, id: &str) -> Result<(), NetError> {
        let _lock = self.lock()?;
        let path = self.path(id);
        let key = self.read(&path, id)?;
        if key.is_settled() {
            return Err(NetError::Store {
                path: path.display().to_string(),
                message: "is settled: only a pending key is removed when its block aborts".into(),
            });
        }
        remove_durably(&path, &self.dir)
    }

    /// Every stored key, verified, by block then ID: the same order in both agents' stores
    /// (creation times differ between the sides, and after a crash). Temporary files of
    /// interrupted writes (`.NAME.tmp`) are skipped.
    ///
    /// # Errors
    /// The folder cannot be read, or a `.key` entry is a link, not this store's or malformed
    /// (named).
    pub fn list(&self) -> Result<Vec<StoredKey>, NetError> {
        let entries = std::fs::read_dir(&self.dir)
            .map_err(NetError::io(format!("read {}", self.dir.display())))?;
        let mut keys = Vec::new();
        for entry in entries {
            let path = entry
                .map_err(NetError::io(format!("read {}", self.dir.display())))?
                .path();
            let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
            let Some(id) = name.as_deref().and_then(|n| n.strip_suffix(".key")) else {
                continue;
            };
            if !id.starts_with('.') {
                keys.push(self.read(&path, id)?);
            }
        }
        keys.sort_by(|a, b| (a.block, &a.id).cmp(&(b.block, &b.id)));
        Ok(keys)
    }

    /// The key `id`, verified, whatever its status.
    ///
    /// # Errors
    /// No such key (a usage error naming it), or its file does not verify.
    pub fn get(&self, id: &str) -> Result<StoredKey, NetError> {
        let path = self.existing(id)?;
        self.read(&path, id)
    }

    /// The key `id` if it is settled.
    ///
    /// # Errors
    /// As [`Self::get`], or [`NetError::Pending`] naming the key and why it is pending.
    pub fn settled(&self, id: &str) -> Result<StoredKey, NetError> {
        let key = self.get(id)?;
        match &key.status {
            KeyStatus::Settled => Ok(key),
            KeyStatus::Pending(reason) => Err(NetError::Pending(format!(
                "key {id} is pending — {reason} — and is withheld until the acknowledgement \
                 or a later session settles it (`robokey keys list` shows its state)"
            ))),
        }
    }

    /// Deletes the settled key `id` durably.
    ///
    /// # Errors
    /// No such key, it is pending ([`NetError::Pending`]), it does not verify, or the
    /// removal fails.
    pub fn delete(&self, id: &str) -> Result<(), NetError> {
        let _lock = self.lock()?;
        self.settled(id)?;
        remove_durably(&self.path(id), &self.dir)
    }

    /// Takes the lock of the key folder (`flock` on the folder), waiting for another
    /// process's change to end; held until the guard is dropped. Every change to `keys/`
    /// holds it, and never takes it twice (a second lock in one process waits for the first).
    ///
    /// # Errors
    /// The folder cannot be opened or locked.
    pub fn lock(&self) -> Result<KeyFolderLock, NetError> {
        let folder = std::fs::File::open(&self.dir)
            .and_then(|folder| folder.lock().map(|()| folder))
            .map_err(NetError::io(format!("lock {}", self.dir.display())))?;
        Ok(KeyFolderLock { _folder: folder })
    }

    /// Replaces the file of `key` (already stored) by its new state, atomically. The caller
    /// holds [`Self::lock`].
    ///
    /// # Errors
    /// The write fails (the old file is then intact).
    pub(crate) fn rewrite(&self, key: &StoredKey, _lock: &KeyFolderLock) -> Result<(), NetError> {
        secret_file::replace(&self.path(&key.id), &self.seal(key)?)?;
        Ok(())
    }

    fn existing(&self, id: &str) -> Result<PathBuf, NetError> {
        let valid = id.len() == 16 && id.bytes().all(|b| b.is_ascii_hexdigit());
        let path = self.path(id);
        if !valid || std::fs::symlink_metadata(&path).is_err() {
            return Err(NetError::Usage(format!(
                "no key {} in {} (IDs are 16 hex digits; `robokey keys list` shows them)",
                brief(id),
                self.dir.display()
            )));
        }
        Ok(path)
    }

    /// `key` as its file's text: its JSON, then the MAC over it.
    fn seal(&self, key: &StoredKey) -> Result<Zeroizing<Vec<u8>>, NetError> {
        if key.role != self.role {
            return Err(NetError::Usage(format!(
                "a {} key cannot be stored in a {} store",
                key.role, self.role
            )));
        }
        let body = Zeroizing::new(serde_json::to_string_pretty(key).expect("a key serialises"));
        let open = body
            .strip_suffix("\n}")
            .expect("a pretty JSON object ends so");
        let tag = self.mac.tag(&[mac_domain(key), body.as_bytes()]);
        let mut text = Zeroizing::new(Vec::with_capacity(body.len() + 100));
        text.extend_from_slice(open.as_bytes());
        text.extend_from_slice(MAC_FIELD.as_bytes());
        text.extend_from_slice(base16ct::lower::encode_string(&tag).as_bytes());
        text.extend_from_slice(b"\"\n}\n");
        Ok(text)
    }

    /// Reads and verifies the key file `path` of ID `id`.
    fn read(&self, path: &Path, id: &str) -> Result<StoredKey, NetError> {
        let bad = |message: String| NetError::Store {
            path: path.display().to_string(),
            message,
        };
        let mut file = owned_file::open(path, OpenOptions::new().read(true), "key file")?;
        owned_file::check_file(&file, path, "key file", ANY_ACCESS_BY_OTHERS)?;
        let mut text = Zeroizing::new(String::new());
        file.read_to_string(&mut text)
            .map_err(|e| bad(format!("cannot be read: {e}")))?;
        let (open, tail) = text.rsplit_once(MAC_FIELD).ok_or_else(|| {
            bad("does not verify: it has no MAC (not a key file this store wrote)".into())
        })?;
        let tag = tail
            .strip_suffix("\"\n}\n")
            .and_then(|hex| base16ct::mixed::decode_vec(hex).ok())
            .ok_or_else(|| bad("does not verify: its MAC is malformed".into()))?;
        let body = Zeroizing::new(format!("{open}\n}}"));
        let domain = [MAC_DOMAIN, SLICED_MAC_DOMAIN]
            .into_iter()
            .find(|domain| tag.len() == 32 && self.mac.verify(&[domain, body.as_bytes()], &tag))
            .ok_or_else(|| {
                bad(format!(
                    "does not verify under this pairing's {} key-file key: not written by this \
                     store (planted, edited, or another pairing's or role's)",
                    self.role
                ))
            })?;
        let key: StoredKey =
            serde_json::from_str(&body).map_err(|e| bad(format!("is malformed: {e}")))?;
        if domain != mac_domain(&key) || !key.taken_spans_fit() {
            return Err(bad(
                "is malformed: its taken slices do not match its MAC domain or its length".into(),
            ));
        }
        if key.id != id || key.role != self.role {
            return Err(bad(format!(
                "holds the {} key {}, not {} key {id}",
                key.role, key.id, self.role
            )));
        }
        Ok(key)
    }
}

/// The MAC domain of `key`'s file: another once a slice was taken.
fn mac_domain(key: &StoredKey) -> &'static [u8] {
    if key.taken.is_empty() {
        MAC_DOMAIN
    } else {
        SLICED_MAC_DOMAIN
    }
}

/// The lock of a key folder, held while alive ([`KeyStore::lock`]).
#[derive(Debug)]
pub struct KeyFolderLock {
    _folder: std::fs::File,
}

/// `id` as an error quotes it: whole if short, else its start and its length.
fn brief(id: &str) -> String {
    if id.chars().count() <= QUOTED_ID {
        return format!("{id:?}");
    }
    let start: String = id.chars().take(QUOTED_ID).collect();
    format!("{start:?}… ({} characters)", id.chars().count())
}

fn remove_durably(path: &Path, dir: &Path) -> Result<(), NetError> {
    std::fs::remove_file(path)
        .and_then(|()| std::fs::File::open(dir)?.sync_all())
        .map_err(NetError::io(format!("delete {}", path.display())))
}

/// Creates `dir` (and its parents) readable by its owner only, if missing.
pub(crate) fn create_private_dir(dir: &Path) -> Result<(), NetError> {
    let mut builder = std::fs::DirBuilder::new();
    builder.recursive(true);
    std::os::unix::fs::DirBuilderExt::mode(&mut builder, 0o700);
    builder
        .create(dir)
        .map_err(NetError::io(format!("create {}", dir.display())))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use robokey::protocol::auth::PairingSecret;
    use robokey_secrecy::BitString;

    pub(crate) fn mac(seed: u8, role: &str) -> StoreMac {
        StoreMac::derive(&PairingSecret::from_bytes(&[seed; 32]), "key-file", role)
    }

    fn final_key() -> FinalKey {
        FinalKey {
            id: "00112233aabbccdd".into(),
            block: 3,
            key: BitString::from_bools(&[
                true, false, true, true, false, false, false, false, true,
            ]),
            sessions: vec![7, 9],
            epsilon: 4e-6,
            assumption: "stated".into(),
            reconciliation: Some(KeyReconciliation {
                method: "ldpc".into(),
                leak_ec: 3_616,
            }),
        }
    }

    #[test]
    fn a_record_names_its_reconciliation_and_older_records_load_without_it() {
        let key = StoredKey::new(
            &final_key(),
            "robot",
            &KeyLabels::default(),
            KeyStatus::Settled,
        );
        let json = serde_json::to_value(&key).unwrap();
        assert_eq!(json["reconciliation"]["method"], "ldpc");
        assert_eq!(json["reconciliation"]["leak_ec"], 3_616);
        let listed = crate::key_listing::ListedKey::from(&key);
        assert_eq!(listed.reconciliation.as_deref(), Some("ldpc"));
        assert_eq!(listed.leak_ec, Some(3_616));
        // A record written before the field existed: it loads, lists nothing for it, and
        // is written back exactly as it was (the MAC covers the JSON).
        let mut old = json;
        old.as_object_mut().unwrap().remove("reconciliation");
        let loaded: StoredKey = serde_json::from_value(old.clone()).unwrap();
        assert_eq!(loaded.reconciliation, None);
        assert_eq!(serde_json::to_value(&loaded).unwrap(), old);
        let listed = serde_json::to_value(crate::key_listing::ListedKey::from(&loaded)).unwrap();
        assert!(listed.get("reconciliation").is_none() && listed.get("leak_ec").is_none());
    }

    #[test]
    fn keys_are_written_once_settled_listed_delivered_and_deleted_by_id() {
        let dir = crate::journal::tests::tempdir("keystore");
        let store = KeyStore::create(&dir, &mac(1, "robot"), "robot").unwrap();
        let pending = StoredKey::new(
            &final_key(),
            "robot",
            &KeyLabels::default(),
            KeyStatus::Pending("prepared".into()),
        );
        assert_eq!(pending.hex, "b080");
        // Committed now, in UTC to the second: `YYYY-MM-DDTHH:MM:SSZ`.
        let created = humantime::parse_rfc3339(&pending.created).unwrap();
        let age = std::time::SystemTime::now()
            .duration_since(created)
            .unwrap();
        assert!(
            age.as_secs() < 3600 && pending.created.len() == 20,
            "{}",
            pending.created
        );
        assert_eq!(store.store(&pending).unwrap(), Stored::Written);
        assert_eq!(store.store(&pending).unwrap(), Stored::Present);
        // A pending key is listed, got, and withheld from delivery and deletion.
        assert_eq!(store.list().unwrap(), vec![pending.clone()]);
        let withheld = store.settled(&pending.id).unwrap_err();
        assert!(matches!(withheld, NetError::Pending(_)), "{withheld}");
        assert!(withheld.to_string().contains("prepared"), "{withheld}");
        assert!(matches!(
            store.delete(&pending.id),
            Err(NetError::Pending(_))
        ));
        // Settling replaces it; a pending write after that changes nothing.
        let mut settled = pending.clone();
        settled.status = KeyStatus::Settled;
        assert_eq!(store.store(&settled).unwrap(), Stored::Settled);
        assert_eq!(store.store(&pending).unwrap(), Stored::Present);
        assert_eq!(store.settled(&settled.id).unwrap(), settled);
        // Another key under the same ID is refused.
        let mut other = settled.clone();
        other.hex = "ffff".into();
        let error = store.store(&other).unwrap_err().to_string();
        assert!(error.contains("another key"), "{error}");
        assert!(store.remove_pending(&settled.id).is_err());
        for bad in ["nope", "00112233aabbccde", "../keys/x"] {
            let error = store.get(bad).unwrap_err().to_string();
            assert!(error.contains("no key"), "{error}");
        }
        store.delete(&settled.id).unwrap();
        assert!(store.list().unwrap().is_empty());
        assert!(store.delete(&settled.id).is_err());
    }

    #[test]
    fn a_five_thousand_character_id_is_named_briefly() {
        let dir = crate::journal::tests::tempdir("keystore-long");
        let store = KeyStore::create(&dir, &mac(1, "robot"), "robot").unwrap();
        let error = store.get(&"a".repeat(5000)).unwrap_err().to_string();
        assert!(error.contains("(5000 characters)"), "{error}");
        assert!(error.len() < 200, "{} characters: {error}", error.len());
    }

    /// Whatever an attacker beside the store puts under a key's name — a file of their own,
    /// a link, a dangling link, another pairing's or role's genuine key file, an edited one —
    /// the write fails naming it, and no listing or delivery accepts it.
    #[test]
    fn a_planted_name_is_never_taken_for_the_key() {
        let dir = crate::journal::tests::tempdir("keystore-planted");
        let store = KeyStore::create(&dir, &mac(1, "robot"), "robot").unwrap();
        let key = StoredKey::new(
            &final_key(),
            "robot",
            &KeyLabels::default(),
            KeyStatus::Settled,
        );
        let path = dir.join("keys").join(format!("{}.key", key.id));
        let victim = dir.join("victim");
        std::fs::write(&victim, b"attacker's bits").unwrap();
        let forged = {
            let other = KeyStore::create(
                &crate::journal::tests::tempdir("keystore-other"),
                &mac(2, "robot"),
                "robot",
            )
            .unwrap();
            String::from_utf8(other.seal(&key).unwrap().to_vec()).unwrap()
        };
        let controllers = {
            let mut theirs = key.clone();
            theirs.role = "controller".into();
            let other = KeyStore::create(
                &crate::journal::tests::tempdir("keystore-role"),
                &mac(1, "controller"),
                "controller",
            )
            .unwrap();
            String::from_utf8(other.seal(&theirs).unwrap().to_vec()).unwrap()
        };
        let genuine = String::from_utf8(store.seal(&key).unwrap().to_vec()).unwrap();
        let edited = genuine.replace(&key.hex, "ffff");
        type Plant<'a> = Box<dyn Fn(&Path) + 'a>;
        let plants: Vec<(&str, Plant<'_>)> = vec![
            (
                "a file",
                Box::new(|p| std::fs::write(p, b"{\"hex\": \"ff\"}").unwrap()),
            ),
            (
                "a link",
                Box::new(|p| std::os::unix::fs::symlink(&victim, p).unwrap()),
            ),
            (
                "a dangling link",
                Box::new(|p| std::os::unix::fs::symlink(dir.join("nowhere"), p).unwrap()),
            ),
            (
                "another pairing's key",
                Box::new(move |p| std::fs::write(p, &forged).unwrap()),
            ),
            (
                "another role's key",
                Box::new(move |p| std::fs::write(p, &controllers).unwrap()),
            ),
            (
                "an edited key",
                Box::new(move |p| std::fs::write(p, &edited).unwrap()),
            ),
        ];
        use std::os::unix::fs::PermissionsExt as _;
        for (what, plant) in &plants {
            plant(&path);
            if !std::fs::symlink_metadata(&path)
                .unwrap()
                .file_type()
                .is_symlink()
            {
                std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
            }
            let error = store.store(&key).unwrap_err().to_string();
            assert!(
                error.contains("refusing to report the key as committed"),
                "{what}: {error}"
            );
            assert!(store.list().is_err(), "{what}");
            assert!(store.settled(&key.id).is_err(), "{what}");
            assert_eq!(
                std::fs::read(&victim).unwrap(),
                b"attacker's bits",
                "{what}"
            );
            assert!(!dir.join("nowhere").exists(), "{what}");
            std::fs::remove_file(&path).unwrap();
        }
        // The name freed, the key is written.
        assert_eq!(store.store(&key).unwrap(), Stored::Written);
        assert_eq!(store.settled(&key.id).unwrap().hex, "b080");
    }

    #[test]
    fn a_key_folder_others_can_write_or_that_is_a_link_is_refused() {
        use std::os::unix::fs::PermissionsExt as _;
        let dir = crate::journal::tests::tempdir("keystore-modes");
        KeyStore::create(&dir, &mac(1, "robot"), "robot").unwrap();
        std::fs::set_permissions(dir.join("keys"), std::fs::Permissions::from_mode(0o777)).unwrap();
        let error = KeyStore::open(&dir, &mac(1, "robot"), "robot")
            .unwrap_err()
            .to_string();
        assert!(error.contains("mode 777"), "{error}");
        std::fs::remove_dir(dir.join("keys")).unwrap();
        let elsewhere = crate::journal::tests::tempdir("keystore-elsewhere");
        std::os::unix::fs::symlink(&elsewhere, dir.join("keys")).unwrap();
        let error = KeyStore::create(&dir, &mac(1, "robot"), "robot")
            .unwrap_err()
            .to_string();
        assert!(error.contains("symbolic link"), "{error}");
    }
}
