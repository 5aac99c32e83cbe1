//! What both endpoints keep: the settings, a nonce generator, the sessions pooled and spent,
//! the committed blocks and the outputs not yet polled.

use std::collections::{BTreeSet, VecDeque};

use rand::rngs::ChaCha20Rng;
use rand::{Rng, SeedableRng};

use super::{MAX_SESSION_BITS, Output, Pool, PostError, Settings};
use crate::bitstring::BitString;

pub(super) struct Ledger {
    pub(super) settings: Settings,
    rng: ChaCha20Rng,
    pub(super) pool: Pool,
    pub(super) spent: BTreeSet<u32>,
    /// Blocks whose keys were committed (the keys themselves go to the shell's store).
    pub(super) committed: BTreeSet<u64>,
    pub(super) outputs: VecDeque<Output>,
}

impl Ledger {
    /// An empty ledger; `rng_seed` seeds the nonces.
    pub(super) fn new(settings: Settings, rng_seed: [u8; 32]) -> Result<Self, PostError> {
        settings.check()?;
        Ok(Self {
            settings,
            rng: ChaCha20Rng::from_seed(rng_seed),
            pool: Pool::new(),
            spent: BTreeSet::new(),
            committed: BTreeSet::new(),
            outputs: VecDeque::new(),
        })
    }

    /// A ledger from stored parts.
    pub(super) fn restore(
        settings: Settings,
        rng_seed: [u8; 32],
        pool: Vec<(u32, BitString)>,
        spent: Vec<u32>,
        committed: Vec<u64>,
    ) -> Result<Self, PostError> {
        let mut ledger = Self::new(settings, rng_seed)?;
        ledger.pool = pool.into_iter().collect();
        ledger.spent = spent.into_iter().collect();
        ledger.committed = committed.into_iter().collect();
        Ok(ledger)
    }

    /// Pools a session unless its size is out of bounds or its ID was seen.
    pub(super) fn add_session(&mut self, id: u32, bits: BitString) -> Result<(), PostError> {
        if bits.is_empty() || bits.len() > MAX_SESSION_BITS {
            return Err(PostError::SessionSize {
                id,
                bits: bits.len(),
            });
        }
        if self.pool.contains_key(&id) || self.spent.contains(&id) {
            return Err(PostError::DuplicateSession(id));
        }
        self.pool.insert(id, bits);
        self.outputs.push_back(Output::Persist);
        Ok(())
    }

    /// The pool as stored.
    pub(super) fn stored_pool(&self) -> Vec<(u32, BitString)> {
        self.pool
            .iter()
            .map(|(&id, bits)| (id, bits.clone()))
            .collect()
    }

    /// A fresh 256-bit nonce.
    pub(super) fn nonce(&mut self) -> [u8; 32] {
        let mut nonce = [0_u8; 32];
        self.rng.fill_bytes(&mut nonce);
        nonce
    }
}
