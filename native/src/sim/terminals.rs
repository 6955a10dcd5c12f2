//! What is wired to the virtual AKD's connectors besides its digital inputs
//! ([`crate::sim::digital_inputs`]): the limit and home switches of 0x60FD, the analog input
//! 0x3470:04, and the digital and analog outputs the master drives through 0x60FE:01 and
//! 0x3470:03 (see [`crate::drive::io`] for the bits and the scaling, and what the manuals leave out).
//!
//! The switches are set as signals of their own (on a real AKD a digital input carries each, as
//! the drive's configuration assigns it; the virtual AKD does not model that assignment). A
//! limit switch stops motion in the direction it guards while it is active: the drive brakes a
//! move toward it with the quick stop deceleration 0x6085 and holds, follows commands away from
//! it, and shows internal limit active (statusword bit 11) while it holds a command back. It
//! does not fault or disable: the manuals say no more of how the AKD reacts, so this is the
//! model's choice.

use crate::drive::io::{self, Switch, ANALOG_VOLTS_PER_COUNT};
use crate::error::SettingError;
use crate::sim::motion::STEP_S;
use crate::sim::od::ObjectDictionary;

/// The largest analog voltage a 16-bit object holds at [`ANALOG_VOLTS_PER_COUNT`].
pub const ANALOG_MAX_VOLTS: f64 = i16::MAX as f64 * ANALOG_VOLTS_PER_COUNT;

/// `volts` as the counts of a 16-bit analog object, refused when not finite or out of range.
pub fn analog_counts(what: &'static str, volts: f64) -> Result<i16, SettingError> {
    let counts = volts / ANALOG_VOLTS_PER_COUNT;
    if !counts.is_finite() || counts.round().abs() > i16::MAX as f64 {
        return Err(SettingError::AnalogVoltage { what, volts, max: ANALOG_MAX_VOLTS });
    }
    Ok(counts.round() as i16)
}

/// The switches and the analog input as set, and the outputs as the master drives them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Terminals {
    switches: u32,
    analog_input: i16,
}

/// The outputs as the drive drives them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Outputs {
    /// Digital outputs 1..2, output 1 in bit 0.
    pub digital: u8,
    /// The analog output, V.
    pub analog: f64,
}

impl Terminals {
    /// Sets switch `name` ("negative_limit", "positive_limit", "home_switch", "interlock")
    /// active or not.
    pub fn set_switch(&mut self, name: &str, active: bool) -> Result<(), SettingError> {
        let switch = Switch::from_name(name)?;
        self.switches = if active { self.switches | switch.mask() } else { self.switches & !switch.mask() };
        Ok(())
    }

    /// Sets the analog input to `volts`.
    pub fn set_analog_input(&mut self, volts: f64) -> Result<(), SettingError> {
        self.analog_input = analog_counts("analog input", volts)?;
        Ok(())
    }

    /// Which directions the limit switches block: (negative, positive).
    pub fn blocked(&self) -> (bool, bool) {
        (Switch::NegativeLimit.active(self.switches), Switch::PositiveLimit.active(self.switches))
    }

    /// Writes the digital inputs 0x60FD (the switches and `levels`, input 1 in bit 0), the
    /// analog input, and the analog output 0x3470:02 as the set-point 0x3470:03 drives it.
    pub fn publish(&self, od: &mut ObjectDictionary, levels: u8) {
        let digital =
            (1..=io::INPUT_COUNT).filter(|i| levels >> (i - 1) & 1 == 1).fold(self.switches, |w, i| w | io::bit(i));
        od.set(io::DIGITAL_INPUTS.0, io::DIGITAL_INPUTS.1, &digital.to_le_bytes());
        od.set(io::ANALOG_INPUT.0, io::ANALOG_INPUT.1, &self.analog_input.to_le_bytes());
        let output = od.get(io::ANALOG_OUTPUT.0, io::ANALOG_OUTPUT.1).map(|b| [b[0], b[1]]).unwrap_or_default();
        od.set(0x3470, 2, &output);
    }

    /// The outputs as the master drives them through `od`.
    pub fn outputs(od: &ObjectDictionary) -> Outputs {
        let word = od
            .get(io::DIGITAL_OUTPUTS.0, io::DIGITAL_OUTPUTS.1)
            .map_or(0, |b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
        let analog = od.get(0x3470, 2).map_or(0, |b| i16::from_le_bytes([b[0], b[1]]));
        Outputs { digital: io::outputs(word), analog: f64::from(analog) * ANALOG_VOLTS_PER_COUNT }
    }
}

/// How the limit switches hold a command back: where the command may go in a blocked
/// direction, braking there with the quick stop deceleration (see the module's words).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LimitStop {
    /// The furthest the command may go, and the stop ramp's velocity, while a switch is active.
    stop: Option<(f64, f64)>,
    /// Whether it held the last command back.
    pub limited: bool,
}

