//! The slices of a stored final key (docs/keys.md): which whole bytes of it are taken, which
//! are free, and cutting one out. A taken slice's bytes are erased (zero) in the key's hex,
//! so that no later read of the file — by robokey, or by whoever reads the store afterwards —
//! finds them; the list of taken spans says which zeros are erasures.

use zeroize::{Zeroize as _, Zeroizing};

use super::StoredKey;
use crate::key_slice::Span;

impl StoredKey {
    /// The bits slices may cover: the key's length rounded down to whole bytes.
    #[must_use]
    pub fn sliceable_bits(&self) -> u64 {
        (self.bits as u64) / 8 * 8
    }

    /// Bits taken so far.
    #[must_use]
    pub fn taken_bits(&self) -> u64 {
        self.taken.iter().map(|span| u64::from(span.bits)).sum()
    }

    /// Bits not taken yet (whole bytes only).
    #[must_use]
    pub fn untaken_bits(&self) -> u64 {
        self.sliceable_bits() - self.taken_bits()
    }

    /// The first bit after every taken slice: where the controller side cuts its next slice
    /// (it cuts in order, so everything before is taken).
    #[must_use]
    pub fn cursor(&self) -> u64 {
        self.taken.iter().map(Span::end).max().unwrap_or(0)
    }

    /// The runs of free whole bytes, in order.
    #[must_use]
    pub fn free_runs(&self) -> Vec<(u64, u64)> {
        let mut runs = Vec::new();
        let mut start = 0;
        for span in &self.taken {
            if u64::from(span.offset) > start {
                runs.push((start, u64::from(span.offset)));
            }
            start = start.max(span.end());
        }
        if self.sliceable_bits() > start {
            runs.push((start, self.sliceable_bits()));
        }
        runs
    }

    /// Whether the taken spans are what [`Self::cut`] leaves: whole bytes within the key, in
    /// order, none overlapping, none empty.
    #[must_use]
    pub fn taken_spans_fit(&self) -> bool {
        let mut previous_end = 0;
        self.taken.iter().all(|span| {
            let fits = span.bits > 0
                && span.offset.is_multiple_of(8)
                && span.bits.is_multiple_of(8)
                && u64::from(span.offset) >= previous_end
                && span.end() <= self.sliceable_bits();
            previous_end = span.end();
            fits
        })
    }

    /// Why `span` cannot be cut from this key, if it cannot: it reaches past the key, or
    /// shares bits with a taken slice.
    #[must_use]
    pub fn refusal(&self, span: &Span) -> Option<String> {
        if span.end() > self.sliceable_bits() {
            return Some(format!(
                "bits {}..{} reach past final key {} ({} bits)",
                span.offset,
                span.end(),
                self.id,
                self.bits
            ));
        }
        let taken = self.taken.iter().find(|t| t.overlaps(span))?;
        Some(if taken == span {
            format!("was delivered already (taken from final key {})", self.id)
        } else {
            format!(
                "shares bits with a key delivered already (bits {}..{} of final key {})",
                taken.offset,
                taken.end(),
                self.id
            )
        })
    }

    /// Cuts `span` out: returns its bytes, erases them from the key and marks them taken.
    /// Whether the key may be delivered (settled) is the caller's to check.
    ///
    /// # Errors
    /// [`Self::refusal`]'s reason; the key is then unchanged.
    pub fn cut(&mut self, span: Span) -> Result<Zeroizing<Vec<u8>>, String> {
        if let Some(refusal) = self.refusal(&span) {
            return Err(refusal);
        }
        let mut bytes = self.bytes();
        let slice = Zeroizing::new(bytes[span.bytes()].to_vec());
        bytes[span.bytes()].zeroize();
        self.hex.zeroize();
        self.hex = base16ct::lower::encode_string(&bytes);
        let at = self.taken.partition_point(|t| t.offset < span.offset);
        self.taken.insert(at, span);
        Ok(slice)
    }

