//! The virtual AKD's CANopen object dictionary: the objects the AKD manual (§5.5–5.14) and the
//! real drive's SII name, with their data types, access rights and value checks.
//!
//! Values are stored as little-endian bytes, as SDO and process data carry them. The DS402,
//! motion and latch objects are stored values here that the drive firmware
//! (the drive module beside it) reads and updates. Checks that involve more than
//! one entry (a PDO mapping, the cycle time) are object checks run after a tentative write,
//! which is undone when the check refuses it.

use crate::drive::pdo::{self, FLEXIBLE_PDO_COUNT};
use crate::drive::scaling;
use crate::ethercat::coe::{access, data_type, ObjectCode, SdoAbortCode};
use crate::ethercat::pdo::{bit_len, Direction, PdoEntry};
use crate::ethercat::sii::Identity;
use crate::sim::sii_image;

/// Power-up following error window 0x6065: five revolutions.
pub const FOLLOWING_ERROR_WINDOW: u32 = 5 << 20;
/// Power-up profile velocity 0x6081: 10 rev/s.
pub const PROFILE_VELOCITY: u32 = 10 << 20;
/// Power-up profile acceleration, deceleration and quick stop deceleration (0x6083, 0x6084,
/// 0x6085): 100 rev/s².
pub const PROFILE_ACCELERATION: u32 = 100 << 20;

/// Checks a value about to be written to one entry; returns the SDO abort code on refusal.
pub type ValueCheck = fn(&[u8]) -> Result<(), SdoAbortCode>;
/// Checks a whole object after a write; returns the SDO abort code on refusal.
pub type ObjectCheck = fn(&ObjectDictionary, &Object, u8) -> Result<(), SdoAbortCode>;

/// One subindex of an object.
#[derive(Clone, Debug)]
pub struct Entry {
    /// Subindex.
    pub subindex: u8,
    /// Name, as the SII or the manual gives it.
    pub name: &'static str,
    /// CoE data type, see [`data_type`].
    pub data_type: u16,
    /// Length in bits (of the current value, for strings).
    pub bits: u16,
    /// Access bits, see [`access`].
    pub access: u16,
    /// Current value, little-endian.
    pub value: Vec<u8>,
    /// Check of a value written by SDO.
    pub check: Option<ValueCheck>,
}

/// One object: a variable, an array or a record.
#[derive(Clone, Debug)]
pub struct Object {
    /// Index.
    pub index: u16,
    /// Name.
    pub name: &'static str,
    /// Object code.
    pub object_code: ObjectCode,
    /// Data type of the object (of its entries for a VAR or ARRAY).
    pub data_type: u16,
    /// Entries, by subindex order.
    pub entries: Vec<Entry>,
    /// Check of the object after an entry was written.
    pub check: Option<ObjectCheck>,
}

impl Object {
    /// The entry at `subindex`.
    pub fn entry(&self, subindex: u8) -> Option<&Entry> {
        self.entries.iter().find(|e| e.subindex == subindex)
    }

    /// Highest subindex.
    pub fn max_subindex(&self) -> u8 {
        self.entries.last().map_or(0, |e| e.subindex)
    }

    /// The value of `subindex` as an unsigned number (0 when absent).
    pub fn unsigned(&self, subindex: u8) -> u64 {
        self.entry(subindex).map_or(0, |e| little_endian(&e.value))
    }
}

fn little_endian(bytes: &[u8]) -> u64 {
    bytes.iter().take(8).rev().fold(0, |v, b| (v << 8) | *b as u64)
}

/// Access of an entry that is read and written in every state.
const RW: u16 = access::READ | access::WRITE;
/// Access of an entry that is written only in PreOp (PDO mapping and assignment).
pub(crate) const RW_PREOP: u16 = access::READ | access::WRITE_PREOP;
/// Access of a read-only entry.
pub(crate) const RO: u16 = access::READ;

pub(crate) fn entry(subindex: u8, name: &'static str, data_type: u16, bits: u16, access: u16, value: u64) -> Entry {
    let bytes = value.to_le_bytes()[..(bits as usize).div_ceil(8)].to_vec();
    Entry { subindex, name, data_type, bits, access, value: bytes, check: None }
}

/// A read-only string variable (device name, versions).
pub(crate) fn string_var(index: u16, name: &'static str, value: &str) -> Object {
    let e = Entry {
        subindex: 0,
        name,
        data_type: data_type::VISIBLE_STRING,
        bits: (value.len() * 8) as u16,
        access: RO,
        value: value.as_bytes().to_vec(),
        check: None,
    };
    Object {
        index,
        name,
        object_code: ObjectCode::Var,
        data_type: data_type::VISIBLE_STRING,
        entries: vec![e],
        check: None,
    }
}

