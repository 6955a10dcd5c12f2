//! Bringing one slave back to Op after it lost its configuration — a drive power-cycled (back
//! in Init, its station address gone), one that fell to SafeOp or Init with an error, a cable
//! that came back — while the others go on cycling: the steps of the start, for that slave
//! alone. It gets its station address again, is reset to Init, gets its mailbox, its
//! process data, its mode of operation and its clock (SYNC0 on the line's common
//! boundary, or the SM2 event) in PreOp, its sync managers and FMMUs at the same logical
//! addresses as before, and is taken through SafeOp to Op. Its DS402 state is left alone: the
//! power stage stays off until it is enabled again.
//!
//! It runs on a restoring master made from the cycling one ([`Master::for_restore`]), whose
//! frames go out through the cycle thread between its cyclic exchanges; the restoring master
//! never sends process data of its own, which would overwrite every other slave's outputs.

use crate::error::{Error, Result};
use crate::ethercat::al::AlState;
use crate::ethercat::dc;
use crate::ethercat::frame::Command;
use crate::ethercat::link::Link;
use crate::ethercat::master::clocks::{ACTIVATE_SYNC0, SYNC0_MARGIN_NS};
use crate::ethercat::master::scan::{FMMUS_CLEARED, SMS_CLEARED};
use crate::ethercat::master::Master;
use crate::ethercat::registers::{self, FMMU0, SM0};

/// How long each AL step of a restore may take (the AKD's firmware takes ~5 ms to PreOp).
const STEP_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(5);

/// How the slave's clock is set again.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SlaveSync {
    /// No DC: SYNC0 off, FBUS.PARAM02 = 0, the drive follows the SM2 event.
    Sm2 {
        /// The cycle time (0x60C2), ns.
        cycle_ns: u32,
    },
    /// DC: its clock set to the reference's time, SYNC0 started on the line's common cycle
    /// boundary, FBUS.PARAM02 = 1.
    Dc {
        /// SYNC0's cycle, ns.
        cycle_ns: u32,
        /// SYNC0's shift from the boundary, ns.
        shift_ns: i32,
        /// The reference clock's station address.
        reference_station: u16,
        /// The slave's propagation delay as measured at the start (0x0928), ns.
        delay_ns: u32,
    },
    /// A slave without a clock to set.
    None,
}

/// What a restore gives the slave besides what the scan and its process data hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Restore {
    /// The mode of operation to write to 0x6060 (a drive that lost power forgot it).
    pub mode: Option<i8>,
    /// Its clock.
    pub sync: SlaveSync,
}

impl Master {
    /// A master of the same slaves (their addresses, SII, mailboxes, process data) on `link`,
    /// without a process image or clock of its own: for [`restore_slave`](Self::restore_slave)
    /// while this one cycles.
    pub fn for_restore(&self, link: Box<dyn Link>) -> Master {
        let mut restoring = Master::new(link, self.timeout);
        restoring.mailbox_timeout = self.mailbox_timeout;
        restoring.slaves = self.slaves.clone();
        restoring
    }

    /// The clock a restore gives the slave at `position`, as this master's set-up did.
    pub fn restore_sync(&self, position: u16, cycle_ns: u32) -> Result<SlaveSync> {
        let slave = self.slave(position)?;
        Ok(match &self.clock {
            Some(clock) => match clock.slaves.iter().find(|s| s.position == position) {
                Some(s) => SlaveSync::Dc {
                    cycle_ns: clock.cycle_ns,
                    shift_ns: clock.shift_ns,
                    reference_station: clock.reference_station,
                    delay_ns: s.delay_ns,
                },
                None => SlaveSync::None,
            },
            None if slave.mailbox.as_ref().is_some_and(|m| m.has_coe()) || slave.has_dc() => {
                SlaveSync::Sm2 { cycle_ns }
            }
            None => SlaveSync::None,
        })
    }

