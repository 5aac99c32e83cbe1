//! After its outcome (docs/protocol.md, "Lingering"): a side that needs nothing more sends
//! `Done` and keeps answering the peer's repeated closing — with its own tags and `Done` — at
//! most once per retransmission interval, so that a lost tag does not leave the peer
//! unconfirmed. It stops at the peer's `Done`, or after ten intervals with nothing to answer.

use std::time::Duration;

use crate::protocol::{Closing, Message, Time, Timing};

/// The courtesy of a side that has its outcome.
#[derive(Clone, Debug)]
pub(crate) struct Courtesy {
    /// What answers a repeated `Finish`, `FinishAck` or `Confirm`: this side's tags (the
    /// robot's preceded by `FinishAck`).
    reply: Vec<Message>,
    interval: Duration,
    /// When it last answered.
    last: Option<Time>,
    /// Whether the peer's `Done` has come.
    pub(crate) peer_done: bool,
}

impl Courtesy {
    /// Answers with `reply`, at most once per retransmission interval of `timing`.
    pub(crate) fn new(reply: Vec<Message>, timing: &Timing) -> Self {
        Self {
            reply,
            interval: timing.retransmit_interval(),
            last: None,
            peer_done: false,
        }
    }

    /// A closing message from the peer at `now`: what to send back (the reply, with `Done`
    /// after it when `done`), if it is a repeat this side answers now. Notes the peer's
    /// `Done`.
    pub(crate) fn answer(&mut self, now: Time, message: &Closing, done: bool) -> Vec<Message> {
        match message {
            Closing::Done => {
                self.peer_done = true;
                Vec::new()
            }
            Closing::Finish { .. } | Closing::FinishAck | Closing::Confirm { .. }
                if self.last.is_none_or(|t| now >= t + self.interval) =>
            {
                self.last = Some(now);
                let done = done.then_some(Closing::Done.into());
                self.reply.iter().cloned().chain(done).collect()
            }
            _ => Vec::new(),
        }
    }
}

/// A side lingering after its outcome: it has sent `Done` and answers until the peer's `Done`
/// or until it has been quiet for [`Timing::linger_quiet`].
#[derive(Clone, Debug)]
pub(crate) struct Linger {
    courtesy: Courtesy,
    /// When it stops if nothing more comes that it must answer.
    until: Time,
    quiet: Duration,
}

impl Linger {
    /// Starts lingering at `now` with `courtesy` (the caller sends `Done`).
    pub(crate) fn new(courtesy: Courtesy, timing: &Timing, now: Time) -> Self {
        Self {
            courtesy,
            until: now + timing.linger_quiet(),
            quiet: timing.linger_quiet(),
        }
    }

    /// Whether it is over at `now`: the peer's `Done` came, or the quiet time passed.
    pub(crate) fn is_over(&self, now: Time) -> bool {
        self.courtesy.peer_done || now >= self.until
    }

    /// When it stops unless something comes.
    pub(crate) fn deadline(&self) -> Time {
        self.until
    }

    /// Something this side must answer (a post-processing frame) came at `now`: it stays at
    /// least `patience` from now — the quiet time, or longer while the peer may be computing
    /// before its next request (the block timeout, for the controller's block-time estimate
    /// of the plant).
    pub(crate) fn busy(&mut self, now: Time, patience: Duration) {
        self.until = now + self.quiet.max(patience);
    }

    /// A closing message from the peer at `now`: what to send back (with `Done`).
    pub(crate) fn answer(&mut self, now: Time, message: &Closing) -> Vec<Message> {
        self.courtesy.answer(now, message, true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::Pace;

    /// A frame answered with a block in flight keeps the side lingering for the patience it
    /// was given (the block timeout), not only the quiet time; without it, the quiet time.
    #[test]
    fn a_frame_keeps_the_side_for_its_patience_or_the_quiet_time() {
        let timing = Timing::new(Pace::Lockstep, Duration::from_secs(2));
        let start = Time::ZERO;
        let mut linger = Linger::new(Courtesy::new(Vec::new(), &timing), &timing, start);
        let quiet = timing.linger_quiet();
        linger.busy(start, Duration::ZERO);
        assert!(!linger.is_over(start + (quiet - Duration::from_millis(1))));
        assert!(linger.is_over(start + quiet));
        linger.busy(start, timing.block_timeout);
        let block = timing.block_timeout;
        assert!(!linger.is_over(start + (block - Duration::from_millis(1))));
        assert!(linger.is_over(start + block));
    }
}
