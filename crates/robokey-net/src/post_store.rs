//! An agent's post-processing store (`--store DIR`): the pool of raw session bits and the
//! post-processing endpoint's durable state in an authenticated [`Journal`], the final keys
//! in a [`KeyStore`] (docs/postprocessing.md, "The store"). Both are keyed by the pairing
//! secret and the role ([`StoreKeys`]): whoever can write beside the store but does not hold
//! the pairing secret can delete or roll back what is there, never make the agent accept
//! or report something it did not write.
//!
//! Records: a header (role, pairing fingerprint), one `session` record per pooled session
//! (its raw bits and, on a controller, what it keeps of the session beside them: the samples
//! for the block's estimate when it measures the plant — a three-step doublet's sample after
//! its second step and entry speed among them —, its quantised LLRs when it reconciles by
//! LDPC — written once; the fields are absent otherwise, so older journals read unchanged),
//! and `state` records (the endpoint's snapshot without the
//! pool's bits, the IDs pooled, and the keys committed in the same batch). The last intact
//! `state` record is the durable state; a session not named by it was never pooled. A key is
//! committed by the `state` record that carries it and then written to `keys/`; recovery
//! writes again any key a last `state` record carries, so a crash between the two loses
//! nothing. A key is stored `pending` while the state says its block awaits the peer (the
//! controller's key until the robot's `CommitAck`, the robot's prepared key until the
//! `Commit`), and settled (or, for an aborted prepared key, removed) once the state says
//! otherwise. A session that a stored key lists as a source is never pooled again, even if
//! the journal was restored from an older copy. The journal is compacted when the store
//! opens and after every block: spent raw bits and settled keys leave the file.

use std::collections::{BTreeMap, BTreeSet};
use std::fs::{File, OpenOptions};
use std::io::{BufRead as _, BufReader, Read as _};
use std::path::{Path, PathBuf};

use robokey::protocol::auth::PairingSecret;
use robokey_secrecy::BitString;
use robokey_secrecy::postprocess::{
    ControllerSnapshot, FinalKey, InFlight, RobotSnapshot, SessionSamples, StagedSession,
};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use zeroize::Zeroizing;

use crate::error::NetError;
use crate::journal::Journal;
use crate::key_store::{KeyLabels, KeyStatus, KeyStore, Stored, StoredKey, create_private_dir};
use crate::owned_file::{self, WRITABLE_BY_OTHERS};
use crate::store_keys::StoreKeys;

/// Why a controller's committed key is pending.
const AWAITING_COMMIT_ACK: &str = "committed here; the robot's acknowledgement (CommitAck) \
                                   has not arrived";
/// Why a robot's prepared key is pending.
const AWAITING_COMMIT: &str = "prepared here; the controller's Commit has not arrived";
/// Why a pending key the journal does not know stays pending.
const SUPERSEDED: &str = "left pending by a journal that was since removed or restored from \
                          an older copy: whether the peer acknowledged it can no longer be \
                          told, so it is never delivered (remove the file once checked)";

/// A block whose key awaits the peer.
#[derive(Debug)]
pub struct Unsettled<'a> {
    /// The block.
    pub block: u64,
    /// Its key, when the durable state holds it (the robot's prepared key).
    pub key: Option<&'a FinalKey>,
    /// Why it is pending.
    pub reason: &'static str,
}

/// A post-processing endpoint's durable state.
pub trait Snapshot: Serialize + DeserializeOwned {
    /// The store's role name: `robot` or `controller`.
    const ROLE: &'static str;
    /// The pooled sessions.
    fn pool(&self) -> &[(u32, BitString)];
    /// The pooled sessions and the spent session IDs, to change.
    fn ledger_mut(&mut self) -> (&mut Vec<(u32, BitString)>, &mut Vec<u32>);
    /// The block whose key awaits the peer here, if any.
    fn unsettled(&self) -> Option<Unsettled<'_>>;
    /// Whether `block`'s key was committed here.
    fn committed(&self, block: u64) -> bool;
    /// Whether `block` ended here without a key after its key was prepared.
    fn aborted(&self, block: u64) -> bool;

