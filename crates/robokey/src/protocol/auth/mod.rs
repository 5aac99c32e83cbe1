//! The session layer's cryptography (`docs/wire.md`, "Authentication"): the pairing secret,
//! the key schedule, frame MACs, and the confirmation tags. No I/O; randomness is passed in.
//!
//! Key schedule, with `S` the 256-bit pairing secret:
//! - handshake key `k_hs = HKDF-SHA256(S, salt = ∅, info = "robokey v2 handshake")`, which
//!   MACs `Hello`, `HelloAck` and `Refuse`;
//! - session keys `k_dir = HKDF-SHA256(S, salt = nonce_c ‖ nonce_r, info = "robokey v2
//!   controller→robot" | "robokey v2 robot→controller")`, which MAC every other frame of
//!   their direction and the confirmation tags.
//!
//! A MAC is HMAC-SHA256 truncated to its first [`TAG_BYTES`] bytes.

mod channel;
mod window;

pub use channel::{
    ChannelCounts, ControllerChannel, Delivery, HALF_OPEN, Rejection, RejectionCounts, RobotChannel,
};
pub use window::{Freshness, ReplayWindow};

use hmac::{Hmac, KeyInit, Mac};
use rand::CryptoRng;
use sha2::{Digest, Sha256};
use subtle::ConstantTimeEq;
use zeroize::Zeroizing;

pub use super::message::{AuthMode, NONCE_BYTES, TAG_BYTES};
use super::wire::{Frame, encode, split_mac};

/// Pairing-secret length (bytes): 256 bits.
pub const SECRET_BYTES: usize = 32;
/// Fingerprint length (bytes).
pub const FINGERPRINT_BYTES: usize = 8;

/// The 256-bit secret shared by a robot and its controller. Zeroized on drop; its `Debug`
/// shows the public fingerprint only.
#[derive(Clone)]
pub struct PairingSecret {
    bytes: Zeroizing<[u8; SECRET_BYTES]>,
    mode: AuthMode,
}

impl std::fmt::Debug for PairingSecret {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "PairingSecret({:?}, {})", self.mode, self.fingerprint())
    }
}

impl PairingSecret {
    /// A fresh secret from `rng` (the OS CSPRNG).
    pub fn generate<R: CryptoRng + ?Sized>(rng: &mut R) -> Self {
        let mut bytes = Zeroizing::new([0u8; SECRET_BYTES]);
        rng.fill_bytes(bytes.as_mut());
        Self {
            bytes,
            mode: AuthMode::Paired,
        }
    }

    /// A secret read from a pairing file.
    #[must_use]
    pub fn from_bytes(bytes: &[u8; SECRET_BYTES]) -> Self {
        Self {
            bytes: Zeroizing::new(*bytes),
            mode: AuthMode::Paired,
        }
    }

    /// The public all-zero secret of `--unauthenticated` sessions (and of the simulator):
    /// frames are checked against faults, not against an attacker.
    #[must_use]
    pub fn unauthenticated() -> Self {
        Self {
            bytes: Zeroizing::new([0; SECRET_BYTES]),
            mode: AuthMode::Unauthenticated,
        }
    }

    /// The secret's bytes, for writing the pairing file.
    #[must_use]
    pub fn expose(&self) -> &[u8; SECRET_BYTES] {
        &self.bytes
    }

    /// Whether it is a real pairing or the public secret.
    #[must_use]
    pub fn mode(&self) -> AuthMode {
        self.mode
    }

    /// Public fingerprint: the first 8 bytes of `SHA-256("robokey pairing fingerprint" ‖
    /// S)`, as hex. Equal on both sides iff they hold the same secret.
    #[must_use]
    pub fn fingerprint(&self) -> String {
        let digest = Sha256::new()
            .chain_update(b"robokey pairing fingerprint")
            .chain_update(self.bytes.as_ref())
            .finalize();
        hex(&digest[..FINGERPRINT_BYTES])
    }

    fn expand(&self, salt: Option<&[u8]>, info: &str) -> MacKey {
        let mut okm = Zeroizing::new([0u8; 32]);
        hkdf::Hkdf::<Sha256>::new(salt, self.bytes.as_ref())
            .expand(info.as_bytes(), okm.as_mut())
            .expect("32 bytes is a valid HKDF-SHA256 output length");
        MacKey(okm)
    }

    /// The handshake key `k_hs`.
    #[must_use]
    pub fn handshake_key(&self) -> MacKey {
        self.expand(None, "robokey v2 handshake")
    }

    /// The session keys of the handshake `(nonce_c, nonce_r)`.
    #[must_use]
    pub fn session_keys(
        &self,
        nonce_c: &[u8; NONCE_BYTES],
        nonce_r: &[u8; NONCE_BYTES],
    ) -> SessionKeys {
        let mut salt = [0u8; 2 * NONCE_BYTES];
        salt[..NONCE_BYTES].copy_from_slice(nonce_c);
        salt[NONCE_BYTES..].copy_from_slice(nonce_r);
        SessionKeys {
            to_robot: self.expand(Some(&salt), Direction::ToRobot.info()),
            to_controller: self.expand(Some(&salt), Direction::ToController.info()),
        }
    }
}

