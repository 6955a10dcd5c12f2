//! Errors of the master, the codecs and the links.
//!
//! Each error names what went wrong in the drive's or the standard's own words (the AL status
//! code's name, the SDO abort code's name) so that the Python exception it becomes can be read
//! without a manual.

use std::borrow::Cow;
use std::fmt;

/// A malformed or unexpected EtherCAT frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// Fewer bytes than the structure named by `what` needs.
    Truncated {
        /// The structure being decoded.
        what: &'static str,
        /// Bytes it needs.
        needed: usize,
        /// Bytes there were.
        got: usize,
    },
    /// The frame header's type is not 1 (EtherCAT datagrams).
    NotDatagrams(u8),
    /// A datagram command byte above 14.
    UnknownCommand(u8),
    /// A frame header announcing no datagrams.
    Empty,
    /// The frame header's length differs from the datagrams' total.
    LengthMismatch {
        /// Length in the frame header.
        header: usize,
        /// Length the datagrams take.
        datagrams: usize,
    },
    /// A datagram that does not fit the frame.
    TooLarge {
        /// Data length asked for.
        len: usize,
        /// Room left.
        room: usize,
    },
    /// Not an EtherCAT Ethernet frame (EtherType other than 0x88A4).
    NotEtherCat(u16),
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FrameError::Truncated { what, needed, got } => {
                write!(f, "truncated frame: the {what} needs {needed} bytes, the frame has {got}")
            }
            FrameError::NotDatagrams(t) => {
                write!(f, "frame header type {t} is not 1 (EtherCAT datagrams)")
            }
            FrameError::UnknownCommand(c) => {
                write!(f, "unknown datagram command {c} (allowed 0..=14, NOP..FRMW)")
            }
            FrameError::Empty => write!(f, "frame header announces no datagrams"),
            FrameError::LengthMismatch { header, datagrams } => {
                write!(f, "frame header announces {header} bytes of datagrams but the datagrams take {datagrams}")
            }
            FrameError::TooLarge { len, room } => {
                write!(f, "datagram of {len} data bytes does not fit the frame ({room} bytes left)")
            }
            FrameError::NotEtherCat(t) => {
                write!(f, "EtherType 0x{t:04X} is not EtherCAT (0x88A4)")
            }
        }
    }
}

impl std::error::Error for FrameError {}

/// Why a text is not a link spec; its text names the allowed forms.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LinkSpecError {
    /// `sim:N` with N not a number in 1..=`max`.
    SimCount {
        /// The spec as given.
        spec: String,
        /// The most virtual AKDs a bus may hold (the link spec's `MAX_SIM_COUNT`).
        max: usize,
    },
    /// `sim...?` with an option other than `missed=late|lost|warn` or `pace=real|immediate`,
    /// or one given twice.
    SimOption {
        /// The spec as given.
        spec: String,
    },
    /// An interface name followed by an option other than `busy_poll=US` with US in 0..=`max`.
    InterfaceOption {
        /// The spec as given.
        spec: String,
        /// The longest busy poll (the link spec's `MAX_BUSY_POLL_US`).
        max: u32,
    },
    /// `udp://` without `HOST:PORT`, or with a port outside 1..=65535.
    UdpAddress {
        /// The spec as given.
        spec: String,
    },
    /// None of the forms (empty, or a path or an address without `udp://`).
    Unknown {
        /// The spec as given.
        spec: String,
        /// As for [`SimCount`](LinkSpecError::SimCount), to name the allowed N.
        max_sim_count: usize,
    },
}

impl LinkSpecError {
    /// The forms a link spec takes, with N's range up to `max_sim_count`: what a spec that is
    /// none of them is told, and what the node's parameter check names as allowed.
    pub fn allowed_forms(max_sim_count: usize) -> String {
        format!(
            "'sim', 'sim:N' (N 1..={max_sim_count}; either with options '?missed=late|lost|warn', \
             '?pace=real|immediate', joined by '&'), 'udp://HOST:PORT' or a network interface name (with \
             '?busy_poll=US' to busy-poll for the returning frame)"
        )
    }
}

impl fmt::Display for LinkSpecError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LinkSpecError::SimCount { spec, max } => {
                write!(f, "link {spec:?}: the number of virtual AKDs must be 1..={max}")
            }
            LinkSpecError::SimOption { spec } => write!(
                f,
                "link {spec:?}: the virtual AKDs take options after '?', joined by '&', each once: \
                 missed=late (the default: a frame that comes late is missed and more than seven \
                 raise F125, as the real drive judges), missed=lost (only frames lost on the line \
                 are missed) or missed=warn (judged as the real drive, but a would-be F125 is \
                 counted and warned of instead of raised, for a host whose master thread is not \
                 real-time); pace=real (the default: AL requests and mailbox answered as slowly as \
                 the real drive answers them) or pace=immediate (at once, for tests that need speed)"
            ),
            LinkSpecError::InterfaceOption { spec, max } => write!(
                f,
                "link {spec:?}: a network interface takes one option, ?busy_poll=US with US in 0..={max}: \
                 how many µs the master busy-polls for the returning frame before it sleeps (0, the \
                 default: it sleeps at once)"
            ),
            // The port range as the node's parameter check has always named it.
            LinkSpecError::UdpAddress { spec } => {
                write!(f, "link {spec:?} is no udp://HOST:PORT with a port in 1..65535")
            }
            LinkSpecError::Unknown { spec, max_sim_count } => {
                write!(f, "link {spec:?} is none of {}", LinkSpecError::allowed_forms(*max_sim_count))
            }
        }
    }
}

impl std::error::Error for LinkSpecError {}

/// A wire code outside its closed set (a CoE service, an SDO information opcode, ...).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UnknownCode {
    /// The field the code came in, e.g. "CoE service".
    pub what: &'static str,
    /// The value received.
    pub value: u16,
    /// The set's codes and names, to say what was allowed.
    pub known: &'static [(u16, &'static str)],
}

impl fmt::Display for UnknownCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {} is none of", self.what, self.value)?;
        for (i, (value, name)) in self.known.iter().enumerate() {
            write!(f, "{} {value} ({name})", if i == 0 { "" } else { "," })?;
        }
        Ok(())
    }
}

impl std::error::Error for UnknownCode {}

/// An EoE message or fragment that does not fit the standard (ETG.1000.6 §5.7), or a frame
/// that cannot be sent through EoE.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum EoeError {
    /// A message, or a field of one, cut short.
    Truncated {
        /// The structure or field.
        what: &'static str,
        /// Bytes there were.
        len: usize,
        /// Bytes it needs.
        needed: usize,
    },
    /// A frame type outside the standard's set.
    UnknownCode(UnknownCode),
    /// A DNS name longer than its field.
    DnsNameTooLong {
        /// Its length in bytes.
        len: usize,
        /// The field's length.
        max: usize,
    },
    /// A DNS name that is not UTF-8 text.
    DnsNameNotText,
    /// An Ethernet frame longer than EoE carries here, or than its fragment 0 announced.
    FrameTooLong {
        /// Its length.
        len: usize,
        /// The most allowed.
        max: usize,
    },
    /// A mailbox too small for one 32-byte unit of a fragment.
    MailboxTooSmall {
        /// The mailbox's length.
        len: usize,
        /// The least that carries a fragment.
        min: usize,
    },
    /// A fragment other than the next one of the frame being put together.
    OutOfOrder {
        /// Its frame number.
        frame_number: u8,
        /// The fragment number expected.
        expected: u8,
        /// The fragment number received.
        got: u8,
    },
    /// A fragment whose offset is not where the frame being put together has reached.
    OffsetMismatch {
        /// Its offset in bytes.
        offset: usize,
        /// Bytes received so far.
        received: usize,
    },
    /// A fragment other than the last whose length is not a multiple of 32 bytes.
    FragmentNotWholeUnits {
        /// Its length.
        len: usize,
    },
    /// The slave's SII does not list EoE among its mailbox protocols.
    NotSupported {
        /// Slave position.
        slave: u16,
    },
    /// The slave answered Set IP Parameter with another result than success.
    Refused {
        /// Slave position.
        slave: u16,
        /// The result code.
        result: u16,
        /// Its name in the standard.
        result_name: &'static str,
    },
    /// A frame whose length does not round to the size its fragment 0 announced.
    SizeMismatch {
        /// The size announced, in 32-byte units.
        announced_units: u8,
        /// Bytes received.
        received: usize,
    },
}