fn bits_of(t: u16) -> u16 {
    match t {
        data_type::INTEGER8 | data_type::UNSIGNED8 | data_type::BOOLEAN => 8,
        data_type::INTEGER16 | data_type::UNSIGNED16 => 16,
        _ => 32,
    }
}

pub(crate) fn var(index: u16, name: &'static str, t: u16, access: u16, value: u64) -> Object {
    let value = if data_type::is_signed(t) { value & (u64::MAX >> (64 - bits_of(t))) } else { value };
    Object {
        index,
        name,
        object_code: ObjectCode::Var,
        data_type: t,
        entries: vec![entry(0, name, t, bits_of(t), access, value)],
        check: None,
    }
}

/// A record or array: subindex 0 holds the count of `entries`.
pub(crate) fn record(
    index: u16,
    name: &'static str,
    code: ObjectCode,
    t: u16,
    sub0_access: u16,
    entries: Vec<Entry>,
) -> Object {
    let count = entries.len() as u64;
    let mut all = vec![entry(0, "SubIndex 000", data_type::UNSIGNED8, 8, sub0_access, count)];
    all.extend(entries);
    Object { index, name, object_code: code, data_type: t, entries: all, check: None }
}

/// An array whose entries, "SubIndex 001" on, have type `t`, `access` and `values`; subindex 0,
/// their count, has `sub0_access`.
pub(crate) fn array(
    index: u16,
    name: &'static str,
    t: u16,
    access: u16,
    sub0_access: u16,
    values: impl IntoIterator<Item = u64>,
) -> Object {
    let entries =
        (1..).zip(values).map(|(i, value)| entry(i, SUBINDEX_NAMES[usize::from(i)], t, bits_of(t), access, value));
    record(index, name, ObjectCode::Array, t, sub0_access, entries.collect())
}

/// The identity object 0x1018 named `name`, with `id` and its revision entry named
/// `revision_name`.
pub(crate) fn identity_object(name: &'static str, revision_name: &'static str, id: Identity) -> Object {
    let values = [
        ("Vendor ID", id.vendor_id),
        ("Product code", id.product_code),
        (revision_name, id.revision),
        ("Serial number", id.serial_number),
    ];
    let entries = (1..).zip(values).map(|(i, (n, v))| entry(i, n, data_type::UNSIGNED32, 32, RO, v.into()));
    record(0x1018, name, ObjectCode::Record, data_type::IDENTITY, RO, entries.collect())
}

pub(crate) fn mapping_object(
    index: u16,
    name: &'static str,
    access: u16,
    entries: &[PdoEntry],
    capacity: usize,
) -> Object {
    let subs = (1..=capacity)
        .map(|i| {
            let value = entries.get(i - 1).map_or(0, |e| e.to_u32()) as u64;
            entry(i as u8, SUBINDEX_NAMES[i], data_type::UNSIGNED32, 32, access, value)
        })
        .collect();
    let mut o = record(index, name, ObjectCode::Record, data_type::PDO_MAPPING, access, subs);
    o.entries[0].value[0] = entries.len() as u8;
    o
}

pub(crate) const SUBINDEX_NAMES: [&str; 11] = [
    "SubIndex 000",
    "SubIndex 001",
    "SubIndex 002",
    "SubIndex 003",
    "SubIndex 004",
    "SubIndex 005",
    "SubIndex 006",
    "SubIndex 007",
    "SubIndex 008",
    "SubIndex 009",
    "SubIndex 010",
];
const RX_NAMES: [&str; 4] =
    ["1st receive PDO mapping", "2nd receive PDO mapping", "3rd receive PDO mapping", "4th receive PDO mapping"];
const TX_NAMES: [&str; 4] =
    ["1st transmit PDO mapping", "2nd transmit PDO mapping", "3rd transmit PDO mapping", "4th transmit PDO mapping"];

/// Largest number of entries of a flexible PDO (eight one-byte objects fill eight bytes).
pub const FLEXIBLE_CAPACITY: usize = 8;

fn modes_of_operation(value: &[u8]) -> Result<(), SdoAbortCode> {
    match value.first().map(|v| *v as i8) {
        Some(1 | 3 | 4 | 6 | 7 | 8) => Ok(()),
        _ => Err(SdoAbortCode::VALUE_RANGE),
    }
}

fn nonzero(value: &[u8]) -> Result<(), SdoAbortCode> {
    if value.iter().any(|b| *b != 0) {
        Ok(())
    } else {
        Err(SdoAbortCode::VALUE_RANGE)
    }
}

