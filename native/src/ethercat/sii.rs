//! The SII EEPROM content (ETG.1000.6 §5.4, ETG.2010): a pure codec, no I/O.
//!
//! The image is 64 header words (identity, mailbox layout, EEPROM size) followed by categories,
//! each a type word, a length word (in words) and data, up to the end category 0xFFFF.
//! [`Sii::parse`] decodes an image (or the part of it a master read, up to the end category);
//! [`Sii::encode`] writes one back, so that `parse` then `encode` gives the same bytes for any
//! valid image (zero padding, 0xFF filler after the end category). Categories this codec does
//! not interpret are kept raw in [`Category::Other`], so they round-trip too.
//! [`Builder`] writes an image from a description, interning strings as it goes.
//!
//! Strings are ISO 8859-1 (Latin-1): each byte is one character, so any byte string decodes and
//! encodes back unchanged.

/// The result of reading or writing an SII image.
type Result<T> = std::result::Result<T, SiiError>;
use crate::ethercat::pdo::{Direction, Pdo, PdoAssignment, PdoEntry, ProcessData};

/// Words in the fixed header before the first category.
pub const HEADER_WORDS: usize = 64;
/// Bytes in the fixed header before the first category.
pub const HEADER_BYTES: usize = HEADER_WORDS * 2;

/// Category types (ETG.2010 table 7). A manufacturer's own categories (0x0800 and up) are kept
/// raw ([`Category::Other`]); its profile reads them.
pub mod category {
    /// Strings referenced by index from the other categories.
    pub const STRINGS: u16 = 0x000A;
    /// General information: names, supported mailbox details, flags.
    pub const GENERAL: u16 = 0x001E;
    /// FMMU usage.
    pub const FMMU: u16 = 0x0028;
    /// Sync manager layout.
    pub const SYNC_MANAGER: u16 = 0x0029;
    /// Sync unit (kept raw: the AKD's is the two bytes F0 FF).
    pub const SYNC_UNIT: u16 = 0x002B;
    /// TxPDOs (drive to master).
    pub const TX_PDO: u16 = 0x0032;
    /// RxPDOs (master to drive).
    pub const RX_PDO: u16 = 0x0033;
    /// Distributed-clock operation modes.
    pub const DC: u16 = 0x003C;
    /// End of the category list.
    pub const END: u16 = 0xFFFF;
}

/// CoE details bit of the general category: the slave takes a PDO assignment (0x1C12, 0x1C13)
/// written over CoE.
pub const COE_PDO_ASSIGN: u8 = 0x04;

/// FMMU usage codes of the FMMU category.
pub mod fmmu_usage {
    /// Process data outputs.
    pub const OUTPUTS: u8 = 0x01;
    /// Process data inputs.
    pub const INPUTS: u8 = 0x02;
    /// Sync manager status (mailbox state).
    pub const SYNC_MANAGER_STATUS: u8 = 0x03;
    /// Not used (ETG.2010 also allows 0x00).
    pub const NOT_USED: u8 = 0xFF;
}

/// Sync manager types of the SM category.
pub mod sync_manager_type {
    /// Mailbox out (master to slave).
    pub const MAILBOX_OUT: u8 = 1;
    /// Mailbox in (slave to master).
    pub const MAILBOX_IN: u8 = 2;
    /// Process data outputs.
    pub const PROCESS_DATA_OUT: u8 = 3;
    /// Process data inputs.
    pub const PROCESS_DATA_IN: u8 = 4;
}

/// CRC-8 of the first seven header words (polynomial x^8+x^2+x+1, initial value 0xFF), the
/// checksum an ESC verifies before it loads its configuration from the EEPROM.
pub fn header_checksum(first_seven_words: &[u8; 14]) -> u8 {
    let mut crc = 0xFFu8;
    for &byte in first_seven_words {
        crc ^= byte;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 { (crc << 1) ^ 0x07 } else { crc << 1 };
        }
    }
    crc
}

/// The identity a master matches a slave by.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Identity {
    /// Vendor id (0x6A Kollmorgen).
    pub vendor_id: u32,
    /// Product code (0x00414B44 "AKD").
    pub product_code: u32,
    /// Revision number.
    pub revision: u32,
    /// Serial number.
    pub serial_number: u32,
}

impl Identity {
    /// The identity in SII words 8..0xF, given as their 16 bytes.
    pub fn from_words(words: &[u8]) -> Identity {
        let dword = |i: usize| u32::from_le_bytes([words[i], words[i + 1], words[i + 2], words[i + 3]]);
        Identity { vendor_id: dword(0), product_code: dword(4), revision: dword(8), serial_number: dword(12) }
    }
}

/// A mailbox layout: where the master writes (SM0) and reads (SM1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
// Python gets a dict keyed by the field names (akd_ros._native): renaming a field renames a key.
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObject))]
pub struct MailboxLayout {
    /// Start of the mailbox the slave receives on (master to slave, SM0).
    pub receive_offset: u16,
    /// Its length in bytes.
    pub receive_size: u16,
    /// Start of the mailbox the slave sends on (slave to master, SM1).
    pub send_offset: u16,
    /// Its length in bytes.
    pub send_size: u16,
}

/// The 64 header words. Reserved words are kept as read so an image round-trips.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Header {
    /// Word 0: PDI control, loaded into register 0x0140.
    pub pdi_control: u16,
    /// Word 1: PDI configuration, loaded into register 0x0150.
    pub pdi_configuration: u16,
    /// Word 2: SYNC impulse length in 10 ns units (register 0x0982).
    pub sync_impulse_length: u16,
    /// Word 3: extended PDI configuration (register 0x0152).
    pub pdi_configuration2: u16,
    /// Word 4: configured station alias (register 0x0012).
    pub configured_station_alias: u16,
    /// Words 5 and 6: reserved.
    pub reserved_05: [u16; 2],
    /// High byte of word 7, reserved; the low byte is the checksum, computed on encode and
    /// checked on parse.
    pub checksum_reserved: u8,
    /// Words 8..0xF: identity.
    pub identity: Identity,
    /// Word 0x10: execution delay.
    pub execution_delay: u16,
    /// Word 0x11: port 0 delay.
    pub port0_delay: u16,
    /// Word 0x12: port 1 delay.
    pub port1_delay: u16,
    /// Word 0x13: reserved.
    pub reserved_13: u16,
    /// Words 0x14..0x17: the bootstrap mailbox.
    pub bootstrap_mailbox: MailboxLayout,
    /// Words 0x18..0x1B: the standard mailbox (PreOp and up).
    pub standard_mailbox: MailboxLayout,
    /// Word 0x1C: supported mailbox protocols, the bits of
    /// [`MailboxType::sii_protocol_bit`](crate::ethercat::mailbox::MailboxType::sii_protocol_bit).
    pub mailbox_protocols: u16,
    /// Words 0x1D..0x3D: reserved.
    pub reserved_1d: [u16; 33],
    /// Word 0x3E: EEPROM size in KiBit minus one.
    pub size: u16,
    /// Word 0x3F: version of the SII layout (1).
    pub version: u16,
}