impl fmt::Display for EoeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EoeError::Truncated { what, len, needed } => {
                write!(f, "{what} cut short: the message has {len} bytes, it needs {needed}")
            }
            EoeError::UnknownCode(e) => write!(f, "{e}"),
            EoeError::DnsNameTooLong { len, max } => write!(f, "DNS name of {len} bytes is longer than {max}"),
            EoeError::DnsNameNotText => write!(f, "DNS name is not valid text"),
            EoeError::FrameTooLong { len, max } => write!(f, "Ethernet frame of {len} bytes is longer than {max}"),
            EoeError::MailboxTooSmall { len, min } => {
                write!(f, "a {len}-byte mailbox cannot carry an EoE fragment (it needs {min} bytes)")
            }
            EoeError::OutOfOrder { frame_number, expected, got } => {
                write!(f, "EoE fragment {got} of frame {frame_number} where fragment {expected} was expected")
            }
            EoeError::OffsetMismatch { offset, received } => {
                write!(f, "EoE fragment at offset {offset} where {received} bytes were received")
            }
            EoeError::FragmentNotWholeUnits { len } => {
                write!(f, "EoE fragment of {len} bytes is not the last but not a multiple of 32 bytes")
            }
            EoeError::NotSupported { slave } => {
                write!(f, "slave {slave} does not speak EoE (SII mailbox protocols)")
            }
            EoeError::Refused { slave, result, result_name } => {
                write!(f, "slave {slave} answered Set IP Parameter with result 0x{result:04X} ({result_name})")
            }
            EoeError::SizeMismatch { announced_units, received } => write!(
                f,
                "EoE frame of {received} bytes where fragment 0 announced {announced_units} units of 32 bytes"
            ),
        }
    }
}

/// A FoE message that does not fit the standard (ETG.1000.6 §5.9), or a transfer that failed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FoeError {
    /// A message cut short.
    Truncated {
        /// The structure.
        what: &'static str,
        /// Bytes there were.
        len: usize,
        /// Bytes it needs.
        needed: usize,
    },
    /// An opcode outside the standard's set.
    UnknownCode(UnknownCode),
    /// A file name that is not UTF-8 text.
    NameNotText,
    /// The slave's SII does not list FoE among its mailbox protocols.
    NotSupported {
        /// Slave position.
        slave: u16,
    },
    /// The slave ended the transfer of `name` with a FoE error.
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
    PacketNumber {
        /// Slave position.
        slave: u16,
        /// The number expected.
        expected: u32,
        /// The number received.
        got: u32,
    },
    /// A file longer than this master reads into memory.
    TooLong {
        /// The file.
        name: String,
        /// The most bytes read.
        max: usize,
    },
}

impl fmt::Display for FoeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FoeError::Truncated { what, len, needed } => {
                write!(f, "{what} of {len} bytes is shorter than the {needed} bytes it needs")
            }
            FoeError::UnknownCode(e) => write!(f, "{e}"),
            FoeError::NameNotText => write!(f, "FoE file name is not valid text"),
            FoeError::NotSupported { slave } => {
                write!(f, "slave {slave} does not speak FoE (SII mailbox protocols)")
            }
            FoeError::Refused { slave, name, code, code_name, text } => {
                write!(f, "slave {slave} refused file {name:?}: FoE error 0x{code:04X} ({code_name})")?;
                if !text.is_empty() && text != code_name {
                    write!(f, ": {text}")?;
                }
                Ok(())
            }
            FoeError::Unexpected { slave, name, expected, got } => {
                write!(f, "slave {slave} answered the transfer of {name:?} with FoE {got} where {expected} was due")
            }
            FoeError::PacketNumber { slave, expected, got } => {
                write!(f, "slave {slave} sent FoE packet number {got} where {expected} was due")
            }
            FoeError::TooLong { name, max } => write!(f, "file {name:?} is longer than {max} bytes"),
        }
    }
}

/// A mailbox message that does not fit the request or the protocol (ETG.1000.6 mailbox and
/// CoE).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum MailboxError {
    /// A message, or a structure in one, shorter than the structure needs.
    Truncated {
        /// The structure, e.g. "SDO response" or "emergency message".
        what: &'static str,
        /// Bytes there were.
        len: usize,
        /// Bytes it needs.
        needed: usize,
    },
    /// The mailbox header announces more data than the mailbox holds.
    LengthMismatch {
        /// Length in the mailbox header.
        announced: u16,
        /// Bytes after the header.
        holds: usize,
    },
    /// A wire code outside the standard's set (CoE service, SDO command specifier, SDO
    /// information opcode).
    UnknownCode(UnknownCode),
    /// A message of another mailbox type where CoE (3) was expected.
    NotCoe {
        /// The mailbox type received.
        mailbox_type: u8,
    },
    /// A name in an SDO information description that is not UTF-8 text.
    NotText {
        /// The name's field.
        what: &'static str,
    },
    /// The slave has no mailbox: its SII lists no mailbox protocol.
    NoMailbox {
        /// Slave position.
        slave: u16,
    },
    /// The slave's SII does not list CoE among its mailbox protocols.
    NoCoe {
        /// Slave position.
        slave: u16,
    },
    /// A message longer than the slave's mailbox (SM0).
    TooLong {
        /// Slave position.
        slave: u16,
        /// The message's length.
        len: usize,
        /// The mailbox's length.
        room: u16,
    },
    /// The slave answered with a mailbox error reply (ETG.1000.6 Table 30).
    ErrorReply {
        /// Slave position.
        slave: u16,
        /// The error detail code.
        detail: u16,
        /// Its name.
        detail_name: &'static str,
    },
    /// A message of a mailbox type this master does not speak (it speaks CoE).
    UnsupportedType {
        /// Slave position.
        slave: u16,
        /// The mailbox type received.
        mailbox_type: u8,
    },
    /// A CoE reply of another service than the one that answers the request.
    UnexpectedService {
        /// Slave position.
        slave: u16,
        /// The request, e.g. "an SDO request".
        request: &'static str,
        /// The service received.
        got: &'static str,
        /// The service expected.
        expected: &'static str,
    },
    /// An SDO upload that carried another number of bytes than it announced.
    UploadSize {
        /// Slave position.
        slave: u16,
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// Bytes announced.
        announced: usize,
        /// Bytes carried.
        carried: usize,
    },
    /// An SDO response that does not answer the request (other than an abort).
    UnexpectedResponse {
        /// Slave position.
        slave: u16,
        /// The transfer, e.g. "upload".
        transfer: &'static str,
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// The response received, as decoded.
        response: String,
    },
    /// An SDO information error request without its abort code.
    InfoErrorWithoutCode,
    /// An SDO information response that does not answer the request's opcode.
    UnexpectedOpcode {
        /// Slave position.
        slave: u16,
        /// The request's opcode.
        asked: &'static str,
        /// The opcode received.
        got: &'static str,
        /// The opcode that answers the request.
        expected: &'static str,
    },
    /// A Get OD List response without its list type.
    OdListWithoutType,
    /// A description of another object or entry than the one asked for.
    WrongDescription {
        /// What was asked, e.g. "0x6041" or "0x6041:00".
        asked: String,
        /// What came.
        got: String,
    },
    /// An SDO transfer asked of the cycle thread that needs segments, which it does not run.
    NeedsSegments {
        /// "read" or "write".
        verb: &'static str,
        /// Slave position.
        slave: u16,
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
    },
    /// A slave without a CoE mailbox asked for an SDO transfer by the cycle thread.
    NoCoeForTransfer {
        /// "read" or "write".
        verb: &'static str,
        /// Slave position.
        slave: u16,
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
    },
    /// A mailbox error reply to an SDO transfer of the cycle thread.
    TransferErrorReply {
        /// "read" or "write".
        verb: &'static str,
        /// Slave position.
        slave: u16,
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// The error detail code.
        detail: u16,
        /// Its name.
        detail_name: &'static str,
    },
    /// Any other reply to an SDO transfer of the cycle thread.
    TransferUnexpected {
        /// "read" or "write".
        verb: &'static str,
        /// Slave position.
        slave: u16,
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
    },
}

