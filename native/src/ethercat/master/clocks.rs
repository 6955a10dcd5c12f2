//! Distributed-clock set-up on the bus (ETG.1020 §9): latch the receive times, set every
//! clock's propagation delay and offset so that all read the master's time, let the clocks
//! settle with a burst of drift-compensation frames, and start SYNC0 at the cycle time on a
//! common cycle boundary, moved by a configurable shift. Every AKD gets FBUS.PARAM02 = 1, so
//! its PLL follows SYNC0 (AKD manual §5.11), once its SDO information confirms the object
//! (see [`dc::FBUS_PARAM02`]), and its cycle time 0x60C2. Without DC
//! ([`configure_sm2_sync`](Master::configure_sm2_sync)) SYNC0 stays off, FBUS.PARAM02 = 0,
//! and the drives follow the SM2 event (§5.11.2). The arithmetic is in [`crate::ethercat::dc`]; the
//! per-cycle drift datagram and the system-time difference reads are sent by
//! [`exchange`](Master::exchange).

use std::time::{SystemTime, UNIX_EPOCH};

use crate::error::{Result, Unavailable};
use crate::ethercat::dc::{self, PortReceiveTimes};
use crate::ethercat::frame::{self, Command};
use crate::ethercat::master::sdo_info::{parameter_confirmed, ObjectInfo};
use crate::ethercat::master::Master;
use crate::ethercat::registers;

/// Drift-compensation frames sent before SYNC0 starts, so the clocks have converged.
const STATIC_DRIFT_FRAMES: usize = 1000;
/// Time from "now" to the first SYNC0 pulse: enough for every slave to be armed.
pub(crate) const SYNC0_MARGIN_NS: u64 = 100_000_000;
/// DC activation: cyclic unit and SYNC0 on.
pub(crate) const ACTIVATE_SYNC0: u8 = 0x03;

/// One slave with a distributed clock, as the set-up left it and the cycle reads it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DcSlave {
    /// Position on the bus.
    pub position: u16,
    /// Station address.
    pub station: u16,
    /// FBUS.PARAM02 as written (1), or `None`, unknown: a slave without CoE, or a drive whose
    /// SDO information does not confirm that object [`dc::FBUS_PARAM02`] is FBUS.PARAM02 (no
    /// such object, or named otherwise), so nothing was written. Its PLL must then be switched
    /// on the drive (FBUS.PARAM02 = 1 in WorkBench), or it does not follow SYNC0.
    pub fbus_param02: Option<u32>,
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

/// Whether a drive's answer to the object description of [`dc::FBUS_PARAM02`] confirms that
/// the object is FBUS.PARAM02, so that it may be written ([`parameter_confirmed`]).
pub fn fbus_param02_confirmed(description: Result<ObjectInfo>) -> Result<bool> {
    parameter_confirmed(description, dc::FBUS_PARAM02_NAME)
}

/// The master's clock as EtherCAT system time.
fn master_time() -> u64 {
    dc::system_time(SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default())
}

