//! The SII EEPROM image of the real AKD the virtual AKD stands in for: an AKD-P00606-NBCC-E000
//! with firmware 01-20-00-003, written out as what it says (identity, mailbox, names, sync
//! managers, PDOs, DC modes) and encoded with [`sii::Builder`](crate::ethercat::sii::Builder).
//!
//! The fixed PDOs come from [`crate::drive::pdo::FIXED`], so the image and the mapping
//! rules cannot drift apart; this file adds only what the SII holds besides them: entry names
//! and data types, default sync-manager assignment, and the flexible PDOs' content at the time
//! the image was read.

use crate::drive::identity;
use crate::drive::objects::{self, MappableObject};
use crate::drive::pdo;
use crate::error::{Error, Result, SiiError};
use crate::ethercat::mailbox::MailboxType;
use crate::ethercat::pdo::{Direction, PdoEntry};
use crate::ethercat::sii::{
    category, fmmu_usage, sync_manager_type, Builder, Category, DcOpMode, General, Header, Identity, MailboxLayout,
    SiiPdo, SiiPdoEntry, SyncManager,
};

/// The drive's model string (category 0x0800).
pub const MODEL: &str = "AKD-P00606-NBCC-E000";
/// The drive's firmware version string (category 0x0801).
pub const FIRMWARE: &str = "01-20-00-003";
/// The device name of the general category.
pub const NAME: &str = "AKD EtherCAT Drive (CoE)";
/// Vendor id, product code, revision and serial number of the real drive.
pub const IDENTITY: Identity = Identity {
    vendor_id: identity::VENDOR_ID,
    product_code: identity::PRODUCT_CODE,
    revision: 2,
    serial_number: 0x9983_0093,
};

/// The identity of the virtual AKD at `position` on its line: the real drive's, its serial
/// number counted up by the position. Drives on one line then tell themselves apart as real ones
/// do (a master or an integrator names a drive by its serial), the same on every run, and the
/// first drive stays the real drive whose captures the replay tests compare with.
pub fn identity(position: usize) -> Identity {
    // Positions are below 65536 on any EtherCAT line.
    Identity { serial_number: IDENTITY.serial_number.wrapping_add(position as u32), ..IDENTITY }
}

/// Both mailboxes (bootstrap and standard) of the AKD: 1 KiB each at 0x1800 and 0x1C00.
const MAILBOX: MailboxLayout =
    MailboxLayout { receive_offset: 0x1800, receive_size: 0x0400, send_offset: 0x1C00, send_size: 0x0400 };

/// The flexible PDOs as the image lists them: only the first of each direction carries an
/// entry (the control or status word); the mapping the drive reports over CoE at power-up is
/// richer ([`pdo::POWER_UP_RX`]) because the drive fills it in after the image was written.
const FLEXIBLE_RX: [(u16, &[PdoEntry]); 4] =
    [(0x1600, &[PdoEntry::new(0x6040, 0, 16)]), (0x1601, &[]), (0x1602, &[]), (0x1603, &[])];
/// TxPDO counterpart of [`FLEXIBLE_RX`].
const FLEXIBLE_TX: [(u16, &[PdoEntry]); 4] =
    [(0x1A00, &[PdoEntry::new(0x6041, 0, 16)]), (0x1A01, &[]), (0x1A02, &[]), (0x1A03, &[])];

/// PDO flag: the content is fixed (ETG.2010 PDO flags bit 4).
const PDO_FIXED_CONTENT: u16 = 0x0010;
/// Sync manager of a PDO not assigned by default.
const NO_SYNC_MANAGER: u8 = 0xFF;

fn header(identity: Identity) -> Header {
    Header {
        pdi_control: 0x0009,
        pdi_configuration: 0x0800,
        sync_impulse_length: 0,
        pdi_configuration2: 0,
        configured_station_alias: 0,
        reserved_05: [0; 2],
        checksum_reserved: 0,
        identity,
        execution_delay: 0,
        port0_delay: 0,
        port1_delay: 0,
        reserved_13: 0,
        bootstrap_mailbox: MAILBOX,
        standard_mailbox: MAILBOX,
        mailbox_protocols: [MailboxType::Eoe, MailboxType::Coe, MailboxType::Foe]
            .into_iter()
            .fold(0, |bits, protocol| bits | protocol.sii_protocol_bit()),
        reserved_1d: [0; 33],
        // 16 KiBit: a 2 KiB EEPROM.
        size: 0x000F,
        version: 1,
    }
}

