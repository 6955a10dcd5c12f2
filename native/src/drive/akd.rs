//! What akd_ros does to an AKD through the master, the master itself knowing no AKD. On one
//! drive ([`AkdSlave`], on the master's [`SlaveRef`]): give it a mapping checked against the
//! AKD's rules, read its position scaling — the DS402 scaling objects 0x608F, 0x6091 and
//! 0x6092, and FBUS.PARAM05 where the drive's SDO information confirms the object
//! ([`scaling::FBUS_PARAM05`] explains why) —, tell it how to follow the line's clock
//! (FBUS.PARAM02 and its cycle time, [`crate::drive::sync`]), and write its mode and clock again
//! after a restore took it back to PreOp. On the line ([`AkdLine`], on the [`Master`]): the
//! master's clock set-up with every drive's side of it. What the values mean is
//! [`scaling`]'s, [`sync`]'s and [`crate::drive::pdo`]'s; this module only carries them.

use crate::drive::identity;
use crate::drive::pdo::Mapping;
use crate::drive::scaling::{self, PositionScaling, SCALING_ENTRIES};
use crate::drive::sync::{self, FBUS_PARAM02, FBUS_PARAM02_NAME, FBUS_PARAM02_PLL};
use crate::error::{Error, Result};
use crate::ethercat::coe::SdoAbortCode;
use crate::ethercat::master::sdo_info::parameter_confirmed;
use crate::ethercat::master::{Master, SlaveRef};

/// How a drive follows the line's clock: FBUS.PARAM02 (its PLL on SYNC0, or the SM2 event) and
/// its cycle time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DriveSync {
    /// The cycle time, ns, written as the interpolation time period 0x60C2.
    pub cycle_ns: u32,
    /// FBUS.PARAM02: [`FBUS_PARAM02_PLL`] with SYNC0, 0 on the SM2 event.
    pub fbus_param02: u32,
}

/// A slave of the master that is an AKD.
pub trait AkdSlave {
    /// Gives the drive (in PreOp) its outputs mapping `rx` and inputs mapping `tx`; both are
    /// checked against the AKD's rules first ([`crate::drive::pdo::check_flexible`]), so a refused mapping
    /// writes nothing.
    fn configure_pdo(&mut self, rx: Mapping, tx: Mapping) -> Result<()>;

    /// The drive's position scaling (in PreOp or above); `None` for a drive without the DS402
    /// scaling objects (an abort "no such object"), as firmware before them.
    fn position_scaling(&mut self) -> Result<Option<PositionScaling>>;

    /// Sets the drive's cycle time (interpolation time period 0x60C2), e.g. for a drive
    /// synchronised on the SM2 event (in PreOp).
    fn set_cycle_time(&mut self, cycle_ns: u32) -> Result<()>;

    /// Tells the drive (in PreOp) how to follow the line's clock: FBUS.PARAM02 where its SDO
    /// information confirms the object ([`sync::FBUS_PARAM02`] explains why), and its cycle
    /// time. Gives FBUS.PARAM02 as it is now in the drive, `None` when unknown: a slave that is
    /// no AKD ([`identity::is_akd`]; nothing is written to it, a terminal with CoE among them),
    /// or a drive whose SDO information does not confirm the
    /// object, whose PLL must then be switched on the drive (FBUS.PARAM02 = 1 in WorkBench),
    /// or it does not follow SYNC0.
    fn set_drive_sync(&mut self, sync: DriveSync) -> Result<Option<u32>>;

    /// Sets the drive's mode of operation (0x6060, `mode` its code) by SDO: the mode it starts
    /// the cycle in, or takes again after a restore.
    fn set_mode(&mut self, mode: i8) -> Result<()>;

    /// After [`Master::restore_to_preop`] brought the drive back to PreOp: its mode of
    /// operation (0x6060; a drive that lost power forgot it) and its clock's side, as the start
    /// gave them; `None` writes nothing of that.
    fn restore(&mut self, mode: Option<i8>, sync: Option<DriveSync>) -> Result<()>;
}