/// 0x608F:01 takes FB1.PSCALE's powers of two only (AKD EtherCAT manual 2017 §5.3.70).
fn power_of_two(value: &[u8]) -> Result<(), SdoAbortCode> {
    match value.try_into().map(u32::from_le_bytes) {
        Ok(v) if v.is_power_of_two() => Ok(()),
        _ => Err(SdoAbortCode::VALUE_RANGE),
    }
}

/// One of the DS402 scaling ratios (0x608F, 0x6091, 0x6092, [`scaling`]), defaults from the
/// AKD EtherCAT manual 2017 §5.3.70-72: numerator and denominator, neither ever 0.
fn scaling_ratio(index: u16, name: &'static str, subs: [(&'static str, u32, ValueCheck); 2]) -> Object {
    let entries = subs.iter().enumerate().map(|(i, &(sub_name, value, check))| Entry {
        check: Some(check),
        ..entry(i as u8 + 1, sub_name, data_type::UNSIGNED32, 32, RW, value as u64)
    });
    record(index, name, ObjectCode::Array, data_type::UNSIGNED32, RO, entries.collect())
}

/// Shortest cycle the AKD runs, in ns (4 kHz).
pub const MIN_CYCLE_NS: u64 = 250_000;

/// The interpolation time period 0x60C2 in ns, or `None` when it is not representable.
pub fn cycle_ns(units: u8, index: i8) -> Option<u64> {
    let exponent = index as i32 + 9;
    (0..=18).contains(&exponent).then(|| units as u64 * 10u64.pow(exponent as u32))
}

/// 0x60C2 is checked when its index (sub 2) is written: the master writes units first, and
/// the pair must then give at least 250 µs.
fn interpolation_period(_: &ObjectDictionary, object: &Object, written: u8) -> Result<(), SdoAbortCode> {
    if written != 2 {
        return Ok(());
    }
    match cycle_ns(object.unsigned(1) as u8, object.unsigned(2) as u8 as i8) {
        Some(ns) if ns >= MIN_CYCLE_NS => Ok(()),
        Some(_) => Err(SdoAbortCode::VALUE_TOO_LOW),
        None => Err(SdoAbortCode::VALUE_RANGE),
    }
}

/// The entries of flexible mapping object `object` as its subindex 0 counts them.
pub fn mapped_entries(object: &Object) -> impl Iterator<Item = PdoEntry> + '_ {
    (1..=object.unsigned(0) as u8).map(|s| PdoEntry::from_u32(object.unsigned(s) as u32))
}

/// A flexible PDO is checked when its count (sub 0) is written; entries may be written only
/// while the count is 0 (AKD manual §5.6: "sub 0 = 0 first, the count last").
fn flexible_pdo(_: &ObjectDictionary, object: &Object, written: u8) -> Result<(), SdoAbortCode> {
    let direction = if object.index < 0x1A00 { Direction::Rx } else { Direction::Tx };
    if written != 0 {
        return Ok(());
    }
    let entries: Vec<PdoEntry> = mapped_entries(object).collect();
    if entries.len() > FLEXIBLE_CAPACITY {
        return Err(SdoAbortCode::VALUE_RANGE);
    }
    pdo::check_flexible_pdo(direction, object.index, &entries)
        .map_err(|r| r.abort_code().unwrap_or(SdoAbortCode::GENERAL))
}

/// An assignment (0x1C12/0x1C13) is checked when its count is written: either one fixed
/// mapping, or up to four flexible PDOs within the drive's total size.
fn assignment(od: &ObjectDictionary, object: &Object, written: u8) -> Result<(), SdoAbortCode> {
    let direction = if object.index == 0x1C12 { Direction::Rx } else { Direction::Tx };
    let count = object.unsigned(0) as usize;
    let assigned: Vec<u16> = (1..=count as u8).map(|s| object.unsigned(s) as u16).collect();
    if written != 0 {
        let chosen = object.unsigned(written) as u16;
        let base = direction.flexible_base();
        let fixed = pdo::fixed(chosen).is_some_and(|p| p.direction == direction);
        return if fixed || (base..base + FLEXIBLE_PDO_COUNT as u16).contains(&chosen) {
            Ok(())
        } else {
            Err(SdoAbortCode::VALUE_RANGE)
        };
    }
    if count > FLEXIBLE_PDO_COUNT {
        return Err(SdoAbortCode::VALUE_RANGE);
    }
    if assigned.iter().any(|i| pdo::fixed(*i).is_some()) {
        return if count == 1 { Ok(()) } else { Err(SdoAbortCode::VALUE_RANGE) };
    }
    let mut total = 0;
    for index in &assigned {
        let o = od.object(*index).ok_or(SdoAbortCode::VALUE_RANGE)?;
        total += bit_len(&mapped_entries(o).collect::<Vec<_>>());
    }
    // Odd lengths are accepted here (the real drive powers up with one) and refused at the
    // PreOp→SafeOp transition with AL status code 0x001D/0x001E.
    if total > pdo::max_bytes(direction) * 8 {
        return Err(SdoAbortCode::PDO_TOO_LONG);
    }
    Ok(())
}

