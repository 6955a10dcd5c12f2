//! The AKD's process-data mappings (AKD manual §5.5–5.7, and the real drive's SII).
//!
//! Fixed mappings are whole PDOs the drive defines (0x1701.., 0x1B01..) and selects through
//! the sync-manager assignment objects 0x1C12 (outputs, RxPDO) and 0x1C13 (inputs, TxPDO).
//! Flexible mappings are built in 0x1600–0x1603 and 0x1A00–0x1A03 under the AKD's rules, which
//! [`check_flexible`] applies, so that a mapping is refused before the master writes anything
//! ([`Mapping::process_data`]) and the virtual AKD refuses it as the drive does.
//!
//! Where the manual and the real drive differ, the real drive's SII wins: 0x1B01 carries the
//! internal position 0x6063, digital outputs 0x60FE:01 are 32 bits, and 0x1725/0x1B26 exist.

use crate::ethercat::coe::data_type::{INTEGER16, INTEGER32, INTEGER8, UNSIGNED16, UNSIGNED32};
use crate::ethercat::coe::SdoAbortCode;
use crate::ethercat::pdo::{bit_len, Direction, Pdo, PdoAssignment, PdoEntry, ProcessData};
use std::fmt;

/// Number of flexible mapping objects per direction (0x1600–0x1603, 0x1A00–0x1A03).
pub const FLEXIBLE_PDO_COUNT: usize = 4;
/// Largest flexible PDO, in bytes.
pub const MAX_FLEXIBLE_PDO_BYTES: usize = 8;
/// Largest flexible set-point image, in bytes.
pub const MAX_RX_BYTES: usize = 22;
/// Largest flexible actual-value image, in bytes.
pub const MAX_TX_BYTES: usize = 32;
/// Dummy object that pads an RxPDO (8 bits, subindex 0).
pub const RX_PADDING_INDEX: u16 = 0x0002;
/// Manufacturer status object whose subindices 1..4 pad a TxPDO.
pub const TX_PADDING_INDEX: u16 = 0x2002;

/// Where the AKD's ESC holds its sync managers' buffers, as its SII gives them: process data
/// out (SM2) and in (SM3), at most 64 bytes each, and the mailbox out (SM0) and in (SM1).
pub const AKD_PROCESS_OUT: u16 = 0x1100;
/// SM3's buffer.
pub const AKD_PROCESS_IN: u16 = 0x1140;
/// SM0's buffer.
pub const AKD_MAILBOX_OUT: u16 = 0x1800;
/// SM1's buffer.
pub const AKD_MAILBOX_IN: u16 = 0x1C00;

/// A fixed mapping the drive defines.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FixedPdo {
    /// The mapping object, e.g. 0x1701.
    pub index: u16,
    /// Which way it carries data.
    pub direction: Direction,
    /// Its entries in wire order.
    pub entries: &'static [PdoEntry],
}

const CONTROLWORD: PdoEntry = PdoEntry::new(0x6040, 0, 16);
const STATUSWORD: PdoEntry = PdoEntry::new(0x6041, 0, 16);
const IP_SETPOINT: PdoEntry = PdoEntry::new(0x60C1, 1, 32);
const TARGET_POSITION: PdoEntry = PdoEntry::new(0x607A, 0, 32);
const TARGET_VELOCITY: PdoEntry = PdoEntry::new(0x60FF, 0, 32);
const LATCH_CONTROLWORD: PdoEntry = PdoEntry::new(0x20A4, 0, 16);
const TORQUE_OFFSET: PdoEntry = PdoEntry::new(0x60B2, 0, 16);
const PHYSICAL_OUTPUTS: PdoEntry = PdoEntry::new(0x60FE, 1, 32);
const MAX_TORQUE: PdoEntry = PdoEntry::new(0x6072, 0, 16);
const CLEAR_INPUT_CHANGED: PdoEntry = PdoEntry::new(0x20B8, 0, 16);
const ANALOG_OUTPUT: PdoEntry = PdoEntry::new(0x3470, 3, 16);
const POSITION_INTERNAL: PdoEntry = PdoEntry::new(0x6063, 0, 32);
const POSITION_ACTUAL: PdoEntry = PdoEntry::new(0x6064, 0, 32);
const SECOND_FEEDBACK: PdoEntry = PdoEntry::new(0x2050, 0, 32);
const VELOCITY_ACTUAL: PdoEntry = PdoEntry::new(0x606C, 0, 32);
const DIGITAL_INPUTS: PdoEntry = PdoEntry::new(0x60FD, 0, 32);
const FOLLOWING_ERROR: PdoEntry = PdoEntry::new(0x60F4, 0, 32);
const TORQUE_ACTUAL: PdoEntry = PdoEntry::new(0x6077, 0, 16);
const LATCH_STATUSWORD: PdoEntry = PdoEntry::new(0x20A5, 0, 16);
const ANALOG_INPUT: PdoEntry = PdoEntry::new(0x3470, 4, 16);

