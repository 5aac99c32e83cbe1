//! An agent's post-processing store (`--store DIR`): the pool of raw session bits and the
//! post-processing endpoint's durable state in a [`Journal`], the final keys in a
//! [`KeyStore`] (docs/postprocessing.md, "The store").
//!
//! Records: a header (role, pairing fingerprint), one `session` record per pooled session
//! (its raw bits, written once), and `state` records (the endpoint's snapshot without the
//! pool's bits, the IDs pooled, and the keys committed in the same batch). The last intact
//! `state` record is the durable state; a session not named by it was never pooled. A key is
//! committed by the `state` record that carries it and then written to `keys/`; recovery
//! writes again any key a last `state` record carries, so a crash between the two loses
//! nothing. The journal is compacted when the store opens and after every block: spent raw
//! bits and settled keys leave the file.

use std::collections::{BTreeMap, BTreeSet};
use std::fs::File;
use std::path::{Path, PathBuf};

use robokey_secrecy::BitString;
use robokey_secrecy::postprocess::{ControllerSnapshot, FinalKey, RobotSnapshot};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use zeroize::Zeroizing;

use crate::error::NetError;
use crate::journal::Journal;
use crate::key_store::{KeyStore, StoredKey, create_private_dir};

/// A post-processing endpoint's durable state.
pub trait Snapshot: Serialize + DeserializeOwned {
    /// The store's role name: `robot` or `controller`.
    const ROLE: &'static str;
    /// The pooled sessions.
    fn pool(&self) -> &[(u32, BitString)];
    /// Takes the pooled sessions out of the snapshot.
    fn take_pool(&mut self) -> Vec<(u32, BitString)>;
    /// Puts them back.
    fn set_pool(&mut self, pool: Vec<(u32, BitString)>);
}

/// Both endpoints' snapshots keep their pool in a `pool` field.
macro_rules! snapshot {
    ($snapshot:ty, $role:literal) => {
        impl Snapshot for $snapshot {
            const ROLE: &'static str = $role;
            fn pool(&self) -> &[(u32, BitString)] {
                &self.pool
            }
            fn take_pool(&mut self) -> Vec<(u32, BitString)> {
                std::mem::take(&mut self.pool)
            }
            fn set_pool(&mut self, pool: Vec<(u32, BitString)>) {
                self.pool = pool;
            }
        }
    };
}

snapshot!(RobotSnapshot, "robot");
snapshot!(ControllerSnapshot, "controller");

/// One journal record.
#[derive(Serialize, Deserialize)]
#[serde(tag = "record", rename_all = "kebab-case")]
enum Record<S> {
    Header {
        role: String,
        pairing: String,
    },
    Session {
        id: u32,
        bits: BitString,
    },
    State {
        snapshot: S,
        pooled: Vec<u32>,
        pending: Vec<StoredKey>,
    },
}

/// What opening a store recovered.
#[derive(Debug)]
pub struct Recovery<S> {
    /// The durable state, pool included (`None` for a new store).
    pub snapshot: Option<S>,
    /// Bytes of a torn journal tail that were cut.
    pub torn_bytes: u64,
    /// Committed keys written to `keys/` only now (a crash came between).
    pub keys_recovered: usize,
}

/// An open store, locked against any other process for its life.
#[derive(Debug)]
pub struct PostStore<S> {
    dir: PathBuf,
    pairing: String,
    restricted: bool,
    _lock: File,
    journal: Journal,
    keys: KeyStore,
    /// Sessions with a `session` record in the journal.
    journaled: BTreeSet<u32>,
    _snapshot: std::marker::PhantomData<S>,
}

impl<S: Snapshot> PostStore<S> {
    /// Opens (creating) the store at `dir` for `S::ROLE` and the pairing of `fingerprint`,
    /// recovers its state and compacts it. Keys committed through it are labelled
    /// `restricted` as told.
    ///
    /// # Errors
    /// Another process holds the store; it belongs to the other role or another pairing; its
    /// journal is inconsistent; a file operation fails.
    pub fn open(
        dir: &Path,
        fingerprint: &str,
        restricted: bool,
    ) -> Result<(Self, Recovery<S>), NetError> {
        create_private_dir(dir)?;
        let keys = KeyStore::create(dir)?;
        let lock = lock_store(dir)?;
        let (journal, contents) = Journal::open(&dir.join("journal"))?;
        let mut store = Self {
            dir: dir.to_owned(),
            pairing: fingerprint.to_owned(),
            restricted,
            _lock: lock,
            journal,
            keys,
            journaled: BTreeSet::new(),
            _snapshot: std::marker::PhantomData,
        };
        let mut sessions = BTreeMap::new();
        let mut state = None;
        for (i, payload) in contents.records.iter().enumerate() {
            let record: Record<S> = serde_json::from_slice(payload)
                .map_err(|e| store.corrupt(format!("record {i} is malformed: {e}")))?;
            match record {
                Record::Header { role, pairing } => store.check_owner(&role, &pairing)?,
                Record::Session { id, bits } => {
                    sessions.insert(id, bits);
                }
                Record::State {
                    snapshot,
                    pooled,
                    pending,
                } => state = Some((snapshot, pooled, pending)),
            }
        }
        let mut recovery = Recovery {
            snapshot: None,
            torn_bytes: contents.torn_bytes,
            keys_recovered: 0,
        };
        if let Some((mut snapshot, pooled, pending)) = state {
            for key in &pending {
                if store.keys.get(&key.id).is_err() {
                    store.keys.write(key)?;
                    recovery.keys_recovered += 1;
                }
            }
            let pool = pooled
                .iter()
                .map(|id| {
                    sessions.remove(id).map(|bits| (*id, bits)).ok_or_else(|| {
                        store.corrupt(format!("session {id} is pooled but its bits are missing"))
                    })
                })
                .collect::<Result<Vec<_>, _>>()?;
            snapshot.set_pool(pool);
            store.compact(&mut snapshot)?;
            recovery.snapshot = Some(snapshot);
        } else {
            store.journal.rewrite(&[store.header()])?;
        }
        Ok((store, recovery))
    }