/// The object dictionary of one virtual AKD.
#[derive(Clone, Debug)]
pub struct ObjectDictionary {
    objects: Vec<Object>,
}

impl Default for ObjectDictionary {
    fn default() -> Self {
        Self::akd()
    }
}

impl ObjectDictionary {
    /// The AKD's dictionary with its power-up values (the flexible mapping the real drive
    /// reports in the SOEM capture, cycle time 2 ms) and the real drive's identity.
    pub fn akd() -> Self {
        Self::akd_of(sii_image::IDENTITY)
    }

    /// The AKD's dictionary at power-up with `id` in the identity object 0x1018, as the drive's
    /// SII holds it.
    pub fn akd_of(id: Identity) -> Self {
        use data_type::*;
        let mut objects = vec![
            var(0x1000, "Device type", UNSIGNED32, RO, 0x0002_0192),
            var(0x1001, "Error register", UNSIGNED8, RO, 0),
            var(0x1002, "Manufacturer status register", UNSIGNED32, RO, 0),
            string_var(0x1008, "Manufacturer device name", "AKD"),
            string_var(0x1009, "Manufacturer hardware version", sii_image::MODEL),
            string_var(0x100A, "Manufacturer software version", sii_image::FIRMWARE),
            identity_object("Identity object", "Revision number", id),
        ];
        for (i, entries) in pdo::POWER_UP_RX.iter().enumerate() {
            let mut o = mapping_object(0x1600 + i as u16, RX_NAMES[i], RW_PREOP, entries, FLEXIBLE_CAPACITY);
            o.check = Some(flexible_pdo);
            objects.push(o);
        }
        for (i, entries) in pdo::POWER_UP_TX.iter().enumerate() {
            let mut o = mapping_object(0x1A00 + i as u16, TX_NAMES[i], RW_PREOP, entries, FLEXIBLE_CAPACITY);
            o.check = Some(flexible_pdo);
            objects.push(o);
        }
        for fixed in pdo::FIXED {
            let name = match fixed.direction {
                Direction::Rx => "Fixed receive PDO mapping",
                Direction::Tx => "Fixed transmit PDO mapping",
            };
            objects.push(mapping_object(fixed.index, name, RO, fixed.entries, fixed.entries.len()));
        }
        objects.push(array(0x1C00, "Sync manager communication type", UNSIGNED8, RO, RO, 1..=4));
        for (index, name, base) in [(0x1C12, "RxPDO assign", 0x1600u64), (0x1C13, "TxPDO assign", 0x1A00)] {
            let mut o = array(index, name, UNSIGNED16, RW_PREOP, RW_PREOP, base..base + 4);
            o.check = Some(assignment);
            objects.push(o);
        }
        for (index, name) in [(0x1C32, "SM output parameter"), (0x1C33, "SM input parameter")] {
            objects.push(record(
                index,
                name,
                ObjectCode::Record,
                SM_SYNCHRONIZATION,
                RO,
                vec![
                    entry(1, "Synchronization type", UNSIGNED16, 16, RW_PREOP, 2),
                    entry(2, "Cycle time", UNSIGNED32, 32, RO, 2_000_000),
                    entry(3, "Shift time", UNSIGNED32, 32, RO, 0),
                    entry(4, "Synchronization types supported", UNSIGNED16, 16, RO, 0x0005),
                    entry(5, "Minimum cycle time", UNSIGNED32, 32, RO, MIN_CYCLE_NS),
                    entry(6, "Calc and copy time", UNSIGNED32, 32, RO, 0),
                ],
            ));
        }
        objects.push(array(0x2002, "Manufacturer status padding", UNSIGNED8, RO, RO, [0; 4]));
        for (index, name, t, acc) in [
            (0x2050, "Second position feedback", INTEGER32, RO),
            (0x2071, "Current command", INTEGER32, RW),
            (0x2077, "Current actual value", INTEGER32, RO),
            (0x20A0, "Latch 1p", INTEGER32, RO),
            (0x20A1, "Latch 1n", INTEGER32, RO),
            (0x20A2, "Latch 2p", INTEGER32, RO),
            (0x20A3, "Latch 2n", INTEGER32, RO),
            (0x20A4, "Latch controlword", UNSIGNED16, RW),
            (0x20A5, "Latch statusword", UNSIGNED16, RO),
            (0x20A6, "Latch 1 pn", INTEGER32, RO),
            (0x20A7, "Latch 2 pn", INTEGER32, RO),
            (0x20B8, "ClearDigInputChangedBit", UNSIGNED16, RW),
            (0x3497, "Position offset", INTEGER32, RW),
            // Modelled: the manual gives FBUS.PARAM02 no CoE index (see crate::drive::sync::FBUS_PARAM02);
            // named as the AKD names the parameter, which the master's SDO information check reads.
            (crate::drive::sync::FBUS_PARAM02, crate::drive::sync::FBUS_PARAM02_NAME, UNSIGNED32, RW),
            // Modelled likewise (see scaling::FBUS_PARAM05); bit 4 selects DS402 scaling.
            (scaling::FBUS_PARAM05, scaling::FBUS_PARAM05_NAME, UNSIGNED32, RW),
            (0x603F, "Error code", UNSIGNED16, RO),
            (0x6040, "Controlword", UNSIGNED16, RW),
            (0x6041, "Statusword", UNSIGNED16, RO),
            (0x6060, "Modes of operation", INTEGER8, RW),
            (0x6061, "Modes of operation display", INTEGER8, RO),
            (0x6063, "Position actual internal value", INTEGER32, RO),
            (0x6064, "Position actual value", INTEGER32, RO),
            (0x6065, "Following error window", UNSIGNED32, RW),
            (0x606C, "Velocity actual value", INTEGER32, RO),
            (0x606D, "Velocity window", UNSIGNED16, RW),
            (0x606E, "Velocity window time", UNSIGNED16, RW),
            (0x6071, "Target torque", INTEGER16, RW),
            (0x6072, "Max torque", UNSIGNED16, RW),
            (0x6077, "Torque actual value", INTEGER16, RO),
            (0x607A, "Target position", INTEGER32, RW),
            (0x6081, "Profile velocity", UNSIGNED32, RW),
            (0x6083, "Profile acceleration", UNSIGNED32, RW),
            (0x6084, "Profile deceleration", UNSIGNED32, RW),
            (0x6085, "Quick stop deceleration", UNSIGNED32, RW),
            (0x60B1, "Velocity offset", INTEGER32, RW),
            (0x60B2, "Torque offset", INTEGER16, RW),
            (0x60B8, "Touch probe function", UNSIGNED16, RW),
            (0x60B9, "Touch probe status", UNSIGNED16, RO),
            (0x60BA, "Touch probe pos1 pos value", INTEGER32, RO),
            (0x60BB, "Touch probe pos1 neg value", INTEGER32, RO),
            (0x60BC, "Touch probe pos2 pos value", INTEGER32, RO),
            (0x60BD, "Touch probe pos2 neg value", INTEGER32, RO),
            (0x60F4, "Following error actual value", INTEGER32, RO),
            (0x60FD, "Digital inputs", UNSIGNED32, RO),
            (0x60FF, "Target velocity", INTEGER32, RW),
            (0x6502, "Supported drive modes", UNSIGNED32, RO),
        ] {
            objects.push(var(index, name, t, acc, 0));
        }
        objects.push(array(0x3427, "Feedback position", UNSIGNED32, RO, RO, [0; 3]));
        objects.push(record(
            0x3470,
            "Analog I/O",
            ObjectCode::Record,
            INTEGER16,
            RO,
            vec![
                entry(1, "AIN.VALUE raw", INTEGER16, 16, RO, 0),
                entry(2, "AOUT.VALUE", INTEGER16, 16, RO, 0),
                entry(3, "AOUT.VALUE write", INTEGER16, 16, RW, 0),
                entry(4, "AIN.VALUE", INTEGER16, 16, RO, 0),
            ],
        ));
        objects.push(record(
            0x60C1,
            "Interpolation data record",
            ObjectCode::Array,
            INTEGER32,
            RO,
            vec![entry(1, "1st set-point", INTEGER32, 32, RW, 0)],
        ));
        let mut period = record(
            0x60C2,
            "Interpolation time period",
            ObjectCode::Record,
            UNSIGNED8,
            RO,
            vec![
                entry(1, "Interpolation time units", UNSIGNED8, 8, RW_PREOP, 2),
                entry(2, "Interpolation time index", INTEGER8, 8, RW_PREOP, (-3i8) as u8 as u64),
            ],
        );
        period.check = Some(interpolation_period);
        period.entries[1].check = Some(nonzero);
        objects.push(period);
        objects.push(scaling_ratio(
            scaling::POSITION_ENCODER_RESOLUTION,
            "Position encoder resolution",
            [
                ("Encoder increments", scaling::DEFAULT_COUNTS_PER_REVOLUTION, power_of_two),
                ("Motor revolutions", 1, nonzero),
            ],
        ));
        objects.push(scaling_ratio(
            scaling::GEAR_RATIO,
            "Gear ratio",
            [("Motor revolutions", 1, nonzero), ("Shaft revolutions", 1, nonzero)],
        ));
        objects.push(scaling_ratio(
            scaling::FEED_CONSTANT,
            "Feed constant",
            [("Feed", 1, nonzero), ("Shaft revolutions", 1, nonzero)],
        ));
        objects.push(record(
            0x60E4,
            "Additional position actual value",
            ObjectCode::Array,
            INTEGER32,
            RO,
            vec![entry(1, "1st additional position actual value", INTEGER32, 32, RO, 0)],
        ));
        objects.push(record(
            0x60FE,
            "Digital outputs",
            ObjectCode::Array,
            UNSIGNED32,
            RO,
            vec![entry(1, "Physical outputs", UNSIGNED32, 32, RW, 0), entry(2, "Bit mask", UNSIGNED32, 32, RW, 0)],
        ));
        let mut od = ObjectDictionary { objects };
        od.objects.sort_by_key(|o| o.index);
        od.set(0x6041, 0, &0x0240u16.to_le_bytes());
        // csp ip hm pv pp, as the AKD's description of 0x6502 gives it: no bit for profile torque
        // (which the AKD offers as mode 4 all the same), none for cyclic synchronous velocity or
        // torque (modes 9 and 10, which no AKD manual lists; docs/virtual_akd.md).
        od.set(0x6502, 0, &0x0000_00E5u32.to_le_bytes());
        // The virtual drive's power-up motion parameters, which the drive model reads back.
        od.set(0x6065, 0, &FOLLOWING_ERROR_WINDOW.to_le_bytes());
        od.set(0x6081, 0, &PROFILE_VELOCITY.to_le_bytes());
        for index in [0x6083, 0x6084, 0x6085] {
            od.set(index, 0, &PROFILE_ACCELERATION.to_le_bytes());
        }
        let modes = od.objects.iter_mut().find(|o| o.index == 0x6060).expect("listed above");
        modes.entries[0].check = Some(modes_of_operation);
        for o in &mut od.objects {
            for e in &mut o.entries {
                let p = PdoEntry::new(o.index, e.subindex, e.bits as u8);
                if pdo::is_mappable(Direction::Rx, p) {
                    e.access |= access::RX_PDO;
                }
                if pdo::is_mappable(Direction::Tx, p) {
                    e.access |= access::TX_PDO;
                }
            }
        }
        od
    }

