//! Choosing a slave's process-data mapping and setting up what carries it.
//!
//! A fixed mapping is selected in 0x1C12 (outputs) and 0x1C13 (inputs) — both, as the real
//! drive requires. A flexible one is checked against the AKD's rules ([`pdo::check_flexible`])
//! before anything is written, then written in the AKD's order (AKD manual §5.6): clear the
//! assignment counts, write each PDO's entries with its count 0 and the count last, assign the
//! PDOs, write the assignment counts. Before SafeOp, SM2/SM3 and FMMU0/FMMU1 are set from the
//! mapping's lengths and the slave's place in the process image.

use crate::drive::pdo::{self, Direction, PdoEntry};
use crate::error::{PdoError, Result};
use crate::ethercat::master::mailbox_client::sm_registers;
use crate::ethercat::master::Master;
use crate::ethercat::registers::{self, fmmu_reg};

/// SM2 start and control when the SII gives none (the AKD's).
const SM2_DEFAULT: (u16, u8) = (registers::AKD_PROCESS_OUT, 0x24);
/// SM3 start and control when the SII gives none (the AKD's).
const SM3_DEFAULT: (u16, u8) = (registers::AKD_PROCESS_IN, 0x20);

/// A mapping of one direction.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Mapping {
    /// A fixed mapping of the drive, e.g. 0x1701 or 0x1B01.
    Fixed(u16),
    /// Up to four flexible PDOs, each a list of entries, written to 0x1600.. or 0x1A00...
    Flexible(Vec<Vec<PdoEntry>>),
}

impl Mapping {
    /// The entries in wire order, after checking the mapping fits `direction` and the AKD's
    /// rules.
    pub fn entries(&self, direction: Direction) -> Result<Vec<PdoEntry>> {
        match self {
            Mapping::Fixed(index) => match pdo::fixed(*index) {
                Some(fixed) if fixed.direction == direction => Ok(fixed.entries.to_vec()),
                _ => Err(PdoError::NotFixed {
                    direction: direction.name(),
                    index: *index,
                    allowed: pdo::FIXED.iter().filter(|p| p.direction == direction).map(|p| p.index).collect(),
                }
                .into()),
            },
            Mapping::Flexible(pdos) => {
                let indexed: Vec<(u16, &[PdoEntry])> = pdos
                    .iter()
                    .enumerate()
                    .map(|(i, e)| (direction.flexible_base() + i as u16, e.as_slice()))
                    .collect();
                pdo::check_flexible(direction, &indexed)?;
                Ok(pdos.iter().flatten().copied().collect())
            }
        }
    }
}

/// The mapping a slave was given, with its entries resolved.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SlaveMapping {
    /// Outputs (RxPDO).
    pub rx: Mapping,
    /// Inputs (TxPDO).
    pub tx: Mapping,
    /// Output entries in wire order.
    pub rx_entries: Vec<PdoEntry>,
    /// Input entries in wire order.
    pub tx_entries: Vec<PdoEntry>,
}

impl SlaveMapping {
    /// Bytes of outputs.
    pub fn rx_bytes(&self) -> usize {
        pdo::bit_len(&self.rx_entries) / 8
    }

    /// Bytes of inputs.
    pub fn tx_bytes(&self) -> usize {
        pdo::bit_len(&self.tx_entries) / 8
    }
}

impl Master {
    /// Gives the slave at `position` (in PreOp) the mappings `rx` and `tx`. Both are checked
    /// first, so a refused mapping writes nothing.
    pub(super) fn configure_pdo(&mut self, position: u16, rx: Mapping, tx: Mapping) -> Result<()> {
        let rx_entries = rx.entries(Direction::Rx)?;
        let tx_entries = tx.entries(Direction::Tx)?;
        self.write_mapping(position, Direction::Rx, &rx)?;
        self.write_mapping(position, Direction::Tx, &tx)?;
        self.slave_entry_mut(position)?.mapping = Some(SlaveMapping { rx, tx, rx_entries, tx_entries });
        // A new mapping changes the process image; it is laid out again before SafeOp.
        self.process = None;
        Ok(())
    }