impl fmt::Display for MailboxError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MailboxError::Truncated { what, len, needed } => {
                write!(f, "{what} of {len} bytes is shorter than the {needed} bytes it needs")
            }
            MailboxError::LengthMismatch { announced, holds } => {
                write!(f, "header announces {announced} bytes but the mailbox holds {holds}")
            }
            MailboxError::UnknownCode(e) => write!(f, "{e}"),
            MailboxError::NotCoe { mailbox_type } => write!(f, "mailbox type {mailbox_type} is not CoE (3)"),
            MailboxError::NotText { what } => write!(f, "{what} is not valid text"),
            MailboxError::NoMailbox { slave } => {
                write!(f, "slave {slave} has no mailbox (its SII lists no mailbox protocol)")
            }
            MailboxError::NoCoe { slave } => write!(f, "slave {slave} does not speak CoE (SII mailbox protocols)"),
            MailboxError::TooLong { slave, len, room } => {
                write!(f, "message of {len} bytes does not fit slave {slave}'s {room}-byte mailbox")
            }
            MailboxError::ErrorReply { slave, detail, detail_name } => {
                write!(f, "slave {slave} answered with mailbox error 0x{detail:04X} ({detail_name})")
            }
            MailboxError::UnsupportedType { slave, mailbox_type } => write!(
                f,
                "slave {slave} sent a mailbox message of type {mailbox_type} that this master does not speak (CoE is 3)"
            ),
            MailboxError::UnexpectedService { slave, request, got, expected } => {
                write!(f, "slave {slave} answered {request} with CoE service {got} (expected {expected})")
            }
            MailboxError::UploadSize { slave, index, subindex, announced, carried } => write!(
                f,
                "upload of 0x{index:04X}:{subindex:02X} from slave {slave} announced {announced} bytes but carried {carried}"
            ),
            MailboxError::UnexpectedResponse { slave, transfer, index, subindex, response } => {
                write!(f, "slave {slave} answered the {transfer} of 0x{index:04X}:{subindex:02X} with {response}")
            }
            MailboxError::InfoErrorWithoutCode => write!(f, "SDO information error without an abort code"),
            MailboxError::UnexpectedOpcode { slave, asked, got, expected } => {
                write!(f, "slave {slave} answered SDO information opcode {asked} with opcode {got} (expected {expected})")
            }
            MailboxError::OdListWithoutType => write!(f, "OD list response without its list type"),
            MailboxError::WrongDescription { asked, got } => {
                write!(f, "asked for the description of {asked}, got {got}'s")
            }
            MailboxError::NeedsSegments { verb, slave, index, subindex } => write!(
                f,
                "SDO {verb} of 0x{index:04X}:{subindex:02X} of slave {slave} needs a segmented transfer, which runs \
                 only with the cycle stopped"
            ),
            MailboxError::NoCoeForTransfer { verb, slave, index, subindex } => write!(
                f,
                "slave {slave} has no CoE mailbox for the SDO {verb} of 0x{index:04X}:{subindex:02X} of slave {slave}"
            ),
            MailboxError::TransferErrorReply { verb, slave, index, subindex, detail, detail_name } => write!(
                f,
                "slave {slave} answered the SDO {verb} of 0x{index:04X}:{subindex:02X} with mailbox error \
                 0x{detail:04X} ({detail_name})"
            ),
            MailboxError::TransferUnexpected { verb, slave, index, subindex } => write!(
                f,
                "slave {slave} answered the SDO {verb} of 0x{index:04X}:{subindex:02X} of slave {slave} with \
                 something else"
            ),
        }
    }
}

impl From<UnknownCode> for MailboxError {
    fn from(e: UnknownCode) -> Self {
        MailboxError::UnknownCode(e)
    }
}

/// SII EEPROM content (ETG.1000.6 §5.4, ETG.2010) or its EEPROM interface not as expected.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SiiError {
    /// A read inside a category that runs past its end.
    CategoryOverrun {
        /// The category, e.g. "General".
        category: &'static str,
        /// The category's length in bytes.
        len: usize,
        /// Bytes read.
        read: usize,
        /// Where, in bytes from the category's start.
        at: usize,
    },
    /// A string with a character outside ISO 8859-1, which the SII strings use.
    NotLatin1 {
        /// The string's role.
        what: &'static str,
        /// The string.
        text: String,
        /// The first character outside.
        character: char,
    },
    /// A string of the strings category that runs past its end.
    StringOverrun {
        /// The string's number, from 1.
        number: usize,
        /// Strings the category announces.
        count: usize,
        /// The string's length.
        len: usize,
        /// Bytes left in the category.
        left: usize,
    },
    /// A category of records whose length is not a multiple of the record's.
    NotWholeRecords {
        /// The category.
        category: &'static str,
        /// Its length in bytes.
        len: usize,
        /// One record's length in bytes.
        record: usize,
    },
    /// A PDO announcing more entries than its category holds.
    PdoEntriesOverrun {
        /// "TxPDO" or "RxPDO".
        what: &'static str,
        /// The PDO's index.
        index: u16,
        /// Entries announced.
        count: u8,
        /// Bytes left in the category.
        left: usize,
    },
    /// An image shorter than the SII header (words 0..63).
    ShortImage {
        /// The image's length.
        len: usize,
        /// The header's length.
        header: usize,
    },
    /// A header checksum (word 7, low byte) that is not the CRC-8 of words 0..6.
    Checksum {
        /// The checksum in the image.
        stored: u8,
        /// The CRC-8 of words 0..6.
        computed: u8,
    },
    /// No end category (0xFFFF) before the image ends.
    NoEndCategory {
        /// The image's length.
        len: usize,
        /// Categories read.
        categories: usize,
    },
    /// A category header without its length word.
    NoLengthWord {
        /// Category type.
        kind: u16,
        /// Where, in words.
        word: usize,
    },
    /// A category that announces more words than the image has left.
    CategoryPastEnd {
        /// Category type.
        kind: u16,
        /// Where, in words.
        word: usize,
        /// Words announced.
        words: usize,
        /// Words left.
        left: usize,
    },
    /// A string number beyond the strings category.
    NoSuchString {
        /// Who names it, e.g. "the General category's name".
        what: String,
        /// The string number.
        index: u8,
        /// Strings in the category.
        count: usize,
    },
    /// A category longer than a length word can announce.
    CategoryTooLong {
        /// Category type.
        kind: u16,
        /// Its length in bytes.
        len: usize,
    },
    /// An image larger than the EEPROM its size word announces.
    ImageTooLarge {
        /// The image's length.
        len: usize,
        /// The size word.
        size_word: u16,
        /// The EEPROM's bytes.
        eeprom: usize,
    },
    /// A PDO with more entries than a count byte holds.
    TooManyEntries {
        /// "TxPDO" or "RxPDO".
        what: &'static str,
        /// The PDO's index.
        index: u16,
        /// Entries.
        count: usize,
    },
    /// More strings than a count byte holds.
    TooManyStrings {
        /// Strings.
        count: usize,
        /// The first one too many, when known.
        first_over: Option<String>,
    },
    /// A string longer than a length byte holds.
    StringTooLong {
        /// The string.
        text: String,
        /// Its length in bytes.
        len: usize,
    },
    /// A category of an odd number of bytes.
    OddCategory {
        /// Category type.
        kind: u16,
        /// Its length in bytes.
        len: usize,
    },
    /// Strings interned while building an image, with no strings category placed.
    NoStringsCategory {
        /// Strings interned.
        count: usize,
    },
    /// An EEPROM read that the ESC did not acknowledge (SII control/status register 0x0502).
    EepromNack {
        /// Station address.
        station: u16,
        /// The word read.
        word: u32,
        /// SII control/status.
        control: u16,
    },
    /// No end category before the EEPROM ends.
    EepromNoEnd {
        /// Station address.
        station: u16,
        /// The EEPROM's size.
        size_kbit: u32,
    },
    /// A category that runs past the EEPROM's end.
    EepromCategoryPastEnd {
        /// Station address.
        station: u16,
        /// Category type.
        kind: u16,
        /// Where, in words.
        word: u32,
        /// Its length in words.
        len: u32,
        /// The EEPROM's size.
        size_kbit: u32,
    },
    /// A standard mailbox too small for an SDO message.
    MailboxTooSmall {
        /// Receive mailbox (SM0) size.
        receive: u16,
        /// Send mailbox (SM1) size.
        send: u16,
        /// The least an SDO message needs.
        min: u16,
    },
    /// A PDO entry that the AKD's image names nowhere.
    NoPdoName {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
    },
    /// Any of these, of one slave found by the scan.
    OfSlave {
        /// Slave position.
        position: u16,
        /// Its station address.
        station: u16,
        /// What is wrong.
        error: Box<SiiError>,
    },
}