    /// A dictionary of `objects` (another slave's than the AKD's, e.g. a terminal's).
    pub fn from_objects(mut objects: Vec<Object>) -> Self {
        objects.sort_by_key(|o| o.index);
        ObjectDictionary { objects }
    }

    /// Every object, by index.
    pub fn objects(&self) -> &[Object] {
        &self.objects
    }

    /// The object at `index`.
    pub fn object(&self, index: u16) -> Option<&Object> {
        self.objects.binary_search_by_key(&index, |o| o.index).ok().map(|i| &self.objects[i])
    }

    /// Adds `object`, or replaces the one at its index. For tests that need an object the AKD
    /// does not have, e.g. a writable string longer than a small mailbox
    /// ([`VirtualAkd::with_mailbox_size`](crate::sim::VirtualAkd::with_mailbox_size)).
    pub fn insert(&mut self, object: Object) {
        match self.objects.binary_search_by_key(&object.index, |o| o.index) {
            Ok(i) => self.objects[i] = object,
            Err(i) => self.objects.insert(i, object),
        }
    }

    /// Removes the object at `index`, if any: for tests of a drive that lacks an object the
    /// virtual AKD has (e.g. [`crate::drive::sync::FBUS_PARAM02`], whose index is not documented).
    pub fn remove(&mut self, index: u16) -> Option<Object> {
        let i = self.objects.binary_search_by_key(&index, |o| o.index).ok()?;
        Some(self.objects.remove(i))
    }

