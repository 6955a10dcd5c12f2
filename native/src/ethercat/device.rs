//! A slave's process data by name, as the slave describes it: its channels ([`Channel`]), one
//! per PDO entry it carries, each named after the entry's name in its SII in snake case, with
//! its direction, its bits, its data type and where it sits in the slave's data; and their
//! values read from a process image, to the bit ([`Channel::read`]), and encoded to be written
//! there ([`Channel::encode`]). What an EL1004 calls "Channel 1"'s "Input" is its channel
//! `channel_1_input`. A pure codec: the master, the cycle thread, the node's messages and the
//! Python side read a terminal's channels from here.
//!
//! Names are the entries' own where they are unique in the slave ("Status", "Value" of one
//! PDO), qualified by their PDO's name where several entries share one (each of an EL1004's
//! PDOs "Channel n" holds an entry "Input": `channel_1_input`), and by their object where even
//! that repeats or the SII names neither (`entry_0x6000_01`). Gaps (index 0) carry no channel.

use crate::ethercat::coe::data_type::{self, ValueKind};
use crate::ethercat::pdo::{copy_bits, Direction, PdoEntry, ProcessData};
use crate::ethercat::sii::Sii;
use crate::spelling::snake_case;

/// One channel of a slave: one PDO entry it carries.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Channel {
    /// Its name, unique in the slave (see the module).
    pub name: String,
    /// Outputs ([`Direction::Rx`]) or inputs ([`Direction::Tx`]).
    pub direction: Direction,
    /// The entry: object, subindex, bits.
    pub entry: PdoEntry,
    /// The PDO that carries it (its mapping object, e.g. 0x1A00).
    pub pdo: u16,
    /// Its CoE data type as the SII gives it (0 where it gives none).
    pub data_type: u16,
    /// The bit of the slave's data that way where it starts.
    pub bit: usize,
}

/// A channel's value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ChannelValue {
    /// A channel of one bit (an EL1004's input, an EL2004's output).
    Bit(bool),
    /// An integer (an EL3102's value, counts), signed where its data type is.
    Integer(i64),
    /// A REAL32 or REAL64.
    Real(f64),
}

impl ChannelValue {
    /// The value as a number: 0 or 1 for a bit.
    pub fn as_f64(self) -> f64 {
        match self {
            ChannelValue::Bit(b) => f64::from(u8::from(b)),
            ChannelValue::Integer(v) => v as f64,
            ChannelValue::Real(v) => v,
        }
    }
}

/// A value a channel cannot take.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("channel {channel}: {given} given, allowed {allowed}")]
pub struct ChannelValueError {
    /// The channel's name.
    pub channel: String,
    /// What was given, in words.
    pub given: String,
    /// What it takes, in words.
    pub allowed: String,
}

impl Channel {
    /// Whether it is one bit.
    pub fn is_bit(&self) -> bool {
        self.entry.bits == 1
    }

    /// Its value in `image` (the whole image of its direction) where the slave's data of that
    /// way starts at bit `start`.
    pub fn read(&self, image: &[u8], start: usize) -> ChannelValue {
        let bits = usize::from(self.entry.bits).min(64);
        let mut raw = [0u8; 8];
        copy_bits(image, start + self.bit, &mut raw, 0, bits);
        let raw = u64::from_le_bytes(raw);
        match data_type::kind(self.data_type) {
            _ if bits == 1 => ChannelValue::Bit(raw == 1),
            ValueKind::Real if bits == 32 => ChannelValue::Real(f64::from(f32::from_bits(raw as u32))),
            ValueKind::Real if bits == 64 => ChannelValue::Real(f64::from_bits(raw)),
            ValueKind::SignedInteger if bits < 64 => {
                ChannelValue::Integer(((raw << (64 - bits)) as i64) >> (64 - bits))
            }
            _ => ChannelValue::Integer(raw as i64),
        }
    }