const fn rx(index: u16, entries: &'static [PdoEntry]) -> FixedPdo {
    FixedPdo { index, direction: Direction::Rx, entries }
}

const fn tx(index: u16, entries: &'static [PdoEntry]) -> FixedPdo {
    FixedPdo { index, direction: Direction::Tx, entries }
}

/// The inputs of 0x1B20, 0x1B22, 0x1B23 and 0x1B25, which differ in their third entry
/// (velocity or latch 2's position) and their sixth (a latched position).
const fn latched(third: PdoEntry, latch: PdoEntry) -> [PdoEntry; 10] {
    [
        POSITION_INTERNAL,
        SECOND_FEEDBACK,
        third,
        DIGITAL_INPUTS,
        FOLLOWING_ERROR,
        latch,
        STATUSWORD,
        TORQUE_ACTUAL,
        LATCH_STATUSWORD,
        ANALOG_INPUT,
    ]
}

/// Every fixed mapping of the real drive (firmware 01-20-00-003), outputs then inputs.
pub const FIXED: &[FixedPdo] = &[
    rx(0x1701, &[IP_SETPOINT, CONTROLWORD]),
    rx(0x1702, &[TARGET_VELOCITY, CONTROLWORD]),
    rx(0x1720, &[CONTROLWORD, IP_SETPOINT, LATCH_CONTROLWORD, TORQUE_OFFSET, PHYSICAL_OUTPUTS]),
    rx(0x1721, &[IP_SETPOINT, CONTROLWORD, TORQUE_OFFSET]),
    rx(0x1722, &[CONTROLWORD, IP_SETPOINT, LATCH_CONTROLWORD, TORQUE_OFFSET, PHYSICAL_OUTPUTS, MAX_TORQUE]),
    rx(0x1723, &[CONTROLWORD, IP_SETPOINT, LATCH_CONTROLWORD, TORQUE_OFFSET, PHYSICAL_OUTPUTS, CLEAR_INPUT_CHANGED]),
    rx(0x1724, &[TARGET_POSITION, CONTROLWORD, TORQUE_OFFSET]),
    rx(0x1725, &[CONTROLWORD, TARGET_POSITION, PHYSICAL_OUTPUTS, TORQUE_OFFSET, ANALOG_OUTPUT, MAX_TORQUE]),
    tx(0x1B01, &[POSITION_INTERNAL, STATUSWORD]),
    tx(0x1B20, &latched(VELOCITY_ACTUAL, PdoEntry::new(0x20A0, 0, 32))),
    tx(0x1B21, &[POSITION_INTERNAL, STATUSWORD]),
    tx(0x1B22, &latched(VELOCITY_ACTUAL, PdoEntry::new(0x20A1, 0, 32))),
    tx(0x1B23, &latched(VELOCITY_ACTUAL, PdoEntry::new(0x20A6, 0, 32))),
    tx(0x1B24, &[POSITION_ACTUAL, STATUSWORD]),
    tx(0x1B25, &latched(PdoEntry::new(0x20A7, 0, 32), PdoEntry::new(0x20A6, 0, 32))),
    tx(0x1B26, &[STATUSWORD, POSITION_ACTUAL, TORQUE_ACTUAL, DIGITAL_INPUTS, ANALOG_INPUT, FOLLOWING_ERROR]),
];

/// The fixed mapping at `index`, if the drive has one.
pub fn fixed(index: u16) -> Option<&'static FixedPdo> {
    FIXED.iter().find(|p| p.index == index)
}

/// The fixed mappings the manual names as the default selection (0x1701 and 0x1B01).
pub const DEFAULT_FIXED: (u16, u16) = (0x1701, 0x1B01);

/// The flexible mapping the real drive reports at power-up (from the SOEM capture): four
/// RxPDOs and four TxPDOs of 17 bytes each way, which the drive itself refuses in SafeOp
/// because the length is odd.
pub const POWER_UP_RX: [&[PdoEntry]; FLEXIBLE_PDO_COUNT] = [
    &[CONTROLWORD],
    &[CONTROLWORD, PdoEntry::new(0x6060, 0, 8)],
    &[CONTROLWORD, TARGET_POSITION],
    &[CONTROLWORD, TARGET_VELOCITY],
];

/// TxPDO counterpart of [`POWER_UP_RX`].
pub const POWER_UP_TX: [&[PdoEntry]; FLEXIBLE_PDO_COUNT] = [
    &[STATUSWORD],
    &[STATUSWORD, PdoEntry::new(0x6061, 0, 8)],
    &[STATUSWORD, POSITION_ACTUAL],
    &[STATUSWORD, VELOCITY_ACTUAL],
];