impl AkdSlave for SlaveRef<'_> {
    fn configure_pdo(&mut self, rx: Mapping, tx: Mapping) -> Result<()> {
        self.configure_process_data(Mapping::process_data(&rx, &tx)?)
    }

    fn position_scaling(&mut self) -> Result<Option<PositionScaling>> {
        let mut entries = [0u32; SCALING_ENTRIES.len()];
        for (value, (index, subindex)) in entries.iter_mut().zip(SCALING_ENTRIES) {
            match self.sdo_read(index, subindex) {
                Ok(bytes) => *value = u32_of(&bytes),
                Err(Error::SdoAbort { code, .. }) if code == SdoAbortCode::NO_SUCH_OBJECT.0 => return Ok(None),
                Err(e) => return Err(e),
            }
        }
        let description = self.sdo_object_description(scaling::FBUS_PARAM05);
        let param05 = match parameter_confirmed(description, scaling::FBUS_PARAM05_NAME)? {
            true => Some(u32_of(&self.sdo_read(scaling::FBUS_PARAM05, 0)?)),
            false => None,
        };
        Ok(Some(PositionScaling::from_entries(entries, param05)))
    }

    fn set_cycle_time(&mut self, cycle_ns: u32) -> Result<()> {
        let (units, exponent) = sync::interpolation_time_period(cycle_ns)?;
        self.sdo_write(sync::INTERPOLATION_TIME_PERIOD, 1, &[units])?;
        self.sdo_write(sync::INTERPOLATION_TIME_PERIOD, 2, &[exponent as u8])
    }

    fn set_drive_sync(&mut self, sync: DriveSync) -> Result<Option<u32>> {
        if !identity::is_akd(&self.info().sii.identity()) {
            return Ok(None);
        }
        let mut written = None;
        if parameter_confirmed(self.sdo_object_description(FBUS_PARAM02), FBUS_PARAM02_NAME)? {
            self.sdo_write(FBUS_PARAM02, 0, &sync.fbus_param02.to_le_bytes())?;
            written = Some(sync.fbus_param02);
        }
        self.set_cycle_time(sync.cycle_ns)?;
        Ok(written)
    }

    fn set_mode(&mut self, mode: i8) -> Result<()> {
        self.sdo_write(0x6060, 0, &[mode as u8])
    }

    fn restore(&mut self, mode: Option<i8>, sync: Option<DriveSync>) -> Result<()> {
        if let Some(mode) = mode {
            self.set_mode(mode)?;
        }
        if let Some(sync) = sync {
            self.set_drive_sync(sync)?;
        }
        Ok(())
    }
}

/// The line of AKDs: the master's clock set-up with every drive's side of it.
pub trait AkdLine {
    /// Sets up distributed clocks and starts SYNC0 at `cycle_ns`, moved by `shift_ns` (less
    /// than a cycle either way; [`Master::set_up_dc`]), then gives every AKD FBUS.PARAM02 = 1
    /// and the cycle time ([`AkdSlave::set_drive_sync`]). Call in PreOp,
    /// before SafeOp. Gives FBUS.PARAM02 as it is now in each slave, by position.
    fn configure_dc(&mut self, cycle_ns: u32, shift_ns: i64) -> Result<Vec<Option<u32>>>;

    /// Runs the drives without distributed clocks: SYNC0 off ([`Master::stop_dc`]), every
    /// AKD given FBUS.PARAM02 = 0 and the cycle time `cycle_ns`, so that each
    /// follows the SM2 event of the cyclic frame (AKD manual §5.11.2). Call in PreOp, before
    /// SafeOp. Gives FBUS.PARAM02 as it is now in each slave, by position.
    fn configure_sm2_sync(&mut self, cycle_ns: u32) -> Result<Vec<Option<u32>>>;

    /// How the drive at `position` follows the clock as the set-up left it, which a restore
    /// gives it again: SYNC0's cycle with the PLL on where it runs SYNC0, `cycle_ns` on the SM2
    /// event without distributed clocks, `None` for a slave without a clock on a line with them.
    fn drive_sync(&self, position: u16, cycle_ns: u32) -> Option<DriveSync>;
}

impl AkdLine for Master {
    fn configure_dc(&mut self, cycle_ns: u32, shift_ns: i64) -> Result<Vec<Option<u32>>> {
        sync::interpolation_time_period(cycle_ns)?;
        self.set_up_dc(cycle_ns, shift_ns)?;
        set_every_drive_sync(self, DriveSync { cycle_ns, fbus_param02: FBUS_PARAM02_PLL })
    }

    fn configure_sm2_sync(&mut self, cycle_ns: u32) -> Result<Vec<Option<u32>>> {
        sync::interpolation_time_period(cycle_ns)?;
        self.stop_dc()?;
        set_every_drive_sync(self, DriveSync { cycle_ns, fbus_param02: 0 })
    }

    fn drive_sync(&self, position: u16, cycle_ns: u32) -> Option<DriveSync> {
        let Some(clock) = self.clock() else { return Some(DriveSync { cycle_ns, fbus_param02: 0 }) };
        let with_sync0 = clock.slaves.iter().any(|s| s.position == position);
        with_sync0.then_some(DriveSync { cycle_ns: clock.cycle_ns, fbus_param02: FBUS_PARAM02_PLL })
    }
}

/// [`AkdSlave::set_drive_sync`] on every slave of `master`, by position.
fn set_every_drive_sync(master: &mut Master, sync: DriveSync) -> Result<Vec<Option<u32>>> {
    (0..master.slaves().len() as u16).map(|position| master.slave_mut(position)?.set_drive_sync(sync)).collect()
}

/// An UNSIGNED32 as the drive sent it (shorter values padded, as an expedited upload may be).
fn u32_of(bytes: &[u8]) -> u32 {
    let mut le = [0u8; 4];
    let n = bytes.len().min(4);
    le[..n].copy_from_slice(&bytes[..n]);
    u32::from_le_bytes(le)
}
