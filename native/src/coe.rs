//! CANopen over EtherCAT codec (ETG.1000.6 §5.6, CiA 301, AKD manual §5.13).
//!
//! A CoE message is a mailbox message of type 3 whose body starts with a 2-byte CoE header
//! (number and service). This module encodes and decodes the SDO transfers (expedited, normal,
//! segmented, abort), emergency messages and the SDO information service, on both the client
//! (master) and server (virtual AKD) side. Values are borrowed from the caller's buffers.
use crate::mailbox::MailboxError;
use crate::mailbox::{MailboxHeader, MailboxType, HEADER_LEN};

/// Length of the CoE header.
pub const COE_HEADER_LEN: usize = 2;
/// Length of an SDO initiate message (command, index, subindex, 4 data bytes).
pub const SDO_LEN: usize = 8;
/// Minimum data area of an SDO segment (shorter data is padded and its size given by `n`).
pub const SEGMENT_MIN_DATA: usize = 7;
/// Offset of the SDO body from the start of the mailbox message.
pub const SDO_OFFSET: usize = HEADER_LEN + COE_HEADER_LEN;
/// Length of the SDO information header (opcode, reserved, fragments left).
pub const SDO_INFO_HEADER_LEN: usize = 4;

wire_codes! {
    /// CoE services (CoE header bits 12–15, ETG.1000.6 Table 29).
    pub enum CoeService: u8, "CoE service" {
        /// Emergency message.
        Emergency = 1 => "Emergency",
        /// SDO request (master to slave).
        SdoRequest = 2 => "SDO Request",
        /// SDO response (slave to master).
        SdoResponse = 3 => "SDO Response",
        /// TxPDO.
        TxPdo = 4 => "TxPDO",
        /// RxPDO.
        RxPdo = 5 => "RxPDO",
        /// TxPDO remote request.
        TxPdoRemoteRequest = 6 => "TxPDO remote request",
        /// RxPDO remote request.
        RxPdoRemoteRequest = 7 => "RxPDO remote request",
        /// SDO information.
        SdoInformation = 8 => "SDO Information",
    }
}

wire_codes! {
    /// Client command specifiers of an SDO request (command byte bits 5–7, CiA 301 §7.2.4.3).
    pub enum ClientCommand: u8, "SDO client command specifier" {
        /// Download segment request.
        DownloadSegment = 0 => "download segment request",
        /// Initiate download request.
        InitiateDownload = 1 => "initiate download request",
        /// Initiate upload request.
        InitiateUpload = 2 => "initiate upload request",
        /// Upload segment request.
        UploadSegment = 3 => "upload segment request",
        /// Abort transfer.
        Abort = 4 => "abort transfer",
    }
}

wire_codes! {
    /// Server command specifiers of an SDO response (command byte bits 5–7, CiA 301 §7.2.4.3).
    pub enum ServerCommand: u8, "SDO server command specifier" {
        /// Upload segment response.
        UploadSegment = 0 => "upload segment response",
        /// Download segment response.
        DownloadSegment = 1 => "download segment response",
        /// Initiate upload response.
        InitiateUpload = 2 => "initiate upload response",
        /// Initiate download response.
        InitiateDownload = 3 => "initiate download response",
        /// Abort transfer.
        Abort = 4 => "abort transfer",
    }
}

/// The command byte's specifier bits for `specifier` (bits 5–7).
fn specifier_bits(specifier: u8) -> u8 {
    specifier << 5
}

/// The CoE header: a 9-bit number (PDO number, unused for SDO) and the service.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CoeHeader {
    /// Number (bits 0–8).
    pub number: u16,
    /// Service (bits 12–15).
    pub service: CoeService,
}

impl CoeHeader {
    /// A header for `service` with number 0.
    pub fn new(service: CoeService) -> Self {
        CoeHeader { number: 0, service }
    }

    /// Decodes the first two bytes of a mailbox body; a service outside the standard's set is an
    /// error naming it.
    pub fn decode(body: &[u8]) -> Result<Self, MailboxError> {
        if body.len() < COE_HEADER_LEN {
            return Err(MailboxError::Truncated { what: "CoE message", len: body.len(), needed: COE_HEADER_LEN });
        }
        let word = u16::from_le_bytes([body[0], body[1]]);
        let service = CoeService::try_from((word >> 12) as u8)?;
        Ok(CoeHeader { number: word & 0x01FF, service })
    }

    /// Encodes into the first two bytes of `out`.
    pub fn encode(&self, out: &mut [u8]) {
        let word = (self.number & 0x01FF) | ((self.service as u16) << 12);
        out[..2].copy_from_slice(&word.to_le_bytes());
    }
}

/// An SDO request from client to server.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SdoRequest<'a> {
    /// Download of 1 to 4 bytes in one message.
    DownloadExpedited {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// Complete access (all subindices at once).
        complete_access: bool,
        /// The value, 1..=4 bytes.
        data: &'a [u8],
    },
    /// Start of a normal download: total size, and the first part of the data in this message.
    DownloadNormal {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// Complete access.
        complete_access: bool,
        /// Size of the whole value.
        complete_size: u32,
        /// The part of the value carried by this message.
        data: &'a [u8],
    },
    /// A further segment of a download.
    DownloadSegment {
        /// Toggle bit, alternating from 0.
        toggle: bool,
        /// No more segments follow.
        last: bool,
        /// The segment's data.
        data: &'a [u8],
    },
    /// Upload (read) request.
    Upload {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// Complete access.
        complete_access: bool,
    },
    /// Request for the next upload segment.
    UploadSegment {
        /// Toggle bit, alternating from 0.
        toggle: bool,
    },
    /// Abort of a transfer by the client.
    Abort {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// Abort code.
        code: SdoAbortCode,
    },
}

/// An SDO response from server to client.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SdoResponse<'a> {
    /// Upload of 1 to 4 bytes in one message.
    UploadExpedited {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// The value.
        data: &'a [u8],
    },
    /// Start of a normal upload: total size and the first part of the data.
    UploadNormal {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// Size of the whole value.
        complete_size: u32,
        /// The part carried by this message.
        data: &'a [u8],
    },
    /// A further segment of an upload.
    UploadSegment {
        /// Toggle bit of the request it answers.
        toggle: bool,
        /// No more segments follow.
        last: bool,
        /// The segment's data.
        data: &'a [u8],
    },
    /// Download accepted (initiate).
    Download {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
    },
    /// Download segment accepted.
    DownloadSegment {
        /// Toggle bit of the request it answers.
        toggle: bool,
    },
    /// Transfer aborted by the server.
    Abort {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// Abort code.
        code: SdoAbortCode,
    },
}

