//! What an ESC is as its registers show it, apart from its EEPROM: the controllers the virtual
//! slaves are built on. [`Esc`](super::esc::Esc) serves datagrams the same way for each; these
//! say where they differ.
//!
//! The values are what the real slaves answered, where a capture holds them:
//! - the AKD's ESC (an ESC20-class IP core): the SOEM capture and TwinCAT (see [`super::esc`]).
//! - the ET1100 of the EK1100: `../shared/real-ethercat/soem-sdinfo-ek1100-only.pcapng` and
//!   `soem-sdinfo-ek1100-el1004.pcapng` (type 0x11 revision 0, port descriptor 0x3B, features
//!   0x00FC, PDI control 0x0D00 from its EEPROM, DL status 0x5611 alone and 0x5A31 with a terminal
//!   behind it, SII control 0x0040: 8-byte reads from a real EEPROM).
//! - the ET1200 of the EL1004 (and, by the same type read through a broadcast, of the EL2004 in
//!   `rs-example-sii-el2004.pcapng`): type and revision ORed with the EK1100's read 0x13 0x01, so
//!   0x12 (ET1200) revision 1; port descriptor 0x4A, features 0x01FC, PDI control 0x0104 (digital
//!   I/O, device emulation) from its EEPROM, DL status 0x5613 as the last slave, SII control 0x0050
//!   until SafeOp and 0x0040 after, no DC system time (reads and writes of 0x0910 and up find no
//!   register: working counter 0), and no FMMU 3 (a broadcast write of 0x0630 counted the EK1100
//!   only).
//! - both Beckhoff ESCs' EEPROM took 0.54 to 0.77 ms for an 8-byte read (SOEM's polls of the busy
//!   bit in both captures): 0.65 ms here.
//!
//! Not in any capture, from Beckhoff's ESC datasheets: the number of FMMUs and sync managers and
//! the process RAM of each ESC (ET1100: 8, 8, 8 KiB; ET1200: 3, 4, 1 KiB), and the ESC build
//! registers (left 0).

use std::ops::Range;

/// First byte of process RAM, in every ESC.
pub const RAM_START: usize = 0x1000;

/// How the ESC reads its SII EEPROM for the master (register 0x0502).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SiiInterface {
    /// The PDI emulates the EEPROM: 4 bytes per read, there at once (SII control 0x0020).
    Emulated,
    /// A real EEPROM on I2C: 8 bytes per read, busy for `read_ns` after the command (SII
    /// control 0x0040).
    Eeprom {
        /// How long a read keeps the busy bit set.
        read_ns: u64,
        /// SII control bit 4 (reserved in the datasheets) reads 1 while the AL state is below
        /// SafeOp, as the EL1004's ET1200 showed it.
        bit4_below_safeop: bool,
    },
}

/// One kind of ESC.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EscHardware {
    /// Register 0x0000: the ESC type.
    pub esc_type: u8,
    /// Register 0x0001: its revision.
    pub revision: u8,
    /// Registers 0x0002-0x0003: its build.
    pub build: u16,
    /// Register 0x0004: FMMUs.
    pub fmmus: u8,
    /// Register 0x0005: sync managers.
    pub sync_managers: u8,
    /// Register 0x0006: process RAM in KiB, from 0x1000.
    pub ram_kib: u8,
    /// Register 0x0007: the port descriptor.
    pub port_descriptor: u8,
    /// Registers 0x0008-0x0009: the features supported.
    pub features: u16,
    /// Register 0x0140 at power-up; `None`: loaded from SII word 0, as an ESC with a real
    /// EEPROM does (bit 8 set there is device emulation: AL control is copied to AL status).
    pub pdi_control: Option<u16>,
    /// DL status bits 0-1: PDI operational (EEPROM loaded) and the PDI watchdog not expired.
    pub dl_status_pdi: u16,
    /// How it reads its EEPROM.
    pub sii: SiiInterface,
    /// Register blocks this ESC lacks: a datagram touching one is not served by it (no data,
    /// no working counter).
    pub absent: &'static [Range<u16>],
}

/// The AKD's ESC, as the real drive answered (today's values of [`super::esc`]).
pub const AKD: EscHardware = EscHardware {
    esc_type: 0x04,
    revision: 0x02,
    build: 0x0043,
    fmmus: 3,
    sync_managers: 4,
    ram_kib: 4,
    port_descriptor: 0x0F,
    features: 0x0184,
    pdi_control: Some(0x0C08),
    dl_status_pdi: 0x0003,
    sii: SiiInterface::Emulated,
    absent: &[],
};

/// How long the Beckhoff ESCs' EEPROMs were busy with an 8-byte read (0.54-0.77 ms seen).
pub const EEPROM_READ_NS: u64 = 650_000;

/// The ET1100 of an EK1100.
pub const ET1100: EscHardware = EscHardware {
    esc_type: 0x11,
    revision: 0x00,
    build: 0,
    fmmus: 8,
    sync_managers: 8,
    ram_kib: 8,
    port_descriptor: 0x3B,
    features: 0x00FC,
    pdi_control: None,
    dl_status_pdi: 0x0001,
    sii: SiiInterface::Eeprom { read_ns: EEPROM_READ_NS, bit4_below_safeop: false },
    absent: &[],
};

/// The ET1200 of the EL1xxx and EL2xxx terminals (their EEPROM sets a digital I/O PDI, no
/// processor), and, for want of a capture of one, of the EL3102 (whose EEPROM sets the PDI of its
/// processor).
pub const ET1200: EscHardware = EscHardware {
    esc_type: 0x12,
    revision: 0x01,
    build: 0,
    fmmus: 3,
    sync_managers: 4,
    ram_kib: 1,
    port_descriptor: 0x4A,
    features: 0x01FC,
    pdi_control: None,
    dl_status_pdi: 0x0003,
    sii: SiiInterface::Eeprom { read_ns: EEPROM_READ_NS, bit4_below_safeop: true },
    // FMMUs 3-15, sync managers 4-15, and DC but the receive times.
    absent: &[0x0630..0x0700, 0x0820..0x0880, 0x0910..0x0A00],
};

impl EscHardware {
    /// One past the last byte of process RAM.
    pub fn ram_end(&self) -> usize {
        RAM_START + usize::from(self.ram_kib) * 1024
    }

    /// Whether this ESC lacks any register of `[at, at + len)`.
    pub fn lacks_any(&self, at: usize, len: usize) -> bool {
        self.absent.iter().any(|r| usize::from(r.start) < at + len && at < usize::from(r.end))
    }
}
