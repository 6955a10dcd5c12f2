//! What the virtual AKD's synchronisation is told, and whether its PLL would lock (AKD manual
//! §5.11): SYNC0 from the ESC's DC registers (activation 0x0981, start 0x0990, cycle 0x09A0),
//! FBUS.PARAM02 and the drive's cycle time 0x60C2 from the object dictionary. The PLL follows
//! SYNC0 when FBUS.PARAM02 bit 0 is set and SYNC0 runs; it locks when the SYNC0 cycle is the
//! drive's cycle time. Otherwise the drive follows the SM2 event (§5.11.2).

use crate::drive::sync::{FBUS_PARAM02, FBUS_PARAM02_PLL};
use crate::ethercat::registers as reg;
use crate::sim::od::{self, ObjectDictionary};

/// DC activation bits the drive needs for SYNC0: cyclic unit (bit 0) and SYNC0 (bit 1).
const SYNC0_ACTIVE: u8 = 0x03;

named_variants! {
    /// What drives the drive's PLL.
    pub enum SyncSource {
        /// The DC SYNC0 event.
        Sync0 => "sync0",
        /// The SM2 event of each cyclic frame.
        Sm2 => "sm2",
    }
    /// "sync0" or "sm2".
    fn name;
}

/// One virtual AKD's synchronisation as the master set it up (`Simulator.drive_state()["dc"]`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObject))]
pub struct SyncState {
    /// Whether SYNC0 is activated (0x0981 bits 0 and 1).
    pub sync0_active: bool,
    /// SYNC0 cycle time (0x09A0), ns.
    pub sync0_cycle_ns: u32,
    /// First SYNC0 pulse (0x0990), system time ns.
    pub sync0_start_ns: u64,
    /// FBUS.PARAM02.
    pub fbus_param02: u32,
    /// The drive's cycle time 0x60C2, ns (`None` when not representable).
    pub cycle_ns: Option<u64>,
    /// What the PLL follows.
    pub source: SyncSource,
    /// Whether the PLL would lock: it follows SYNC0 and SYNC0's cycle is the drive's.
    pub pll_locked: bool,
}

impl SyncState {
    /// The state from the ESC's `registers` and the drive's object dictionary.
    pub fn of(registers: &[u8], od: &ObjectDictionary) -> Self {
        let bytes = |at: u16, n: usize| &registers[at as usize..at as usize + n];
        let sync0_active = registers[reg::DC_ACTIVATION as usize] & SYNC0_ACTIVE == SYNC0_ACTIVE;
        let sync0_cycle_ns = u32::from_le_bytes(bytes(reg::DC_SYNC0_CYCLE_TIME, 4).try_into().expect("4 bytes"));
        let sync0_start_ns = u64::from_le_bytes(bytes(reg::DC_SYNC0_START_TIME, 8).try_into().expect("8 bytes"));
        let fbus_param02 = od.get(FBUS_PARAM02, 0).map_or(0, |v| u32::from_le_bytes(v.try_into().unwrap_or([0; 4])));
        let byte = |sub| od.get(0x60C2, sub).and_then(|v| v.first().copied());
        let cycle_ns = byte(1).zip(byte(2)).and_then(|(units, index)| od::cycle_ns(units, index as i8));
        let source = match fbus_param02 & FBUS_PARAM02_PLL != 0 && sync0_active {
            true => SyncSource::Sync0,
            false => SyncSource::Sm2,
        };
        let pll_locked = source == SyncSource::Sync0 && cycle_ns == Some(sync0_cycle_ns as u64);
        SyncState { sync0_active, sync0_cycle_ns, sync0_start_ns, fbus_param02, cycle_ns, source, pll_locked }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pll_follows_sync0_only_when_told_and_locks_at_the_drives_cycle() {
        let mut registers = vec![0u8; 0x1000];
        let mut od = ObjectDictionary::akd();
        let power_up = SyncState::of(&registers, &od);
        assert_eq!(
            (power_up.source, power_up.pll_locked, power_up.cycle_ns),
            (SyncSource::Sm2, false, Some(2_000_000))
        );
        registers[0x0981] = 0x03;
        registers[0x09A0..0x09A4].copy_from_slice(&2_000_000u32.to_le_bytes());
        // SYNC0 runs but FBUS.PARAM02 is 0: the drive still follows SM2.
        assert_eq!(SyncState::of(&registers, &od).source, SyncSource::Sm2);
        od.set(FBUS_PARAM02, 0, &1u32.to_le_bytes());
        let locked = SyncState::of(&registers, &od);
        assert_eq!((locked.source, locked.pll_locked, locked.fbus_param02), (SyncSource::Sync0, true, 1));
        od.set(0x60C2, 1, &[1]);
        assert!(!SyncState::of(&registers, &od).pll_locked, "1 ms drive cycle against a 2 ms SYNC0");
    }
}
