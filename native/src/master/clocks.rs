//! Distributed-clock set-up on the bus (ETG.1020 §9): latch the receive times, set every
//! clock's propagation delay and offset so that all read the master's time, let the clocks
//! settle with a burst of drift-compensation frames, and start SYNC0 at the cycle time on a
//! common cycle boundary. The arithmetic is in [`crate::dc`]; the per-cycle drift datagram is
//! sent by [`exchange`](Master::exchange).

use std::time::{SystemTime, UNIX_EPOCH};

use crate::dc::{self, PortReceiveTimes};
use crate::error::{Result, Unavailable};
use crate::frame::{self, Command};
use crate::master::Master;
use crate::registers;

/// Drift-compensation frames sent before SYNC0 starts, so the clocks have converged.
const STATIC_DRIFT_FRAMES: usize = 1000;
/// Time from "now" to the first SYNC0 pulse: enough for every slave to be armed.
const SYNC0_MARGIN_NS: u64 = 100_000_000;
/// DC activation: cyclic unit and SYNC0 on.
const ACTIVATE_SYNC0: u8 = 0x03;

/// The bus's distributed-clock set-up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Clock {
    /// Station address of the reference clock (the first slave with DC).
    pub reference_station: u16,
    /// Working counter of the drift datagram: one per slave with DC.
    pub expected_wkc: u16,
    /// SYNC0 cycle time in ns.
    pub cycle_ns: u32,
    /// The reference clock's system time read in the last cycle.
    pub system_time: u64,
}

/// The master's clock as EtherCAT system time.
fn master_time() -> u64 {
    dc::system_time(SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default())
}

impl Master {
    /// Sets up distributed clocks on every slave that has one and starts SYNC0 with
    /// `cycle_ns`; the drives' cycle time (0x60C2) is set to the same. Call in PreOp, before
    /// SafeOp.
    pub fn configure_dc(&mut self, cycle_ns: u32) -> Result<()> {
        dc::interpolation_time_period(cycle_ns)?;
        let dc_slaves: Vec<u16> = self.slaves.iter().filter(|s| s.has_dc()).map(|s| s.station_address).collect();
        let Some(&reference_station) = dc_slaves.first() else {
            return Err(Unavailable::NoDistributedClock.into());
        };
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
            let offset = dc::system_time_offset(sent_at, delays[i], local[i]);
            self.write_registers(station, registers::DC_SYSTEM_TIME_OFFSET, &offset.to_le_bytes())?;
            self.write_registers(station, registers::DC_SYSTEM_TIME_DELAY, &delays[i].to_le_bytes())?;
        }
        for _ in 0..STATIC_DRIFT_FRAMES {
            self.datagram(Command::Frmw, reference_station, registers::DC_SYSTEM_TIME, &mut [0u8; 8])?;
        }
        let mut now = [0u8; 8];
        self.read_registers(reference_station, registers::DC_SYSTEM_TIME, &mut now)?;
        let start = dc::sync0_start(u64::from_le_bytes(now), cycle_ns, SYNC0_MARGIN_NS);
        for &station in &dc_slaves {
            self.write_registers(station, registers::DC_ACTIVATION, &[0])?;
            self.write_registers(station, registers::DC_SYNC0_CYCLE_TIME, &cycle_ns.to_le_bytes())?;
            self.write_registers(station, registers::DC_SYNC0_START_TIME, &start.to_le_bytes())?;
            self.write_registers(station, registers::DC_ACTIVATION, &[ACTIVATE_SYNC0])?;
        }
        for position in 0..self.slaves.len() as u16 {
            if self.slaves[position as usize].mailbox.as_ref().is_some_and(|m| m.has_coe()) {
                self.set_cycle_time(position, cycle_ns)?;
            }
        }
        self.clock = Some(Clock {
            reference_station,
            expected_wkc: frame::expected_wkc(Command::Frmw, 1, dc_slaves.len() as u16 - 1),
            cycle_ns,
            system_time: u64::from_le_bytes(now),
        });
        Ok(())
    }

    /// The distributed-clock set-up, if any.
    pub fn clock(&self) -> Option<&Clock> {
        self.clock.as_ref()
    }
}
