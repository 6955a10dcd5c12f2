//! The SII EEPROM images of the virtual Beckhoff terminals, written out as what they say
//! (identity, names, sync managers, FMMUs, PDOs) and encoded with [`Builder`], as the AKD's is
//! in [`super::sii_image`].
//!
//! Where the evidence comes from (`../shared/real-ethercat/`, whose README names the sources):
//! - **EK1100** and **EL2004**: their real EEPROM dumps (`ek1100.hex`, `el2004-eeprom-dump.bin`);
//!   the images here are those dumps byte for byte (`tests/test_real_ethercat.py` holds them to
//!   it where `../shared` is present).
//! - **EL1004**: the SII words SOEM read from a real one in `soem-sdinfo-ek1100-el1004.pcapng`:
//!   identity, the strings category's length and first strings, the general category but its
//!   last 12 bytes, the FMMU, sync manager and sync unit categories, and its TxPDOs but their
//!   flags and the entries' index and name (read as Beckhoff numbers them, 0x6000:01, 0x6010:01,
//!   ... named "Input", and with the EL2004's flags). Not read: header words 0-7 but the PDI
//!   control word 0 (0x0104, which the ESC showed in register 0x0140), and the last strings,
//!   taken as Beckhoff names them ("Digitale Eingangsklemmen (EL1xxx)", "EL1004 4K. Dig. Eingang
//!   24V, 3ms"); their lengths add up to the category's length the capture gives.
//! - **EL1008** and **EL2008**: no image of either is shared. They are the EL1004's and the
//!   EL2004's with eight channels, as the EL2828's and EL2889's images number theirs (PDO
//!   0x1600 plus n, entry 0x7000 plus 0x10·n), with Beckhoff's product codes (0x03F03052,
//!   0x07D83052) and
//!   E-bus currents (90 mA, 110 mA); the revision is their four-channel sibling's, and the
//!   EL2008's extended PDI configuration the EL2828's (0x00FF for eight outputs).
//! - **EL3102**: no image is shared either. Its identity (product 0x0C1E3052, revision
//!   0x00140000) and PDOs (0x1A00 and 0x1A01, each a status byte 0x3101:01 and a 16-bit value
//!   0x3101:02, 0x3102 for the second channel) are those IgH's `ethercat cstruct` printed from
//!   real ones in published configurations; its mailbox (128 bytes each way at 0x1000 and
//!   0x1080, CoE) and process-data sync managers (0x1100, 0x1180) follow Beckhoff's usual layout,
//!   as the ClipX's image has them; names and E-bus current (130 mA) are Beckhoff's catalogue's.
//!   Thin evidence throughout: what a master reads of it is consistent, not measured.

use crate::ethercat::mailbox::MailboxType;
use crate::ethercat::sii::{
    category, fmmu_usage, sync_manager_type, Builder, Category, General, Header, Identity, MailboxLayout, SiiError,
    SiiPdo, SiiPdoEntry, SyncManager,
};

/// Beckhoff's vendor id.
pub const BECKHOFF: u32 = 0x0000_0002;
/// CoE data type codes' low bytes as the SII carries them.
const BOOLEAN: u8 = 0x01;
const INTEGER16: u8 = 0x03;
const UNSIGNED8: u8 = 0x05;
/// PDO flags of Beckhoff's fixed PDOs: mandatory, fixed content.
const PDO_FLAGS: u16 = 0x0011;
/// Sync manager enable byte of the digital terminals: enabled, Op only.
const SM_ENABLE_OP_ONLY: u8 = 0x09;
/// Physical ports of a terminal: ports 0 and 1 E-bus.
const EBUS_PORTS: u16 = 0x0033;

/// One Beckhoff terminal's image, before it is encoded.
#[derive(Clone, Copy, Debug)]
pub struct TerminalSii {
    /// Order number, e.g. "EL2004" (also the name SOEM shows).
    pub order: &'static str,
    /// Identity words.
    pub identity: Identity,
    /// E-bus current, mA (negative: fed into the E-bus).
    pub current_on_ebus: i16,
    /// What it is.
    pub kind: Kind,
}

/// What kind of terminal an image describes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A coupler: no process data.
    Coupler,
    /// `channels` digital inputs.
    DigitalInputs {
        /// Number of inputs.
        channels: u8,
    },
    /// `channels` digital outputs.
    DigitalOutputs {
        /// Number of outputs.
        channels: u8,
    },
    /// `channels` analog inputs with a mailbox (CoE).
    AnalogInputs {
        /// Number of inputs.
        channels: u8,
    },
}

