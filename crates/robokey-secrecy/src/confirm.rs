//! Key confirmation (docs/secrecy.md, docs/postprocessing.md): a 64-bit tag = HMAC-SHA256 keyed with the reconciled key
//! over the session's public data, truncated to 64 bits, compared in constant time.
//!
//! Correctness: modelling HMAC-SHA256 as a pseudorandom function, two different keys give the
//! same tag with probability ε_ver = 2⁻⁶⁴ (plus the PRF distinguishing advantage), for each
//! comparison. Secrecy: the tag is a 64-bit function of the key, so t_ver = 64 bits are
//! counted as leak.

use hmac::{Hmac, KeyInit, Mac};
use sha2::{Digest, Sha256};
use subtle::{Choice, ConstantTimeEq};
use zeroize::Zeroizing;

use crate::bitstring::BitString;

/// Tag length t_ver in bits, subtracted from the output length as leak.
pub const TAG_BITS: u64 = 64;

/// ε_ver = 2⁻⁶⁴: probability that different keys pass confirmation (HMAC as a PRF).
pub const EPSILON_VER: f64 = 1.0 / 18_446_744_073_709_551_616.0;

/// Domain-separation label hashed first into every tag.
pub const DOMAIN_LABEL: &[u8] = b"robokey/key-confirmation/v1";

/// SHA-256 block size: HMAC keys are zero-padded or hashed to this many bytes.
const HMAC_BLOCK_BYTES: usize = 64;

/// The public data a tag binds the key to; both sides must agree on every field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ConfirmationContext<'a> {
    /// Session id.
    pub session_id: u32,
    /// Digest of the resolved configuration.
    pub config_digest: [u8; 32],
    /// Fate bitmap: which codewords were accepted (the public acks).
    pub fate_bitmap: &'a [u8],
    /// Fresh public nonce, chosen after reconciliation.
    pub nonce: [u8; 16],
}

/// A 64-bit confirmation tag (public). Compare with [`ConfirmationTag::matches`], which is
/// constant-time; there is deliberately no `PartialEq`.
#[derive(Debug, Clone, Copy)]
pub struct ConfirmationTag(pub [u8; 8]);

impl ConstantTimeEq for ConfirmationTag {
    fn ct_eq(&self, other: &Self) -> Choice {
        self.0.ct_eq(&other.0)
    }
}

impl ConfirmationTag {
    /// Tag = first 64 bits of HMAC-SHA256(K, label ‖ session id ‖ config digest ‖ |fate| ‖
    /// fate ‖ |K| in bits ‖ nonce), with K the key packed little-endian into bytes and
    /// lengths as big-endian u64 (so no two different inputs share an encoding).
    #[must_use]
    pub fn compute(key: &BitString, context: &ConfirmationContext<'_>) -> Self {
        let key_bytes = Zeroizing::new(key.to_bytes());
        let mut mac = hmac_sha256(&key_bytes);
        mac.update(&(DOMAIN_LABEL.len() as u64).to_be_bytes());
        mac.update(DOMAIN_LABEL);
        mac.update(&context.session_id.to_be_bytes());
        mac.update(&context.config_digest);
        mac.update(&(context.fate_bitmap.len() as u64).to_be_bytes());
        mac.update(context.fate_bitmap);
        mac.update(&(key.len() as u64).to_be_bytes());
        mac.update(&context.nonce);
        let full = mac.finalize().into_bytes();
        let mut tag = [0_u8; 8];
        tag.copy_from_slice(&full[..8]);
        Self(tag)
    }

    /// A directional tag over a pooled block's reconciled key: the first 64 bits of
    /// HMAC-SHA256(K, |label| ‖ label ‖ |direction| ‖ direction ‖ |K| in bits ‖ context),
    /// lengths big-endian u64. The two directions use different labels, so one side's tag
    /// reflected back never passes as the other's.
    #[must_use]
    pub fn directional(key: &BitString, direction: &[u8], context: &[u8]) -> Self {
        const LABEL: &[u8] = b"robokey/block-confirmation/v1";
        let key_bytes = Zeroizing::new(key.to_bytes());
        let mut mac = hmac_sha256(&key_bytes);
        for part in [LABEL, direction] {
            mac.update(&(part.len() as u64).to_be_bytes());
            mac.update(part);
        }
        mac.update(&(key.len() as u64).to_be_bytes());
        mac.update(context);
        let full = mac.finalize().into_bytes();
        let mut tag = [0_u8; 8];
        tag.copy_from_slice(&full[..8]);
        Self(tag)
    }