    /// The store's folder.
    #[must_use]
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Stores `snapshot` with the keys committed in the same batch, then writes the keys to
    /// `keys/`: the new sessions' bits first, then the state that names them and carries the
    /// keys, then the key files, then the state without them. Returns the keys as stored.
    ///
    /// # Errors
    /// A write fails (the last durable state is then the one before).
    pub fn persist(
        &mut self,
        snapshot: &mut S,
        committed: &[FinalKey],
    ) -> Result<Vec<StoredKey>, NetError> {
        let pool = snapshot.take_pool();
        let stored = self.persist_pool(snapshot, &pool, committed);
        snapshot.set_pool(pool);
        stored
    }

    fn persist_pool(
        &mut self,
        snapshot: &S,
        pool: &[(u32, BitString)],
        committed: &[FinalKey],
    ) -> Result<Vec<StoredKey>, NetError> {
        for (id, bits) in pool {
            if !self.journaled.contains(id) {
                self.journal.append(&encode(&Record::<S>::Session {
                    id: *id,
                    bits: bits.clone(),
                }))?;
                self.journaled.insert(*id);
            }
        }
        let pooled: Vec<u32> = pool.iter().map(|(id, _)| *id).collect();
        let stored: Vec<StoredKey> = committed
            .iter()
            .map(|key| StoredKey::new(key, S::ROLE, self.restricted))
            .collect();
        self.journal
            .append(&encode_state(snapshot, &pooled, &stored))?;
        if !stored.is_empty() {
            for key in &stored {
                self.keys.write(key)?;
            }
            self.journal.append(&encode_state(snapshot, &pooled, &[]))?;
        }
        Ok(stored)
    }

    /// Rewrites the journal with only what `snapshot` needs: the header, the pooled sessions'
    /// bits, and the state.
    ///
    /// # Errors
    /// The rewrite fails (the old journal is then intact).
    pub fn compact(&mut self, snapshot: &mut S) -> Result<(), NetError> {
        let pool = snapshot.take_pool();
        let pooled: Vec<u32> = pool.iter().map(|(id, _)| *id).collect();
        let mut records = vec![self.header()];
        records.extend(pool.iter().map(|(id, bits)| {
            encode(&Record::<S>::Session {
                id: *id,
                bits: bits.clone(),
            })
        }));
        records.push(encode_state(snapshot, &pooled, &[]));
        snapshot.set_pool(pool);
        self.journal.rewrite(&records)?;
        self.journaled = pooled.into_iter().collect();
        Ok(())
    }

    fn header(&self) -> Zeroizing<Vec<u8>> {
        encode(&Record::<S>::Header {
            role: S::ROLE.to_owned(),
            pairing: self.pairing.clone(),
        })
    }

    fn check_owner(&self, role: &str, pairing: &str) -> Result<(), NetError> {
        if role != S::ROLE {
            return Err(NetError::Usage(format!(
                "store {} belongs to a {role} agent, not to this {}",
                self.dir.display(),
                S::ROLE
            )));
        }
        if pairing != self.pairing {
            return Err(NetError::Usage(format!(
                "store {} belongs to the pairing with fingerprint {pairing}, not to this one \
                 ({}): each pairing has its own store",
                self.dir.display(),
                self.pairing
            )));
        }
        Ok(())
    }

    fn corrupt(&self, message: String) -> NetError {
        NetError::Store {
            path: self.dir.join("journal").display().to_string(),
            message,
        }
    }
}

fn encode<S: Serialize>(record: &Record<S>) -> Zeroizing<Vec<u8>> {
    Zeroizing::new(serde_json::to_vec(record).expect("a record always serialises"))
}

fn encode_state<S: Serialize>(
    snapshot: &S,
    pooled: &[u32],
    pending: &[StoredKey],
) -> Zeroizing<Vec<u8>> {
    #[derive(Serialize)]
    #[serde(tag = "record", rename = "state")]
    struct State<'a, S> {
        snapshot: &'a S,
        pooled: &'a [u32],
        pending: &'a [StoredKey],
    }
    Zeroizing::new(
        serde_json::to_vec(&State {
            snapshot,
            pooled,
            pending,
        })
        .expect("a state always serialises"),
    )
}

