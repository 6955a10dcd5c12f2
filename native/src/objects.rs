//! The objects the AKD maps into process data, with their CoE data types, and their values read
//! out of a process image by its mapping.
//!
//! [`pdo`] says where a mapped object sits and how many bits it takes; this says what those
//! bits are (signed or not, how wide), so that the master, the virtual AKD's SII image and the
//! Python package read an object the same way, from one table.

use crate::coe::data_type::{self, *};
use crate::pdo::{self, PdoEntry};

/// One object the AKD can map: its address, its name as the drive's SII gives it, and its
/// CoE data type (see [`data_type`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MappableObject {
    /// Object index.
    pub index: u16,
    /// Subindex.
    pub subindex: u8,
    /// Name.
    pub name: &'static str,
    /// CoE data type code.
    pub data_type: u16,
}

const fn object(index: u16, subindex: u8, name: &'static str, data_type: u16) -> MappableObject {
    MappableObject { index, subindex, name, data_type }
}

/// Every object of [`pdo::MAPPABLE_RX`] and [`pdo::MAPPABLE_TX`] but the padding entries and
/// the two the manual lists with lengths of no CoE type (0x3470:00 with 16 bits, 0x60E4:00 with
/// 48), outputs first.
pub const MAPPABLE_OBJECTS: &[MappableObject] = &[
    object(0x60C1, 1, "1st set-point", INTEGER32),
    object(0x60FF, 0, "Target velocity", INTEGER32),
    object(0x6040, 0, "Controlword", UNSIGNED16),
    object(0x20A4, 0, "Latch controlword", UNSIGNED16),
    object(0x60B2, 0, "Torque offset", INTEGER16),
    object(0x60FE, 1, "Physical outputs", UNSIGNED32),
    object(0x2071, 0, "Current command", INTEGER32),
    object(0x6060, 0, "Modes of operation", INTEGER8),
    object(0x606D, 0, "Velocity window", UNSIGNED16),
    object(0x606E, 0, "Velocity window time", UNSIGNED16),
    object(0x6071, 0, "Target torque", INTEGER16),
    object(0x6072, 0, "Max torque", UNSIGNED16),
    object(0x6081, 0, "Profile velocity", UNSIGNED32),
    object(0x6083, 0, "Profile acceleration", UNSIGNED32),
    object(0x6084, 0, "Profile deceleration", UNSIGNED32),
    object(0x60B1, 0, "Velocity offset", INTEGER32),
    object(0x60B8, 0, "Touch probe function", UNSIGNED16),
    object(0x3470, 3, "AOUT.VALUE write", INTEGER16),
    object(0x3497, 0, "Position offset", INTEGER32),
    object(0x20B8, 0, "ClearDigInputChangedBit", UNSIGNED16),
    object(0x607A, 0, "Target position", INTEGER32),
    object(0x6063, 0, "Position actual internal value", INTEGER32),
    object(0x606C, 0, "Velocity actual value", INTEGER32),
    object(0x6041, 0, "Statusword", UNSIGNED16),
    object(0x2050, 0, "Second position feedback", INTEGER32),
    object(0x60FD, 0, "Digital inputs", UNSIGNED32),
    object(0x60F4, 0, "Following error actual value", INTEGER32),
    object(0x20A0, 0, "Latch 1p", INTEGER32),
    object(0x6077, 0, "Torque actual value", INTEGER16),
    object(0x20A5, 0, "Latch statusword", UNSIGNED16),
    object(0x3470, 4, "AIN.VALUE", INTEGER16),
    object(0x2077, 0, "Current actual value", INTEGER32),
    object(0x20A1, 0, "Latch 1n", INTEGER32),
    object(0x20A2, 0, "Latch 2p", INTEGER32),
    object(0x20A3, 0, "Latch 2n", INTEGER32),
    object(0x20A6, 0, "Latch 1 pn", INTEGER32),
    object(0x20A7, 0, "Latch 2 pn", INTEGER32),
    object(0x6061, 0, "Modes of operation display", INTEGER8),
    object(0x6064, 0, "Position actual value", INTEGER32),
    object(0x60B9, 0, "Touch probe status", UNSIGNED16),
    object(0x60BA, 0, "Touch probe pos1 pos value", INTEGER32),
    object(0x60BB, 0, "Touch probe pos1 neg value", INTEGER32),
    object(0x60BC, 0, "Touch probe pos2 pos value", INTEGER32),
    object(0x60BD, 0, "Touch probe pos2 neg value", INTEGER32),
    object(0x60E4, 1, "1st additional position actual value", INTEGER32),
    object(0x3427, 3, "Feedback position 3", UNSIGNED32),
    object(0x3470, 2, "AOUT.VALUE", INTEGER16),
    object(0x1002, 0, "Manufacturer status register", UNSIGNED32),
];

