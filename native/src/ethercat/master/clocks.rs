//! Distributed-clock set-up on the bus (ETG.1020 §9): latch the receive times, set every
//! clock's propagation delay and offset so that all read the master's time, let the clocks
//! settle with a burst of drift-compensation frames, and start SYNC0 at the cycle time on a
//! common cycle boundary, moved by a configurable shift ([`Master::set_up_dc`]); or switch
//! SYNC0 off on every slave ([`Master::stop_dc`]). Registers only: what a slave's application
//! is told of the clock (an AKD's PLL and cycle time) is its profile's, written around these
//! steps ([`crate::drive::akd::AkdLine`]). The arithmetic is in [`crate::ethercat::dc`]; the
//! per-cycle drift datagram and the system-time difference reads are sent by
//! [`exchange`](Master::exchange).

use std::time::{SystemTime, UNIX_EPOCH};

use crate::error::{Result, Unavailable};
use crate::ethercat::dc::{self, PortReceiveTimes};
use crate::ethercat::frame::{self, Command};
use crate::ethercat::master::Master;
use crate::ethercat::registers;

/// Drift-compensation frames sent before SYNC0 starts, so the clocks have converged.
const STATIC_DRIFT_FRAMES: usize = 1000;
/// Time from "now" to the first SYNC0 pulse: enough for every slave to be armed.
const SYNC0_MARGIN_NS: u64 = 100_000_000;
/// DC activation: cyclic unit and SYNC0 on.
const ACTIVATE_SYNC0: u8 = 0x03;

/// One slave with a distributed clock, as the set-up left it and the cycle reads it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DcSlave {
    /// Position on the bus.
    pub position: u16,
    /// Station address.
    pub station: u16,
    /// Its propagation delay from the reference (register 0x0928), ns, as set up.
    pub delay_ns: u32,
    /// The last system-time difference read (register 0x092C, ns, positive when the slave's
    /// copy is behind), `None` before the first read.
    pub time_difference_ns: Option<i64>,
}

/// The bus's distributed-clock set-up.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Clock {
    /// Station address of the reference clock (the first slave with DC).
    pub reference_station: u16,
    /// Position of the reference clock on the bus.
    pub reference_position: u16,
    /// Working counter of the drift datagram: one per slave with DC.
    pub expected_wkc: u16,
    /// SYNC0 cycle time in ns.
    pub cycle_ns: u32,
    /// How far SYNC0 is moved from the cycle boundary, ns.
    pub shift_ns: i32,
    /// The first SYNC0 pulse, in system time (ns since 2000).
    pub sync0_start: u64,
    /// The reference clock's system time read in the last cycle.
    pub system_time: u64,
    /// Every slave with DC, in bus order.
    pub slaves: Vec<DcSlave>,
    /// The slave whose system-time difference the next cycle reads (one per cycle, in turn).
    pub(super) next_difference: usize,
    /// System-time difference reads the cyclic frame carried, and those not answered.
    pub difference_reads: u64,
    /// Of [`difference_reads`](Self::difference_reads), those the slave did not answer.
    pub difference_misses: u64,
}

/// The master's clock as EtherCAT system time.
fn master_time() -> u64 {
    dc::system_time(SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default())
}