    /// Takes the pooled sessions out of the snapshot.
    fn take_pool(&mut self) -> Vec<(u32, BitString)> {
        std::mem::take(self.ledger_mut().0)
    }
    /// Puts them back.
    fn set_pool(&mut self, pool: Vec<(u32, BitString)>) {
        *self.ledger_mut().0 = pool;
    }
    /// Takes out what the pool keeps of its sessions beside their bits (a controller's
    /// samples and LLRs; nothing otherwise).
    fn take_extras(&mut self) -> BTreeMap<u32, SessionExtras> {
        BTreeMap::new()
    }
    /// Puts them back.
    fn set_extras(&mut self, _extras: BTreeMap<u32, SessionExtras>) {}
    /// Marks `sessions` spent, dropping those pooled; returns how many were.
    fn spend(&mut self, sessions: &BTreeSet<u32>) -> usize {
        let (pool, spent) = self.ledger_mut();
        spend_in(pool, spent, sessions)
    }
}

/// What a controller's pool keeps of a session beside its bits, journaled once with them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SessionExtras {
    /// The samples for the block's estimate (measured sizing) or commands check (configured).
    pub samples: Option<SessionSamples>,
    /// The quantised LLR of each bit (LDPC reconciliation).
    pub llrs: Option<Vec<i16>>,
    /// A multilevel slice with a slice after it: what the next slice needs
    /// (docs/postprocessing.md, "Multilevel slices").
    pub staged: Option<StagedSession>,
}

/// Drops `sessions` from `pool` and adds them to `spent`; how many were pooled.
fn spend_in(
    pool: &mut Vec<(u32, BitString)>,
    spent: &mut Vec<u32>,
    sessions: &BTreeSet<u32>,
) -> usize {
    let before = pool.len();
    pool.retain(|(id, _)| !sessions.contains(id));
    spent.extend(sessions);
    spent.sort_unstable();
    spent.dedup();
    before - pool.len()
}

impl Snapshot for RobotSnapshot {
    const ROLE: &'static str = "robot";
    fn pool(&self) -> &[(u32, BitString)] {
        &self.pool
    }
    fn ledger_mut(&mut self) -> (&mut Vec<(u32, BitString)>, &mut Vec<u32>) {
        (&mut self.pool, &mut self.spent)
    }
    fn unsettled(&self) -> Option<Unsettled<'_>> {
        self.prepared.as_ref().map(|p| Unsettled {
            block: p.block,
            key: Some(&p.key),
            reason: AWAITING_COMMIT,
        })
    }
    fn committed(&self, block: u64) -> bool {
        self.committed.contains(&block)
    }
    fn aborted(&self, block: u64) -> bool {
        !self.committed(block)
            && self.prepared.as_ref().is_none_or(|p| p.block != block)
            && self.highest_block.is_some_and(|h| h >= block)
    }
}

