//! What both agents share: pacing, timeouts, the session report, and the key file.

use std::path::Path;
use std::time::Duration;

use robokey::protocol::Outcome;
use serde::Serialize;

use crate::error::NetError;
use crate::transport::FrameCounts;
use robokey::protocol::auth::{AuthMode, PairingSecret, RejectionCounts};

/// Longest a blocking wait (a receive, a sleep) lasts before it looks at the stop request
/// again.
pub const STOP_POLL: Duration = Duration::from_millis(50);

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

/// Answers the peer's retransmitted `Finish`, `FinishAck` or `Confirm` with `reply` (and
/// `Done` once this side needs nothing more), at most once per retransmission interval, so
/// that a lost tag does not leave the peer unconfirmed.
#[derive(Debug)]
pub struct Courtesy<'a> {
    reply: &'a [robokey::protocol::Message],
    interval: Duration,
    last: Option<std::time::Instant>,
}

impl<'a> Courtesy<'a> {
    /// Answers with `reply` (this side's tag).
    #[must_use]
    pub fn new(reply: &'a [robokey::protocol::Message], timing: &Timing) -> Self {
        Self {
            reply,
            interval: timing.retransmit_interval(),
            last: None,
        }
    }

    /// Answers `message` if it is a repeat, with `Done` after the reply if `done`; true when
    /// it is the peer's `Done`.
    ///
    /// # Errors
    /// The socket fails.
    pub fn answer(
        &mut self,
        transport: &mut crate::transport::Transport,
        message: &robokey::protocol::Message,
        done: bool,
    ) -> Result<bool, NetError> {
        use robokey::protocol::{Closing, Message};
        match message {
            Message::Closing(Closing::Done) => Ok(true),
            Message::Closing(
                Closing::Finish { .. } | Closing::FinishAck | Closing::Confirm { .. },
            ) if self.last.is_none_or(|t| t.elapsed() >= self.interval) => {
                self.last = Some(std::time::Instant::now());
                let done = done.then_some(Message::Closing(Closing::Done));
                for m in self.reply.iter().cloned().chain(done) {
                    transport.send(m)?;
                }
                Ok(false)
            }
            _ => Ok(false),
        }
    }
}

/// After its outcome: sends `Done` (this side needs nothing more), then answers the peer
/// with `courtesy` — and, on the robot, post-processing with `post` — until the peer's
/// `Done` (at once if it came already: `peer_done`), or ten retransmission intervals without
/// a post-processing frame: two lingering agents cannot keep each other busy. Without loss,
/// it returns a round trip after the outcome.
///
/// # Errors
/// The socket or the store fails, or a stop was requested.
pub fn linger(
    transport: &mut crate::transport::Transport,
    timing: &Timing,
    courtesy: &mut Courtesy<'_>,
    peer_done: bool,
    mut post: Option<&mut crate::post_link::PostSide<robokey_secrecy::postprocess::RobotPost>>,
) -> Result<(), NetError> {
    use robokey::protocol::auth::Delivery;
    use robokey::protocol::{Closing, Message};
    use std::time::Instant;
    transport.send(Closing::Done.into())?;
    if peer_done {
        return Ok(());
    }
    let quiet = timing.retransmit_interval() * 10;
    let mut end = Instant::now() + quiet;
    while let Some(delivery) = transport.recv_until(end)? {
        let Delivery::Message(message) = delivery else {
            continue;
        };
        match (message, post.as_deref_mut()) {
            (Message::Post(fragment), Some(post)) => {
                post.receive(&fragment);
                post.flush(transport)?;
                end = Instant::now() + quiet;
            }
            (message, _) => {
                if courtesy.answer(transport, &message, true)? {
                    return Ok(());
                }
            }
        }
    }
    Ok(())
}