impl Header {
    /// The EEPROM size in bytes the size word announces.
    pub fn eeprom_bytes(&self) -> usize {
        (usize::from(self.size) + 1) * 128
    }
}

/// Category General (ETG.2010 table 9), 32 bytes.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObjectRef))]
pub struct General {
    /// String index of the group type.
    pub group_idx: u8,
    /// String index of the image name.
    pub image_idx: u8,
    /// String index of the order number.
    pub order_idx: u8,
    /// String index of the device name.
    pub name_idx: u8,
    /// Byte 4, reserved.
    pub reserved_4: u8,
    /// CoE details: bit 0 SDO, 1 SDO information, 2 PDO assign, 3 PDO configuration, 4 upload
    /// at startup, 5 SDO complete access.
    pub coe_details: u8,
    /// FoE details: bit 0 FoE supported.
    pub foe_details: u8,
    /// EoE details: bit 0 EoE supported.
    pub eoe_details: u8,
    /// SoE channels (reserved).
    pub soe_channels: u8,
    /// DS402 channels (reserved).
    pub ds402_channels: u8,
    /// Sysman class (reserved).
    pub sysman_class: u8,
    /// Flags: bit 0 enable SafeOp, 1 enable not-LRW, 2 mailbox data link layer, 3 identification
    /// by AL status code, 4 identification by physical memory.
    pub flags: u8,
    /// Current drawn from the E-bus in mA (negative: fed into it).
    pub current_on_ebus: i16,
    /// Byte 14: the second group string index (ETG.2010 "GroupIdx, duplicate"); the AKD puts
    /// its group's display name ("Drives") here.
    pub group_idx_2: u8,
    /// Byte 15, reserved.
    pub reserved_15: u8,
    /// Physical ports 0..3, one nibble each.
    pub physical_port: u16,
    /// Physical memory address.
    pub physical_memory_address: u16,
    /// Bytes 20..31, reserved.
    pub reserved_20: [u8; 12],
}

/// One sync manager of the SM category (8 bytes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
// Python gets a dict keyed by the field names (akd_ros._native): renaming a field renames a key.
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObjectRef))]
pub struct SyncManager {
    /// Physical start address.
    pub start_address: u16,
    /// Length in bytes (0 for process data: the master sets it from the mapping).
    pub length: u16,
    /// Control register value (0x0804 + 8n).
    pub control: u8,
    /// Status register value (reserved, 0).
    pub status: u8,
    /// Enable byte: bit 0 enable, bit 1 fixed content, bit 2 virtual, bit 3 Op only.
    pub enable: u8,
    /// Type, one of [`sync_manager_type`].
    #[cfg_attr(feature = "python", pyo3(item("type")))]
    pub sm_type: u8,
}

/// One entry of a PDO in the TxPDO or RxPDO category (8 bytes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SiiPdoEntry {
    /// Object index (0 for a gap).
    pub index: u16,
    /// Subindex.
    pub subindex: u8,
    /// String index of the entry's name.
    pub name_idx: u8,
    /// CoE data type code (low byte of the codes in [`crate::ethercat::coe::data_type`]).
    pub data_type: u8,
    /// Length in bits.
    pub bit_len: u8,
    /// Flags (reserved, 0).
    pub flags: u16,
}

impl SiiPdoEntry {
    /// An entry without flags, as the images written here carry them.
    pub fn new(index: u16, subindex: u8, name_idx: u8, data_type: u8, bit_len: u8) -> Self {
        SiiPdoEntry { index, subindex, name_idx, data_type, bit_len, flags: 0 }
    }

    /// The entry as a mapping object value.
    pub fn pdo_entry(&self) -> PdoEntry {
        PdoEntry::new(self.index, self.subindex, self.bit_len)
    }
}

/// One PDO of the TxPDO or RxPDO category.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SiiPdo {
    /// PDO index (0x1600.., 0x1A00..).
    pub index: u16,
    /// Sync manager the PDO is assigned to by default, 0xFF for none.
    pub sync_manager: u8,
    /// DC sync unit.
    pub dc_sync: u8,
    /// String index of the PDO's name.
    pub name_idx: u8,
    /// Flags: bit 0 mandatory, 1 default, 4 fixed content, ...
    pub flags: u16,
    /// The mapped entries.
    pub entries: Vec<SiiPdoEntry>,
}

/// One distributed-clock operation mode of the DC category (24 bytes).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DcOpMode {
    /// SYNC0 cycle time in ns (0: set by the master).
    pub cycle_time0: u32,
    /// SYNC0 shift time in ns.
    pub shift_time0: u32,
    /// SYNC1 shift time in ns.
    pub shift_time1: u32,
    /// SYNC1 cycle factor.
    pub sync1_cycle_factor: i16,
    /// Value for register 0x0980 (cyclic unit control and activation).
    pub assign_activate: u16,
    /// SYNC0 cycle factor.
    pub sync0_cycle_factor: i16,
    /// String index of the mode's name.
    pub name_idx: u8,
    /// String index of its description.
    pub description_idx: u8,
    /// Bytes 20..23, reserved.
    pub reserved: [u8; 4],
}

/// One category of the image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Category {
    /// 0x000A: strings; string index n (1-based) is element n-1.
    Strings(Vec<String>),
    /// 0x001E: general information.
    General(General),
    /// 0x0028: FMMU usage, one code of [`fmmu_usage`] per byte, including the padding byte.
    Fmmu(Vec<u8>),
    /// 0x0029: sync managers.
    SyncManagers(Vec<SyncManager>),
    /// 0x0032: TxPDOs.
    TxPdos(Vec<SiiPdo>),
    /// 0x0033: RxPDOs.
    RxPdos(Vec<SiiPdo>),
    /// 0x003C: DC operation modes.
    Dc(Vec<DcOpMode>),
    /// Any other category, kept as read.
    Other {
        /// Category type.
        kind: u16,
        /// Its data (an even number of bytes).
        data: Vec<u8>,
    },
}

impl Category {
    /// The category type word.
    pub fn kind(&self) -> u16 {
        match self {
            Category::Strings(_) => category::STRINGS,
            Category::General(_) => category::GENERAL,
            Category::Fmmu(_) => category::FMMU,
            Category::SyncManagers(_) => category::SYNC_MANAGER,
            Category::TxPdos(_) => category::TX_PDO,
            Category::RxPdos(_) => category::RX_PDO,
            Category::Dc(_) => category::DC,
            Category::Other { kind, .. } => *kind,
        }
    }
}

