//! CoE basic data types (ETG.1000.6 table 64) and their names.

/// Declares the data types as `u16` constants and [`name`] from one list, so that each type's
/// name is written once; a type's documentation ends with its code and name.
macro_rules! data_types {
    ($($(#[$meta:meta])* $name:ident = $value:literal,)+) => {
        $(
            $(#[$meta])*
            #[doc = concat!("`", stringify!($value), "`: ", stringify!($name), ".")]
            pub const $name: u16 = $value;
        )+

        /// The type's name, e.g. `UNSIGNED16`.
        pub fn name(code: u16) -> &'static str {
            match code {
                $($name => stringify!($name),)+
                _ => "unknown data type",
            }
        }
    };
}

data_types! {
    BOOLEAN = 0x0001,
    INTEGER8 = 0x0002,
    INTEGER16 = 0x0003,
    INTEGER32 = 0x0004,
    UNSIGNED8 = 0x0005,
    UNSIGNED16 = 0x0006,
    UNSIGNED32 = 0x0007,
    REAL32 = 0x0008,
    VISIBLE_STRING = 0x0009,
    OCTET_STRING = 0x000A,
    UNICODE_STRING = 0x000B,
    DOMAIN = 0x000F,
    INTEGER24 = 0x0010,
    REAL64 = 0x0011,
    INTEGER40 = 0x0012,
    INTEGER48 = 0x0013,
    INTEGER56 = 0x0014,
    INTEGER64 = 0x0015,
    UNSIGNED24 = 0x0016,
    UNSIGNED40 = 0x0018,
    UNSIGNED48 = 0x0019,
    UNSIGNED56 = 0x001A,
    UNSIGNED64 = 0x001B,
    /// PDO communication parameter record.
    PDO_COMMUNICATION = 0x0020,
    /// PDO mapping record.
    PDO_MAPPING = 0x0021,
    /// Identity record.
    IDENTITY = 0x0023,
    /// Sync manager communication type record (0x1C00).
    SM_COMMUNICATION_TYPE = 0x0029,
    /// Sync manager synchronisation record (0x1C32/0x1C33).
    SM_SYNCHRONIZATION = 0x0042,
}

/// Whether values of the type are signed integers (for display and range checks).
pub fn is_signed(code: u16) -> bool {
    matches!(code, INTEGER8 | INTEGER16 | INTEGER24 | INTEGER32 | INTEGER40 | INTEGER48 | INTEGER56 | INTEGER64)
}

named_variants! {
    /// How a value of a data type reads: the classes a tool shows and checks values by.
    pub enum ValueKind {
        /// INTEGER8 .. INTEGER64: a two's-complement little-endian number.
        SignedInteger => "signed_integer",
        /// BOOLEAN and UNSIGNED8 .. UNSIGNED64: an unsigned little-endian number.
        UnsignedInteger => "unsigned_integer",
        /// REAL32 or REAL64: an IEEE 754 number.
        Real => "real",
        /// VISIBLE_STRING: text, padded with NUL bytes.
        VisibleString => "visible_string",
        /// Anything else (octet strings, domains, records): raw bytes.
        Other => "other",
    }
    /// The kind's name as the Python API spells it, e.g. `signed_integer`.
    fn name;
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
