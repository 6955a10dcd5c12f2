//! Process data as the master sets it up for any slave: the entries PDOs carry ([`PdoEntry`],
//! index, subindex and bit length), which way ([`Direction`]), where each sits in a slave's
//! process data ([`layout`]), and the description the master configures a slave from
//! ([`ProcessData`]): the PDOs its sync managers 2 and 3 carry and whether the master writes them
//! over CoE. Which PDOs a slave takes, and its rules, are its profile's (the AKD's are
//! [`crate::drive::pdo`]'s) or its SII's ([`crate::ethercat::sii::Sii::process_data`]).

/// One mapped object: index, subindex and bit length, as written to a mapping object's
/// subindices in the form 0xIIIISSBB.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PdoEntry {
    /// Object index.
    pub index: u16,
    /// Subindex.
    pub subindex: u8,
    /// Length in bits.
    pub bits: u8,
}

impl PdoEntry {
    /// An entry of `bits` bits of `index:subindex`.
    pub const fn new(index: u16, subindex: u8, bits: u8) -> Self {
        PdoEntry { index, subindex, bits }
    }

    /// Decodes a mapping object value 0xIIIISSBB.
    pub const fn from_u32(value: u32) -> Self {
        PdoEntry { index: (value >> 16) as u16, subindex: (value >> 8) as u8, bits: value as u8 }
    }

    /// Encodes as a mapping object value 0xIIIISSBB.
    pub const fn to_u32(self) -> u32 {
        ((self.index as u32) << 16) | ((self.subindex as u32) << 8) | self.bits as u32
    }

    /// Bytes the entry occupies in the process image, a partial byte counting as one.
    pub const fn byte_len(self) -> usize {
        (self.bits as usize).div_ceil(8)
    }
}

named_variants! {
    /// Which way a PDO carries data.
    pub enum Direction {
        /// Master to slave: outputs (RxPDO, sync manager 2, assignment 0x1C12).
        Rx => "RxPDO",
        /// Slave to master: inputs (TxPDO, sync manager 3, assignment 0x1C13).
        Tx => "TxPDO",
    }
    /// "RxPDO" or "TxPDO".
    fn name;
}

impl Direction {
    /// The sync-manager assignment object of this direction.
    pub const fn assignment_index(self) -> u16 {
        match self {
            Direction::Rx => 0x1C12,
            Direction::Tx => 0x1C13,
        }
    }

    /// First PDO mapping object of this direction (0x1600 or 0x1A00, CiA 301).
    pub const fn flexible_base(self) -> u16 {
        match self {
            Direction::Rx => 0x1600,
            Direction::Tx => 0x1A00,
        }
    }

    /// The PDO mapping objects of this direction (CiA 301: 0x1600-0x17FF, 0x1A00-0x1BFF).
    pub const fn mapping_objects(self) -> std::ops::RangeInclusive<u16> {
        let base = self.flexible_base();
        base..=base + 0x1FF
    }

    /// The sync manager carrying this direction.
    pub const fn sync_manager(self) -> u8 {
        match self {
            Direction::Rx => 2,
            Direction::Tx => 3,
        }
    }
}

/// Whether `index` is a PDO mapping object of either direction.
pub fn is_mapping_object(index: u16) -> bool {
    Direction::ALL.iter().any(|d| d.mapping_objects().contains(&index))
}

/// Total bit length of `entries`.
pub fn bit_len(entries: &[PdoEntry]) -> usize {
    entries.iter().map(|e| e.bits as usize).sum()
}

/// Clears `bits` bits of `image` from bit `from`, leaving the others as they are.
pub fn clear_bits(image: &mut [u8], from: usize, bits: usize) {
    for n in from..from + bits {
        image[n / 8] &= !(1 << (n % 8));
    }
}

