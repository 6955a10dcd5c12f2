//! File access over EtherCAT (ETG.1000.6 §5.9): read and write a file by name.
//!
//! Every FoE message has a 6-byte header after the mailbox header: an opcode, a reserved byte
//! and a 32-bit word whose meaning the opcode gives (the password of a read or write request,
//! the packet number of data and acknowledges, the error code of an error, "done" and "entire"
//! of a busy). A request names the file; the side that sends the file then sends data packets
//! numbered from 1, each answered by an acknowledge of its number (or a busy: send it again
//! later). A packet shorter than a full mailbox ends the file, so a file of whole packets ends
//! with an empty one. Either side may end a transfer with an error.

use std::borrow::Cow;

use crate::ethercat::mailbox::{MailboxHeader, MailboxType, HEADER_LEN};
use crate::wire_code::UnknownCode;

/// Length of the FoE header.
pub const FOE_HEADER_LEN: usize = 6;
/// Offset of a FoE message's data (name, file data, error text) in a mailbox message.
pub const DATA_OFFSET: usize = HEADER_LEN + FOE_HEADER_LEN;

wire_codes! {
    /// The FoE opcode (first byte of the FoE header).
    pub enum FoeOpcode: u8, "FoE opcode" {
        /// Read request: the master asks for a file.
        ReadRequest = 1 => "read request",
        /// Write request: the master sends a file.
        WriteRequest = 2 => "write request",
        /// A packet of the file.
        Data = 3 => "data",
        /// A packet received.
        Ack = 4 => "acknowledge",
        /// The transfer ends with an error.
        Error = 5 => "error",
        /// The receiver cannot take the packet yet.
        Busy = 6 => "busy",
    }
}

wire_codes! {
    /// A FoE error code (ETG.1000.6 table "FoE error codes"). Codes outside the standard's list
    /// are the vendor's, so this is the wire value with the standard's codes as constants and
    /// [`name`](FoeErrorCode::name) for any of them.
    pub struct FoeErrorCode(u32) {
        NOT_DEFINED = 0x0000_8000 => "not defined",
        NOT_FOUND = 0x0000_8001 => "not found",
        ACCESS_DENIED = 0x0000_8002 => "access denied",
        DISK_FULL = 0x0000_8003 => "disk full",
        ILLEGAL = 0x0000_8004 => "illegal",
        PACKET_NUMBER_WRONG = 0x0000_8005 => "packet number wrong",
        ALREADY_EXISTS = 0x0000_8006 => "already exists",
        NO_USER = 0x0000_8007 => "no user",
        BOOTSTRAP_ONLY = 0x0000_8008 => "bootstrap only",
        NOT_BOOTSTRAP = 0x0000_8009 => "not bootstrap",
        NO_RIGHTS = 0x0000_800A => "no rights",
        PROGRAM_ERROR = 0x0000_800B => "program error",
    } else {
        _ => "vendor-specific FoE error",
    }
}

/// One decoded FoE message (the mailbox body of a message of type FoE).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FoeMessage<'a> {
    /// The master asks for the file `name`.
    ReadRequest {
        /// Password (0: none).
        password: u32,
        /// File name.
        name: &'a str,
    },
    /// The master will send the file `name`.
    WriteRequest {
        /// Password (0: none).
        password: u32,
        /// File name.
        name: &'a str,
    },
    /// Packet `packet` of the file.
    Data {
        /// Packet number, from 1.
        packet: u32,
        /// The packet's bytes.
        data: &'a [u8],
    },
    /// Packet `packet` received (0: the write request).
    Ack {
        /// Packet number.
        packet: u32,
    },
    /// The transfer ends with `code`.
    Error {
        /// Error code.
        code: FoeErrorCode,
        /// The sender's text, as sent (not necessarily UTF-8).
        text: &'a [u8],
    },
    /// The receiver is busy: `done` of `entire` (e.g. per cent) of its work is done.
    Busy {
        /// Work done.
        done: u16,
        /// All the work.
        entire: u16,
        /// The sender's text.
        text: &'a [u8],
    },
}

impl<'a> FoeMessage<'a> {
    /// The message's opcode.
    pub fn opcode(&self) -> FoeOpcode {
        match self {
            FoeMessage::ReadRequest { .. } => FoeOpcode::ReadRequest,
            FoeMessage::WriteRequest { .. } => FoeOpcode::WriteRequest,
            FoeMessage::Data { .. } => FoeOpcode::Data,
            FoeMessage::Ack { .. } => FoeOpcode::Ack,
            FoeMessage::Error { .. } => FoeOpcode::Error,
            FoeMessage::Busy { .. } => FoeOpcode::Busy,
        }
    }

