//! Fragmentation of encoded post-processing messages into chunks that fit one datagram, and
//! their reassembly (docs/postprocessing.md, "Encoding"). The sender gives every transmission
//! (retransmissions included) a fresh message id, so the receiver never merges two
//! transmissions: a message whose fragments were lost is simply never completed, and the
//! endpoint's retransmission sends it again whole under a new id.

use std::collections::VecDeque;

/// Largest chunk of one fragment (bytes); equal to the core wire format's
/// `MAX_POST_FRAGMENT_BYTES`.
pub const FRAGMENT_BYTES: usize = 1024;

/// Most fragments of one message; equal to the core wire format's `MAX_POST_FRAGMENTS`.
pub const MAX_FRAGMENTS: usize = 1024;

/// Longest encoded message that can be sent (bytes): 1 MiB.
pub const MAX_MESSAGE_BYTES: usize = FRAGMENT_BYTES * MAX_FRAGMENTS;

/// Messages the [`Reassembler`] collects at once; a fragment of a further one drops the
/// oldest (by its first fragment's arrival).
const IN_PROGRESS: usize = 4;

/// Completed message ids the [`Reassembler`] remembers, so late duplicates do not deliver
/// a message again.
const REMEMBERED: usize = 64;

/// Whether an encoded message of `encoded_len` bytes can be fragmented: 1 to
/// [`MAX_MESSAGE_BYTES`].
#[must_use]
pub fn fits(encoded_len: usize) -> bool {
    (1..=MAX_MESSAGE_BYTES).contains(&encoded_len)
}

/// Splits `encoded` into `(index, count, chunk)`: chunks of [`FRAGMENT_BYTES`], the last one
/// shorter, `index` from 0 to `count − 1`. An input that does not [`fits`] (empty, or over
/// [`MAX_MESSAGE_BYTES`]) gives no fragment at all: check [`fits`] before sending.
pub fn fragments(encoded: &[u8]) -> impl Iterator<Item = (u16, u16, &[u8])> {
    let sendable: &[u8] = if fits(encoded.len()) { encoded } else { &[] };
    let chunks = sendable.chunks(FRAGMENT_BYTES);
    // At most MAX_FRAGMENTS (1024) chunks, so count and index fit a u16.
    let count = chunks.len() as u16;
    chunks
        .enumerate()
        .map(move |(index, chunk)| (index as u16, count, chunk))
}

/// Collects fragments into whole messages, in bounded memory: at most 4 messages in
/// progress, each at most `count ×` [`FRAGMENT_BYTES`] bytes, and the ids of the last 64
/// completed messages.
#[derive(Debug, Default)]
pub struct Reassembler {
    /// Messages in progress, oldest first.
    partial: VecDeque<Partial>,
    /// Ids of the last completed messages, oldest first.
    completed: VecDeque<u32>,
}

/// One message in progress.
#[derive(Debug)]
struct Partial {
    message: u32,
    /// Chunks received, by index (`count` slots).
    chunks: Vec<Option<Vec<u8>>>,
    /// Slots filled.
    received: usize,
}

impl Reassembler {
    /// An empty reassembler.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes fragment `index` of `count` of message `message`; returns the whole message
    /// once its last missing fragment arrives, once per id. Ignored (`None`, nothing kept):
    /// `count` outside 1 to [`MAX_FRAGMENTS`], `index ≥ count`, an empty chunk, a chunk
    /// longer than [`FRAGMENT_BYTES`] or, other than the last, shorter; a `count` other than
    /// the message's first fragment's; a duplicate; a fragment of one of the last 64
    /// completed messages.
    pub fn accept(
        &mut self,
        message: u32,
        index: u16,
        count: u16,
        bytes: &[u8],
    ) -> Option<Vec<u8>> {
        let (index, count) = (usize::from(index), usize::from(count));
        let well_formed = (1..=MAX_FRAGMENTS).contains(&count)
            && index < count
            && !bytes.is_empty()
            && bytes.len() <= FRAGMENT_BYTES
            && (index + 1 == count || bytes.len() == FRAGMENT_BYTES);
        if !well_formed || self.completed.contains(&message) {
            return None;
        }
        let at = match self.partial.iter().position(|p| p.message == message) {
            Some(at) if self.partial[at].chunks.len() != count => return None,
            Some(at) => at,
            None => {
                if self.partial.len() == IN_PROGRESS {
                    self.partial.pop_front();
                }
                self.partial.push_back(Partial {
                    message,
                    chunks: vec![None; count],
                    received: 0,
                });
                self.partial.len() - 1
            }
        };
        let partial = &mut self.partial[at];
        if partial.chunks[index].is_some() {
            return None;
        }
        partial.chunks[index] = Some(bytes.to_vec());
        partial.received += 1;
        if partial.received < count {
            return None;
        }
        let done = self.partial.remove(at)?;
        if self.completed.len() == REMEMBERED {
            self.completed.pop_front();
        }
        self.completed.push_back(message);
        Some(done.chunks.into_iter().flatten().flatten().collect())
    }