impl fmt::Display for SiiError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SiiError::CategoryOverrun { category, len, read, at } => {
                write!(f, "the {category} category is {len} bytes: reading {read} bytes at byte {at} runs past its end")
            }
            SiiError::NotLatin1 { what, text, character } => {
                write!(f, "{what} {text:?} holds {character:?}, outside ISO 8859-1 (allowed U+0000..=U+00FF)")
            }
            SiiError::StringOverrun { number, count, len, left } => {
                write!(f, "string {number} of {count} announces {len} bytes but the strings category has {left} left")
            }
            SiiError::NotWholeRecords { category, len, record } => {
                write!(f, "the {category} category is {len} bytes, not a multiple of its {record}-byte records")
            }
            SiiError::PdoEntriesOverrun { what, index, count, left } => write!(
                f,
                "{what} 0x{index:04X} announces {count} entries ({} bytes) but the category has {left} bytes left",
                usize::from(*count) * 8
            ),
            SiiError::ShortImage { len, header } => {
                write!(f, "image of {len} bytes is shorter than the {header}-byte header")
            }
            SiiError::Checksum { stored, computed } => write!(
                f,
                "header checksum (low byte of word 7) is 0x{stored:02X} but the CRC-8 of words 0..6 is 0x{computed:02X}"
            ),
            SiiError::NoEndCategory { len, categories } => write!(
                f,
                "no end category (0xFFFF) before the end of the {len}-byte image (after {categories} categories)"
            ),
            SiiError::NoLengthWord { kind, word } => {
                write!(f, "category 0x{kind:04X} at word 0x{word:04X} has no length word")
            }
            SiiError::CategoryPastEnd { kind, word, words, left } => write!(
                f,
                "category 0x{kind:04X} at word 0x{word:04X} announces {words} words but the image has {left} words left"
            ),
            SiiError::NoSuchString { what, index, count } => write!(
                f,
                "{what} names string {index} but the strings category has {count} (allowed 0..={count}, 0 = none)"
            ),
            SiiError::CategoryTooLong { kind, len } => {
                write!(f, "category 0x{kind:04X} of {len} bytes exceeds the 65535 words a length word holds")
            }
            SiiError::ImageTooLarge { len, size_word, eeprom } => write!(
                f,
                "the image takes {len} bytes but the size word 0x{size_word:04X} announces an EEPROM of {eeprom} bytes"
            ),
            SiiError::TooManyEntries { what, index, count } => {
                write!(f, "{what} 0x{index:04X} has {count} entries (allowed 0..=255)")
            }
            SiiError::TooManyStrings { count, first_over: None } => write!(f, "{count} strings (allowed 0..=255)"),
            SiiError::TooManyStrings { first_over: Some(text), .. } => {
                write!(f, "more than 255 strings (the 256th is {text:?})")
            }
            SiiError::StringTooLong { text, len } => write!(f, "string {text:?} is {len} bytes (allowed 0..=255)"),
            SiiError::OddCategory { kind, len } => {
                write!(f, "category 0x{kind:04X} has {len} bytes; a category is whole words")
            }
            SiiError::NoStringsCategory { count } => {
                write!(f, "{count} strings interned but no strings category placed (call strings_here)")
            }
            SiiError::EepromNack { station, word, control } => write!(
                f,
                "station 0x{station:04X}: EEPROM read of word 0x{word:04X} failed (SII control 0x{control:04X}: \
                 missing acknowledge)"
            ),
            SiiError::EepromNoEnd { station, size_kbit } => write!(
                f,
                "station 0x{station:04X}: no end category (0xFFFF) before the end of the {size_kbit} kbit EEPROM"
            ),
            SiiError::EepromCategoryPastEnd { station, kind, word, len, size_kbit } => write!(
                f,
                "station 0x{station:04X}: category 0x{kind:04X} at word 0x{word:04X} of {len} words runs past the \
                 {size_kbit} kbit EEPROM"
            ),
            SiiError::MailboxTooSmall { receive, send, min } => write!(
                f,
                "mailbox of {receive} bytes out and {send} in is smaller than the {min} bytes of an SDO message"
            ),
            SiiError::NoPdoName { index, subindex } => {
                write!(f, "no name for PDO object 0x{index:04X}:{subindex:02X} in the AKD's image")
            }
            SiiError::OfSlave { position, station, error } => {
                write!(f, "slave {position} (station 0x{station:04X}): {error}")
            }
        }
    }
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
    /// The slave has no process-data mapping yet.
    NoMapping {
        /// Slave position.
        slave: u16,
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
            PdoError::NoMapping { slave } => write!(f, "slave {slave} has no process-data mapping"),
        }
    }
}