    fn write_mapping(&mut self, position: u16, direction: Direction, mapping: &Mapping) -> Result<()> {
        let assign = direction.assignment_index();
        self.sdo_write(position, assign, 0, &[0])?;
        let assigned: Vec<u16> = match mapping {
            Mapping::Fixed(index) => vec![*index],
            Mapping::Flexible(pdos) => {
                let mut indices = Vec::with_capacity(pdos.len());
                for (i, entries) in pdos.iter().enumerate() {
                    let index = direction.flexible_base() + i as u16;
                    self.sdo_write(position, index, 0, &[0])?;
                    for (sub, entry) in entries.iter().enumerate() {
                        self.sdo_write(position, index, sub as u8 + 1, &entry.to_u32().to_le_bytes())?;
                    }
                    self.sdo_write(position, index, 0, &[entries.len() as u8])?;
                    indices.push(index);
                }
                indices
            }
        };
        for (sub, index) in assigned.iter().enumerate() {
            self.sdo_write(position, assign, sub as u8 + 1, &index.to_le_bytes())?;
        }
        self.sdo_write(position, assign, 0, &[assigned.len() as u8])
    }

    /// Sets the drive's cycle time (interpolation time period 0x60C2) of the slave at
    /// `position`, e.g. 2 ms as (2, -3).
    pub(super) fn set_cycle_time(&mut self, position: u16, cycle_ns: u32) -> Result<()> {
        let (units, exponent) = crate::ethercat::dc::interpolation_time_period(cycle_ns)?;
        self.sdo_write(position, 0x60C2, 1, &[units])?;
        self.sdo_write(position, 0x60C2, 2, &[exponent as u8])
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
        let mapping = slave.mapping.clone().ok_or(PdoError::NoMapping { slave: position })?;
        let sm = |n: usize, default: (u16, u8)| {
            slave.sii.sync_managers().get(n).map_or(default, |sm| (sm.start_address, sm.control))
        };
        let (out_start, out_control) = sm(2, SM2_DEFAULT);
        let (in_start, in_control) = sm(3, SM3_DEFAULT);
        let (out_len, in_len) = (mapping.rx_bytes() as u16, mapping.tx_bytes() as u16);
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
    fn fixed_mappings_resolve_in_their_direction_only() {
        assert_eq!(Mapping::Fixed(0x1701).entries(Direction::Rx).unwrap().len(), 2);
        let err = Mapping::Fixed(0x1701).entries(Direction::Tx).unwrap_err().to_string();
        assert!(err.contains("0x1B01") && err.contains("not a fixed TxPDO"), "{err}");
        assert!(Mapping::Fixed(0x1234).entries(Direction::Rx).is_err());
    }

    #[test]
    fn odd_flexible_mapping_is_refused_before_writing() {
        let odd = Mapping::Flexible(vec![vec![PdoEntry::new(0x6040, 0, 16), PdoEntry::new(0x6060, 0, 8)]]);
        let err = odd.entries(Direction::Rx).unwrap_err().to_string();
        assert!(err.contains("odd") && err.contains("0x0002"), "{err}");
        let padded = Mapping::Flexible(vec![vec![
            PdoEntry::new(0x6040, 0, 16),
            PdoEntry::new(0x6060, 0, 8),
            PdoEntry::new(0x0002, 0, 8),
        ]]);
        assert_eq!(padded.entries(Direction::Rx).unwrap().len(), 3);
    }

    #[test]
    fn fmmu_layout() {
        let r = fmmu_registers(0x10, 6, 0x1100, fmmu_reg::TYPE_WRITE);
        assert_eq!(&r[..8], &[0x10, 0, 0, 0, 6, 0, 0, 7]);
        assert_eq!(&r[8..13], &[0x00, 0x11, 0, 2, 1]);
    }
}
