//! CoE basic data types (ETG.1000.6 table 64) and their names.

/// BOOLEAN.
pub const BOOLEAN: u16 = 0x0001;
/// INTEGER8.
pub const INTEGER8: u16 = 0x0002;
/// INTEGER16.
pub const INTEGER16: u16 = 0x0003;
/// INTEGER32.
pub const INTEGER32: u16 = 0x0004;
/// UNSIGNED8.
pub const UNSIGNED8: u16 = 0x0005;
/// UNSIGNED16.
pub const UNSIGNED16: u16 = 0x0006;
/// UNSIGNED32.
pub const UNSIGNED32: u16 = 0x0007;
/// REAL32.
pub const REAL32: u16 = 0x0008;
/// VISIBLE_STRING.
pub const VISIBLE_STRING: u16 = 0x0009;
/// OCTET_STRING.
pub const OCTET_STRING: u16 = 0x000A;
/// UNICODE_STRING.
pub const UNICODE_STRING: u16 = 0x000B;
/// DOMAIN.
pub const DOMAIN: u16 = 0x000F;
/// INTEGER24.
pub const INTEGER24: u16 = 0x0010;
/// REAL64.
pub const REAL64: u16 = 0x0011;
/// INTEGER64.
pub const INTEGER64: u16 = 0x0015;
/// UNSIGNED24.
pub const UNSIGNED24: u16 = 0x0016;
/// UNSIGNED64.
pub const UNSIGNED64: u16 = 0x001B;
/// PDO mapping record.
pub const PDO_MAPPING: u16 = 0x0021;
/// Identity record.
pub const IDENTITY: u16 = 0x0023;
/// PDO communication parameter record.
pub const PDO_COMMUNICATION: u16 = 0x0020;
/// Sync manager communication type record (0x1C00).
pub const SM_COMMUNICATION_TYPE: u16 = 0x0029;
/// Sync manager synchronisation record (0x1C32/0x1C33).
pub const SM_SYNCHRONIZATION: u16 = 0x0042;

/// The type's name, e.g. `UNSIGNED16`.
pub fn name(code: u16) -> &'static str {
    match code {
        BOOLEAN => "BOOLEAN",
        INTEGER8 => "INTEGER8",
        INTEGER16 => "INTEGER16",
        INTEGER32 => "INTEGER32",
        UNSIGNED8 => "UNSIGNED8",
        UNSIGNED16 => "UNSIGNED16",
        UNSIGNED32 => "UNSIGNED32",
        REAL32 => "REAL32",
        VISIBLE_STRING => "VISIBLE_STRING",
        OCTET_STRING => "OCTET_STRING",
        UNICODE_STRING => "UNICODE_STRING",
        DOMAIN => "DOMAIN",
        INTEGER24 => "INTEGER24",
        REAL64 => "REAL64",
        INTEGER64 => "INTEGER64",
        UNSIGNED24 => "UNSIGNED24",
        UNSIGNED64 => "UNSIGNED64",
        INTEGER40 => "INTEGER40",
        INTEGER48 => "INTEGER48",
        INTEGER56 => "INTEGER56",
        UNSIGNED40 => "UNSIGNED40",
        UNSIGNED48 => "UNSIGNED48",
        UNSIGNED56 => "UNSIGNED56",
        PDO_MAPPING => "PDO_MAPPING",
        IDENTITY => "IDENTITY",
        PDO_COMMUNICATION => "PDO_COMMUNICATION",
        SM_COMMUNICATION_TYPE => "SM_COMMUNICATION_TYPE",
        SM_SYNCHRONIZATION => "SM_SYNCHRONIZATION",
        _ => "unknown data type",
    }
}

/// Whether values of the type are signed integers (for display and range checks).
pub fn is_signed(code: u16) -> bool {
    matches!(code, INTEGER8 | INTEGER16 | INTEGER24 | INTEGER32 | INTEGER40 | INTEGER48 | INTEGER56 | INTEGER64)
}

/// INTEGER40.
pub const INTEGER40: u16 = 0x0012;
/// INTEGER48.
pub const INTEGER48: u16 = 0x0013;
/// INTEGER56.
pub const INTEGER56: u16 = 0x0014;
/// UNSIGNED40.
pub const UNSIGNED40: u16 = 0x0018;
/// UNSIGNED48.
pub const UNSIGNED48: u16 = 0x0019;
/// UNSIGNED56.
pub const UNSIGNED56: u16 = 0x001A;

/// How a value of a data type reads: the classes a tool shows and checks values by.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ValueKind {
    /// INTEGER8 .. INTEGER64: a two's-complement little-endian number.
    SignedInteger,
    /// BOOLEAN and UNSIGNED8 .. UNSIGNED64: an unsigned little-endian number.
    UnsignedInteger,
    /// REAL32 or REAL64: an IEEE 754 number.
    Real,
    /// VISIBLE_STRING: text, padded with NUL bytes.
    VisibleString,
    /// Anything else (octet strings, domains, records): raw bytes.
    Other,
}

impl ValueKind {
    /// The kind's name as the Python API spells it, e.g. `signed_integer`.
    pub fn name(self) -> &'static str {
        match self {
            ValueKind::SignedInteger => "signed_integer",
            ValueKind::UnsignedInteger => "unsigned_integer",
            ValueKind::Real => "real",
            ValueKind::VisibleString => "visible_string",
            ValueKind::Other => "other",
        }
    }
}

/// How values of the type `code` read.
pub fn kind(code: u16) -> ValueKind {
    match code {
        _ if is_signed(code) => ValueKind::SignedInteger,
        BOOLEAN | UNSIGNED8 | UNSIGNED16 | UNSIGNED24 | UNSIGNED32 | UNSIGNED40 | UNSIGNED48 | UNSIGNED56
        | UNSIGNED64 => ValueKind::UnsignedInteger,
        REAL32 | REAL64 => ValueKind::Real,
        VISIBLE_STRING => ValueKind::VisibleString,
        _ => ValueKind::Other,
    }
}

/// The length of a value of the numeric type `code` in bits (BOOLEAN takes a byte, as the
/// AKD maps and transfers it); `None` for strings, domains and records.
pub fn bit_len(code: u16) -> Option<u16> {
    Some(match code {
        BOOLEAN | INTEGER8 | UNSIGNED8 => 8,
        INTEGER16 | UNSIGNED16 => 16,
        INTEGER24 | UNSIGNED24 => 24,
        INTEGER32 | UNSIGNED32 | REAL32 => 32,
        INTEGER40 | UNSIGNED40 => 40,
        INTEGER48 | UNSIGNED48 => 48,
        INTEGER56 | UNSIGNED56 => 56,
        INTEGER64 | UNSIGNED64 | REAL64 => 64,
        _ => return None,
    })
}
