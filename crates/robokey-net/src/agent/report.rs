//! The session report each agent writes (JSON) and prints (one line), and how a run ended
//! for scripts (README, "Exit codes").

use std::path::Path;
use std::time::Duration;

use robokey::protocol::auth::{AuthMode, ChannelCounts, PairingSecret, RejectionCounts};
use robokey::protocol::{Actuation, ControllerEvent, Outcome, SessionPlan};
use serde::Serialize;

use super::post::PostReport;
use super::socket::SocketCounts;
use crate::error::NetError;

/// Frame counters of one agent.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct FrameCounts {
    /// Datagrams sent.
    pub sent: u64,
    /// Datagrams the OS refused to send (each lost, like a dropped one).
    pub unsent: u64,
    /// Authenticated, fresh session frames received.
    pub received: u64,
    /// Of those, received out of order within the replay window.
    pub reordered: u64,
    /// Robot: verified `Hello`s answered, retransmissions included (a replayed old one until
    /// it is known as one: then it is rejected as `replayed`).
    pub hellos_answered: u64,
    /// Datagrams from a source that cannot be a peer (port 0, an unspecified, broadcast or
    /// multicast address), dropped unread.
    pub impossible_source: u64,
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
    pub post: Option<PostReport>,
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
    /// The report of `role` under `pairing`, before a session binds.
    #[must_use]
    pub fn new(role: &str, pairing: &PairingSecret) -> Self {
        Self {
            role: role.to_owned(),
            authentication: authentication_label(pairing),
            ..Self::default()
        }
    }

    /// Session `session` of `plan` is bound.
    pub fn bound(&mut self, session: u32, plan: &SessionPlan) {
        self.session = session;
        self.steps = plan.agreed.steps;
        self.codewords = plan.units();
        self.doublets = plan.private().map(|_| DoubletCounts::default());
    }

    /// The robot applied `actuation`, having applied `commands_applied` commands so far.
    pub fn applied(&mut self, actuation: &Actuation, plan: &SessionPlan, commands_applied: u32) {
        self.erased_steps += u32::from(actuation.erased);
        self.commands_applied = Some(commands_applied);
        // Stopped for want of commands, once they had started the wheels.
        if actuation.erased && actuation.wheels.iter().all(|w| *w == 0.0) && commands_applied > 0 {
            self.wheels_stopped_at_step.get_or_insert(actuation.step);
        }
        if let Some(counts) = &mut self.doublets
            && plan.starts_doublet(actuation.step)
        {
            // A doublet's first step tells its fate at the robot.
            if actuation.erased {
                counts.erased += 1;
            } else if actuation.bit.is_none() && plan.agreed.enabled {
                counts.gated += 1;
            }
        }
    }

    /// The controller reported `event` in session `plan`.
    pub fn controller_event(&mut self, event: &ControllerEvent, plan: &SessionPlan) {
        let enabled = plan.agreed.enabled;
        match event {
            ControllerEvent::Decoded(decision) => {
                self.steps_done = decision.step + 1;
                self.erased_steps += u32::from(decision.bit.is_none() && enabled);
            }
            ControllerEvent::Missing(range) => self.erased_steps += range.len() as u32,
            ControllerEvent::DoubletCommanded { carries, .. } => {
                if let Some(counts) = &mut self.doublets {
                    counts.gated += u32::from(enabled && !carries);
                }
            }
            ControllerEvent::DoubletErased { .. } => {
                self.erased_steps += plan.steps_per_doublet();
                if let Some(counts) = &mut self.doublets {
                    counts.erased += 1;
                }
            }
            _ => {}
        }
    }

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

    /// Copies the socket's and the session layer's counters into the report.
    pub fn count_frames(&mut self, socket: SocketCounts, channel: ChannelCounts) {
        self.frames = FrameCounts {
            sent: socket.sent,
            unsent: socket.unsent,
            received: channel.accepted,
            reordered: channel.reordered,
            hellos_answered: channel.hellos_answered,
            impossible_source: socket.impossible_source,
        };
        self.frames_rejected = channel.rejected;
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
    pub fn set_post(&mut self, post: Option<PostReport>) {
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

/// An agent's session report (the JSON `--report` writes), read back.
///
/// # Errors
/// The file cannot be read, or is not JSON ([`NetError::Usage`], naming the file).
pub fn read_report(path: &Path) -> Result<serde_json::Value, NetError> {
    let name = path.display();
    let text = std::fs::read_to_string(path)
        .map_err(NetError::io(format!("read the agent report {name}")))?;
    serde_json::from_str(&text)
        .map_err(|e| NetError::Usage(format!("{name}: not an agent's JSON report: {e}")))
}

/// How a report names a session's authentication.
#[must_use]
pub fn authentication_label(secret: &PairingSecret) -> String {
    match secret.mode() {
        AuthMode::Paired => format!("paired (fingerprint {})", secret.fingerprint()),
        AuthMode::Unauthenticated => "none: passive adversary only".to_owned(),
    }
}
