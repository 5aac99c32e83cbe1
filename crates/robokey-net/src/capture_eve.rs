//! Eavesdroppers on a relay capture: the same Eve code as the simulator, fed the frames in
//! the order they crossed the network.

use std::path::Path;

use robokey::Config;
use robokey::config::EveStrategy;
use robokey::eve::{Eavesdropper, Eve, ModelErrors};
use robokey::model::DiffDrive;
use robokey::private::{DoubletEavesdropper, Eavesdroppers, EveDoublet};
use robokey::protocol::auth::{AuthMode, PairingSecret};
use robokey::protocol::wire::{Frame, decode};
use robokey::protocol::{
    Closing, Confirmer, Handshake, KeyBits, Message, SessionPlan, agreement_terms, config_digest,
    terms_difference,
};

use crate::error::NetError;
use crate::pcap;
use crate::pose_stream::CameraLog;

/// The frames of one session in a capture, in the order they crossed the network.
#[derive(Debug)]
pub struct CapturedSession {
    /// Session id.
    pub session: u32,
    /// Its valid frames' messages (duplicates included, as heard).
    pub messages: Vec<Message>,
    /// Datagrams that did not decode.
    pub undecodable: usize,
    /// What the capture held that could not be read ([`pcap::Capture::shortfalls`]).
    pub shortfalls: Vec<String>,
    /// The reason of the session's first `Abort`, if it was aborted: then no key was agreed,
    /// whatever bits an eavesdropper collected.
    pub aborted: Option<String>,
    /// An `--unauthenticated` session's confirmer: its keys come from the public secret and
    /// the nonces on the wire, so the eavesdropper can compute the tags too. `None` for a
    /// paired session.
    pub public_confirmer: Option<Confirmer>,
}

/// What one eavesdropper made of a captured session.
#[derive(Debug)]
pub struct CaptureResult {
    /// Her decision per step (`None`: erased or never decided), index = step.
    pub decisions: Vec<Option<u8>>,
    /// Her key `K_a` (messages of the acked codewords).
    pub key: KeyBits,
    /// Codewords she flipped to match the confirmation tag, when she verified her key.
    pub tag_flips: Option<u32>,
    /// Her wheel model at the end (m).
    pub model: DiffDrive,
}

/// Reads the first session in `capture`, checking that `config` agrees with its `Hello`
/// (when the capture holds one).
///
/// # Errors
/// The capture cannot be read, holds no session, or its terms differ from `config`.
pub fn read_session(capture: &Path, config: &Config) -> Result<CapturedSession, NetError> {
    let pcap::Capture {
        datagrams,
        shortfalls,
    } = pcap::read(capture)?;
    let frames: Vec<_> = datagrams
        .iter()
        .filter_map(|d| decode(&d.payload).ok().map(|f| (f, d.payload.as_slice())))
        .collect();
    let undecodable = datagrams.len() - frames.len();
    let session = frames
        .iter()
        .find(|(f, _)| matches!(f.message, Message::Handshake(Handshake::Hello { .. })))
        .or(frames.first())
        .map(|(f, _)| f.session)
        .ok_or_else(|| NetError::Capture {
            path: capture.display().to_string(),
            message: "no robokey frame in the capture".into(),
        })?;
    let frames: Vec<_> = frames
        .into_iter()
        .filter(|(f, _)| f.session == session)
        .collect();
    let public_confirmer = public_confirmer(&frames);
    let messages: Vec<Message> = frames.into_iter().map(|(f, _)| f.message).collect();
    for message in &messages {
        if let Message::Handshake(Handshake::Hello {
            config_digest: digest,
            terms,
            ..
        }) = message
            && *digest != config_digest(config)
        {
            return Err(NetError::Usage(format!(
                "the captured session used other terms than the given config: {} (pass the session's --config)",
                terms_difference(&agreement_terms(config), terms, "--config", "the capture")
            )));
        }
    }
    let aborted = messages.iter().find_map(|m| match m {
        Message::Closing(Closing::Abort { reason }) => Some(reason.clone()),
        _ => None,
    });
    Ok(CapturedSession {
        session,
        messages,
        undecodable,
        shortfalls,
        aborted,
        public_confirmer,
    })
}