/// How a session ended, for scripts: the agents' exit codes follow it (README, "Exit codes").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Ending {
    /// The peer proved it holds the same key (its tag verified).
    Confirmed,
    /// Private sensing: the peer confirmed which doublets were kept; the raw bits await
    /// post-processing.
    Kept,
    /// Confirmed or kept, but post-processing left a block or a final key in flight: pending
    /// until a later session settles it (`post.in_flight` says which and how).
    InFlight,
    /// Aborted or unconfirmed: no key.
    #[default]
    NoKey,
    /// No peer proved it holds the pairing secret, and datagrams that failed to verify came.
    AuthenticationFailed,
    /// Stopped by a signal.
    Interrupted,
    /// A socket, file or robot error ended it.
    Failed,
}

/// A line on stderr every 10 s while a session runs, so a real-time session (N·T, minutes)
/// does not look hung.
#[derive(Debug)]
pub struct Progress {
    role: &'static str,
    steps: u32,
    last: std::time::Instant,
}

impl Progress {
    /// Interval between lines.
    const EVERY: Duration = Duration::from_secs(10);

    /// Progress of a session of `steps` steps, for `role`.
    #[must_use]
    pub fn new(role: &'static str, steps: u32) -> Self {
        Self {
            role,
            steps,
            last: std::time::Instant::now(),
        }
    }

    /// Prints `step k/N, e erased` if 10 s passed since the last line.
    pub fn tick(&mut self, step: u32, erased: u32) {
        if self.last.elapsed() >= Self::EVERY {
            self.last = std::time::Instant::now();
            eprintln!(
                "{}: step {step}/{} ({erased} erased so far)",
                self.role, self.steps
            );
        }
    }
}

/// The session report each agent writes (JSON).
#[derive(Clone, Debug, Default, Serialize)]
pub struct SessionReport {
    /// `robot` or `controller`.
    pub role: String,
    /// `paired (fingerprint F)`, or `none: passive adversary only` (`--unauthenticated`).
    pub authentication: String,
    /// Session id, in hex as on the terminal.
    #[serde(serialize_with = "hex_id")]
    pub session: u32,
    /// Steps N of the session.
    pub steps: u32,
    /// Steps completed before the end.
    pub steps_done: u32,
    /// Erased steps, which carry no key bit. Robot: steps whose command did not arrive in time
    /// (it applied the fallback). Controller: steps it could not decode — those same steps
    /// (their measurement says so), plus steps whose bracketing measurement was lost on the
    /// way back. The controller's count is therefore the larger one.
    pub erased_steps: u32,
    /// Complete codewords of the session.
    pub codewords: u32,
    /// Codewords accepted into the key.
    pub accepted: u32,
    /// Key length (bits).
    pub key_bits: usize,
    /// `confirmed`, `kept` (private sensing), `unconfirmed` or `aborted`.
    pub outcome: String,
    /// How it ended: `confirmed`, `kept`, `in-flight`, `no-key`, `authentication-failed`,
    /// `interrupted`, `failed`.
    pub ending: Ending,
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
    /// Private sensing: doublets without a bit, by cause (`codewords` counts the doublets,
    /// `accepted` the kept ones).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub doublets: Option<DoubletCounts>,
    /// Post-processing during this run (`--store`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub post: Option<crate::post_link::PostReport>,
}

/// Private sensing: the doublets of a session that carry no kept bit, by cause.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct DoubletCounts {
    /// Doublets the public turn gate left without a bit.
    pub gated: u32,
    /// Carrying doublets dropped because a command, a measurement or (at the controller) a
    /// sensor sample was lost, or the robot did not apply them.
    pub erased: u32,
}

impl SessionReport {
    /// Records the outcome.
    pub fn set_outcome(&mut self, outcome: &Outcome) {
        let (name, reason) = match outcome {
            Outcome::Confirmed => ("confirmed", None),
            Outcome::Kept => ("kept", None),
            Outcome::Unconfirmed(why) => ("unconfirmed", Some(why.clone())),
            Outcome::Aborted(why) => ("aborted", Some(why.clone())),
        };
        self.outcome = name.to_owned();
        self.reason = reason;
        self.ending = match outcome {
            Outcome::Confirmed => Ending::Confirmed,
            Outcome::Kept => Ending::Kept,
            _ => Ending::NoKey,
        };
    }