    /// Decodes the mailbox body of a FoE message.
    pub fn decode(body: &'a [u8]) -> Result<Self, FoeError> {
        let Some(header) = body.get(..FOE_HEADER_LEN) else {
            return Err(FoeError::Truncated { what: "FoE header", len: body.len(), needed: FOE_HEADER_LEN });
        };
        let opcode = FoeOpcode::try_from(header[0]).map_err(FoeError::UnknownCode)?;
        let word = u32::from_le_bytes(header[2..6].try_into().expect("4 bytes"));
        let rest = &body[FOE_HEADER_LEN..];
        let name = || std::str::from_utf8(rest).map_err(|_| FoeError::NameNotText);
        Ok(match opcode {
            FoeOpcode::ReadRequest => FoeMessage::ReadRequest { password: word, name: name()? },
            FoeOpcode::WriteRequest => FoeMessage::WriteRequest { password: word, name: name()? },
            FoeOpcode::Data => FoeMessage::Data { packet: word, data: rest },
            FoeOpcode::Ack => FoeMessage::Ack { packet: word },
            FoeOpcode::Error => FoeMessage::Error { code: FoeErrorCode(word), text: rest },
            FoeOpcode::Busy => FoeMessage::Busy { done: word as u16, entire: (word >> 16) as u16, text: rest },
        })
    }

    /// The length of the message (mailbox header included) when written.
    pub fn len(&self) -> usize {
        DATA_OFFSET
            + match self {
                FoeMessage::ReadRequest { name, .. } | FoeMessage::WriteRequest { name, .. } => name.len(),
                FoeMessage::Data { data, .. } => data.len(),
                FoeMessage::Ack { .. } => 0,
                FoeMessage::Error { text, .. } | FoeMessage::Busy { text, .. } => text.len(),
            }
    }

    /// Always false: a message has at least its headers (for clippy's `len` rule).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Writes the whole message (mailbox header, FoE header, its data) into `out`, which must
    /// hold [`len`](Self::len) bytes; returns that length.
    pub fn write(&self, out: &mut [u8], counter: u8) -> usize {
        let (word, data): (u32, &[u8]) = match *self {
            FoeMessage::ReadRequest { password, name } | FoeMessage::WriteRequest { password, name } => {
                (password, name.as_bytes())
            }
            FoeMessage::Data { packet, data } => (packet, data),
            FoeMessage::Ack { packet } => (packet, &[]),
            FoeMessage::Error { code, text } => (code.0, text),
            FoeMessage::Busy { done, entire, text } => (u32::from(done) | (u32::from(entire) << 16), text),
        };
        MailboxHeader::new(MailboxType::Foe, (FOE_HEADER_LEN + data.len()) as u16, counter).encode(out);
        out[HEADER_LEN] = self.opcode() as u8;
        out[HEADER_LEN + 1] = 0;
        out[HEADER_LEN + 2..DATA_OFFSET].copy_from_slice(&word.to_le_bytes());
        out[DATA_OFFSET..DATA_OFFSET + data.len()].copy_from_slice(data);
        DATA_OFFSET + data.len()
    }
}

/// The text of an error or busy message, replacing what is not UTF-8.
pub fn text(raw: &[u8]) -> Cow<'_, str> {
    let end = raw.iter().position(|&b| b == 0).unwrap_or(raw.len());
    String::from_utf8_lossy(&raw[..end])
}

/// Bytes of the file one data packet carries when full, in a mailbox of `mailbox_len` bytes:
/// a shorter packet is the last.
pub fn packet_room(mailbox_len: usize) -> usize {
    mailbox_len.saturating_sub(DATA_OFFSET)
}

/// The packets a file goes in: full ones, then a shorter last one, empty when the file is a
/// whole number of full packets (or empty), so that the receiver sees its end. Numbered from 1.
pub fn packets(file: &[u8], room: usize) -> impl Iterator<Item = (u32, &[u8])> + '_ {
    let full = file.len() / room.max(1);
    (0..=full).map(move |i| {
        let from = i * room;
        ((i + 1) as u32, &file[from..(from + room).min(file.len())])
    })
}