    /// Constant-time equality of two tags.
    #[must_use]
    pub fn matches(&self, other: &Self) -> bool {
        self.ct_eq(other).into()
    }
}

/// HMAC-SHA256 keyed with `key` of any length, built infallibly: RFC 2104 pads keys of at
/// most one block with zeros and hashes longer ones first, which is what `KeyInit::new`
/// receives here.
fn hmac_sha256(key: &[u8]) -> Hmac<Sha256> {
    let mut block = Zeroizing::new([0_u8; HMAC_BLOCK_BYTES]);
    if key.len() <= HMAC_BLOCK_BYTES {
        block[..key.len()].copy_from_slice(key);
    } else {
        let digest = Sha256::digest(key);
        block[..digest.len()].copy_from_slice(&digest);
    }
    let block_ref: &[u8; HMAC_BLOCK_BYTES] = &block;
    <Hmac<Sha256> as KeyInit>::new(block_ref.into())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hex(bytes: &[u8]) -> String {
        bytes.iter().map(|b| format!("{b:02x}")).collect()
    }

    #[test]
    fn hmac_matches_rfc_4231() {
        // Test case 1: 20-byte key.
        let mut mac = hmac_sha256(&[0x0b; 20]);
        mac.update(b"Hi There");
        assert_eq!(
            hex(&mac.finalize().into_bytes()),
            "b0344c61d8db38535ca8afceaf0bf12b881dc200c9833da726e9376c2e32cff7"
        );
        // Test case 6: 131-byte key (longer than a block: hashed first).
        let mut mac = hmac_sha256(&[0xaa; 131]);
        mac.update(b"Test Using Larger Than Block-Size Key - Hash Key First");
        assert_eq!(
            hex(&mac.finalize().into_bytes()),
            "60e431591ee0b67f0d8a26aacbf5b77f8e0bc6213728c5140546040f0ee37f54"
        );
    }

    fn context(fate: &[u8]) -> ConfirmationContext<'_> {
        ConfirmationContext {
            session_id: 7,
            config_digest: [3; 32],
            fate_bitmap: fate,
            nonce: [9; 16],
        }
    }

    #[test]
    fn every_single_bit_difference_changes_the_tag() {
        use rand::SeedableRng;
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(42);
        let key = BitString::random(345, &mut rng);
        let fate = [0xa5_u8; 44];
        let ctx = context(&fate);
        let tag = ConfirmationTag::compute(&key, &ctx);
        assert!(tag.matches(&ConfirmationTag::compute(&key.clone(), &ctx)));
        for i in 0..key.len() {
            let mut other = key.clone();
            other.flip(i).unwrap();
            assert!(
                !tag.matches(&ConfirmationTag::compute(&other, &ctx)),
                "bit {i}"
            );
        }
    }

    #[test]
    fn tag_binds_public_data_and_length() {
        let key = BitString::from_bools(&[true, false, true]);
        let fate = [1_u8, 2];
        let base = ConfirmationTag::compute(&key, &context(&fate));
        let mut ctx = context(&fate);
        ctx.session_id = 8;
        assert!(!base.matches(&ConfirmationTag::compute(&key, &ctx)));
        let mut ctx = context(&fate);
        ctx.nonce[0] ^= 1;
        assert!(!base.matches(&ConfirmationTag::compute(&key, &ctx)));
        let mut ctx = context(&fate);
        ctx.config_digest[31] ^= 1;
        assert!(!base.matches(&ConfirmationTag::compute(&key, &ctx)));
        assert!(!base.matches(&ConfirmationTag::compute(&key, &context(&[1, 2, 0]))));
        // Same bytes, different bit length (trailing zero bit).
        let longer = BitString::from_bools(&[true, false, true, false]);
        assert!(!base.matches(&ConfirmationTag::compute(&longer, &context(&fate))));
    }
}
