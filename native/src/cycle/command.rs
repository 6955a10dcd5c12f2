//! A joint's command, from its SI value to the drive, in one call on the handle
//! ([`CycleThread::command`]): the target object of the drive's mode of operation that its
//! mapping carries, the value converted by the joint's [`JointScaling`] and encoded in that
//! object's type, then written into the next cycle's outputs, or by SDO where a mode started
//! by a handshake has its target unmapped, and the mode's set-point handshake started in the
//! cycle thread. Nothing waits for the handshake: its outcome is
//! [`CycleThread::setpoint_status`]'s. The drive's own outputs are set likewise, by number and
//! in volts ([`CycleThread::set_drive_outputs`]).

use super::CycleThread;
use crate::drive::ds402::{CommandKind, Mode};
use crate::drive::io::{self, ANALOG_OUTPUT, DIGITAL_OUTPUTS};
use crate::drive::objects;
use crate::drive::scaling::JointScaling;
use crate::error::{CommandRefused, Error, NotSent, Result};
use crate::ethercat::pdo;

/// A joint's command ready to go: what [`CycleThread::prepare_command`] made of it.
#[derive(Clone, Debug, PartialEq)]
pub struct PreparedCommand {
    /// The drive's position on the bus.
    pub position: u16,
    /// What it commands.
    pub kind: CommandKind,
    /// The mode it was made for.
    pub mode: Mode,
    /// The object it is written to.
    pub object: (u16, u8),
    /// The object's bytes.
    pub data: Vec<u8>,
    /// Whether the object is in the outputs (else it goes by SDO).
    pub mapped: bool,
}

/// What is refused when a command of `kind` is.
fn refused(kind: CommandKind) -> String {
    format!("{} command", kind.name())
}

/// `value` as the bytes of `object`.
fn encoded(object: (u16, u8), value: i64, what: impl std::fmt::Display) -> Result<Vec<u8>> {
    objects::encode(object.0, object.1, value)
        .map_err(|e| CommandRefused::NotSent { what: what.to_string(), why: NotSent::Encode(e) }.into())
}

impl CycleThread {
    /// The `kind` command `value` (SI) of the joint on the drive at `position`, scaled by
    /// `scaling`, made ready for the drive's present mode: refused when the mode commands
    /// another kind or none, or the value has no drive value. Nothing is sent.
    pub fn prepare_command(
        &self,
        position: u16,
        kind: CommandKind,
        value: f64,
        scaling: &JointScaling,
    ) -> Result<PreparedCommand> {
        let (rx, _) = self.mapping(position)?;
        let mode = self.mode_set(position).and_then(Mode::from_i8);
        let Some(mode) = mode.filter(|m| m.command() == Some(kind)) else {
            let needs = Mode::ALL.into_iter().filter(|m| m.command() == Some(kind)).map(Mode::snake_name);
            let mode = mode.map_or_else(|| "unknown".to_owned(), Mode::snake_name);
            return Err(CommandRefused::Mode { kind, mode, needs: needs.collect::<Vec<_>>().join(" or ") }.into());
        };
        let drive_value = scaling.to_drive(kind, value).map_err(|e| CommandRefused::Value { kind, reason: e })?;
        let carried = |&&(index, sub): &&(u16, u8)| pdo::find(rx, index, sub).is_some();
        let mapped = mode.command_objects().iter().find(carried);
        // Every mode with a command has a command object.
        let object = *mapped.unwrap_or(&mode.command_objects()[0]);
        let data = encoded(object, drive_value, refused(kind))?;
        Ok(PreparedCommand { position, kind, mode, object, data, mapped: mapped.is_some() })
    }

    /// Sends `command`: into the next cycle's outputs, or by SDO where unmapped, then starts
    /// its mode's set-point handshake where it has one (its number; the handshake runs in the
    /// cycle thread and nothing here waits for it). Refused, nothing sent, when the mode
    /// changed since it was made, or where the cycle refuses the set-point (its step past the
    /// joint's limits, a trajectory or a homing driving the drive).
    pub fn apply_command(&self, command: &PreparedCommand) -> Result<Option<u32>> {
        let (kind, position) = (command.kind, command.position);
        let mode = self.mode_set(position).and_then(Mode::from_i8);
        if mode != Some(command.mode) {
            let now = mode.map_or_else(|| "unknown".to_owned(), Mode::snake_name);
            return Err(CommandRefused::ModeChanged { kind, made: command.mode.snake_name(), now }.into());
        }
        let (index, subindex) = command.object;
        if command.mapped {
            let not_sent = |why| Error::from(CommandRefused::NotSent { what: refused(kind), why });
            self.set_object(position, index, subindex, &command.data).map_err(|e| match e {
                Error::Setting(e) => not_sent(NotSent::Setting(e)),
                Error::Unavailable(e) => not_sent(NotSent::Unavailable(e)),
                e => e,
            })?;
        } else {
            self.sdo_write(position, index, subindex, &command.data)?;
        }
        command.mode.handshake_controlword().map(|bits| self.start_setpoint(position, bits, None)).transpose()
    }