fn sdo_too_short(what: &'static str, len: usize) -> MailboxError {
    MailboxError::Truncated { what, len, needed: SDO_LEN }
}

fn address(body: &[u8]) -> (u16, u8) {
    (u16::from_le_bytes([body[1], body[2]]), body[3])
}

fn write_address(out: &mut [u8], command: u8, index: u16, subindex: u8) {
    out[0] = command;
    out[1..3].copy_from_slice(&index.to_le_bytes());
    out[3] = subindex;
}

/// Decodes the data of a segment: `n` (bits 1–3) counts padding bytes when the segment
/// carries the minimum of seven; longer segments carry exactly what the mailbox holds.
fn segment_data<'a>(body: &'a [u8], what: &'static str) -> Result<(bool, bool, &'a [u8]), MailboxError> {
    if body.len() < 1 + SEGMENT_MIN_DATA {
        return Err(sdo_too_short(what, body.len()));
    }
    let command = body[0];
    let unused = ((command >> 1) & 0x07) as usize;
    let area = &body[1..];
    let len = if area.len() == SEGMENT_MIN_DATA { SEGMENT_MIN_DATA - unused } else { area.len() };
    Ok((command & 0x10 != 0, command & 0x01 != 0, &area[..len]))
}

/// Writes a segment's command byte and data (padded to seven bytes); returns the body length.
fn write_segment(out: &mut [u8], base: u8, toggle: bool, last: bool, data: &[u8]) -> usize {
    let unused = SEGMENT_MIN_DATA.saturating_sub(data.len()) as u8;
    out[0] = base | ((toggle as u8) << 4) | (unused << 1) | last as u8;
    out[1..1 + data.len()].copy_from_slice(data);
    let len = 1 + data.len().max(SEGMENT_MIN_DATA);
    out[1 + data.len()..len].fill(0);
    len
}

/// Writes an expedited value: size indicated, `n` = unused bytes of the four.
fn write_expedited(out: &mut [u8], base: u8, index: u16, subindex: u8, data: &[u8]) {
    let unused = (4 - data.len()) as u8;
    write_address(out, base | (unused << 2) | 0x03, index, subindex);
    out[4..4 + data.len()].copy_from_slice(data);
    out[4 + data.len()..SDO_LEN].fill(0);
}

/// Reads an expedited value of an initiate message: size from `n` when indicated, else 4.
fn expedited_data(body: &[u8]) -> &[u8] {
    let command = body[0];
    let len = if command & 0x01 != 0 { 4 - ((command >> 2) & 0x03) as usize } else { 4 };
    &body[4..4 + len]
}

impl<'a> SdoRequest<'a> {
    /// Decodes the SDO part of a request (the bytes after the CoE header).
    pub fn decode(body: &'a [u8]) -> Result<Self, MailboxError> {
        let command = *body.first().ok_or_else(|| sdo_too_short("SDO request", 0))?;
        let ccs = ClientCommand::try_from(command >> 5)?;
        match ccs {
            ClientCommand::DownloadSegment => {
                let (toggle, last, data) = segment_data(body, "SDO download segment")?;
                Ok(SdoRequest::DownloadSegment { toggle, last, data })
            }
            ClientCommand::UploadSegment => Ok(SdoRequest::UploadSegment { toggle: command & 0x10 != 0 }),
            ClientCommand::InitiateDownload | ClientCommand::InitiateUpload | ClientCommand::Abort => {
                if body.len() < SDO_LEN {
                    return Err(sdo_too_short("SDO request", body.len()));
                }
                let (index, subindex) = address(body);
                let complete_access = command & 0x10 != 0;
                match ccs {
                    ClientCommand::InitiateDownload if command & 0x02 != 0 => Ok(SdoRequest::DownloadExpedited {
                        index,
                        subindex,
                        complete_access,
                        data: expedited_data(body),
                    }),
                    ClientCommand::InitiateDownload => Ok(SdoRequest::DownloadNormal {
                        index,
                        subindex,
                        complete_access,
                        complete_size: u32::from_le_bytes([body[4], body[5], body[6], body[7]]),
                        data: &body[SDO_LEN..],
                    }),
                    ClientCommand::InitiateUpload => Ok(SdoRequest::Upload { index, subindex, complete_access }),
                    // The arm above lets only an abort get here.
                    _ => Ok(SdoRequest::Abort {
                        index,
                        subindex,
                        code: SdoAbortCode(u32::from_le_bytes([body[4], body[5], body[6], body[7]])),
                    }),
                }
            }
        }
    }

    /// Encodes the SDO part into `out`; returns its length. Panics only if `out` is shorter
    /// than the message, which callers size from the mailbox.
    pub fn encode(&self, out: &mut [u8]) -> usize {
        match *self {
            SdoRequest::DownloadExpedited { index, subindex, complete_access, data } => {
                write_expedited(
                    out,
                    specifier_bits(ClientCommand::InitiateDownload as u8) | ((complete_access as u8) << 4),
                    index,
                    subindex,
                    data,
                );
                SDO_LEN
            }
            SdoRequest::DownloadNormal { index, subindex, complete_access, complete_size, data } => {
                write_address(
                    out,
                    specifier_bits(ClientCommand::InitiateDownload as u8) | 0x01 | ((complete_access as u8) << 4),
                    index,
                    subindex,
                );
                out[4..8].copy_from_slice(&complete_size.to_le_bytes());
                out[SDO_LEN..SDO_LEN + data.len()].copy_from_slice(data);
                SDO_LEN + data.len()
            }
            SdoRequest::DownloadSegment { toggle, last, data } => {
                write_segment(out, specifier_bits(ClientCommand::DownloadSegment as u8), toggle, last, data)
            }
            SdoRequest::Upload { index, subindex, complete_access } => {
                write_address(
                    out,
                    specifier_bits(ClientCommand::InitiateUpload as u8) | ((complete_access as u8) << 4),
                    index,
                    subindex,
                );
                out[4..SDO_LEN].fill(0);
                SDO_LEN
            }
            SdoRequest::UploadSegment { toggle } => {
                out[0] = specifier_bits(ClientCommand::UploadSegment as u8) | ((toggle as u8) << 4);
                out[1..SDO_LEN].fill(0);
                SDO_LEN
            }
            SdoRequest::Abort { index, subindex, code } => write_abort(out, index, subindex, code),
        }
    }
}

