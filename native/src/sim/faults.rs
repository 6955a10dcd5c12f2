//! The faults the virtual AKD raises, by itself or injected by a test or the simulator
//! command: the AKD's fault number and text, the CiA error code it shows in 0x603F and sends
//! in the emergency message.
//!
//! Error codes: 0x4310 for F235 is the AKD's own table (Kollmorgen, "CANopen Emergency
//! Messages and Error Codes"); the others are the CiA 402/301 codes of the same class
//! (0x8611 following error, 0x8700 sync controller, 0x8250 RPDO time-out), as the AKD's table
//! is not in the project's sources.

use crate::drive::akd_fault::{self, AkdFault};
use crate::error::UnknownName;
use crate::ethercat::coe::Emergency;

wire_codes! {
    /// A drive fault.
    pub enum Fault: u16, "AKD fault number" {
        /// F439: the following error exceeded the window 0x6065.
        FollowingError = 439 => "following_error",
        /// F235: heat sink over-temperature.
        OverTemperature = 235 => "over_temperature",
        /// F125: more than seven frames missed while enabled (AKD manual §5.14, FBUS.PARAM04).
        SyncLost = 125 => "sync_lost",
        /// F706: enabled in a cyclic position mode but no cyclic set-points arrive.
        SetpointsMissing = 706 => "setpoints_missing",
    }
}

/// Error register 0x1001 bits (CiA 301).
mod error_register {
    pub const GENERIC: u8 = 1 << 0;
    pub const TEMPERATURE: u8 = 1 << 3;
    pub const COMMUNICATION: u8 = 1 << 4;
    pub const DEVICE_PROFILE: u8 = 1 << 5;
}

impl Fault {
    /// The AKD's fault number (F439, ...).
    pub fn number(self) -> u16 {
        self as u16
    }

    /// The fault's number, text and code as the real drive has them.
    fn info(self) -> &'static AkdFault {
        akd_fault::by_number(self.number()).expect("every simulated fault is in the table")
    }

    /// The AKD's text.
    pub fn text(self) -> &'static str {
        self.info().text
    }

    /// The CiA error code of 0x603F and the emergency message.
    pub fn error_code(self) -> u16 {
        self.info().error_code
    }

    /// The error register 0x1001 while the fault is active.
    pub fn error_register(self) -> u8 {
        error_register::GENERIC
            | match self {
                Fault::FollowingError => error_register::DEVICE_PROFILE,
                Fault::OverTemperature => error_register::TEMPERATURE,
                Fault::SyncLost | Fault::SetpointsMissing => error_register::COMMUNICATION,
            }
    }

    /// The emergency message; its manufacturer data carry the fault number in ASCII
    /// ("F125"), as the AKD sends it with CANOPEN.ADDMANUEMCYCODE set.
    pub fn emergency(self) -> Emergency {
        let mut data = [0u8; 5];
        let text = format!("F{}", self.number());
        data[..4].copy_from_slice(&text.as_bytes()[..4]);
        Emergency { error_code: self.error_code(), error_register: self.error_register(), data }
    }

    /// The fault named `name` (its [`name`](Fault::name) or "F" and its number, e.g. "F125").
    pub fn from_name(name: &str) -> Result<Fault, UnknownName> {
        Self::ALL.iter().copied().find(|f| f.name() == name || format!("F{}", f.number()) == name).ok_or_else(|| {
            UnknownName::Fault {
                name: name.to_owned(),
                allowed: Self::ALL.iter().map(|f| format!("{} (F{})", f.name(), f.number())).collect(),
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_numbers_find_the_fault() {
        for fault in Fault::ALL {
            assert_eq!(Fault::from_name(fault.name()), Ok(fault));
            assert_eq!(Fault::from_name(&format!("F{}", fault.number())), Ok(fault));
        }
        let e = Fault::from_name("F999").unwrap_err().to_string();
        assert!(e.contains("F999") && e.contains("sync_lost (F125)"), "{e}");
    }

    #[test]
    fn the_emergency_carries_code_register_and_number() {
        let e = Fault::SyncLost.emergency();
        assert_eq!((e.error_code, e.error_register, &e.data), (0x8700, 0x11, b"F125\0"));
        assert_eq!(Fault::OverTemperature.emergency().error_register, 0x09);
    }
}