fn sii_entry(b: &mut Builder, entry: PdoEntry) -> Result<SiiPdoEntry> {
    let (&MappableObject { name, .. }, data_type) = objects::mappable_object(entry.index, entry.subindex)
        .ok_or_else(|| Error::from(SiiError::NoPdoName { index: entry.index, subindex: entry.subindex }))?;
    // SII data types are the CoE codes' low byte (all the AKD maps are below 0x100).
    Ok(SiiPdoEntry::new(entry.index, entry.subindex, b.string(name), data_type as u8, entry.bits))
}

/// The PDOs of one direction in image order: flexible ones first, then the fixed ones, the
/// default pair (0x1701, 0x1B01) assigned to its sync manager.
fn pdos(b: &mut Builder, direction: Direction) -> Result<Vec<SiiPdo>> {
    let (name, flexible, default, sm) = match direction {
        Direction::Rx => ("Outputs", FLEXIBLE_RX, pdo::DEFAULT_FIXED.0, 2),
        Direction::Tx => ("Inputs", FLEXIBLE_TX, pdo::DEFAULT_FIXED.1, 3),
    };
    let flexible = flexible.iter().map(|&(index, entries)| (index, entries, NO_SYNC_MANAGER, 0));
    let fixed = pdo::FIXED
        .iter()
        .filter(|p| p.direction == direction)
        .map(|p| (p.index, p.entries, if p.index == default { sm } else { NO_SYNC_MANAGER }, PDO_FIXED_CONTENT));
    let mut out = Vec::new();
    for (index, entries, sync_manager, flags) in flexible.chain(fixed) {
        let name_idx = b.string(name);
        let entries = entries.iter().map(|&e| sii_entry(b, e)).collect::<Result<_>>()?;
        out.push(SiiPdo { index, sync_manager, dc_sync: 0, name_idx, flags, entries });
    }
    Ok(out)
}

fn sync_manager(start_address: u16, length: u16, control: u8, sm_type: u8) -> SyncManager {
    SyncManager { start_address, length, control, status: 0, enable: 1, sm_type }
}

fn describe(identity: Identity) -> Result<Vec<u8>> {
    let mut b = Builder::new(header(identity));
    b.push(identity::string_category(identity::MODEL_CATEGORY, MODEL));
    b.push(identity::string_category(identity::FIRMWARE_CATEGORY, FIRMWARE));
    b.strings_here();
    // Fields in the order the drive's string table names them.
    let general = General {
        order_idx: b.string("AKD"),
        group_idx: b.string("Drive"),
        group_idx_2: b.string("Drives"),
        name_idx: b.string(NAME),
        image_idx: b.string("DRIVE"),
        // As the drive writes it, though ETG.2010 reserves it.
        reserved_4: 1,
        // SDO, PDO assign, PDO configuration; the drive answers SDO information all the same.
        coe_details: 0x0D,
        foe_details: 0x01,
        eoe_details: 0x03,
        ds402_channels: 1,
        // Enable SafeOp, mailbox data link layer.
        flags: 0x05,
        // Ports 0 and 1: MII.
        physical_port: 0x0011,
        ..General::default()
    };
    b.push(Category::General(general));
    b.push(Category::Fmmu(vec![
        fmmu_usage::OUTPUTS,
        fmmu_usage::INPUTS,
        fmmu_usage::SYNC_MANAGER_STATUS,
        fmmu_usage::NOT_USED,
    ]));
    b.push(Category::SyncManagers(vec![
        sync_manager(0x1800, 0x0400, 0x26, sync_manager_type::MAILBOX_OUT),
        sync_manager(0x1C00, 0x0400, 0x22, sync_manager_type::MAILBOX_IN),
        sync_manager(0x1100, 0, 0x24, sync_manager_type::PROCESS_DATA_OUT),
        sync_manager(0x1140, 0, 0x20, sync_manager_type::PROCESS_DATA_IN),
    ]));
    b.push(Category::Other { kind: category::SYNC_UNIT, data: vec![0xF0, 0xFF] });
    // The drive's string table names the DC modes before the PDOs.
    let dc = vec![
        // SYNC0 from the master's cycle (0x0980 = 0x0300: cyclic unit and SYNC0 active).
        DcOpMode {
            assign_activate: 0x0300,
            sync0_cycle_factor: 1,
            name_idx: b.string("DcSync"),
            ..DcOpMode::default()
        },
        DcOpMode { assign_activate: 0, sync0_cycle_factor: 1, name_idx: b.string("DcOff"), ..DcOpMode::default() },
    ];
    let tx = pdos(&mut b, Direction::Tx)?;
    let rx = pdos(&mut b, Direction::Rx)?;
    b.push(Category::TxPdos(tx));
    b.push(Category::RxPdos(rx));
    b.push(Category::Dc(dc));
    Ok(b.finish()?)
}

