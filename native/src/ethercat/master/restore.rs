//! Bringing one slave back to Op after it lost its configuration — a drive power-cycled (back
//! in Init, its station address gone), one that fell to SafeOp or Init with an error, a cable
//! that came back — while the others go on cycling: the steps of the start, for that slave
//! alone, in two halves with its profile's writes between them. [`Master::restore_to_preop`]
//! gives it its station address again, resets it to Init, gives it its mailbox, its process
//! data and its clock (SYNC0 on the line's common boundary, or off) in PreOp;
//! [`Master::restore_to_op`] gives it its sync managers and FMMUs at the same logical addresses
//! as before and takes it through SafeOp to Op. A slave no profile writes to takes the two
//! halves one after the other. Its application's state (a drive's DS402 state) is left alone:
//! a drive's power stage stays off until it is enabled again.
//!
//! It runs on a restoring master made from the cycling one ([`Master::for_restore`]), whose
//! frames go out through the cycle thread between its cyclic exchanges; the restoring master
//! never sends process data of its own, which would overwrite every other slave's outputs.

use crate::error::{Error, Result};
use crate::ethercat::al::AlState;
use crate::ethercat::frame::Command;
use crate::ethercat::link::Link;
use crate::ethercat::master::scan::{FMMUS_CLEARED, SMS_CLEARED};
use crate::ethercat::master::Master;
use crate::ethercat::registers::{self, FMMU0, SM0};

/// How long each AL step of a restore may take (the AKD's firmware takes ~5 ms to PreOp).
const STEP_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(5);

/// Where [`Master::restore_to_preop`] left the slave.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Restoring {
    /// It kept its station address and is in Op without an error: it came back by itself (the
    /// line was cut, not its power) and needs nothing more.
    InOp,
    /// In PreOp with its mailbox, process data and clock, for its profile's writes and then
    /// [`Master::restore_to_op`].
    InPreOp,
}

impl Master {
    /// A master of the same slaves (their addresses, SII, mailboxes, process data) and the
    /// same distributed clocks on `link`, without a process image of its own: for
    /// [`restore_to_preop`](Self::restore_to_preop) and [`restore_to_op`](Self::restore_to_op)
    /// while this one cycles.
    pub fn for_restore(&self, link: Box<dyn Link>) -> Master {
        let mut restoring = Master::new(link, self.timeout);
        restoring.mailbox_timeout = self.mailbox_timeout;
        restoring.slaves = self.slaves.clone();
        restoring.clock = self.clock.clone();
        restoring
    }

    /// The first half of a restore, as the module says: the slave at `position` back in PreOp
    /// with its mailbox, process data and SYNC0 as the set-up started it, or found in Op by
    /// itself. Fails (and may be tried again) while the slave does not answer; refuses a
    /// different device at its position.
    pub fn restore_to_preop(&mut self, position: u16) -> Result<Restoring> {
        let adp = 0u16.wrapping_sub(position);
        let station = self.station(position)?;
        let mut address = [0u8; 2];
        let wkc = self.datagram(Command::Aprd, adp, registers::STATION_ADDRESS, &mut address)?;
        self.expect_wkc(|| format!("APRD of position {position}'s station address (is it there?)"), 1, wkc)?;
        if u16::from_le_bytes(address) == station && self.in_op_without_error(position)? {
            return Ok(Restoring::InOp);
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
        self.restart_sync0(position, station)?;
        Ok(Restoring::InPreOp)
    }

    /// The second half of a restore: the slave at `position`, in PreOp, through SafeOp to Op.
    pub fn restore_to_op(&mut self, position: u16) -> Result<()> {
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
}
