//! The store against crashes, rollbacks and an attacker who can write beside it.

use std::os::unix::fs::PermissionsExt as _;

use robokey_secrecy::postprocess::Prepared;

use super::*;
use crate::journal::tests::tempdir;

fn pairing(seed: u8) -> PairingSecret {
    PairingSecret::from_bytes(&[seed; 32])
}

fn open<S: Snapshot>(dir: &Path, seed: u8) -> Result<(PostStore<S>, Recovery<S>), NetError> {
    let labels = KeyLabels {
        restricted: true,
        basis: None,
    };
    PostStore::open(dir, &pairing(seed), labels)
}

fn controller(pool: &[(u32, bool)], committed: &[u64]) -> ControllerSnapshot {
    ControllerSnapshot {
        next_block: committed.len() as u64,
        pool: pool
            .iter()
            .map(|&(id, bit)| (id, BitString::from_bools(&[bit; 100])))
            .collect(),
        separations: Vec::new(),
        separation_counts: Vec::new(),
        samples: Vec::new(),
        llrs: Vec::new(),
        staged: Vec::new(),
        spent: Vec::new(),
        in_flight: None,
        committed: committed.to_vec(),
    }
}

fn key(block: u64, sessions: &[u32]) -> FinalKey {
    FinalKey {
        id: format!("{block:016x}"),
        block,
        key: BitString::from_bools(&[true, false, true]),
        sessions: sessions.to_vec(),
        epsilon: 4e-6,
        assumption: "stated".into(),
        reconciliation: None,
    }
}

fn keys_of(dir: &Path, seed: u8) -> KeyStore {
    open_keys(dir, &pairing(seed)).unwrap()
}

/// The journal's records after a crash that undid its last `n` appends.
fn undo_last_appends<S: Snapshot>(dir: &Path, n: usize) {
    let secrets = StoreKeys::new(&pairing(1), S::ROLE);
    let owner = format!("{} {}", S::ROLE, pairing(1).fingerprint());
    let path = dir.join("journal");
    let (mut journal, contents) = Journal::open(&path, &secrets.journal, &owner)
        .unwrap()
        .unwrap();
    let kept = contents.records.len() - n;
    journal.rewrite(&contents.records[..kept]).unwrap();
}

#[test]
fn the_pool_and_state_survive_reopening_and_the_store_is_exclusive() {
    let dir = tempdir("post-store");
    let (mut store, recovery) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    assert!(recovery.snapshot.is_none());
    let mut state = controller(&[(1, true), (2, false)], &[]);
    store.persist(&mut state, &[]).unwrap();
    // A second process is refused while the first holds the store.
    let error = open::<ControllerSnapshot>(&dir, 1).unwrap_err();
    assert!(error.to_string().contains("in use"), "{error}");
    drop(store);
    let (_, recovery) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    assert_eq!(recovery.snapshot, Some(state));
    assert_eq!(recovery.figures, StoreRecovery::default());
    // The other role and another pairing are refused, naming what differs.
    let error = open::<RobotSnapshot>(&dir, 1).unwrap_err().to_string();
    assert!(error.contains("belongs to `controller"), "{error}");
    let error = open::<ControllerSnapshot>(&dir, 2).unwrap_err().to_string();
    assert!(error.contains(&pairing(1).fingerprint()), "{error}");
    let error = open_keys(&dir, &pairing(2)).unwrap_err().to_string();
    assert!(error.contains("belongs to the pairing"), "{error}");
}

/// A controller reconciling by LDPC keeps each pooled session's quantised LLRs: journaled
/// once with the session's bits, restored on opening, kept through compaction, and forgotten
/// with the session once spent.
#[test]
fn the_pooled_sessions_llrs_survive_reopening_and_compaction() {
    let mut state = controller(&[(1, true), (2, false)], &[]);
    state.llrs = vec![(1, vec![-512; 100]), (2, vec![300; 100])];
    let restored = reopen_spend_and_compact("post-store-llrs", &mut state, 1);
    assert_eq!(restored.llrs, vec![(2, vec![300; 100])]);
}

