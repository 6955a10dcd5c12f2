//! The virtual AKD's process data: the checks of the PreOp→SafeOp transition and the copy of
//! the process image between the sync-manager buffers and the object dictionary.
//!
//! The image layout is the assigned PDOs' entries in order (0x1C12 for outputs in SM2,
//! 0x1C13 for inputs in SM3). The real drive refuses SafeOp with 0x001D when the output image
//! has an odd length (17 bytes at power-up, in the SOEM capture), 0x001E for the inputs, and
//! 0x0017 when SM2/SM3 do not match the image.

use crate::drive::pdo::is_padding;
use crate::drive::pdo::{AKD_PROCESS_IN, AKD_PROCESS_OUT};
use crate::ethercat::al::AlStatusCode;
use crate::ethercat::pdo::{self, Direction, PdoEntry};
use crate::sim::od::ObjectDictionary;
use crate::sim::sync_manager::{SyncManager, ACTIVATE_ENABLE};

/// The process image of one direction: entries in wire order.
pub type Image = Vec<PdoEntry>;

/// The output and input images of the current assignment.
pub fn images(od: &ObjectDictionary) -> (Image, Image) {
    let flatten = |d| od.assigned_pdos(d).into_iter().flat_map(|(_, e)| e).collect();
    (flatten(Direction::Rx), flatten(Direction::Tx))
}

/// Checks one process-data sync manager against its image length, start and direction.
pub fn check_sync_manager(sm: &SyncManager, start: u16, bytes: usize, master_writes: bool) -> Result<(), AlStatusCode> {
    let enabled = sm.activate & ACTIVATE_ENABLE != 0 && sm.length > 0;
    if bytes == 0 {
        return if enabled { Err(AlStatusCode::INVALID_SM_CONFIG) } else { Ok(()) };
    }
    let buffered = sm.control & 0x03 == 0;
    if !enabled || sm.start != start || sm.length as usize != bytes || !buffered || sm.master_writes() != master_writes
    {
        return Err(AlStatusCode::INVALID_SM_CONFIG);
    }
    Ok(())
}

/// The drive's checks of PreOp→SafeOp: even image lengths, then SM2 and SM3.
pub fn check_safeop(od: &ObjectDictionary, memory: &[u8]) -> Result<(), AlStatusCode> {
    let (rx, tx) = images(od);
    let (rx_bits, tx_bits) = (pdo::bit_len(&rx), pdo::bit_len(&tx));
    if rx_bits % 16 != 0 {
        return Err(AlStatusCode::INVALID_OUTPUT_CONFIG);
    }
    if tx_bits % 16 != 0 {
        return Err(AlStatusCode::INVALID_INPUT_CONFIG);
    }
    check_sync_manager(&SyncManager::read(memory, 2), AKD_PROCESS_OUT, rx_bits / 8, true)?;
    check_sync_manager(&SyncManager::read(memory, 3), AKD_PROCESS_IN, tx_bits / 8, false)
}

/// Copies the outputs in SM2's buffer into the objects they carry.
pub fn apply_outputs(od: &mut ObjectDictionary, memory: &[u8], image: &[PdoEntry]) {
    let base = AKD_PROCESS_OUT as usize;
    for (at, entry) in pdo::layout(image.iter().copied()) {
        if !is_padding(entry) {
            let len = entry.byte_len();
            od.set(entry.index, entry.subindex, &memory[base + at..base + at + len]);
        }
    }
}

/// Copies the objects the inputs carry into SM3's buffer.
pub fn refresh_inputs(od: &ObjectDictionary, memory: &mut [u8], image: &[PdoEntry]) {
    refresh_inputs_at(od, memory, image, AKD_PROCESS_IN);
}

/// Copies the objects the inputs carry into the input buffer at `base` (another slave's SM3).
pub fn refresh_inputs_at(od: &ObjectDictionary, memory: &mut [u8], image: &[PdoEntry], base: u16) {
    let base = usize::from(base);
    for (at, entry) in pdo::layout(image.iter().copied()) {
        let len = entry.byte_len();
        let target = &mut memory[base + at..base + at + len];
        target.fill(0);
        if let Some(value) = od.get(entry.index, entry.subindex) {
            let n = len.min(value.len());
            target[..n].copy_from_slice(&value[..n]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::coe::access::WRITE_PREOP;

    fn select_fixed(od: &mut ObjectDictionary, rx: u16, tx: u16) {
        for (assign, pdo) in [(0x1C12, rx), (0x1C13, tx)] {
            od.write(assign, 0, &[0], WRITE_PREOP).unwrap();
            od.write(assign, 1, &pdo.to_le_bytes(), WRITE_PREOP).unwrap();
            od.write(assign, 0, &[1], WRITE_PREOP).unwrap();
        }
    }

    fn configure(memory: &mut [u8], rx_len: u16, tx_len: u16) {
        memory[0x0810..0x0818].copy_from_slice(&[0x00, 0x11, rx_len as u8, 0, 0x24, 0, 1, 0]);
        memory[0x0818..0x0820].copy_from_slice(&[0x40, 0x11, tx_len as u8, 0, 0x20, 0, 1, 0]);
    }

    #[test]
    fn the_power_up_mapping_is_refused_as_the_real_drive_does() {
        let od = ObjectDictionary::akd();
        let mut memory = vec![0u8; 0x2000];
        configure(&mut memory, 17, 17);
        assert_eq!(check_safeop(&od, &memory), Err(AlStatusCode::INVALID_OUTPUT_CONFIG));
    }

    #[test]
    fn fixed_mappings_need_matching_sync_managers() {
        let mut od = ObjectDictionary::akd();
        select_fixed(&mut od, 0x1701, 0x1B01);
        let mut memory = vec![0u8; 0x2000];
        configure(&mut memory, 6, 8);
        assert_eq!(check_safeop(&od, &memory), Err(AlStatusCode::INVALID_SM_CONFIG));
        configure(&mut memory, 6, 6);
        assert_eq!(check_safeop(&od, &memory), Ok(()));
    }

    #[test]
    fn images_carry_the_objects() {
        let mut od = ObjectDictionary::akd();
        select_fixed(&mut od, 0x1701, 0x1B01);
        let (rx, tx) = images(&od);
        let mut memory = vec![0u8; 0x2000];
        memory[0x1100..0x1106].copy_from_slice(&[1, 2, 3, 4, 0x0F, 0x00]);
        apply_outputs(&mut od, &memory, &rx);
        assert_eq!(od.get(0x60C1, 1).unwrap(), &[1, 2, 3, 4]);
        assert_eq!(od.get(0x6040, 0).unwrap(), &[0x0F, 0x00]);
        od.set(0x6063, 0, &[9, 8, 7, 6]);
        refresh_inputs(&od, &mut memory, &tx);
        assert_eq!(&memory[0x1140..0x1146], &[9, 8, 7, 6, 0x40, 0x02]);
    }
}