impl LimitStop {
    /// The position command and its velocity (counts, counts/s) of one model step, with the
    /// directions `blocked` (negative, positive) held back, braking at `deceleration` counts/s².
    pub fn position(
        &mut self,
        blocked: (bool, bool),
        (position, velocity): (f64, f64),
        deceleration: f64,
    ) -> (f64, f64) {
        let blocks = |x: f64| (x < 0.0 && blocked.0) || (x > 0.0 && blocked.1);
        if !blocked.0 && !blocked.1 {
            *self = LimitStop::default();
            return (position, velocity);
        }
        let ramp = |v: f64| if blocks(v) { v } else { 0.0 };
        let (mut stop, mut v) = self.stop.unwrap_or((position, ramp(velocity)));
        if blocks(v) {
            v = if deceleration > 0.0 { v - v.signum() * (deceleration * STEP_S).min(v.abs()) } else { 0.0 };
            stop += v * STEP_S;
        }
        self.limited = blocks(position - stop);
        let command = if self.limited {
            (stop, v)
        } else {
            // Behind the stop: the command goes on, and the stop comes back with it.
            (stop, v) = (position, ramp(velocity));
            (position, velocity)
        };
        self.stop = Some((stop, v));
        command
    }

    /// A velocity (or torque) `target` with the directions `blocked` held back: zero where it
    /// points into one.
    pub fn target(&mut self, blocked: (bool, bool), target: f64) -> f64 {
        self.limited = (target < 0.0 && blocked.0) || (target > 0.0 && blocked.1);
        if self.limited {
            0.0
        } else {
            target
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn switches_and_inputs_make_0x60fd_and_the_analog_values_are_scaled() {
        let mut t = Terminals::default();
        t.set_switch("positive_limit", true).unwrap();
        t.set_switch("home_switch", true).unwrap();
        t.set_switch("home_switch", false).unwrap();
        assert!(t.set_switch("limit", true).unwrap_err().to_string().contains("negative_limit, positive_limit"));
        t.set_analog_input(5.0).unwrap();
        assert!(t.set_analog_input(f64::NAN).is_err());
        assert!(t.set_analog_input(10.5).unwrap_err().to_string().contains("±10.0000 V"));
        let mut od = ObjectDictionary::akd();
        od.set(0x60FE, 1, &io::bit(2).to_le_bytes());
        od.set(0x3470, 3, &(-16384i16).to_le_bytes());
        t.publish(&mut od, 0b000_0101);
        assert_eq!(od.get(0x60FD, 0).unwrap(), (0x2 | io::bit(1) | io::bit(3)).to_le_bytes());
        assert_eq!(od.get(0x3470, 4).unwrap(), 16384i16.to_le_bytes());
        let outputs = Terminals::outputs(&od);
        assert_eq!(outputs.digital, 0b10);
        assert!((outputs.analog + 5.0).abs() < 1e-3, "{outputs:?}");
        assert_eq!(t.blocked(), (false, true));
    }

    #[test]
    fn a_limit_switch_brakes_a_move_toward_it_and_lets_one_away_from_it_go() {
        let mut stop = LimitStop::default();
        // Commanded at 10000 counts/s toward the positive switch, braking at 1e6 counts/s².
        let (mut position, velocity) = (0.0, 10_000.0);
        let mut last = (0.0, 0.0);
        for _ in 0..1000 {
            position += velocity * STEP_S;
            last = stop.position((false, true), (position, velocity), 1e6);
        }
        assert!(stop.limited && last.1 == 0.0, "{last:?}");
        // 10000 counts/s braked at 1e6 counts/s² stops within 50 counts of where the switch came.
        assert!(last.0 > 0.0 && last.0 < 60.0 + velocity * STEP_S, "{last:?}");
        // Back away from it: followed at once, and the stop comes back with the command.
        let away = stop.position((false, true), (last.0 - 100.0, -1000.0), 1e6);
        assert_eq!(away, (last.0 - 100.0, -1000.0));
        assert!(!stop.limited);
        let again = stop.position((false, true), (last.0, 1000.0), 1e6);
        assert!(stop.limited && again.0 < last.0, "toward it again: held near where it turned, {again:?}");
        assert_eq!(stop.position((false, false), (5.0, 1.0), 1e6), (5.0, 1.0), "released");
        assert_eq!((stop.target((true, false), -3.0), stop.limited), (0.0, true));
        assert_eq!((stop.target((true, false), 3.0), stop.limited), (3.0, false));
    }
}
