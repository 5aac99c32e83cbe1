//! What both agents share: pacing, timeouts, the session report, and the key file.

use std::io::Write as _;
use std::path::Path;
use std::time::Duration;

use robokey::protocol::Outcome;
use serde::Serialize;

use crate::error::NetError;
use crate::transport::FrameCounts;
use robokey::protocol::auth::{AuthMode, PairingSecret, RejectionCounts};

/// How the robot's clock runs (docs/protocol.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pace {
    /// Period T on the wall clock; a command is late after `T·deadline_fraction`.
    Realtime,
    /// Virtual clock: wait up to `step_timeout` for each command, then go on.
    Lockstep,
}

/// Timing of a session.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timing {
    /// Pacing mode.
    pub pace: Pace,
    /// Lockstep: wall time to wait for a command before treating it as missing.
    pub step_timeout: Duration,
    /// Realtime: a command is late after this fraction of T.
    pub deadline_fraction: f64,
    /// The session aborts after this long without a valid frame.
    pub silence_timeout: Duration,
}

impl Timing {
    /// The defaults of docs/protocol.md for a pace: deadline T/2, lockstep timeout 50 ms, silence 2 s.
    #[must_use]
    pub fn new(pace: Pace, silence_timeout: Duration) -> Self {
        Self {
            pace,
            step_timeout: Duration::from_millis(50),
            deadline_fraction: 0.5,
            silence_timeout,
        }
    }

    /// Interval between retransmissions of Hello, Finish and Confirm.
    #[must_use]
    pub fn retransmit_interval(&self) -> Duration {
        match self.pace {
            Pace::Lockstep => Duration::from_millis(30),
            Pace::Realtime => Duration::from_millis(100),
        }
    }
}

/// After its outcome, an agent keeps answering the peer's retransmitted Finish, FinishAck
/// or Confirm with `reply` (its own tag), so that a lost tag does not leave the peer
/// unconfirmed. It answers at most once per retransmission interval and stops after ten
/// intervals in all: two lingering agents cannot keep each other busy.
///
/// # Errors
/// The socket fails.
pub fn linger(
    transport: &mut crate::transport::Transport,
    timing: &Timing,
    reply: &[robokey::protocol::Message],
) -> Result<(), NetError> {
    use robokey::protocol::Message;
    use robokey::protocol::auth::Delivery;
    use std::time::Instant;
    let interval = timing.retransmit_interval();
    let end = Instant::now() + interval * 10;
    let mut last_answer: Option<Instant> = None;
    while let Some(delivery) = transport.recv_until(end)? {
        let asks = matches!(
            delivery,
            Delivery::Message(
                Message::Finish { .. } | Message::FinishAck | Message::Confirm { .. }
            )
        );
        if asks && last_answer.is_none_or(|t| t.elapsed() >= interval) {
            last_answer = Some(Instant::now());
            for m in reply {
                transport.send(m.clone())?;
            }
        }
    }
    Ok(())
}

/// The session report each agent writes (JSON).
#[derive(Clone, Debug, Default, Serialize)]
pub struct SessionReport {
    /// `robot` or `controller`.
    pub role: String,
    /// `paired (fingerprint F)`, or `none: passive adversary only` (`--unauthenticated`).
    pub authentication: String,
    /// Session id.
    pub session: u32,
    /// Steps N of the session.
    pub steps: u32,
    /// Steps completed before the end.
    pub steps_done: u32,
    /// Erased steps (missing command at the robot; missing or fallback measurement at the
    /// controller).
    pub erased_steps: u32,
    /// Complete codewords of the session.
    pub codewords: u32,
    /// Codewords accepted into the key.
    pub accepted: u32,
    /// Key length (bits).
    pub key_bits: usize,
    /// `confirmed`, `unconfirmed` or `aborted`.
    pub outcome: String,
    /// Why, unless confirmed.
    pub reason: Option<String>,
    /// Robot: the first step at which it stopped its wheels because commands stopped
    /// arriving (after `max_hold` fallbacks).
    pub wheels_stopped_at_step: Option<u32>,
    /// Where the key was written (only when confirmed).
    pub key_file: Option<String>,
    /// Frame counters.
    pub frames: FrameCounts,
    /// Datagrams dropped by the session layer, by reason; none changed any state.
    pub frames_rejected: RejectionCounts,
    /// Robot: commands applied to the wheels (authenticated, fresh, within the agreed
    /// terms; stop commands and fallbacks excluded).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub commands_applied: Option<u32>,
}

impl SessionReport {
    /// Records the outcome.
    pub fn set_outcome(&mut self, outcome: &Outcome) {
        let (name, reason) = match outcome {
            Outcome::Confirmed => ("confirmed", None),
            Outcome::Unconfirmed(why) => ("unconfirmed", Some(why.clone())),
            Outcome::Aborted(why) => ("aborted", Some(why.clone())),
        };
        self.outcome = name.to_owned();
        self.reason = reason;
    }