/// One object the AKD can map cyclically (§5.7): the direction it travels, its entry with the
/// bit length the drive maps it with, its name as the drive's SII gives it, and its CoE data
/// type — `None` for the two the manual lists with lengths of no CoE type (0x3470:00 with 16
/// bits, 0x60E4:00 with 48). The one table of mappable objects: the mapping rules, the virtual
/// AKD's dictionary and SII, and reading values from a process image all use it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MappableObject {
    /// RxPDO (outputs) or TxPDO (inputs).
    pub direction: Direction,
    /// Index, subindex and mapped bit length.
    pub entry: PdoEntry,
    /// Name.
    pub name: &'static str,
    /// CoE data type code, where the object has one.
    pub data_type: Option<u16>,
}

const fn output(entry: PdoEntry, name: &'static str, data_type: Option<u16>) -> MappableObject {
    MappableObject { direction: Direction::Rx, entry, name, data_type }
}

const fn input(entry: PdoEntry, name: &'static str, data_type: Option<u16>) -> MappableObject {
    MappableObject { direction: Direction::Tx, entry, name, data_type }
}

/// Every object the AKD maps, outputs first, in the manual's order.
pub const MAPPABLE_OBJECTS: &[MappableObject] = &[
    output(IP_SETPOINT, "1st set-point", Some(INTEGER32)),
    output(TARGET_VELOCITY, "Target velocity", Some(INTEGER32)),
    output(CONTROLWORD, "Controlword", Some(UNSIGNED16)),
    output(LATCH_CONTROLWORD, "Latch controlword", Some(UNSIGNED16)),
    output(TORQUE_OFFSET, "Torque offset", Some(INTEGER16)),
    output(PHYSICAL_OUTPUTS, "Physical outputs", Some(UNSIGNED32)),
    output(PdoEntry::new(0x2071, 0, 32), "Current command", Some(INTEGER32)),
    output(PdoEntry::new(0x6060, 0, 8), "Modes of operation", Some(INTEGER8)),
    output(PdoEntry::new(0x606D, 0, 16), "Velocity window", Some(UNSIGNED16)),
    output(PdoEntry::new(0x606E, 0, 16), "Velocity window time", Some(UNSIGNED16)),
    output(PdoEntry::new(0x6071, 0, 16), "Target torque", Some(INTEGER16)),
    output(MAX_TORQUE, "Max torque", Some(UNSIGNED16)),
    output(PdoEntry::new(0x6081, 0, 32), "Profile velocity", Some(UNSIGNED32)),
    output(PdoEntry::new(0x6083, 0, 32), "Profile acceleration", Some(UNSIGNED32)),
    output(PdoEntry::new(0x6084, 0, 32), "Profile deceleration", Some(UNSIGNED32)),
    output(PdoEntry::new(0x60B1, 0, 32), "Velocity offset", Some(INTEGER32)),
    output(PdoEntry::new(0x60B8, 0, 16), "Touch probe function", Some(UNSIGNED16)),
    output(ANALOG_OUTPUT, "AOUT.VALUE write", Some(INTEGER16)),
    output(PdoEntry::new(0x3497, 0, 32), "Position offset", Some(INTEGER32)),
    output(CLEAR_INPUT_CHANGED, "ClearDigInputChangedBit", Some(UNSIGNED16)),
    output(TARGET_POSITION, "Target position", Some(INTEGER32)),
    input(POSITION_INTERNAL, "Position actual internal value", Some(INTEGER32)),
    input(VELOCITY_ACTUAL, "Velocity actual value", Some(INTEGER32)),
    input(STATUSWORD, "Statusword", Some(UNSIGNED16)),
    input(SECOND_FEEDBACK, "Second position feedback", Some(INTEGER32)),
    input(DIGITAL_INPUTS, "Digital inputs", Some(UNSIGNED32)),
    input(FOLLOWING_ERROR, "Following error actual value", Some(INTEGER32)),
    input(PdoEntry::new(0x20A0, 0, 32), "Latch 1p", Some(INTEGER32)),
    input(TORQUE_ACTUAL, "Torque actual value", Some(INTEGER16)),
    input(LATCH_STATUSWORD, "Latch statusword", Some(UNSIGNED16)),
    input(PdoEntry::new(0x3470, 0, 16), "Analog I/O", None),
    input(ANALOG_INPUT, "AIN.VALUE", Some(INTEGER16)),
    input(PdoEntry::new(0x2077, 0, 32), "Current actual value", Some(INTEGER32)),
    input(PdoEntry::new(0x20A1, 0, 32), "Latch 1n", Some(INTEGER32)),
    input(PdoEntry::new(0x20A2, 0, 32), "Latch 2p", Some(INTEGER32)),
    input(PdoEntry::new(0x20A3, 0, 32), "Latch 2n", Some(INTEGER32)),
    input(PdoEntry::new(0x20A6, 0, 32), "Latch 1 pn", Some(INTEGER32)),
    input(PdoEntry::new(0x20A7, 0, 32), "Latch 2 pn", Some(INTEGER32)),
    input(PdoEntry::new(0x6061, 0, 8), "Modes of operation display", Some(INTEGER8)),
    input(POSITION_ACTUAL, "Position actual value", Some(INTEGER32)),
    input(PdoEntry::new(0x60B9, 0, 16), "Touch probe status", Some(UNSIGNED16)),
    input(PdoEntry::new(0x60BA, 0, 32), "Touch probe pos1 pos value", Some(INTEGER32)),
    input(PdoEntry::new(0x60BB, 0, 32), "Touch probe pos1 neg value", Some(INTEGER32)),
    input(PdoEntry::new(0x60BC, 0, 32), "Touch probe pos2 pos value", Some(INTEGER32)),
    input(PdoEntry::new(0x60BD, 0, 32), "Touch probe pos2 neg value", Some(INTEGER32)),
    input(PdoEntry::new(0x60E4, 0, 48), "Additional position actual value", None),
    input(PdoEntry::new(0x60E4, 1, 32), "1st additional position actual value", Some(INTEGER32)),
    input(PdoEntry::new(0x3427, 3, 32), "Feedback position 3", Some(UNSIGNED32)),
    input(PdoEntry::new(0x3470, 2, 16), "AOUT.VALUE", Some(INTEGER16)),
    input(PdoEntry::new(0x1002, 0, 32), "Manufacturer status register", Some(UNSIGNED32)),
];

