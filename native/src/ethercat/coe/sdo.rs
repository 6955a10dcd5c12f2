//! SDO transfers (CoE service 2 and 3, CiA 301 §7.2.4.3): expedited, normal and segmented
//! uploads and downloads and their aborts, on the client and the server side, with the abort
//! codes.

use super::{write_message, CoeService};
use crate::ethercat::mailbox::MailboxError;

/// Length of an SDO initiate message (command, index, subindex, 4 data bytes).
pub const SDO_LEN: usize = 8;
/// Minimum data area of an SDO segment (shorter data is padded and its size given by `n`).
pub const SEGMENT_MIN_DATA: usize = 7;

wire_codes! {
    /// Client command specifiers of an SDO request (command byte bits 5–7, CiA 301 §7.2.4.3).
    pub enum ClientCommand: u8, "SDO client command specifier" {
        DownloadSegment = 0 => "download segment request",
        InitiateDownload = 1 => "initiate download request",
        InitiateUpload = 2 => "initiate upload request",
        UploadSegment = 3 => "upload segment request",
        Abort = 4 => "abort transfer",
    }
}

wire_codes! {
    /// Server command specifiers of an SDO response (command byte bits 5–7, CiA 301 §7.2.4.3).
    pub enum ServerCommand: u8, "SDO server command specifier" {
        UploadSegment = 0 => "upload segment response",
        DownloadSegment = 1 => "download segment response",
        InitiateUpload = 2 => "initiate upload response",
        InitiateDownload = 3 => "initiate download response",
        Abort = 4 => "abort transfer",
    }
}

/// The command byte's specifier bits for `specifier` (bits 5–7).
fn specifier_bits(specifier: u8) -> u8 {
    specifier << 5
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
                let word = u32::from_le_bytes([body[4], body[5], body[6], body[7]]);
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
                        complete_size: word,
                        data: &body[SDO_LEN..],
                    }),
                    ClientCommand::InitiateUpload => Ok(SdoRequest::Upload { index, subindex, complete_access }),
                    // The arm above lets only an abort get here.
                    _ => Ok(SdoRequest::Abort { index, subindex, code: SdoAbortCode(word) }),
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

/// Writes a complete SDO request message; returns its length.
pub fn write_sdo_request(out: &mut [u8], counter: u8, request: &SdoRequest<'_>) -> usize {
    write_message(out, counter, CoeService::SdoRequest, |b| request.encode(b))
}

/// Writes a complete SDO response message; returns its length.
pub fn write_sdo_response(out: &mut [u8], counter: u8, response: &SdoResponse<'_>) -> usize {
    write_message(out, counter, CoeService::SdoResponse, |b| response.encode(b))
}

wire_codes! {
    /// An SDO abort code (CiA 301 §7.2.4.3.17, AKD manual §5.13). A slave may abort with a code
    /// outside the standard's list (a manufacturer's), so this is the wire value with the
    /// standard's codes as constants and [`name`](SdoAbortCode::name) for any of them.
    pub struct SdoAbortCode(u32) {
        TOGGLE_BIT = 0x0503_0000 => "toggle bit not alternated",
        TIMEOUT = 0x0504_0000 => "SDO protocol timed out",
        BAD_COMMAND = 0x0504_0001 => "client/server command specifier not valid or unknown",
        0x0504_0002 => "invalid block size",
        0x0504_0003 => "invalid sequence number",
        0x0504_0004 => "CRC error",
        OUT_OF_MEMORY = 0x0504_0005 => "out of memory",
        UNSUPPORTED_ACCESS = 0x0601_0000 => "unsupported access to an object",
        WRITE_ONLY = 0x0601_0001 => "attempt to read a write-only object",
        READ_ONLY = 0x0601_0002 => "attempt to write a read-only object",
        SUBINDEX_WRITE_NEEDS_ZERO = 0x0601_0003 => "subindex cannot be written, subindex 0 must be 0 for write access",
        COMPLETE_ACCESS_UNSUPPORTED = 0x0601_0004 => "complete access not supported for objects of variable length",
        0x0601_0005 => "object length exceeds mailbox size",
        0x0601_0006 => "object mapped to RxPDO, SDO download blocked",
        NO_SUCH_OBJECT = 0x0602_0000 => "object does not exist in the object dictionary",
        NOT_MAPPABLE = 0x0604_0041 => "object cannot be mapped to the PDO",
        PDO_TOO_LONG = 0x0604_0042 => "number and length of mapped objects exceed the PDO length",
        PARAMETER_INCOMPATIBLE = 0x0604_0043 => "general parameter incompatibility",
        DEVICE_INCOMPATIBLE = 0x0604_0047 => "general internal incompatibility in the device",
        HARDWARE_ERROR = 0x0606_0000 => "access failed due to a hardware error",
        LENGTH_MISMATCH = 0x0607_0010 => "data type does not match, length of service parameter does not match",
        LENGTH_TOO_HIGH = 0x0607_0012 => "data type does not match, length of service parameter too high",
        LENGTH_TOO_LOW = 0x0607_0013 => "data type does not match, length of service parameter too low",
        NO_SUCH_SUBINDEX = 0x0609_0011 => "subindex does not exist",
        /// Value range of parameter exceeded (download only).
        VALUE_RANGE = 0x0609_0030 => "value range of parameter exceeded",
        VALUE_TOO_HIGH = 0x0609_0031 => "value of parameter written too high",
        VALUE_TOO_LOW = 0x0609_0032 => "value of parameter written too low",
        MAX_BELOW_MIN = 0x0609_0036 => "maximum value is less than minimum value",
        GENERAL = 0x0800_0000 => "general error",
        CANNOT_STORE = 0x0800_0020 => "data cannot be transferred or stored to the application",
        LOCAL_CONTROL = 0x0800_0021 => "data cannot be transferred or stored because of local control",
        DEVICE_STATE = 0x0800_0022 => "data cannot be transferred or stored because of the present device state",
        /// Object dictionary dynamic generation fails or no object dictionary is present.
        NO_OBJECT_DICTIONARY = 0x0800_0023 => "no object dictionary is present",
    } else {
        _ => "unknown abort code",
    }
}