/// A FoE message that does not fit the standard (ETG.1000.6 §5.9), or a transfer that failed.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FoeError {
    /// A message cut short.
    #[error("{what} of {len} bytes is shorter than the {needed} bytes it needs")]
    Truncated {
        /// The structure.
        what: &'static str,
        /// Bytes there were.
        len: usize,
        /// Bytes it needs.
        needed: usize,
    },
    /// An opcode outside the standard's set.
    #[error("{0}")]
    UnknownCode(UnknownCode),
    /// A file name that is not UTF-8 text.
    #[error("FoE file name is not valid text")]
    NameNotText,
    /// The slave's SII does not list FoE among its mailbox protocols.
    #[error("slave {slave} does not speak FoE (SII mailbox protocols)")]
    NotSupported {
        /// Slave position.
        slave: u16,
    },
    /// The slave ended the transfer of `name` with a FoE error.
    #[error(
        "slave {slave} refused file {name:?}: FoE error 0x{code:04X} ({code_name}){}",
        if .text.is_empty() || .text == .code_name { String::new() } else { format!(": {}", .text) }
    )]
    Refused {
        /// Slave position.
        slave: u16,
        /// The file.
        name: String,
        /// The error code.
        code: u32,
        /// Its name in the standard.
        code_name: &'static str,
        /// The slave's text.
        text: String,
    },
    /// The slave answered with another message than the transfer allows.
    #[error("slave {slave} answered the transfer of {name:?} with FoE {got} where {expected} was due")]
    Unexpected {
        /// Slave position.
        slave: u16,
        /// The file.
        name: String,
        /// What was awaited.
        expected: &'static str,
        /// The opcode received.
        got: &'static str,
    },
    /// A packet or acknowledge with another number than the transfer reached.
    #[error("slave {slave} sent FoE packet number {got} where {expected} was due")]
    PacketNumber {
        /// Slave position.
        slave: u16,
        /// The number expected.
        expected: u32,
        /// The number received.
        got: u32,
    },
    /// A file longer than this master reads into memory.
    #[error("file {name:?} is longer than {max} bytes")]
    TooLong {
        /// The file.
        name: String,
        /// The most bytes read.
        max: usize,
    },
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn round_trip(message: &FoeMessage<'_>) -> Vec<u8> {
        let mut out = vec![0u8; message.len()];
        let len = message.write(&mut out, 5);
        assert_eq!(len, message.len());
        let header = MailboxHeader::decode(&out).unwrap();
        assert_eq!((header.protocol(), header.counter), (Some(MailboxType::Foe), 5));
        assert_eq!(&FoeMessage::decode(header.body(&out)).unwrap(), message);
        out
    }

    #[test]
    fn requests_name_the_file() {
        let out = round_trip(&FoeMessage::WriteRequest { password: 0x1234_5678, name: "fw.i00" });
        assert_eq!(&out[6..], &[0x02, 0x00, 0x78, 0x56, 0x34, 0x12, b'f', b'w', b'.', b'i', b'0', b'0']);
        round_trip(&FoeMessage::ReadRequest { password: 0, name: "" });
        assert_eq!(FoeMessage::decode(&[1, 0, 0, 0, 0, 0, 0xFF]).unwrap_err(), FoeError::NameNotText);
    }

    #[test]
    fn data_ack_error_busy() {
        let out = round_trip(&FoeMessage::Data { packet: 3, data: &[9, 8, 7] });
        assert_eq!(&out[6..], &[0x03, 0, 3, 0, 0, 0, 9, 8, 7]);
        assert_eq!(&round_trip(&FoeMessage::Ack { packet: 0x0102 })[6..], &[0x04, 0, 2, 1, 0, 0]);
        let out = round_trip(&FoeMessage::Error { code: FoeErrorCode::NOT_FOUND, text: b"not found" });
        assert_eq!(&out[6..12], &[0x05, 0, 0x01, 0x80, 0, 0]);
        let out = round_trip(&FoeMessage::Busy { done: 40, entire: 100, text: b"" });
        assert_eq!(&out[6..], &[0x06, 0, 40, 0, 100, 0]);
        assert_eq!(FoeErrorCode(0x8001).name(), "not found");
        assert_eq!(FoeErrorCode(0x1234).name(), "vendor-specific FoE error");
        assert_eq!(text(b"disk full\0\0"), "disk full");
    }

    #[test]
    fn malformed_messages_are_errors() {
        assert_eq!(
            FoeMessage::decode(&[3, 0, 1]).unwrap_err(),
            FoeError::Truncated { what: "FoE header", len: 3, needed: 6 }
        );
        let FoeError::UnknownCode(code) = FoeMessage::decode(&[7, 0, 0, 0, 0, 0]).unwrap_err() else { panic!() };
        assert_eq!(code.value, 7);
    }

    #[test]
    fn a_file_of_whole_packets_ends_with_an_empty_one() {
        let file = [1u8; 20];
        let lens: Vec<_> = packets(&file, 10).map(|(n, p)| (n, p.len())).collect();
        assert_eq!(lens, vec![(1, 10), (2, 10), (3, 0)]);
        let lens: Vec<_> = packets(&file[..15], 10).map(|(n, p)| (n, p.len())).collect();
        assert_eq!(lens, vec![(1, 10), (2, 5)]);
        assert_eq!(packets(&[], 10).map(|(n, p)| (n, p.len())).collect::<Vec<_>>(), vec![(1, 0)]);
        assert_eq!(packet_room(1024), 1012);
    }

    proptest! {
        #[test]
        fn packets_put_back_are_the_file(file in proptest::collection::vec(any::<u8>(), 0..500), room in 1usize..64) {
            let all: Vec<_> = packets(&file, room).collect();
            prop_assert!(all.iter().rev().skip(1).all(|(_, p)| p.len() == room));
            prop_assert!(all.last().unwrap().1.len() < room);
            prop_assert_eq!(all.iter().flat_map(|(_, p)| p.iter().copied()).collect::<Vec<_>>(), file);
        }

        #[test]
        fn decode_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..40)) {
            let _ = FoeMessage::decode(&bytes);
        }
    }
}