/// A frame as sent: its encoding followed by its MAC under `key`.
#[must_use]
pub fn seal(frame: &Frame, key: &MacKey) -> Vec<u8> {
    let mut bytes = encode(frame);
    let tag = key.tag(&[&bytes]);
    bytes.extend_from_slice(&tag);
    bytes
}

/// Whether a datagram's MAC verifies under `key`.
fn verifies(bytes: &[u8], key: &MacKey) -> bool {
    split_mac(bytes).is_some_and(|(body, mac)| key.verify(&[body], mac))
}

/// Lower-case hex of bytes.
fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Direction of a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// Controller → robot.
    ToRobot,
    /// Robot → controller.
    ToController,
}

impl Direction {
    fn info(self) -> &'static str {
        match self {
            Self::ToRobot => "robokey v2 controller→robot",
            Self::ToController => "robokey v2 robot→controller",
        }
    }

    fn byte(self) -> u8 {
        match self {
            Self::ToRobot => 0,
            Self::ToController => 1,
        }
    }

    /// The other direction.
    #[must_use]
    pub fn reverse(self) -> Self {
        match self {
            Self::ToRobot => Self::ToController,
            Self::ToController => Self::ToRobot,
        }
    }
}

/// A 256-bit HMAC-SHA256 key, zeroized on drop, never printed.
#[derive(Clone)]
pub struct MacKey(Zeroizing<[u8; 32]>);

impl std::fmt::Debug for MacKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("MacKey(..)")
    }
}

impl MacKey {
    /// HMAC-SHA256 over the concatenation of `parts`, truncated to [`TAG_BYTES`].
    #[must_use]
    pub fn tag(&self, parts: &[&[u8]]) -> [u8; TAG_BYTES] {
        let mut mac = <Hmac<Sha256> as KeyInit>::new_from_slice(self.0.as_ref())
            .expect("HMAC takes keys of any length");
        for part in parts {
            mac.update(part);
        }
        let full = mac.finalize().into_bytes();
        let mut tag = [0u8; TAG_BYTES];
        tag.copy_from_slice(&full[..TAG_BYTES]);
        tag
    }

    /// Whether `tag` is the MAC of `parts` (constant-time compare).
    #[must_use]
    pub fn verify(&self, parts: &[&[u8]], tag: &[u8]) -> bool {
        self.tag(parts).ct_eq(tag).into()
    }
}

/// The per-direction session keys of one handshake.
#[derive(Clone, Debug)]
pub struct SessionKeys {
    to_robot: MacKey,
    to_controller: MacKey,
}

impl SessionKeys {
    /// The key of `direction`.
    #[must_use]
    pub fn key(&self, direction: Direction) -> &MacKey {
        match direction {
            Direction::ToRobot => &self.to_robot,
            Direction::ToController => &self.to_controller,
        }
    }
}

/// A side's two confirmation tags.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ConfirmTags {
    /// Over the transcript and the final fate bitmap: both ran the same session and kept
    /// the same positions. Independent of the key bits.
    pub session: [u8; TAG_BYTES],
    /// Over the transcript and the raw key: both hold the same key (128 bits charged as
    /// leak if the key is ever pooled).
    pub key: [u8; TAG_BYTES],
}

/// Computes and checks the confirmation tags of one session (`docs/wire.md`):
/// `MAC(k_dir, label ‖ dir ‖ transcript ‖ data)` with `transcript = Hello ‖ HelloAck` as
/// exact frame bytes, so a tag reflected to its sender fails.
#[derive(Clone, Debug)]
pub struct Confirmer {
    keys: SessionKeys,
    transcript: Vec<u8>,
}

impl Confirmer {
    /// The confirmer of a session with these keys and handshake transcript.
    #[must_use]
    pub fn new(keys: SessionKeys, transcript: Vec<u8>) -> Self {
        Self { keys, transcript }
    }

    /// The simulator's confirmer for session `session` with terms digest `digest`: the
    /// public secret, with nonces and transcript derived from both, so an eavesdropper
    /// holds every key (the worst case: a pairing secret that leaks later).
    #[must_use]
    pub fn public(session: u32, digest: &[u8; 32]) -> Self {
        let mut nonce = [0u8; NONCE_BYTES];
        nonce[..4].copy_from_slice(&session.to_be_bytes());
        let keys = PairingSecret::unauthenticated().session_keys(&nonce, &nonce);
        Self::new(keys, digest.to_vec())
    }

    fn mac(&self, direction: Direction, label: &[u8], data: &[&[u8]]) -> [u8; TAG_BYTES] {
        let dir = [direction.byte()];
        let mut parts: Vec<&[u8]> = vec![label, &dir, &self.transcript];
        parts.extend_from_slice(data);
        self.keys.key(direction).tag(&parts)
    }

    fn session_tag(&self, direction: Direction, fates: &[u64]) -> [u8; TAG_BYTES] {
        let bitmap: Vec<u8> = fates.iter().flat_map(|w| w.to_be_bytes()).collect();
        self.mac(direction, b"robokey v2 confirm", &[&bitmap])
    }