fn write_abort(out: &mut [u8], index: u16, subindex: u8, code: SdoAbortCode) -> usize {
    write_address(out, specifier_bits(ClientCommand::Abort as u8), index, subindex);
    out[4..8].copy_from_slice(&code.0.to_le_bytes());
    SDO_LEN
}

impl<'a> SdoResponse<'a> {
    /// Decodes the SDO part of a response (the bytes after the CoE header).
    pub fn decode(body: &'a [u8]) -> Result<Self, MailboxError> {
        let command = *body.first().ok_or_else(|| sdo_too_short("SDO response", 0))?;
        let scs = ServerCommand::try_from(command >> 5)?;
        match scs {
            ServerCommand::UploadSegment => {
                let (toggle, last, data) = segment_data(body, "SDO upload segment")?;
                Ok(SdoResponse::UploadSegment { toggle, last, data })
            }
            ServerCommand::DownloadSegment => Ok(SdoResponse::DownloadSegment { toggle: command & 0x10 != 0 }),
            ServerCommand::InitiateUpload | ServerCommand::InitiateDownload | ServerCommand::Abort => {
                if body.len() < SDO_LEN {
                    return Err(sdo_too_short("SDO response", body.len()));
                }
                let (index, subindex) = address(body);
                let word = u32::from_le_bytes([body[4], body[5], body[6], body[7]]);
                match scs {
                    ServerCommand::InitiateUpload if command & 0x02 != 0 => {
                        Ok(SdoResponse::UploadExpedited { index, subindex, data: expedited_data(body) })
                    }
                    ServerCommand::InitiateUpload => {
                        Ok(SdoResponse::UploadNormal { index, subindex, complete_size: word, data: &body[SDO_LEN..] })
                    }
                    ServerCommand::InitiateDownload => Ok(SdoResponse::Download { index, subindex }),
                    // The arm above lets only an abort get here.
                    _ => Ok(SdoResponse::Abort { index, subindex, code: SdoAbortCode(word) }),
                }
            }
        }
    }

    /// Encodes the SDO part into `out`; returns its length.
    pub fn encode(&self, out: &mut [u8]) -> usize {
        match *self {
            SdoResponse::UploadExpedited { index, subindex, data } => {
                write_expedited(out, specifier_bits(ServerCommand::InitiateUpload as u8), index, subindex, data);
                SDO_LEN
            }
            SdoResponse::UploadNormal { index, subindex, complete_size, data } => {
                write_address(out, specifier_bits(ServerCommand::InitiateUpload as u8) | 0x01, index, subindex);
                out[4..8].copy_from_slice(&complete_size.to_le_bytes());
                out[SDO_LEN..SDO_LEN + data.len()].copy_from_slice(data);
                SDO_LEN + data.len()
            }
            SdoResponse::UploadSegment { toggle, last, data } => {
                write_segment(out, specifier_bits(ServerCommand::UploadSegment as u8), toggle, last, data)
            }
            SdoResponse::Download { index, subindex } => {
                write_address(out, specifier_bits(ServerCommand::InitiateDownload as u8), index, subindex);
                out[4..SDO_LEN].fill(0);
                SDO_LEN
            }
            SdoResponse::DownloadSegment { toggle } => {
                out[0] = specifier_bits(ServerCommand::DownloadSegment as u8) | ((toggle as u8) << 4);
                out[1..SDO_LEN].fill(0);
                SDO_LEN
            }
            SdoResponse::Abort { index, subindex, code } => write_abort(out, index, subindex, code),
        }
    }
}

/// Writes a whole CoE mailbox message: mailbox header, CoE header for `service`, and a body
/// written by `body` into the space after them. Returns the message length.
pub fn write_message(out: &mut [u8], counter: u8, service: CoeService, body: impl FnOnce(&mut [u8]) -> usize) -> usize {
    let len = body(&mut out[SDO_OFFSET..]);
    MailboxHeader::new(MailboxType::Coe, (COE_HEADER_LEN + len) as u16, counter).encode(out);
    CoeHeader::new(service).encode(&mut out[HEADER_LEN..]);
    SDO_OFFSET + len
}

/// Writes a complete SDO request message; returns its length.
pub fn write_sdo_request(out: &mut [u8], counter: u8, request: &SdoRequest<'_>) -> usize {
    write_message(out, counter, CoeService::SdoRequest, |b| request.encode(b))
}

/// Writes a complete SDO response message; returns its length.
pub fn write_sdo_response(out: &mut [u8], counter: u8, response: &SdoResponse<'_>) -> usize {
    write_message(out, counter, CoeService::SdoResponse, |b| response.encode(b))
}

/// Splits a CoE mailbox message into its mailbox header, CoE header and the body after them.
pub fn split_message(message: &[u8]) -> Result<(MailboxHeader, CoeHeader, &[u8]), MailboxError> {
    let header = MailboxHeader::decode(message)?;
    if header.protocol() != Some(MailboxType::Coe) {
        return Err(MailboxError::NotCoe { mailbox_type: header.mailbox_type });
    }
    let body = header.body(message);
    let coe = CoeHeader::decode(body)?;
    Ok((header, coe, &body[COE_HEADER_LEN..]))
}