/// A value given for a setting outside what the setting allows.
#[derive(Clone, Debug, PartialEq)]
pub enum SettingError {
    /// A simulator asked to busy-poll from a thread under a real-time policy.
    BusyPollRealTime,
    /// A cycle period outside 250 µs (the AKD's minimum) ..= 10 ms.
    CyclePeriod {
        /// The period asked for, µs.
        period_us: f64,
    },
    /// A cycle period given in seconds outside 0.00025 ..= 0.01 s.
    CyclePeriodSeconds {
        /// The period asked for, s.
        seconds: f64,
    },
    /// A SCHED_FIFO priority outside the scheduler's range.
    Priority {
        /// The priority asked for.
        priority: i32,
        /// The lowest.
        low: i32,
        /// The highest.
        high: i32,
    },
    /// A CPU this machine does not have.
    Cpu {
        /// The CPU asked for.
        cpu: usize,
        /// CPUs of this machine.
        cpus: usize,
    },
    /// A CPU wake-up latency outside what a cycle may hold.
    CpuLatency {
        /// The latency asked for, µs.
        us: i64,
        /// The longest allowed, µs.
        max: u32,
    },
    /// A drive cycle time below the AKD's minimum.
    CycleTimeBelowMinimum {
        /// The cycle time, ns.
        cycle_ns: u32,
        /// The AKD's minimum, ns.
        min_ns: u32,
    },
    /// A drive cycle time that 0x60C2 (units times a power of ten) cannot encode exactly.
    CycleTimeNotEncodable {
        /// The cycle time, ns.
        cycle_ns: u32,
    },
    /// A SYNC0 shift of a whole cycle or more.
    Sync0Shift {
        /// The shift asked for, ns.
        shift_ns: i64,
        /// The cycle time, ns.
        cycle_ns: u32,
    },
    /// A duration that is not a non-negative number of seconds.
    Seconds {
        /// The setting, e.g. "timeout".
        what: &'static str,
        /// The value given.
        value: f64,
    },
    /// A virtual AKD's Init→PreOp time that is no number of ms in 0..=10000.
    InitToPreOp {
        /// The time asked for, ms.
        ms: f64,
    },
    /// A virtual AKD's mailbox size outside what the simulator builds.
    MailboxSize {
        /// The size asked for.
        size: u16,
        /// The smallest.
        min: u16,
        /// The largest (the real drive's).
        max: u16,
    },
    /// A latch channel the AKD does not have.
    LatchChannel {
        /// The channel asked for.
        channel: u8,
    },
    /// A digital input the AKD does not have.
    DigitalInput {
        /// The input asked for, from 1.
        input: usize,
        /// Inputs the AKD has.
        count: usize,
    },
    /// A digital input's toggle position that is not a finite number of counts.
    TogglePosition {
        /// The input, from 1.
        input: usize,
        /// The position given.
        position: f64,
    },
    /// A switch of 0x60FD by a name CiA 402 does not give one.
    Switch {
        /// The name given.
        name: String,
    },
    /// An analog voltage that is not a finite number within the range its 16-bit object holds.
    AnalogVoltage {
        /// What it is, e.g. "analog input".
        what: &'static str,
        /// The voltage given.
        volts: f64,
        /// The largest magnitude the object holds, V.
        max: f64,
    },
    /// An SDO write with no data.
    EmptySdoWrite {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
    },
    /// An SDO write through the cycle thread of more bytes than one mailbox message carries.
    SdoWriteLength {
        /// Slave position.
        slave: u16,
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// Bytes given.
        len: usize,
        /// The most allowed.
        max: usize,
    },
    /// Outputs of another length than the slave's.
    OutputsLength {
        /// Slave position.
        slave: u16,
        /// The slave's output bytes.
        expected: usize,
        /// Bytes given.
        given: usize,
    },
    /// A value of another length than its mapped entry's.
    EntryLength {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// The entry's bytes.
        expected: usize,
        /// Bytes given.
        given: usize,
    },
    /// A mapping given in a form that is neither a fixed index nor a list of PDOs.
    MappingForm,
    /// A process image larger than one frame carries.
    ImageTooLarge {
        /// Output and input bytes.
        bytes: usize,
        /// The most one frame carries beside the clock's datagrams.
        limit: usize,
    },
    /// A process image and the supervision reads that together exceed one frame.
    SupervisionTooLarge {
        /// Output and input bytes.
        image: usize,
        /// Slaves supervised.
        slaves: usize,
        /// Bytes of the broadcast status reads.
        watch: usize,
    },
    /// A host name that resolves to no address.
    UnresolvedHost {
        /// The host, as given.
        host: String,
        /// "bind" for a server, "connect" for a link.
        role: &'static str,
    },
    /// A duration that is not a finite number of seconds in the setting's range.
    Duration {
        /// The setting, e.g. "command timeout".
        what: &'static str,
        /// The value given, s.
        seconds: f64,
        /// What the setting allows.
        allowed: &'static str,
    },
    /// Set-point handshake bits outside those the AKD's profile position and homing take.
    HandshakeBits {
        /// The bits given.
        bits: u16,
    },
    /// A virtual drive's position beyond any bus position (above 65535).
    DrivePosition {
        /// The position asked for.
        position: usize,
        /// Drives on the bus.
        count: usize,
    },
    /// A burst of simulated line faults of a negative number of frames.
    FrameCount {
        /// The number asked for.
        frames: i64,
    },
    /// An interface name with a NUL byte, which the OS cannot take.
    InterfaceName {
        /// The name.
        name: String,
    },
    /// An address for EoE that is not in its form.
    Address {
        /// The field ("IP address", "MAC address", ...).
        what: &'static str,
        /// The text given.
        value: String,
        /// The form it must have.
        form: &'static str,
    },
}

impl fmt::Display for SettingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SettingError::CyclePeriod { period_us } => write!(
                f,
                "cycle period {period_us} µs is outside the allowed range 250 µs ..= 10000 µs (the AKD's minimum to \
                 10 ms)"
            ),
            SettingError::CyclePeriodSeconds { seconds } => {
                write!(f, "cycle period {seconds} s is outside the allowed range 0.00025 ..= 0.01 s")
            }
            SettingError::Priority { priority, low, high } => {
                write!(f, "SCHED_FIFO priority {priority} is outside {low}..={high}")
            }
            SettingError::CpuLatency { us, max } => {
                write!(f, "CPU wake-up latency {us} µs is outside the allowed range 0..={max} µs")
            }
            SettingError::Cpu { cpu, cpus } => {
                write!(f, "CPU {cpu} does not exist: this machine has CPUs 0..={}", cpus - 1)
            }
            SettingError::CycleTimeBelowMinimum { cycle_ns, min_ns } => {
                write!(f, "cycle time {cycle_ns} ns is below the AKD's minimum of {min_ns} ns (4 kHz)")
            }
            SettingError::CycleTimeNotEncodable { cycle_ns } => write!(
                f,
                "cycle time {cycle_ns} ns has no exact encoding as units (0..=255) times a power of ten for 0x60C2"
            ),
            SettingError::Sync0Shift { shift_ns, cycle_ns } => {
                let max = *cycle_ns as i64 - 1;
                write!(
                    f,
                    "SYNC0 shift {shift_ns} ns is not within the {cycle_ns} ns cycle: allowed are -{max} to {max} ns"
                )
            }
            SettingError::Seconds { what, value } => {
                write!(f, "{what} must be a non-negative number of seconds, got {value}")
            }
            SettingError::InitToPreOp { ms } => {
                write!(f, "a virtual AKD's Init->PreOp time of {ms} ms: allowed are 0 to 10000 ms")
            }
            SettingError::MailboxSize { size, min, max } => {
                write!(f, "a virtual AKD's mailbox of {size} bytes: allowed are {min} to {max}")
            }
            SettingError::LatchChannel { channel } => write!(f, "latch channel {channel}: the AKD has latches 1 and 2"),
            SettingError::DigitalInput { input, count } => {
                write!(f, "digital input {input}: the AKD has inputs 1 to {count}")
            }
            SettingError::TogglePosition { input, position } => {
                write!(f, "toggle position {position} of digital input {input} is not a finite number of counts")
            }
            SettingError::Switch { name } => {
                let names: Vec<_> = crate::io::Switch::ALL.iter().map(|s| s.name()).collect();
                write!(f, "switch {name:?} is not one of {}", names.join(", "))
            }
            SettingError::AnalogVoltage { what, volts, max } => {
                write!(f, "{what} {volts} V: allowed a finite voltage within ±{max:.4} V")
            }
            SettingError::EmptySdoWrite { index, subindex } => {
                write!(f, "SDO write of 0x{index:04X}:{subindex:02X} with no data")
            }
            SettingError::SdoWriteLength { slave, index, subindex, len, max } => write!(
                f,
                "SDO write of {len} bytes to 0x{index:04X}:{subindex:02X} of slave {slave}: 1 ..= {max} bytes while \
                 cycling"
            ),
            SettingError::OutputsLength { slave, expected, given } => {
                write!(f, "slave {slave} has {expected} bytes of outputs, {given} given")
            }
            SettingError::EntryLength { index, subindex, expected, given } => {
                write!(f, "0x{index:04X}:{subindex:02X} takes {expected} bytes, {given} given")
            }
            SettingError::MappingForm => write!(
                f,
                "a mapping is a fixed mapping index (e.g. 0x1701) or a list of PDOs, each a list of entries 0xIIIISSBB"
            ),
            SettingError::ImageTooLarge { bytes, limit } => write!(
                f,
                "process image of {bytes} bytes (outputs and inputs of every drive) does not fit one frame ({limit} \
                 bytes at most): map fewer objects per drive, e.g. a flexible mapping of what the mode needs"
            ),
            SettingError::SupervisionTooLarge { image, slaves, watch } => write!(
                f,
                "the process image ({image} bytes) leaves no room in one frame for the status reads of {slaves} \
                 slaves ({watch} bytes)"
            ),
            SettingError::UnresolvedHost { host, role: "bind" } => {
                write!(f, "cannot resolve {host:?} as a host to bind")
            }
            SettingError::UnresolvedHost { host, .. } => write!(f, "UDP address {host:?} resolves to nothing"),
            SettingError::Duration { what, seconds, allowed } => write!(f, "{what} {seconds} s: allowed {allowed}"),
            SettingError::HandshakeBits { bits } => write!(
                f,
                "set-point handshake bits 0x{bits:04X}: allowed are bit 4 (0x0010, new set-point or start homing) \
                 with bit 5 (0x0020, change set immediately) and bit 6 (0x0040, relative), e.g. 0x0030 or 0x0010"
            ),
            SettingError::DrivePosition { position, count } => {
                write!(f, "no slave at position {position}: the bus has {count} slave(s)")
            }
            SettingError::FrameCount { frames } => {
                write!(f, "{frames} frames: allowed are 0 (ends the burst) or more")
            }
            SettingError::InterfaceName { name } => write!(f, "interface name {name:?} contains a NUL byte"),
            SettingError::BusyPollRealTime => f.write_str(
                "a busy-polling simulator must run under the normal scheduler, not SCHED_FIFO or SCHED_RR: \
                 the kernel stops a real-time thread that never sleeps for 50 ms of every second \
                 (sched_rt_runtime_us), and it would take its CPU from every other thread meanwhile",
            ),
            SettingError::Address { what, value, form } => write!(f, "{what} {value:?} is not of the form {form}"),
        }
    }
}

