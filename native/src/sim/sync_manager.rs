//! Sync manager semantics of the virtual AKD's ESC (ETG.1000.4 §6.7).
//!
//! A mailbox sync manager guards one buffer: the writer fills it (the last byte written makes it
//! full), the reader empties it (the last byte read makes it empty), and the other side cannot
//! touch it in between. The status bits follow what the real drive shows in the SOEM capture:
//! a completed write leaves status 0x09 (written, full), a completed read leaves 0x02 (read).
//! Buffered sync managers (process data) are always accessible while enabled; a complete write
//! of the output buffer triggers the process-data watchdog.

use crate::ethercat::registers::{sm, sm_reg};

/// Number of sync managers of the AKD's ESC.
pub const SM_COUNT: u8 = 4;
/// Status bit 0: the buffer was completely written.
pub const STATUS_WRITTEN: u8 = 0x01;
/// Status bit 1: the buffer was completely read.
pub const STATUS_READ: u8 = 0x02;
/// Activate bit 0: the master enabled the sync manager.
pub const ACTIVATE_ENABLE: u8 = 0x01;
/// PDI control bit 0: the application deactivated the sync manager.
pub const PDI_DEACTIVATE: u8 = 0x01;
/// Control bit 6: writes to this sync manager restart the process-data watchdog.
pub const CONTROL_WATCHDOG: u8 = 0x40;
/// Shortest mailbox sync manager the drive accepts at Init→PreOp, bytes.
pub const MIN_MAILBOX_SIZE: u16 = 64;

/// One sync manager's registers, as read from the ESC's register space.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SyncManager {
    /// Physical start address of the buffer.
    pub start: u16,
    /// Buffer length in bytes.
    pub length: u16,
    /// Control byte: mode, direction, interrupts, watchdog trigger.
    pub control: u8,
    /// Status byte.
    pub status: u8,
    /// Activate byte (master side).
    pub activate: u8,
    /// PDI control byte (application side).
    pub pdi_control: u8,
}

impl SyncManager {
    /// Decodes the eight register bytes of sync manager `n` from the register space.
    pub fn read(memory: &[u8], n: u8) -> Self {
        let at = sm(n) as usize;
        let r = &memory[at..at + 8];
        SyncManager {
            start: u16::from_le_bytes([r[sm_reg::START], r[sm_reg::START + 1]]),
            length: u16::from_le_bytes([r[sm_reg::LENGTH], r[sm_reg::LENGTH + 1]]),
            control: r[sm_reg::CONTROL],
            status: r[sm_reg::STATUS],
            activate: r[sm_reg::ACTIVATE],
            pdi_control: r[sm_reg::PDI_CONTROL],
        }
    }

    /// Whether the master enabled it and the application did not deactivate it.
    pub fn active(&self) -> bool {
        self.activate & ACTIVATE_ENABLE != 0 && self.pdi_control & PDI_DEACTIVATE == 0 && self.length > 0
    }

    /// Whether it runs in mailbox (one-buffer) mode.
    pub fn is_mailbox(&self) -> bool {
        self.control & 0x03 == sm_reg::MODE_MAILBOX
    }

    /// Whether the master writes its buffer.
    pub fn master_writes(&self) -> bool {
        self.control & 0x0C == sm_reg::DIRECTION_WRITE
    }

    /// Whether the mailbox buffer holds an unread message.
    pub fn full(&self) -> bool {
        self.status & sm_reg::STATUS_MAILBOX_FULL != 0
    }

    /// The buffer's address range.
    pub fn range(&self) -> std::ops::Range<usize> {
        self.start as usize..self.start as usize + self.length as usize
    }

    /// The part of the buffer's range that lies in a register space of `len` bytes. A master
    /// may set a buffer running past the end of the ESC's memory (start and length are any
    /// 16-bit values), and the firmware can only read and fill what exists.
    pub fn range_within(&self, len: usize) -> std::ops::Range<usize> {
        let r = self.range();
        r.start.min(len)..r.end.min(len)
    }

    /// Whether `[at, at + len)` overlaps the buffer.
    pub fn overlaps(&self, at: usize, len: usize) -> bool {
        let r = self.range();
        at < r.end && r.start < at + len
    }