impl Snapshot for ControllerSnapshot {
    const ROLE: &'static str = "controller";
    fn pool(&self) -> &[(u32, BitString)] {
        &self.pool
    }
    fn ledger_mut(&mut self) -> (&mut Vec<(u32, BitString)>, &mut Vec<u32>) {
        (&mut self.pool, &mut self.spent)
    }
    /// Also forgets the spent sessions' Eve separations, kept samples and LLRs.
    fn spend(&mut self, sessions: &BTreeSet<u32>) -> usize {
        self.separations.retain(|(id, _)| !sessions.contains(id));
        self.separation_counts
            .retain(|(id, _)| !sessions.contains(id));
        self.samples.retain(|(id, _)| !sessions.contains(id));
        self.llrs.retain(|(id, _)| !sessions.contains(id));
        self.staged.retain(|(id, _)| !sessions.contains(id));
        spend_in(&mut self.pool, &mut self.spent, sessions)
    }
    fn take_extras(&mut self) -> BTreeMap<u32, SessionExtras> {
        let mut extras: BTreeMap<u32, SessionExtras> = BTreeMap::new();
        for (id, samples) in std::mem::take(&mut self.samples) {
            extras.entry(id).or_default().samples = Some(samples);
        }
        for (id, llrs) in std::mem::take(&mut self.llrs) {
            extras.entry(id).or_default().llrs = Some(llrs);
        }
        for (id, staged) in std::mem::take(&mut self.staged) {
            extras.entry(id).or_default().staged = Some(staged);
        }
        extras
    }
    fn set_extras(&mut self, extras: BTreeMap<u32, SessionExtras>) {
        self.samples = extras
            .iter()
            .filter_map(|(&id, e)| e.samples.clone().map(|s| (id, s)))
            .collect();
        self.llrs = extras
            .iter()
            .filter_map(|(&id, e)| e.llrs.clone().map(|l| (id, l)))
            .collect();
        self.staged = extras
            .into_iter()
            .filter_map(|(id, e)| e.staged.map(|s| (id, s)))
            .collect();
    }
    fn unsettled(&self) -> Option<Unsettled<'_>> {
        match self.in_flight {
            Some(InFlight::Committed { block, .. }) => Some(Unsettled {
                block,
                key: None,
                reason: AWAITING_COMMIT_ACK,
            }),
            _ => None,
        }
    }
    fn committed(&self, block: u64) -> bool {
        self.committed.contains(&block)
    }
    /// A controller never aborts a block it committed.
    fn aborted(&self, _block: u64) -> bool {
        false
    }
}

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
        /// What the controller keeps of the session for the block's estimate (absent when
        /// nothing is kept). A three-step doublet's sample after its second step and entry
        /// speed (`late`) are absent from records written before they were kept: such a
        /// session reads unchanged and is sized from its three samples.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        samples: Option<SessionSamples>,
        /// The controller's quantised LLR of each bit (absent when it keeps none).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        llrs: Option<Vec<i16>>,
        /// A multilevel slice's staged material (absent for binary sessions and last
        /// slices; journals written before it read without).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        staged: Option<StagedSession>,
    },
    State {
        snapshot: S,
        pooled: Vec<u32>,
        keys: Vec<StoredKey>,
        pending: Vec<String>,
    },
}

/// What opening a store found and repaired, for the reports.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct StoreRecovery {
    /// Bytes of a torn journal tail that were cut (a crash during an append).
    pub torn_bytes: u64,
    /// Committed (or prepared) keys written to `keys/` only now (a crash came between).
    pub keys_recovered: usize,
    /// Pending keys the durable state had settled, settled only now.
    pub keys_settled: usize,
    /// Pending prepared keys of blocks the durable state had aborted, removed only now.
    pub pending_removed: usize,
    /// Pending keys the journal does not know (it was removed or restored from an older copy),
    /// marked so and never settled.
    pub pending_superseded: usize,
    /// Pooled sessions dropped because a stored key already lists them as a source (the
    /// journal was restored from an older copy).
    pub sessions_already_spent: usize,
}

/// What opening a store recovered.
#[derive(Debug)]
pub struct Recovery<S> {
    /// The durable state, pool included (`None` for a new store).
    pub snapshot: Option<S>,
    /// What was found and repaired.
    pub figures: StoreRecovery,
}

/// A key pending in a store, for the reports.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct PendingKey {
    /// Its ID.
    pub id: String,
    /// Its block.
    pub block: u64,
    /// Why it is pending.
    pub reason: String,
}

/// An open store, locked against any other process for its life.
#[derive(Debug)]
pub struct PostStore<S> {
    dir: PathBuf,
    fingerprint: String,
    labels: KeyLabels,
    _lock: File,
    journal: Journal,
    keys: KeyStore,
    /// Sessions with a `session` record in the journal.
    journaled: BTreeSet<u32>,
    /// Sessions that stored keys list as sources: never pooled again.
    sources: BTreeSet<u32>,
    /// Pending keys in `keys/`, by ID.
    pending: BTreeMap<String, PendingKey>,
    _snapshot: std::marker::PhantomData<S>,
}

