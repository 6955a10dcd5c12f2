//! The SDO information service (CoE service 8, ETG.1000.6 §5.6.3): OD lists, object and
//! entry descriptions, in fragments.

use super::{write_message, CoeService};
use crate::ethercat::mailbox::MailboxError;

/// Length of the SDO information header (opcode, reserved, fragments left).
pub const SDO_INFO_HEADER_LEN: usize = 4;

wire_codes! {
    /// SDO information opcodes (ETG.1000.6 §5.6.3).
    pub enum SdoInfoOpcode: u8, "SDO information opcode" {
        GetOdListRequest = 0x01 => "Get OD List Request",
        GetOdListResponse = 0x02 => "Get OD List Response",
        GetObjectDescriptionRequest = 0x03 => "Get Object Description Request",
        GetObjectDescriptionResponse = 0x04 => "Get Object Description Response",
        GetEntryDescriptionRequest = 0x05 => "Get Entry Description Request",
        GetEntryDescriptionResponse = 0x06 => "Get Entry Description Response",
        /// SDO information error request (carries an abort code).
        SdoInfoErrorRequest = 0x07 => "SDO Info Error Request",
    }
}

impl SdoInfoOpcode {
    /// The response that answers this request; `None` for what is not a request.
    pub fn response(self) -> Option<SdoInfoOpcode> {
        match self {
            SdoInfoOpcode::GetOdListRequest => Some(SdoInfoOpcode::GetOdListResponse),
            SdoInfoOpcode::GetObjectDescriptionRequest => Some(SdoInfoOpcode::GetObjectDescriptionResponse),
            SdoInfoOpcode::GetEntryDescriptionRequest => Some(SdoInfoOpcode::GetEntryDescriptionResponse),
            _ => None,
        }
    }
}

wire_codes! {
    /// OD list types of a Get OD list request (ETG.1000.6 §5.6.3.3).
    pub enum OdListType: u16, "OD list type" {
        Lengths = 0x00 => "number of objects in the five lists",
        All = 0x01 => "all objects",
        RxPdoMappable = 0x02 => "RxPDO mappable objects",
        TxPdoMappable = 0x03 => "TxPDO mappable objects",
        Backup = 0x04 => "objects to be stored for a device replacement",
        Startup = 0x05 => "startup parameters",
    }
}

/// The SDO information header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SdoInfoHeader {
    /// Opcode.
    pub opcode: SdoInfoOpcode,
    /// More fragments follow.
    pub incomplete: bool,
    /// Fragments still to come after this one.
    pub fragments_left: u16,
}

impl SdoInfoHeader {
    /// Decodes the header at the start of an SDO information body; an opcode outside the
    /// standard's set is an error naming it.
    pub fn decode(body: &[u8]) -> Result<Self, MailboxError> {
        if body.len() < SDO_INFO_HEADER_LEN {
            return Err(MailboxError::Truncated {
                what: "SDO information message",
                len: body.len(),
                needed: SDO_INFO_HEADER_LEN,
            });
        }
        Ok(SdoInfoHeader {
            opcode: SdoInfoOpcode::try_from(body[0] & 0x7F)?,
            incomplete: body[0] & 0x80 != 0,
            fragments_left: u16::from_le_bytes([body[2], body[3]]),
        })
    }

    /// Encodes into the first four bytes of `out`.
    pub fn encode(&self, out: &mut [u8]) {
        out[0] = (self.opcode as u8 & 0x7F) | ((self.incomplete as u8) << 7);
        out[1] = 0;
        out[2..4].copy_from_slice(&self.fragments_left.to_le_bytes());
    }
}

/// Writes an SDO information message carrying `data` after its header; returns the length.
pub fn write_info_message(out: &mut [u8], counter: u8, header: SdoInfoHeader, data: &[u8]) -> usize {
    write_message(out, counter, CoeService::SdoInformation, |b| {
        header.encode(b);
        b[SDO_INFO_HEADER_LEN..SDO_INFO_HEADER_LEN + data.len()].copy_from_slice(data);
        SDO_INFO_HEADER_LEN + data.len()
    })
}