/// A Beckhoff terminal: its order number, product code, revision, E-bus current (mA) and kind.
const fn terminal(
    order: &'static str,
    product_code: u32,
    revision: u32,
    current_on_ebus: i16,
    kind: Kind,
) -> TerminalSii {
    let identity = Identity { vendor_id: BECKHOFF, product_code, revision, serial_number: 0 };
    TerminalSii { order, identity, current_on_ebus, kind }
}

/// The EK1100 EtherCAT coupler.
pub const EK1100: TerminalSii = terminal("EK1100", 0x044C_2C52, 0x0012_0000, -2000, Kind::Coupler);
/// The EL1004: 4 digital inputs.
pub const EL1004: TerminalSii = terminal("EL1004", 0x03EC_3052, 0x0013_0000, 90, Kind::DigitalInputs { channels: 4 });
/// The EL1008: 8 digital inputs.
pub const EL1008: TerminalSii = terminal("EL1008", 0x03F0_3052, 0x0013_0000, 90, Kind::DigitalInputs { channels: 8 });
/// The EL2004: 4 digital outputs.
pub const EL2004: TerminalSii = terminal("EL2004", 0x07D4_3052, 0x0010_0000, 100, Kind::DigitalOutputs { channels: 4 });
/// The EL2008: 8 digital outputs.
pub const EL2008: TerminalSii = terminal("EL2008", 0x07D8_3052, 0x0010_0000, 110, Kind::DigitalOutputs { channels: 8 });
/// The EL3102: 2 analog inputs, ±10 V.
pub const EL3102: TerminalSii = terminal("EL3102", 0x0C1E_3052, 0x0014_0000, 130, Kind::AnalogInputs { channels: 2 });

/// The EL3102's mailbox: 128 bytes each way at 0x1000 and 0x1080.
pub const EL3102_MAILBOX: MailboxLayout =
    MailboxLayout { receive_offset: 0x1000, receive_size: 0x80, send_offset: 0x1080, send_size: 0x80 };
/// Where the EL3102's inputs are (SM3).
pub const EL3102_INPUTS: u16 = 0x1180;
/// Where the EL3102's outputs would be (SM2; it has none).
pub const EL3102_OUTPUTS: u16 = 0x1100;
/// Where the digital input terminals' inputs are: SM0, in process RAM, where the ESC's digital
/// I/O PDI puts them.
pub const DIGITAL_INPUTS: u16 = 0x1000;
/// Where the digital output terminals' outputs are: SM0 on the ESC's digital output register.
pub const DIGITAL_OUTPUTS: u16 = 0x0F00;

impl TerminalSii {
    fn header(&self) -> Header {
        let (pdi_control, pdi_configuration2, mailbox, protocols, reserved) = match self.kind {
            // The EK1100's reserved words 0x20-0x22 as its dump holds them.
            Kind::Coupler => (0x0D00, 0, MailboxLayout::default(), 0, [(3, 0x0006), (4, 0x001A), (5, 0x8A0E)]),
            // Digital I/O PDI with device emulation; its extended configuration sets the outputs'
            // pins (0x000F for the EL2004's four, 0x00FF for the EL2828's eight), none for inputs.
            Kind::DigitalInputs { .. } => (0x0104, 0, MailboxLayout::default(), 0, [(0, 0); 3]),
            Kind::DigitalOutputs { channels } => {
                (0x0104, (1u16 << channels) - 1, MailboxLayout::default(), 0, [(0, 0); 3])
            }
            // A processor on the PDI (SPI), no device emulation.
            Kind::AnalogInputs { .. } => (0x0005, 0, EL3102_MAILBOX, MailboxType::Coe.sii_protocol_bit(), [(0, 0); 3]),
        };
        let mut reserved_1d = [0; 33];
        for (i, value) in reserved {
            reserved_1d[i] = value;
        }
        Header {
            pdi_control,
            pdi_configuration: 0,
            sync_impulse_length: 0,
            pdi_configuration2,
            configured_station_alias: 0,
            reserved_05: [0; 2],
            checksum_reserved: 0,
            identity: self.identity,
            execution_delay: 0,
            port0_delay: 0,
            port1_delay: 0,
            reserved_13: 0,
            bootstrap_mailbox: mailbox,
            standard_mailbox: mailbox,
            mailbox_protocols: protocols,
            reserved_1d,
            // 16 KiBit: a 2 KiB EEPROM.
            size: 0x000F,
            version: 1,
        }
    }