wire_codes! {
    /// An SDO abort code (CiA 301 §7.2.4.3.17, AKD manual §5.13). A slave may abort with a code
    /// outside the standard's list (a manufacturer's), so this is the wire value with the
    /// standard's codes as constants and [`name`](SdoAbortCode::name) for any of them.
    pub struct SdoAbortCode(u32) {
        /// Toggle bit not alternated.
        TOGGLE_BIT = 0x0503_0000 => "toggle bit not alternated",
        /// SDO protocol timed out.
        TIMEOUT = 0x0504_0000 => "SDO protocol timed out",
        /// Client/server command specifier not valid or unknown.
        BAD_COMMAND = 0x0504_0001 => "client/server command specifier not valid or unknown",
        0x0504_0002 => "invalid block size",
        0x0504_0003 => "invalid sequence number",
        0x0504_0004 => "CRC error",
        /// Out of memory.
        OUT_OF_MEMORY = 0x0504_0005 => "out of memory",
        /// Unsupported access to an object.
        UNSUPPORTED_ACCESS = 0x0601_0000 => "unsupported access to an object",
        /// Attempt to read a write-only object.
        WRITE_ONLY = 0x0601_0001 => "attempt to read a write-only object",
        /// Attempt to write a read-only object.
        READ_ONLY = 0x0601_0002 => "attempt to write a read-only object",
        /// Subindex cannot be written, sub 0 must be 0 for write access.
        SUBINDEX_WRITE_NEEDS_ZERO = 0x0601_0003 => "subindex cannot be written, subindex 0 must be 0 for write access",
        /// Complete access not supported.
        COMPLETE_ACCESS_UNSUPPORTED = 0x0601_0004 => "complete access not supported for objects of variable length",
        0x0601_0005 => "object length exceeds mailbox size",
        0x0601_0006 => "object mapped to RxPDO, SDO download blocked",
        /// Object does not exist in the object dictionary.
        NO_SUCH_OBJECT = 0x0602_0000 => "object does not exist in the object dictionary",
        /// Object cannot be mapped to the PDO.
        NOT_MAPPABLE = 0x0604_0041 => "object cannot be mapped to the PDO",
        /// The number and length of the objects to be mapped would exceed the PDO length.
        PDO_TOO_LONG = 0x0604_0042 => "number and length of mapped objects exceed the PDO length",
        /// General parameter incompatibility.
        PARAMETER_INCOMPATIBLE = 0x0604_0043 => "general parameter incompatibility",
        /// General internal incompatibility in the device.
        DEVICE_INCOMPATIBLE = 0x0604_0047 => "general internal incompatibility in the device",
        /// Access failed due to a hardware error.
        HARDWARE_ERROR = 0x0606_0000 => "access failed due to a hardware error",
        /// Data type does not match, length of service parameter does not match.
        LENGTH_MISMATCH = 0x0607_0010 => "data type does not match, length of service parameter does not match",
        /// Data type does not match, length of service parameter too high.
        LENGTH_TOO_HIGH = 0x0607_0012 => "data type does not match, length of service parameter too high",
        /// Data type does not match, length of service parameter too low.
        LENGTH_TOO_LOW = 0x0607_0013 => "data type does not match, length of service parameter too low",
        /// Subindex does not exist.
        NO_SUCH_SUBINDEX = 0x0609_0011 => "subindex does not exist",
        /// Value range of parameter exceeded (download only).
        VALUE_RANGE = 0x0609_0030 => "value range of parameter exceeded",
        /// Value of parameter written too high.
        VALUE_TOO_HIGH = 0x0609_0031 => "value of parameter written too high",
        /// Value of parameter written too low.
        VALUE_TOO_LOW = 0x0609_0032 => "value of parameter written too low",
        /// Maximum value is less than minimum value.
        MAX_BELOW_MIN = 0x0609_0036 => "maximum value is less than minimum value",
        /// General error.
        GENERAL = 0x0800_0000 => "general error",
        /// Data cannot be transferred or stored to the application.
        CANNOT_STORE = 0x0800_0020 => "data cannot be transferred or stored to the application",
        /// Data cannot be transferred because of local control.
        LOCAL_CONTROL = 0x0800_0021 => "data cannot be transferred or stored because of local control",
        /// Data cannot be transferred because of the present device state.
        DEVICE_STATE = 0x0800_0022 => "data cannot be transferred or stored because of the present device state",
        /// Object dictionary dynamic generation fails or no object dictionary is present.
        NO_OBJECT_DICTIONARY = 0x0800_0023 => "no object dictionary is present",
    } else {
        _ => "unknown abort code",
    }
}

/// An emergency message (CoE service 1): CiA error code, error register, 5 bytes of
/// manufacturer data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
// Python gets a dict keyed by the field names (akd_ros._native): renaming a field renames a key.
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObject))]
pub struct Emergency {
    /// CiA 301 / 402 error code, also readable in 0x603F on the AKD.
    pub error_code: u16,
    /// Error register (0x1001).
    pub error_register: u8,
    /// Manufacturer-specific data.
    pub data: [u8; 5],
}

/// Length of an emergency message body after the CoE header.
pub const EMERGENCY_LEN: usize = 8;

impl Emergency {
    /// Decodes the body after the CoE header.
    pub fn decode(body: &[u8]) -> Result<Self, MailboxError> {
        if body.len() < EMERGENCY_LEN {
            return Err(MailboxError::Truncated { what: "emergency message", len: body.len(), needed: EMERGENCY_LEN });
        }
        let mut data = [0; 5];
        data.copy_from_slice(&body[3..8]);
        Ok(Emergency { error_code: u16::from_le_bytes([body[0], body[1]]), error_register: body[2], data })
    }

    /// Encodes the body after the CoE header; returns its length.
    pub fn encode(&self, out: &mut [u8]) -> usize {
        out[0..2].copy_from_slice(&self.error_code.to_le_bytes());
        out[2] = self.error_register;
        out[3..8].copy_from_slice(&self.data);
        EMERGENCY_LEN
    }
}

wire_codes! {
    /// SDO information opcodes (ETG.1000.6 §5.6.3).
    pub enum SdoInfoOpcode: u8, "SDO information opcode" {
        /// Get OD list request.
        GetOdListRequest = 0x01 => "Get OD List Request",
        /// Get OD list response.
        GetOdListResponse = 0x02 => "Get OD List Response",
        /// Get object description request.
        GetObjectDescriptionRequest = 0x03 => "Get Object Description Request",
        /// Get object description response.
        GetObjectDescriptionResponse = 0x04 => "Get Object Description Response",
        /// Get entry description request.
        GetEntryDescriptionRequest = 0x05 => "Get Entry Description Request",
        /// Get entry description response.
        GetEntryDescriptionResponse = 0x06 => "Get Entry Description Response",
        /// SDO information error request (carries an abort code).
        SdoInfoErrorRequest = 0x07 => "SDO Info Error Request",
    }
}