/// The mappable object at `index:subindex`, if the AKD has one.
pub fn mappable_object(index: u16, subindex: u8) -> Option<&'static MappableObject> {
    MAPPABLE_OBJECTS.iter().find(|o| (o.index, o.subindex) == (index, subindex))
}

/// The value of `index:subindex` in `image`, a drive's process data laid out by `entries`
/// (outputs or inputs, in wire order), read as its data type: sign-extended for a signed type,
/// an object of no known type as unsigned. `None` when the mapping lacks the object or the
/// image is shorter than the mapping.
pub fn read(entries: &[PdoEntry], image: &[u8], index: u16, subindex: u8) -> Option<i64> {
    let (at, entry) = pdo::layout(entries.iter().copied()).find(|(_, e)| (e.index, e.subindex) == (index, subindex))?;
    let bytes = image.get(at..at + entry.byte_len())?;
    let raw = bytes.iter().rev().fold(0u64, |v, b| (v << 8) | *b as u64);
    let bits = u32::from(entry.bits).min(64);
    let signed = mappable_object(index, subindex).is_some_and(|o| data_type::is_signed(o.data_type));
    Some(if signed && (1..64).contains(&bits) {
        // Shift the sign bit to the top and back: an arithmetic shift extends it.
        ((raw << (64 - bits)) as i64) >> (64 - bits)
    } else {
        raw as i64
    })
}

/// What one drive's inputs say, read by its mapping: each value `None` where the mapping lacks
/// its object. The values a caller of one axis shows every cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DriveInputs {
    /// Statusword 0x6041.
    pub statusword: Option<u16>,
    /// Modes of operation display 0x6061.
    pub mode_display: Option<i8>,
    /// Actual position in counts: position actual value 0x6064, else the internal value 0x6063
    /// (which the fixed mapping 0x1B01 carries instead).
    pub position_actual: Option<i32>,
    /// Velocity actual value 0x606C.
    pub velocity_actual: Option<i32>,
    /// Torque actual value 0x6077.
    pub torque_actual: Option<i16>,
    /// Following error actual value 0x60F4.
    pub following_error: Option<i32>,
    /// Digital inputs 0x60FD.
    pub digital_inputs: Option<u32>,
}

impl DriveInputs {
    /// Reads a drive's `inputs` laid out by its TxPDO `entries`.
    pub fn read(entries: &[PdoEntry], inputs: &[u8]) -> DriveInputs {
        let value = |index: u16| read(entries, inputs, index, 0);
        DriveInputs {
            statusword: value(0x6041).map(|v| v as u16),
            mode_display: value(0x6061).map(|v| v as i8),
            position_actual: value(0x6064).or_else(|| value(0x6063)).map(|v| v as i32),
            velocity_actual: value(0x606C).map(|v| v as i32),
            torque_actual: value(0x6077).map(|v| v as i16),
            following_error: value(0x60F4).map(|v| v as i32),
            digital_inputs: value(0x60FD).map(|v| v as u32),
        }
    }
}

/// Why a value cannot be written to an object as its data type.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum EncodeError {
    /// The object is none the AKD maps, so its type is not known here.
    NotMappable {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
    },
    /// The value is outside the data type's range.
    OutOfRange {
        /// The object.
        object: MappableObject,
        /// The value given.
        value: i64,
        /// The lowest value the type holds.
        min: i64,
        /// The highest.
        max: i64,
    },
}

