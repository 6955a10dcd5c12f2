//! Setting up a slave's process data from its description ([`ProcessData`]): over CoE where
//! the description says so — clear the assignment count, write each flexible PDO's entries with
//! its count 0 and the count last, assign the PDOs, write the assignment count (CiA 301's order,
//! which the AKD requires, AKD manual §5.6) — and, before SafeOp, sync managers 2 and 3 as the
//! slave's SII gives them and FMMU0/FMMU1 from the slave's place in the process image.

use crate::error::{Result, Unavailable};
use crate::ethercat::master::mailbox_client::sm_registers;
use crate::ethercat::master::Master;
use crate::ethercat::pdo::{Direction, PdoAssignment, ProcessData};
use crate::ethercat::registers::{self, fmmu_reg};

impl Master {
    /// Gives the slave at `position` (in PreOp) the process data `process_data`.
    pub(super) fn configure_process_data(&mut self, position: u16, process_data: ProcessData) -> Result<()> {
        self.write_assignment(position, Direction::Rx, &process_data.outputs)?;
        self.write_assignment(position, Direction::Tx, &process_data.inputs)?;
        self.slave_entry_mut(position)?.process_data = Some(process_data);
        // New process data change the process image; it is laid out again before SafeOp.
        self.process = None;
        Ok(())
    }

    fn write_assignment(&mut self, position: u16, direction: Direction, assignment: &PdoAssignment) -> Result<()> {
        if !assignment.over_coe {
            return Ok(());
        }
        let assign = direction.assignment_index();
        self.sdo_write(position, assign, 0, &[0])?;
        for pdo in assignment.pdos.iter().filter(|_| assignment.write_entries) {
            self.sdo_write(position, pdo.index, 0, &[0])?;
            for (sub, entry) in pdo.entries.iter().enumerate() {
                self.sdo_write(position, pdo.index, sub as u8 + 1, &entry.to_u32().to_le_bytes())?;
            }
            self.sdo_write(position, pdo.index, 0, &[pdo.entries.len() as u8])?;
        }
        for (sub, pdo) in assignment.pdos.iter().enumerate() {
            self.sdo_write(position, assign, sub as u8 + 1, &pdo.index.to_le_bytes())?;
        }
        self.sdo_write(position, assign, 0, &[assignment.pdos.len() as u8])
    }

    /// Writes SM2/SM3 and FMMU0/FMMU1 of the slave at `position` for outputs at logical
    /// address `out_logical` and inputs at `in_logical`.
    pub(crate) fn setup_process_syncmanagers(
        &mut self,
        position: u16,
        out_logical: u32,
        in_logical: u32,
    ) -> Result<()> {
        let slave = self.slave(position)?;
        let station = slave.station_address;
        let process_data = slave.process_data.as_ref().ok_or(Unavailable::NoMapping { slave: position })?;
        let sm = |direction: Direction| {
            let n = direction.sync_manager();
            let sm = slave.sii.sync_managers().get(n as usize);
            sm.map(|sm| (sm.start_address, sm.control)).ok_or(Unavailable::NoSyncManager { slave: position, n })
        };
        let ((out_start, out_control), (in_start, in_control)) = (sm(Direction::Rx)?, sm(Direction::Tx)?);
        let (out_len, in_len) = (process_data.bytes(Direction::Rx) as u16, process_data.bytes(Direction::Tx) as u16);
        let mut both = [0u8; 16];
        both[..8].copy_from_slice(&sm_registers(out_start, out_len, out_control, out_len > 0));
        both[8..].copy_from_slice(&sm_registers(in_start, in_len, in_control, in_len > 0));
        self.write_registers(station, registers::sm(2), &both)?;
        let mut fmmus = [0u8; 32];
        fmmus[..16].copy_from_slice(&fmmu_registers(out_logical, out_len, out_start, fmmu_reg::TYPE_WRITE));
        fmmus[16..].copy_from_slice(&fmmu_registers(in_logical, in_len, in_start, fmmu_reg::TYPE_READ));
        self.write_registers(station, registers::fmmu(0), &fmmus)
    }
}

/// The sixteen bytes of an FMMU mapping `len` whole bytes from `logical` to `physical`.
fn fmmu_registers(logical: u32, len: u16, physical: u16, kind: u8) -> [u8; 16] {
    let mut r = [0u8; 16];
    r[fmmu_reg::LOGICAL_START..fmmu_reg::LOGICAL_START + 4].copy_from_slice(&logical.to_le_bytes());
    r[fmmu_reg::LENGTH..fmmu_reg::LENGTH + 2].copy_from_slice(&len.to_le_bytes());
    r[fmmu_reg::LOGICAL_START_BIT] = 0;
    r[fmmu_reg::LOGICAL_END_BIT] = 7;
    r[fmmu_reg::PHYSICAL_START..fmmu_reg::PHYSICAL_START + 2].copy_from_slice(&physical.to_le_bytes());
    r[fmmu_reg::PHYSICAL_START_BIT] = 0;
    r[fmmu_reg::TYPE] = kind;
    r[fmmu_reg::ACTIVATE] = (len > 0) as u8;
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fmmu_layout() {
        let r = fmmu_registers(0x10, 6, 0x1100, fmmu_reg::TYPE_WRITE);
        assert_eq!(&r[..8], &[0x10, 0, 0, 0, 6, 0, 0, 7]);
        assert_eq!(&r[8..13], &[0x00, 0x11, 0, 2, 1]);
    }
}