impl SdoInfoOpcode {
    /// The response that answers this request; `None` for what is not a request.
    pub fn response(self) -> Option<SdoInfoOpcode> {
        match self {
            SdoInfoOpcode::GetOdListRequest => Some(SdoInfoOpcode::GetOdListResponse),
            SdoInfoOpcode::GetObjectDescriptionRequest => Some(SdoInfoOpcode::GetObjectDescriptionResponse),
            SdoInfoOpcode::GetEntryDescriptionRequest => Some(SdoInfoOpcode::GetEntryDescriptionResponse),
            _ => None,
        }
    }
}

wire_codes! {
    /// OD list types of a Get OD list request (ETG.1000.6 §5.6.3.3).
    pub enum OdListType: u16, "OD list type" {
        /// Number of objects in each of the five lists.
        Lengths = 0x00 => "number of objects in the five lists",
        /// All objects.
        All = 0x01 => "all objects",
        /// Objects mappable in an RxPDO.
        RxPdoMappable = 0x02 => "RxPDO mappable objects",
        /// Objects mappable in a TxPDO.
        TxPdoMappable = 0x03 => "TxPDO mappable objects",
        /// Objects to be stored for a device replacement.
        Backup = 0x04 => "objects to be stored for a device replacement",
        /// Start-up parameters.
        Startup = 0x05 => "startup parameters",
    }
}

/// The SDO information header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SdoInfoHeader {
    /// Opcode.
    pub opcode: SdoInfoOpcode,
    /// More fragments follow.
    pub incomplete: bool,
    /// Fragments still to come after this one.
    pub fragments_left: u16,
}

impl SdoInfoHeader {
    /// Decodes the header at the start of an SDO information body; an opcode outside the
    /// standard's set is an error naming it.
    pub fn decode(body: &[u8]) -> Result<Self, MailboxError> {
        if body.len() < SDO_INFO_HEADER_LEN {
            return Err(MailboxError::Truncated {
                what: "SDO information message",
                len: body.len(),
                needed: SDO_INFO_HEADER_LEN,
            });
        }
        Ok(SdoInfoHeader {
            opcode: SdoInfoOpcode::try_from(body[0] & 0x7F)?,
            incomplete: body[0] & 0x80 != 0,
            fragments_left: u16::from_le_bytes([body[2], body[3]]),
        })
    }

    /// Encodes into the first four bytes of `out`.
    pub fn encode(&self, out: &mut [u8]) {
        out[0] = (self.opcode as u8 & 0x7F) | ((self.incomplete as u8) << 7);
        out[1] = 0;
        out[2..4].copy_from_slice(&self.fragments_left.to_le_bytes());
    }
}

/// Writes an SDO information message carrying `data` after its header; returns the length.
pub fn write_info_message(out: &mut [u8], counter: u8, header: SdoInfoHeader, data: &[u8]) -> usize {
    write_message(out, counter, CoeService::SdoInformation, |b| {
        header.encode(b);
        b[SDO_INFO_HEADER_LEN..SDO_INFO_HEADER_LEN + data.len()].copy_from_slice(data);
        SDO_INFO_HEADER_LEN + data.len()
    })
}

wire_codes! {
    /// Object codes of an object description (ETG.1000.6 Table 43, CiA 301 §7.4.3).
    pub enum ObjectCode: u8, "object code" {
        /// A large variable amount of data.
        Domain = 0x02 => "DOMAIN",
        /// A type definition.
        Deftype = 0x05 => "DEFTYPE",
        /// A record type definition.
        Defstruct = 0x06 => "DEFSTRUCT",
        /// A single value.
        Var = 0x07 => "VAR",
        /// Subindices of one type.
        Array = 0x08 => "ARRAY",
        /// Subindices of different types.
        Record = 0x09 => "RECORD",
    }
}

/// An object description (Get object description response data).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ObjectDescription<'a> {
    /// Object index.
    pub index: u16,
    /// Data type, see [`data_type`].
    pub data_type: u16,
    /// Highest subindex.
    pub max_subindex: u8,
    /// Object code.
    pub object_code: ObjectCode,
    /// Name.
    pub name: &'a str,
}

/// Length of an object description before its name.
pub const OBJECT_DESCRIPTION_FIXED_LEN: usize = 6;
/// Length of an entry description before its optional values and name.
pub const ENTRY_DESCRIPTION_FIXED_LEN: usize = 10;

fn text<'a>(bytes: &'a [u8], what: &'static str) -> Result<&'a str, MailboxError> {
    std::str::from_utf8(bytes).map_err(|_| MailboxError::NotText { what })
}

impl<'a> ObjectDescription<'a> {
    /// Decodes the data of a Get object description response.
    pub fn decode(data: &'a [u8]) -> Result<Self, MailboxError> {
        if data.len() < OBJECT_DESCRIPTION_FIXED_LEN {
            return Err(MailboxError::Truncated {
                what: "object description",
                len: data.len(),
                needed: OBJECT_DESCRIPTION_FIXED_LEN,
            });
        }
        Ok(ObjectDescription {
            index: u16::from_le_bytes([data[0], data[1]]),
            data_type: u16::from_le_bytes([data[2], data[3]]),
            max_subindex: data[4],
            object_code: ObjectCode::try_from(data[5])?,
            name: text(&data[OBJECT_DESCRIPTION_FIXED_LEN..], "object name")?,
        })
    }

    /// Encodes into `out`; returns the length.
    pub fn encode(&self, out: &mut [u8]) -> usize {
        out[0..2].copy_from_slice(&self.index.to_le_bytes());
        out[2..4].copy_from_slice(&self.data_type.to_le_bytes());
        out[4] = self.max_subindex;
        out[5] = self.object_code.into();
        let end = OBJECT_DESCRIPTION_FIXED_LEN + self.name.len();
        out[OBJECT_DESCRIPTION_FIXED_LEN..end].copy_from_slice(self.name.as_bytes());
        end
    }
}

