//! The wheels between a command and the motion (docs/world.md, "Actuators"): each command is
//! quantised to the command resolution and clipped to the motors' limit when applied, acts
//! after the transport delay, and each wheel's speed follows the command acting on it
//! through a first-order lag, `dω/dt = (ω_cmd − ω)/τ`. Deterministic: the noise is the
//! motion's.

use std::collections::VecDeque;

use crate::model::{WheelSpeeds, clip_wheels};

/// A stretch of time over which one command acts on the wheels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Piece {
    /// Its length (s).
    pub duration: f64,
    /// The command acting (rad/s, right first).
    pub command: WheelSpeeds,
    /// The wheels' speeds at its start (rad/s).
    pub start: WheelSpeeds,
}

/// The mean and the final speed of a wheel that starts at `start` and follows `command`
/// through a lag τ = `lag` (s) for `duration` (s):
/// `ω(t) = c + (ω₀ − c)·e^(−t/τ)`, mean `c + (ω₀ − c)·(τ/h)·(1 − e^(−h/τ))`. Without lag
/// the wheel is at the command at once.
#[must_use]
pub fn lagged(
    command: WheelSpeeds,
    start: WheelSpeeds,
    duration: f64,
    lag: f64,
) -> (WheelSpeeds, WheelSpeeds) {
    if lag == 0.0 {
        return (command, command);
    }
    let decay = (-duration / lag).exp();
    let offset = start - command;
    let mean_fraction = if duration > 0.0 {
        lag / duration * (1.0 - decay)
    } else {
        1.0
    };
    (command + offset * mean_fraction, command + offset * decay)
}

/// `q·round(x/q)` per wheel (0: `x`).
#[must_use]
pub fn quantise(wheels: WheelSpeeds, quantum: f64) -> WheelSpeeds {
    if quantum > 0.0 {
        wheels.map(|w| (w / quantum).round() * quantum)
    } else {
        wheels
    }
}

/// The wheels of one robot: the commands in the delay line, the one acting, and the
/// wheels' speeds.
#[derive(Clone, Debug, PartialEq)]
pub struct Actuator {
    lag: f64,
    delay: f64,
    quantum: f64,
    limit: f64,
    /// Time since the session began (s).
    now: f64,
    /// Commands applied but not acting yet, with the time each starts to act (s).
    pending: VecDeque<(f64, WheelSpeeds)>,
    acting: WheelSpeeds,
    speed: WheelSpeeds,
}

/// Most commands the delay line holds: with a delay of at most 1 s a command per
/// millisecond fits; beyond it the oldest pending command acts at once.
pub const MAX_PENDING: usize = 1024;

impl Actuator {
    /// Wheels at rest: lag τ (s), delay (s), command resolution (rad/s, 0: none) and the
    /// motors' limit (rad/s).
    #[must_use]
    pub fn new(lag: f64, delay: f64, quantum: f64, limit: f64) -> Self {
        Self {
            lag,
            delay,
            quantum,
            limit,
            now: 0.0,
            pending: VecDeque::new(),
            acting: WheelSpeeds::zeros(),
            speed: WheelSpeeds::zeros(),
        }
    }

    /// A command from now on (quantised, clipped), acting after the delay.
    pub fn apply(&mut self, wheels: WheelSpeeds) {
        let command = clip_wheels(quantise(wheels, self.quantum), self.limit);
        if self.delay == 0.0 {
            self.acting = command;
            if self.lag == 0.0 {
                self.speed = command;
            }
            return;
        }
        if self.pending.len() == MAX_PENDING
            && let Some((_, oldest)) = self.pending.pop_front()
        {
            self.acting = oldest;
        }
        self.pending.push_back((self.now + self.delay, command));
    }

    /// The wheels' speeds now (rad/s).
    #[must_use]
    pub fn speed(&self) -> WheelSpeeds {
        self.speed
    }

