//! Key-confirmation tags (docs/protocol.md, docs/secrecy.md): the protocol's view of
//! [`robokey_secrecy::ConfirmationTag`].

use robokey_secrecy::{BitString, ConfirmationContext, ConfirmationTag};

/// Tag length (bytes): 64 bits, counted as leak by the secrecy accounting.
pub const TAG_BYTES: usize = 8;

/// The 64-bit HMAC-SHA256 tag over (session, config digest, fate bitmap, key). The session
/// id is fresh per session and serves as the public nonce.
#[must_use]
pub fn confirmation_tag(
    session: u32,
    config_digest: &[u8; 32],
    fate_bitmap: &[u64],
    key_bits: &[u8],
) -> [u8; TAG_BYTES] {
    let fates: Vec<u8> = fate_bitmap.iter().flat_map(|w| w.to_be_bytes()).collect();
    let bools: zeroize::Zeroizing<Vec<bool>> =
        zeroize::Zeroizing::new(key_bits.iter().map(|&b| b & 1 == 1).collect());
    let mut nonce = [0u8; 16];
    nonce[..4].copy_from_slice(&session.to_be_bytes());
    let context = ConfirmationContext {
        session_id: session,
        config_digest: *config_digest,
        fate_bitmap: &fates,
        nonce,
    };
    ConfirmationTag::compute(&BitString::from_bools(&bools), &context).0
}

/// The tag of a session's key under its plan and fates.
#[must_use]
pub fn session_tag(
    plan: &super::SessionPlan,
    fates: &super::FateLedger,
    key: &[u8],
) -> [u8; TAG_BYTES] {
    confirmation_tag(plan.session, &plan.config_digest, &fates.bitmap(), key)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tag_binds_key_fates_and_session() {
        let key: Vec<u8> = (0..345).map(|i| ((i * 7 + 3) % 5 % 2) as u8).collect();
        let base = confirmation_tag(7, &[1; 32], &[0b1011], &key);
        let mut flipped = key.clone();
        flipped[100] ^= 1;
        assert_ne!(confirmation_tag(7, &[1; 32], &[0b1011], &flipped), base);
        assert_ne!(confirmation_tag(7, &[1; 32], &[0b1010], &key), base);
        assert_ne!(confirmation_tag(8, &[1; 32], &[0b1011], &key), base);
        assert_eq!(confirmation_tag(7, &[1; 32], &[0b1011], &key), base);
    }
}