/// Access bits of an entry description.
pub mod access {
    /// Readable in PreOp.
    pub const READ_PREOP: u16 = 0x0001;
    /// Readable in SafeOp.
    pub const READ_SAFEOP: u16 = 0x0002;
    /// Readable in Op.
    pub const READ_OP: u16 = 0x0004;
    /// Writable in PreOp.
    pub const WRITE_PREOP: u16 = 0x0008;
    /// Writable in SafeOp.
    pub const WRITE_SAFEOP: u16 = 0x0010;
    /// Writable in Op.
    pub const WRITE_OP: u16 = 0x0020;
    /// Mappable in an RxPDO.
    pub const RX_PDO: u16 = 0x0040;
    /// Mappable in a TxPDO.
    pub const TX_PDO: u16 = 0x0080;
    /// Readable in every state.
    pub const READ: u16 = READ_PREOP | READ_SAFEOP | READ_OP;
    /// Writable in every state.
    pub const WRITE: u16 = WRITE_PREOP | WRITE_SAFEOP | WRITE_OP;

    /// Each access bit with its name, in bit order.
    pub const NAMES: [(u16, &str); 8] = [
        (READ_PREOP, "read_preop"),
        (READ_SAFEOP, "read_safeop"),
        (READ_OP, "read_op"),
        (WRITE_PREOP, "write_preop"),
        (WRITE_SAFEOP, "write_safeop"),
        (WRITE_OP, "write_op"),
        (RX_PDO, "rx_pdo"),
        (TX_PDO, "tx_pdo"),
    ];

    /// The names of the bits set in `bits`, in bit order.
    pub fn names(bits: u16) -> impl Iterator<Item = &'static str> {
        NAMES.into_iter().filter(move |(bit, _)| bits & bit != 0).map(|(_, name)| name)
    }
}

/// An entry description (Get entry description response data), without the optional
/// unit/default/minimum/maximum values, which the AKD does not send.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EntryDescription<'a> {
    /// Object index.
    pub index: u16,
    /// Subindex.
    pub subindex: u8,
    /// Value information bits the request asked for.
    pub value_info: u8,
    /// Data type, see [`data_type`].
    pub data_type: u16,
    /// Length in bits.
    pub bit_length: u16,
    /// Access bits, see [`access`].
    pub access: u16,
    /// Name.
    pub name: &'a str,
}

impl<'a> EntryDescription<'a> {
    /// Decodes the data of a Get entry description response.
    pub fn decode(data: &'a [u8]) -> Result<Self, MailboxError> {
        if data.len() < ENTRY_DESCRIPTION_FIXED_LEN {
            return Err(MailboxError::Truncated {
                what: "entry description",
                len: data.len(),
                needed: ENTRY_DESCRIPTION_FIXED_LEN,
            });
        }
        Ok(EntryDescription {
            index: u16::from_le_bytes([data[0], data[1]]),
            subindex: data[2],
            value_info: data[3],
            data_type: u16::from_le_bytes([data[4], data[5]]),
            bit_length: u16::from_le_bytes([data[6], data[7]]),
            access: u16::from_le_bytes([data[8], data[9]]),
            name: text(&data[ENTRY_DESCRIPTION_FIXED_LEN..], "entry name")?,
        })
    }

    /// Encodes into `out`; returns the length.
    pub fn encode(&self, out: &mut [u8]) -> usize {
        out[0..2].copy_from_slice(&self.index.to_le_bytes());
        out[2] = self.subindex;
        out[3] = self.value_info;
        out[4..6].copy_from_slice(&self.data_type.to_le_bytes());
        out[6..8].copy_from_slice(&self.bit_length.to_le_bytes());
        out[8..10].copy_from_slice(&self.access.to_le_bytes());
        let end = ENTRY_DESCRIPTION_FIXED_LEN + self.name.len();
        out[ENTRY_DESCRIPTION_FIXED_LEN..end].copy_from_slice(self.name.as_bytes());
        end
    }
}

/// CoE basic data types (ETG.1000.6 table 64) and their names.
pub mod data_type {
    /// BOOLEAN.
    pub const BOOLEAN: u16 = 0x0001;
    /// INTEGER8.
    pub const INTEGER8: u16 = 0x0002;
    /// INTEGER16.
    pub const INTEGER16: u16 = 0x0003;
    /// INTEGER32.
    pub const INTEGER32: u16 = 0x0004;
    /// UNSIGNED8.
    pub const UNSIGNED8: u16 = 0x0005;
    /// UNSIGNED16.
    pub const UNSIGNED16: u16 = 0x0006;
    /// UNSIGNED32.
    pub const UNSIGNED32: u16 = 0x0007;
    /// REAL32.
    pub const REAL32: u16 = 0x0008;
    /// VISIBLE_STRING.
    pub const VISIBLE_STRING: u16 = 0x0009;
    /// OCTET_STRING.
    pub const OCTET_STRING: u16 = 0x000A;
    /// UNICODE_STRING.
    pub const UNICODE_STRING: u16 = 0x000B;
    /// DOMAIN.
    pub const DOMAIN: u16 = 0x000F;
    /// INTEGER24.
    pub const INTEGER24: u16 = 0x0010;
    /// REAL64.
    pub const REAL64: u16 = 0x0011;
    /// INTEGER64.
    pub const INTEGER64: u16 = 0x0015;
    /// UNSIGNED24.
    pub const UNSIGNED24: u16 = 0x0016;
    /// UNSIGNED64.
    pub const UNSIGNED64: u16 = 0x001B;
    /// PDO mapping record.
    pub const PDO_MAPPING: u16 = 0x0021;
    /// Identity record.
    pub const IDENTITY: u16 = 0x0023;
    /// PDO communication parameter record.
    pub const PDO_COMMUNICATION: u16 = 0x0020;
    /// Sync manager communication type record (0x1C00).
    pub const SM_COMMUNICATION_TYPE: u16 = 0x0029;
    /// Sync manager synchronisation record (0x1C32/0x1C33).
    pub const SM_SYNCHRONIZATION: u16 = 0x0042;