impl std::fmt::Display for EncodeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            EncodeError::NotMappable { index, subindex } => {
                write!(f, "0x{index:04X}:{subindex:02X} is no object the AKD maps, so its data type is not known")
            }
            EncodeError::OutOfRange { object, value, min, max } => write!(
                f,
                "{value} is outside the range of 0x{:04X}:{:02X} {} ({}: {min}..={max})",
                object.index,
                object.subindex,
                object.name,
                data_type::name(object.data_type)
            ),
        }
    }
}

impl std::error::Error for EncodeError {}

/// `value` as mappable object `index:subindex` holds it: little-endian in its data type's
/// length, after checking it is within the type's range.
pub fn encode(index: u16, subindex: u8, value: i64) -> Result<Vec<u8>, EncodeError> {
    let object = mappable_object(index, subindex).ok_or(EncodeError::NotMappable { index, subindex })?;
    // Every mappable object is an integer of at most 32 bits (see the tests), so the range fits an i64.
    let bits = u32::from(data_type::bit_len(object.data_type).unwrap_or(32));
    let (min, max) = if data_type::is_signed(object.data_type) {
        (-(1i64 << (bits - 1)), (1i64 << (bits - 1)) - 1)
    } else {
        (0, (1i64 << bits) - 1)
    };
    if !(min..=max).contains(&value) {
        return Err(EncodeError::OutOfRange { object: *object, value, min, max });
    }
    Ok(value.to_le_bytes()[..bits as usize / 8].to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pdo::Direction;
    use crate::sim::od::ObjectDictionary;

    #[test]
    fn every_mappable_entry_has_its_type_with_the_bits_it_is_mapped_with() {
        for direction in [Direction::Rx, Direction::Tx] {
            for entry in pdo::mappable(direction).iter().filter(|e| !e.is_padding()) {
                let Some(object) = mappable_object(entry.index, entry.subindex) else {
                    assert!(
                        [(0x3470, 0, 16), (0x60E4, 0, 48)].contains(&(entry.index, entry.subindex, entry.bits)),
                        "0x{:04X}:{:02X} has no type",
                        entry.index,
                        entry.subindex
                    );
                    continue;
                };
                assert_eq!(data_type::bit_len(object.data_type), Some(entry.bits.into()), "{}", object.name);
            }
        }
        let listed = pdo::MAPPABLE_RX.len() + pdo::MAPPABLE_TX.len();
        let padding = pdo::MAPPABLE_RX.iter().chain(pdo::MAPPABLE_TX).filter(|e| e.is_padding()).count();
        assert_eq!(MAPPABLE_OBJECTS.len(), listed - padding - 2, "an object the mappable tables do not list");
    }

    #[test]
    fn the_types_agree_with_the_virtual_akds_dictionary() {
        let od = ObjectDictionary::default();
        for o in MAPPABLE_OBJECTS {
            let entry = od.object(o.index).and_then(|object| object.entry(o.subindex));
            let entry = entry.unwrap_or_else(|| panic!("the virtual AKD lacks 0x{:04X}:{:02X}", o.index, o.subindex));
            assert_eq!(entry.data_type, o.data_type, "0x{:04X}:{:02X} {}", o.index, o.subindex, o.name);
            assert_eq!(Some(entry.bits), data_type::bit_len(o.data_type), "{}", o.name);
        }
    }

    #[test]
    fn values_read_with_their_sign_and_width() {
        let tx = [
            PdoEntry::new(0x6041, 0, 16),
            PdoEntry::new(0x6061, 0, 8),
            PdoEntry::new(0x2002, 1, 8),
            PdoEntry::new(0x6063, 0, 32),
            PdoEntry::new(0x6077, 0, 16),
            PdoEntry::new(0x60FD, 0, 32),
        ];
        let mut image = Vec::new();
        image.extend_from_slice(&0x8237u16.to_le_bytes());
        image.push(-3i8 as u8);
        image.push(0xFF);
        image.extend_from_slice(&(-123_456i32).to_le_bytes());
        image.extend_from_slice(&(-300i16).to_le_bytes());
        image.extend_from_slice(&0x8001_0000u32.to_le_bytes());
        assert_eq!(read(&tx, &image, 0x6041, 0), Some(0x8237), "UNSIGNED16 keeps its top bit");
        assert_eq!(read(&tx, &image, 0x2002, 1), Some(0xFF));
        assert_eq!(read(&tx, &image, 0x6064, 0), None);
        assert_eq!(read(&tx, &image[..4], 0x6063, 0), None, "the image is shorter than the mapping");
        let inputs = DriveInputs::read(&tx, &image);
        assert_eq!(
            inputs,
            DriveInputs {
                statusword: Some(0x8237),
                mode_display: Some(-3),
                position_actual: Some(-123_456),
                velocity_actual: None,
                torque_actual: Some(-300),
                following_error: None,
                digital_inputs: Some(0x8001_0000),
            }
        );
    }

    #[test]
    fn position_actual_prefers_0x6064_to_the_internal_value() {
        let tx = [PdoEntry::new(0x6063, 0, 32), PdoEntry::new(0x6064, 0, 32)];
        let image = [1i32.to_le_bytes(), 2i32.to_le_bytes()].concat();
        assert_eq!(DriveInputs::read(&tx, &image).position_actual, Some(2));
    }

    #[test]
    fn value_kinds_and_lengths_cover_the_numeric_types() {
        use data_type::ValueKind;
        assert_eq!(data_type::kind(INTEGER40), ValueKind::SignedInteger);
        assert_eq!(data_type::kind(BOOLEAN), ValueKind::UnsignedInteger);
        assert_eq!(data_type::kind(REAL64), ValueKind::Real);
        assert_eq!(data_type::kind(VISIBLE_STRING), ValueKind::VisibleString);
        assert_eq!(data_type::kind(DOMAIN), ValueKind::Other);
        for code in 0..0x40 {
            let numeric = matches!(
                data_type::kind(code),
                ValueKind::SignedInteger | ValueKind::UnsignedInteger | ValueKind::Real
            );
            assert_eq!(numeric, data_type::bit_len(code).is_some(), "{}", data_type::name(code));
            if numeric {
                assert_ne!(data_type::name(code), "unknown data type", "0x{code:04X}");
            }
        }
    }

    #[test]
    fn values_encode_in_their_types_length_and_range() {
        assert_eq!(encode(0x6071, 0, -2), Ok(vec![0xFE, 0xFF]));
        assert_eq!(encode(0x607A, 0, i32::MIN.into()), Ok(i32::MIN.to_le_bytes().to_vec()));
        assert_eq!(encode(0x6040, 0, 0xFFFF), Ok(vec![0xFF, 0xFF]));
        assert_eq!(encode(0x6060, 0, -1), Ok(vec![0xFF]));
        let refused = encode(0x6071, 0, 40_000).unwrap_err();
        assert_eq!(
            refused.to_string(),
            "40000 is outside the range of 0x6071:00 Target torque (INTEGER16: -32768..=32767)"
        );
        assert!(matches!(encode(0x6040, 0, -1), Err(EncodeError::OutOfRange { min: 0, max: 0xFFFF, .. })));
        assert_eq!(encode(0x1234, 5, 0), Err(EncodeError::NotMappable { index: 0x1234, subindex: 5 }));
        for o in MAPPABLE_OBJECTS {
            assert!(data_type::bit_len(o.data_type).is_some_and(|bits| bits <= 32), "{}", o.name);
        }
        // What encode writes, read reads back, for every object at both ends of its range.
        for o in MAPPABLE_OBJECTS {
            let bits = data_type::bit_len(o.data_type).unwrap() as u8;
            let entries = [PdoEntry::new(o.index, o.subindex, bits)];
            let (min, max) = match encode(o.index, o.subindex, i64::MIN).unwrap_err() {
                EncodeError::OutOfRange { min, max, .. } => (min, max),
                other => panic!("{other}"),
            };
            for value in [min, max, 0] {
                let image = encode(o.index, o.subindex, value).unwrap();
                assert_eq!(read(&entries, &image, o.index, o.subindex), Some(value), "{}", o.name);
            }
        }
    }
}
