//! Arbitrary bytes to the post-processing decoder (what decodes must re-encode to the same
//! bytes), and the same bytes read as a sequence of fragments for a `Reassembler`: nothing may
//! panic, no message id is delivered twice, and a delivered message is within its bound.
#![no_main]

use std::collections::HashSet;

use libfuzzer_sys::arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;
use robokey_secrecy::postprocess::{
    FRAGMENT_BYTES, MAX_FRAGMENTS, Reassembler, decode, encode, fragments,
};

fuzz_target!(|data: &[u8]| {
    if let Ok(message) = decode(data) {
        assert_eq!(encode(&message), data, "{message:?} is not canonical");
    }
    // The input itself, fragmented and fed back to front, comes back whole.
    let mut reassembler = Reassembler::new();
    let parts: Vec<_> = fragments(data).collect();
    let back = parts
        .iter()
        .rev()
        .filter_map(|&(index, count, chunk)| reassembler.accept(0, index, count, chunk))
        .collect::<Vec<_>>();
    assert_eq!(back.len(), usize::from(!data.is_empty()));
    assert!(back.iter().all(|whole| whole == data));
    let _ = feed(&mut Unstructured::new(data));
});

/// Fragments of eight message ids (few enough that the reassembler remembers every completed
/// one), with arbitrary indices, counts and chunks.
fn feed(u: &mut Unstructured<'_>) -> Result<()> {
    let mut reassembler = Reassembler::new();
    let mut delivered = HashSet::new();
    while !u.is_empty() {
        let message = u.int_in_range(0..=7)?;
        let count: u16 = if u.arbitrary()? {
            u.int_in_range(0..=4)?
        } else {
            u.arbitrary()?
        };
        let index = u.int_in_range(0..=count.saturating_add(1))?;
        let len = if u.arbitrary()? {
            FRAGMENT_BYTES
        } else {
            u.int_in_range(0..=FRAGMENT_BYTES + 1)?
        };
        let bytes = u.bytes(len.min(u.len()))?;
        if let Some(whole) = reassembler.accept(message, index, count, bytes) {
            assert!(
                delivered.insert(message),
                "message {message} delivered twice"
            );
            assert!(usize::from(count) <= MAX_FRAGMENTS);
            assert!(!whole.is_empty() && whole.len() <= usize::from(count) * FRAGMENT_BYTES);
        }
    }
    Ok(())
}
