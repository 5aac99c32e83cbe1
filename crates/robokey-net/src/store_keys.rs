//! The keys that authenticate a store, derived from the pairing secret S so that only a
//! holder of S writes a journal record or a key file the store accepts, and bound to the
//! role so that a robot's store never accepts a controller's files:
//! `K = HKDF-SHA256(no salt, S, "robokey store v1 PURPOSE ROLE")`, and a tag over `parts`
//! is `HMAC-SHA256(K, parts[0] ‖ parts[1] ‖ …)` (callers make the parts unambiguous:
//! fixed lengths, or a length before each).

use hmac::{Hmac, KeyInit as _, Mac as _};
use robokey::protocol::auth::PairingSecret;
use sha2::Sha256;
use zeroize::Zeroizing;

/// One 256-bit MAC key of a store. Its `Debug` shows nothing of it.
#[derive(Clone)]
pub struct StoreMac(Zeroizing<[u8; 32]>);

impl std::fmt::Debug for StoreMac {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("StoreMac(..)")
    }
}

impl StoreMac {
    /// The key for `purpose` and `role` under `pairing`.
    #[must_use]
    pub fn derive(pairing: &PairingSecret, purpose: &str, role: &str) -> Self {
        let mut key = Zeroizing::new([0_u8; 32]);
        hkdf::Hkdf::<Sha256>::new(None, pairing.expose())
            .expand(
                format!("robokey store v1 {purpose} {role}").as_bytes(),
                key.as_mut(),
            )
            .expect("32 bytes is a valid HKDF-SHA256 output length");
        Self(key)
    }

    /// HMAC-SHA256 over the concatenated `parts`.
    #[must_use]
    pub fn tag(&self, parts: &[&[u8]]) -> [u8; 32] {
        let mut mac = <Hmac<Sha256>>::new_from_slice(self.0.as_ref())
            .expect("HMAC takes a key of any length");
        for part in parts {
            mac.update(part);
        }
        mac.finalize().into_bytes().into()
    }

    /// Whether `tag` is the first `tag.len()` bytes of [`Self::tag`] (constant time).
    #[must_use]
    pub fn verify(&self, parts: &[&[u8]], tag: &[u8]) -> bool {
        use subtle::ConstantTimeEq as _;
        let full = self.tag(parts);
        tag.len() <= full.len() && bool::from(full[..tag.len()].ct_eq(tag))
    }
}

/// The two MAC keys of one agent's store.
#[derive(Clone, Debug)]
pub struct StoreKeys {
    /// Authenticates the journal's records.
    pub journal: StoreMac,
    /// Authenticates the key files.
    pub key_files: StoreMac,
}

impl StoreKeys {
    /// The keys of `role`'s store under `pairing`.
    #[must_use]
    pub fn new(pairing: &PairingSecret, role: &str) -> Self {
        Self {
            journal: StoreMac::derive(pairing, "journal", role),
            key_files: StoreMac::derive(pairing, "key-file", role),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_differ_by_pairing_purpose_and_role() {
        let a = PairingSecret::from_bytes(&[1; 32]);
        let b = PairingSecret::from_bytes(&[2; 32]);
        let tags = [
            StoreKeys::new(&a, "robot").journal.tag(&[b"x"]),
            StoreKeys::new(&a, "robot").key_files.tag(&[b"x"]),
            StoreKeys::new(&a, "controller").journal.tag(&[b"x"]),
            StoreKeys::new(&b, "robot").journal.tag(&[b"x"]),
        ];
        for i in 0..tags.len() {
            for j in i + 1..tags.len() {
                assert_ne!(tags[i], tags[j], "{i} {j}");
            }
        }
        let mac = StoreKeys::new(&a, "robot").journal;
        let tag = mac.tag(&[b"ab", b"c"]);
        assert!(mac.verify(&[b"a", b"bc"], &tag[..16]));
        assert!(!mac.verify(&[b"a", b"bd"], &tag[..16]));
    }
}