impl<S: Snapshot> PostStore<S> {
    /// Opens (creating) the store at `dir` for `S::ROLE` and `pairing`, recovers its state
    /// and compacts it. Keys committed through it carry `labels` (restricted or not, and
    /// what they rest on).
    ///
    /// # Errors
    /// Another process holds the store; it belongs to the other role or another pairing; a
    /// folder or file is a link, another user's or open to others; the journal or a key file
    /// does not authenticate (named); a file operation fails.
    pub fn open(
        dir: &Path,
        pairing: &PairingSecret,
        labels: KeyLabels,
    ) -> Result<(Self, Recovery<S>), NetError> {
        create_private_dir(dir)?;
        owned_file::check_folder(dir, "store")?;
        let secrets = StoreKeys::new(pairing, S::ROLE);
        let keys = KeyStore::create(dir, &secrets.key_files, S::ROLE)?;
        let lock = lock_store(dir)?;
        let fingerprint = pairing.fingerprint();
        let owner = format!("{} {fingerprint}", S::ROLE);
        let path = dir.join("journal");
        let header = encode(&Record::<S>::Header {
            role: S::ROLE.to_owned(),
            pairing: fingerprint.clone(),
        });
        let (journal, contents) = match Journal::open(&path, &secrets.journal, &owner)? {
            Some((journal, contents)) => (journal, Some(contents)),
            None => (
                Journal::create(
                    &path,
                    &secrets.journal,
                    &owner,
                    std::slice::from_ref(&header),
                )?,
                None,
            ),
        };
        let mut store = Self {
            dir: dir.to_owned(),
            fingerprint: fingerprint.clone(),
            labels,
            _lock: lock,
            journal,
            keys,
            journaled: BTreeSet::new(),
            sources: BTreeSet::new(),
            pending: BTreeMap::new(),
            _snapshot: std::marker::PhantomData,
        };
        let mut found = BTreeMap::new();
        for key in store.keys.list()? {
            store.sources.extend(&key.sessions);
            if let KeyStatus::Pending(reason) = &key.status {
                found.insert(key.id.clone(), pending_key(&key, reason));
            }
        }
        let mut figures = StoreRecovery::default();
        let Some(contents) = contents else {
            figures.pending_superseded = store.supersede(found.keys())?;
            return Ok((
                store,
                Recovery {
                    snapshot: None,
                    figures,
                },
            ));
        };
        figures.torn_bytes = contents.torn_bytes;
        let mut sessions = BTreeMap::new();
        let mut state = None;
        for (i, payload) in contents.records.iter().enumerate() {
            let record: Record<S> = serde_json::from_slice(payload)
                .map_err(|e| store.corrupt(format!("record {i} is malformed: {e}")))?;
            match record {
                Record::Header { role, pairing } if i == 0 => {
                    if (role.as_str(), pairing.as_str()) != (S::ROLE, fingerprint.as_str()) {
                        return Err(store.corrupt(format!(
                            "its header names the {role} of pairing {pairing}, not this {} of \
                             pairing {fingerprint}",
                            S::ROLE
                        )));
                    }
                }
                Record::Header { .. } => {
                    return Err(store.corrupt(format!("record {i} is a second header")));
                }
                _ if i == 0 => return Err(store.corrupt("it does not begin with a header".into())),
                Record::Session {
                    id,
                    bits,
                    samples,
                    llrs,
                    staged,
                } => {
                    let kept = samples.as_ref().map_or(0, Vec::len);
                    if kept > bits.len() {
                        return Err(store.corrupt(format!(
                            "session {id}'s record keeps samples of {kept} doublets for its {} \
                             raw bits (allowed: at most one doublet per bit)",
                            bits.len()
                        )));
                    }
                    let late = samples
                        .as_ref()
                        .map_or(0, |s| s.iter().filter(|k| k.late.is_some()).count());
                    if late != 0 && late != kept {
                        return Err(store.corrupt(format!(
                            "session {id}'s record keeps the sample after the second step \
                             (samples[].late) of {late} of its {kept} doublets (allowed: all \
                             of them, three-step doublets, or none)"
                        )));
                    }
                    if let Some(llrs) = llrs.as_ref().filter(|l| l.len() != bits.len()) {
                        return Err(store.corrupt(format!(
                            "session {id}'s record keeps {} LLRs for its {} raw bits \
                             (allowed: one per bit)",
                            llrs.len(),
                            bits.len()
                        )));
                    }
                    if let Some(problem) = staged.as_ref().and_then(|s| {
                        s.check().err().or_else(|| {
                            (s.slice_bits() != bits.len()).then(|| {
                                format!("{} bits for its slice of {}", bits.len(), s.slice_bits())
                            })
                        })
                    }) {
                        return Err(store.corrupt(format!(
                            "session {id}'s record keeps staged slices that do not fit: \
                             {problem}"
                        )));
                    }
                    sessions.insert(
                        id,
                        (
                            bits,
                            SessionExtras {
                                samples,
                                llrs,
                                staged,
                            },
                        ),
                    );
                }
                Record::State {
                    snapshot,
                    pooled,
                    keys,
                    pending,
                } => state = Some((snapshot, pooled, keys, pending)),
            }
        }
        let Some((mut snapshot, pooled, carried, known)) = state else {
            figures.pending_superseded = store.supersede(found.keys())?;
            store.journal.rewrite(&[header])?;
            return Ok((
                store,
                Recovery {
                    snapshot: None,
                    figures,
                },
            ));
        };
        let mut kept = BTreeMap::new();
        let pool = pooled
            .iter()
            .map(|id| {
                let (bits, extras) = sessions.remove(id).ok_or_else(|| {
                    store.corrupt(format!("session {id} is pooled but its bits are missing"))
                })?;
                if extras != SessionExtras::default() {
                    kept.insert(*id, extras);
                }
                Ok((*id, bits))
            })
            .collect::<Result<Vec<_>, NetError>>()?;
        snapshot.set_pool(pool);
        snapshot.set_extras(kept);
        store.pending = found
            .iter()
            .filter(|(id, _)| known.contains(id))
            .map(|(id, key)| (id.clone(), key.clone()))
            .collect();
        let written = store.write_keys(&snapshot, &carried)?;
        figures.keys_recovered = written.written;
        figures.keys_settled = written.settled;
        figures.pending_removed = written.removed;
        let unknown: Vec<&String> = found
            .keys()
            .filter(|id| !store.pending.contains_key(*id) && !carried.iter().any(|k| &k.id == *id))
            .collect();
        figures.pending_superseded = store.supersede(unknown)?;
        figures.sessions_already_spent = snapshot.spend(&store.sources.clone());
        store.compact(&mut snapshot)?;
        Ok((
            store,
            Recovery {
                snapshot: Some(snapshot),
                figures,
            },
        ))
    }