    /// Writes the report as pretty JSON.
    ///
    /// # Errors
    /// The file cannot be written.
    pub fn write(&self, path: &Path) -> Result<(), NetError> {
        let text = serde_json::to_string_pretty(self).expect("a report serializes") + "\n";
        std::fs::write(path, text).map_err(NetError::io(format!("write report {}", path.display())))
    }

    /// Whether the session ran without a pairing.
    #[must_use]
    pub fn is_unauthenticated(&self) -> bool {
        self.authentication.starts_with("none")
    }

    /// One line for the terminal.
    #[must_use]
    pub fn line(&self) -> String {
        let rejected = match self.frames_rejected.total() {
            0 => String::new(),
            n => format!(" [{n} datagrams rejected, see the report]"),
        };
        format!(
            "{}{}: session {:08x}, {} steps ({} erased), {}/{} codewords accepted, {} key bits, {}{}{rejected}",
            if self.is_unauthenticated() {
                "[passive adversary only] "
            } else {
                ""
            },
            self.role,
            self.session,
            self.steps_done,
            self.erased_steps,
            self.accepted,
            self.codewords,
            self.key_bits,
            self.outcome,
            self.reason
                .as_ref()
                .map_or(String::new(), |r| format!(": {r}"))
        )
    }
}

/// A ChaCha20 generator seeded from the operating system's CSPRNG: the robot's key source
/// in deployment, and the source of session ids.
///
/// # Errors
/// The OS generator is unavailable.
pub fn os_rng() -> Result<rand::rngs::ChaCha20Rng, NetError> {
    use rand::SeedableRng;
    rand::rngs::ChaCha20Rng::try_from_rng(&mut rand::rngs::SysRng)
        .map_err(|e| NetError::Usage(format!("the OS random generator failed: {e}")))
}

/// How a report names a session's authentication.
#[must_use]
pub fn authentication_label(secret: &PairingSecret) -> String {
    match secret.mode() {
        AuthMode::Paired => format!("paired (fingerprint {})", secret.fingerprint()),
        AuthMode::Unauthenticated => "none: passive adversary only".to_owned(),
    }
}

/// Writes a confirmed key (`bits` of 0/1) as hex of the bit-packed key (bit i of the key =
/// bit i % 8 of byte i / 8), with mode 0600, followed by comment lines saying what it is
/// (`labels`). Refuses to overwrite.
///
/// # Errors
/// The file exists or cannot be written.
pub fn write_key_file(path: &Path, bits: &[u8], labels: &[&str]) -> Result<(), NetError> {
    let mut packed = zeroize::Zeroizing::new(vec![0u8; bits.len().div_ceil(8)]);
    for (i, bit) in bits.iter().enumerate() {
        packed[i / 8] |= (bit & 1) << (i % 8);
    }
    let hex: zeroize::Zeroizing<String> =
        zeroize::Zeroizing::new(packed.iter().map(|b| format!("{b:02x}")).collect());
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    let mut file = options
        .open(path)
        .map_err(NetError::io(format!("create key file {}", path.display())))?;
    let mut text = format!("robokey-key-v1 bits={}\n{}\n", bits.len(), hex.as_str());
    for label in labels {
        text += &format!("# {label}\n");
    }
    let text = zeroize::Zeroizing::new(text);
    file.write_all(text.as_bytes())
        .and_then(|()| file.sync_all())
        .map_err(NetError::io(format!("write key file {}", path.display())))
}

/// Reads a key file written by [`write_key_file`] back into bits.
///
/// # Errors
/// The file cannot be read or is malformed.
pub fn read_key_file(path: &Path) -> Result<zeroize::Zeroizing<Vec<u8>>, NetError> {
    let bad = |why: &str| {
        NetError::Usage(format!(
            "{}: not a robokey key file ({why})",
            path.display()
        ))
    };
    let text = zeroize::Zeroizing::new(
        std::fs::read_to_string(path)
            .map_err(NetError::io(format!("read key file {}", path.display())))?,
    );
    let mut lines = text.lines();
    let bits: usize = lines
        .next()
        .and_then(|l| l.strip_prefix("robokey-key-v1 bits="))
        .and_then(|n| n.parse().ok())
        .ok_or_else(|| bad("header"))?;
    let hex = lines.next().unwrap_or("");
    if hex.len() != bits.div_ceil(8) * 2 || !hex.is_ascii() {
        return Err(bad("length"));
    }
    let mut out = zeroize::Zeroizing::new(Vec::with_capacity(bits));
    for i in 0..bits {
        let byte =
            u8::from_str_radix(&hex[i / 8 * 2..i / 8 * 2 + 2], 16).map_err(|_| bad("hex"))?;
        out.push(byte >> (i % 8) & 1);
    }
    Ok(out)
}