wire_codes! {
    /// Object codes of an object description (ETG.1000.6 Table 43, CiA 301 §7.4.3).
    pub enum ObjectCode: u8, "object code" {
        /// A large variable amount of data.
        Domain = 0x02 => "DOMAIN",
        /// A type definition.
        Deftype = 0x05 => "DEFTYPE",
        /// A record type definition.
        Defstruct = 0x06 => "DEFSTRUCT",
        /// A single value.
        Var = 0x07 => "VAR",
        /// Subindices of one type.
        Array = 0x08 => "ARRAY",
        /// Subindices of different types.
        Record = 0x09 => "RECORD",
    }
}

/// An object description (Get object description response data).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ObjectDescription<'a> {
    /// Object index.
    pub index: u16,
    /// Data type, see [`data_type`](super::data_type).
    pub data_type: u16,
    /// Highest subindex.
    pub max_subindex: u8,
    /// Object code.
    pub object_code: ObjectCode,
    /// Name.
    pub name: &'a str,
}

/// Length of an object description before its name.
pub const OBJECT_DESCRIPTION_FIXED_LEN: usize = 6;
/// Length of an entry description before its optional values and name.
pub const ENTRY_DESCRIPTION_FIXED_LEN: usize = 10;

fn text<'a>(bytes: &'a [u8], what: &'static str) -> Result<&'a str, MailboxError> {
    std::str::from_utf8(bytes).map_err(|_| MailboxError::NotText { what })
}

impl<'a> ObjectDescription<'a> {
    /// Decodes the data of a Get object description response.
    pub fn decode(data: &'a [u8]) -> Result<Self, MailboxError> {
        if data.len() < OBJECT_DESCRIPTION_FIXED_LEN {
            return Err(MailboxError::Truncated {
                what: "object description",
                len: data.len(),
                needed: OBJECT_DESCRIPTION_FIXED_LEN,
            });
        }
        Ok(ObjectDescription {
            index: u16::from_le_bytes([data[0], data[1]]),
            data_type: u16::from_le_bytes([data[2], data[3]]),
            max_subindex: data[4],
            object_code: ObjectCode::try_from(data[5])?,
            name: text(&data[OBJECT_DESCRIPTION_FIXED_LEN..], "object name")?,
        })
    }

    /// Encodes into `out`; returns the length.
    pub fn encode(&self, out: &mut [u8]) -> usize {
        out[0..2].copy_from_slice(&self.index.to_le_bytes());
        out[2..4].copy_from_slice(&self.data_type.to_le_bytes());
        out[4] = self.max_subindex;
        out[5] = self.object_code.into();
        let end = OBJECT_DESCRIPTION_FIXED_LEN + self.name.len();
        out[OBJECT_DESCRIPTION_FIXED_LEN..end].copy_from_slice(self.name.as_bytes());
        end
    }
}

/// Access bits of an entry description.
pub mod access {
    /// Readable in PreOp.
    pub const READ_PREOP: u16 = 0x0001;
    /// Readable in SafeOp.
    pub const READ_SAFEOP: u16 = 0x0002;
    /// Readable in Op.
    pub const READ_OP: u16 = 0x0004;
    /// Writable in PreOp.
    pub const WRITE_PREOP: u16 = 0x0008;
    /// Writable in SafeOp.
    pub const WRITE_SAFEOP: u16 = 0x0010;
    /// Writable in Op.
    pub const WRITE_OP: u16 = 0x0020;
    /// Mappable in an RxPDO.
    pub const RX_PDO: u16 = 0x0040;
    /// Mappable in a TxPDO.
    pub const TX_PDO: u16 = 0x0080;
    /// Readable in every state.
    pub const READ: u16 = READ_PREOP | READ_SAFEOP | READ_OP;
    /// Writable in every state.
    pub const WRITE: u16 = WRITE_PREOP | WRITE_SAFEOP | WRITE_OP;

