//! Reading a slave's SII EEPROM through its ESC's SII interface (registers 0x0502–0x050F).
//!
//! Each read hands the interface a word address and a read command, waits while it is busy,
//! and takes 4 bytes (8 when the ESC says so in 0x0502 bit 6; the AKD reads 4). Only the used
//! part is read: the 64-word header, then category after category up to the end marker, so a
//! scan does not spend frames on the empty tail.

use std::time::{Duration, Instant};

use crate::error::{Error, Result, SiiError};
use crate::ethercat::master::Master;
use crate::ethercat::registers::{sii_reg, SII_CONTROL};

/// Words of the SII header before the first category.
const HEADER_WORDS: u32 = 0x40;
/// Category type that ends the category list.
const END_CATEGORY: u16 = 0xFFFF;
/// SII header word holding the EEPROM size in KiBit minus one.
const SIZE_WORD: usize = 0x3E;
/// How long one SII read may keep the interface busy.
const SII_BUSY_TIMEOUT: Duration = Duration::from_millis(100);

impl Master {
    /// Reads one chunk (4 or 8 bytes) of the SII of `station` starting at `word`, appending
    /// it to `out`.
    fn read_sii_chunk(&mut self, station: u16, word: u32, out: &mut Vec<u8>) -> Result<()> {
        let mut command = [0u8; 6];
        command[..2].copy_from_slice(&sii_reg::CMD_READ.to_le_bytes());
        command[2..].copy_from_slice(&word.to_le_bytes());
        self.write_registers(station, SII_CONTROL, &command)?;
        let deadline = Instant::now() + SII_BUSY_TIMEOUT;
        // Control (2), address (4) and up to 8 data bytes in one read.
        let mut state = [0u8; 14];
        loop {
            // Judged before the read: a thread stalled past the deadline after a busy read reads
            // once more, and fails only on what the interface says after the deadline.
            let expired = Instant::now() > deadline;
            self.read_registers(station, SII_CONTROL, &mut state)?;
            let control = u16::from_le_bytes([state[0], state[1]]);
            if control & (sii_reg::BUSY | sii_reg::CMD_READ) == 0 {
                if control & sii_reg::ERROR_ACK != 0 {
                    return Err(SiiError::EepromNack { station, word, control }.into());
                }
                let len = if control & sii_reg::READ_8_BYTES != 0 { 8 } else { 4 };
                out.extend_from_slice(&state[6..6 + len]);
                return Ok(());
            }
            if expired {
                return Err(Error::Timeout {
                    what: format!(
                        "station 0x{station:04X}'s SII interface (word 0x{word:04X}, control 0x{control:04X})"
                    )
                    .into(),
                });
            }
        }
    }

    /// Reads `words` words of the SII of `station` from `word` on.
    pub(crate) fn read_sii_words(&mut self, station: u16, word: u32, words: u32) -> Result<Vec<u8>> {
        let mut out = Vec::with_capacity(words as usize * 2 + 8);
        while (out.len() as u32) < words * 2 {
            self.read_sii_chunk(station, word + out.len() as u32 / 2, &mut out)?;
        }
        out.truncate(words as usize * 2);
        Ok(out)
    }

    /// Reads the used part of the SII of `station`: header and every category up to the end
    /// marker (included), bounded by the EEPROM size the header gives; a header whose checksum
    /// is wrong is refused before any category is read.
    pub fn read_sii(&mut self, station: u16) -> Result<Vec<u8>> {
        // Give the EEPROM interface to EtherCAT (0x0500 = 0) rather than to the PDI.
        self.write_registers(station, crate::ethercat::registers::SII_CONFIG, &[0])?;
        let mut image = self.read_sii_words(station, 0, HEADER_WORDS)?;
        // A damaged header is told at once, before its size word sends the reads past the EEPROM.
        let first: [u8; 14] = image[..14].try_into().expect("the header's first seven words");
        let computed = crate::ethercat::sii::header_checksum(&first);
        if image[14] != computed {
            return Err(SiiError::Checksum { stored: image[14], computed }.into());
        }
        let size_kbit = u16::from_le_bytes([image[SIZE_WORD * 2], image[SIZE_WORD * 2 + 1]]) as u32 + 1;
        let size_words = size_kbit * 1024 / 16;
        let mut word = HEADER_WORDS;
        loop {
            if word + 1 >= size_words {
                return Err(SiiError::EepromNoEnd { station, size_kbit }.into());
            }
            let header = self.read_sii_words(station, word, 2)?;
            let kind = u16::from_le_bytes([header[0], header[1]]);
            image.extend_from_slice(&header);
            if kind == END_CATEGORY {
                return Ok(image);
            }
            let len = u16::from_le_bytes([header[2], header[3]]) as u32;
            if word + 2 + len > size_words {
                return Err(SiiError::EepromCategoryPastEnd { station, kind, word, len, size_kbit }.into());
            }
            image.extend(self.read_sii_words(station, word + 2, len)?);
            word += 2 + len;
        }
    }
}