/// A name that is none of the allowed ones; the text lists them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum UnknownName {
    /// An AL state name.
    AlState {
        /// The name given.
        name: String,
    },
    /// A CiA 402 state name.
    DriveState {
        /// The name given.
        name: String,
        /// The states' names.
        allowed: Vec<&'static str>,
    },
    /// A fault the virtual AKD does not raise.
    Fault {
        /// The name given.
        name: String,
        /// The faults' names and numbers, e.g. "sync_lost (F125)".
        allowed: Vec<String>,
    },
    /// A latch edge name.
    LatchEdge {
        /// The name given.
        name: String,
    },
    /// A command time-out policy name.
    CommandTimeoutPolicy {
        /// The name given.
        name: String,
    },
    /// How virtual AKDs judge missed frames.
    MissedFrames {
        /// The name given.
        name: String,
    },
    /// How a virtual AKD's homing fails.
    HomingFailure {
        /// The name given.
        name: String,
    },
    /// How fast virtual AKDs answer.
    Pace {
        /// The name given.
        name: String,
    },
}

impl fmt::Display for UnknownName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            UnknownName::AlState { name } => {
                write!(f, "unknown AL state {name:?} (allowed: init, preop, safeop, op, bootstrap)")
            }
            UnknownName::DriveState { name, allowed } => {
                write!(f, "unknown state {name:?} (allowed: {})", allowed.join(", "))
            }
            UnknownName::Fault { name, allowed } => {
                write!(f, "no fault named {name:?}: the virtual AKD raises {}", allowed.join(", "))
            }
            UnknownName::LatchEdge { name } => write!(f, "latch edge {name:?}: allowed \"rising\" or \"falling\""),
            UnknownName::CommandTimeoutPolicy { name } => {
                write!(f, "command timeout policy {name:?}: allowed \"hold\" or \"quick_stop\"")
            }
            UnknownName::MissedFrames { name } => write!(
                f,
                "missed frames judged {name:?}: allowed \"late\" (as the real drive), \"lost\" (only frames lost on \
                 the line) or \"warn\" (as the real drive, a would-be F125 counted and warned of, not raised)"
            ),
            UnknownName::Pace { name } => write!(
                f,
                "virtual AKD pace {name:?}: allowed \"real\" (as the real drive) or \"immediate\" (requests handled \
                 at once)"
            ),
            UnknownName::HomingFailure { name } => {
                write!(f, "homing failure {name:?}: allowed ok, error, no_reference")
            }
        }
    }
}

/// An operation that the master, the cycle thread or the simulator cannot do in the state it
/// is in; the text says what would make it possible.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Unavailable {
    /// Homing needs modes of operation and its display in the process data.
    HomingUnmapped {
        /// The slave's position.
        slave: u16,
    },
    /// Homing starts only in Operation enabled.
    HomingNotEnabled {
        /// The slave's position.
        slave: u16,
        /// The state it is in.
        state: &'static str,
    },
    /// No process image: the slaves were not taken to SafeOp.
    NoProcessImage,
    /// A slave without process data in the image.
    NoProcessData {
        /// Slave position.
        slave: u16,
        /// The slaves that have process data, when the cycle thread knows them.
        with_data: Option<Vec<u16>>,
    },
    /// Supervision asked of a bus without slaves.
    NoSlaves,
    /// Distributed clocks asked of a bus where no slave has one.
    NoDistributedClock,
    /// The cycle thread is stopped.
    CycleStopped {
        /// What no longer happens, e.g. "set-points no longer go out".
        consequence: Cow<'static, str>,
    },
    /// The cycle thread was stopped before.
    CycleAlreadyStopped,
    /// The slave is lost and being brought back: its mailbox is the recovery's meanwhile.
    Recovering {
        /// The slave's position.
        slave: u16,
    },
    /// The cycle thread panicked and took the master with it.
    CyclePanicked,
    /// A drive whose mapping lacks what the CiA 402 sequencer needs.
    NotSequenced {
        /// Slave position, once known.
        slave: Option<u16>,
        /// What the mapping lacks.
        missing: Vec<&'static str>,
    },
    /// A slave without a mapping, asked of the cycle thread.
    NoMapping {
        /// Slave position.
        slave: u16,
    },
    /// A latch asked of a slave whose mapping carries none.
    NoLatch {
        /// Slave position.
        slave: u16,
    },
    /// Latch edges whose latched positions the mapping does not carry.
    LatchEdgesUnreadable {
        /// Slave position.
        slave: u16,
        /// Edge bits asked for and not readable.
        missing: u8,
        /// Edge bits readable.
        readable: u8,
    },
    /// A trajectory id that was never given, or whose status is no longer kept.
    NoSuchTrajectory {
        /// The id asked for.
        id: u32,
        /// The first and last ids whose statuses are kept, if any.
        kept: Option<(u32, u32)>,
    },
    /// A set-point handshake waited for where none was asked.
    NoHandshake {
        /// Drive position.
        position: u16,
    },
    /// A command time-out asked of a drive whose mapping does not carry what it watches.
    CommandTimeoutUnwatched {
        /// Slave position.
        slave: u16,
        /// What the mapping lacks.
        missing: &'static str,
    },
    /// An object that is not in the slave's output mapping.
    NotInOutputs {
        /// Slave position.
        slave: u16,
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
    },
    /// A cyclic frame sent while the last one's return was not taken yet.
    CyclicFrameInFlight,
    /// A cyclic frame's return asked for where none was sent.
    NoCyclicFrameInFlight,
    /// The master was closed, or is held by a cycle thread.
    MasterClosed,
    /// The master is in use by another thread.
    MasterBusy,
    /// A simulator asked of a link that is not in-process.
    NoSimulator,
    /// The simulator's server thread panicked.
    SimulatorPanicked,
    /// A set-point trace that cannot take a server.
    SetpointTrace {
        /// The trace file.
        path: String,
        /// Why not: closed, or taken by another server.
        why: &'static str,
    },
    /// The virtual AKDs are gone with their master or server.
    SimulatorGone,
    /// A virtual AKD whose bus served no frame in time to answer a query.
    SimulatorSilent {
        /// Drive position, or `None` for a query of the line's counts.
        position: Option<usize>,
        /// How long the query waited.
        timeout: std::time::Duration,
    },
}