/// The real AKD's 2 KiB SII image: the content above, 0xFF after the end category.
pub fn akd_sii() -> Vec<u8> {
    akd_sii_of(IDENTITY)
}

/// The real AKD's SII image with `identity` in its header: the image of the drive at a position
/// of its own on a line ([`identity()`]). The header checksum covers words 0 to 6 only, before the
/// identity, so it stays the real image's.
pub fn akd_sii_of(identity: Identity) -> Vec<u8> {
    // Only the identity varies, and no identity can fail to encode; `describes_the_real_drive`
    // proves the rest encodes.
    describe(identity).expect("the AKD's SII description encodes")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::coe::data_type;
    use crate::ethercat::sii::Sii;

    #[test]
    fn describes_the_real_drive() {
        let image = describe(IDENTITY).unwrap();
        assert_eq!(image.len(), 2048);
        let sii = Sii::parse(&image).unwrap();
        let id = sii.identity();
        assert_eq!((id.vendor_id, id.product_code, id.revision), (0x6A, 0x0041_4B44, 2));
        assert_eq!(sii.name(), Some("AKD EtherCAT Drive (CoE)"));
        assert_eq!(identity::model(&sii).as_deref(), Some("AKD-P00606-NBCC-E000"));
        assert_eq!(identity::firmware(&sii).as_deref(), Some("01-20-00-003"));
        let sms: Vec<_> = sii.sync_managers().iter().map(|sm| (sm.start_address, sm.control)).collect();
        assert_eq!(sms, [(0x1800, 0x26), (0x1C00, 0x22), (0x1100, 0x24), (0x1140, 0x20)]);
        assert_eq!(sii.header.mailbox_protocols, 0x000E);
        let assigned: Vec<_> =
            sii.rx_pdos().iter().chain(sii.tx_pdos()).filter(|p| p.sync_manager != 0xFF).map(|p| p.index).collect();
        assert_eq!(assigned, [0x1701, 0x1B01]);
        let statusword = &sii.tx_pdos()[0].entries[0];
        assert_eq!(sii.string(statusword.name_idx), Some("Statusword"));
        assert_eq!(u16::from(statusword.data_type), data_type::UNSIGNED16);
    }

    #[test]
    fn each_position_has_a_serial_of_its_own_and_the_first_is_the_real_drives() {
        assert_eq!(identity(0), IDENTITY);
        assert_eq!(akd_sii_of(identity(0)), akd_sii());
        let serials: Vec<_> = (0..64).map(|p| identity(p).serial_number).collect();
        assert_eq!(serials[..3], [0x9983_0093, 0x9983_0094, 0x9983_0095]);
        let mut distinct = serials.clone();
        distinct.sort_unstable();
        distinct.dedup();
        assert_eq!(distinct.len(), 64);
        for position in [1, 5, 63] {
            let image = akd_sii_of(identity(position));
            // Sii::parse checks the header checksum.
            let sii = Sii::parse(&image).unwrap();
            assert_eq!(sii.identity(), identity(position));
            // Nothing but the serial number (words 0x0E..0x0F) differs from the real image.
            let real = akd_sii();
            let differing: Vec<_> = (0..image.len()).filter(|&i| image[i] != real[i]).collect();
            assert!(!differing.is_empty() && differing.iter().all(|i| (0x1C..0x20).contains(i)), "{differing:02X?}");
        }
    }

    // The byte-for-byte comparison with the real drive's EEPROM is
    // tests/test_real_akd_sii.py::test_real_akd_sii_virtual_image_equals_the_real_one, where a
    // missing ../shared is reported as a skip rather than passed off as a pass.
}