/// The confirmer of an unauthenticated session's handshake (its first `Hello` and the
/// `HelloAck` answering it), with the public secret's keys.
fn public_confirmer(frames: &[(Frame, &[u8])]) -> Option<Confirmer> {
    let (nonce_c, hello) = frames.iter().find_map(|(f, bytes)| match f.message {
        Message::Handshake(Handshake::Hello {
            auth: AuthMode::Unauthenticated,
            nonce,
            ..
        }) => Some((nonce, *bytes)),
        _ => None,
    })?;
    let (nonce_r, ack) = frames.iter().find_map(|(f, bytes)| match f.message {
        Message::Handshake(Handshake::HelloAck {
            nonce_c: echoed,
            nonce_r,
            ..
        }) if echoed == nonce_c => Some((nonce_r, *bytes)),
        _ => None,
    })?;
    let keys = PairingSecret::unauthenticated().session_keys(&nonce_c, &nonce_r);
    Some(Confirmer::new(keys, [hello, ack].concat()))
}

/// Runs an eavesdropper of `strategy`, starting from `errors`, on a captured session.
#[must_use]
pub fn listen(
    captured: &CapturedSession,
    config: &Config,
    strategy: EveStrategy,
    errors: ModelErrors,
) -> CaptureResult {
    let mut plan = SessionPlan::from_config(config, captured.session);
    if let Some(confirmer) = &captured.public_confirmer {
        plan.agreed.confirmer = confirmer.clone();
    }
    let mut eve = Eve::new(config, strategy, errors);
    eve.begin_session(&plan);
    let mut decisions = vec![None; plan.agreed.steps as usize];
    for message in &captured.messages {
        if let Some(decision) = eve.observe(message)
            && let Some(slot) = decisions.get_mut(decision.step as usize)
        {
            *slot = decision.bit;
        }
    }
    CaptureResult {
        decisions,
        key: eve.key(),
        tag_flips: eve.verified(),
        model: eve.model(),
    }
}

/// What the private-sensing eavesdroppers made of a captured session and her camera log.
#[derive(Debug)]
pub struct PrivateCaptureResult {
    /// Every carrying doublet they decided, in doublet order.
    pub doublets: Vec<EveDoublet>,
    /// The `camera` adversary's key: her decisions on the kept doublets.
    pub camera_key: KeyBits,
    /// The `commands` adversary's key.
    pub commands_key: KeyBits,
    /// The kept doublets (the `Finish` bitmap's), in order: whose bits the keys hold.
    pub kept: Vec<u32>,
}

/// Runs the `camera` and `commands` eavesdroppers of private sensing — who know the world of
/// `config` — on a captured session and her camera's record: the same code and decisions as
/// in the simulator. With the robot's raw bits (`robot_bits`: the kept doublets' bits in
/// order, as its key file holds them) each doublet's evidence given the rest of the block's
/// bits is measured too ([`EveDoublet::camera_given_others`]).
#[must_use]
pub fn listen_private(
    captured: &CapturedSession,
    camera: &CameraLog,
    config: &Config,
    robot_bits: Option<&[u8]>,
) -> PrivateCaptureResult {
    let mut eve = DoubletEavesdropper::new(config, Eavesdroppers::Both);
    let kept = kept_doublets(captured, config);
    if let Some(bits) = robot_bits {
        let per = config.protocol.key_bits_per_doublet();
        for (&doublet, chunk) in kept.iter().zip(bits.chunks_exact(per)) {
            let word = chunk
                .iter()
                .enumerate()
                .fold(0, |word, (i, &bit)| word | u64::from(bit & 1) << i);
            eve.reveal(doublet, word);
        }
    }
    match camera {
        CameraLog::Instants(samples) => {
            for sample in samples {
                eve.film(sample.step, sample.pose);
            }
        }
        CameraLog::Frames(frames) => {
            for frame in frames {
                eve.film_frame(*frame);
            }
        }
    }
    for message in &captured.messages {
        eve.observe(message);
    }
    eve.finish();
    let mut doublets: Vec<EveDoublet> = std::iter::from_fn(|| eve.poll()).collect();
    doublets.sort_by_key(|d| d.doublet);
    PrivateCaptureResult {
        doublets,
        camera_key: eve
            .key(true)
            .expect("the camera eavesdropper is always judged"),
        commands_key: eve.key(false).expect("both eavesdroppers are judged"),
        kept,
    }
}

/// The doublets the session's `Finish` kept, in order (none without one).
fn kept_doublets(captured: &CapturedSession, config: &Config) -> Vec<u32> {
    let plan = SessionPlan::from_config(config, captured.session);
    let Some(bitmap) = captured.messages.iter().find_map(|m| match m {
        Message::Closing(Closing::Finish { codewords, bitmap }) if *codewords == plan.units() => {
            Some(bitmap)
        }
        _ => None,
    }) else {
        return Vec::new();
    };
    (0..plan.units())
        .filter(|&j| {
            let j = j as usize;
            bitmap.get(j / 64).is_some_and(|w| w >> (j % 64) & 1 == 1)
        })
        .collect()
}
