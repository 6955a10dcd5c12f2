//! Distributed-clock arithmetic (ETG.1000.4 §9.1, ETG.1020 §9), pure and free of I/O.
//!
//! The master latches every slave's port receive times with one broadcast write to 0x0900,
//! derives each slave's propagation delay from how long the frame took to come back through
//! the slaves behind it, and sets each slave's system-time offset so that all clocks read the
//! master's time (ns since 2000-01-01). SYNC0 then starts on a cycle boundary of that time;
//! each cycle's ARMW/FRMW of the reference clock's system time keeps the others from drifting.

use std::time::Duration;

use crate::setting::SettingError;

/// Seconds from the Unix epoch to the EtherCAT epoch, 2000-01-01 00:00:00 UTC.
pub const EPOCH_OFFSET_S: u64 = 946_684_800;

/// EtherCAT system time (ns since 2000-01-01) of a time given as elapsed since the Unix epoch.
pub fn system_time(since_unix_epoch: Duration) -> u64 {
    (since_unix_epoch.as_nanos() as u64).wrapping_sub(EPOCH_OFFSET_S * 1_000_000_000)
}

/// The four 32-bit port receive times of registers 0x0900..0x090F, latched by a write to 0x0900.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PortReceiveTimes(pub [u32; 4]);

impl PortReceiveTimes {
    /// Decodes the 16 bytes read from 0x0900.
    pub fn decode(bytes: &[u8; 16]) -> Self {
        let word = |i: usize| u32::from_le_bytes([bytes[4 * i], bytes[4 * i + 1], bytes[4 * i + 2], bytes[4 * i + 3]]);
        PortReceiveTimes([word(0), word(1), word(2), word(3)])
    }

    /// Time the frame spent behind this slave: from passing port 0 on the way out to coming
    /// back through port 1. A port time counts only when the port has a successor.
    pub fn loop_time(&self, has_successor: bool) -> u32 {
        if has_successor {
            self.0[1].wrapping_sub(self.0[0])
        } else {
            0
        }
    }
}

/// Propagation delay of every slave of a line (port 0 in, port 1 out, as the AKD's two ports
/// are wired), from the receive times latched by one frame. Slave k's delay exceeds slave
/// k-1's by half of what the frame spent between passing k-1 and passing k on both ways.
/// `delays` receives one value per slave; the first slave is the reference (delay 0).
pub fn propagation_delays(times: &[PortReceiveTimes], delays: &mut [u32]) {
    let last = times.len().saturating_sub(1);
    let mut delay = 0u32;
    for (k, out) in delays.iter_mut().enumerate().take(times.len()) {
        if k > 0 {
            let before = times[k - 1].loop_time(true);
            let after = times[k].loop_time(k < last);
            delay = delay.wrapping_add(before.wrapping_sub(after) / 2);
        }
        *out = delay;
    }
}

/// System-time offset (register 0x0920) that makes a slave's clock read the master's time:
/// the slave saw the latch frame `delay_ns` after the master sent it at `master_time_ns`, and
/// its local clock read `local_receive_ns` (register 0x0918) then.
pub fn system_time_offset(master_time_ns: u64, delay_ns: u32, local_receive_ns: u64) -> u64 {
    master_time_ns.wrapping_add(delay_ns as u64).wrapping_sub(local_receive_ns)
}

/// First SYNC0 pulse (register 0x0990): the first cycle boundary at least `margin_ns` after
/// `system_time_ns`, so that every slave is armed before it comes.
pub fn sync0_start(system_time_ns: u64, cycle_ns: u32, margin_ns: u64) -> u64 {
    let cycle = cycle_ns.max(1) as u64;
    (system_time_ns.saturating_add(margin_ns) / cycle + 1) * cycle
}

/// Checks a SYNC0 shift against the cycle: the first pulse, and with it every pulse, moves by
/// `shift_ns` from the cycle boundary; a shift of a whole cycle or more would name the same
/// pulses as a smaller one, so it is refused as a mistake (a wrong unit, most often).
pub fn check_sync0_shift(shift_ns: i64, cycle_ns: u32) -> Result<i32, SettingError> {
    let max = cycle_ns as i64 - 1;
    if (-max..=max).contains(&shift_ns) {
        return Ok(shift_ns as i32);
    }
    Err(SettingError::Sync0Shift { shift_ns, cycle_ns })
}

