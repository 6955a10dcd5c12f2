//! Mailbox header codec (ETG.1000.4 §5.6, AKD manual §5.13).
//!
//! Every mailbox message starts with a 6-byte header: the length of what follows, an address,
//! channel and priority, and the protocol type with a 3-bit counter. The counter lets a slave
//! tell a repeated message from a new one; the AKD echoes the master's counter in its reply.

use crate::wire_code::UnknownCode;

/// Length of the mailbox header.
pub const HEADER_LEN: usize = 6;

wire_codes! {
    /// The protocol a mailbox message carries (header byte 5, bits 0–3).
    pub enum MailboxType: u8, "mailbox type" {
        /// A mailbox error reply.
        Error = 0x00 => "mailbox error",
        Aoe = 0x01 => "ADS over EtherCAT",
        Eoe = 0x02 => "Ethernet over EtherCAT",
        Coe = 0x03 => "CANopen over EtherCAT",
        Foe = 0x04 => "File access over EtherCAT",
        Soe = 0x05 => "Servo profile over EtherCAT",
        Voe = 0x0F => "vendor specific",
    }
}

impl MailboxType {
    /// Bit of this protocol in the SII mailbox-protocol word (0x1C): AoE 0x01, EoE 0x02,
    /// CoE 0x04, FoE 0x08, SoE 0x10, VoE 0x20.
    pub fn sii_protocol_bit(self) -> u16 {
        match self {
            MailboxType::Error => 0,
            MailboxType::Aoe => 0x01,
            MailboxType::Eoe => 0x02,
            MailboxType::Coe => 0x04,
            MailboxType::Foe => 0x08,
            MailboxType::Soe => 0x10,
            MailboxType::Voe => 0x20,
        }
    }
}

/// A decoded mailbox header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MailboxHeader {
    /// Bytes that follow the header.
    pub length: u16,
    /// Station address of the source (slave to master) or destination; 0 for the master.
    pub address: u16,
    /// Channel (bits 0–5 of byte 4).
    pub channel: u8,
    /// Priority (bits 6–7 of byte 4).
    pub priority: u8,
    /// Protocol type nibble, kept raw so that an unsupported type can be answered.
    pub mailbox_type: u8,
    /// Counter 1..=7 (0 is reserved for "not used").
    pub counter: u8,
}

impl MailboxHeader {
    /// A header for a message of `length` bytes of `mailbox_type` with `counter`.
    pub fn new(mailbox_type: MailboxType, length: u16, counter: u8) -> Self {
        MailboxHeader { length, address: 0, channel: 0, priority: 0, mailbox_type: mailbox_type as u8, counter }
    }

    /// Decodes a header and checks that the message it announces fits `bytes`.
    pub fn decode(bytes: &[u8]) -> Result<Self, MailboxError> {
        if bytes.len() < HEADER_LEN {
            return Err(MailboxError::Truncated { what: "mailbox message", len: bytes.len(), needed: HEADER_LEN });
        }
        let header = MailboxHeader {
            length: u16::from_le_bytes([bytes[0], bytes[1]]),
            address: u16::from_le_bytes([bytes[2], bytes[3]]),
            channel: bytes[4] & 0x3F,
            priority: bytes[4] >> 6,
            mailbox_type: bytes[5] & 0x0F,
            counter: (bytes[5] >> 4) & 0x07,
        };
        if HEADER_LEN + header.length as usize > bytes.len() {
            return Err(MailboxError::LengthMismatch { announced: header.length, holds: bytes.len() - HEADER_LEN });
        }
        Ok(header)
    }

    /// Encodes the header into the first six bytes of `out`.
    pub fn encode(&self, out: &mut [u8]) {
        out[0..2].copy_from_slice(&self.length.to_le_bytes());
        out[2..4].copy_from_slice(&self.address.to_le_bytes());
        out[4] = (self.channel & 0x3F) | (self.priority << 6);
        out[5] = (self.mailbox_type & 0x0F) | ((self.counter & 0x07) << 4);
    }

    /// The decoded protocol type, if not reserved.
    pub fn protocol(&self) -> Option<MailboxType> {
        MailboxType::try_from(self.mailbox_type & 0x0F).ok()
    }

    /// The message body that follows this header in `bytes`.
    pub fn body<'a>(&self, bytes: &'a [u8]) -> &'a [u8] {
        &bytes[HEADER_LEN..HEADER_LEN + self.length as usize]
    }
}

/// The counter after `counter`: 1, 2, ... 7, 1, ... (0 is skipped, it means "not used").
pub fn next_counter(counter: u8) -> u8 {
    if counter >= 7 {
        1
    } else {
        counter + 1
    }
}