impl fmt::Display for Unavailable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Unavailable::NoProcessImage => write!(f, "no process image yet: take the slaves to SafeOp first"),
            Unavailable::HomingUnmapped { slave } => write!(
                f,
                "slave {slave} cannot home from the cycle: its mapping lacks modes of operation 0x6060 (outputs) or \
                 its display 0x6061 (inputs); map both (akd_ros's default mapping has them)"
            ),
            Unavailable::HomingNotEnabled { slave, state } => {
                write!(f, "slave {slave} cannot home: it is in {state}, not Operation enabled; enable it first")
            }
            Unavailable::NoProcessData { slave, with_data: None } => {
                write!(f, "slave {slave} has no process data (map it, then go to SafeOp)")
            }
            Unavailable::NoProcessData { slave, with_data: Some(with) } => {
                write!(f, "slave {slave} has no process data (slaves with process data: {with:?})")
            }
            Unavailable::NoSlaves => write!(f, "supervision needs at least one slave"),
            Unavailable::NoDistributedClock => {
                write!(f, "no slave on the bus has a distributed clock (ESC feature bit 2)")
            }
            Unavailable::CycleStopped { consequence } => write!(f, "the cycle is stopped: {consequence}"),
            Unavailable::CycleAlreadyStopped => write!(f, "the cycle thread was already stopped"),
            Unavailable::Recovering { slave } => write!(
                f,
                "slave {slave} is unreachable and being brought back; its objects can be read and written again once \
                 it is back in Op (see recovery_status)"
            ),
            Unavailable::CyclePanicked => write!(f, "the cycle thread panicked; the master is lost"),
            Unavailable::NotSequenced { slave, missing } => {
                if let Some(slave) = slave {
                    write!(f, "slave {slave}: ")?;
                }
                write!(f, "the drive cannot be sequenced: its mapping lacks {}", missing.join(" and "))
            }
            Unavailable::NoMapping { slave } => write!(f, "slave {slave} has no process-data mapping"),
            Unavailable::NoLatch { slave } => write!(
                f,
                "slave {slave}'s mapping carries no latch: map latch control 0x20A4 and latch status 0x20A5 with a \
                 latched position (0x20A0..0x20A3, 0x20A6, 0x20A7), or the touch probe 0x60B8/0x60B9 with \
                 0x60BA..0x60BD"
            ),
            Unavailable::LatchEdgesUnreadable { slave, missing, readable } => write!(
                f,
                "slave {slave}'s mapping carries no latched position for edge bits 0x{missing:X} (readable: \
                 0x{readable:X}; bit 0 latch 1 rising, 1 latch 1 falling, 2 latch 2 rising, 3 latch 2 falling)"
            ),
            Unavailable::NoSuchTrajectory { id, kept: Some((first, last)) } => {
                write!(f, "no trajectory {id}: the statuses of trajectories {first} ..= {last} are kept")
            }
            Unavailable::NoSuchTrajectory { id, kept: None } => write!(f, "no trajectory {id}: none was played"),
            Unavailable::NoHandshake { position } => {
                write!(f, "drive {position}: no set-point handshake was asked for")
            }
            Unavailable::CommandTimeoutUnwatched { slave, missing } => {
                write!(f, "slave {slave}: the command time-out watches mapped targets, and the mapping lacks {missing}")
            }
            Unavailable::NotInOutputs { slave, index, subindex } => {
                write!(f, "0x{index:04X}:{subindex:02X} is not in slave {slave}'s output mapping")
            }
            Unavailable::CyclicFrameInFlight => write!(
                f,
                "a cyclic frame is already on its way: take its return with receive_process_data before sending \
                 the next"
            ),
            Unavailable::NoCyclicFrameInFlight => {
                write!(f, "no cyclic frame is on its way: send one with send_process_data first")
            }
            Unavailable::MasterClosed => {
                write!(f, "the master is closed, or handed to a Cycle (stop the Cycle to get it back)")
            }
            Unavailable::MasterBusy => {
                write!(f, "the master is in use by another thread; use one master from one thread at a time")
            }
            Unavailable::NoSimulator => write!(
                f,
                "Master.simulator is there for the in-process links \"sim\" and \"sim:N\" only; an akd-sim server \
                 takes its commands on stdin"
            ),
            Unavailable::SimulatorPanicked => write!(f, "the simulator thread panicked"),
            Unavailable::SetpointTrace { path, why } => write!(f, "the set-point trace {path} {why}"),
            Unavailable::SimulatorGone => {
                write!(f, "the virtual AKDs are gone: their master was closed or their server stopped")
            }
            Unavailable::SimulatorSilent { position, timeout } => write!(
                f,
                "{} not answered within {timeout:?}: the drives answer when their bus serves a frame and none passed \
                 (an idle in-process master exchanges no frames: start a Cycle, or query while a master call runs)",
                match position {
                    Some(position) => format!("the state of virtual AKD {position} was"),
                    None => "the line's counts were".to_owned(),
                }
            ),
        }
    }
}

/// Why a trajectory is refused before anything moves. Points and joints count from 0, in the
/// order given; positions are counts, velocities counts/s, accelerations counts/s².
#[derive(Clone, Debug, PartialEq)]
pub enum TrajectoryError {
    /// A trajectory for no joint.
    NoJoints,
    /// A trajectory of no point.
    NoPoints,
    /// Points and their times of different numbers.
    TimesCount {
        /// Points given.
        points: usize,
        /// Times given.
        times: usize,
    },
    /// A point with another number of values than the trajectory has joints.
    JointCount {
        /// The point.
        point: usize,
        /// Values it gives.
        given: usize,
        /// Joints of the trajectory.
        joints: usize,
    },
    /// Limits for another number of joints than the trajectory has.
    LimitsCount {
        /// Limits given.
        given: usize,
        /// Joints of the trajectory.
        joints: usize,
    },
    /// Tolerances for another number of joints than the trajectory has.
    TolerancesCount {
        /// Tolerances given.
        given: usize,
        /// Joints of the trajectory.
        joints: usize,
    },
    /// A joint's limits that are not finite or whose minimum is above the maximum.
    BadLimits {
        /// The joint.
        joint: usize,
        /// The minimum given.
        min: f64,
        /// The maximum given.
        max: f64,
    },
    /// A point's time from the start that is not after the previous point's (or, for the first
    /// point, after the start).
    TimeNotIncreasing {
        /// The point.
        point: usize,
        /// Its time from the start, ns.
        time_ns: u64,
        /// The time it must be after, ns (0: the start).
        after_ns: u64,
    },
    /// A position, velocity or acceleration that is NaN or infinite.
    NotFinite {
        /// The point.
        point: usize,
        /// The joint.
        joint: usize,
        /// "position", "velocity" or "acceleration".
        what: &'static str,
        /// The value given.
        value: f64,
    },
    /// A position outside the joint's limits.
    OutOfLimits {
        /// The point.
        point: usize,
        /// The joint.
        joint: usize,
        /// The position given.
        position: f64,
        /// The joint's minimum.
        min: f64,
        /// The joint's maximum.
        max: f64,
    },
    /// An acceleration given without a velocity (a quintic segment needs both).
    AccelerationWithoutVelocity {
        /// The point.
        point: usize,
        /// The joint.
        joint: usize,
    },
    /// A drive named for two joints.
    DriveTwice {
        /// The drive's position on the bus.
        slave: u16,
        /// The first joint it was named for.
        first: usize,
        /// The second.
        second: usize,
    },
    /// A drive that cannot follow a trajectory now: not on the bus, not sequenced, not in
    /// Operation enabled, not in a cyclic position mode, or without its position target mapped.
    DriveNotReady {
        /// The joint.
        joint: usize,
        /// The drive's position on the bus.
        slave: u16,
        /// Why, with what it would need.
        why: String,
    },
}