    /// The store's folder.
    #[must_use]
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The sessions stored keys list as sources: they are never pooled again.
    #[must_use]
    pub fn sources(&self) -> &BTreeSet<u32> {
        &self.sources
    }

    /// The keys pending in the store, by block.
    #[must_use]
    pub fn pending(&self) -> Vec<PendingKey> {
        let mut pending: Vec<PendingKey> = self.pending.values().cloned().collect();
        pending.sort_by_key(|p| p.block);
        pending
    }

    /// Stores `snapshot` with the keys committed in the same batch, then brings `keys/` in
    /// line with it: the new sessions' bits first, then the state that names them and carries
    /// the keys, then the key files (pending while the state says the peer has not
    /// acknowledged; settled or removed when it says so), then the state without the keys.
    /// Returns the committed keys as stored.
    ///
    /// # Errors
    /// A write fails, or a key's name is taken by something this store did not write (the
    /// last durable state is then the one before, or the one that carries the keys, which the
    /// next opening writes).
    pub fn persist(
        &mut self,
        snapshot: &mut S,
        committed: &[FinalKey],
    ) -> Result<Vec<StoredKey>, NetError> {
        let pool = snapshot.take_pool();
        let extras = snapshot.take_extras();
        let stored = self.persist_pool(snapshot, &pool, &extras, committed);
        snapshot.set_pool(pool);
        snapshot.set_extras(extras);
        stored
    }

    fn persist_pool(
        &mut self,
        snapshot: &S,
        pool: &[(u32, BitString)],
        extras: &BTreeMap<u32, SessionExtras>,
        committed: &[FinalKey],
    ) -> Result<Vec<StoredKey>, NetError> {
        for (id, bits) in pool {
            if !self.journaled.contains(id) {
                let extra = extras.get(id).cloned().unwrap_or_default();
                self.journal.append(&encode(&Record::<S>::Session {
                    id: *id,
                    bits: bits.clone(),
                    samples: extra.samples,
                    llrs: extra.llrs,
                    staged: extra.staged,
                }))?;
                self.journaled.insert(*id);
            }
        }
        let pooled: Vec<u32> = pool.iter().map(|(id, _)| *id).collect();
        let stored: Vec<StoredKey> = committed
            .iter()
            .map(|key| StoredKey::new(key, S::ROLE, &self.labels, status(snapshot, key.block)))
            .collect();
        self.journal.append(&encode_state(
            snapshot,
            &pooled,
            &stored,
            &self.pending_ids(),
        ))?;
        let changed = self.write_keys(snapshot, &stored)?;
        if !stored.is_empty() || changed.any() {
            self.journal
                .append(&encode_state(snapshot, &pooled, &[], &self.pending_ids()))?;
        }
        Ok(stored)
    }