    fn object_mut(&mut self, index: u16) -> Option<&mut Object> {
        self.objects.binary_search_by_key(&index, |o| o.index).ok().map(|i| &mut self.objects[i])
    }

    /// The value of `index:subindex`.
    pub fn get(&self, index: u16, subindex: u8) -> Option<&[u8]> {
        self.object(index)?.entry(subindex).map(|e| e.value.as_slice())
    }

    /// Sets a value without any check (the drive's own updates, process data). Bytes beyond the
    /// entry's length are dropped, missing ones keep their value.
    pub fn set(&mut self, index: u16, subindex: u8, value: &[u8]) {
        if let Some(e) = self.object_mut(index).and_then(|o| o.entries.iter_mut().find(|e| e.subindex == subindex)) {
            let n = e.value.len().min(value.len());
            e.value[..n].copy_from_slice(&value[..n]);
        }
    }

    /// An SDO read in AL state `state` (as access bits READ_PREOP/SAFEOP/OP).
    pub fn read(&self, index: u16, subindex: u8) -> Result<&[u8], SdoAbortCode> {
        let object = self.object(index).ok_or(SdoAbortCode::NO_SUCH_OBJECT)?;
        let entry = object.entry(subindex).ok_or(SdoAbortCode::NO_SUCH_SUBINDEX)?;
        if entry.access & access::READ == 0 {
            return Err(SdoAbortCode::WRITE_ONLY);
        }
        Ok(&entry.value)
    }