/// Whether `entry` pads (0x0002 on outputs, 0x2002:01..04 on inputs): it occupies bits but
/// carries no object.
pub const fn is_padding(entry: PdoEntry) -> bool {
    entry.index == RX_PADDING_INDEX || entry.index == TX_PADDING_INDEX
}

/// Largest process image the AKD accepts in `direction`, in bytes.
pub const fn max_bytes(direction: Direction) -> usize {
    match direction {
        Direction::Rx => MAX_RX_BYTES,
        Direction::Tx => MAX_TX_BYTES,
    }
}

/// The padding entries a flexible PDO may carry, per direction (not objects of the drive).
const RX_PADDING: &[PdoEntry] = &[PdoEntry::new(RX_PADDING_INDEX, 0, 8)];
const TX_PADDING: &[PdoEntry] = &[
    PdoEntry::new(TX_PADDING_INDEX, 1, 8),
    PdoEntry::new(TX_PADDING_INDEX, 2, 8),
    PdoEntry::new(TX_PADDING_INDEX, 3, 8),
    PdoEntry::new(TX_PADDING_INDEX, 4, 8),
];

/// What a flexible PDO of `direction` may carry: the drive's objects of that direction and the
/// padding entries.
pub fn mappable(direction: Direction) -> impl Iterator<Item = PdoEntry> {
    let padding = match direction {
        Direction::Rx => RX_PADDING,
        Direction::Tx => TX_PADDING,
    };
    MAPPABLE_OBJECTS.iter().filter(move |o| o.direction == direction).map(|o| o.entry).chain(padding.iter().copied())
}

/// Whether `entry` (with its bit length) may go in a flexible PDO of `direction`.
pub fn is_mappable(direction: Direction, entry: PdoEntry) -> bool {
    mappable(direction).any(|e| e == entry)
}

/// A process-data mapping the AKD refuses (AKD manual §5.6, §5.7): each variant is one of the
/// drive's rules, and [`abort_code`](PdoError::abort_code) the SDO abort code the drive answers
/// the offending write with.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PdoError {
    /// An entry the AKD does not map in this direction, or not with this bit length.
    NotMappable {
        /// "RxPDO" or "TxPDO".
        direction: &'static str,
        /// The PDO's index.
        pdo: u16,
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// Bit length asked for.
        bits: u8,
    },
    /// A flexible PDO of more bytes than the AKD takes in one.
    PdoTooLong {
        /// "RxPDO" or "TxPDO".
        direction: &'static str,
        /// The PDO's index.
        pdo: u16,
        /// Its bytes.
        bytes: usize,
        /// The most one PDO holds.
        max: usize,
    },
    /// More flexible PDOs assigned than the AKD takes.
    TooManyPdos {
        /// "RxPDO" or "TxPDO".
        direction: &'static str,
        /// PDOs assigned.
        count: usize,
        /// The most the AKD takes.
        max: usize,
    },
    /// An index that is not one of the flexible PDOs of this direction.
    NotFlexible {
        /// "RxPDO" or "TxPDO".
        direction: &'static str,
        /// The index.
        index: u16,
        /// The first flexible PDO.
        first: u16,
        /// The last flexible PDO.
        last: u16,
    },
    /// A mapping of more bytes than the AKD's process image of this direction holds.
    MappingTooLong {
        /// "RxPDO" or "TxPDO".
        direction: &'static str,
        /// Its bytes.
        bytes: usize,
        /// The most the AKD takes.
        max: usize,
    },
    /// A mapping of an odd number of bytes, which the AKD refuses at SafeOp.
    OddLength {
        /// "RxPDO" or "TxPDO".
        direction: &'static str,
        /// Its bits.
        bits: usize,
        /// The entry that pads it.
        padding: &'static str,
    },
    /// An index that is not one of the AKD's fixed mappings of this direction.
    NotFixed {
        /// "RxPDO" or "TxPDO".
        direction: &'static str,
        /// The index.
        index: u16,
        /// The fixed mappings of this direction.
        allowed: Vec<u16>,
    },
}

