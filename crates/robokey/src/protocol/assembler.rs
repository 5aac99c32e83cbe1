//! Collects per-step bit decisions into codewords.

/// A completed received codeword (key material: its `Debug` omits the bits).
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct ReceivedWord {
    /// Codeword index i.
    pub index: u32,
    /// The decided bits, bit j = step `n_c·i + j`.
    pub word: u64,
    /// Whether any of its steps was erased.
    pub erased: bool,
}

impl std::fmt::Debug for ReceivedWord {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ReceivedWord")
            .field("index", &self.index)
            .field("erased", &self.erased)
            .finish_non_exhaustive()
    }
}

/// Assembles bits, pushed in step order, into codewords of `n` bits; steps past the last
/// complete codeword are ignored. The partial codeword is zeroized on drop and never
/// printed.
#[derive(Clone, zeroize::Zeroize, zeroize::ZeroizeOnDrop)]
pub struct CodewordAssembler {
    n: u32,
    codewords: u32,
    word: u64,
    erased: bool,
}

impl std::fmt::Debug for CodewordAssembler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CodewordAssembler")
            .field("n", &self.n)
            .field("codewords", &self.codewords)
            .finish_non_exhaustive()
    }
}

impl CodewordAssembler {
    /// An assembler for `codewords` codewords of `n` bits.
    #[must_use]
    pub fn new(n: u32, codewords: u32) -> Self {
        Self {
            n,
            codewords,
            word: 0,
            erased: false,
        }
    }

    /// Adds the decision for `step` (`None` = erased); returns the codeword it completes.
    pub fn push(&mut self, step: u32, bit: Option<u8>) -> Option<ReceivedWord> {
        let (index, position) = (step / self.n, step % self.n);
        if index >= self.codewords {
            return None;
        }
        match bit {
            Some(b) => self.word |= u64::from(b & 1) << position,
            None => self.erased = true,
        }
        (position + 1 == self.n).then(|| {
            let done = ReceivedWord {
                index,
                word: self.word,
                erased: self.erased,
            };
            self.word = 0;
            self.erased = false;
            done
        })
    }
}