    /// Brings the slave at `position` back to Op as the module says. Fails (and may be tried
    /// again) while the slave does not answer; refuses a different device at its position.
    pub fn restore_slave(&mut self, position: u16, restore: &Restore) -> Result<()> {
        let adp = 0u16.wrapping_sub(position);
        let station = self.station(position)?;
        let mut address = [0u8; 2];
        let wkc = self.datagram(Command::Aprd, adp, registers::STATION_ADDRESS, &mut address)?;
        self.expect_wkc(|| format!("APRD of position {position}'s station address (is it there?)"), 1, wkc)?;
        if u16::from_le_bytes(address) == station && self.in_op_without_error(position)? {
            return Ok(());
        }
        let wkc = self.datagram(Command::Apwr, adp, registers::STATION_ADDRESS, &mut station.to_le_bytes())?;
        self.expect_wkc(|| format!("APWR of the station address to position {position}"), 1, wkc)?;
        self.check_identity(position, station)?;
        self.reset_to_init(position, station, STEP_TIMEOUT)?;
        self.write_registers(station, FMMU0, &[0; FMMUS_CLEARED * registers::FMMU_LEN as usize])?;
        self.write_registers(station, SM0, &[0; SMS_CLEARED * registers::SM_LEN as usize])?;
        if self.slave(position)?.has_dc() {
            self.write_registers(station, registers::DC_ACTIVATION, &[0])?;
        }
        self.request_state_of(AlState::PreOp, Some(position), STEP_TIMEOUT)?;
        if let Some(process_data) = self.slave(position)?.process_data.clone() {
            self.configure_process_data(position, process_data)?;
        }
        if let Some(mode) = restore.mode {
            self.sdo_write(position, 0x6060, 0, &[mode as u8])?;
        }
        self.restore_clock(position, station, restore.sync)?;
        self.request_state_of(AlState::SafeOp, Some(position), STEP_TIMEOUT)?;
        // The cycling master's frames carry the outputs Op waits for; this one sends none.
        self.process = None;
        self.request_state_of(AlState::Op, Some(position), STEP_TIMEOUT)
    }

    /// Whether the slave at `position` (which kept its station address) is in Op without an
    /// error: it came back by itself (the line was cut, not the drive's power) and needs no
    /// restore.
    fn in_op_without_error(&mut self, position: u16) -> Result<bool> {
        let status = self.al_status(position)?;
        Ok(status.state() == Some(AlState::Op) && !status.error())
    }

    /// Refuses a device at `position` that is not the one the scan found there: another drive
    /// swapped in is not configured as if it were the old one.
    fn check_identity(&mut self, position: u16, station: u16) -> Result<()> {
        let expected = self.slave(position)?.sii.identity();
        let found = crate::ethercat::sii::Identity::from_words(&self.read_sii_words(station, 0x0008, 8)?);
        if found == expected {
            return Ok(());
        }
        Err(Error::Replaced { slave: position, expected, found })
    }

    fn restore_clock(&mut self, position: u16, station: u16, sync: SlaveSync) -> Result<()> {
        let param02 = match sync {
            SlaveSync::None => return Ok(()),
            SlaveSync::Sm2 { cycle_ns } => (cycle_ns, 0),
            SlaveSync::Dc { cycle_ns, shift_ns, reference_station, delay_ns } => {
                let read_time = |m: &mut Master, s: u16| -> Result<u64> {
                    let mut b = [0u8; 8];
                    m.read_registers(s, registers::DC_SYSTEM_TIME, &mut b)?;
                    Ok(u64::from_le_bytes(b))
                };
                let local = read_time(self, station)?;
                let reference = read_time(self, reference_station)?;
                let offset = reference.wrapping_sub(local).wrapping_add(delay_ns as u64);
                self.write_registers(station, registers::DC_SYSTEM_TIME_OFFSET, &offset.to_le_bytes())?;
                self.write_registers(station, registers::DC_SYSTEM_TIME_DELAY, &delay_ns.to_le_bytes())?;
                let start = dc::shifted_sync0_start(reference, cycle_ns, SYNC0_MARGIN_NS, shift_ns);
                self.write_registers(station, registers::DC_SYNC0_CYCLE_TIME, &cycle_ns.to_le_bytes())?;
                self.write_registers(station, registers::DC_SYNC0_START_TIME, &start.to_le_bytes())?;
                self.write_registers(station, registers::DC_ACTIVATION, &[ACTIVATE_SYNC0])?;
                (cycle_ns, dc::FBUS_PARAM02_PLL)
            }
        };
        self.set_slave_sync(position, param02.0, param02.1).map(|_| ())
    }
}