    /// An SDO write while the drive is in the state whose write-access bit is `state_write`
    /// (e.g. [`access::WRITE_PREOP`]): checks access, length and range, then the object.
    pub fn write(&mut self, index: u16, subindex: u8, value: &[u8], state_write: u16) -> Result<(), SdoAbortCode> {
        let object = self.object(index).ok_or(SdoAbortCode::NO_SUCH_OBJECT)?;
        let entry = object.entry(subindex).ok_or(SdoAbortCode::NO_SUCH_SUBINDEX)?;
        if entry.access & access::WRITE == 0 {
            return Err(SdoAbortCode::READ_ONLY);
        }
        if entry.access & state_write == 0 {
            return Err(SdoAbortCode::DEVICE_STATE);
        }
        if value.len() != entry.value.len() {
            return Err(match value.len().cmp(&entry.value.len()) {
                std::cmp::Ordering::Greater => SdoAbortCode::LENGTH_TOO_HIGH,
                _ => SdoAbortCode::LENGTH_TOO_LOW,
            });
        }
        if let Some(check) = entry.check {
            check(value)?;
        }
        let flexible = matches!(index, 0x1600..=0x1603 | 0x1A00..=0x1A03);
        if subindex != 0 && flexible && object.unsigned(0) != 0 {
            return Err(SdoAbortCode::SUBINDEX_WRITE_NEEDS_ZERO);
        }
        let old = entry.value.clone();
        self.set(index, subindex, value);
        let object = self.object(index).expect("found above");
        if let Some(check) = object.check {
            if let Err(code) = check(self, object, subindex) {
                self.set(index, subindex, &old);
                return Err(code);
            }
        }
        Ok(())
    }

    /// The PDOs assigned in `direction` (0x1C12/0x1C13), each with its entries.
    pub fn assigned_pdos(&self, direction: Direction) -> Vec<(u16, Vec<PdoEntry>)> {
        let Some(assign) = self.object(direction.assignment_index()) else {
            return Vec::new();
        };
        (1..=assign.unsigned(0) as u8)
            .filter_map(|s| {
                let index = assign.unsigned(s) as u16;
                let o = self.object(index)?;
                Some((index, mapped_entries(o).collect()))
            })
            .collect()
    }

    /// The drive's position scaling as its objects hold it (FBUS.PARAM05 included).
    pub fn position_scaling(&self) -> scaling::PositionScaling {
        let entries =
            scaling::SCALING_ENTRIES.map(|(index, sub)| self.object(index).map_or(0, |o| o.unsigned(sub) as u32));
        let param05 = self.object(scaling::FBUS_PARAM05).map_or(0, |o| o.unsigned(0) as u32);
        scaling::PositionScaling::from_entries(entries, Some(param05))
    }

    /// How many counts of position object `index:subindex` make one count of the drive model
    /// (2^20 per motor revolution, UNIT.PIN's default where DS402 scaling is off); 1 for any
    /// other object.
    pub fn position_scale(&self, index: u16, subindex: u8) -> f64 {
        let model = scaling::DEFAULT_COUNTS_PER_REVOLUTION as f64;
        self.position_scaling().counts_per_revolution(index, subindex, Some(model)).map_or(1.0, |c| c / model)
    }