/// Copies `bits` bits of `src` from bit `from` into `dst` from bit `to`, leaving `dst`'s other
/// bits as they are; bit n is bit n % 8 of byte n / 8, as in a process image. Whole bytes are
/// copied as such where both ends sit on byte boundaries. Panics past either slice's end:
/// callers check ranges first.
pub fn copy_bits(src: &[u8], from: usize, dst: &mut [u8], to: usize, bits: usize) {
    if from.is_multiple_of(8) && to.is_multiple_of(8) && bits.is_multiple_of(8) {
        dst[to / 8..(to + bits) / 8].copy_from_slice(&src[from / 8..(from + bits) / 8]);
        return;
    }
    for n in 0..bits {
        let (s, d) = (from + n, to + n);
        let bit = src[s / 8] >> (s % 8) & 1;
        dst[d / 8] = dst[d / 8] & !(1 << (d % 8)) | bit << (d % 8);
    }
}

/// Where each entry of a mapping sits in the process image: byte offset and entry.
pub fn layout(entries: impl IntoIterator<Item = PdoEntry>) -> impl Iterator<Item = (usize, PdoEntry)> {
    let mut bit = 0usize;
    entries.into_iter().map(move |e| {
        let at = bit / 8;
        bit += e.bits as usize;
        (at, e)
    })
}

/// Where object `index:subindex` sits in a mapping's process data (byte offset) and how it is
/// mapped, if the mapping carries it.
pub fn find(entries: &[PdoEntry], index: u16, subindex: u8) -> Option<(usize, PdoEntry)> {
    layout(entries.iter().copied()).find(|(_, e)| (e.index, e.subindex) == (index, subindex))
}

/// A mapping entry written as text in a form other than [`PdoEntry::parse`] takes.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("entry '{text}' is not INDEX:SUB/BITS in hex, e.g. 0x6040:00/16")]
pub struct EntrySyntaxError {
    /// The text as given.
    pub text: String,
}

impl PdoEntry {
    /// Parses an entry written as the node's parameters write it, `INDEX:SUB/BITS`: index in
    /// four hex digits, subindex in one or two, each with or without `0x`, and the bit length
    /// in one or two decimal digits, e.g. `0x6040:00/16`. Whether a slave maps it is
    /// its profile's question.
    pub fn parse(text: &str) -> Result<PdoEntry, EntrySyntaxError> {
        let refused = || EntrySyntaxError { text: text.to_owned() };
        let hex = |part: &str, digits: std::ops::RangeInclusive<usize>| {
            let part = part.strip_prefix("0x").unwrap_or(part);
            let well_formed = digits.contains(&part.len()) && part.bytes().all(|b| b.is_ascii_hexdigit());
            well_formed.then(|| u16::from_str_radix(part, 16).ok()).flatten()
        };
        let (address, bits) = text.split_once('/').ok_or_else(refused)?;
        let (index, subindex) = address.split_once(':').ok_or_else(refused)?;
        let index = hex(index, 4..=4).ok_or_else(refused)?;
        let subindex = hex(subindex, 1..=2).ok_or_else(refused)? as u8;
        if !(1..=2).contains(&bits.len()) || !bits.bytes().all(|b| b.is_ascii_digit()) {
            return Err(refused());
        }
        let bits = bits.parse().map_err(|_| refused())?;
        Ok(PdoEntry::new(index, subindex, bits))
    }
}

/// One PDO of a slave: its mapping object (e.g. 0x1A00) and its entries in wire order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Pdo {
    /// The mapping object.
    pub index: u16,
    /// Its entries.
    pub entries: Vec<PdoEntry>,
}

/// What one sync manager of process data carries, and how the master gives it to the slave.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PdoAssignment {
    /// The PDOs assigned, in wire order.
    pub pdos: Vec<Pdo>,
    /// Whether the master writes the assignment over CoE (0x1C12, 0x1C13); without, the slave
    /// carries what its SII says.
    pub over_coe: bool,
    /// Whether the master also writes each PDO's entries into its mapping object over CoE
    /// before assigning it (a flexible PDO); a fixed PDO's entries are the slave's own.
    pub write_entries: bool,
}