    /// The bits `value` is written as, or why the channel cannot take it: a bit takes a bit (or
    /// 0 or 1), an integer one within its bits' range as signed or unsigned, a real any number.
    pub fn encode(&self, value: ChannelValue) -> Result<u64, ChannelValueError> {
        let bits = u32::from(self.entry.bits).min(64);
        let refused = |given: String, allowed: String| ChannelValueError { channel: self.name.clone(), given, allowed };
        let kind = data_type::kind(self.data_type);
        match (value, kind) {
            (ChannelValue::Bit(b), _) if bits == 1 => Ok(u64::from(b)),
            (ChannelValue::Real(v), ValueKind::Real) if bits == 32 => Ok(u64::from((v as f32).to_bits())),
            (ChannelValue::Real(v), ValueKind::Real) if bits == 64 => Ok(v.to_bits()),
            (ChannelValue::Integer(v), _) if kind != ValueKind::Real => {
                let (min, max) = match (kind, bits) {
                    (_, 1) => (0, 1),
                    (ValueKind::SignedInteger, 64) => (i64::MIN, i64::MAX),
                    (ValueKind::SignedInteger, _) => (-(1i64 << (bits - 1)), (1i64 << (bits - 1)) - 1),
                    (_, 64) => (0, i64::MAX),
                    _ => (0, (1i64 << bits) - 1),
                };
                if (min..=max).contains(&v) {
                    Ok(v as u64 & mask(bits))
                } else {
                    Err(refused(v.to_string(), format!("{min}..={max} ({bits} bits)")))
                }
            }
            (given, _) => {
                let given = match given {
                    ChannelValue::Bit(b) => format!("a bit ({b})"),
                    ChannelValue::Integer(v) => format!("an integer ({v})"),
                    ChannelValue::Real(v) => format!("a real number ({v})"),
                };
                let allowed = match (bits, kind) {
                    (1, _) => "a bit (true or false, 0 or 1)".to_owned(),
                    (_, ValueKind::Real) => format!("a real number ({bits} bits)"),
                    _ => format!("an integer ({bits} bits)"),
                };
                Err(refused(given, allowed))
            }
        }
    }
}

fn mask(bits: u32) -> u64 {
    if bits >= 64 {
        u64::MAX
    } else {
        (1u64 << bits) - 1
    }
}

