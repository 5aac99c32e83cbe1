//! The messages of the protocol (`docs/wire.md`; session id and frame sequence numbers live
//! in the wire header, added by the session layer).

use super::auth::{AuthMode, NONCE_BYTES, TAG_BYTES};
use super::fates::FateWindow;

/// One protocol message.
#[derive(Clone, Debug, PartialEq)]
pub enum Message {
    /// Controller → robot: opens a session (MACed under the handshake key).
    Hello {
        /// Whether the sender holds a pairing secret.
        auth: AuthMode,
        /// `nonce_c`, fresh from the OS CSPRNG.
        nonce: [u8; NONCE_BYTES],
        /// SHA-256 of `terms`.
        config_digest: [u8; 32],
        /// The agreement terms as `field = value` lines, so a mismatch can be named.
        terms: String,
    },
    /// Robot → controller: accepts a session with the same configuration digest (MACed
    /// under the handshake key, over both nonces).
    HelloAck {
        /// Whether the sender holds a pairing secret.
        auth: AuthMode,
        /// The controller's `nonce_c`, echoed.
        nonce_c: [u8; NONCE_BYTES],
        /// `nonce_r`, fresh from the robot's CSPRNG.
        nonce_r: [u8; NONCE_BYTES],
        /// SHA-256 of the robot's agreement terms.
        config_digest: [u8; 32],
    },
    /// Robot → controller: refuses the Hello carrying `nonce_c` (MACed under the handshake
    /// key), e.g. because the terms differ.
    Refuse {
        /// The refused Hello's `nonce_c`.
        nonce_c: [u8; NONCE_BYTES],
        /// Human-readable reason.
        reason: String,
    },
    /// Controller → robot: the first frame under the controller→robot session key; it
    /// binds the session and the controller's address at the robot.
    Ready,
    /// Robot → controller: odometry `y(k)`.
    Measurement {
        /// Sample index k.
        step: u32,
        /// `y(k)` = `[px, py, θ]` (m, m, rad).
        y: [f64; 3],
        /// The command step applied on `[t_{k−1}, t_k)`, or `None` after a fallback.
        applied_step: Option<u32>,
        /// The robot's contiguous fate cursor: first codeword whose fate it lacks.
        fate_cursor: u32,
    },
    /// Controller → robot: the pair of wheel commands for step k, plus acks. At `k = N`
    /// it is the stop command (both pairs zero).
    Command {
        /// Step k.
        step: u32,
        /// `u0D(k)` (rad/s, right first).
        u0: [f64; 2],
        /// `u1D(k)` (rad/s, right first).
        u1: [f64; 2],
        /// Fates of the codewords the robot has not confirmed yet.
        fates: FateWindow,
    },
    /// Robot → controller, private sensing: the sample instant `t_k` has passed. It carries
    /// no pose: the controller reads its own sensor, and odometry stays on the robot.
    PrivateMeasurement {
        /// Sample index k.
        step: u32,
        /// The command step applied on `[t_{k−1}, t_k)`, or `None` after a fallback.
        applied_step: Option<u32>,
        /// The robot's contiguous fate cursor: first doublet whose fate it lacks.
        fate_cursor: u32,
    },
    /// Controller → robot, private sensing: the nominal inputs of the doublet that starts
    /// at step k (or of a lone last step), from which the robot derives `u + s·Δ` and
    /// `u' − s·Δ` itself, plus acks. At `k = N` it is the stop command (inputs zero).
    DoubletCommand {
        /// Step k.
        step: u32,
        /// The controller's sample `y_c(k)` = `[px, py, θ]` (m, m, rad) the inputs were
        /// computed from. The tracking law is invertible, so the inputs reveal it anyway
        /// (docs/private-sensing.md); the secrecy accounting charges it to the eavesdropper.
        sample: [f64; 3],
        /// `u(k)` = `[v, ω]` (m/s, rad/s).
        first: [f64; 2],
        /// `u'(k+1)`, from the open-loop prediction; `None` on a lone last step and on the
        /// stop command.
        second: Option<[f64; 2]>,
        /// Fates of the doublets the robot has not confirmed yet.
        fates: FateWindow,
    },
    /// Controller → robot: every codeword's (private sensing: doublet's) fate, sent after
    /// the stop command.
    Finish {
        /// Number of decided codewords (doublets).
        codewords: u32,
        /// Fate bitmap, bit `i % 64` of word `i / 64` = codeword `i` accepted.
        bitmap: Vec<u64>,
    },
    /// Robot → controller: the Finish arrived.
    FinishAck,
    /// Either side: its session and key confirmation tags (see [`super::Confirmer`]).
    Confirm {
        /// `MAC(k_dir, "confirm" ‖ dir ‖ Hello ‖ HelloAck ‖ fate bitmap)`, truncated.
        session_tag: [u8; TAG_BYTES],
        /// `MAC(k_dir, "key" ‖ dir ‖ Hello ‖ HelloAck ‖ key)`, truncated.
        key_tag: [u8; TAG_BYTES],
    },
    /// Either side, after its outcome (confirmed or not): it needs nothing more from the peer,
    /// which may stop lingering (docs/protocol.md, "Lingering").
    Done,
    /// Either side: one fragment of an encoded post-processing message
    /// (`robokey_secrecy::postprocess::encode`), which the receiver reassembles. It belongs to
    /// no session step: session endpoints ignore it.
    PostFragment {
        /// The sender's id of the encoded message (fresh for every transmission).
        message: u32,
        /// This fragment's position, `0..count`.
        index: u16,
        /// Fragments of the message, `1..=MAX_POST_FRAGMENTS`.
        count: u16,
        /// The chunk, 1 to `MAX_POST_FRAGMENT_BYTES` bytes.
        bytes: Vec<u8>,
    },
    /// Either side: the session is over, with a reason.
    Abort {
        /// Human-readable reason.
        reason: String,
    },
}
