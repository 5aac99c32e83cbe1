//! Delivery against misuse, races with an agent and an attacker beside the store.

use std::collections::BTreeSet;
use std::sync::{Arc, Barrier};

use robokey_secrecy::BitString;
use robokey_secrecy::postprocess::{ControllerSnapshot, FinalKey, InFlight, RobotSnapshot};

use super::*;
use crate::journal::tests::tempdir;
use crate::key_store::KeyLabels;
use crate::post_store::{PostStore, Snapshot};

pub(crate) fn pairing() -> PairingSecret {
    PairingSecret::from_bytes(&[5; 32])
}

/// A final key of `bits` bits whose byte `i` is `i + seed` (wrapping).
pub(crate) fn final_key(block: u64, bits: usize, seed: u8) -> FinalKey {
    let bools: Vec<bool> = (0..bits)
        .map(|i| ((i / 8) as u8).wrapping_add(seed) & (0x80 >> (i % 8)) != 0)
        .collect();
    FinalKey {
        id: format!("{:016x}", 0xa000 + block),
        block,
        key: BitString::from_bools(&bools),
        sessions: vec![block as u32],
        epsilon: 4e-6,
        assumption: "stated".into(),
        reconciliation: None,
    }
}

/// The bytes of `final_key(_, _, seed)` in `range`.
pub(crate) fn expected(seed: u8, range: std::ops::Range<usize>) -> Vec<u8> {
    range.map(|i| (i as u8).wrapping_add(seed)).collect()
}

/// A store of `S::ROLE` (with its journal) holding `keys`, each settled or pending.
pub(crate) fn store_with<S: Snapshot>(
    name: &str,
    keys: &[(FinalKey, bool)],
) -> (std::path::PathBuf, KeyDelivery) {
    let dir = tempdir(name);
    drop(PostStore::<S>::open(&dir, &pairing(), KeyLabels::default()).unwrap());
    let delivery = KeyDelivery::open(&dir, &pairing()).unwrap();
    for (key, settled) in keys {
        let status = if *settled {
            KeyStatus::Settled
        } else {
            KeyStatus::Pending("awaiting the peer".into())
        };
        delivery
            .keys()
            .store(&StoredKey::new(key, S::ROLE, &KeyLabels::default(), status))
            .unwrap();
    }
    (dir, delivery)
}

fn ids(delivered: &[Delivered]) -> Vec<String> {
    delivered.iter().map(|d| d.id.to_string()).collect()
}

fn id_refs(ids: &[String]) -> Vec<&str> {
    ids.iter().map(String::as_str).collect()
}

/// The controller side cuts in order, from the first settled key with room, leaving each
/// remainder for later; the robot side gives the same bytes by ID, once; pending keys give
/// nothing; each side refuses the other's way of taking.
#[test]
fn both_sides_give_the_same_keys_by_id_once_and_never_a_pending_one() {
    // 1,000 and 700 bits settled (125 and 87 whole bytes), 2,000 pending.
    let keys = [
        (final_key(0, 1000, 0), true),
        (final_key(1, 700, 100), true),
        (final_key(2, 2000, 200), false),
    ];
    let (_, controller) = store_with::<ControllerSnapshot>("delivery-c", &keys);
    let (_, robot) = store_with::<RobotSnapshot>("delivery-r", &keys);
    assert_eq!(
        controller.available(256).unwrap(),
        Availability {
            settled: 3 + 2,
            pending: 7
        }
    );
    let first = controller.take_new(256, 2).unwrap();
    assert_eq!(*first[0].key, expected(0, 0..32));
    assert_eq!(*first[1].key, expected(0, 32..64));
    // 488 bits remain in the first key: a 512-bit key comes from the second.
    let big = controller.take_new(512, 1).unwrap();
    assert_eq!(*big[0].key, expected(100, 0..64));
    // The first key's remainder serves a smaller key later.
    let small = controller.take_new(128, 1).unwrap();
    assert_eq!(*small[0].key, expected(0, 64..80));
    // Final key 000000000000a000, bits 512 (0x200) to 639: 128 (0x80) bits.
    assert_eq!(ids(&small), ["00000000-0000-8a00-8000-000200000080"]);
    // The robot gives the same bytes by ID, in the order asked, and never again.
    let all: Vec<String> = [ids(&first), ids(&big), ids(&small)].concat();
    let again = robot.take_by_id(&id_refs(&all)).unwrap();
    let sent: Vec<&Delivered> = first.iter().chain(&big).chain(&small).collect();
    for (theirs, ours) in sent.iter().zip(&again) {
        assert_eq!((theirs.id, &*theirs.key), (ours.id, &*ours.key));
    }
    let error = robot.take_by_id(&[&all[1]]).unwrap_err();
    assert!(error.to_string().contains("delivered already"), "{error}");
    // Asking for more than there is takes nothing.
    let before = controller.available(64).unwrap();
    let error = controller.take_new(64, 1000).unwrap_err();
    assert!(matches!(error, NetError::NoKey(_)), "{error}");
    assert!(
        error
            .to_string()
            .contains("more once the pending ones settle"),
        "{error}"
    );
    assert_eq!(controller.available(64).unwrap(), before);
    // The pending key is never cut: an ID into it is withheld on the robot side.
    let pending = SliceId::new(
        &keys[2].0.id,
        Span {
            offset: 0,
            bits: 256,
        },
    )
    .unwrap()
    .uuid()
    .to_string();
    let error = robot.take_by_id(&[&pending]).unwrap_err();
    assert!(matches!(error, NetError::Pending(_)), "{error}");
    // Each side refuses the other's way of taking.
    assert!(matches!(robot.take_new(256, 1), Err(NetError::Usage(_))));
    assert!(matches!(
        controller.take_by_id(&[&all[0]]),
        Err(NetError::Usage(_))
    ));
}