    /// Bytes held by messages in progress (for tests of the memory bound).
    #[cfg(test)]
    fn held(&self) -> usize {
        self.partial
            .iter()
            .flat_map(|p| p.chunks.iter().flatten())
            .map(Vec::len)
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::ChaCha8Rng;
    use rand::seq::SliceRandom;
    use rand::{RngExt, SeedableRng};

    #[test]
    fn fragments_cover_the_message_in_order() {
        for len in [1, 1023, 1024, 1025, 3000, MAX_MESSAGE_BYTES] {
            let message: Vec<u8> = (0..len).map(|i| i as u8).collect();
            let parts: Vec<_> = fragments(&message).collect();
            assert_eq!(parts.len(), len.div_ceil(FRAGMENT_BYTES), "{len}");
            for (i, (index, count, chunk)) in parts.iter().enumerate() {
                assert_eq!((usize::from(*index), usize::from(*count)), (i, parts.len()));
                assert!(!chunk.is_empty() && chunk.len() <= FRAGMENT_BYTES);
            }
            let joined: Vec<u8> = parts.iter().flat_map(|p| p.2.iter().copied()).collect();
            assert_eq!(joined, message);
        }
        assert!(!fits(0) && fits(1) && fits(MAX_MESSAGE_BYTES) && !fits(MAX_MESSAGE_BYTES + 1));
        assert_eq!(fragments(&[]).count(), 0);
        assert_eq!(fragments(&vec![0; MAX_MESSAGE_BYTES + 1]).count(), 0);
    }

    /// Lossy, duplicating, reordering delivery of fragments of two transmissions at a time,
    /// each message re-sent whole under a fresh id until it arrives.
    #[test]
    fn lossy_delivery_gives_every_message_exactly_once() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let messages: Vec<Vec<u8>> = (0..300)
            .map(|_| {
                let len = rng.random_range(1..6 * FRAGMENT_BYTES);
                (0..len).map(|_| rng.random()).collect()
            })
            .collect();
        let mut reassembler = Reassembler::new();
        let mut delivered: Vec<Vec<u8>> = Vec::new();
        let mut next_id = 0u32;
        let mut resent = 0;
        for pair in messages.chunks(2) {
            let mut pending: Vec<&Vec<u8>> = pair.iter().collect();
            while !pending.is_empty() {
                let mut wire = Vec::new();
                let mut ids = Vec::new();
                for message in &pending {
                    next_id += 1;
                    ids.push((next_id, *message));
                    for (index, count, chunk) in fragments(message) {
                        for _ in 0..rng.random_range(1..=2) {
                            if !rng.random_bool(0.1) {
                                wire.push((next_id, index, count, chunk.to_vec()));
                            }
                        }
                    }
                }
                wire.shuffle(&mut rng);
                let mut got = Vec::new();
                for (id, index, count, chunk) in &wire {
                    if let Some(whole) = reassembler.accept(*id, *index, *count, chunk) {
                        got.push((*id, whole));
                    }
                }
                // Late duplicates of every fragment sent deliver nothing more.
                for (id, index, count, chunk) in &wire {
                    assert_eq!(reassembler.accept(*id, *index, *count, chunk), None);
                }
                for (id, whole) in got {
                    let (_, sent) = ids.iter().find(|(i, _)| *i == id).unwrap();
                    assert_eq!(&whole, *sent);
                    delivered.push(whole);
                }
                pending.retain(|m| !delivered.contains(m));
                resent += pending.len();
            }
        }
        // Every message exactly once (they may arrive in either order within a pair).
        let sorted = |mut v: Vec<Vec<u8>>| {
            v.sort();
            v
        };
        assert_eq!(sorted(delivered), sorted(messages));
        // The losses did make some transmissions fail and be repeated.
        assert!(resent > 50, "{resent}");
        assert!(reassembler.partial.len() <= IN_PROGRESS);
    }

    #[test]
    fn malformed_and_mismatched_fragments_are_ignored_without_growth() {
        let full = vec![7; FRAGMENT_BYTES];
        let mut r = Reassembler::new();
        for (index, count, bytes) in [
            (0, 0, &full[..1]),
            (3, 3, &full[..1]),
            (0, MAX_FRAGMENTS as u16 + 1, &full[..]),
            (0, 1, &[][..]),
            (0, 2, &full[..10]),
        ] {
            assert_eq!(r.accept(1, index, count, bytes), None);
        }
        let oversized = vec![7; FRAGMENT_BYTES + 1];
        assert_eq!(r.accept(1, 0, 1, &oversized), None);
        assert_eq!((r.partial.len(), r.held()), (0, 0));
        // Message 2 declares 3 fragments; a fragment claiming 2 (or 1) is not taken.
        assert_eq!(r.accept(2, 0, 3, &full), None);
        assert_eq!(r.accept(2, 1, 2, &full), None);
        assert_eq!(r.accept(2, 0, 1, &[1]), None);
        assert_eq!(r.accept(2, 0, 3, &full), None);
        assert_eq!(r.held(), FRAGMENT_BYTES);
        assert_eq!(r.accept(2, 2, 3, &[9]), None);
        let whole = r.accept(2, 1, 3, &full).unwrap();
        assert_eq!(whole.len(), 2 * FRAGMENT_BYTES + 1);
        // Many half-sent large messages: at most four kept, each within its count.
        for id in 100..200 {
            for index in 0..MAX_FRAGMENTS as u16 / 2 {
                r.accept(id, index, MAX_FRAGMENTS as u16, &full);
            }
            assert!(r.partial.len() <= IN_PROGRESS);
            assert!(r.held() <= IN_PROGRESS * MAX_MESSAGE_BYTES / 2);
        }
        // The oldest was dropped: completing message 100 now needs all of it again.
        assert!(r.partial.iter().all(|p| p.message >= 196));
    }

    #[test]
    fn completed_ids_are_remembered_for_the_last_64() {
        let mut r = Reassembler::new();
        for id in 0..=REMEMBERED as u32 {
            assert_eq!(r.accept(id, 0, 1, &[1]), Some(vec![1]));
        }
        assert_eq!(r.accept(REMEMBERED as u32, 0, 1, &[1]), None);
        assert_eq!(r.accept(1, 0, 1, &[1]), None);
        // Id 0 fell out of the memory; ids are never reused by a sender.
        assert_eq!(r.accept(0, 0, 1, &[1]), Some(vec![1]));
    }
}