    /// The interpolation time period 0x60C2 in ns.
    pub fn cycle_time_ns(&self) -> Option<u64> {
        let o = self.object(0x60C2)?;
        cycle_ns(o.unsigned(1) as u8, o.unsigned(2) as u8 as i8)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn power_up_values_are_the_real_drives() {
        let od = ObjectDictionary::akd();
        assert_eq!(od.read(0x1C12, 0).unwrap(), &[4]);
        assert_eq!(od.read(0x1C12, 1).unwrap(), &[0x00, 0x16]);
        assert_eq!(od.read(0x1600, 1).unwrap(), &0x6040_0010u32.to_le_bytes());
        assert_eq!(od.read(0x1A03, 2).unwrap(), &0x606C_0020u32.to_le_bytes());
        assert_eq!(od.read(0x1C00, 3).unwrap(), &[3]);
        assert_eq!(od.read(0x1018, 1).unwrap(), &0x6Au32.to_le_bytes());
        let rx: usize = od.assigned_pdos(Direction::Rx).iter().map(|(_, e)| bit_len(e)).sum();
        assert_eq!(rx, 17 * 8);
        assert_eq!(od.cycle_time_ns(), Some(2_000_000));
        assert!(od.objects().windows(2).all(|w| w[0].index < w[1].index));
    }

    #[test]
    fn the_identity_object_holds_the_identity_it_was_given() {
        assert_eq!(ObjectDictionary::akd().read(0x1018, 4).unwrap(), &0x9983_0093u32.to_le_bytes());
        let od = ObjectDictionary::akd_of(sii_image::identity(2));
        assert_eq!(od.read(0x1018, 4).unwrap(), &0x9983_0095u32.to_le_bytes());
        assert_eq!(od.read(0x1018, 2).unwrap(), &0x0041_4B44u32.to_le_bytes());
    }

    #[test]
    fn writes_are_checked() {
        let mut od = ObjectDictionary::akd();
        let preop = access::WRITE_PREOP;
        assert_eq!(od.write(0x1234, 0, &[0], preop), Err(SdoAbortCode::NO_SUCH_OBJECT));
        assert_eq!(od.write(0x6040, 1, &[0, 0], preop), Err(SdoAbortCode::NO_SUCH_SUBINDEX));
        assert_eq!(od.write(0x6041, 0, &[0, 0], preop), Err(SdoAbortCode::READ_ONLY));
        assert_eq!(od.write(0x6040, 0, &[0], preop), Err(SdoAbortCode::LENGTH_TOO_LOW));
        assert_eq!(od.write(0x6060, 0, &[2], preop), Err(SdoAbortCode::VALUE_RANGE));
        assert_eq!(od.write(0x1C12, 0, &[0], access::WRITE_SAFEOP), Err(SdoAbortCode::DEVICE_STATE));
        // Entries of a flexible PDO only while its count is 0, then the count is checked.
        assert_eq!(
            od.write(0x1600, 2, &0x6060_0008u32.to_le_bytes(), preop),
            Err(SdoAbortCode::SUBINDEX_WRITE_NEEDS_ZERO)
        );
        od.write(0x1600, 0, &[0], preop).unwrap();
        od.write(0x1600, 1, &0x6041_0010u32.to_le_bytes(), preop).unwrap();
        assert_eq!(od.write(0x1600, 0, &[1], preop), Err(SdoAbortCode::NOT_MAPPABLE));
        assert_eq!(od.read(0x1600, 0).unwrap(), &[0], "a refused count is undone");
        od.write(0x1600, 1, &0x6040_0010u32.to_le_bytes(), preop).unwrap();
        od.write(0x1600, 0, &[1], preop).unwrap();
        // Fixed mappings: one per direction.
        od.write(0x1C12, 0, &[0], preop).unwrap();
        assert_eq!(od.write(0x1C12, 1, &0x1B01u16.to_le_bytes(), preop), Err(SdoAbortCode::VALUE_RANGE));
        od.write(0x1C12, 1, &0x1701u16.to_le_bytes(), preop).unwrap();
        od.write(0x1C12, 0, &[1], preop).unwrap();
        assert_eq!(od.assigned_pdos(Direction::Rx)[0].0, 0x1701);
        // The cycle time: at least 250 µs, checked when the index is written.
        od.write(0x60C2, 1, &[25], preop).unwrap();
        od.write(0x60C2, 2, &[(-5i8) as u8], preop).unwrap();
        assert_eq!(od.cycle_time_ns(), Some(250_000));
        od.write(0x60C2, 1, &[1], preop).unwrap();
        assert_eq!(od.write(0x60C2, 2, &[(-5i8) as u8], preop), Err(SdoAbortCode::VALUE_TOO_LOW));
    }
}