/// A request for several keys by ID takes all or none: one bad ID leaves the others free.
#[test]
fn a_request_by_id_takes_all_of_its_keys_or_none() {
    let keys = [(final_key(0, 1024, 7), true)];
    let (_, robot) = store_with::<RobotSnapshot>("delivery-all-or-none", &keys);
    let slice = |offset: u32, bits: u32| {
        SliceId::new(&keys[0].0.id, Span { offset, bits })
            .unwrap()
            .uuid()
            .to_string()
    };
    let (a, b) = (slice(0, 256), slice(256, 256));
    for (bad, says) in [
        (slice(768, 512), "reach past"),
        (a.clone(), "asked twice"),
        (slice(128, 256), "share bits"),
        (
            "550e8400-e29b-41d4-a716-446655440000".into(),
            "not a robokey key ID",
        ),
        (
            SliceId::new(
                "00000000000000ff",
                Span {
                    offset: 0,
                    bits: 256,
                },
            )
            .unwrap()
            .uuid()
            .to_string(),
            "does not hold",
        ),
    ] {
        let error = robot.take_by_id(&[&a, &b, &bad]).unwrap_err().to_string();
        assert!(error.contains(says), "{bad}: {error}");
    }
    assert_eq!(robot.available(256).unwrap().settled, 4);
    assert_eq!(robot.take_by_id(&[&b, &a]).unwrap().len(), 2);
    assert_eq!(robot.available(256).unwrap().settled, 2);
}

/// What the store promises about taken keys against someone beside it without the pairing
/// secret: a taken slice's bytes are in no file of the store, so nothing can deliver them
/// again; undoing the mark (the taken list edited, or the file replaced by one of another
/// key) makes the key refused, never delivered; removing the file loses the rest of the key.
#[test]
fn a_taken_key_cannot_be_untaken_or_taken_again_from_beside_the_store() {
    let keys = [
        (final_key(0, 1024, 40), true),
        (final_key(1, 1024, 90), true),
    ];
    let (dir, controller) = store_with::<ControllerSnapshot>("delivery-attacker", &keys);
    let taken = controller.take_new(256, 1).unwrap();
    let hex = base16ct::lower::encode_string(&taken[0].key);
    let path = dir.join("keys").join(format!("{}.key", keys[0].0.id));
    let file = std::fs::read_to_string(&path).unwrap();
    assert!(file.contains("\"taken\""), "{file}");
    for entry in walk(&dir) {
        let text = String::from_utf8_lossy(&std::fs::read(&entry).unwrap()).into_owned();
        assert!(
            !text.contains(&hex),
            "{} keeps the taken bytes",
            entry.display()
        );
    }
    let edits: [(&str, String); 3] = [
        (
            "the taken list emptied",
            file.replace("\"taken\": [", "\"untaken\": ["),
        ),
        (
            "the taken slice moved",
            file.replace("\"offset\": 0", "\"offset\": 256"),
        ),
        (
            "another key's file",
            std::fs::read_to_string(dir.join("keys").join(format!("{}.key", keys[1].0.id)))
                .unwrap(),
        ),
    ];
    for (what, text) in edits {
        std::fs::write(&path, &text).unwrap();
        let error = controller.take_new(256, 1).unwrap_err().to_string();
        assert!(
            error.contains("does not verify") || error.contains("holds the"),
            "{what}: {error}"
        );
        assert!(controller.available(256).is_err(), "{what}");
    }
    std::fs::write(&path, &file).unwrap();
    assert_eq!(controller.available(256).unwrap().settled, 3 + 4);
    std::fs::remove_file(&path).unwrap();
    assert_eq!(controller.available(256).unwrap().settled, 4);
    let next = controller.take_new(256, 1).unwrap();
    assert_eq!(*next[0].key, expected(90, 0..32));
}

/// Every file under `dir`.
fn walk(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            files.extend(walk(&path));
        } else {
            files.push(path);
        }
    }
    files
}