/// Persists `state` in a fresh store, checks that reopening restores it, spends session
/// `spent`, compacts, reopens again and checks the snapshot equals `state`; returns it.
fn reopen_spend_and_compact(
    name: &str,
    state: &mut ControllerSnapshot,
    spent: u32,
) -> ControllerSnapshot {
    let dir = tempdir(name);
    let (mut store, _) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    store.persist(state, &[]).unwrap();
    drop(store);
    let (mut store, recovery) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    assert_eq!(recovery.snapshot.as_ref(), Some(&*state));
    state.spend(&BTreeSet::from([spent]));
    store.persist(state, &[]).unwrap();
    store.compact(state).unwrap();
    drop(store);
    let (_, recovery) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    let restored = recovery.snapshot.unwrap();
    assert_eq!(&restored, &*state);
    restored
}

/// `n` kept doublets, each with a sample after its second step when `late`.
fn kept_doublets(n: u32, late: bool) -> robokey_secrecy::postprocess::SessionSamples {
    use robokey_secrecy::postprocess::{KeptDoublet, KeptLate};
    (0..n)
        .map(|doublet| KeptDoublet {
            doublet,
            inputs: [[0.1, 0.2], [0.1, -0.2]],
            samples: [[f64::from(doublet), 0.5, 0.25]; 3],
            late: late.then_some(KeptLate {
                sample: [f64::from(doublet), 0.75, 0.125],
                entry: [0.1, 0.05],
            }),
        })
        .collect()
}

/// Three-step doublets' samples after their second step and entry speeds are journaled
/// with the session and restored; a journal written before they were kept (its session
/// records' doublets without `late`) still reads, each doublet's three samples as they were
/// and no later sample; a record that keeps it for some of a session's doublets only is
/// refused, naming the field.
#[test]
fn three_step_samples_survive_reopening_and_older_records_still_read() {
    let mut state = controller(&[(1, true), (2, false)], &[]);
    state.samples = vec![(1, kept_doublets(100, true)), (2, kept_doublets(100, true))];
    let restored = reopen_spend_and_compact("post-store-late", &mut state, 1);
    assert_eq!(restored.samples, vec![(2, kept_doublets(100, true))]);
    // The format before: the same journal with every `late` field taken out.
    let dir = tempdir("post-store-late-older");
    let (mut store, _) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    let mut state = controller(&[(1, true), (2, false)], &[]);
    state.samples = vec![(1, kept_doublets(100, true)), (2, kept_doublets(100, true))];
    store.persist(&mut state, &[]).unwrap();
    drop(store);
    let secrets = StoreKeys::new(&pairing(1), "controller");
    let owner = format!("controller {}", pairing(1).fingerprint());
    let path = dir.join("journal");
    let (mut journal, contents) = Journal::open(&path, &secrets.journal, &owner)
        .unwrap()
        .unwrap();
    let mut stripped = 0;
    let older: Vec<Zeroizing<Vec<u8>>> = contents
        .records
        .iter()
        .map(|payload| {
            let mut record: serde_json::Value = serde_json::from_slice(payload).unwrap();
            if let Some(samples) = record.get_mut("samples").and_then(|s| s.as_array_mut()) {
                for doublet in samples {
                    let fields = doublet.as_object_mut().unwrap();
                    stripped += usize::from(fields.remove("late").is_some());
                    let names: Vec<&str> = fields.keys().map(String::as_str).collect();
                    assert_eq!(names, ["doublet", "inputs", "samples"]);
                }
            }
            Zeroizing::new(serde_json::to_vec(&record).unwrap())
        })
        .collect();
    assert_eq!(stripped, 200);
    journal.rewrite(&older).unwrap();
    drop(journal);
    let (_, recovery) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    let read = recovery.snapshot.unwrap();
    assert_eq!(
        read.samples,
        vec![
            (1, kept_doublets(100, false)),
            (2, kept_doublets(100, false))
        ]
    );
    // Some doublets of a session with the later sample, some without: refused by name.
    let dir = tempdir("post-store-late-mixed");
    let (mut store, _) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    let mut state = controller(&[(5, true)], &[]);
    let mut mixed = kept_doublets(100, true);
    mixed[7].late = None;
    state.samples = vec![(5, mixed)];
    store.persist(&mut state, &[]).unwrap();
    drop(store);
    let error = open::<ControllerSnapshot>(&dir, 1).unwrap_err().to_string();
    assert!(
        error.contains("session 5's record keeps the sample after the second step")
            && error.contains("samples[].late")
            && error.contains("99 of its 100"),
        "{error}"
    );
}