    /// The type's name, e.g. `UNSIGNED16`.
    pub fn name(code: u16) -> &'static str {
        match code {
            BOOLEAN => "BOOLEAN",
            INTEGER8 => "INTEGER8",
            INTEGER16 => "INTEGER16",
            INTEGER32 => "INTEGER32",
            UNSIGNED8 => "UNSIGNED8",
            UNSIGNED16 => "UNSIGNED16",
            UNSIGNED32 => "UNSIGNED32",
            REAL32 => "REAL32",
            VISIBLE_STRING => "VISIBLE_STRING",
            OCTET_STRING => "OCTET_STRING",
            UNICODE_STRING => "UNICODE_STRING",
            DOMAIN => "DOMAIN",
            INTEGER24 => "INTEGER24",
            REAL64 => "REAL64",
            INTEGER64 => "INTEGER64",
            UNSIGNED24 => "UNSIGNED24",
            UNSIGNED64 => "UNSIGNED64",
            INTEGER40 => "INTEGER40",
            INTEGER48 => "INTEGER48",
            INTEGER56 => "INTEGER56",
            UNSIGNED40 => "UNSIGNED40",
            UNSIGNED48 => "UNSIGNED48",
            UNSIGNED56 => "UNSIGNED56",
            PDO_MAPPING => "PDO_MAPPING",
            IDENTITY => "IDENTITY",
            PDO_COMMUNICATION => "PDO_COMMUNICATION",
            SM_COMMUNICATION_TYPE => "SM_COMMUNICATION_TYPE",
            SM_SYNCHRONIZATION => "SM_SYNCHRONIZATION",
            _ => "unknown data type",
        }
    }

    /// Whether values of the type are signed integers (for display and range checks).
    pub fn is_signed(code: u16) -> bool {
        matches!(code, INTEGER8 | INTEGER16 | INTEGER24 | INTEGER32 | INTEGER40 | INTEGER48 | INTEGER56 | INTEGER64)
    }

    /// INTEGER40.
    pub const INTEGER40: u16 = 0x0012;
    /// INTEGER48.
    pub const INTEGER48: u16 = 0x0013;
    /// INTEGER56.
    pub const INTEGER56: u16 = 0x0014;
    /// UNSIGNED40.
    pub const UNSIGNED40: u16 = 0x0018;
    /// UNSIGNED48.
    pub const UNSIGNED48: u16 = 0x0019;
    /// UNSIGNED56.
    pub const UNSIGNED56: u16 = 0x001A;

    /// How a value of a data type reads: the classes a tool shows and checks values by.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub enum ValueKind {
        /// INTEGER8 .. INTEGER64: a two's-complement little-endian number.
        SignedInteger,
        /// BOOLEAN and UNSIGNED8 .. UNSIGNED64: an unsigned little-endian number.
        UnsignedInteger,
        /// REAL32 or REAL64: an IEEE 754 number.
        Real,
        /// VISIBLE_STRING: text, padded with NUL bytes.
        VisibleString,
        /// Anything else (octet strings, domains, records): raw bytes.
        Other,
    }

    impl ValueKind {
        /// The kind's name as the Python API spells it, e.g. `signed_integer`.
        pub fn name(self) -> &'static str {
            match self {
                ValueKind::SignedInteger => "signed_integer",
                ValueKind::UnsignedInteger => "unsigned_integer",
                ValueKind::Real => "real",
                ValueKind::VisibleString => "visible_string",
                ValueKind::Other => "other",
            }
        }
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
}