impl Master {
    /// Sets up distributed clocks on every slave that has one and starts SYNC0 with
    /// `cycle_ns`, every pulse `shift_ns` after the cycle boundary (negative: before; less
    /// than a cycle either way). Call in PreOp, before SafeOp.
    pub fn set_up_dc(&mut self, cycle_ns: u32, shift_ns: i64) -> Result<()> {
        let shift_ns = dc::check_sync0_shift(shift_ns, cycle_ns)?;
        let dc_positions: Vec<u16> = self.slaves.iter().filter(|s| s.has_dc()).map(|s| s.position).collect();
        let dc_slaves: Vec<u16> = dc_positions.iter().map(|&p| self.slaves[p as usize].station_address).collect();
        let (Some(&reference_station), Some(&reference_position)) = (dc_slaves.first(), dc_positions.first()) else {
            return Err(Unavailable::NoDistributedClock.into());
        };
        self.clock = None;
        // Latch every port's receive time with one frame, noting when the master sent it.
        let sent_at = master_time();
        self.broadcast_write(registers::DC_RECEIVE_TIME_PORT0, &[0; 4])?;
        let mut times = Vec::with_capacity(dc_slaves.len());
        let mut local = Vec::with_capacity(dc_slaves.len());
        for &station in &dc_slaves {
            let mut ports = [0u8; 16];
            self.read_registers(station, registers::DC_RECEIVE_TIME_PORT0, &mut ports)?;
            times.push(PortReceiveTimes::decode(&ports));
            let mut ecat = [0u8; 8];
            self.read_registers(station, registers::DC_RECEIVE_TIME_ECAT, &mut ecat)?;
            local.push(u64::from_le_bytes(ecat));
        }
        let mut delays = vec![0u32; dc_slaves.len()];
        dc::propagation_delays(&times, &mut delays);
        for (i, &station) in dc_slaves.iter().enumerate() {
            self.set_clock(station, dc::system_time_offset(sent_at, delays[i], local[i]), delays[i])?;
        }
        for _ in 0..STATIC_DRIFT_FRAMES {
            self.datagram(Command::Frmw, reference_station, registers::DC_SYSTEM_TIME, &mut [0u8; 8])?;
        }
        let now = self.system_time_of(reference_station)?;
        let start = dc::shifted_sync0_start(now, cycle_ns, SYNC0_MARGIN_NS, shift_ns);
        for &station in &dc_slaves {
            self.write_registers(station, registers::DC_ACTIVATION, &[0])?;
            self.start_sync0(station, cycle_ns, start)?;
        }
        let slaves = dc_positions
            .iter()
            .zip(&dc_slaves)
            .zip(&delays)
            .map(|((&position, &station), &delay_ns)| DcSlave { position, station, delay_ns, time_difference_ns: None })
            .collect();
        self.clock = Some(Clock {
            reference_station,
            reference_position,
            expected_wkc: frame::expected_wkc(Command::Frmw, 1, dc_slaves.len() as u16 - 1),
            cycle_ns,
            shift_ns,
            sync0_start: start,
            system_time: now,
            slaves,
            next_difference: 0,
            difference_reads: 0,
            difference_misses: 0,
        });
        Ok(())
    }

    /// Runs the bus without distributed clocks: SYNC0 off on every slave with DC. Call in
    /// PreOp, before SafeOp.
    pub fn stop_dc(&mut self) -> Result<()> {
        self.clock = None;
        let stations: Vec<u16> = self.slaves.iter().filter(|s| s.has_dc()).map(|s| s.station_address).collect();
        for station in stations {
            self.write_registers(station, registers::DC_ACTIVATION, &[0])?;
        }
        Ok(())
    }

    /// Sets the clock of the slave at `position` (at `station`), if the set-up gave it SYNC0, to
    /// system time again after it lost it: its offset to the reference's time, its propagation
    /// delay as measured at the set-up, and SYNC0 as the set-up started it, on the line's common
    /// cycle boundary.
    pub(super) fn restart_sync0(&mut self, position: u16, station: u16) -> Result<()> {
        let Some(clock) = &self.clock else { return Ok(()) };
        let Some(delay_ns) = clock.slaves.iter().find(|s| s.position == position).map(|s| s.delay_ns) else {
            return Ok(());
        };
        let (cycle_ns, shift_ns, reference_station) = (clock.cycle_ns, clock.shift_ns, clock.reference_station);
        let local = self.system_time_of(station)?;
        let reference = self.system_time_of(reference_station)?;
        self.set_clock(station, reference.wrapping_sub(local).wrapping_add(delay_ns as u64), delay_ns)?;
        let start = dc::shifted_sync0_start(reference, cycle_ns, SYNC0_MARGIN_NS, shift_ns);
        self.start_sync0(station, cycle_ns, start)
    }

    /// The system time of the slave at `station` (register 0x0910).
    fn system_time_of(&mut self, station: u16) -> Result<u64> {
        let mut time = [0u8; 8];
        self.read_registers(station, registers::DC_SYSTEM_TIME, &mut time)?;
        Ok(u64::from_le_bytes(time))
    }

    /// Sets the offset of the slave at `station` to system time and its propagation delay.
    fn set_clock(&mut self, station: u16, offset: u64, delay_ns: u32) -> Result<()> {
        self.write_registers(station, registers::DC_SYSTEM_TIME_OFFSET, &offset.to_le_bytes())?;
        self.write_registers(station, registers::DC_SYSTEM_TIME_DELAY, &delay_ns.to_le_bytes())
    }

    /// Starts SYNC0 on the slave at `station`, every `cycle_ns` from `start` (system time).
    fn start_sync0(&mut self, station: u16, cycle_ns: u32, start: u64) -> Result<()> {
        self.write_registers(station, registers::DC_SYNC0_CYCLE_TIME, &cycle_ns.to_le_bytes())?;
        self.write_registers(station, registers::DC_SYNC0_START_TIME, &start.to_le_bytes())?;
        self.write_registers(station, registers::DC_ACTIVATION, &[ACTIVATE_SYNC0])
    }

    /// The distributed-clock set-up, if any.
    pub fn clock(&self) -> Option<&Clock> {
        self.clock.as_ref()
    }
}