/// Takes the lock of the store at `dir` without waiting: agents hold it for their life,
/// `keys delete` for its change.
///
/// # Errors
/// Another process holds it, or the lock file cannot be created.
pub fn lock_store(dir: &Path) -> Result<File, NetError> {
    let path = dir.join("lock");
    let file = File::create(&path).map_err(NetError::io(format!("create {}", path.display())))?;
    match file.try_lock() {
        Ok(()) => Ok(file),
        Err(std::fs::TryLockError::WouldBlock) => Err(NetError::Usage(format!(
            "store {} is in use by another robokey process",
            dir.display()
        ))),
        Err(std::fs::TryLockError::Error(e)) => {
            Err(NetError::io(format!("lock {}", path.display()))(e))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::journal::tests::tempdir;

    fn snapshot(pool: &[(u32, bool)], committed: &[u64]) -> ControllerSnapshot {
        ControllerSnapshot {
            next_block: committed.len() as u64,
            pool: pool
                .iter()
                .map(|&(id, bit)| (id, BitString::from_bools(&[bit; 100])))
                .collect(),
            separations: Vec::new(),
            spent: Vec::new(),
            in_flight: None,
            committed: committed.to_vec(),
        }
    }

    fn key(block: u64) -> FinalKey {
        FinalKey {
            id: format!("{block:016x}"),
            block,
            key: BitString::from_bools(&[true, false, true]),
            sessions: vec![1, 2],
            epsilon: 4e-6,
            assumption: "stated".into(),
        }
    }

    #[test]
    fn the_pool_and_state_survive_reopening_and_the_store_is_exclusive() {
        let dir = tempdir("post-store");
        let (mut store, recovery) =
            PostStore::<ControllerSnapshot>::open(&dir, "f1", false).unwrap();
        assert!(recovery.snapshot.is_none());
        let mut state = snapshot(&[(1, true), (2, false)], &[]);
        store.persist(&mut state, &[]).unwrap();
        // A second process is refused while the first holds the store.
        let error = PostStore::<ControllerSnapshot>::open(&dir, "f1", false).unwrap_err();
        assert!(error.to_string().contains("in use"), "{error}");
        drop(store);
        let (_, recovery) = PostStore::<ControllerSnapshot>::open(&dir, "f1", false).unwrap();
        assert_eq!(recovery.snapshot, Some(state));
        // The other role and another pairing are refused, naming what differs.
        let error = PostStore::<RobotSnapshot>::open(&dir, "f1", false).unwrap_err();
        assert!(error.to_string().contains("controller agent"), "{error}");
        let error = PostStore::<ControllerSnapshot>::open(&dir, "f2", false).unwrap_err();
        assert!(error.to_string().contains("fingerprint f1"), "{error}");
    }

    /// A crash after the state that carries a committed key and before its key file: the
    /// store writes the key when it opens. Then compaction drops spent bits.
    #[test]
    fn a_committed_key_whose_file_a_crash_prevented_is_written_on_opening() {
        let dir = tempdir("post-store-crash");
        let (mut store, _) = PostStore::<ControllerSnapshot>::open(&dir, "f", true).unwrap();
        let mut state = snapshot(&[(3, true)], &[0]);
        let stored = store.persist(&mut state, &[key(0)]).unwrap();
        assert_eq!(stored[0].hex, "a0");
        assert!(stored[0].restricted);
        drop(store);
        // Undo the key file and the state record that followed it, as a crash would.
        let (mut journal, contents) = Journal::open(&dir.join("journal")).unwrap();
        let n = contents.records.len();
        journal.rewrite(&contents.records[..n - 1]).unwrap();
        let keys = KeyStore::open(&dir).unwrap();
        keys.delete(&key(0).id).unwrap();
        let (mut store, recovery) = PostStore::<ControllerSnapshot>::open(&dir, "f", true).unwrap();
        assert_eq!(recovery.keys_recovered, 1);
        let recovered = keys.get(&key(0).id).unwrap();
        assert_eq!((recovered.hex.as_str(), recovered.block), ("a0", 0));
        // The pool emptied (a block took the session): its bits leave the journal.
        let mut state = recovery.snapshot.unwrap();
        state.pool.clear();
        store.persist(&mut state, &[]).unwrap();
        store.compact(&mut state).unwrap();
        let (_, contents) = Journal::open(&dir.join("journal")).unwrap();
        assert_eq!(contents.records.len(), 2, "header and state only");
        let recovery = PostStore::<ControllerSnapshot>::open(&dir, "f", true);
        assert!(recovery.is_err(), "still held by `store`");
        drop(store);
        let (_, recovery) = PostStore::<ControllerSnapshot>::open(&dir, "f", true).unwrap();
        assert_eq!(recovery.keys_recovered, 0);
        assert!(recovery.snapshot.unwrap().pool.is_empty());
    }
}