    /// Whether `[at, at + len)` covers the buffer's last byte (which completes a transfer).
    pub fn covers_last_byte(&self, at: usize, len: usize) -> bool {
        let last = self.start as usize + self.length as usize - 1;
        (at..at + len).contains(&last)
    }
}

/// Address of sync manager `n`'s status byte.
pub fn status_address(n: u8) -> usize {
    sm(n) as usize + sm_reg::STATUS
}

/// Address of sync manager `n`'s PDI control byte.
pub fn pdi_control_address(n: u8) -> usize {
    sm(n) as usize + sm_reg::PDI_CONTROL
}

/// Marks sync manager `n`'s buffer completely written: status "written, full".
pub fn mark_written(memory: &mut [u8], n: u8) {
    let s = &mut memory[status_address(n)];
    *s = (*s & !(STATUS_READ | STATUS_WRITTEN)) | STATUS_WRITTEN | sm_reg::STATUS_MAILBOX_FULL;
}

/// Marks sync manager `n`'s buffer completely read: status "read, empty".
pub fn mark_read(memory: &mut [u8], n: u8) {
    let s = &mut memory[status_address(n)];
    *s = (*s & !(STATUS_WRITTEN | sm_reg::STATUS_MAILBOX_FULL)) | STATUS_READ;
}

/// Sets or clears the application's deactivation of sync manager `n`.
pub fn set_pdi_deactivated(memory: &mut [u8], n: u8, deactivated: bool) {
    let p = &mut memory[pdi_control_address(n)];
    *p = if deactivated { *p | PDI_DEACTIVATE } else { *p & !PDI_DEACTIVATE };
}

/// The drive's checks of Init→PreOp: the mailbox sync managers where the AKD's SII puts them,
/// in mailbox mode, with a buffer of [`MIN_MAILBOX_SIZE`] up to the `mailbox_size` the SII
/// declares.
pub fn check_mailbox(memory: &[u8], mailbox_size: u16) -> Result<(), crate::ethercat::al::AlStatusCode> {
    check_mailbox_at(memory, (0x1800, 0x1C00), mailbox_size)
}

/// The checks of [`check_mailbox`] for a slave whose SII puts its mailbox-out and mailbox-in
/// buffers at `starts`.
pub fn check_mailbox_at(
    memory: &[u8],
    starts: (u16, u16),
    mailbox_size: u16,
) -> Result<(), crate::ethercat::al::AlStatusCode> {
    for (n, start, master_writes) in [(0u8, starts.0, true), (1, starts.1, false)] {
        let sm = SyncManager::read(memory, n);
        let enabled = sm.activate & ACTIVATE_ENABLE != 0;
        if !enabled
            || sm.start != start
            || !(MIN_MAILBOX_SIZE..=mailbox_size).contains(&sm.length)
            || !sm.is_mailbox()
            || sm.master_writes() != master_writes
        {
            return Err(crate::ethercat::al::AlStatusCode::INVALID_SM_CONFIG);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mailbox_status_follows_the_real_drive() {
        let mut memory = vec![0u8; 0x1000];
        mark_written(&mut memory, 1);
        assert_eq!(memory[status_address(1)], 0x09);
        mark_read(&mut memory, 1);
        assert_eq!(memory[status_address(1)], 0x02);
    }

    #[test]
    fn decodes_the_registers_soem_writes() {
        let mut memory = vec![0u8; 0x1000];
        memory[0x0800..0x0808].copy_from_slice(&[0x00, 0x18, 0x00, 0x04, 0x26, 0x00, 0x01, 0x00]);
        let sm0 = SyncManager::read(&memory, 0);
        assert_eq!((sm0.start, sm0.length, sm0.control), (0x1800, 0x400, 0x26));
        assert!(sm0.active() && sm0.is_mailbox() && sm0.master_writes());
        assert!(sm0.covers_last_byte(0x1800, 0x400) && !sm0.covers_last_byte(0x1800, 0x3FF));
        set_pdi_deactivated(&mut memory, 0, true);
        assert!(!SyncManager::read(&memory, 0).active());
    }
}
