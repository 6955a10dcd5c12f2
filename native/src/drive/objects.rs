//! The objects the AKD maps into process data, with their CoE data types, and their values read
//! out of a process image by its mapping.
//!
//! [`pdo`] says where a mapped object sits and how many bits it takes; this says what those
//! bits are (signed or not, how wide), so that the master, the virtual AKD's SII image and the
//! Python package read an object the same way, from one table.

use crate::ethercat::coe::data_type;
use crate::ethercat::pdo::{self, PdoEntry};

pub use crate::drive::pdo::{MappableObject, MAPPABLE_OBJECTS};

/// The mappable object at `index:subindex` with its CoE data type, if the AKD maps one of a
/// known type there.
pub fn mappable_object(index: u16, subindex: u8) -> Option<(&'static MappableObject, u16)> {
    MAPPABLE_OBJECTS
        .iter()
        .filter(|o| (o.entry.index, o.entry.subindex) == (index, subindex))
        .find_map(|o| Some((o, o.data_type?)))
}

/// The value of `index:subindex` in `image`, a drive's process data laid out by `entries`
/// (outputs or inputs, in wire order), read as its data type: sign-extended for a signed type,
/// an object of no known type as unsigned. `None` when the mapping lacks the object or the
/// image is shorter than the mapping.
pub fn read(entries: &[PdoEntry], image: &[u8], index: u16, subindex: u8) -> Option<i64> {
    let (at, entry) = pdo::find(entries, index, subindex)?;
    let bytes = image.get(at..at + entry.byte_len())?;
    let raw = bytes.iter().rev().fold(0u64, |v, b| (v << 8) | *b as u64);
    let bits = u32::from(entry.bits).min(64);
    let signed = mappable_object(index, subindex).is_some_and(|(_, code)| data_type::is_signed(code));
    Some(if signed && (1..64).contains(&bits) {
        // Shift the sign bit to the top and back: an arithmetic shift extends it.
        ((raw << (64 - bits)) as i64) >> (64 - bits)
    } else {
        raw as i64
    })
}

/// Where a drive's actual position is, in the order looked for: position actual value 0x6064,
/// else the internal value 0x6063 (which the fixed mapping 0x1B01 carries instead).
pub const POSITION_ACTUAL: [(u16, u8); 2] = [(0x6064, 0), (0x6063, 0)];

/// What one drive's inputs say in one cycle, read by its mapping with each object's data type:
/// each value `None` where the mapping lacks its object. The values a caller of one axis shows
/// every cycle (`Cycle.drive_inputs` in Python).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "python", pyo3::pyclass(module = "akd_ros._native", frozen, get_all))]
pub struct DriveInputs {
    /// The cycle they are from (from 1; 0 where not read from a cycle's snapshot).
    pub cycle: u64,
    /// That cycle's wake-up time on the monotonic clock (ns).
    pub time_ns: u64,
    /// Whether that cycle's exchange succeeded (else they are the last good ones).
    pub fresh: bool,
    /// Statusword 0x6041.
    pub statusword: Option<u16>,
    /// Modes of operation display 0x6061.
    pub mode_display: Option<i8>,
    /// Actual position in counts: 0x6064, else the internal value 0x6063 ([`POSITION_ACTUAL`]).
    pub position_actual: Option<i32>,
    /// Velocity actual value 0x606C, counts/s.
    pub velocity_actual: Option<i32>,
    /// Torque actual value 0x6077, 0.1 % of peak torque.
    pub torque_actual: Option<i16>,
    /// Following error actual value 0x60F4, counts.
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
            position_actual: POSITION_ACTUAL
                .iter()
                .find_map(|&(index, subindex)| read(entries, inputs, index, subindex))
                .map(|v| v as i32),
            velocity_actual: value(0x606C).map(|v| v as i32),
            torque_actual: value(0x6077).map(|v| v as i16),
            following_error: value(0x60F4).map(|v| v as i32),
            digital_inputs: value(0x60FD).map(|v| v as u32),
            ..DriveInputs::default()
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
                object.entry.index,
                object.entry.subindex,
                object.name,
                object.data_type.map_or("no CoE type", data_type::name)
            ),
        }
    }
}

impl std::error::Error for EncodeError {}

/// `value` as mappable object `index:subindex` holds it: little-endian in its data type's
/// length, after checking it is within the type's range.
pub fn encode(index: u16, subindex: u8, value: i64) -> Result<Vec<u8>, EncodeError> {
    let (object, code) = mappable_object(index, subindex).ok_or(EncodeError::NotMappable { index, subindex })?;
    // Every typed mappable object is an integer of at most 32 bits (see the tests), so the range fits an i64.
    let bits = u32::from(data_type::bit_len(code).unwrap_or(32));
    let (min, max) = if data_type::is_signed(code) {
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
    use crate::ethercat::coe::data_type::*;
    use crate::sim::od::ObjectDictionary;

    /// The typed objects, as (object, data type).
    fn typed() -> impl Iterator<Item = (&'static MappableObject, u16)> {
        MAPPABLE_OBJECTS.iter().filter_map(|o| Some((o, o.data_type?)))
    }

    #[test]
    fn every_mappable_object_has_its_type_with_the_bits_it_is_mapped_with() {
        for o in MAPPABLE_OBJECTS {
            let Some(code) = o.data_type else {
                let e = o.entry;
                assert!(
                    [(0x3470, 0, 16), (0x60E4, 0, 48)].contains(&(e.index, e.subindex, e.bits)),
                    "0x{:04X}:{:02X} has no type",
                    e.index,
                    e.subindex
                );
                continue;
            };
            assert_eq!(data_type::bit_len(code), Some(o.entry.bits.into()), "{}", o.name);
            assert_eq!(mappable_object(o.entry.index, o.entry.subindex), Some((o, code)), "{}", o.name);
        }
    }

    #[test]
    fn the_types_agree_with_the_virtual_akds_dictionary() {
        let od = ObjectDictionary::default();
        for (o, code) in typed() {
            let PdoEntry { index, subindex, .. } = o.entry;
            let entry = od.object(index).and_then(|object| object.entry(subindex));
            let entry = entry.unwrap_or_else(|| panic!("the virtual AKD lacks 0x{index:04X}:{subindex:02X}"));
            assert_eq!(entry.data_type, code, "0x{index:04X}:{subindex:02X} {}", o.name);
            assert_eq!(Some(entry.bits), data_type::bit_len(code), "{}", o.name);
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
                ..DriveInputs::default()
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
        for (o, code) in typed() {
            assert!(data_type::bit_len(code).is_some_and(|bits| bits <= 32), "{}", o.name);
        }
        // What encode writes, read reads back, for every object at both ends of its range.
        for (o, code) in typed() {
            let PdoEntry { index, subindex, .. } = o.entry;
            let bits = data_type::bit_len(code).unwrap() as u8;
            let entries = [PdoEntry::new(index, subindex, bits)];
            let (min, max) = match encode(index, subindex, i64::MIN).unwrap_err() {
                EncodeError::OutOfRange { min, max, .. } => (min, max),
                other => panic!("{other}"),
            };
            for value in [min, max, 0] {
                let image = encode(index, subindex, value).unwrap();
                assert_eq!(read(&entries, &image, index, subindex), Some(value), "{}", o.name);
            }
        }
    }
}