/// The channels of the slave whose SII is `sii`, given `process_data`: outputs first, then
/// inputs, each in wire order, named as the module says.
pub fn channels(sii: &Sii, process_data: &ProcessData) -> Vec<Channel> {
    // (channel without its name yet, the entry's name, its PDO's name)
    let mut found: Vec<(Channel, String, String)> = Vec::new();
    for direction in Direction::ALL {
        let described = match direction {
            Direction::Rx => sii.rx_pdos(),
            Direction::Tx => sii.tx_pdos(),
        };
        let mut bit = 0;
        for pdo in &process_data.assignment(direction).pdos {
            let sii_pdo = described.iter().find(|p| p.index == pdo.index);
            let pdo_name = sii_pdo.and_then(|p| sii.string(p.name_idx)).map(snake_case).unwrap_or_default();
            for (n, entry) in pdo.entries.iter().enumerate() {
                let sii_entry = sii_pdo
                    .and_then(|p| p.entries.get(n).filter(|e| (e.index, e.subindex) == (entry.index, entry.subindex)));
                if entry.index != 0 {
                    let name = sii_entry.and_then(|e| sii.string(e.name_idx)).map(snake_case).unwrap_or_default();
                    let data_type = sii_entry.map_or(0, |e| u16::from(e.data_type));
                    let channel =
                        Channel { name: String::new(), direction, entry: *entry, pdo: pdo.index, data_type, bit };
                    found.push((channel, name, pdo_name.clone()));
                }
                bit += usize::from(entry.bits);
            }
        }
    }
    let count = |names: &[String], name: &String| names.iter().filter(|n| *n == name).count();
    let entries: Vec<String> = found.iter().map(|f| f.1.clone()).collect();
    let qualified: Vec<String> = found
        .iter()
        .map(|(_, entry, pdo)| match (pdo.is_empty(), entry.is_empty()) {
            (_, true) => String::new(),
            (true, false) => entry.clone(),
            (false, false) => format!("{pdo}_{entry}"),
        })
        .collect();
    found
        .into_iter()
        .enumerate()
        .map(|(k, (mut channel, entry, _))| {
            let object = || format!("entry_0x{:04x}_{:02x}", channel.entry.index, channel.entry.subindex);
            channel.name = if !entry.is_empty() && count(&entries, &entry) == 1 {
                entry
            } else if !qualified[k].is_empty() && count(&qualified, &qualified[k]) == 1 {
                qualified[k].clone()
            } else {
                object()
            };
            channel
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::pdo::{Pdo, PdoAssignment};

    fn one_bit(name: &str, direction: Direction, bit: usize) -> Channel {
        Channel {
            name: name.into(),
            direction,
            entry: PdoEntry::new(0x7010, 1, 1),
            pdo: 0x1601,
            data_type: data_type::BOOLEAN,
            bit,
        }
    }

    #[test]
    fn bits_and_integers_read_and_encode_to_the_bit() {
        let output = one_bit("channel_2_output", Direction::Rx, 1);
        assert_eq!(output.read(&[0b1010_0000, 0], 4), ChannelValue::Bit(true));
        assert_eq!(output.read(&[0b1000_0000, 0], 4), ChannelValue::Bit(false));
        assert_eq!(output.encode(ChannelValue::Bit(true)), Ok(1));
        assert_eq!(output.encode(ChannelValue::Integer(1)), Ok(1));
        let refused = output.encode(ChannelValue::Integer(2)).unwrap_err().to_string();
        assert_eq!(refused, "channel channel_2_output: 2 given, allowed 0..=1 (1 bits)");
        let value = Channel {
            name: "value".into(),
            direction: Direction::Tx,
            entry: PdoEntry::new(0x3101, 2, 16),
            pdo: 0x1A00,
            data_type: data_type::INTEGER16,
            bit: 8,
        };
        let inputs = [0xFF, 0x00, 0x18, 0xFC];
        assert_eq!(value.read(&inputs, 8), ChannelValue::Integer(-1000));
        assert!(value.encode(ChannelValue::Integer(40000)).unwrap_err().to_string().contains("-32768..=32767"));
        assert!(value.encode(ChannelValue::Real(1.5)).unwrap_err().to_string().contains("an integer (16 bits)"));
    }

    #[test]
    fn names_are_the_entries_qualified_by_their_pdo_where_they_repeat() {
        let sii = Sii::parse(&crate::sim::terminal_sii::EL2004.image().unwrap()).unwrap();
        let channels = channels(&sii, &sii.process_data(false));
        let names: Vec<&str> = channels.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["channel_1_output", "channel_2_output", "channel_3_output", "channel_4_output"]);
        assert_eq!(channels[3], Channel { bit: 3, ..one_bit("channel_4_output", Direction::Rx, 3) }.with_entry(0x7030));
        let el3102 = Sii::parse(&crate::sim::terminal_sii::EL3102.image().unwrap()).unwrap();
        let names: Vec<String> = channels_of(&el3102).into_iter().map(|c| c.name).collect();
        assert_eq!(
            names,
            [
                "tx_pdo_map_channel_1_status",
                "tx_pdo_map_channel_1_value",
                "tx_pdo_map_channel_2_status",
                "tx_pdo_map_channel_2_value"
            ]
        );
        // A PDO the SII does not describe: its entries are named by their objects.
        let odd = ProcessData {
            inputs: PdoAssignment {
                pdos: vec![Pdo { index: 0x1A7F, entries: vec![PdoEntry::new(0x6000, 1, 8), PdoEntry::new(0, 0, 8)] }],
                ..PdoAssignment::default()
            },
            ..ProcessData::default()
        };
        let found = super::channels(&el3102, &odd);
        assert_eq!((found.len(), found[0].name.as_str()), (1, "entry_0x6000_01"));
    }

    fn channels_of(sii: &Sii) -> Vec<Channel> {
        channels(sii, &sii.process_data(false))
    }

    impl Channel {
        fn with_entry(self, index: u16) -> Channel {
            Channel { entry: PdoEntry::new(index, 1, 1), pdo: 0x1600 + (index - 0x7000) / 0x10, ..self }
        }
    }
}