impl fmt::Display for PdoError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PdoError::NotMappable { direction, pdo, index, subindex, bits } => write!(
                f,
                "0x{index:04X}:{subindex:02X} with {bits} bits cannot be mapped in {direction} 0x{pdo:04X} (see AKD \
                 manual §5.7 for the mappable objects)"
            ),
            PdoError::PdoTooLong { direction, pdo, bytes, max } => {
                write!(f, "{direction} 0x{pdo:04X} holds {bytes} bytes; a flexible PDO holds at most {max}")
            }
            PdoError::TooManyPdos { direction, count, max } => {
                write!(f, "{count} {direction} PDOs assigned; the AKD takes at most {max}")
            }
            PdoError::NotFlexible { direction, index, first, last } => {
                write!(f, "0x{index:04X} is not a flexible {direction} (allowed 0x{first:04X}..=0x{last:04X})")
            }
            PdoError::MappingTooLong { direction, bytes, max } => {
                write!(f, "{direction} mapping of {bytes} bytes exceeds the AKD's {max} bytes")
            }
            PdoError::OddLength { direction, bits, padding } => write!(
                f,
                "{direction} mapping of {bits} bits has an odd byte length, which the AKD refuses; pad it with {padding}"
            ),
            PdoError::NotFixed { direction, index, allowed } => {
                write!(f, "0x{index:04X} is not a fixed {direction} of the AKD (allowed: ")?;
                for (i, a) in allowed.iter().enumerate() {
                    write!(f, "{}0x{a:04X}", if i == 0 { "" } else { ", " })?;
                }
                write!(f, ")")
            }
        }
    }
}

impl std::error::Error for PdoError {}

impl PdoError {
    /// The SDO abort code the AKD answers the write that breaks this rule with; `None` where no
    /// single write breaks it (a mapping this master refuses before writing anything).
    pub fn abort_code(&self) -> Option<SdoAbortCode> {
        match self {
            PdoError::NotMappable { .. } => Some(SdoAbortCode::NOT_MAPPABLE),
            PdoError::PdoTooLong { .. } | PdoError::MappingTooLong { .. } => Some(SdoAbortCode::PDO_TOO_LONG),
            PdoError::TooManyPdos { .. } | PdoError::NotFlexible { .. } => Some(SdoAbortCode::VALUE_RANGE),
            PdoError::OddLength { .. } => Some(SdoAbortCode::PARAMETER_INCOMPATIBLE),
            PdoError::NotFixed { .. } => None,
        }
    }
}

/// Checks one flexible PDO's entries: each mappable in this direction with its real bit
/// length, and the PDO at most 8 bytes.
pub fn check_flexible_pdo(direction: Direction, pdo_index: u16, entries: &[PdoEntry]) -> Result<(), PdoError> {
    for entry in entries {
        if !is_mappable(direction, *entry) {
            return Err(PdoError::NotMappable {
                direction: direction.name(),
                pdo: pdo_index,
                index: entry.index,
                subindex: entry.subindex,
                bits: entry.bits,
            });
        }
    }
    let bits = bit_len(entries);
    if bits > MAX_FLEXIBLE_PDO_BYTES * 8 {
        return Err(PdoError::PdoTooLong {
            direction: direction.name(),
            pdo: pdo_index,
            bytes: bits / 8,
            max: MAX_FLEXIBLE_PDO_BYTES,
        });
    }
    Ok(())
}

/// Checks a whole flexible mapping of one direction: at most four PDOs from 0x1600/0x1A00
/// upwards, each valid, the total within 22 (Rx) or 32 (Tx) bytes and of even length.
pub fn check_flexible(direction: Direction, pdos: &[(u16, &[PdoEntry])]) -> Result<(), PdoError> {
    if pdos.len() > FLEXIBLE_PDO_COUNT {
        return Err(PdoError::TooManyPdos { direction: direction.name(), count: pdos.len(), max: FLEXIBLE_PDO_COUNT });
    }
    let base = direction.flexible_base();
    for (index, entries) in pdos {
        if !(base..base + FLEXIBLE_PDO_COUNT as u16).contains(index) {
            return Err(PdoError::NotFlexible {
                direction: direction.name(),
                index: *index,
                first: base,
                last: base + FLEXIBLE_PDO_COUNT as u16 - 1,
            });
        }
        check_flexible_pdo(direction, *index, entries)?;
    }
    let bits: usize = pdos.iter().map(|(_, e)| bit_len(e)).sum();
    if bits > max_bytes(direction) * 8 {
        return Err(PdoError::MappingTooLong {
            direction: direction.name(),
            bytes: bits / 8,
            max: max_bytes(direction),
        });
    }
    if !bits.is_multiple_of(16) {
        let padding = match direction {
            Direction::Rx => "0x0002:00 (8 bits)",
            Direction::Tx => "one of 0x2002:01..04 (8 bits)",
        };
        return Err(PdoError::OddLength { direction: direction.name(), bits, padding });
    }
    Ok(())
}