    /// The group, its display name and the device's name, as Beckhoff's images name them.
    fn names(&self) -> (&'static str, &'static str, String) {
        match self.kind {
            Kind::Coupler => ("SystemBk", "System Koppler", format!("{} EtherCAT-Koppler (2A E-Bus)", self.order)),
            Kind::DigitalInputs { channels } => (
                "DigIn",
                "Digitale Eingangsklemmen (EL1xxx)",
                format!("{} {channels}K. Dig. Eingang 24V, 3ms", self.order),
            ),
            Kind::DigitalOutputs { channels } => (
                "DigOut",
                "Digitale Ausgangklemmen (EL2xxx)",
                format!("{} {channels}K. Dig. Ausgang 24V, 0.5A", self.order),
            ),
            Kind::AnalogInputs { channels } => (
                "AnaIn",
                "Analoge Eingangsklemmen (EL3xxx)",
                format!("{} {channels}K. Ana. Eingang +/-10V, Diff.", self.order),
            ),
        }
    }

    /// The encoded 2 KiB image, 0xFF after the end category and in the pad bytes, as
    /// Beckhoff writes them.
    pub fn image(&self) -> Result<Vec<u8>, SiiError> {
        let mut b = Builder::new(self.header());
        b.pad_with(0xFF);
        b.strings_here();
        let (group, group_name, name) = self.names();
        let general = General {
            order_idx: b.string(self.order),
            group_idx: b.string(group),
            group_idx_2: b.string(group_name),
            name_idx: b.string(&name),
            // As Beckhoff writes it, though ETG.2010 reserves it.
            reserved_4: if self.kind == Kind::Coupler { 0x02 } else { 0x0C },
            current_on_ebus: self.current_on_ebus,
            physical_port: if self.kind == Kind::Coupler { 0x0131 } else { EBUS_PORTS },
            ..General::default()
        };
        match self.kind {
            Kind::Coupler => b.push(Category::General(general)),
            Kind::DigitalInputs { channels } => {
                b.push(Category::General(general));
                b.push(Category::Fmmu(vec![fmmu_usage::INPUTS, fmmu_usage::NOT_USED]));
                let sm = sync_manager(DIGITAL_INPUTS, 1, 0x00, 0x01, sync_manager_type::PROCESS_DATA_IN);
                b.push(Category::SyncManagers(vec![sm]));
                b.push(Category::Other { kind: category::SYNC_UNIT, data: vec![0xF0, 0xFF] });
                let pdos = digital_pdos(&mut b, 0x1A00, 0x6000, "Input", channels);
                b.push(Category::TxPdos(pdos));
            }
            Kind::DigitalOutputs { channels } => {
                b.push(Category::General(general));
                b.push(Category::Fmmu(vec![fmmu_usage::OUTPUTS, fmmu_usage::NOT_USED]));
                let sm = sync_manager(DIGITAL_OUTPUTS, 0, 0x44, SM_ENABLE_OP_ONLY, sync_manager_type::PROCESS_DATA_OUT);
                b.push(Category::SyncManagers(vec![sm]));
                b.push(Category::Other { kind: category::SYNC_UNIT, data: vec![0xF0, 0xFF] });
                let pdos = digital_pdos(&mut b, 0x1600, 0x7000, "Output", channels);
                b.push(Category::RxPdos(pdos));
            }
            Kind::AnalogInputs { channels } => {
                // SDO, SDO information, PDO assignment.
                b.push(Category::General(General { coe_details: 0x07, flags: 0x00, ..general }));
                let usage = [fmmu_usage::OUTPUTS, fmmu_usage::INPUTS, fmmu_usage::SYNC_MANAGER_STATUS, 0xFF];
                b.push(Category::Fmmu(usage.to_vec()));
                let mb = EL3102_MAILBOX;
                b.push(Category::SyncManagers(vec![
                    sync_manager(mb.receive_offset, mb.receive_size, 0x26, 0x01, sync_manager_type::MAILBOX_OUT),
                    sync_manager(mb.send_offset, mb.send_size, 0x22, 0x01, sync_manager_type::MAILBOX_IN),
                    sync_manager(EL3102_OUTPUTS, 0, 0x24, 0x00, sync_manager_type::PROCESS_DATA_OUT),
                    sync_manager(EL3102_INPUTS, 0, 0x20, 0x01, sync_manager_type::PROCESS_DATA_IN),
                ]));
                let pdos = (0..channels)
                    .map(|n| {
                        let object = analog_object(n);
                        let entries = vec![
                            SiiPdoEntry::new(object, 1, b.string("Status"), UNSIGNED8, 8),
                            SiiPdoEntry::new(object, 2, b.string("Value"), INTEGER16, 16),
                        ];
                        let index = 0x1A00 + u16::from(n);
                        let name_idx = b.string(&format!("TxPDO-Map Channel {}", n + 1));
                        SiiPdo { index, sync_manager: 3, dc_sync: 0, name_idx, flags: PDO_FLAGS, entries }
                    })
                    .collect();
                b.push(Category::TxPdos(pdos));
            }
        }
        b.finish()
    }
}