/// A multilevel slice's staged material (docs/postprocessing.md, "Multilevel slices") is
/// journaled once with its bits, restored on opening, kept through compaction and
/// forgotten once spent; a record whose material does not fit its bits is refused by name.
#[test]
fn staged_slices_survive_reopening_and_compaction_and_must_fit() {
    use robokey_secrecy::postprocess::{Slicing, StagedSession};
    // Sessions of 100 bits at slice 0 of two: 200 bits, 50 doublets of 4 bits.
    let staged = |session: u32| StagedSession {
        session,
        slice: 0,
        slicing: Slicing::new(4, 2).unwrap(),
        likelihoods: vec![-100; 50 * 16],
        separations: vec![1.5; 200],
        known: BitString::zeros(200),
        samples: Vec::new(),
    };
    let mut state = controller(&[(1, true), (2, false)], &[]);
    state.staged = vec![(1, staged(1)), (2, staged(2))];
    let restored = reopen_spend_and_compact("post-store-staged", &mut state, 1);
    assert_eq!(restored.staged, vec![(2, staged(2))]);
    // Material for 300 bits beside a slice of 100: refused, naming the session.
    let dir = tempdir("post-store-staged-misfit");
    let (mut store, _) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    let mut state = controller(&[(5, true)], &[]);
    let mut misfit = staged(5);
    misfit.known = BitString::zeros(300);
    misfit.separations = vec![1.5; 300];
    misfit.likelihoods = vec![0; 75 * 16];
    state.staged = vec![(5, misfit)];
    store.persist(&mut state, &[]).unwrap();
    drop(store);
    let error = open::<ControllerSnapshot>(&dir, 1).unwrap_err().to_string();
    assert!(
        error.contains("session 5's record keeps staged slices that do not fit"),
        "{error}"
    );
}

/// A crash after the state that carries a committed key and before its key file: the
/// store writes the key when it opens. Then compaction drops spent bits.
#[test]
fn a_committed_key_whose_file_a_crash_prevented_is_written_on_opening() {
    let dir = tempdir("post-store-crash");
    let (mut store, _) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    let mut state = controller(&[(3, true)], &[0]);
    let stored = store.persist(&mut state, &[key(0, &[1, 2])]).unwrap();
    assert_eq!(stored[0].hex, "a0");
    assert!(stored[0].restricted && stored[0].is_settled());
    drop(store);
    // Undo the key file and the state record that followed it, as a crash would.
    undo_last_appends::<ControllerSnapshot>(&dir, 1);
    keys_of(&dir, 1).delete(&key(0, &[]).id).unwrap();
    let (mut store, recovery) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    assert_eq!(recovery.figures.keys_recovered, 1);
    let recovered = keys_of(&dir, 1).settled(&key(0, &[]).id).unwrap();
    assert_eq!((recovered.hex.as_str(), recovered.block), ("a0", 0));
    // The pool emptied (a block took the session): its bits leave the journal.
    let mut state = recovery.snapshot.unwrap();
    state.pool.clear();
    store.persist(&mut state, &[]).unwrap();
    store.compact(&mut state).unwrap();
    drop(store);
    let (_, recovery) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    assert_eq!(recovery.figures.keys_recovered, 0);
    assert!(recovery.snapshot.unwrap().pool.is_empty());
}