    /// Copies the transport's frame counters and rejections into the report.
    pub fn count_frames(&mut self, transport: &crate::transport::Transport) {
        self.frames = transport.counts();
        self.frames_rejected = transport.rejected();
    }

    /// Records a session cut short by `error` (a signal, or a socket, file or robot error).
    pub fn set_error(&mut self, error: &NetError) {
        self.set_outcome(&Outcome::Aborted(error.to_string()));
        self.ending = Self::ending_of(error);
    }

    /// Post-processing after the session stopped on `error`: the session's outcome (and its
    /// key file) stand; the run ends interrupted or failed, saying why.
    pub fn post_stopped(&mut self, error: &NetError) {
        self.ending = Self::ending_of(error);
        self.reason = Some(format!("post-processing stopped: {error}"));
    }

    /// Attaches post-processing's report; a confirmed (or kept) session whose
    /// post-processing left a block or key in flight ends [`Ending::InFlight`].
    pub fn set_post(&mut self, post: Option<crate::post_link::PostReport>) {
        let in_flight = post.as_ref().is_some_and(|p| p.in_flight.is_some());
        if in_flight && matches!(self.ending, Ending::Confirmed | Ending::Kept) {
            self.ending = Ending::InFlight;
        }
        self.post = post;
    }

    fn ending_of(error: &NetError) -> Ending {
        match error {
            NetError::Interrupted(_) => Ending::Interrupted,
            _ => Ending::Failed,
        }
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
        let kept = match &self.doublets {
            Some(d) => format!(
                "{}/{} doublets kept ({} gated, {} erased), {} raw bits",
                self.accepted, self.codewords, d.gated, d.erased, self.key_bits
            ),
            None => format!(
                "{}/{} codewords accepted, {} key bits",
                self.accepted, self.codewords, self.key_bits
            ),
        };
        let post = self
            .post
            .as_ref()
            .map_or(String::new(), |p| format!("; {}", p.line()));
        format!(
            "{}{}: session {:08x}, {} steps ({} erased), {kept}, {}{}{rejected}{post}",
            if self.is_unauthenticated() {
                "[passive adversary only] "
            } else {
                ""
            },
            self.role,
            self.session,
            self.steps_done,
            self.erased_steps,
            self.outcome,
            self.reason
                .as_ref()
                .map_or(String::new(), |r| format!(": {r}"))
        )
    }
}

/// Writes a session id as the terminal shows it: 8 hex digits.
fn hex_id<S: serde::Serializer>(session: &u32, serializer: S) -> Result<S::Ok, S::Error> {
    serializer.serialize_str(&format!("{session:08x}"))
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
/// bit i % 8 of byte i / 8), followed by comment lines saying what it is (`labels`): all or
/// nothing, mode 0600, never over an existing file ([`crate::secret_file`]).
///
/// # Errors
/// The file exists or cannot be written.
pub fn write_key_file(path: &Path, bits: &[u8], labels: &[&str]) -> Result<(), NetError> {
    let mut packed = zeroize::Zeroizing::new(vec![0u8; bits.len().div_ceil(8)]);
    for (i, bit) in bits.iter().enumerate() {
        packed[i / 8] |= (bit & 1) << (i % 8);
    }
    // Sized up front: a growing buffer would leave copies of the key in freed memory.
    let labels_len: usize = labels.iter().map(|l| l.len() + 3).sum();
    let mut text = zeroize::Zeroizing::new(String::with_capacity(
        64 + 2 * packed.len() + 1 + labels_len,
    ));
    text.push_str(&format!("robokey-key-v1 bits={}\n", bits.len()));
    for byte in packed.iter() {
        text.push(char::from(b"0123456789abcdef"[usize::from(byte >> 4)]));
        text.push(char::from(b"0123456789abcdef"[usize::from(byte & 15)]));
    }
    text.push('\n');
    for label in labels {
        text.push_str(&format!("# {label}\n"));
    }
    crate::secret_file::write_new(path, text.as_bytes())
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
    let text = crate::secret_file::read(path, "key file")?;
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
