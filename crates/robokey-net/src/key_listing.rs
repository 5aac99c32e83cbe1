//! A key store's listing as `robokey keys list` gives it: everything about each final key
//! but its bits (docs/postprocessing.md, "Key store"; docs/keys.md).

use robokey::post_settings::KeyBasis;
use serde::Serialize;

use crate::key_slice::{SliceId, Span};
use crate::key_store::{KeyStatus, StoredKey};

/// A final key as listed: everything but its bits.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ListedKey {
    /// The key's ID (16 hex digits, the same on the robot and the controller).
    pub id: String,
    /// The store's agent: `robot` or `controller`.
    pub role: String,
    /// The privacy-amplification block the key came from.
    pub block: u64,
    /// The key's length (bits).
    pub bits: usize,
    /// Whole bytes' bits not taken yet, deliverable once settled (0 while pending).
    pub available_bits: u64,
    /// Bits taken (delivered) and erased.
    pub taken_bits: u64,
    /// The IDs of the keys taken from it.
    pub taken: Vec<String>,
    /// The key's ε (the secrecy parameter it was amplified with).
    pub epsilon: f64,
    /// `physical`, or `restricted` when it is secret only under a restriction on Eve.
    pub label: &'static str,
    /// `settled`, or `pending` until the peer acknowledges it.
    pub status: &'static str,
    /// Why a pending key is pending.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pending_reason: Option<String>,
    /// The assumption about Eve the key is secret under.
    pub assumption: String,
    /// Private sensing: what the key rests on, Eve's camera and the plant's model class.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub basis: Option<KeyBasis>,
    /// How the key's block was reconciled: `cascade` or `ldpc` (absent in records written
    /// before it was stated).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reconciliation: Option<String>,
    /// leak_EC of its block (bits): what its length was charged for reconciliation.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub leak_ec: Option<u64>,
    /// When the key was made (as the store wrote it).
    pub created: String,
    /// The sessions whose bits it holds.
    pub sessions: Vec<u32>,
}

impl From<&StoredKey> for ListedKey {
    fn from(key: &StoredKey) -> Self {
        let (status, pending_reason) = match &key.status {
            KeyStatus::Settled => ("settled", None),
            KeyStatus::Pending(reason) => ("pending", Some(reason.clone())),
        };
        Self {
            id: key.id.clone(),
            role: key.role.clone(),
            block: key.block,
            bits: key.bits,
            available_bits: if key.is_settled() {
                key.untaken_bits()
            } else {
                0
            },
            taken_bits: key.taken_bits(),
            taken: key.taken.iter().map(|span| taken_id(key, *span)).collect(),
            epsilon: key.epsilon,
            label: if key.restricted {
                "restricted"
            } else {
                "physical"
            },
            status,
            pending_reason,
            assumption: key.assumption.clone(),
            basis: key.basis.clone(),
            reconciliation: key.reconciliation.as_ref().map(|r| r.method.clone()),
            leak_ec: key.reconciliation.as_ref().map(|r| r.leak_ec),
            created: key.created.clone(),
            sessions: key.sessions.clone(),
        }
    }
}

/// The ID of the key taken as `span` from `key`.
fn taken_id(key: &StoredKey, span: Span) -> String {
    SliceId::new(&key.id, span).map_or_else(|e| e, |id| id.uuid().to_string())
}