/// The controller's key is pending from its commit to the robot's `CommitAck`, also across
/// a crash; withheld from delivery meanwhile.
#[test]
fn the_controllers_key_is_pending_until_the_robot_acknowledges() {
    let dir = tempdir("post-store-pending");
    let (mut store, _) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    let mut state = controller(&[], &[0]);
    state.in_flight = Some(InFlight::Committed {
        block: 0,
        sessions: vec![1, 2],
    });
    store.persist(&mut state, &[key(0, &[1, 2])]).unwrap();
    let id = key(0, &[]).id;
    let error = keys_of(&dir, 1).settled(&id).unwrap_err();
    assert!(matches!(error, NetError::Pending(_)), "{error}");
    assert!(error.to_string().contains("CommitAck"), "{error}");
    assert_eq!(store.pending().len(), 1);
    drop(store);
    // Across a restart the state still awaits the acknowledgement: still pending.
    let (mut store, recovery) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    assert_eq!(store.pending()[0].id, id);
    let mut state = recovery.snapshot.unwrap();
    // The acknowledgement: the block leaves flight, and the key settles.
    state.in_flight = None;
    store.persist(&mut state, &[]).unwrap();
    assert!(store.pending().is_empty());
    assert!(keys_of(&dir, 1).settled(&id).unwrap().is_settled());
    // Settled by the state, not yet in the file (a crash between): settled on opening.
    drop(store);
    let (mut store, recovery) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    let mut state = recovery.snapshot.unwrap();
    state.in_flight = Some(InFlight::Committed {
        block: 1,
        sessions: vec![3],
    });
    state.committed.push(1);
    store.persist(&mut state, &[key(1, &[3])]).unwrap();
    state.in_flight = None;
    store.persist(&mut state, &[]).unwrap();
    drop(store);
    let mut text = std::fs::read_to_string(dir.join("keys/0000000000000001.key")).unwrap();
    assert!(text.contains("\"settled\""), "{text}");
    undo_last_appends::<ControllerSnapshot>(&dir, 1);
    let (_, recovery) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    assert_eq!(
        recovery.figures.keys_settled, 0,
        "the file was settled already"
    );
    text.clear();
}

/// The robot's prepared key is pending until the `Commit`, and removed if the block aborts.
#[test]
fn the_robots_prepared_key_is_pending_until_the_commit_and_removed_on_abort() {
    let dir = tempdir("post-store-prepared");
    let (mut store, _) = open::<RobotSnapshot>(&dir, 1).unwrap();
    let prepared = |block: u64| RobotSnapshot {
        pool: Vec::new(),
        spent: vec![1, 2],
        highest_block: Some(block),
        prepared: Some(Prepared {
            block,
            key: key(block, &[1, 2]),
            tag: [0; 8],
            report: robokey_secrecy::postprocess::BlockReport {
                block,
                length: 3,
                ..Default::default()
            },
        }),
        committed: Vec::new(),
    };
    let mut state = prepared(0);
    store.persist(&mut state, &[]).unwrap();
    let id = key(0, &[]).id;
    let error = keys_of(&dir, 1).settled(&id).unwrap_err().to_string();
    assert!(error.contains("Commit has not arrived"), "{error}");
    // The Commit: the key settles.
    state.prepared = None;
    state.committed.push(0);
    store.persist(&mut state, &[key(0, &[1, 2])]).unwrap();
    assert!(keys_of(&dir, 1).settled(&id).unwrap().is_settled());
    // Block 1 prepared, then aborted: its pending key goes.
    let mut state = prepared(1);
    state.committed.push(0);
    store.persist(&mut state, &[]).unwrap();
    assert_eq!(keys_of(&dir, 1).list().unwrap().len(), 2);
    state.prepared = None;
    store.persist(&mut state, &[]).unwrap();
    let listed = keys_of(&dir, 1).list().unwrap();
    assert_eq!(listed.iter().map(|k| k.block).collect::<Vec<_>>(), [0]);
}