/// Takers racing on one store — four on the controller side, four after one ID on the robot
/// side — never get the same bits: the folder lock makes each take whole.
#[test]
fn racing_takers_never_get_the_same_bits() {
    let keys = [(final_key(0, 8192, 3), true), (final_key(1, 4096, 9), true)];
    let (_, controller) = store_with::<ControllerSnapshot>("delivery-race-c", &keys);
    let (dir, _robot) = store_with::<RobotSnapshot>("delivery-race-r", &keys);
    let start = Arc::new(Barrier::new(4));
    let takers: Vec<_> = (0..4)
        .map(|_| {
            let keys = controller.keys().clone();
            let start = Arc::clone(&start);
            std::thread::spawn(move || {
                let delivery = KeyDelivery::new(keys);
                start.wait();
                (0..6)
                    .flat_map(|_| delivery.take_new(256, 2).unwrap())
                    .collect::<Vec<_>>()
            })
        })
        .collect();
    let delivered: Vec<Delivered> = takers.into_iter().flat_map(|t| t.join().unwrap()).collect();
    assert_eq!(delivered.len(), 48);
    let distinct: BTreeSet<String> = ids(&delivered).into_iter().collect();
    assert_eq!(distinct.len(), 48);
    let mut bytes: Vec<Vec<u8>> = delivered.iter().map(|d| d.key.to_vec()).collect();
    bytes.sort();
    let mut whole: Vec<Vec<u8>> = (0..32).map(|i| expected(3, 32 * i..32 * i + 32)).collect();
    whole.extend((0..16).map(|i| expected(9, 32 * i..32 * i + 32)));
    whole.sort();
    assert_eq!(bytes, whole, "every byte of both keys, each once");
    // Four robot-side takers after the same ID: exactly one gets it.
    let id = ids(&delivered[..1]).remove(0);
    let start = Arc::new(Barrier::new(4));
    let racers: Vec<_> = (0..4)
        .map(|_| {
            let (dir, id, start) = (dir.clone(), id.clone(), Arc::clone(&start));
            std::thread::spawn(move || {
                let delivery = KeyDelivery::open(&dir, &pairing()).unwrap();
                start.wait();
                delivery.take_by_id(&[&id]).is_ok()
            })
        })
        .collect();
    let won = racers
        .into_iter()
        .filter_map(|r| r.join().unwrap().then_some(()))
        .count();
    assert_eq!(won, 1);
}

/// An agent committing and settling keys in its store while a server takes from it: every
/// file verifies throughout, only settled keys are cut, and the agent never finds a sliced
/// key to be another key when it stores a committed key again (as recovery does).
#[test]
fn an_agent_and_a_taker_on_one_store_do_not_corrupt_each_other() {
    let dir = tempdir("delivery-agent");
    let (mut store, _) =
        PostStore::<ControllerSnapshot>::open(&dir, &pairing(), KeyLabels::default()).unwrap();
    let delivery = KeyDelivery::open(&dir, &pairing()).unwrap();
    let done = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let taker = std::thread::spawn({
        let (keys, done) = (delivery.keys().clone(), Arc::clone(&done));
        move || {
            let delivery = KeyDelivery::new(keys);
            let mut delivered = Vec::new();
            while !done.load(std::sync::atomic::Ordering::SeqCst) {
                match delivery.take_new(128, 1) {
                    Ok(keys) => delivered.extend(keys),
                    Err(NetError::NoKey(_)) => std::thread::yield_now(),
                    Err(other) => panic!("{other}"),
                }
            }
            delivered
        }
    });
    let blocks = 40;
    for block in 0..blocks {
        let key = final_key(block, 1024, block as u8);
        // Committed, awaiting the robot's CommitAck: pending.
        let mut state = ControllerSnapshot {
            next_block: block + 1,
            pool: Vec::new(),
            separations: Vec::new(),
            separation_counts: Vec::new(),
            samples: Vec::new(),
            llrs: Vec::new(),
            staged: Vec::new(),
            spent: Vec::new(),
            in_flight: Some(InFlight::Committed {
                block,
                sessions: vec![block as u32],
            }),
            committed: (0..=block).collect(),
        };
        store
            .persist(&mut state, std::slice::from_ref(&key))
            .unwrap();
        // Acknowledged: settled, and the key stored again as recovery would.
        state.in_flight = None;
        store.persist(&mut state, &[]).unwrap();
        let again = StoredKey::new(
            &key,
            "controller",
            &KeyLabels::default(),
            KeyStatus::Settled,
        );
        delivery.keys().store(&again).unwrap();
    }
    done.store(true, std::sync::atomic::Ordering::SeqCst);
    let delivered = taker.join().unwrap();
    let keys = delivery.keys().list().unwrap();
    assert_eq!(keys.len(), blocks as usize);
    assert!(keys.iter().all(StoredKey::is_settled));
    let taken: u64 = keys.iter().map(StoredKey::taken_bits).sum();
    assert_eq!(taken, 128 * delivered.len() as u64);
    let distinct: BTreeSet<String> = ids(&delivered).into_iter().collect();
    assert_eq!(distinct.len(), delivered.len());
    for d in &delivered {
        let slice = SliceId::parse(&d.id.to_string()).unwrap();
        let block = u64::from_str_radix(&slice.key, 16).unwrap() - 0xa000;
        assert_eq!(*d.key, expected(block as u8, slice.span.bytes()));
    }
    assert!(
        !delivered.is_empty(),
        "the taker took nothing while the agent ran"
    );
}
