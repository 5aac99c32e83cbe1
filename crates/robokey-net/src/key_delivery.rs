//! Keys delivered to applications (docs/keys.md): slices of settled final keys, each taken
//! once, by `robokey keys take` and `robokey kme` alike.
//!
//! Taking is role-aware, as an ETSI GS QKD 014 master/slave pair: the controller side hands
//! out new slices — from the first settled final key (by block, then ID) with enough bits
//! left after its last slice, so the remainder stays for later — and the robot side hands
//! out a slice only by the ID the controller side gave ([`SliceId`]), so the two sides never
//! give the same bits to two different uses. A pending key is never cut.
//!
//! One take holds the key folder's lock ([`KeyStore::lock`]) from reading the final keys to
//! writing them back with the slices erased and marked taken, and returns the slices only
//! then: a crash before the write delivered nothing, a crash after it loses the slices (an
//! application never got them) but never delivers them twice. A request for several slices
//! takes all of them or none.

use std::collections::BTreeMap;
use std::path::Path;

use robokey::protocol::auth::PairingSecret;
use uuid::Uuid;
use zeroize::Zeroizing;

use crate::error::NetError;
use crate::key_slice::{SliceId, Span, check_slice_bits};
use crate::key_store::{KeyStatus, KeyStore, StoredKey};
use crate::post_store::open_keys;

/// Which side of the pairing a store belongs to, and so how it hands out keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// The controller's store: hands out new keys (the ETSI master's KME).
    Controller,
    /// The robot's store: hands out a key only by the ID the controller side gave (the ETSI
    /// slave's KME).
    Robot,
}

impl Side {
    /// `controller` or `robot`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Controller => "controller",
            Self::Robot => "robot",
        }
    }

    /// The other side.
    #[must_use]
    pub fn peer(self) -> Self {
        match self {
            Self::Controller => Self::Robot,
            Self::Robot => Self::Controller,
        }
    }
}

/// A key handed out: its ID and its bytes (zeroized when dropped).
pub struct Delivered {
    /// The ID both sides compute.
    pub id: Uuid,
    /// The key.
    pub key: Zeroizing<Vec<u8>>,
}

impl Delivered {
    /// The key in lowercase hex.
    #[must_use]
    pub fn hex(&self) -> Zeroizing<String> {
        Zeroizing::new(base16ct::lower::encode_string(&self.key))
    }

    /// The key in standard base64 with padding (RFC 4648), constant-time.
    #[must_use]
    pub fn base64(&self) -> Zeroizing<String> {
        Zeroizing::new(<base64ct::Base64 as base64ct::Encoding>::encode_string(
            &self.key,
        ))
    }
}

impl std::fmt::Debug for Delivered {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Delivered")
            .field("id", &self.id)
            .field("bits", &(self.key.len() * 8))
            .finish_non_exhaustive()
    }
}

/// How many keys of one length a store can still hand out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Availability {
    /// From settled final keys: deliverable now.
    pub settled: u64,
    /// From pending final keys, once their peer acknowledges them.
    pub pending: u64,
}

/// The key delivery of one store.
#[derive(Debug)]
pub struct KeyDelivery {
    keys: KeyStore,
    side: Side,
}

impl KeyDelivery {
    /// The delivery of the store at `dir`, verified under `pairing`.
    ///
    /// # Errors
    /// As [`open_keys`].
    pub fn open(dir: &Path, pairing: &PairingSecret) -> Result<Self, NetError> {
        Ok(Self::new(open_keys(dir, pairing)?))
    }

    /// The delivery of an open key folder.
    #[must_use]
    pub fn new(keys: KeyStore) -> Self {
        let side = if keys.role() == "controller" {
            Side::Controller
        } else {
            Side::Robot
        };
        Self { keys, side }
    }

    /// The store's side.
    #[must_use]
    pub fn side(&self) -> Side {
        self.side
    }

    /// The key folder.
    #[must_use]
    pub fn keys(&self) -> &KeyStore {
        &self.keys
    }

    /// Takes `number` new keys of `bits` bits each (the controller side): all or none.
    ///
    /// # Errors
    /// The robot side, or a length outside the slice lengths ([`NetError::Usage`]); fewer
    /// than `number` such keys in the settled final keys ([`NetError::NoKey`], saying how
    /// many there are and how many pending keys would add); the store fails.
    pub fn take_new(&self, bits: u32, number: usize) -> Result<Vec<Delivered>, NetError> {
        if self.side == Side::Robot {
            return Err(NetError::Usage(
                "the robot side hands out keys only by the ID the controller side gave (robokey \
                 keys take --id ID, or the ETSI dec_keys call); new keys come from the \
                 controller's store"
                    .into(),
            ));
        }
        check_slice_bits(bits).map_err(NetError::Usage)?;
        let lock = self.keys.lock()?;
        let mut finals = self.keys.list()?;
        let available = count(&finals, bits, self.side);
        if available.settled < number as u64 {
            return Err(NetError::NoKey(format!(
                "{number} keys of {bits} bits asked, {} available in the settled final keys{}",
                available.settled,
                match available.pending {
                    0 => String::new(),
                    n => format!(" ({n} more once the pending ones settle)"),
                }
            )));
        }
        let mut delivered = Vec::with_capacity(number);
        let mut changed = vec![false; finals.len()];
        for _ in 0..number {
            let (index, key) = finals
                .iter_mut()
                .enumerate()
                .find(|(_, key)| {
                    key.is_settled() && key.sliceable_bits() - key.cursor() >= u64::from(bits)
                })
                .ok_or_else(|| NetError::NoKey(format!("no key of {bits} bits is left")))?;
            let span = Span {
                offset: u32::try_from(key.cursor()).map_err(|_| {
                    NetError::Usage(format!("final key {} is too long to slice", key.id))
                })?,
                bits,
            };
            let id = SliceId::new(&key.id, span).map_err(NetError::Usage)?;
            let bytes = key.cut(span).map_err(NetError::Usage)?;
            changed[index] = true;
            delivered.push(Delivered {
                id: id.uuid(),
                key: bytes,
            });
        }
        for (key, _) in finals.iter().zip(&changed).filter(|(_, c)| **c) {
            self.keys.rewrite(key, &lock)?;
        }
        Ok(delivered)
    }