/// The object of analog input `n` (from 0) of the EL3102: 0x3101, 0x3102.
pub fn analog_object(n: u8) -> u16 {
    0x3101 + u16::from(n)
}

fn sync_manager(start_address: u16, length: u16, control: u8, enable: u8, sm_type: u8) -> SyncManager {
    SyncManager { start_address, length, control, status: 0, enable, sm_type }
}

/// One PDO of one bit per channel, `pdo + n` mapping `object + 0x10·n`:01, each named "Channel
/// n+1" with its entry named `entry`: the digital terminals' PDOs.
fn digital_pdos(b: &mut Builder, pdo: u16, object: u16, entry: &str, channels: u8) -> Vec<SiiPdo> {
    (0..u16::from(channels))
        .map(|n| {
            let name_idx = b.string(&format!("Channel {}", n + 1));
            let entry = SiiPdoEntry::new(object + 0x10 * n, 1, b.string(entry), BOOLEAN, 1);
            SiiPdo { index: pdo + n, sync_manager: 0, dc_sync: 0, name_idx, flags: PDO_FLAGS, entries: vec![entry] }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::sii::Sii;

    #[test]
    fn every_image_encodes_and_reads_back() {
        for t in [EK1100, EL1004, EL1008, EL2004, EL2008, EL3102] {
            let image = t.image().unwrap();
            assert_eq!(image.len(), 2048, "{}", t.order);
            let sii = Sii::parse(&image).unwrap();
            assert_eq!((sii.identity(), sii.order()), (t.identity, Some(t.order)));
            assert_eq!(sii.encode().unwrap(), image, "{}", t.order);
        }
    }

    #[test]
    fn the_el1004_holds_what_soem_read_of_a_real_one() {
        // SII words SOEM read in soem-sdinfo-ek1100-el1004.pcapng: (word address, 8 bytes).
        let read: [(usize, &[u8]); 13] = [
            (0x0040, &[0x0a, 0x00, 0x40, 0x00, 0x09, 0x06, 0x45, 0x4c]),
            (0x0044, &[0x31, 0x30, 0x30, 0x34, 0x05, 0x44, 0x69, 0x67]),
            (0x0082, &[0x1e, 0x00, 0x10, 0x00, 0x02, 0x00, 0x01, 0x04]),
            (0x0086, &[0x0c, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00]),
            (0x008a, &[0x5a, 0x00, 0x03, 0x00, 0x33, 0x00, 0x00, 0x00]),
            (0x0094, &[0x28, 0x00, 0x01, 0x00, 0x02, 0xff, 0x29, 0x00]),
            (0x0098, &[0x04, 0x00, 0x00, 0x10, 0x01, 0x00, 0x00, 0x00]),
            (0x009c, &[0x01, 0x04, 0x2b, 0x00, 0x01, 0x00, 0xf0, 0xff]),
            (0x00a1, &[0x20, 0x00, 0x00, 0x1a, 0x01, 0x00, 0x00, 0x05]),
            (0x00a8, &[0x01, 0x01, 0x00, 0x00, 0x01, 0x1a, 0x01, 0x00]),
            (0x00b0, &[0x01, 0x01, 0x00, 0x00, 0x02, 0x1a, 0x01, 0x00]),
            (0x00b8, &[0x01, 0x01, 0x00, 0x00, 0x03, 0x1a, 0x01, 0x00]),
            (0x00c0, &[0x01, 0x01, 0x00, 0x00, 0xff, 0xff, 0xff, 0xff]),
        ];
        let image = EL1004.image().unwrap();
        for (word, bytes) in read {
            assert_eq!(&image[2 * word..2 * word + 8], bytes, "word 0x{word:04X}");
        }
        assert_eq!(&image[0x10..0x1C], &[0x02, 0, 0, 0, 0x52, 0x30, 0xec, 0x03, 0, 0, 0x13, 0]);
        assert_eq!(&image[..2], &[0x04, 0x01], "PDI control as register 0x0140 showed it");
    }
}