/// An AKD's mapping of one direction.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Mapping {
    /// A fixed mapping of the drive, e.g. 0x1701 or 0x1B01.
    Fixed(u16),
    /// Up to four flexible PDOs, each a list of entries, written to 0x1600.. or 0x1A00...
    Flexible(Vec<Vec<PdoEntry>>),
}

impl Mapping {
    /// What the master assigns to the drive for this mapping in `direction`, after checking that
    /// the mapping fits `direction` and the AKD's rules. Both kinds are assigned over CoE, as the
    /// real drive requires (it keeps its odd power-up mapping otherwise).
    pub fn assignment(&self, direction: Direction) -> Result<PdoAssignment, PdoError> {
        match self {
            Mapping::Fixed(index) => match fixed(*index) {
                Some(fixed) if fixed.direction == direction => Ok(PdoAssignment {
                    pdos: vec![Pdo { index: *index, entries: fixed.entries.to_vec() }],
                    over_coe: true,
                    write_entries: false,
                }),
                _ => Err(PdoError::NotFixed {
                    direction: direction.name(),
                    index: *index,
                    allowed: FIXED.iter().filter(|p| p.direction == direction).map(|p| p.index).collect(),
                }),
            },
            Mapping::Flexible(pdos) => {
                let pdos: Vec<Pdo> = pdos
                    .iter()
                    .enumerate()
                    .map(|(i, entries)| Pdo { index: direction.flexible_base() + i as u16, entries: entries.clone() })
                    .collect();
                let indexed: Vec<(u16, &[PdoEntry])> = pdos.iter().map(|p| (p.index, p.entries.as_slice())).collect();
                check_flexible(direction, &indexed)?;
                Ok(PdoAssignment { pdos, over_coe: true, write_entries: true })
            }
        }
    }

    /// The entries in wire order, after the checks of [`assignment`](Self::assignment).
    pub fn entries(&self, direction: Direction) -> Result<Vec<PdoEntry>, PdoError> {
        Ok(self.assignment(direction)?.entries().collect())
    }

    /// An AKD's process data with outputs `rx` and inputs `tx`, both checked before the master
    /// writes anything.
    pub fn process_data(rx: &Mapping, tx: &Mapping) -> Result<ProcessData, PdoError> {
        Ok(ProcessData { outputs: rx.assignment(Direction::Rx)?, inputs: tx.assignment(Direction::Tx)? })
    }
}

/// akd_ros's default mapping, outputs: everything every mode of operation needs within the
/// AKD's flexible limits (22 bytes out, 32 in, 8 per PDO). Controlword, interpolation set-point
/// 0x60C1:01, modes of operation 0x6060, padding | target velocity 0x60FF, target torque 0x6071,
/// latch controlword | target position 0x607A (which the real drive maps flexibly: its power-up
/// mapping has it). Unlike [`DEFAULT_FIXED`], the manual's default, it carries every mode's
/// command, so a mode change needs no new mapping.
pub const DEFAULT_RX: [&[PdoEntry]; 3] = [
    &[CONTROLWORD, IP_SETPOINT, MODES_OF_OPERATION, PdoEntry::new(RX_PADDING_INDEX, 0, 8)],
    &[TARGET_VELOCITY, TARGET_TORQUE, LATCH_CONTROLWORD],
    &[TARGET_POSITION],
];

/// Inputs of akd_ros's default mapping (see [`DEFAULT_RX`]): statusword, modes of operation
/// display, padding, position actual 0x6064 | velocity actual, torque actual, latch statusword
/// | following error, latch 1 position 0x20A6 | latch 2 position 0x20A7, digital inputs 0x60FD.
pub const DEFAULT_TX: [&[PdoEntry]; 4] = [
    &[STATUSWORD, MODES_OF_OPERATION_DISPLAY, PdoEntry::new(TX_PADDING_INDEX, 1, 8), POSITION_ACTUAL],
    &[VELOCITY_ACTUAL, TORQUE_ACTUAL, LATCH_STATUSWORD],
    &[FOLLOWING_ERROR, LATCH_1_POSITION],
    &[LATCH_2_POSITION, DIGITAL_INPUTS],
];