/// Restoring the journal from an older copy puts spent sessions back in the pool: those a
/// stored key lists as sources are dropped, so no second key comes from them.
#[test]
fn a_journal_restored_from_an_older_copy_never_pools_a_keys_sources_again() {
    let dir = tempdir("post-store-rollback");
    let (mut store, _) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    let mut state = controller(&[(1, true), (2, false), (3, true)], &[]);
    store.persist(&mut state, &[]).unwrap();
    drop(store);
    let old = std::fs::read(dir.join("journal")).unwrap();
    let (mut store, recovery) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    let mut state = recovery.snapshot.unwrap();
    state.pool.retain(|(id, _)| *id == 3);
    state.committed.push(0);
    store.persist(&mut state, &[key(0, &[1, 2])]).unwrap();
    assert!(store.sources().contains(&1) && !store.sources().contains(&3));
    drop(store);
    std::fs::write(dir.join("journal"), &old).unwrap();
    let (store, recovery) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    assert_eq!(recovery.figures.sessions_already_spent, 2);
    let state = recovery.snapshot.unwrap();
    assert_eq!(
        state.pool.iter().map(|(id, _)| *id).collect::<Vec<_>>(),
        [3]
    );
    assert!(state.spent.contains(&1) && state.spent.contains(&2));
    assert!(store.sources().contains(&2));
}

/// Links planted at `lock` and `journal` are refused, their targets keep every byte, and an
/// existing lock file is never truncated.
#[test]
fn links_at_the_lock_or_the_journal_are_refused_and_nothing_is_cut() {
    let dir = tempdir("post-store-links");
    let victim = dir.join("victim");
    std::fs::write(&victim, b"precious").unwrap();
    let store = dir.join("store");
    for name in ["lock", "journal"] {
        std::fs::create_dir_all(&store).unwrap();
        std::os::unix::fs::symlink(&victim, store.join(name)).unwrap();
        let error = open::<RobotSnapshot>(&store, 1).unwrap_err().to_string();
        assert!(error.contains("symbolic link"), "{name}: {error}");
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious", "{name}");
        std::fs::remove_dir_all(&store).unwrap();
    }
    std::fs::create_dir_all(&store).unwrap();
    std::fs::set_permissions(&store, std::fs::Permissions::from_mode(0o700)).unwrap();
    std::fs::write(store.join("lock"), b"not cut").unwrap();
    std::fs::set_permissions(store.join("lock"), std::fs::Permissions::from_mode(0o600)).unwrap();
    drop(open::<RobotSnapshot>(&store, 1).unwrap());
    assert_eq!(std::fs::read(store.join("lock")).unwrap(), b"not cut");
}

/// A pre-made store others can write is refused, not adopted.
#[test]
fn a_store_others_can_write_is_refused() {
    let dir = tempdir("post-store-mode");
    std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o777)).unwrap();
    let error = open::<RobotSnapshot>(&dir, 1).unwrap_err().to_string();
    assert!(error.contains("mode 777"), "{error}");
    assert!(!dir.join("journal").exists());
}