impl fmt::Display for TrajectoryError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "trajectory refused, nothing moved: ")?;
        match self {
            TrajectoryError::NoJoints => write!(f, "it names no joint; at least one is needed"),
            TrajectoryError::NoPoints => write!(f, "it has no point; at least one is needed"),
            TrajectoryError::TimesCount { points, times } => {
                write!(f, "{points} point(s) but {times} time(s) from the start; one time per point is needed")
            }
            TrajectoryError::JointCount { point, given, joints } => {
                write!(f, "point {point} gives {given} joint value(s); the trajectory has {joints} joint(s)")
            }
            TrajectoryError::LimitsCount { given, joints } => {
                write!(f, "{given} joint limit(s) given; the trajectory has {joints} joint(s)")
            }
            TrajectoryError::TolerancesCount { given, joints } => {
                write!(f, "{given} joint tolerance(s) given; the trajectory has {joints} joint(s)")
            }
            TrajectoryError::BadLimits { joint, min, max } => {
                write!(f, "joint {joint}: limits {min} ..= {max} counts; they must be finite with min <= max")
            }
            TrajectoryError::TimeNotIncreasing { point, time_ns, after_ns: 0 } => write!(
                f,
                "point {point}: time from the start {time_ns} ns; the first point's must be after the start (> 0 ns)"
            ),
            TrajectoryError::TimeNotIncreasing { point, time_ns, after_ns } => write!(
                f,
                "point {point}: time from the start {time_ns} ns is not after the previous point's {after_ns} ns; \
                 times must increase strictly"
            ),
            TrajectoryError::NotFinite { point, joint, what, value } => {
                write!(f, "point {point}, joint {joint}: {what} {value}; it must be a finite number")
            }
            TrajectoryError::OutOfLimits { point, joint, position, min, max } => write!(
                f,
                "point {point}, joint {joint}: position {position} counts is outside the joint's limits \
                 {min} ..= {max} counts"
            ),
            TrajectoryError::AccelerationWithoutVelocity { point, joint } => write!(
                f,
                "point {point}, joint {joint}: an acceleration without a velocity; give both (quintic), the \
                 velocity alone (cubic) or neither (linear)"
            ),
            TrajectoryError::DriveTwice { slave, first, second } => {
                write!(f, "drive {slave} is named for joints {first} and {second}; each drive may be one joint")
            }
            TrajectoryError::DriveNotReady { joint, slave, why } => write!(f, "joint {joint} (drive {slave}): {why}"),
        }
    }
}

/// Any failure of the master or of a link.
#[derive(Debug)]
pub enum Error {
    /// A malformed frame.
    Frame(FrameError),
    /// The operating system refused an operation on a link (socket, interface).
    Io {
        /// What was being done.
        context: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// No reply in time.
    Timeout {
        /// What was awaited; a fixed text where the cycle thread may meet it, which must not
        /// allocate even when a frame is lost.
        what: Cow<'static, str>,
    },
    /// A datagram's working counter was not the expected one.
    WorkingCounter {
        /// What the datagram did (a fixed text in the cycle, as for a time-out).
        what: Cow<'static, str>,
        /// The expected WKC.
        expected: u16,
        /// The WKC received.
        got: u16,
    },
    /// A slave refused or failed an AL state change.
    AlState {
        /// Slave position on the bus.
        slave: u16,
        /// The state requested.
        requested: &'static str,
        /// The state the slave is in.
        actual: &'static str,
        /// AL status code (register 0x0134).
        code: u16,
        /// The code's name.
        code_name: &'static str,
    },
    /// An SDO transfer was aborted by the slave or by the master.
    SdoAbort {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// Abort code.
        code: u32,
        /// The abort code's name.
        code_name: &'static str,
    },
    /// A mailbox reply that does not fit the request or the protocol.
    Mailbox(MailboxError),
    /// The SII EEPROM content or its interface is not as expected.
    Sii(SiiError),
    /// A process-data mapping that the AKD would refuse, or an unknown one.
    Pdo(PdoError),
    /// A link spec that names no link.
    LinkSpec(LinkSpecError),
    /// A value given for a setting outside what it allows.
    Setting(SettingError),
    /// A name that is none of the allowed ones.
    UnknownName(UnknownName),
    /// An operation not possible in the present state of the master, cycle or simulator.
    Unavailable(Unavailable),
    /// A station alias that is on no slave or on several, so it names no one drive.
    AliasNotUnique {
        /// The alias asked for.
        alias: u16,
        /// Slaves that have it.
        count: usize,
    },
    /// Another device answers at a slave's position than the scan found there (a drive swapped
    /// while the bus ran): it is not configured as if it were the old one.
    Replaced {
        /// The position.
        slave: u16,
        /// What the scan found there.
        expected: crate::sii::Identity,
        /// What answers now.
        found: crate::sii::Identity,
    },
    /// A slave position that is not on the bus.
    NoSuchSlave {
        /// The position asked for.
        position: u16,
        /// Slaves found.
        count: u16,
    },
    /// A trajectory refused before anything moved.
    Trajectory(TrajectoryError),
    /// An Ethernet-over-EtherCAT message or frame that does not fit the standard.
    Eoe(EoeError),
    /// A file transfer over EtherCAT that failed or a message that does not fit the standard.
    Foe(FoeError),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Frame(e) => write!(f, "{e}"),
            Error::Io { context, source } => write!(f, "{context}: {source}"),
            Error::Timeout { what } => write!(f, "timed out waiting for {what}"),
            Error::WorkingCounter { what, expected, got } => {
                write!(f, "working counter error on {what}: expected {expected}, got {got}")
            }
            Error::AlState { slave, requested, actual, code, code_name } => write!(
                f,
                "slave {slave} did not reach {requested}: it is in {actual}, AL status code 0x{code:04X} ({code_name})"
            ),
            Error::SdoAbort { index, subindex, code, code_name } => {
                write!(f, "SDO 0x{index:04X}:{subindex:02X} aborted with 0x{code:08X} ({code_name})")
            }
            Error::Mailbox(m) => write!(f, "mailbox: {m}"),
            Error::Sii(m) => write!(f, "SII: {m}"),
            Error::Pdo(m) => write!(f, "PDO mapping: {m}"),
            Error::LinkSpec(e) => write!(f, "configuration: {e}"),
            Error::Setting(e) => write!(f, "configuration: {e}"),
            Error::UnknownName(e) => write!(f, "configuration: {e}"),
            Error::Unavailable(e) => write!(f, "configuration: {e}"),
            Error::AliasNotUnique { alias, count } => {
                write!(f, "station alias {alias} is on {count} slave(s), not one")
            }
            Error::Replaced { slave, expected: e, found: n } => write!(
                f,
                "another device is at position {slave}: vendor 0x{:X}, product 0x{:X}, serial {} where the scan found \
                 vendor 0x{:X}, product 0x{:X}, serial {}; it is not configured as the old one (restart the bus to \
                 take it)",
                n.vendor_id, n.product_code, n.serial_number, e.vendor_id, e.product_code, e.serial_number
            ),
            Error::NoSuchSlave { position, count } => {
                write!(f, "no slave at position {position}: the bus has {count} slave(s)")
            }
            Error::Trajectory(e) => write!(f, "{e}"),
            Error::Eoe(e) => write!(f, "EoE: {e}"),
            Error::Foe(e) => write!(f, "FoE: {e}"),
        }
    }
}

impl std::error::Error for Error {}

/// `From` of each sub-error into the [`Error`] variant that carries it, so `?` lifts it.
macro_rules! error_from {
    ($($sub:ident => $variant:ident),+ $(,)?) => {
        $(impl From<$sub> for Error {
            fn from(e: $sub) -> Self {
                Error::$variant(e)
            }
        })+
    };
}

error_from! {
    MailboxError => Mailbox,
    SiiError => Sii,
    PdoError => Pdo,
    SettingError => Setting,
    UnknownName => UnknownName,
    Unavailable => Unavailable,
    LinkSpecError => LinkSpec,
    FrameError => Frame,
    TrajectoryError => Trajectory,
    EoeError => Eoe,
    FoeError => Foe,
}

impl From<UnknownCode> for Error {
    fn from(e: UnknownCode) -> Self {
        Error::Mailbox(MailboxError::UnknownCode(e))
    }
}

/// Result of master and link operations.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An I/O error with what was being done.
    pub fn io(context: impl Into<String>, source: std::io::Error) -> Self {
        Error::Io { context: context.into(), source }
    }

    /// The last OS error with what was being done.
    pub fn last_os(context: impl Into<String>) -> Self {
        Error::io(context, std::io::Error::last_os_error())
    }
}

impl std::error::Error for MailboxError {}
impl std::error::Error for SiiError {}
impl std::error::Error for PdoError {}
impl std::error::Error for SettingError {}
impl std::error::Error for UnknownName {}
impl std::error::Error for Unavailable {}
impl std::error::Error for TrajectoryError {}
impl std::error::Error for EoeError {}
impl std::error::Error for FoeError {}