/// akd_ros's mapping with the drive's own I/O (the node's `mapping: io`), outputs: the default's
/// commands but interpolated position's 0x60C1:01, whose four bytes and the two left over carry
/// the digital outputs 0x60FE:01 and the analog output set-point 0x3470:03 — 22 bytes, the
/// AKD's most. Controlword, modes of operation, padding, target position 0x607A | target
/// velocity, target torque, latch controlword | digital outputs, analog output.
pub const IO_RX: [&[PdoEntry]; 3] = [
    &[CONTROLWORD, MODES_OF_OPERATION, PdoEntry::new(RX_PADDING_INDEX, 0, 8), TARGET_POSITION],
    &[TARGET_VELOCITY, TARGET_TORQUE, LATCH_CONTROLWORD],
    &[PHYSICAL_OUTPUTS, ANALOG_OUTPUT],
];

/// Inputs of the mapping with the drive's I/O (see [`IO_RX`]): the default's, with the digital
/// inputs 0x60FD and the analog input 0x3470:04 in place of latch 2's position 0x20A7 (latch 1
/// keeps 0x20A6): statusword, modes of operation display, padding, position actual | velocity
/// actual, torque actual, latch statusword | following error, latch 1 position | digital
/// inputs, analog input — 30 bytes.
pub const IO_TX: [&[PdoEntry]; 4] = [
    &[STATUSWORD, MODES_OF_OPERATION_DISPLAY, PdoEntry::new(TX_PADDING_INDEX, 1, 8), POSITION_ACTUAL],
    &[VELOCITY_ACTUAL, TORQUE_ACTUAL, LATCH_STATUSWORD],
    &[FOLLOWING_ERROR, LATCH_1_POSITION],
    &[DIGITAL_INPUTS, ANALOG_INPUT],
];