    /// The pieces of the next `duration` seconds (split where a delayed command starts to
    /// act), appended to `out`; the wheels advance to its end.
    pub fn advance(&mut self, duration: f64, out: &mut Vec<Piece>) {
        let end = self.now + duration;
        let mut left = duration;
        loop {
            // A command due now (or before) acts from now on.
            while let Some(&(due, command)) = self.pending.front() {
                if due > self.now {
                    break;
                }
                self.acting = command;
                self.pending.pop_front();
            }
            let next = self.pending.front().map(|&(due, _)| due);
            let length = match next {
                Some(due) if due < end => due - self.now,
                _ => left,
            };
            let piece = Piece {
                duration: length,
                command: self.acting,
                start: self.speed,
            };
            self.speed = lagged(piece.command, piece.start, length, self.lag).1;
            out.push(piece);
            left -= length;
            match next {
                Some(due) if due < end => self.now = due,
                _ => {
                    self.now = end;
                    return;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(actuator: &mut Actuator, duration: f64) -> Vec<Piece> {
        let mut out = Vec::new();
        actuator.advance(duration, &mut out);
        out
    }

    #[test]
    fn without_lag_or_delay_the_wheels_follow_at_once() {
        let mut a = Actuator::new(0.0, 0.0, 0.0, 38.0);
        a.apply(WheelSpeeds::new(4.0, 50.0));
        let pieces = run(&mut a, 0.2);
        assert_eq!(pieces.len(), 1);
        assert_eq!(pieces[0].command, WheelSpeeds::new(4.0, 38.0));
        assert_eq!(
            lagged(pieces[0].command, pieces[0].start, 0.2, 0.0).0,
            pieces[0].command
        );
    }

    #[test]
    fn a_delayed_command_acts_from_its_due_time() {
        let mut a = Actuator::new(0.0, 0.05, 0.0, 38.0);
        a.apply(WheelSpeeds::new(1.0, 1.0));
        let pieces = run(&mut a, 0.2);
        assert_eq!(pieces.len(), 2);
        assert!((pieces[0].duration - 0.05).abs() < 1e-15);
        assert_eq!(pieces[0].command, WheelSpeeds::zeros());
        assert!((pieces[1].duration - 0.15).abs() < 1e-15);
        assert_eq!(pieces[1].command, WheelSpeeds::new(1.0, 1.0));
        // A delay longer than a period: the command acts two periods later.
        let mut a = Actuator::new(0.0, 0.3, 0.0, 38.0);
        a.apply(WheelSpeeds::new(2.0, 2.0));
        let first = run(&mut a, 0.2);
        assert_eq!(first.len(), 1);
        assert_eq!(first[0].command, WheelSpeeds::zeros());
        let second = run(&mut a, 0.2);
        assert_eq!(second[1].command, WheelSpeeds::new(2.0, 2.0));
        assert!((second[0].duration - 0.1).abs() < 1e-12);
    }

    #[test]
    fn a_lagged_wheel_moves_exponentially_and_its_mean_is_exact() {
        let (tau, h) = (0.05, 0.2);
        let (mean, end) = lagged(WheelSpeeds::new(1.0, 0.0), WheelSpeeds::zeros(), h, tau);
        let a = (-h / tau).exp();
        assert!((end.x - (1.0 - a)).abs() < 1e-15);
        // The mean by fine midpoint quadrature.
        let n = 100_000;
        let quadrature: f64 = (0..n)
            .map(|i| 1.0 - (-(i as f64 + 0.5) * h / n as f64 / tau).exp())
            .sum::<f64>()
            / n as f64;
        assert!(
            (mean.x - quadrature).abs() < 1e-9,
            "{} vs {quadrature}",
            mean.x
        );
    }

    #[test]
    fn commands_round_to_the_resolution() {
        let q = quantise(WheelSpeeds::new(0.104, -0.104), 0.05);
        assert!((q.x - 0.1).abs() < 1e-15 && (q.y + 0.1).abs() < 1e-15);
        assert_eq!(
            quantise(WheelSpeeds::new(0.104, 1.0), 0.0),
            WheelSpeeds::new(0.104, 1.0)
        );
    }
}