/// Service word of a mailbox error reply.
pub const ERROR_SERVICE: u16 = 0x0001;
/// Length of a mailbox error reply body (service and detail words).
pub const ERROR_BODY_LEN: usize = 4;

wire_codes! {
    /// Detail codes of a mailbox error reply (ETG.1000.4 table 30).
    pub enum MailboxErrorDetail: u16, "mailbox error detail" {
        Syntax = 0x0001 => "syntax error in the mailbox header",
        UnsupportedProtocol = 0x0002 => "mailbox protocol not supported",
        /// The channel field is not 0.
        InvalidChannel = 0x0003 => "invalid channel",
        ServiceNotSupported = 0x0004 => "service not supported",
        InvalidHeader = 0x0005 => "invalid protocol header",
        SizeTooShort = 0x0006 => "data too short",
        NoMoreMemory = 0x0007 => "no more memory",
        InvalidSize = 0x0008 => "inconsistent length",
    }
}

/// Name of a mailbox error detail code as a slave sent it, which may be outside the table.
pub fn error_detail_name(detail: u16) -> &'static str {
    MailboxErrorDetail::try_from(detail).map_or("unknown mailbox error", MailboxErrorDetail::name)
}

/// Writes a complete mailbox error reply (header and body) into `out`; returns its length.
pub fn write_error_reply(out: &mut [u8], counter: u8, detail: MailboxErrorDetail) -> usize {
    MailboxHeader::new(MailboxType::Error, ERROR_BODY_LEN as u16, counter).encode(out);
    out[HEADER_LEN..HEADER_LEN + 2].copy_from_slice(&ERROR_SERVICE.to_le_bytes());
    out[HEADER_LEN + 2..HEADER_LEN + 4].copy_from_slice(&u16::from(detail).to_le_bytes());
    HEADER_LEN + ERROR_BODY_LEN
}

/// Reads the detail code of a mailbox error reply body.
pub fn parse_error_reply(body: &[u8]) -> Result<u16, MailboxError> {
    if body.len() < ERROR_BODY_LEN {
        return Err(MailboxError::Truncated { what: "mailbox error reply", len: body.len(), needed: ERROR_BODY_LEN });
    }
    Ok(u16::from_le_bytes([body[2], body[3]]))
}