    /// Brings `keys/` in line with `snapshot`: stores `carried` (the keys its batch
    /// committed) and the key it holds pending, settles the pending keys whose block it
    /// committed, removes those whose block it aborted.
    fn write_keys(&mut self, snapshot: &S, carried: &[StoredKey]) -> Result<KeyChanges, NetError> {
        let mut changes = KeyChanges::default();
        let unsettled = snapshot.unsettled();
        let held = unsettled.as_ref().and_then(|u| {
            u.key
                .map(|key| StoredKey::new(key, S::ROLE, &self.labels, status(snapshot, key.block)))
        });
        for key in carried.iter().chain(&held) {
            let mut key = key.clone();
            key.status = status(snapshot, key.block);
            match self.keys.store(&key)? {
                Stored::Written => changes.written += 1,
                Stored::Settled => changes.settled += 1,
                Stored::Present => {}
            }
            self.sources.extend(&key.sessions);
            self.pending.remove(&key.id);
            if let KeyStatus::Pending(reason) = &key.status {
                self.pending
                    .insert(key.id.clone(), pending_key(&key, reason));
            }
        }
        let waiting = unsettled.map(|u| u.block);
        for (id, pending) in self.pending.clone() {
            if waiting == Some(pending.block) {
                continue;
            }
            if snapshot.committed(pending.block) {
                match self.keys.restate(&id, KeyStatus::Settled) {
                    Ok(()) => changes.settled += 1,
                    // A pending key removed by hand is forgotten, not written again.
                    Err(NetError::Usage(_)) => {}
                    Err(error) => return Err(error),
                }
            } else if snapshot.aborted(pending.block) {
                self.keys.remove_pending(&id)?;
                changes.removed += 1;
            } else {
                continue;
            }
            self.pending.remove(&id);
        }
        Ok(changes)
    }

    /// Marks the pending keys `ids` superseded (unless they are so already): the journal does
    /// not know them, so nothing will ever settle them. Returns how many changed.
    fn supersede<'a>(&self, ids: impl IntoIterator<Item = &'a String>) -> Result<usize, NetError> {
        let mut changed = 0;
        for id in ids {
            if self.keys.get(id)?.status != KeyStatus::Pending(SUPERSEDED.to_owned()) {
                self.keys
                    .restate(id, KeyStatus::Pending(SUPERSEDED.to_owned()))?;
                changed += 1;
            }
        }
        Ok(changed)
    }

    /// Rewrites the journal with only what `snapshot` needs: the header, the pooled sessions'
    /// bits, and the state.
    ///
    /// # Errors
    /// The rewrite fails (the old journal is then intact).
    pub fn compact(&mut self, snapshot: &mut S) -> Result<(), NetError> {
        let pool = snapshot.take_pool();
        let extras = snapshot.take_extras();
        let pooled: Vec<u32> = pool.iter().map(|(id, _)| *id).collect();
        let mut records = vec![encode(&Record::<S>::Header {
            role: S::ROLE.to_owned(),
            pairing: self.fingerprint.clone(),
        })];
        records.extend(pool.iter().map(|(id, bits)| {
            let extra = extras.get(id).cloned().unwrap_or_default();
            encode(&Record::<S>::Session {
                id: *id,
                bits: bits.clone(),
                samples: extra.samples,
                llrs: extra.llrs,
                staged: extra.staged,
            })
        }));
        records.push(encode_state(snapshot, &pooled, &[], &self.pending_ids()));
        snapshot.set_pool(pool);
        snapshot.set_extras(extras);
        self.journal.rewrite(&records)?;
        self.journaled = pooled.into_iter().collect();
        Ok(())
    }

    fn pending_ids(&self) -> Vec<String> {
        self.pending.keys().cloned().collect()
    }

    fn corrupt(&self, message: String) -> NetError {
        NetError::Store {
            path: self.dir.join("journal").display().to_string(),
            message,
        }
    }
}

/// What [`PostStore::write_keys`] changed in `keys/`.
#[derive(Debug, Default)]
struct KeyChanges {
    written: usize,
    settled: usize,
    removed: usize,
}