    /// The key tag of `key` (bits as 0/1 bytes) sent in `direction`.
    #[must_use]
    pub fn key_tag(&self, direction: Direction, key: &[u8]) -> [u8; TAG_BYTES] {
        let mut packed = Zeroizing::new(vec![0u8; key.len().div_ceil(8)]);
        for (i, bit) in key.iter().enumerate() {
            packed[i / 8] |= (bit & 1) << (i % 8);
        }
        let length = (key.len() as u64).to_be_bytes();
        self.mac(direction, b"robokey v2 key", &[&length, &packed])
    }

    /// The tags of the side sending in direction `ours`, over the final fate bitmap and
    /// its key.
    #[must_use]
    pub fn tags(&self, ours: Direction, fates: &[u64], key: &[u8]) -> ConfirmTags {
        ConfirmTags {
            session: self.session_tag(ours, fates),
            key: self.key_tag(ours, key),
        }
    }

    /// Checks the peer's tags (the peer sends opposite to `ours`) against our fates and
    /// key, with constant-time compares.
    ///
    /// # Errors
    /// Names what differs: the session (transcript or fates) or the key.
    pub fn check(
        &self,
        ours: Direction,
        fates: &[u64],
        key: &[u8],
        peer: &ConfirmTags,
    ) -> Result<(), &'static str> {
        let theirs = ours.reverse();
        if !bool::from(self.session_tag(theirs, fates).ct_eq(&peer.session)) {
            return Err("session tag differs: not the same session or not the same fates");
        }
        if !bool::from(self.key_tag(theirs, key).ct_eq(&peer.key)) {
            return Err("key tag differs: keys differ");
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fingerprints_and_keys_depend_on_the_secret_and_nonces() {
        let a = PairingSecret::from_bytes(&[7; 32]);
        let b = PairingSecret::from_bytes(&[8; 32]);
        assert_ne!(a.fingerprint(), b.fingerprint());
        assert_eq!(a.fingerprint().len(), 16);
        assert!(!format!("{a:?}").contains("0707"));
        let k1 = a.session_keys(&[1; 16], &[2; 16]);
        let k2 = a.session_keys(&[1; 16], &[3; 16]);
        let msg: &[&[u8]] = &[b"frame"];
        let t = k1.key(Direction::ToRobot).tag(msg);
        assert!(k1.key(Direction::ToRobot).verify(msg, &t));
        assert!(!k1.key(Direction::ToController).verify(msg, &t));
        assert!(!k2.key(Direction::ToRobot).verify(msg, &t));
        assert!(
            !b.session_keys(&[1; 16], &[2; 16])
                .key(Direction::ToRobot)
                .verify(msg, &t)
        );
    }

    #[test]
    fn hkdf_matches_rfc_5869_case_1() {
        // RFC 5869 test case 1 (IKM 22 × 0x0b, salt 0x00..0x0c, info 0xf0..0xf9), L = 32.
        let ikm = [0x0b_u8; 22];
        let salt: Vec<u8> = (0..=0x0c).collect();
        let info: Vec<u8> = (0xf0..=0xf9).collect();
        let mut okm = [0u8; 32];
        hkdf::Hkdf::<Sha256>::new(Some(&salt), &ikm)
            .expand(&info, &mut okm)
            .unwrap();
        assert_eq!(
            hex(&okm),
            "3cb25f25faacd57a90434f64d0362f2a2d2d0a90cf1a5a4c5db02d56ecc4c5bf"
        );
    }

    #[test]
    fn a_reflected_tag_fails_and_each_part_is_bound() {
        let keys = PairingSecret::from_bytes(&[9; 32]).session_keys(&[1; 16], &[2; 16]);
        let transcript = b"hello-bytes helloack-bytes".to_vec();
        let confirmer = Confirmer::new(keys, transcript);
        let (robot, controller) = (Direction::ToController, Direction::ToRobot);
        let key = [1u8, 0, 1, 1, 0];
        let fates = [0b101u64];
        let from_robot = confirmer.tags(robot, &fates, &key);
        assert_eq!(
            confirmer.check(controller, &fates, &key, &from_robot),
            Ok(())
        );
        // The controller's own tags, reflected back to it, fail.
        let reflected = confirmer.tags(controller, &fates, &key);
        assert!(
            confirmer
                .check(controller, &fates, &key, &reflected)
                .is_err()
        );
        let other_fates = confirmer.check(controller, &[0b100], &key, &from_robot);
        assert!(other_fates.unwrap_err().contains("session"));
        let other_key = confirmer.check(controller, &fates, &[1, 0, 1, 1, 1], &from_robot);
        assert!(other_key.unwrap_err().contains("keys differ"));
        let other_transcript = Confirmer::new(
            PairingSecret::from_bytes(&[9; 32]).session_keys(&[1; 16], &[2; 16]),
            b"hello-bytes helloack-bytez".to_vec(),
        );
        assert!(
            other_transcript
                .check(controller, &fates, &key, &from_robot)
                .is_err()
        );
    }
}