/// A flexible mapping of akd_ros's own: its name, its RxPDOs and its TxPDOs.
pub type NamedMapping = (&'static str, &'static [&'static [PdoEntry]], &'static [&'static [PdoEntry]]);

/// akd_ros's own flexible mappings by the name the node's `mapping` parameter gives them.
pub const NAMED: [NamedMapping; 2] = [("default", &DEFAULT_RX, &DEFAULT_TX), ("io", &IO_RX, &IO_TX)];

const MODES_OF_OPERATION: PdoEntry = PdoEntry::new(0x6060, 0, 8);
const MODES_OF_OPERATION_DISPLAY: PdoEntry = PdoEntry::new(0x6061, 0, 8);
const TARGET_TORQUE: PdoEntry = PdoEntry::new(0x6071, 0, 16);
const LATCH_1_POSITION: PdoEntry = PdoEntry::new(0x20A6, 0, 32);
const LATCH_2_POSITION: PdoEntry = PdoEntry::new(0x20A7, 0, 32);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::pdo::{find, layout};

    #[test]
    fn fixed_mappings_resolve_in_their_direction_only() {
        assert_eq!(Mapping::Fixed(0x1701).entries(Direction::Rx).unwrap().len(), 2);
        let err = Mapping::Fixed(0x1701).entries(Direction::Tx).unwrap_err().to_string();
        assert!(err.contains("0x1B01") && err.contains("not a fixed TxPDO"), "{err}");
        assert!(Mapping::Fixed(0x1234).entries(Direction::Rx).is_err());
    }

    #[test]
    fn odd_flexible_mapping_is_refused_before_writing() {
        let odd = Mapping::Flexible(vec![vec![PdoEntry::new(0x6040, 0, 16), PdoEntry::new(0x6060, 0, 8)]]);
        let err = odd.entries(Direction::Rx).unwrap_err().to_string();
        assert!(err.contains("odd") && err.contains("0x0002"), "{err}");
        let padded = Mapping::Flexible(vec![vec![
            PdoEntry::new(0x6040, 0, 16),
            PdoEntry::new(0x6060, 0, 8),
            PdoEntry::new(0x0002, 0, 8),
        ]]);
        assert_eq!(padded.entries(Direction::Rx).unwrap().len(), 3);
    }

    #[test]
    fn fixed_mappings_match_the_manual() {
        let velocity = fixed(0x1702).unwrap();
        assert_eq!(velocity.entries.iter().map(|e| e.to_u32()).collect::<Vec<_>>(), vec![0x60FF0020, 0x60400010]);
        assert_eq!(bit_len(fixed(0x1701).unwrap().entries) / 8, 6);
        assert_eq!(bit_len(fixed(0x1B01).unwrap().entries) / 8, 6);
        assert_eq!(bit_len(fixed(0x1B20).unwrap().entries) / 8, 32);
        assert_eq!(bit_len(fixed(0x1720).unwrap().entries) / 8, 14);
        assert!(fixed(0x1704).is_none());
        for p in FIXED {
            assert!(bit_len(p.entries) / 8 <= 64, "0x{:04X} exceeds the 64-byte SM buffer", p.index);
        }
    }

    #[test]
    fn the_power_up_mapping_is_refused_for_its_odd_length() {
        let pdos: Vec<(u16, &[PdoEntry])> =
            POWER_UP_RX.iter().enumerate().map(|(i, e)| (0x1600 + i as u16, *e)).collect();
        let refused = check_flexible(Direction::Rx, &pdos).unwrap_err();
        assert!(refused.to_string().contains("odd"), "{refused}");
        assert_eq!(bit_len(&POWER_UP_RX.concat()), 17 * 8);
    }

    #[test]
    fn flexible_rules() {
        let ok: &[PdoEntry] = &[CONTROLWORD, IP_SETPOINT];
        assert!(check_flexible(Direction::Rx, &[(0x1600, ok)]).is_ok());
        let padded: &[PdoEntry] = &[CONTROLWORD, PdoEntry::new(0x6060, 0, 8), PdoEntry::new(0x0002, 0, 8)];
        assert!(check_flexible(Direction::Rx, &[(0x1600, padded)]).is_ok());
        let too_long: &[PdoEntry] = &[CONTROLWORD, IP_SETPOINT, TARGET_VELOCITY];
        assert_eq!(
            check_flexible(Direction::Rx, &[(0x1600, too_long)]).unwrap_err().abort_code(),
            Some(SdoAbortCode::PDO_TOO_LONG)
        );
        let wrong_way: &[PdoEntry] = &[STATUSWORD];
        assert_eq!(
            check_flexible(Direction::Rx, &[(0x1600, wrong_way)]).unwrap_err().abort_code(),
            Some(SdoAbortCode::NOT_MAPPABLE)
        );
        assert!(check_flexible(Direction::Rx, &[(0x1A00, ok)]).is_err());
        let full: &[PdoEntry] = &[TARGET_POSITION, TARGET_VELOCITY];
        let over: Vec<(u16, &[PdoEntry])> = (0..3).map(|i| (0x1600 + i, full)).collect();
        assert!(check_flexible(Direction::Rx, &over).unwrap_err().to_string().contains("22"));
    }

    #[test]
    fn layout_gives_byte_offsets() {
        let offsets: Vec<usize> = layout(fixed(0x1720).unwrap().entries.iter().copied()).map(|(o, _)| o).collect();
        assert_eq!(offsets, vec![0, 2, 6, 8, 10]);
    }

    #[test]
    fn the_default_mapping_is_one_the_akd_takes_and_carries_every_modes_command() {
        for (direction, pdos) in [(Direction::Rx, &DEFAULT_RX[..]), (Direction::Tx, &DEFAULT_TX[..])] {
            let indexed: Vec<(u16, &[PdoEntry])> =
                pdos.iter().enumerate().map(|(i, e)| (direction.flexible_base() + i as u16, *e)).collect();
            assert_eq!(check_flexible(direction, &indexed), Ok(()), "{}", direction.name());
        }
        let rx: Vec<PdoEntry> = DEFAULT_RX.concat();
        for mode in crate::drive::ds402::Mode::ALL {
            if let Some(&(index, subindex)) = mode.command_objects().first() {
                assert!(rx.iter().any(|e| (e.index, e.subindex) == (index, subindex)), "{}", mode.name());
            }
        }
        let inputs = crate::drive::objects::DriveInputs::read(&DEFAULT_TX.concat(), &[0; MAX_TX_BYTES]);
        assert_eq!(
            inputs,
            crate::drive::objects::DriveInputs {
                statusword: Some(0),
                mode_display: Some(0),
                position_actual: Some(0),
                velocity_actual: Some(0),
                torque_actual: Some(0),
                following_error: Some(0),
                digital_inputs: Some(0),
                ..Default::default()
            },
            "the default inputs carry every value an axis shows"
        );
    }

    #[test]
    fn the_io_mapping_is_one_the_akd_takes_and_fills_the_outputs() {
        for (name, rx, tx) in NAMED {
            for (direction, pdos) in [(Direction::Rx, rx), (Direction::Tx, tx)] {
                let indexed: Vec<(u16, &[PdoEntry])> =
                    pdos.iter().enumerate().map(|(i, e)| (direction.flexible_base() + i as u16, *e)).collect();
                assert_eq!(check_flexible(direction, &indexed), Ok(()), "{name} {}", direction.name());
            }
        }
        assert_eq!(bit_len(&IO_RX.concat()) / 8, MAX_RX_BYTES);
        let rx = IO_RX.concat();
        for mode in crate::drive::ds402::Mode::ALL {
            let carried = mode.command_objects().iter().all(|&(i, s)| find(&rx, i, s).is_some());
            assert_eq!(carried, mode != crate::drive::ds402::Mode::InterpolatedPosition, "{}", mode.name());
        }
    }
}