/// A `state` record forged without the pairing secret — carrying a key of the attacker's
/// choosing — is never adopted, and nothing is written to `keys/`: at the end of the journal
/// it is a tail of foreign bytes, cut; before a genuine record it is corruption, refused.
#[test]
fn a_forged_record_is_refused_and_writes_no_key() {
    let dir = tempdir("post-store-forged");
    let (mut store, _) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    let mut state = controller(&[(1, true)], &[]);
    store.persist(&mut state, &[]).unwrap();
    drop(store);
    let genuine = std::fs::read(dir.join("journal")).unwrap();
    // The attacker frames the record under a key of their own.
    let planted = StoredKey::new(
        &key(7, &[1]),
        "controller",
        &KeyLabels::default(),
        KeyStatus::Settled,
    );
    let forged = encode_state(&controller(&[], &[7]), &[], &[planted], &[]);
    let owner = format!("controller {}", pairing(1).fingerprint());
    let other = tempdir("post-store-forger");
    let theirs = StoreKeys::new(&pairing(9), "controller").journal;
    drop(Journal::create(&other.join("journal"), &theirs, &owner, &[forged]).unwrap());
    let start = format!("robokey-journal-v2 {owner}\n").len() + 16;
    let record = std::fs::read(other.join("journal")).unwrap()[start..].to_vec();
    let mut appended = genuine.clone();
    appended.extend_from_slice(&record);
    std::fs::write(dir.join("journal"), &appended).unwrap();
    let (store, recovery) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    assert_eq!(recovery.figures.torn_bytes, record.len() as u64);
    assert!(recovery.snapshot.unwrap().committed.is_empty());
    assert!(keys_of(&dir, 1).list().unwrap().is_empty());
    drop(store);
    // Before the last genuine record: refused, the file kept as it was.
    let (mut store, _) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    store.persist(&mut state, &[]).unwrap();
    drop(store);
    let genuine = std::fs::read(dir.join("journal")).unwrap();
    let last = genuine.len()
        - (genuine.len() - start).min(
            // The last record: the state just appended.
            HEADER_AND_TAG + encode_state(&state_without_pool(&state), &[1], &[], &[]).len(),
        );
    let mut inserted = genuine[..last].to_vec();
    inserted.extend_from_slice(&record);
    inserted.extend_from_slice(&genuine[last..]);
    std::fs::write(dir.join("journal"), &inserted).unwrap();
    let error = open::<ControllerSnapshot>(&dir, 1).unwrap_err().to_string();
    assert!(error.contains(&format!("offset {last}:")), "{error}");
    assert!(error.contains("intact records follow"), "{error}");
    assert_eq!(std::fs::read(dir.join("journal")).unwrap(), inserted);
    assert!(keys_of(&dir, 1).list().unwrap().is_empty());
}

/// A record's framing around its payload: length, header tag, tag.
const HEADER_AND_TAG: usize = 4 + 8 + 16;

fn state_without_pool(state: &ControllerSnapshot) -> ControllerSnapshot {
    let mut state = state.clone();
    state.pool.clear();
    state
}

/// A pending key the journal does not know — the journal was restored from a copy taken
/// before the key's commit — is marked superseded and never settled, even when the same
/// block number is committed again with another key.
#[test]
fn a_pending_key_a_restored_journal_does_not_know_is_never_settled() {
    let dir = tempdir("post-store-superseded");
    let (mut store, _) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    let mut state = controller(&[], &[]);
    store.persist(&mut state, &[]).unwrap();
    drop(store);
    let old = std::fs::read(dir.join("journal")).unwrap();
    let (mut store, recovery) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    let mut state = recovery.snapshot.unwrap();
    let committed = |state: &mut ControllerSnapshot| {
        state.committed.push(0);
        state.in_flight = Some(InFlight::Committed {
            block: 0,
            sessions: vec![1],
        });
    };
    committed(&mut state);
    store.persist(&mut state, &[key(0, &[1])]).unwrap();
    drop(store);
    std::fs::write(dir.join("journal"), &old).unwrap();
    let (mut store, recovery) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    assert_eq!(recovery.figures.pending_superseded, 1);
    assert!(store.pending().is_empty());
    // Block 0 again, with another key, committed and acknowledged.
    let mut state = recovery.snapshot.unwrap();
    committed(&mut state);
    let mut other = key(0, &[2]);
    other.id = "00000000000000ff".into();
    store.persist(&mut state, &[other.clone()]).unwrap();
    state.in_flight = None;
    store.persist(&mut state, &[]).unwrap();
    let keys = keys_of(&dir, 1);
    assert!(keys.settled(&other.id).unwrap().is_settled());
    let error = keys.settled(&key(0, &[]).id).unwrap_err().to_string();
    assert!(error.contains("restored from an older copy"), "{error}");
    drop(store);
    let (_, recovery) = open::<ControllerSnapshot>(&dir, 1).unwrap();
    assert_eq!(recovery.figures.pending_superseded, 0, "marked once");
}