impl Master {
    /// Sets up distributed clocks on every slave that has one and starts SYNC0 with
    /// `cycle_ns`, every pulse `shift_ns` after the cycle boundary (negative: before; less
    /// than a cycle either way); every AKD gets FBUS.PARAM02 = 1 and its cycle time (0x60C2)
    /// the same. Call in PreOp, before SafeOp.
    pub fn configure_dc(&mut self, cycle_ns: u32, shift_ns: i64) -> Result<()> {
        dc::interpolation_time_period(cycle_ns)?;
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
            let offset = dc::system_time_offset(sent_at, delays[i], local[i]);
            self.write_registers(station, registers::DC_SYSTEM_TIME_OFFSET, &offset.to_le_bytes())?;
            self.write_registers(station, registers::DC_SYSTEM_TIME_DELAY, &delays[i].to_le_bytes())?;
        }
        for _ in 0..STATIC_DRIFT_FRAMES {
            self.datagram(Command::Frmw, reference_station, registers::DC_SYSTEM_TIME, &mut [0u8; 8])?;
        }
        let mut now = [0u8; 8];
        self.read_registers(reference_station, registers::DC_SYSTEM_TIME, &mut now)?;
        let start = dc::shifted_sync0_start(u64::from_le_bytes(now), cycle_ns, SYNC0_MARGIN_NS, shift_ns);
        for &station in &dc_slaves {
            self.write_registers(station, registers::DC_ACTIVATION, &[0])?;
            self.write_registers(station, registers::DC_SYNC0_CYCLE_TIME, &cycle_ns.to_le_bytes())?;
            self.write_registers(station, registers::DC_SYNC0_START_TIME, &start.to_le_bytes())?;
            self.write_registers(station, registers::DC_ACTIVATION, &[ACTIVATE_SYNC0])?;
        }
        let param02 = self.set_drive_sync(cycle_ns, dc::FBUS_PARAM02_PLL)?;
        let slaves = dc_positions
            .iter()
            .zip(&dc_slaves)
            .map(|(&position, &station)| DcSlave {
                position,
                station,
                fbus_param02: param02[position as usize],
                delay_ns: delays[dc_positions.iter().position(|&p| p == position).unwrap_or(0)],
                time_difference_ns: None,
            })
            .collect();
        self.clock = Some(Clock {
            reference_station,
            reference_position,
            expected_wkc: frame::expected_wkc(Command::Frmw, 1, dc_slaves.len() as u16 - 1),
            cycle_ns,
            shift_ns,
            sync0_start: start,
            system_time: u64::from_le_bytes(now),
            slaves,
            next_difference: 0,
            difference_reads: 0,
            difference_misses: 0,
        });
        Ok(())
    }

    /// Runs the drives without distributed clocks: SYNC0 off on every slave with DC, every
    /// AKD's FBUS.PARAM02 = 0 and its cycle time (0x60C2) `cycle_ns`, so that each follows the
    /// SM2 event of the cyclic frame (AKD manual §5.11.2). Call in PreOp, before SafeOp.
    pub fn configure_sm2_sync(&mut self, cycle_ns: u32) -> Result<()> {
        dc::interpolation_time_period(cycle_ns)?;
        self.clock = None;
        let stations: Vec<u16> = self.slaves.iter().filter(|s| s.has_dc()).map(|s| s.station_address).collect();
        for station in stations {
            self.write_registers(station, registers::DC_ACTIVATION, &[0])?;
        }
        self.set_drive_sync(cycle_ns, 0)?;
        Ok(())
    }

    /// Writes FBUS.PARAM02 = `param02` to every slave with CoE whose SDO information confirms
    /// the object ([`dc::FBUS_PARAM02`] explains why), and the cycle time to every slave with
    /// CoE; per slave, the FBUS.PARAM02 now in the drive (`None`: unknown, nothing written).
    fn set_drive_sync(&mut self, cycle_ns: u32, param02: u32) -> Result<Vec<Option<u32>>> {
        (0..self.slaves.len() as u16).map(|position| self.set_slave_sync(position, cycle_ns, param02)).collect()
    }

    /// [`set_drive_sync`](Self::set_drive_sync) for the slave at `position` alone.
    pub(crate) fn set_slave_sync(&mut self, position: u16, cycle_ns: u32, param02: u32) -> Result<Option<u32>> {
        if !self.slave(position)?.mailbox.as_ref().is_some_and(|m| m.has_coe()) {
            return Ok(None);
        }
        let mut written = None;
        if fbus_param02_confirmed(self.sdo_object_description(position, dc::FBUS_PARAM02))? {
            self.sdo_write(position, dc::FBUS_PARAM02, 0, &param02.to_le_bytes())?;
            written = Some(param02);
        }
        self.set_cycle_time(position, cycle_ns)?;
        Ok(written)
    }

    /// Sets the drive's cycle time (interpolation time period 0x60C2) of the slave at
    /// `position`, e.g. 2 ms as (2, -3).
    pub(super) fn set_cycle_time(&mut self, position: u16, cycle_ns: u32) -> Result<()> {
        let (units, exponent) = crate::ethercat::dc::interpolation_time_period(cycle_ns)?;
        self.sdo_write(position, 0x60C2, 1, &[units])?;
        self.sdo_write(position, 0x60C2, 2, &[exponent as u8])
    }

    /// The distributed-clock set-up, if any.
    pub fn clock(&self) -> Option<&Clock> {
        self.clock.as_ref()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Error;
    use crate::error::MailboxError;
    use crate::ethercat::coe::{ObjectCode, SdoAbortCode};

    fn described(name: &str) -> Result<ObjectInfo> {
        Ok(ObjectInfo {
            index: dc::FBUS_PARAM02,
            data_type: 0x0007,
            max_subindex: 0,
            object_code: ObjectCode::Var,
            name: name.into(),
        })
    }

    #[test]
    fn fbus_param02_is_written_only_where_the_drive_names_the_object_so() {
        assert!(fbus_param02_confirmed(described("FBUS.PARAM02")).unwrap());
        assert!(!fbus_param02_confirmed(described("Position offset")).unwrap());
        let no_object = Error::sdo_abort(dc::FBUS_PARAM02, 0, SdoAbortCode::NO_SUCH_OBJECT);
        assert!(!fbus_param02_confirmed(Err(no_object)).unwrap());
        let mailbox_failed = Err(MailboxError::InfoErrorWithoutCode.into());
        assert!(fbus_param02_confirmed(mailbox_failed).is_err(), "not a drive's answer: the set-up fails");
    }
}
