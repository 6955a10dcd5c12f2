//! The ESC's process-data watchdog (registers 0x0400 divider and 0x0420 time).
//!
//! It is restarted by each complete write of a sync manager whose control byte has the
//! watchdog-trigger bit (6); when it runs out in Op the drive falls back to SafeOp with AL
//! status code 0x001B. A time of 0 disables it, as does a master that never sets the trigger
//! bit (the AKD's SII gives SM2 control 0x24, without it).

use crate::ethercat::registers::{WATCHDOG_DIVIDER, WATCHDOG_STATUS, WATCHDOG_TIME_PROCESS_DATA};

/// Length of one watchdog-divider tick (the ESC's 25 MHz clock).
const TICK_NS: u64 = 40;

/// The process-data watchdog of one drive.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Watchdog {
    last_trigger_ns: Option<u64>,
}

fn u16_at(memory: &[u8], addr: u16) -> u16 {
    u16::from_le_bytes([memory[addr as usize], memory[addr as usize + 1]])
}

/// The watchdog time the registers set, or `None` when it is disabled (time 0).
pub fn timeout_ns(memory: &[u8]) -> Option<u64> {
    let divider = u16_at(memory, WATCHDOG_DIVIDER) as u64;
    let time = u16_at(memory, WATCHDOG_TIME_PROCESS_DATA) as u64;
    (time != 0).then_some((divider + 2) * TICK_NS * time)
}

impl Watchdog {
    /// A trigger: outputs were written at `now_ns`.
    pub fn trigger(&mut self, now_ns: u64) {
        self.last_trigger_ns = Some(now_ns);
    }

    /// Stops it until the next trigger (outputs no longer expected).
    pub fn stop(&mut self) {
        self.last_trigger_ns = None;
    }

    /// Whether it ran out by `now_ns`; updates the watchdog status register (bit 0 = running).
    pub fn expired(&self, now_ns: u64, memory: &mut [u8]) -> bool {
        let expired = match (self.last_trigger_ns, timeout_ns(memory)) {
            (Some(last), Some(timeout)) => now_ns.saturating_sub(last) > timeout,
            _ => false,
        };
        memory[WATCHDOG_STATUS as usize] = u8::from(!expired);
        expired
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_out_after_the_register_time() {
        let mut memory = vec![0u8; 0x1000];
        memory[0x0400..0x0402].copy_from_slice(&0x09C2u16.to_le_bytes());
        memory[0x0420..0x0422].copy_from_slice(&1000u16.to_le_bytes());
        assert_eq!(timeout_ns(&memory), Some(100_000_000));
        let mut w = Watchdog::default();
        assert!(!w.expired(1_000_000_000, &mut memory), "not triggered yet");
        w.trigger(0);
        assert!(!w.expired(100_000_000, &mut memory));
        assert_eq!(memory[0x0440], 1);
        assert!(w.expired(100_000_001, &mut memory));
        assert_eq!(memory[0x0440], 0);
        memory[0x0420..0x0422].fill(0);
        assert!(!w.expired(u64::MAX, &mut memory));
    }
}