    /// Commands several joints at once, each (drive position, kind, SI value, scaling): every
    /// one is made ready first ([`prepare_command`](Self::prepare_command)), so that a refusal
    /// sends none of them, then each is sent in turn ([`apply_command`](Self::apply_command));
    /// each one's set-point handshake number where its mode has one; a refusal comes with the
    /// index of the command refused.
    pub fn command(
        &self,
        commands: &[(u16, CommandKind, f64, JointScaling)],
    ) -> std::result::Result<Vec<Option<u32>>, (usize, Error)> {
        let prepared = commands
            .iter()
            .enumerate()
            .map(|(i, (position, kind, value, scaling))| {
                self.prepare_command(*position, *kind, *value, scaling).map_err(|e| (i, e))
            })
            .collect::<std::result::Result<Vec<_>, _>>()?;
        prepared.iter().enumerate().map(|(i, c)| self.apply_command(c).map_err(|e| (i, e))).collect()
    }

    /// Sets the digital outputs of the drive at `position` at `levels` (each an AKD output
    /// number and its level) and its analog output set-point at `analog_volts` (V, at
    /// `volts_per_count`) from the next cycle on, its other outputs as they are and a held
    /// target held; everything is checked first, so a refusal (a mapping without the object,
    /// naming those with it for the drive's mode and `joint`; an output the AKD does not have; a
    /// voltage that is not finite or past the output's range) changes nothing.
    pub fn set_drive_outputs(
        &self,
        position: u16,
        joint: &str,
        levels: &[(i64, bool)],
        analog_volts: Option<f64>,
        volts_per_count: f64,
    ) -> Result<()> {
        let (rx, _) = self.mapping(position)?;
        let unmapped = |what, wanted: fn(io::Carried) -> bool| {
            let mode = self.mode_set(position).and_then(Mode::from_i8);
            let mappings = mode.map_or_else(
                || io::mappings_in_words(Mode::CyclicSynchronousPosition, |_| false),
                |m| io::mappings_in_words(m, wanted),
            );
            let mode = mode.map_or_else(|| "unknown".to_owned(), Mode::snake_name);
            Error::from(CommandRefused::OutputUnmapped { joint: joint.to_owned(), what, mode, mappings })
        };
        let mut writes = Vec::new();
        if !levels.is_empty() {
            let (index, sub) = DIGITAL_OUTPUTS;
            let (offset, entry) = pdo::find(rx, index, sub)
                .ok_or_else(|| unmapped("digital outputs (0x60FE:01)", |c: io::Carried| c.digital_outputs))?;
            let outputs = self.outputs(position)?;
            let bytes = &outputs[offset..offset + entry.byte_len()];
            let word = bytes.iter().rev().fold(0u32, |w, b| w << 8 | u32::from(*b));
            let word = io::with_output_levels(word, levels)
                .map_err(|n| CommandRefused::NoSuchOutput { number: n.to_string() })?;
            writes.push((DIGITAL_OUTPUTS, encoded(DIGITAL_OUTPUTS, word.into(), "outputs")?));
        }
        if let Some(volts) = analog_volts {
            let (index, sub) = ANALOG_OUTPUT;
            pdo::find(rx, index, sub)
                .ok_or_else(|| unmapped("analog output (0x3470:03)", |c: io::Carried| c.analog_output))?;
            let highest = 32767.0 * volts_per_count;
            if !volts.is_finite() || volts.abs() > highest * (1.0 + 1e-12) {
                return Err(CommandRefused::Voltage { volts, highest }.into());
            }
            let counts = (volts / volts_per_count).round().clamp(-32767.0, 32767.0) as i64;
            writes.push((ANALOG_OUTPUT, encoded(ANALOG_OUTPUT, counts, "analog output")?));
        }
        for ((index, sub), data) in writes {
            self.set_object(position, index, sub, &data)?;
        }
        Ok(())
    }
}