    /// Takes the keys the controller side gave under `ids` (the robot side): all or none, in
    /// the order asked.
    ///
    /// # Errors
    /// The controller side, an ID that is not a robokey key ID, names a final key this store
    /// does not hold, bits already taken, or is asked twice ([`NetError::Usage`], naming it);
    /// its final key is pending here ([`NetError::Pending`]); the store fails.
    pub fn take_by_id(&self, ids: &[&str]) -> Result<Vec<Delivered>, NetError> {
        if self.side == Side::Controller {
            return Err(NetError::Usage(
                "the controller side hands out new keys only (robokey keys take without --id, \
                 or the ETSI enc_keys call); the robot side hands them out again by ID"
                    .into(),
            ));
        }
        let slices = ids
            .iter()
            .map(|id| SliceId::parse(id).map_err(NetError::Usage))
            .collect::<Result<Vec<_>, _>>()?;
        for (i, a) in slices.iter().enumerate() {
            if let Some(b) = slices[..i]
                .iter()
                .find(|b| b.key == a.key && b.span.overlaps(&a.span))
            {
                return Err(NetError::Usage(if a == b {
                    format!("key_ID {} is asked twice", a.uuid())
                } else {
                    format!("key_IDs {} and {} share bits", b.uuid(), a.uuid())
                }));
            }
        }
        let lock = self.keys.lock()?;
        let mut finals: BTreeMap<&str, StoredKey> = BTreeMap::new();
        let mut delivered = Vec::with_capacity(slices.len());
        for slice in &slices {
            let uuid = slice.uuid();
            let key = match finals.entry(&slice.key) {
                std::collections::btree_map::Entry::Occupied(entry) => entry.into_mut(),
                std::collections::btree_map::Entry::Vacant(entry) => {
                    entry.insert(self.final_key(slice, &uuid)?)
                }
            };
            let bytes = key
                .cut(slice.span)
                .map_err(|reason| NetError::Usage(format!("key_ID {uuid} {reason}")))?;
            delivered.push(Delivered {
                id: uuid,
                key: bytes,
            });
        }
        for key in finals.values() {
            self.keys.rewrite(key, &lock)?;
        }
        Ok(delivered)
    }

    /// How many keys of `bits` bits the store can still hand out.
    ///
    /// # Errors
    /// The store cannot be listed (a file that does not verify is named).
    pub fn available(&self, bits: u32) -> Result<Availability, NetError> {
        Ok(count(&self.keys.list()?, bits, self.side))
    }

    /// The settled final key a slice ID names, verified.
    fn final_key(&self, slice: &SliceId, uuid: &Uuid) -> Result<StoredKey, NetError> {
        let key = self.keys.get(&slice.key).map_err(|error| match error {
            NetError::Usage(_) => NetError::Usage(format!(
                "key_ID {uuid} names final key {}, which this robot store does not hold \
                 (deleted, or the ID comes from another pairing)",
                slice.key
            )),
            other => other,
        })?;
        match &key.status {
            KeyStatus::Settled => Ok(key),
            KeyStatus::Pending(reason) => Err(NetError::Pending(format!(
                "key_ID {uuid}: final key {} is pending here — {reason} — and is withheld \
                 until it settles",
                slice.key
            ))),
        }
    }
}

/// How many keys of `bits` bits `finals` can still give on `side`: after the cursor of each
/// key on the controller side (it cuts in order), in each free run on the robot side.
fn count(finals: &[StoredKey], bits: u32, side: Side) -> Availability {
    let bits = u64::from(bits.max(1));
    let mut availability = Availability {
        settled: 0,
        pending: 0,
    };
    for key in finals {
        let keys = match side {
            Side::Controller => (key.sliceable_bits() - key.cursor()) / bits,
            Side::Robot => key
                .free_runs()
                .iter()
                .map(|(start, end)| (end - start) / bits)
                .sum(),
        };
        if key.is_settled() {
            availability.settled += keys;
        } else {
            availability.pending += keys;
        }
    }
    availability
}

#[cfg(test)]
pub(crate) mod tests;