    /// Each access bit with its name, in bit order.
    pub const NAMES: [(u16, &str); 8] = [
        (READ_PREOP, "read_preop"),
        (READ_SAFEOP, "read_safeop"),
        (READ_OP, "read_op"),
        (WRITE_PREOP, "write_preop"),
        (WRITE_SAFEOP, "write_safeop"),
        (WRITE_OP, "write_op"),
        (RX_PDO, "rx_pdo"),
        (TX_PDO, "tx_pdo"),
    ];

    /// The names of the bits set in `bits`, in bit order.
    pub fn names(bits: u16) -> impl Iterator<Item = &'static str> {
        NAMES.into_iter().filter(move |(bit, _)| bits & bit != 0).map(|(_, name)| name)
    }
}

/// An entry description (Get entry description response data), without the optional
/// unit/default/minimum/maximum values, which the AKD does not send.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EntryDescription<'a> {
    /// Object index.
    pub index: u16,
    /// Subindex.
    pub subindex: u8,
    /// Value information bits the request asked for.
    pub value_info: u8,
    /// Data type, see [`data_type`](super::data_type).
    pub data_type: u16,
    /// Length in bits.
    pub bit_length: u16,
    /// Access bits, see [`access`].
    pub access: u16,
    /// Name.
    pub name: &'a str,
}

impl<'a> EntryDescription<'a> {
    /// Decodes the data of a Get entry description response.
    pub fn decode(data: &'a [u8]) -> Result<Self, MailboxError> {
        if data.len() < ENTRY_DESCRIPTION_FIXED_LEN {
            return Err(MailboxError::Truncated {
                what: "entry description",
                len: data.len(),
                needed: ENTRY_DESCRIPTION_FIXED_LEN,
            });
        }
        Ok(EntryDescription {
            index: u16::from_le_bytes([data[0], data[1]]),
            subindex: data[2],
            value_info: data[3],
            data_type: u16::from_le_bytes([data[4], data[5]]),
            bit_length: u16::from_le_bytes([data[6], data[7]]),
            access: u16::from_le_bytes([data[8], data[9]]),
            name: text(&data[ENTRY_DESCRIPTION_FIXED_LEN..], "entry name")?,
        })
    }

    /// Encodes into `out`; returns the length.
    pub fn encode(&self, out: &mut [u8]) -> usize {
        out[0..2].copy_from_slice(&self.index.to_le_bytes());
        out[2] = self.subindex;
        out[3] = self.value_info;
        out[4..6].copy_from_slice(&self.data_type.to_le_bytes());
        out[6..8].copy_from_slice(&self.bit_length.to_le_bytes());
        out[8..10].copy_from_slice(&self.access.to_le_bytes());
        let end = ENTRY_DESCRIPTION_FIXED_LEN + self.name.len();
        out[ENTRY_DESCRIPTION_FIXED_LEN..end].copy_from_slice(self.name.as_bytes());
        end
    }
}

/// Whether `name`, an object's name in a drive's SDO information, names the AKD parameter
/// `parameter` (e.g. "FBUS.PARAM02") as a word of its own, in any case: "FBUS.PARAM02" and
/// "FBUS.PARAM02 PLL mode" do, "FBUS.PARAM020" or "Sync mode" do not. A master writes or trusts
/// a manufacturer object whose index no manual gives only where the drive names it so.
pub fn names_parameter(name: &str, parameter: &str) -> bool {
    name.split(|c: char| !(c.is_ascii_alphanumeric() || c == '.' || c == '_'))
        .any(|word| word.eq_ignore_ascii_case(parameter))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_name_names_a_parameter_only_as_a_word_of_its_own() {
        for name in ["FBUS.PARAM02", "fbus.param02", "FBUS.PARAM02 PLL mode", "(FBUS.PARAM02)"] {
            assert!(names_parameter(name, "FBUS.PARAM02"), "{name}");
        }
        for name in ["", "FBUS.PARAM020", "FBUS.PARAM03", "XFBUS.PARAM02", "Sync mode", "FBUS PARAM02"] {
            assert!(!names_parameter(name, "FBUS.PARAM02"), "{name}");
        }
    }
}