/// A mailbox message that does not fit the request or the protocol (ETG.1000.6 mailbox and
/// CoE).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum MailboxError {
    /// A message, or a structure in one, shorter than the structure needs.
    #[error("{what} of {len} bytes is shorter than the {needed} bytes it needs")]
    Truncated {
        /// The structure, e.g. "SDO response" or "emergency message".
        what: &'static str,
        /// Bytes there were.
        len: usize,
        /// Bytes it needs.
        needed: usize,
    },
    /// The mailbox header announces more data than the mailbox holds.
    #[error("header announces {announced} bytes but the mailbox holds {holds}")]
    LengthMismatch {
        /// Length in the mailbox header.
        announced: u16,
        /// Bytes after the header.
        holds: usize,
    },
    /// A wire code outside the standard's set (CoE service, SDO command specifier, SDO
    /// information opcode).
    #[error(transparent)]
    UnknownCode(#[from] UnknownCode),
    /// A message of another mailbox type where CoE (3) was expected.
    #[error("mailbox type {mailbox_type} is not CoE (3)")]
    NotCoe {
        /// The mailbox type received.
        mailbox_type: u8,
    },
    /// A name in an SDO information description that is not UTF-8 text.
    #[error("{what} is not valid text")]
    NotText {
        /// The name's field.
        what: &'static str,
    },
    /// The slave has no mailbox: its SII lists no mailbox protocol.
    #[error("slave {slave} has no mailbox (its SII lists no mailbox protocol)")]
    NoMailbox {
        /// Slave position.
        slave: u16,
    },
    /// The slave's SII does not list CoE among its mailbox protocols.
    #[error("slave {slave} does not speak CoE (SII mailbox protocols)")]
    NoCoe {
        /// Slave position.
        slave: u16,
    },
    /// A message longer than the slave's mailbox (SM0).
    #[error("message of {len} bytes does not fit slave {slave}'s {room}-byte mailbox")]
    TooLong {
        /// Slave position.
        slave: u16,
        /// The message's length.
        len: usize,
        /// The mailbox's length.
        room: u16,
    },
    /// The slave answered with a mailbox error reply (ETG.1000.6 Table 30).
    #[error("slave {slave} answered with mailbox error 0x{detail:04X} ({detail_name})")]
    ErrorReply {
        /// Slave position.
        slave: u16,
        /// The error detail code.
        detail: u16,
        /// Its name.
        detail_name: &'static str,
    },
    /// A message of a mailbox type this master does not speak (it speaks CoE).
    #[error("slave {slave} sent a mailbox message of type {mailbox_type} that this master does not speak (CoE is 3)")]
    UnsupportedType {
        /// Slave position.
        slave: u16,
        /// The mailbox type received.
        mailbox_type: u8,
    },
    /// A CoE reply of another service than the one that answers the request.
    #[error("slave {slave} answered {request} with CoE service {got} (expected {expected})")]
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
    #[error(
        "upload of 0x{index:04X}:{subindex:02X} from slave {slave} announced {announced} bytes but carried {carried}"
    )]
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
    #[error("slave {slave} answered the {transfer} of 0x{index:04X}:{subindex:02X} with {response}")]
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
    #[error("SDO information error without an abort code")]
    InfoErrorWithoutCode,
    /// An SDO information response that does not answer the request's opcode.
    #[error("slave {slave} answered SDO information opcode {asked} with opcode {got} (expected {expected})")]
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
    #[error("OD list response without its list type")]
    OdListWithoutType,
    /// A description of another object or entry than the one asked for.
    #[error("asked for the description of {asked}, got {got}'s")]
    WrongDescription {
        /// What was asked, e.g. "0x6041" or "0x6041:00".
        asked: String,
        /// What came.
        got: String,
    },
    /// An SDO transfer asked of the cycle thread that needs segments, which it does not run.
    #[error(
        "SDO {verb} of 0x{index:04X}:{subindex:02X} of slave {slave} needs a segmented transfer, which runs \
         only with the cycle stopped"
    )]
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
    #[error("slave {slave} has no CoE mailbox for the SDO {verb} of 0x{index:04X}:{subindex:02X} of slave {slave}")]
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
    #[error(
        "slave {slave} answered the SDO {verb} of 0x{index:04X}:{subindex:02X} with mailbox error \
         0x{detail:04X} ({detail_name})"
    )]
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
    #[error(
        "slave {slave} answered the SDO {verb} of 0x{index:04X}:{subindex:02X} of slave {slave} with \
         something else"
    )]
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn decodes_the_manuals_example() {
        // AKD manual §5.13.3: write 0x1C12:01 = 0x1704.
        let request = [0x0A, 0x00, 0x00, 0x00, 0x00, 0x03, 0x00, 0x20, 0x2B, 0x12, 0x1C, 0x01, 0x04, 0x17, 0x00, 0x00];
        let h = MailboxHeader::decode(&request).unwrap();
        assert_eq!(h.length, 10);
        assert_eq!(h.protocol(), Some(MailboxType::Coe));
        assert_eq!(h.counter, 0);
        assert_eq!(h.body(&request).len(), 10);
    }

    #[test]
    fn counter_skips_zero() {
        let mut c = 0;
        let seen: Vec<u8> = (0..9)
            .map(|_| {
                c = next_counter(c);
                c
            })
            .collect();
        assert_eq!(seen, vec![1, 2, 3, 4, 5, 6, 7, 1, 2]);
    }

    #[test]
    fn error_reply_round_trips() {
        let mut buf = [0u8; 16];
        let len = write_error_reply(&mut buf, 3, MailboxErrorDetail::UnsupportedProtocol);
        let h = MailboxHeader::decode(&buf[..len]).unwrap();
        assert_eq!(h.protocol(), Some(MailboxType::Error));
        assert_eq!(h.counter, 3);
        assert_eq!(parse_error_reply(h.body(&buf)).unwrap(), u16::from(MailboxErrorDetail::UnsupportedProtocol));
    }

    #[test]
    fn refuses_overlong_length() {
        let bytes = [0xFF, 0x00, 0, 0, 0, 0x13, 0, 0];
        assert!(MailboxHeader::decode(&bytes).is_err());
        assert!(MailboxHeader::decode(&bytes[..3]).is_err());
    }

    proptest! {
        #[test]
        fn header_round_trips(length in 0u16..100, address: u16, channel in 0u8..64, priority in 0u8..4, t in 0u8..16, counter in 0u8..8) {
            let h = MailboxHeader { length, address, channel, priority, mailbox_type: t, counter };
            let mut buf = vec![0u8; HEADER_LEN + length as usize];
            h.encode(&mut buf);
            prop_assert_eq!(MailboxHeader::decode(&buf).unwrap(), h);
        }
    }
}