/// Whether `name`, an object's name in a drive's SDO information, names the AKD parameter
/// `parameter` (e.g. "FBUS.PARAM02") as a word of its own, in any case: "FBUS.PARAM02" and
/// "FBUS.PARAM02 PLL mode" do, "FBUS.PARAM020" or "Sync mode" do not. A master writes or trusts
/// a manufacturer object whose index no manual gives only where the drive names it so.
pub fn names_parameter(name: &str, parameter: &str) -> bool {
    name.split(|c: char| !(c.is_ascii_alphanumeric() || c == '.' || c == '_'))
        .any(|word| word.eq_ignore_ascii_case(parameter))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wire_codes_round_trip_and_name_the_unknown() {
        for &service in CoeService::ALL {
            assert_eq!(CoeService::try_from(u8::from(service)), Ok(service));
        }
        assert_eq!(CoeService::SdoInformation.to_string(), "8 (SDO Information)");
        let err = CoeService::try_from(9).unwrap_err().to_string();
        assert!(err.starts_with("CoE service 9 is none of 1 (Emergency), 2 (SDO Request)"), "{err}");
        assert_eq!(SdoInfoOpcode::GetOdListRequest.response(), Some(SdoInfoOpcode::GetOdListResponse));
        assert!(SdoRequest::decode(&[0xA0, 0, 0, 0, 0, 0, 0, 0]).unwrap_err().to_string().contains("specifier 5"));
    }

    #[test]
    fn access_bits_are_named_in_bit_order() {
        let names: Vec<_> = access::names(access::READ | access::WRITE_PREOP | access::TX_PDO).collect();
        assert_eq!(names, ["read_preop", "read_safeop", "read_op", "write_preop", "tx_pdo"]);
        assert_eq!(access::names(0).count(), 0);
        assert_eq!(access::NAMES.iter().fold(0, |all, (bit, _)| all | bit), 0x00FF);
    }
    use proptest::prelude::*;

    #[test]
    fn encodes_the_manuals_download_example() {
        // AKD manual §5.13.3: write 0x1C12:01 = 0x1704 with a 2-byte expedited download.
        let mut buf = [0u8; 32];
        let len = write_sdo_request(
            &mut buf,
            0,
            &SdoRequest::DownloadExpedited { index: 0x1C12, subindex: 1, complete_access: false, data: &[0x04, 0x17] },
        );
        assert_eq!(
            &buf[..len],
            &[0x0A, 0x00, 0x00, 0x00, 0x00, 0x03, 0x00, 0x20, 0x2B, 0x12, 0x1C, 0x01, 0x04, 0x17, 0x00, 0x00]
        );
        // The manual's reply announces 14 bytes but prints 10; the master reads the whole SM1
        // buffer, so the announced length fits there.
        let mut reply = [0u8; 32];
        reply[..16].copy_from_slice(&[
            0x0E, 0x00, 0x00, 0x00, 0x00, 0x03, 0x00, 0x30, 0x60, 0x12, 0x1C, 0x01, 0x00, 0x00, 0x00, 0x00,
        ]);
        let (_, coe, body) = split_message(&reply).unwrap();
        assert_eq!(coe.service, CoeService::SdoResponse);
        assert_eq!(SdoResponse::decode(body).unwrap(), SdoResponse::Download { index: 0x1C12, subindex: 1 });
    }

    #[test]
    fn decodes_the_real_drives_upload_replies() {
        // From soem-sdinfo-akd.pcapng: 0x1C12:01 -> 0x1600 (2 bytes), 0x1600:01 -> 0x60400010.
        let body = [0x4B, 0x12, 0x1C, 0x01, 0x00, 0x16, 0x00, 0x00];
        assert_eq!(
            SdoResponse::decode(&body).unwrap(),
            SdoResponse::UploadExpedited { index: 0x1C12, subindex: 1, data: &[0x00, 0x16] }
        );
        let body = [0x43, 0x00, 0x16, 0x01, 0x10, 0x00, 0x40, 0x60];
        assert_eq!(
            SdoResponse::decode(&body).unwrap(),
            SdoResponse::UploadExpedited { index: 0x1600, subindex: 1, data: &[0x10, 0x00, 0x40, 0x60] }
        );
    }

    #[test]
    fn short_segments_are_padded_and_sized() {
        let mut buf = [0u8; 16];
        let len = SdoResponse::UploadSegment { toggle: true, last: true, data: b"AKD" }.encode(&mut buf);
        assert_eq!(len, 8);
        assert_eq!(buf[0], 0x10 | (4 << 1) | 1);
        assert_eq!(
            SdoResponse::decode(&buf[..len]).unwrap(),
            SdoResponse::UploadSegment { toggle: true, last: true, data: b"AKD" }
        );
    }

    #[test]
    fn names_abort_codes() {
        assert_eq!(SdoAbortCode::NO_SUCH_OBJECT.name(), "object does not exist in the object dictionary");
        assert_eq!(SdoAbortCode::READ_ONLY.name(), "attempt to write a read-only object");
        assert_eq!(SdoAbortCode::VALUE_RANGE.name(), "value range of parameter exceeded");
        assert_eq!(SdoAbortCode(0x1234_5678).name(), "unknown abort code");
    }

    #[test]
    fn refuses_truncated_and_unknown_messages() {
        assert!(SdoRequest::decode(&[]).is_err());
        assert!(SdoRequest::decode(&[0x40, 0x00]).is_err());
        assert!(SdoRequest::decode(&[0xA0, 0, 0, 0, 0, 0, 0, 0]).is_err());
        assert!(SdoResponse::decode(&[0x00, 1, 2]).is_err());
        assert!(Emergency::decode(&[1, 2, 3]).is_err());
        assert!(SdoInfoHeader::decode(&[1]).is_err());
        assert!(ObjectDescription::decode(&[0; 5]).is_err());
        assert!(EntryDescription::decode(&[0; 9]).is_err());
        assert!(split_message(&[0x02, 0, 0, 0, 0, 0x02, 0, 0]).is_err());
    }

    #[test]
    fn descriptions_round_trip() {
        let mut buf = [0u8; 64];
        let d = ObjectDescription {
            index: 0x6041,
            data_type: data_type::UNSIGNED16,
            max_subindex: 0,
            object_code: ObjectCode::Var,
            name: "Statusword",
        };
        let len = d.encode(&mut buf);
        assert_eq!(ObjectDescription::decode(&buf[..len]).unwrap(), d);
        let e = EntryDescription {
            index: 0x6041,
            subindex: 0,
            value_info: 0,
            data_type: data_type::UNSIGNED16,
            bit_length: 16,
            access: access::READ | access::TX_PDO,
            name: "Statusword",
        };
        let len = e.encode(&mut buf);
        assert_eq!(EntryDescription::decode(&buf[..len]).unwrap(), e);
        let h = SdoInfoHeader { opcode: SdoInfoOpcode::GetOdListResponse, incomplete: true, fragments_left: 3 };
        h.encode(&mut buf);
        assert_eq!(SdoInfoHeader::decode(&buf).unwrap(), h);
    }

    proptest! {
        #[test]
        fn decoding_arbitrary_bodies_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..40)) {
            let _ = SdoRequest::decode(&bytes);
            let _ = SdoResponse::decode(&bytes);
            let _ = Emergency::decode(&bytes);
            let _ = SdoInfoHeader::decode(&bytes);
            let _ = ObjectDescription::decode(&bytes);
            let _ = EntryDescription::decode(&bytes);
            let _ = split_message(&bytes);
        }

        #[test]
        fn expedited_round_trips(index: u16, subindex: u8, data in proptest::collection::vec(any::<u8>(), 1..=4)) {
            let mut buf = [0u8; 16];
            let req = SdoRequest::DownloadExpedited { index, subindex, complete_access: false, data: &data };
            let len = req.encode(&mut buf);
            prop_assert_eq!(SdoRequest::decode(&buf[..len]).unwrap(), req);
            let resp = SdoResponse::UploadExpedited { index, subindex, data: &data };
            let len = resp.encode(&mut buf);
            prop_assert_eq!(SdoResponse::decode(&buf[..len]).unwrap(), resp);
        }

        #[test]
        fn segments_round_trip(toggle: bool, last: bool, data in proptest::collection::vec(any::<u8>(), 0..40)) {
            let mut buf = [0u8; 64];
            let req = SdoRequest::DownloadSegment { toggle, last, data: &data };
            let len = req.encode(&mut buf);
            prop_assert_eq!(SdoRequest::decode(&buf[..len]).unwrap(), req);
            let resp = SdoResponse::UploadSegment { toggle, last, data: &data };
            let len = resp.encode(&mut buf);
            prop_assert_eq!(SdoResponse::decode(&buf[..len]).unwrap(), resp);
        }

        #[test]
        fn normal_transfers_round_trip(index: u16, subindex: u8, size: u32, data in proptest::collection::vec(any::<u8>(), 0..40)) {
            let mut buf = [0u8; 64];
            let req = SdoRequest::DownloadNormal { index, subindex, complete_access: false, complete_size: size, data: &data };
            let len = req.encode(&mut buf);
            prop_assert_eq!(SdoRequest::decode(&buf[..len]).unwrap(), req);
            let resp = SdoResponse::UploadNormal { index, subindex, complete_size: size, data: &data };
            let len = resp.encode(&mut buf);
            prop_assert_eq!(SdoResponse::decode(&buf[..len]).unwrap(), resp);
        }
    }
}