impl PdoAssignment {
    /// The entries of every PDO, in wire order.
    pub fn entries(&self) -> impl Iterator<Item = PdoEntry> + '_ {
        self.pdos.iter().flat_map(|p| p.entries.iter().copied())
    }
}

/// A slave's process data as the master sets it up: its outputs (sync manager 2, RxPDOs) and
/// its inputs (sync manager 3, TxPDOs). The master takes the sync managers' addresses from the
/// slave's SII and lays the FMMUs out over every slave's process data.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ProcessData {
    /// Outputs.
    pub outputs: PdoAssignment,
    /// Inputs.
    pub inputs: PdoAssignment,
}

impl ProcessData {
    /// The assignment of `direction`.
    pub fn assignment(&self, direction: Direction) -> &PdoAssignment {
        match direction {
            Direction::Rx => &self.outputs,
            Direction::Tx => &self.inputs,
        }
    }

    /// Bits of process data in `direction`.
    pub fn bits(&self, direction: Direction) -> usize {
        self.assignment(direction).entries().map(|e| e.bits as usize).sum()
    }

    /// Bytes its sync manager of `direction` holds: the bits, a partial byte counting as one.
    pub fn bytes(&self, direction: Direction) -> usize {
        self.bits(direction).div_ceil(8)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mapping_objects_are_cia_301s_two_ranges() {
        let mapping: Vec<u16> = (0x1500..=0x1C20).filter(|&i| is_mapping_object(i)).collect();
        let expected: Vec<u16> = (0x1600..=0x17FF).chain(0x1A00..=0x1BFF).collect();
        assert_eq!(mapping, expected);
    }

    #[test]
    fn entries_round_trip_the_wire_form() {
        assert_eq!(PdoEntry::from_u32(0x60FF0020), PdoEntry::new(0x60FF, 0, 32));
        assert_eq!(PdoEntry::new(0x6040, 0, 16).to_u32(), 0x60400010);
        assert_eq!(PdoEntry::new(0x60C1, 1, 32).to_u32(), 0x60C10120);
    }

    #[test]
    fn bits_are_copied_across_bytes_leaving_the_others() {
        let mut image = [0xFFu8, 0x00, 0xFF];
        copy_bits(&[0b0000_0101], 0, &mut image, 6, 4);
        assert_eq!(image, [0b0111_1111, 0b0000_0001, 0xFF]);
        let mut out = [0u8; 1];
        copy_bits(&image, 6, &mut out, 0, 4);
        assert_eq!(out, [0b0101]);
        clear_bits(&mut image, 5, 4);
        assert_eq!(image, [0b0001_1111, 0b0000_0000, 0xFF]);
        let mut whole = [0u8; 3];
        copy_bits(&[1, 2], 0, &mut whole, 8, 16);
        assert_eq!(whole, [0, 1, 2]);
    }

    #[test]
    fn entries_parse_from_the_parameters_text() {
        assert_eq!(PdoEntry::parse("0x6040:00/16"), Ok(PdoEntry::new(0x6040, 0, 16)));
        assert_eq!(PdoEntry::parse("60C1:1/32"), Ok(PdoEntry::new(0x60C1, 1, 32)));
        assert_eq!(PdoEntry::parse("0x60c1:0x01/32"), Ok(PdoEntry::new(0x60C1, 1, 32)));
        for bad in [
            "6040-16",
            "0x6040:00",
            "0x604:00/16",
            "0x60400:00/16",
            "0x6040:000/16",
            "0x6040:00/160",
            "0x6040:00/",
            "0x6040:0g/16",
            "0X6040:00/16",
            "0x6040:00/+8",
            " 0x6040:00/16",
            "",
        ] {
            let refused = PdoEntry::parse(bad).unwrap_err();
            assert!(refused.to_string().contains(&format!("'{bad}'")), "{refused}");
            assert!(refused.to_string().contains("INDEX:SUB/BITS"), "{refused}");
        }
    }
}
