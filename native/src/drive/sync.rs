//! How an AKD follows the line's clock, pure and free of I/O: FBUS.PARAM02 switches its PLL to
//! SYNC0 or leaves it on the SM2 event (AKD manual §5.11), and the interpolation time period
//! 0x60C2 tells it the cycle time. The drive profile writes both around the master's clock
//! set-up ([`crate::drive::akd::AkdLine`]); the virtual AKD reads them back.

use crate::setting::SettingError;

/// The AKD's shortest cycle (AKD manual §5.9): 250 µs.
pub const MIN_CYCLE_NS: u32 = 250_000;

/// FBUS.PARAM02, the AKD's switch of its PLL (manual §5.11, §5.14): bit 0 set, the drive's
/// 62.5 µs task follows SYNC0; clear, it does not wait for DC events and follows the SM2
/// event (§5.11.2). The manual names the parameter but gives no CoE index for it; it is
/// modelled here as manufacturer object 0x3E02:00 (UNSIGNED32, in the AKD's 0x2000-0x5FFF
/// manufacturer range where its other drive parameters sit, e.g. 0x3470, 0x3497). The virtual
/// AKD holds it there.
///
/// The index is a guess, and on a real drive 0x3E02 could be another, writable parameter. A
/// master must not write an object whose identity it cannot confirm, so the profile first asks
/// the drive's SDO information for the object's description and writes only when its name
/// names FBUS.PARAM02 ([`crate::ethercat::coe::names_parameter`]); otherwise it writes nothing
/// and records the parameter as unknown ([`crate::drive::akd::AkdSlave::set_drive_sync`]), and
/// the node's /diagnostics warns to set FBUS.PARAM02 = 1 on the drive (WorkBench).
pub const FBUS_PARAM02: u16 = 0x3E02;
/// The parameter's name as the AKD names its parameters (manual, WorkBench), and as the
/// virtual AKD's SDO information names object [`FBUS_PARAM02`].
pub const FBUS_PARAM02_NAME: &str = "FBUS.PARAM02";

/// FBUS.PARAM02 bit 0: the drive's PLL follows SYNC0.
pub const FBUS_PARAM02_PLL: u32 = 0x0000_0001;

/// The interpolation time period 0x60C2, the drive's cycle time: units (sub 1) times a power
/// of ten (sub 2), which the drive checks as one value when the power is written.
pub const INTERPOLATION_TIME_PERIOD: u16 = 0x60C2;

/// Objects the drive checks as a whole when their last entry is written: a restore that
/// changes any entry writes them all.
pub const WRITTEN_WHOLE: &[u16] = &[INTERPOLATION_TIME_PERIOD];

/// The cycle time as the interpolation time period 0x60C2: units (sub 1, UNSIGNED8) and a
/// signed power of ten (sub 2, INTEGER8), choosing the coarsest exact exponent, e.g. 2 ms =
/// (2, -3), 250 µs = (25, -5). Refuses cycles under 250 µs or without an exact encoding.
pub fn interpolation_time_period(cycle_ns: u32) -> Result<(u8, i8), SettingError> {
    if cycle_ns < MIN_CYCLE_NS {
        return Err(SettingError::CycleTimeBelowMinimum { cycle_ns, min_ns: MIN_CYCLE_NS });
    }
    (-9i8..=0)
        .rev()
        .find_map(|exponent| {
            let unit = 10u64.pow((exponent + 9) as u32);
            let units = cycle_ns as u64 / unit;
            ((cycle_ns as u64).is_multiple_of(unit) && units <= u8::MAX as u64).then_some((units as u8, exponent))
        })
        .ok_or(SettingError::CycleTimeNotEncodable { cycle_ns })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn interpolation_period_as_the_manual_writes_it() {
        assert_eq!(interpolation_time_period(2_000_000).unwrap(), (2, -3));
        assert_eq!(interpolation_time_period(250_000).unwrap(), (25, -5));
        assert_eq!(interpolation_time_period(1_000_000).unwrap(), (1, -3));
        assert_eq!(interpolation_time_period(500_000).unwrap(), (5, -4));
        assert!(interpolation_time_period(312_500).is_err());
        let err = interpolation_time_period(125_000).unwrap_err().to_string();
        assert!(err.contains("250000"), "{err}");
        assert!(interpolation_time_period(1_000_001).is_err());
    }

    proptest! {
        #[test]
        fn interpolation_period_is_exact(cycle in MIN_CYCLE_NS..u32::MAX) {
            if let Ok((units, exponent)) = interpolation_time_period(cycle) {
                prop_assert_eq!(units as u64 * 10u64.pow((exponent + 9) as u32), cycle as u64);
            }
        }
    }
}
