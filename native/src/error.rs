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
        /// The most virtual AKDs a bus may hold ([`MAX_SIM_COUNT`](crate::link::spec::MAX_SIM_COUNT)).
        max: usize,
    },
    /// None of the forms (empty, or a path or an address without `udp://`).
    Unknown {
        /// The spec as given.
        spec: String,
        /// As for [`SimCount`](LinkSpecError::SimCount), to name the allowed N.
        max_sim_count: usize,
    },
}

impl fmt::Display for LinkSpecError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LinkSpecError::SimCount { spec, max } => {
                write!(f, "link {spec:?}: the number of virtual AKDs must be 1..={max}")
            }
            LinkSpecError::Unknown { spec, max_sim_count } => write!(
                f,
                "link {spec:?} is none of \"sim\", \"sim:N\" (N 1..={max_sim_count}), \"udp://HOST:PORT\" or a network \
                 interface name"
            ),
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
    Mailbox(String),
    /// The SII EEPROM content or its interface is not as expected.
    Sii(String),
    /// A process-data mapping that the AKD would refuse, or an unknown one.
    Pdo(String),
    /// A link spec that names no link.
    LinkSpec(LinkSpecError),
    /// A configuration value out of its allowed range.
    Config(String),
    /// A station alias that is on no slave or on several, so it names no one drive.
    AliasNotUnique {
        /// The alias asked for.
        alias: u16,
        /// Slaves that have it.
        count: usize,
    },
    /// A slave position that is not on the bus.
    NoSuchSlave {
        /// The position asked for.
        position: u16,
        /// Slaves found.
        count: u16,
    },
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
            Error::Config(m) => write!(f, "configuration: {m}"),
            Error::AliasNotUnique { alias, count } => {
                write!(f, "station alias {alias} is on {count} slave(s), not one")
            }
            Error::NoSuchSlave { position, count } => {
                write!(f, "no slave at position {position}: the bus has {count} slave(s)")
            }
        }
    }
}

impl std::error::Error for Error {}

impl From<LinkSpecError> for Error {
    fn from(e: LinkSpecError) -> Self {
        Error::LinkSpec(e)
    }
}

impl From<FrameError> for Error {
    fn from(e: FrameError) -> Self {
        Error::Frame(e)
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