/// A decoded SII image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Sii {
    /// The 64 header words.
    pub header: Header,
    /// The categories in image order, without the end category.
    pub categories: Vec<Category>,
    /// The byte a category of an odd number of bytes is padded with to a whole word: 0 in the
    /// AKD's image, 0xFF in Beckhoff's. Kept so that an image encodes back as it was read.
    pub padding: u8,
}

/// Little-endian reader over a category's data that names what it reads in its errors.
struct Reader<'a> {
    data: &'a [u8],
    at: usize,
    what: &'static str,
}

impl<'a> Reader<'a> {
    fn new(data: &'a [u8], what: &'static str) -> Self {
        Reader { data, at: 0, what }
    }

    fn bytes(&mut self, n: usize) -> Result<&'a [u8]> {
        let rest = &self.data[self.at..];
        if rest.len() < n {
            return Err(SiiError::CategoryOverrun { category: self.what, len: self.data.len(), read: n, at: self.at });
        }
        self.at += n;
        Ok(&rest[..n])
    }

    fn u8(&mut self) -> Result<u8> {
        Ok(self.bytes(1)?[0])
    }

    fn u16(&mut self) -> Result<u16> {
        let b = self.bytes(2)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }

    fn u32(&mut self) -> Result<u32> {
        let b = self.bytes(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// A byte, or 0 where a short category ends (older images write a shorter General).
    fn u8_or_zero(&mut self) -> u8 {
        self.u8().unwrap_or(0)
    }

    fn remaining(&self) -> usize {
        self.data.len() - self.at
    }
}

fn latin1(bytes: &[u8]) -> String {
    bytes.iter().map(|&b| char::from(b)).collect()
}

fn latin1_bytes(s: &str, what: &'static str) -> Result<Vec<u8>> {
    s.chars()
        .map(|c| u8::try_from(u32::from(c)).map_err(|_| SiiError::NotLatin1 { what, text: s.to_owned(), character: c }))
        .collect()
}

fn decode_strings(data: &[u8]) -> Result<Vec<String>> {
    let mut r = Reader::new(data, "strings");
    let count = r.u8()?;
    let mut strings = Vec::with_capacity(usize::from(count));
    for n in 1..=count {
        let len = r.u8()?;
        let bytes = r.bytes(usize::from(len)).map_err(|_| SiiError::StringOverrun {
            number: n.into(),
            count: count.into(),
            len: len.into(),
            left: r.remaining(),
        })?;
        strings.push(latin1(bytes));
    }
    Ok(strings)
}

fn decode_general(data: &[u8]) -> General {
    let mut r = Reader::new(data, "general");
    let mut g = General {
        group_idx: r.u8_or_zero(),
        image_idx: r.u8_or_zero(),
        order_idx: r.u8_or_zero(),
        name_idx: r.u8_or_zero(),
        reserved_4: r.u8_or_zero(),
        coe_details: r.u8_or_zero(),
        foe_details: r.u8_or_zero(),
        eoe_details: r.u8_or_zero(),
        soe_channels: r.u8_or_zero(),
        ds402_channels: r.u8_or_zero(),
        sysman_class: r.u8_or_zero(),
        flags: r.u8_or_zero(),
        current_on_ebus: i16::from_le_bytes([r.u8_or_zero(), r.u8_or_zero()]),
        group_idx_2: r.u8_or_zero(),
        reserved_15: r.u8_or_zero(),
        physical_port: u16::from_le_bytes([r.u8_or_zero(), r.u8_or_zero()]),
        physical_memory_address: u16::from_le_bytes([r.u8_or_zero(), r.u8_or_zero()]),
        reserved_20: [0; 12],
    };
    for byte in g.reserved_20.iter_mut() {
        *byte = r.u8_or_zero();
    }
    g
}

fn whole_records(data: &[u8], record: usize, what: &'static str) -> Result<()> {
    if !data.len().is_multiple_of(record) {
        return Err(SiiError::NotWholeRecords { category: what, len: data.len(), record });
    }
    Ok(())
}

fn decode_sync_managers(data: &[u8]) -> Result<Vec<SyncManager>> {
    whole_records(data, 8, "sync manager")?;
    let mut r = Reader::new(data, "sync manager");
    let mut sms = Vec::with_capacity(data.len() / 8);
    while r.remaining() > 0 {
        sms.push(SyncManager {
            start_address: r.u16()?,
            length: r.u16()?,
            control: r.u8()?,
            status: r.u8()?,
            enable: r.u8()?,
            sm_type: r.u8()?,
        });
    }
    Ok(sms)
}

fn decode_pdos(data: &[u8], what: &'static str) -> Result<Vec<SiiPdo>> {
    let mut r = Reader::new(data, what);
    let mut pdos = Vec::new();
    while r.remaining() > 0 {
        let index = r.u16()?;
        let count = r.u8()?;
        let mut pdo = SiiPdo {
            index,
            sync_manager: r.u8()?,
            dc_sync: r.u8()?,
            name_idx: r.u8()?,
            flags: r.u16()?,
            entries: Vec::with_capacity(usize::from(count)),
        };
        if r.remaining() < usize::from(count) * 8 {
            return Err(SiiError::PdoEntriesOverrun { what, index, count, left: r.remaining() });
        }
        for _ in 0..count {
            pdo.entries.push(SiiPdoEntry {
                index: r.u16()?,
                subindex: r.u8()?,
                name_idx: r.u8()?,
                data_type: r.u8()?,
                bit_len: r.u8()?,
                flags: r.u16()?,
            });
        }
        pdos.push(pdo);
    }
    Ok(pdos)
}

fn decode_dc(data: &[u8]) -> Result<Vec<DcOpMode>> {
    whole_records(data, 24, "DC")?;
    let mut r = Reader::new(data, "DC");
    let mut modes = Vec::with_capacity(data.len() / 24);
    while r.remaining() > 0 {
        let mut mode = DcOpMode {
            cycle_time0: r.u32()?,
            shift_time0: r.u32()?,
            shift_time1: r.u32()?,
            sync1_cycle_factor: r.u16()? as i16,
            assign_activate: r.u16()?,
            sync0_cycle_factor: r.u16()? as i16,
            name_idx: r.u8()?,
            description_idx: r.u8()?,
            reserved: [0; 4],
        };
        mode.reserved.copy_from_slice(r.bytes(4)?);
        modes.push(mode);
    }
    Ok(modes)
}

fn decode_category(kind: u16, data: &[u8]) -> Result<Category> {
    Ok(match kind {
        category::STRINGS => Category::Strings(decode_strings(data)?),
        category::GENERAL => Category::General(decode_general(data)),
        category::FMMU => Category::Fmmu(data.to_vec()),
        category::SYNC_MANAGER => Category::SyncManagers(decode_sync_managers(data)?),
        category::TX_PDO => Category::TxPdos(decode_pdos(data, "TxPDO")?),
        category::RX_PDO => Category::RxPdos(decode_pdos(data, "RxPDO")?),
        category::DC => Category::Dc(decode_dc(data)?),
        _ => Category::Other { kind, data: data.to_vec() },
    })
}

fn word(data: &[u8], w: usize) -> u16 {
    u16::from_le_bytes([data[2 * w], data[2 * w + 1]])
}

fn decode_header(data: &[u8]) -> Result<Header> {
    if data.len() < HEADER_BYTES {
        return Err(SiiError::ShortImage { len: data.len(), header: HEADER_BYTES });
    }
    let mut first = [0u8; 14];
    first.copy_from_slice(&data[..14]);
    let crc = header_checksum(&first);
    if data[14] != crc {
        return Err(SiiError::Checksum { stored: data[14], computed: crc });
    }
    let mailbox = |w| MailboxLayout {
        receive_offset: word(data, w),
        receive_size: word(data, w + 1),
        send_offset: word(data, w + 2),
        send_size: word(data, w + 3),
    };
    let mut reserved_1d = [0u16; 33];
    for (i, r) in reserved_1d.iter_mut().enumerate() {
        *r = word(data, 0x1D + i);
    }
    Ok(Header {
        pdi_control: word(data, 0),
        pdi_configuration: word(data, 1),
        sync_impulse_length: word(data, 2),
        pdi_configuration2: word(data, 3),
        configured_station_alias: word(data, 4),
        reserved_05: [word(data, 5), word(data, 6)],
        checksum_reserved: data[15],
        identity: Identity::from_words(&data[16..32]),
        execution_delay: word(data, 0x10),
        port0_delay: word(data, 0x11),
        port1_delay: word(data, 0x12),
        reserved_13: word(data, 0x13),
        bootstrap_mailbox: mailbox(0x14),
        standard_mailbox: mailbox(0x18),
        mailbox_protocols: word(data, 0x1C),
        reserved_1d,
        size: word(data, 0x3E),
        version: word(data, 0x3F),
    })
}

impl Sii {
    /// Decodes an image: the whole EEPROM, or the bytes from word 0 up to the end category.
    /// Every length that runs past the data, every string index beyond the strings category
    /// and a header checksum that matches neither byte of word 7 is an [`SiiError`] that says
    /// where.
    pub fn parse(data: &[u8]) -> Result<Sii> {
        let header = decode_header(data)?;
        let mut categories = Vec::new();
        let mut padding = None;
        let mut at = HEADER_BYTES;
        loop {
            if at + 2 > data.len() {
                return Err(SiiError::NoEndCategory { len: data.len(), categories: categories.len() });
            }
            let kind = u16::from_le_bytes([data[at], data[at + 1]]);
            if kind == category::END {
                break;
            }
            if at + 4 > data.len() {
                return Err(SiiError::NoLengthWord { kind, word: at / 2 });
            }
            let len = usize::from(u16::from_le_bytes([data[at + 2], data[at + 3]])) * 2;
            let start = at + 4;
            if start + len > data.len() {
                return Err(SiiError::CategoryPastEnd {
                    kind,
                    word: at / 2,
                    words: len / 2,
                    left: (data.len() - start) / 2,
                });
            }
            let category = decode_category(kind, &data[start..start + len])?;
            if padding.is_none() {
                // A category of an odd number of bytes shows the writer's padding.
                let bytes = encode_category_unpadded(&category).map_or(0, |raw| raw.len());
                padding = (bytes % 2 == 1 && bytes < len).then(|| data[start + bytes]);
            }
            categories.push(category);
            at = start + len;
        }
        let sii = Sii { header, categories, padding: padding.unwrap_or(0) };
        sii.check_string_indices()?;
        Ok(sii)
    }

    fn check_string_indices(&self) -> Result<()> {
        let count = self.strings().len();
        let check = |idx: u8, what: &dyn Fn() -> String| {
            if usize::from(idx) > count {
                Err(SiiError::NoSuchString { what: what(), index: idx, count })
            } else {
                Ok(())
            }
        };
        for c in &self.categories {
            match c {
                Category::General(g) => {
                    for (idx, field) in [
                        (g.group_idx, "group"),
                        (g.image_idx, "image"),
                        (g.order_idx, "order"),
                        (g.name_idx, "name"),
                        (g.group_idx_2, "second group"),
                    ] {
                        check(idx, &|| format!("the general category's {field}"))?;
                    }
                }
                Category::TxPdos(pdos) | Category::RxPdos(pdos) => {
                    let dir = if matches!(c, Category::TxPdos(_)) { "TxPDO" } else { "RxPDO" };
                    for p in pdos {
                        check(p.name_idx, &|| format!("{dir} 0x{:04X}", p.index))?;
                        for e in &p.entries {
                            check(e.name_idx, &|| {
                                format!("{dir} 0x{:04X} entry 0x{:04X}:{:02X}", p.index, e.index, e.subindex)
                            })?;
                        }
                    }
                }
                Category::Dc(modes) => {
                    for (i, m) in modes.iter().enumerate() {
                        check(m.name_idx, &|| format!("DC mode {i}"))?;
                        check(m.description_idx, &|| format!("DC mode {i}'s description"))?;
                    }
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// Encodes the image: header (with its checksum), categories, the end category, then 0xFF
    /// up to the EEPROM size of header word 0x3E.
    pub fn encode(&self) -> Result<Vec<u8>> {
        let h = &self.header;
        let mut out = Vec::with_capacity(h.eeprom_bytes());
        let push16 = |out: &mut Vec<u8>, v: u16| out.extend_from_slice(&v.to_le_bytes());
        let push32 = |out: &mut Vec<u8>, v: u32| out.extend_from_slice(&v.to_le_bytes());
        for w in [h.pdi_control, h.pdi_configuration, h.sync_impulse_length, h.pdi_configuration2]
            .into_iter()
            .chain([h.configured_station_alias])
            .chain(h.reserved_05)
        {
            push16(&mut out, w);
        }
        let mut first = [0u8; 14];
        first.copy_from_slice(&out);
        let crc = header_checksum(&first);
        out.extend_from_slice(&[crc, h.checksum_reserved]);
        let id = h.identity;
        for v in [id.vendor_id, id.product_code, id.revision, id.serial_number] {
            push32(&mut out, v);
        }
        for w in [h.execution_delay, h.port0_delay, h.port1_delay, h.reserved_13] {
            push16(&mut out, w);
        }
        for m in [h.bootstrap_mailbox, h.standard_mailbox] {
            for w in [m.receive_offset, m.receive_size, m.send_offset, m.send_size] {
                push16(&mut out, w);
            }
        }
        push16(&mut out, h.mailbox_protocols);
        for w in h.reserved_1d {
            push16(&mut out, w);
        }
        push16(&mut out, h.size);
        push16(&mut out, h.version);
        for c in &self.categories {
            let mut data = encode_category_unpadded(c)?;
            if data.len() % 2 == 1 {
                data.push(self.padding);
            }
            let words = u16::try_from(data.len() / 2)
                .map_err(|_| SiiError::CategoryTooLong { kind: c.kind(), len: data.len() })?;
            push16(&mut out, c.kind());
            push16(&mut out, words);
            out.extend_from_slice(&data);
        }
        push16(&mut out, category::END);
        if out.len() > h.eeprom_bytes() {
            return Err(SiiError::ImageTooLarge { len: out.len(), size_word: h.size, eeprom: h.eeprom_bytes() });
        }
        out.resize(h.eeprom_bytes(), 0xFF);
        Ok(out)
    }

    /// The list a category holds, empty when the image has no such category.
    fn slice<T>(&self, pick: fn(&Category) -> Option<&[T]>) -> &[T] {
        self.categories.iter().find_map(pick).unwrap_or(&[])
    }

    /// Vendor id, product code, revision and serial number.
    pub fn identity(&self) -> Identity {
        self.header.identity
    }

    /// The configured station alias (header word 4).
    pub fn alias(&self) -> u16 {
        self.header.configured_station_alias
    }

    /// The strings category's strings (empty without one).
    pub fn strings(&self) -> &[String] {
        self.slice(|c| if let Category::Strings(v) = c { Some(v.as_slice()) } else { None })
    }

    /// String `idx` (1-based); `None` for 0 (no string) or an index past the table.
    pub fn string(&self, idx: u8) -> Option<&str> {
        let i = usize::from(idx).checked_sub(1)?;
        self.strings().get(i).map(String::as_str)
    }

    /// The general category.
    pub fn general(&self) -> Option<&General> {
        self.categories.iter().find_map(|c| if let Category::General(g) = c { Some(g) } else { None })
    }

    /// The device name (general category's name string), e.g. "AKD EtherCAT Drive (CoE)".
    pub fn name(&self) -> Option<&str> {
        self.general().and_then(|g| self.string(g.name_idx))
    }

    /// The group type (general category's group string), e.g. "Drive".
    pub fn group(&self) -> Option<&str> {
        self.general().and_then(|g| self.string(g.group_idx))
    }

    /// The order number (general category's order string), e.g. "AKD".
    pub fn order(&self) -> Option<&str> {
        self.general().and_then(|g| self.string(g.order_idx))
    }

    /// The FMMU usage codes.
    pub fn fmmu_usage(&self) -> &[u8] {
        self.slice(|c| if let Category::Fmmu(v) = c { Some(v.as_slice()) } else { None })
    }

    /// The sync managers, SM0 first.
    pub fn sync_managers(&self) -> &[SyncManager] {
        self.slice(|c| if let Category::SyncManagers(v) = c { Some(v.as_slice()) } else { None })
    }

    /// The TxPDOs (drive to master).
    pub fn tx_pdos(&self) -> &[SiiPdo] {
        self.slice(|c| if let Category::TxPdos(v) = c { Some(v.as_slice()) } else { None })
    }

    /// The RxPDOs (master to drive).
    pub fn rx_pdos(&self) -> &[SiiPdo] {
        self.slice(|c| if let Category::RxPdos(v) = c { Some(v.as_slice()) } else { None })
    }

    /// What this SII assigns to its sync managers of process data (its PDOs that name the first
    /// sync manager of outputs, and of inputs: SM2 and SM3 of a slave with a mailbox, SM0 of a
    /// digital I/O terminal): the process data of a slave no profile describes. With `coe` (the
    /// slave has CoE) and a general category saying it takes a PDO assignment (CoE details bit
    /// 2), the assignment is also written over CoE, as the slave's object dictionary may hold
    /// another one; without, the slave carries what its SII says.
    pub fn process_data(&self, coe: bool) -> ProcessData {
        let over_coe = coe && self.general().is_some_and(|g| g.coe_details & COE_PDO_ASSIGN != 0);
        let assigned = |pdos: &[SiiPdo], direction: Direction| {
            let kind = match direction {
                Direction::Rx => sync_manager_type::PROCESS_DATA_OUT,
                Direction::Tx => sync_manager_type::PROCESS_DATA_IN,
            };
            let sm = self.sync_managers().iter().position(|sm| sm.sm_type == kind);
            PdoAssignment {
                pdos: pdos
                    .iter()
                    .filter(|p| sm.is_some_and(|n| usize::from(p.sync_manager) == n))
                    .map(|p| Pdo { index: p.index, entries: p.entries.iter().map(|e| e.pdo_entry()).collect() })
                    .collect(),
                over_coe,
                write_entries: false,
            }
        };
        ProcessData {
            outputs: assigned(self.rx_pdos(), Direction::Rx),
            inputs: assigned(self.tx_pdos(), Direction::Tx),
        }
    }

    /// The DC operation modes.
    pub fn dc_modes(&self) -> &[DcOpMode] {
        self.slice(|c| if let Category::Dc(v) = c { Some(v.as_slice()) } else { None })
    }

    /// The data of the first category of type `kind` kept raw ([`Category::Other`]): a
    /// manufacturer's own, for its profile to read.
    pub fn other_category(&self, kind: u16) -> Option<&[u8]> {
        self.categories.iter().find_map(|c| match c {
            Category::Other { kind: k, data } if *k == kind => Some(data.as_slice()),
            _ => None,
        })
    }
}

fn encode_pdos(pdos: &[SiiPdo], what: &'static str) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    for p in pdos {
        let count = u8::try_from(p.entries.len()).map_err(|_| SiiError::TooManyEntries {
            what,
            index: p.index,
            count: p.entries.len(),
        })?;
        out.extend_from_slice(&p.index.to_le_bytes());
        out.extend_from_slice(&[count, p.sync_manager, p.dc_sync, p.name_idx]);
        out.extend_from_slice(&p.flags.to_le_bytes());
        for e in &p.entries {
            out.extend_from_slice(&e.index.to_le_bytes());
            out.extend_from_slice(&[e.subindex, e.name_idx, e.data_type, e.bit_len]);
            out.extend_from_slice(&e.flags.to_le_bytes());
        }
    }
    Ok(out)
}

/// A category's data as written, before it is padded to a whole word.
fn encode_category_unpadded(c: &Category) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    match c {
        Category::Strings(strings) => {
            let count = u8::try_from(strings.len())
                .map_err(|_| SiiError::TooManyStrings { count: strings.len(), first_over: None })?;
            out.push(count);
            for s in strings {
                let bytes = latin1_bytes(s, "string")?;
                let len = u8::try_from(bytes.len())
                    .map_err(|_| SiiError::StringTooLong { text: s.clone(), len: bytes.len() })?;
                out.push(len);
                out.extend_from_slice(&bytes);
            }
        }
        Category::General(g) => {
            out.extend_from_slice(&[
                g.group_idx,
                g.image_idx,
                g.order_idx,
                g.name_idx,
                g.reserved_4,
                g.coe_details,
                g.foe_details,
                g.eoe_details,
                g.soe_channels,
                g.ds402_channels,
                g.sysman_class,
                g.flags,
            ]);
            out.extend_from_slice(&g.current_on_ebus.to_le_bytes());
            out.extend_from_slice(&[g.group_idx_2, g.reserved_15]);
            out.extend_from_slice(&g.physical_port.to_le_bytes());
            out.extend_from_slice(&g.physical_memory_address.to_le_bytes());
            out.extend_from_slice(&g.reserved_20);
        }
        Category::Fmmu(usage) => out.extend_from_slice(usage),
        Category::SyncManagers(sms) => {
            for sm in sms {
                out.extend_from_slice(&sm.start_address.to_le_bytes());
                out.extend_from_slice(&sm.length.to_le_bytes());
                out.extend_from_slice(&[sm.control, sm.status, sm.enable, sm.sm_type]);
            }
        }
        Category::TxPdos(pdos) => out = encode_pdos(pdos, "TxPDO")?,
        Category::RxPdos(pdos) => out = encode_pdos(pdos, "RxPDO")?,
        Category::Dc(modes) => {
            for m in modes {
                for v in [m.cycle_time0, m.shift_time0, m.shift_time1] {
                    out.extend_from_slice(&v.to_le_bytes());
                }
                out.extend_from_slice(&m.sync1_cycle_factor.to_le_bytes());
                out.extend_from_slice(&m.assign_activate.to_le_bytes());
                out.extend_from_slice(&m.sync0_cycle_factor.to_le_bytes());
                out.extend_from_slice(&[m.name_idx, m.description_idx]);
                out.extend_from_slice(&m.reserved);
            }
        }
        Category::Other { kind, data } => {
            if data.len() % 2 == 1 {
                return Err(SiiError::OddCategory { kind: *kind, len: data.len() });
            }
            out.extend_from_slice(data);
        }
    }
    Ok(out)
}

/// Writes an image from a description: strings are interned as the description names them,
/// so the strings category lists them in the order first named.
#[derive(Debug)]
pub struct Builder {
    header: Header,
    strings: Vec<String>,
    categories: Vec<Category>,
    strings_at: Option<usize>,
    error: Option<SiiError>,
    padding: u8,
}

impl Builder {
    /// A builder for an image with this header, odd categories padded with 0.
    pub fn new(header: Header) -> Self {
        Builder { header, strings: Vec::new(), categories: Vec::new(), strings_at: None, error: None, padding: 0 }
    }

    /// Pads categories of an odd number of bytes with `byte` (see [`Sii::padding`]).
    pub fn pad_with(&mut self, byte: u8) {
        self.padding = byte;
    }

    /// The 1-based index of `s` in the strings category, adding it if new. More than 255
    /// strings is reported by [`finish`](Self::finish).
    pub fn string(&mut self, s: &str) -> u8 {
        let i = match self.strings.iter().position(|t| t == s) {
            Some(i) => i,
            None => {
                self.strings.push(s.to_owned());
                self.strings.len() - 1
            }
        };
        u8::try_from(i + 1).unwrap_or_else(|_| {
            self.error.get_or_insert_with(|| SiiError::TooManyStrings { count: i + 1, first_over: Some(s.to_owned()) });
            0
        })
    }

    /// Places the strings category here; it holds every string interned before `finish`.
    pub fn strings_here(&mut self) {
        self.strings_at = Some(self.categories.len());
        self.categories.push(Category::Strings(Vec::new()));
    }

    /// Appends a category.
    pub fn push(&mut self, category: Category) {
        self.categories.push(category);
    }

    /// The decoded image.
    pub fn build(mut self) -> Result<Sii> {
        if let Some(e) = self.error {
            return Err(e);
        }
        match self.strings_at {
            Some(i) => self.categories[i] = Category::Strings(self.strings),
            None if !self.strings.is_empty() => return Err(SiiError::NoStringsCategory { count: self.strings.len() }),
            None => {}
        }
        Ok(Sii { header: self.header, categories: self.categories, padding: self.padding })
    }

    /// The encoded image.
    pub fn finish(self) -> Result<Vec<u8>> {
        self.build()?.encode()
    }
}

/// SII EEPROM content (ETG.1000.6 §5.4, ETG.2010) or its EEPROM interface not as expected.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SiiError {
    /// A read inside a category that runs past its end.
    #[error("the {category} category is {len} bytes: reading {read} bytes at byte {at} runs past its end")]
    CategoryOverrun {
        /// The category, e.g. "General".
        category: &'static str,
        /// The category's length in bytes.
        len: usize,
        /// Bytes read.
        read: usize,
        /// Where, in bytes from the category's start.
        at: usize,
    },
    /// A string with a character outside ISO 8859-1, which the SII strings use.
    #[error("{what} {text:?} holds {character:?}, outside ISO 8859-1 (allowed U+0000..=U+00FF)")]
    NotLatin1 {
        /// The string's role.
        what: &'static str,
        /// The string.
        text: String,
        /// The first character outside.
        character: char,
    },
    /// A string of the strings category that runs past its end.
    #[error("string {number} of {count} announces {len} bytes but the strings category has {left} left")]
    StringOverrun {
        /// The string's number, from 1.
        number: usize,
        /// Strings the category announces.
        count: usize,
        /// The string's length.
        len: usize,
        /// Bytes left in the category.
        left: usize,
    },
    /// A category of records whose length is not a multiple of the record's.
    #[error("the {category} category is {len} bytes, not a multiple of its {record}-byte records")]
    NotWholeRecords {
        /// The category.
        category: &'static str,
        /// Its length in bytes.
        len: usize,
        /// One record's length in bytes.
        record: usize,
    },
    /// A PDO announcing more entries than its category holds.
    #[error(
        "{what} 0x{index:04X} announces {count} entries ({} bytes) but the category has {left} bytes left",
        usize::from(*.count) * 8
    )]
    PdoEntriesOverrun {
        /// "TxPDO" or "RxPDO".
        what: &'static str,
        /// The PDO's index.
        index: u16,
        /// Entries announced.
        count: u8,
        /// Bytes left in the category.
        left: usize,
    },
    /// An image shorter than the SII header (words 0..63).
    #[error("image of {len} bytes is shorter than the {header}-byte header")]
    ShortImage {
        /// The image's length.
        len: usize,
        /// The header's length.
        header: usize,
    },
    /// A header checksum (word 7, low byte) that is not the CRC-8 of words 0..6.
    #[error("header checksum (low byte of word 7) is 0x{stored:02X} but the CRC-8 of words 0..6 is 0x{computed:02X}")]
    Checksum {
        /// The checksum in the image.
        stored: u8,
        /// The CRC-8 of words 0..6.
        computed: u8,
    },
    /// No end category (0xFFFF) before the image ends.
    #[error("no end category (0xFFFF) before the end of the {len}-byte image (after {categories} categories)")]
    NoEndCategory {
        /// The image's length.
        len: usize,
        /// Categories read.
        categories: usize,
    },
    /// A category header without its length word.
    #[error("category 0x{kind:04X} at word 0x{word:04X} has no length word")]
    NoLengthWord {
        /// Category type.
        kind: u16,
        /// Where, in words.
        word: usize,
    },
    /// A category that announces more words than the image has left.
    #[error("category 0x{kind:04X} at word 0x{word:04X} announces {words} words but the image has {left} words left")]
    CategoryPastEnd {
        /// Category type.
        kind: u16,
        /// Where, in words.
        word: usize,
        /// Words announced.
        words: usize,
        /// Words left.
        left: usize,
    },
    /// A string number beyond the strings category.
    #[error("{what} names string {index} but the strings category has {count} (allowed 0..={count}, 0 = none)")]
    NoSuchString {
        /// Who names it, e.g. "the General category's name".
        what: String,
        /// The string number.
        index: u8,
        /// Strings in the category.
        count: usize,
    },
    /// A category longer than a length word can announce.
    #[error("category 0x{kind:04X} of {len} bytes exceeds the 65535 words a length word holds")]
    CategoryTooLong {
        /// Category type.
        kind: u16,
        /// Its length in bytes.
        len: usize,
    },
    /// An image larger than the EEPROM its size word announces.
    #[error("the image takes {len} bytes but the size word 0x{size_word:04X} announces an EEPROM of {eeprom} bytes")]
    ImageTooLarge {
        /// The image's length.
        len: usize,
        /// The size word.
        size_word: u16,
        /// The EEPROM's bytes.
        eeprom: usize,
    },
    /// A PDO with more entries than a count byte holds.
    #[error("{what} 0x{index:04X} has {count} entries (allowed 0..=255)")]
    TooManyEntries {
        /// "TxPDO" or "RxPDO".
        what: &'static str,
        /// The PDO's index.
        index: u16,
        /// Entries.
        count: usize,
    },
    /// More strings than a count byte holds.
    #[error(
        "{}",
        match .first_over {
            None => format!("{} strings (allowed 0..=255)", .count),
            Some(text) => format!("more than 255 strings (the 256th is {text:?})"),
        }
    )]
    TooManyStrings {
        /// Strings.
        count: usize,
        /// The first one too many, when known.
        first_over: Option<String>,
    },
    /// A string longer than a length byte holds.
    #[error("string {text:?} is {len} bytes (allowed 0..=255)")]
    StringTooLong {
        /// The string.
        text: String,
        /// Its length in bytes.
        len: usize,
    },
    /// A category of an odd number of bytes.
    #[error("category 0x{kind:04X} has {len} bytes; a category is whole words")]
    OddCategory {
        /// Category type.
        kind: u16,
        /// Its length in bytes.
        len: usize,
    },
    /// Strings interned while building an image, with no strings category placed.
    #[error("{count} strings interned but no strings category placed (call strings_here)")]
    NoStringsCategory {
        /// Strings interned.
        count: usize,
    },
    /// An EEPROM read that the ESC did not acknowledge (SII control/status register 0x0502).
    #[error(
        "station 0x{station:04X}: EEPROM read of word 0x{word:04X} failed (SII control 0x{control:04X}: \
         missing acknowledge)"
    )]
    EepromNack {
        /// Station address.
        station: u16,
        /// The word read.
        word: u32,
        /// SII control/status.
        control: u16,
    },
    /// No end category before the EEPROM ends.
    #[error("station 0x{station:04X}: no end category (0xFFFF) before the end of the {size_kbit} kbit EEPROM")]
    EepromNoEnd {
        /// Station address.
        station: u16,
        /// The EEPROM's size.
        size_kbit: u32,
    },
    /// A category that runs past the EEPROM's end.
    #[error(
        "station 0x{station:04X}: category 0x{kind:04X} at word 0x{word:04X} of {len} words runs past the \
         {size_kbit} kbit EEPROM"
    )]
    EepromCategoryPastEnd {
        /// Station address.
        station: u16,
        /// Category type.
        kind: u16,
        /// Where, in words.
        word: u32,
        /// Its length in words.
        len: u32,
        /// The EEPROM's size.
        size_kbit: u32,
    },
    /// A standard mailbox too small for an SDO message.
    #[error("mailbox of {receive} bytes out and {send} in is smaller than the {min} bytes of an SDO message")]
    MailboxTooSmall {
        /// Receive mailbox (SM0) size.
        receive: u16,
        /// Send mailbox (SM1) size.
        send: u16,
        /// The least an SDO message needs.
        min: u16,
    },
    /// A PDO entry that the AKD's image names nowhere.
    #[error("no name for PDO object 0x{index:04X}:{subindex:02X} in the AKD's image")]
    NoPdoName {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
    },
    /// Any of these, of one slave found by the scan.
    #[error("slave {position} (station 0x{station:04X}): {error}")]
    OfSlave {
        /// Slave position.
        position: u16,
        /// Its station address.
        station: u16,
        /// What is wrong.
        error: Box<SiiError>,
    },
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn header(size: u16, checksum_reserved: u8) -> Header {
        Header {
            pdi_control: 0x0C08,
            pdi_configuration: 0x0800,
            sync_impulse_length: 0,
            pdi_configuration2: 0,
            configured_station_alias: 0x1234,
            reserved_05: [0, 0],
            checksum_reserved,
            identity: Identity { vendor_id: 2, product_code: 0x0444_2752, revision: 1, serial_number: 9 },
            execution_delay: 0,
            port0_delay: 0,
            port1_delay: 0,
            reserved_13: 0,
            bootstrap_mailbox: MailboxLayout::default(),
            standard_mailbox: MailboxLayout {
                receive_offset: 0x1000,
                receive_size: 128,
                send_offset: 0x1080,
                send_size: 128,
            },
            mailbox_protocols: crate::ethercat::mailbox::MailboxType::Coe.sii_protocol_bit(),
            reserved_1d: [0; 33],
            size,
            version: 1,
        }
    }

    #[test]
    fn checksum_sits_in_the_low_byte_of_word_7() {
        let sii = Sii { header: header(1, 0), categories: vec![], padding: 0 };
        let image = sii.encode().unwrap();
        let mut first = [0u8; 14];
        first.copy_from_slice(&image[..14]);
        assert_eq!(image[14], header_checksum(&first));
        assert_eq!(image.len(), 256);
        assert_eq!(Sii::parse(&image).unwrap(), sii);
    }

    #[test]
    fn bad_checksum_is_named() {
        let sii = Sii { header: header(1, 0), categories: vec![], padding: 0 };
        let mut image = sii.encode().unwrap();
        image[0] ^= 1;
        let e = Sii::parse(&image).unwrap_err().to_string();
        assert!(e.contains("checksum"), "{e}");
    }

    #[test]
    fn overrunning_category_and_bad_string_index_are_errors() {
        let mut b = Builder::new(header(3, 0));
        b.strings_here();
        let name = b.string("Inputs");
        b.push(Category::TxPdos(vec![SiiPdo {
            index: 0x1A00,
            sync_manager: 3,
            dc_sync: 0,
            name_idx: name,
            flags: 0,
            entries: vec![SiiPdoEntry::new(0x6041, 0, 2, 6, 16)],
        }]));
        let image = b.finish().unwrap();
        let e = Sii::parse(&image).unwrap_err().to_string();
        assert!(e.contains("TxPDO 0x1A00 entry 0x6041:00 names string 2"), "{e}");

        let mut cut = Sii { header: header(1, 0), categories: vec![], padding: 0 }.encode().unwrap();
        cut[HEADER_BYTES..HEADER_BYTES + 4].copy_from_slice(&[0x0A, 0, 0x40, 0]);
        let e = Sii::parse(&cut).unwrap_err().to_string();
        assert!(e.contains("announces 64 words"), "{e}");
    }

    fn any_category(strings: usize) -> impl Strategy<Value = Category> {
        let idx = 0..=strings as u8;
        let entry = (any::<u16>(), any::<u8>(), idx.clone(), any::<u8>(), any::<u8>(), any::<u16>()).prop_map(
            |(index, subindex, name_idx, data_type, bit_len, flags)| SiiPdoEntry {
                index,
                subindex,
                name_idx,
                data_type,
                bit_len,
                flags,
            },
        );
        let pdo =
            (any::<u16>(), any::<u8>(), any::<u8>(), idx.clone(), any::<u16>(), prop::collection::vec(entry, 0..5))
                .prop_map(|(index, sync_manager, dc_sync, name_idx, flags, entries)| SiiPdo {
                    index,
                    sync_manager,
                    dc_sync,
                    name_idx,
                    flags,
                    entries,
                });
        let sm = (any::<u16>(), any::<u16>(), any::<u8>(), any::<u8>(), any::<u8>(), any::<u8>()).prop_map(
            |(start_address, length, control, status, enable, sm_type)| SyncManager {
                start_address,
                length,
                control,
                status,
                enable,
                sm_type,
            },
        );
        let dc =
            (any::<[u32; 3]>(), any::<i16>(), any::<u16>(), any::<i16>(), idx.clone(), idx.clone(), any::<[u8; 4]>())
                .prop_map(|(t, s1, aa, s0, n, d, reserved)| DcOpMode {
                    cycle_time0: t[0],
                    shift_time0: t[1],
                    shift_time1: t[2],
                    sync1_cycle_factor: s1,
                    assign_activate: aa,
                    sync0_cycle_factor: s0,
                    name_idx: n,
                    description_idx: d,
                    reserved,
                });
        let general =
            (any::<[u8; 16]>(), idx.clone(), idx.clone(), any::<[u8; 12]>()).prop_map(|(b, name, group, r)| General {
                group_idx: group,
                image_idx: 0,
                order_idx: 0,
                name_idx: name,
                reserved_4: b[0],
                coe_details: b[1],
                foe_details: b[2],
                eoe_details: b[3],
                soe_channels: b[4],
                ds402_channels: b[5],
                sysman_class: b[6],
                flags: b[7],
                current_on_ebus: i16::from_le_bytes([b[8], b[9]]),
                group_idx_2: 0,
                reserved_15: b[10],
                physical_port: u16::from_le_bytes([b[11], b[12]]),
                physical_memory_address: u16::from_le_bytes([b[13], b[14]]),
                reserved_20: r,
            });
        prop_oneof![
            general.prop_map(Category::General),
            prop::collection::vec(any::<u8>(), 0..4).prop_map(|mut v| {
                v.resize(v.len().next_multiple_of(2), 0);
                Category::Fmmu(v)
            }),
            prop::collection::vec(sm, 0..5).prop_map(Category::SyncManagers),
            prop::collection::vec(pdo.clone(), 0..4).prop_map(Category::TxPdos),
            prop::collection::vec(pdo, 0..4).prop_map(Category::RxPdos),
            prop::collection::vec(dc, 0..3).prop_map(Category::Dc),
            (0x0100u16..0x0900, prop::collection::vec(any::<u8>(), 0..8)).prop_map(|(kind, mut data)| {
                data.resize(data.len().next_multiple_of(2), 0);
                Category::Other { kind, data }
            }),
        ]
    }

    fn any_sii() -> impl Strategy<Value = Sii> {
        (prop::collection::vec("[ -~\u{a0}-\u{ff}]{0,20}", 0..8), any::<u8>(), any::<u32>())
            .prop_flat_map(|(strings, reserved, serial)| {
                let n = strings.len();
                (Just(strings), Just(reserved), Just(serial), prop::collection::vec(any_category(n), 0..8))
            })
            .prop_map(|(strings, reserved, serial, mut categories)| {
                let mut h = header(0x0F, reserved);
                h.identity.serial_number = serial;
                categories.insert(0, Category::Strings(strings));
                Sii { header: h, categories, padding: 0 }
            })
    }

    proptest! {
        #[test]
        fn parse_never_panics_on_arbitrary_bytes(data in prop::collection::vec(any::<u8>(), 0..600)) {
            let _ = Sii::parse(&data);
        }

        #[test]
        fn parse_never_panics_behind_a_valid_header(tail in prop::collection::vec(any::<u8>(), 0..600)) {
            let mut image = Sii { header: header(0x0F, 0), categories: vec![], padding: 0 }
                .encode()
                .unwrap();
            image.truncate(HEADER_BYTES);
            image.extend_from_slice(&tail);
            let _ = Sii::parse(&image);
        }

        #[test]
        fn encode_then_parse_round_trips(sii in any_sii()) {
            let image = sii.encode().unwrap();
            let back = Sii::parse(&image).unwrap();
            prop_assert_eq!(back.encode().unwrap(), image);
            prop_assert_eq!(back, sii);
        }
    }
}