    /// The hex with the bytes of `spans` erased (for comparing keys whatever was taken).
    pub(super) fn erased_hex(&self, spans: &[Span]) -> Zeroizing<String> {
        let mut bytes = self.bytes();
        for span in spans {
            let range = span.bytes();
            if range.end <= bytes.len() {
                bytes[range].zeroize();
            }
        }
        Zeroizing::new(base16ct::lower::encode_string(&bytes))
    }

    /// The key's bytes (empty if its hex is malformed: a verified file never is).
    fn bytes(&self) -> Zeroizing<Vec<u8>> {
        Zeroizing::new(base16ct::mixed::decode_vec(&self.hex).unwrap_or_default())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::key_store::KeyStatus;

    fn key(bits: usize, hex: &str) -> StoredKey {
        StoredKey {
            id: "00112233aabbccdd".into(),
            role: "robot".into(),
            block: 0,
            bits,
            hex: hex.into(),
            epsilon: 4e-6,
            assumption: "stated".into(),
            restricted: false,
            basis: None,
            reconciliation: None,
            created: "2026-01-01T00:00:00Z".into(),
            sessions: vec![1],
            status: KeyStatus::Settled,
            taken: Vec::new(),
        }
    }

    fn span(offset: u32, bits: u32) -> Span {
        Span { offset, bits }
    }

    #[test]
    fn a_cut_returns_its_bytes_erases_them_and_is_refused_again() {
        // 35 bits: four whole bytes are sliceable, the last three bits never are.
        let mut key = key(35, "0123456789");
        assert_eq!(key.sliceable_bits(), 32);
        assert_eq!(*key.cut(span(8, 16)).unwrap(), [0x23, 0x45]);
        assert_eq!(key.hex, "0100006789");
        assert_eq!(key.taken, [span(8, 16)]);
        assert_eq!(
            (key.taken_bits(), key.untaken_bits(), key.cursor()),
            (16, 16, 24)
        );
        assert_eq!(key.free_runs(), [(0, 8), (24, 32)]);
        assert!(key.taken_spans_fit());
        let again = key.refusal(&span(8, 16)).unwrap();
        assert!(again.contains("delivered already"), "{again}");
        let overlap = key.refusal(&span(16, 16)).unwrap();
        assert!(overlap.contains("shares bits"), "{overlap}");
        let past = key.cut(span(24, 16)).unwrap_err();
        assert!(past.contains("reach past"), "{past}");
        assert_eq!(key.hex, "0100006789", "a refused cut changes nothing");
        assert_eq!(*key.cut(span(0, 8)).unwrap(), [0x01]);
        assert_eq!(key.taken, [span(0, 8), span(8, 16)]);
        assert_eq!(*key.cut(span(24, 8)).unwrap(), [0x67]);
        assert_eq!(key.hex, "0000000089");
        assert_eq!((key.untaken_bits(), key.free_runs()), (0, vec![]));
    }

    #[test]
    fn a_key_compares_equal_to_itself_whatever_was_taken() {
        let whole = key(32, "01234567");
        let mut sliced = whole.clone();
        sliced.cut(span(8, 8)).unwrap();
        assert!(whole.same_key(&sliced) && sliced.same_key(&whole));
        let mut other = key(32, "01ff4567");
        assert!(!whole.same_key(&other));
        // The difference lies in the taken byte only: no bit that remains differs.
        assert!(sliced.same_key(&other));
        other.hex = "01234568".into();
        assert!(!sliced.same_key(&other));
    }

    #[test]
    fn taken_spans_that_no_cut_leaves_do_not_fit() {
        for taken in [
            vec![span(0, 0)],
            vec![span(4, 8)],
            vec![span(0, 12)],
            vec![span(8, 8), span(0, 8)],
            vec![span(0, 16), span(8, 8)],
            vec![span(24, 16)],
        ] {
            let mut key = key(32, "01234567");
            key.taken = taken.clone();
            assert!(!key.taken_spans_fit(), "{taken:?}");
        }
    }
}