impl KeyChanges {
    fn any(&self) -> bool {
        self.written + self.settled + self.removed > 0
    }
}

/// The status `snapshot` gives a committed key of `block`.
fn status<S: Snapshot>(snapshot: &S, block: u64) -> KeyStatus {
    match snapshot.unsettled() {
        Some(u) if u.block == block => KeyStatus::Pending(u.reason.to_owned()),
        _ => KeyStatus::Settled,
    }
}

fn pending_key(key: &StoredKey, reason: &str) -> PendingKey {
    PendingKey {
        id: key.id.clone(),
        block: key.block,
        reason: reason.to_owned(),
    }
}

fn encode<S: Serialize>(record: &Record<S>) -> Zeroizing<Vec<u8>> {
    Zeroizing::new(serde_json::to_vec(record).expect("a record always serialises"))
}

/// A `state` record: the snapshot, the sessions pooled, the keys its batch committed, and
/// the IDs of the keys pending in `keys/`.
fn encode_state<S: Serialize>(
    snapshot: &S,
    pooled: &[u32],
    keys: &[StoredKey],
    pending: &[String],
) -> Zeroizing<Vec<u8>> {
    #[derive(Serialize)]
    #[serde(tag = "record", rename = "state")]
    struct State<'a, S> {
        snapshot: &'a S,
        pooled: &'a [u32],
        keys: &'a [StoredKey],
        pending: &'a [String],
    }
    Zeroizing::new(
        serde_json::to_vec(&State {
            snapshot,
            pooled,
            keys,
            pending,
        })
        .expect("a state always serialises"),
    )
}

/// Takes the lock of the store at `dir` without waiting: agents hold it for their life,
/// `keys delete` for its change. The lock file is opened without following a link and never
/// truncated.
///
/// # Errors
/// Another process holds it; the lock file is a link, not a regular file, another user's or
/// writable by others; it cannot be created.
pub fn lock_store(dir: &Path) -> Result<File, NetError> {
    let path = dir.join("lock");
    let mut options = OpenOptions::new();
    options.write(true).create(true);
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    let file = owned_file::open(&path, &mut options, "lock file")?;
    owned_file::check_file(&file, &path, "lock file", WRITABLE_BY_OTHERS)?;
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

/// The key folder of the existing store at `dir`, for `pairing`: its role is read from the
/// journal's first line and proved by every key file's MAC.
///
/// # Errors
/// No store or journal there; the store belongs to another pairing; a folder or the journal
/// is a link, another user's or open to others.
pub fn open_keys(dir: &Path, pairing: &PairingSecret) -> Result<KeyStore, NetError> {
    let path = dir.join("journal");
    let file =
        owned_file::open(&path, OpenOptions::new().read(true), "journal").map_err(|e| match e {
            NetError::Io { error, .. } if error.kind() == std::io::ErrorKind::NotFound => {
                NetError::Usage(format!(
                    "{} is not a store (no journal; agents create one with --store)",
                    dir.display()
                ))
            }
            other => other,
        })?;
    owned_file::check_file(&file, &path, "journal", owned_file::ANY_ACCESS_BY_OTHERS)?;
    let mut line = String::new();
    BufReader::new(file.take(200))
        .read_line(&mut line)
        .map_err(NetError::io(format!("read {}", path.display())))?;
    let owner = line.trim_end().strip_prefix("robokey-journal-v2 ");
    let Some((role, fingerprint)) = owner.and_then(|o| o.split_once(' ')) else {
        return Err(NetError::Store {
            path: path.display().to_string(),
            message: "not a robokey-journal-v2 journal".into(),
        });
    };
    let role = match role {
        "robot" => "robot",
        "controller" => "controller",
        other => {
            return Err(NetError::Store {
                path: path.display().to_string(),
                message: format!("names the role {other:?}"),
            });
        }
    };
    if fingerprint != pairing.fingerprint() {
        return Err(NetError::Usage(format!(
            "store {} belongs to the pairing with fingerprint {fingerprint}, not to this one ({}): \
             pass the pairing file its agents use",
            dir.display(),
            pairing.fingerprint()
        )));
    }
    KeyStore::open(dir, &StoreKeys::new(pairing, role).key_files, role)
}

#[cfg(test)]
mod tests;
