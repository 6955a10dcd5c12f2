//! Setting up a slave's process data from its description ([`ProcessData`]): over CoE where
//! the description says so — clear the assignment count, write each flexible PDO's entries with
//! its count 0 and the count last, assign the PDOs, write the assignment count (CiA 301's order,
//! which the AKD requires, AKD manual §5.6) — and, before SafeOp, the sync managers of process
//! data as the slave's SII gives them (by their type: SM2 and SM3 of a slave with a mailbox, SM0
//! of a digital I/O terminal) and an FMMU each way, the one its SII's FMMU category gives that
//! use, from the slave's place in the process image, to the bit.

use crate::error::{Result, Unavailable};
use crate::ethercat::master::cyclic::ImageSlot;
use crate::ethercat::master::mailbox_client::sm_registers;
use crate::ethercat::master::Master;
use crate::ethercat::pdo::{Direction, PdoAssignment, ProcessData};
use crate::ethercat::registers::{self, fmmu_reg};
use crate::ethercat::sii::{fmmu_usage, sync_manager_type, Sii};

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

    /// Writes the process-data sync managers and FMMUs of the slave at `position` for its
    /// place `slot` in the process image, whose inputs start at logical address `in_base`
    /// (after every slave's outputs).
    pub(crate) fn setup_process_syncmanagers(&mut self, position: u16, slot: &ImageSlot, in_base: u32) -> Result<()> {
        let slave = self.slave(position)?;
        let station = slave.station_address;
        let process_data = slave.process_data.as_ref().ok_or(Unavailable::NoMapping { slave: position })?;
        let mut writes = Vec::with_capacity(4);
        for direction in Direction::ALL {
            let len = process_data.bytes(direction) as u16;
            let Some((n, start, control)) = process_data_sync_manager(&slave.sii, direction) else {
                if len > 0 {
                    return Err(Unavailable::NoSyncManager { slave: position, n: direction.sync_manager() }.into());
                }
                continue;
            };
            writes.push((registers::sm(n), sm_registers(start, len, control, len > 0).to_vec()));
            if len > 0 {
                let fmmu = fmmu_for(&slave.sii, direction);
                let place = match direction {
                    Direction::Rx => Place {
                        logical: slot.out_offset as u32,
                        len: slot.out_len as u16,
                        bit: slot.out_bit,
                        bits: slot.out_bits,
                    },
                    Direction::Tx => Place {
                        logical: in_base + slot.in_offset as u32,
                        len: slot.in_len as u16,
                        bit: slot.in_bit,
                        bits: slot.in_bits,
                    },
                };
                writes.push((registers::fmmu(fmmu), fmmu_registers(place, start, direction).to_vec()));
            }
        }
        for (register, data) in writes {
            self.write_registers(station, register, &data)?;
        }
        Ok(())
    }
}

/// The sync manager that carries `direction` in the slave `sii` describes: the first of the
/// type of process data that way (outputs 3, inputs 4), as its number, start address and
/// control byte.
fn process_data_sync_manager(sii: &Sii, direction: Direction) -> Option<(u8, u16, u8)> {
    let wanted = match direction {
        Direction::Rx => sync_manager_type::PROCESS_DATA_OUT,
        Direction::Tx => sync_manager_type::PROCESS_DATA_IN,
    };
    let (n, sm) = sii.sync_managers().iter().enumerate().find(|(_, sm)| sm.sm_type == wanted)?;
    Some((n as u8, sm.start_address, sm.control))
}

/// The FMMU the slave's SII gives to `direction` (the first of that use in its FMMU
/// category); without one, FMMU 0 for outputs and 1 for inputs.
pub(crate) fn fmmu_for(sii: &Sii, direction: Direction) -> u8 {
    let (usage, otherwise) = match direction {
        Direction::Rx => (fmmu_usage::OUTPUTS, 0),
        Direction::Tx => (fmmu_usage::INPUTS, 1),
    };
    sii.fmmu_usage().iter().position(|&u| u == usage).map_or(otherwise, |n| n as u8)
}

/// Where one way of a slave's process data sits in the logical address space: the first byte
/// and the bytes it touches, the bit of its first bit in that byte and its bits.
struct Place {
    logical: u32,
    len: u16,
    bit: u8,
    bits: usize,
}

/// The sixteen bytes of an FMMU mapping `place` to the sync manager's buffer at `physical`,
/// bit for bit: its first logical bit to physical bit 0.
fn fmmu_registers(place: Place, physical: u16, direction: Direction) -> [u8; 16] {
    let mut r = [0u8; 16];
    r[fmmu_reg::LOGICAL_START..fmmu_reg::LOGICAL_START + 4].copy_from_slice(&place.logical.to_le_bytes());
    r[fmmu_reg::LENGTH..fmmu_reg::LENGTH + 2].copy_from_slice(&place.len.to_le_bytes());
    r[fmmu_reg::LOGICAL_START_BIT] = place.bit;
    r[fmmu_reg::LOGICAL_END_BIT] = ((usize::from(place.bit) + place.bits + 7) % 8) as u8;
    r[fmmu_reg::PHYSICAL_START..fmmu_reg::PHYSICAL_START + 2].copy_from_slice(&physical.to_le_bytes());
    r[fmmu_reg::PHYSICAL_START_BIT] = 0;
    r[fmmu_reg::TYPE] = match direction {
        Direction::Rx => fmmu_reg::TYPE_WRITE,
        Direction::Tx => fmmu_reg::TYPE_READ,
    };
    r[fmmu_reg::ACTIVATE] = 1;
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fmmu_layout() {
        let r = fmmu_registers(Place { logical: 0x10, len: 6, bit: 0, bits: 48 }, 0x1100, Direction::Rx);
        assert_eq!(&r[..8], &[0x10, 0, 0, 0, 6, 0, 0, 7]);
        assert_eq!(&r[8..13], &[0x00, 0x11, 0, 2, 1]);
    }

    #[test]
    fn an_fmmu_of_a_few_bits_maps_them_as_soem_maps_an_el2004() {
        // SOEM's slaveinfo of two EL2004s: "FMMU0 Ls:00000000 Ll:1 Lsb:0 Leb:3 Ps:0f00" and
        // "Lsb:4 Leb:7".
        let first = fmmu_registers(Place { logical: 0, len: 1, bit: 0, bits: 4 }, 0x0F00, Direction::Rx);
        let second = fmmu_registers(Place { logical: 0, len: 1, bit: 4, bits: 4 }, 0x0F00, Direction::Rx);
        assert_eq!(&first[..12], &[0, 0, 0, 0, 1, 0, 0, 3, 0x00, 0x0F, 0, 2]);
        assert_eq!(&second[6..8], &[4, 7]);
    }
}
