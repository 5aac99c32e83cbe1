//! The observer side of the protocol, shared by the controller and the eavesdroppers:
//! turns the stream of command pairs and measurements into per-step bit decisions,
//! handling duplicates, erasures and gaps (docs/protocol.md, docs/observer.md).

use std::ops::Range;

use crate::model::{DiffDrive, Pose, Unicycle, WheelSpeeds};
use crate::observer::{InputEstimate, Observer, ObserverError, decide_bit};

/// A command pair as the decoder knows it.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Pair {
    step: u32,
    nominal: Unicycle,
    u0: WheelSpeeds,
    u1: WheelSpeeds,
}

/// What one measurement `y(k)` told about step `k − 1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepDecision {
    /// The step decided, `k − 1`.
    pub step: u32,
    /// The observer's estimate from `y(k)`.
    pub estimate: InputEstimate,
    /// `b̂(k−1)`, or `None` when the step is erased (fallback applied, pair unknown) or
    /// the decoder does not decide (protocol off).
    pub bit: Option<u8>,
    /// The deviations `[d0, d1]` (m/s, rad/s) that applying `u0D` or `u1D` would have
    /// produced under the decoder's model, when `bit` is decided by a decoder that
    /// [weighs](StepDecoder::weighing) them: the hypotheses a likelihood decision weighs
    /// `estimate` against (an eavesdropper's; the controller decides by distance only).
    pub hypotheses: Option<[Unicycle; 2]>,
}

/// The result of a fresh measurement.
#[derive(Clone, Debug, PartialEq)]
pub struct Measured {
    /// Steps erased because their measurement never arrived (in order).
    pub missing: Range<u32>,
    /// The decision about step `k − 1` (none at `k = 0`).
    pub decision: Option<StepDecision>,
}

/// Tracks the robot with an unknown-input observer and decides bits.
#[derive(Clone, Debug)]
pub struct StepDecoder {
    drive: DiffDrive,
    observer: Observer,
    delta: Unicycle,
    decides: bool,
    weighs: bool,
    last_pair: Option<Pair>,
    next_measurement: u32,
}

impl StepDecoder {
    /// A decoder with the decoder's own wheel model `drive`, a fresh observer, and the
    /// protocol's `delta` (m/s, rad/s); `decides = false` tracks without deciding bits.
    #[must_use]
    pub fn new(drive: DiffDrive, observer: Observer, delta: Unicycle, decides: bool) -> Self {
        Self {
            drive,
            observer,
            delta,
            decides,
            weighs: false,
            last_pair: None,
            next_measurement: 0,
        }
    }

    /// The decoder whose decisions also carry their two hypotheses
    /// ([`StepDecision::hypotheses`]).
    #[must_use]
    pub fn weighing(self) -> Self {
        Self {
            weighs: true,
            ..self
        }
    }

    /// The decoder's wheel model.
    #[must_use]
    pub fn drive(&self) -> DiffDrive {
        self.drive
    }

    /// Replaces the decoder's wheel model (an eavesdropper that identifies `r` and `D`
    /// online); it applies to the decisions that follow.
    pub fn set_drive(&mut self, drive: DiffDrive) {
        self.drive = drive;
    }

    /// Records the pair sent for `step` with its nominal input `uU` (m/s, rad/s).
    pub fn on_command(&mut self, step: u32, nominal: Unicycle, u0: WheelSpeeds, u1: WheelSpeeds) {
        if self.last_pair.is_none_or(|p| step > p.step) {
            self.last_pair = Some(Pair {
                step,
                nominal,
                u0,
                u1,
            });
        }
    }

    /// The next measurement step the decoder waits for.
    #[must_use]
    pub fn next_measurement(&self) -> u32 {
        self.next_measurement
    }

    /// The observer's current state estimate `x̂`.
    #[must_use]
    pub fn state(&self) -> Pose {
        self.observer.state()
    }

    /// The input believed applied on step `step`: its pair's nominal, or — when that pair
    /// was never sent — the midpoint of the last pair, which the robot holds (docs/protocol.md).
    fn input_for(&self, step: u32) -> Unicycle {
        self.last_pair
            .filter(|p| p.step <= step)
            .map_or_else(Unicycle::zeros, |p| p.nominal)
    }

    /// Processes `y(k)`; returns `None` for a stale or duplicate measurement.
    ///
    /// # Errors
    /// [`ObserverError`] when the observer's covariance breaks down.
    pub fn on_measurement(
        &mut self,
        step: u32,
        y: &Pose,
        applied_step: Option<u32>,
    ) -> Result<Option<Measured>, ObserverError> {
        if step < self.next_measurement {
            return Ok(None);
        }
        let missing_start = self.next_measurement.max(1) - 1;
        let missing_end = step.max(1) - 1;
        for gap in missing_start..missing_end {
            // y(gap + 1) never arrived: propagate over step `gap` without a decision.
            let input = self.input_for(gap);
            self.observer.predict(&input, &self.delta);
        }
        self.next_measurement = step + 1;
        let decision = if step == 0 {
            None
        } else {
            let decided = step - 1;
            let estimate = self.observer.step(&self.input_for(decided), y)?;
            let pair = self.last_pair.filter(|p| p.step == decided);
            let (bit, hypotheses) = match pair {
                Some(p) if self.decides && applied_step == Some(decided) => {
                    let applied = self.drive.to_wheels(p.nominal + estimate.deviation);
                    let deviation_of = |u| self.drive.to_unicycle(u) - p.nominal;
                    (
                        Some(decide_bit(&applied, &p.u0, &p.u1)),
                        self.weighs
                            .then(|| [deviation_of(p.u0), deviation_of(p.u1)]),
                    )
                }
                _ => (None, None),
            };
            Some(StepDecision {
                step: decided,
                estimate,
                bit,
                hypotheses,
            })
        };
        Ok(Some(Measured {
            missing: missing_start.min(missing_end)..missing_end,
            decision,
        }))
    }
}
