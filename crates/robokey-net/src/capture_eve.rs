//! The paper's eavesdropper on a relay capture: the same Eve code as the simulator, fed the
//! frames in the order they crossed the network.

use std::path::Path;

use robokey::Config;
use robokey::eve::{Eavesdropper, ModelErrors, PaperEve};
use robokey::protocol::wire::decode;
use robokey::protocol::{
    KeyBits, Message, SessionPlan, agreement_terms, config_digest, terms_difference,
};

use crate::error::NetError;
use crate::pcap;

/// What Eve made of a capture.
#[derive(Debug)]
pub struct CaptureResult {
    /// Session id she followed.
    pub session: u32,
    /// Valid frames of that session (duplicates included, as heard).
    pub frames: usize,
    /// Datagrams that did not decode.
    pub undecodable: usize,
    /// Her decision per step (`None`: erased or never decided), index = step.
    pub decisions: Vec<Option<u8>>,
    /// Her key `K_a` (messages of the acked codewords).
    pub key: KeyBits,
}

/// Runs Eve with `errors` on the first session in `capture`, under `config` (which must
/// agree with the session's `Hello`, when the capture holds one).
///
/// # Errors
/// The capture cannot be read, holds no session, or its terms differ from `config`.
pub fn eve_on_capture(
    capture: &Path,
    config: &Config,
    errors: ModelErrors,
) -> Result<CaptureResult, NetError> {
    let datagrams = pcap::read(capture)?;
    let frames: Vec<_> = datagrams
        .iter()
        .filter_map(|d| decode(&d.payload).ok())
        .collect();
    let undecodable = datagrams.len() - frames.len();
    let session = frames
        .iter()
        .find(|f| matches!(f.message, Message::Hello { .. }))
        .or(frames.first())
        .map(|f| f.session)
        .ok_or_else(|| NetError::Capture {
            path: capture.display().to_string(),
            message: "no robokey frame in the capture".into(),
        })?;
    for frame in frames.iter().filter(|f| f.session == session) {
        if let Message::Hello {
            config_digest: digest,
            terms,
            ..
        } = &frame.message
            && *digest != config_digest(config)
        {
            return Err(NetError::Usage(format!(
                "the captured session used other terms than the given config: {} (pass the session's --config)",
                terms_difference(&agreement_terms(config), terms, "--config", "the capture")
            )));
        }
    }
    let plan = SessionPlan::from_config(config, session);
    let mut eve = PaperEve::new(config, &plan, errors);
    let mut decisions = vec![None; plan.steps as usize];
    let mut count = 0;
    for frame in frames.iter().filter(|f| f.session == session) {
        count += 1;
        if let Some(decision) = eve.observe(&frame.message)
            && let Some(slot) = decisions.get_mut(decision.step as usize)
        {
            *slot = decision.bit;
        }
    }
    Ok(CaptureResult {
        session,
        frames: count,
        undecodable,
        decisions,
        key: eve.key(),
    })
}
