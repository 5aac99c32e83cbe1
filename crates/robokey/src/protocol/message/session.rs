//! The session layer (docs/protocol.md): one message per sample step, the robot's
//! measurement and the controller's command, in either sensing mode. The session endpoints
//! take them; each carries its step k in the header's `step` field, not in its payload.

use robokey_codec::{Codec, DecodeError, Reader, Writer};

use super::MessageType;
use crate::protocol::fates::FateWindow;

/// A message of the session layer.
#[derive(Clone, Debug, PartialEq)]
pub enum SessionMessage {
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
}

impl SessionMessage {
    /// Its wire type.
    #[must_use]
    pub fn message_type(&self) -> MessageType {
        match self {
            Self::Measurement { .. } => MessageType::Measurement,
            Self::Command { .. } => MessageType::Command,
            Self::PrivateMeasurement { .. } => MessageType::PrivateMeasurement,
            Self::DoubletCommand { .. } => MessageType::DoubletCommand,
        }
    }

    /// Its sample index k (the header's `step`).
    #[must_use]
    pub fn step(&self) -> u32 {
        match self {
            Self::Measurement { step, .. }
            | Self::Command { step, .. }
            | Self::PrivateMeasurement { step, .. }
            | Self::DoubletCommand { step, .. } => *step,
        }
    }

    /// Appends its payload (docs/wire.md, "Payloads"); the step goes in the header.
    pub(super) fn encode_payload(&self, writer: &mut Writer) {
        match self {
            Self::Measurement {
                y,
                applied_step,
                fate_cursor,
                ..
            } => {
                writer.f64s(y);
                put_applied_step(writer, *applied_step);
                writer.u32(*fate_cursor);
            }
            Self::PrivateMeasurement {
                applied_step,
                fate_cursor,
                ..
            } => {
                put_applied_step(writer, *applied_step);
                writer.u32(*fate_cursor);
            }
            Self::Command { u0, u1, fates, .. } => {
                writer.f64s(u0);
                writer.f64s(u1);
                fates.encode(writer);
            }
            Self::DoubletCommand {
                sample,
                first,
                second,
                fates,
                ..
            } => {
                writer.f64s(sample);
                writer.f64s(first);
                writer.u8(u8::from(second.is_some()));
                writer.f64s(&second.unwrap_or([0.0; 2]));
                fates.encode(writer);
            }
        }
    }

    /// `y: 3 × f64 | applied_flag u8 | applied_step u32 | fate_cursor u32`.
    pub(super) fn decode_measurement(
        step: u32,
        reader: &mut Reader<'_>,
    ) -> Result<Self, DecodeError> {
        Ok(Self::Measurement {
            step,
            y: reader.f64s("y")?,
            applied_step: read_applied_step(reader)?,
            fate_cursor: reader.u32("fate_cursor")?,
        })
    }

    /// `applied_flag u8 | applied_step u32 | fate_cursor u32`.
    pub(super) fn decode_private_measurement(
        step: u32,
        reader: &mut Reader<'_>,
    ) -> Result<Self, DecodeError> {
        Ok(Self::PrivateMeasurement {
            step,
            applied_step: read_applied_step(reader)?,
            fate_cursor: reader.u32("fate_cursor")?,
        })
    }

    /// `u0D: 2 × f64 | u1D: 2 × f64 | fates`.
    pub(super) fn decode_command(step: u32, reader: &mut Reader<'_>) -> Result<Self, DecodeError> {
        Ok(Self::Command {
            step,
            u0: reader.f64s("u0D")?,
            u1: reader.f64s("u1D")?,
            fates: FateWindow::decode(reader)?,
        })
    }

    /// `sample: 3 × f64 | first: 2 × f64 | second_flag u8 | second: 2 × f64 | fates`, the
    /// second input all zero bits when the flag says it is absent.
    pub(super) fn decode_doublet_command(
        step: u32,
        reader: &mut Reader<'_>,
    ) -> Result<Self, DecodeError> {
        let sample = reader.f64s("sample")?;
        let first = reader.f64s("first")?;
        let flag = reader.u8("second_flag")?;
        let pair: [f64; 2] = reader.f64s("second")?;
        let second = match flag {
            0 => match pair.iter().find(|v| v.to_bits() != 0) {
                None => None,
                Some(set) => {
                    return Err(DecodeError::Invalid {
                        field: "second",
                        value: set.to_bits(),
                        allowed: "zero bits when second_flag is 0",
                    });
                }
            },
            1 => Some(pair),
            other => {
                return Err(DecodeError::Invalid {
                    field: "second_flag",
                    value: other.into(),
                    allowed: "0 (none) or 1 (present)",
                });
            }
        };
        Ok(Self::DoubletCommand {
            step,
            sample,
            first,
            second,
            fates: FateWindow::decode(reader)?,
        })
    }
}

/// Appends `applied_flag u8 | applied_step u32`, the step 0 when absent.
fn put_applied_step(writer: &mut Writer, applied_step: Option<u32>) {
    writer.u8(u8::from(applied_step.is_some()));
    writer.u32(applied_step.unwrap_or(0));
}

/// Reads `applied_flag u8 | applied_step u32`: flag 1 with any step, or flag 0 with step 0.
fn read_applied_step(reader: &mut Reader<'_>) -> Result<Option<u32>, DecodeError> {
    match (reader.u8("applied_flag")?, reader.u32("applied_step")?) {
        (1, step) => Ok(Some(step)),
        (0, 0) => Ok(None),
        (0, step) => Err(DecodeError::Invalid {
            field: "applied_step",
            value: step.into(),
            allowed: "0 when applied_flag is 0",
        }),
        (flag, _) => Err(DecodeError::Invalid {
            field: "applied_flag",
            value: flag.into(),
            allowed: "0 (none) or 1 (present)",
        }),
    }
}

impl Codec for FateWindow {
    /// `fates.first u32 | fates.count u8 | fates.accepted u64`.
    fn encode(&self, writer: &mut Writer) {
        writer.u32(self.first);
        writer.u8(self.count);
        writer.u64(self.accepted);
    }

    fn decode(reader: &mut Reader<'_>) -> Result<Self, DecodeError> {
        let fates = Self {
            first: reader.u32("fates.first")?,
            count: reader.u8("fates.count")?,
            accepted: reader.u64("fates.accepted")?,
        };
        if u32::from(fates.count) > Self::CAPACITY {
            return Err(DecodeError::Invalid {
                field: "fates.count",
                value: fates.count.into(),
                allowed: "at most 64",
            });
        }
        Ok(fates)
    }
}