/// First SYNC0 pulse moved by `shift_ns` (checked by [`check_sync0_shift`]) from the cycle
/// boundary [`sync0_start`] gives; a negative shift fires before it, still after the margin
/// less one cycle.
pub fn shifted_sync0_start(system_time_ns: u64, cycle_ns: u32, margin_ns: u64, shift_ns: i32) -> u64 {
    sync0_start(system_time_ns, cycle_ns, margin_ns).wrapping_add_signed(shift_ns as i64)
}

/// Signed difference of a slave's clock to the reference (register 0x092C: bit 31 set when the
/// local copy is smaller, magnitude in bits 0..30), in ns; positive when the slave is ahead.
pub fn time_difference(raw: u32) -> i64 {
    let magnitude = (raw & 0x7FFF_FFFF) as i64;
    if raw & 0x8000_0000 != 0 {
        -magnitude
    } else {
        magnitude
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn epoch_is_2000() {
        assert_eq!(system_time(Duration::from_secs(EPOCH_OFFSET_S + 2)), 2_000_000_000);
    }

    #[test]
    fn delays_of_a_line_from_loop_times() {
        // Three slaves, 100 ns per link each way, 50 ns processing: the frame passes slave 0
        // at 0, slave 1 at 150, slave 2 at 300, and comes back through port 1 of slave 1 at
        // 300 + 50 + 100 = 450, of slave 0 at 600.
        let times = [
            PortReceiveTimes([1000, 1600, 0, 0]),
            PortReceiveTimes([5150, 5450, 0, 0]),
            PortReceiveTimes([9300, 7, 0, 0]), // last slave: port 1 is open, its time is noise
        ];
        let mut delays = [u32::MAX; 3];
        propagation_delays(&times, &mut delays);
        assert_eq!(delays, [0, 150, 300]);
    }

    #[test]
    fn delays_survive_the_32_bit_wrap() {
        let times = [PortReceiveTimes([u32::MAX - 99, 100, 0, 0]), PortReceiveTimes([5, 0, 0, 0])];
        let mut delays = [0; 2];
        propagation_delays(&times, &mut delays);
        assert_eq!(delays, [0, 100]);
    }

    #[test]
    fn offset_makes_the_slave_read_master_time() {
        let offset = system_time_offset(1_000_000, 300, 42);
        // At the latch the slave's local clock read 42 and the master's clock read 1_000_300.
        assert_eq!(42u64.wrapping_add(offset), 1_000_300);
        assert_eq!(system_time_offset(5, 0, 10).wrapping_add(10), 5);
    }

    #[test]
    fn sync0_starts_on_a_boundary_after_the_margin() {
        assert_eq!(sync0_start(1_000_500, 1_000, 10_000), 1_011_000);
        assert_eq!(sync0_start(0, 250_000, 0), 250_000);
    }

    #[test]
    fn a_shift_moves_sync0_within_the_cycle() {
        assert_eq!(shifted_sync0_start(1_000_500, 1_000, 10_000, 250), 1_011_250);
        assert_eq!(shifted_sync0_start(1_000_500, 1_000, 10_000, -250), 1_010_750);
        assert_eq!(check_sync0_shift(-999, 1_000).unwrap(), -999);
        for shift in [1_000, -1_000, i64::MAX] {
            let err = check_sync0_shift(shift, 1_000).unwrap_err().to_string();
            assert!(err.contains(&format!("SYNC0 shift {shift} ns")) && err.contains("-999 to 999 ns"), "{err}");
        }
    }

    #[test]
    fn time_difference_sign() {
        assert_eq!(time_difference(0x0000_0010), 16);
        assert_eq!(time_difference(0x8000_0010), -16);
    }

    proptest! {
        #[test]
        fn sync0_start_is_a_future_boundary(now in 0u64..u64::MAX / 4, cycle in 1u32.., margin in 0u64..1_000_000_000) {
            let start = sync0_start(now, cycle, margin);
            prop_assert_eq!(start % cycle as u64, 0);
            prop_assert!(start > now + margin);
            prop_assert!(start <= now + margin + cycle as u64);
        }
    }
}
