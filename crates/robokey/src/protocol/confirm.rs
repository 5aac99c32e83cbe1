//! Key-confirmation tags (SPEC §4b, SECRECY §4).

use sha2::{Digest, Sha256};

/// Tag length (bytes): 64 bits, so a wrong key passes with probability 2⁻⁶⁴.
pub const TAG_BYTES: usize = 8;

/// `SHA-256("robokey confirm v1" ‖ session ‖ config digest ‖ fate bitmap ‖ key)` truncated
/// to 64 bits. Public data binds the tag to this session; the 64 bits it reveals about the
/// key are counted as leak by the secrecy accounting.
#[must_use]
pub fn confirmation_tag(
    session: u32,
    config_digest: &[u8; 32],
    fate_bitmap: &[u64],
    key_bits: &[u8],
) -> [u8; TAG_BYTES] {
    let mut hasher = Sha256::new();
    hasher.update(b"robokey confirm v1");
    hasher.update(session.to_be_bytes());
    hasher.update(config_digest);
    hasher.update((fate_bitmap.len() as u64).to_be_bytes());
    for word in fate_bitmap {
        hasher.update(word.to_be_bytes());
    }
    hasher.update((key_bits.len() as u64).to_be_bytes());
    let mut packed = zeroize::Zeroizing::new(vec![0u8; key_bits.len().div_ceil(8)]);
    for (i, bit) in key_bits.iter().enumerate() {
        packed[i / 8] |= (bit & 1) << (i % 8);
    }
    hasher.update(packed.as_slice());
    let digest = hasher.finalize();
    let mut tag = [0u8; TAG_BYTES];
    tag.copy_from_slice(&digest[..TAG_BYTES]);
    tag
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_single_bit_difference_changes_the_tag() {
        let key: Vec<u8> = (0..345).map(|i| ((i * 7 + 3) % 5 % 2) as u8).collect();
        let base = confirmation_tag(7, &[1; 32], &[0b1011], &key);
        for i in 0..key.len() {
            let mut other = key.clone();
            other[i] ^= 1;
            assert_ne!(
                confirmation_tag(7, &[1; 32], &[0b1011], &other),
                base,
                "bit {i}"
            );
        }
        assert_ne!(confirmation_tag(7, &[1; 32], &[0b1010], &key), base);
        assert_ne!(confirmation_tag(8, &[1; 32], &[0b1011], &key), base);
    }
}
