//! Ethernet over EtherCAT (ETG.1000.6 §5.7): the EoE header, Ethernet frames cut into
//! fragments that fit a mailbox and put back together, and the Set IP Parameter request and
//! response with which a master gives a slave its MAC and IP settings.
//!
//! After the mailbox header come two words. The first holds the frame type (bits 0–3), the
//! port (4–7), "last fragment" (8), "time appended" (9) and "time request" (10). For a fragment
//! the second holds the fragment number (bits 0–5), an offset in 32-byte units (6–11; in
//! fragment 0 the frame's whole size, rounded up to 32-byte units) and a frame number (12–15)
//! that tells one frame's fragments from the next's; in a Set IP Parameter response it is the
//! result. Every fragment but the last carries a multiple of 32 bytes.
//!
//! A Set IP Parameter request carries a 32-bit word of flags and then each field at a fixed
//! place, present or not, up to the last one present: MAC (6 bytes), IP address, subnet mask, default gateway, DNS server
//! (4 bytes each, a little-endian 32-bit word as all EtherCAT words are, so `192.168.0.1` goes
//! as `01 00 A8 C0`) and the DNS name (32 bytes, zero-padded; TwinCAT sends all 32 however short
//! the name is).

use std::net::Ipv4Addr;

use crate::ethercat::mailbox::{MailboxHeader, MailboxType, HEADER_LEN};
use crate::setting::SettingError;
use crate::wire_code::UnknownCode;

/// Length of the EoE header (the two words after the mailbox header).
pub const EOE_HEADER_LEN: usize = 4;
/// Fragments other than the last carry a multiple of this many bytes; offsets count in it.
pub const FRAGMENT_UNIT: usize = 32;
/// Length of the time stamp a fragment with "time appended" carries after its data.
pub const TIMESTAMP_LEN: usize = 4;
/// The longest Ethernet frame EoE carries here: 1514 bytes and a VLAN tag, without the FCS.
pub const MAX_FRAME_LEN: usize = 1518;
/// Length of the DNS name field.
pub const DNS_NAME_LEN: usize = 32;
/// Length of a Set IP Parameter request's body after the EoE header with all fields.
pub const SET_IP_LEN: usize = 4 + 6 + 4 * 4 + DNS_NAME_LEN;

wire_codes! {
    /// The EoE frame type (first EoE word, bits 0–3).
    pub enum EoeFrameType: u8, "EoE frame type" {
        /// A fragment of an Ethernet frame.
        Fragment = 0 => "fragment",
        /// A time stamp answering a fragment that asked for one.
        TimestampResponse = 1 => "time stamp response",
        SetIpRequest = 2 => "set IP parameter request",
        SetIpResponse = 3 => "set IP parameter response",
        SetAddressFilterRequest = 4 => "set address filter request",
        SetAddressFilterResponse = 5 => "set address filter response",
        GetIpRequest = 6 => "get IP parameter request",
        GetIpResponse = 7 => "get IP parameter response",
        GetAddressFilterRequest = 8 => "get address filter request",
        GetAddressFilterResponse = 9 => "get address filter response",
    }
}

wire_codes! {
    /// The result word of an EoE response (ETG.1000.6 table "EoE result"). A slave may answer
    /// with a code outside the standard's list, so this is the wire value with the standard's
    /// codes as constants and [`name`](EoeResult::name) for any of them.
    pub struct EoeResult(u16) {
        SUCCESS = 0x0000 => "success",
        UNSPECIFIED = 0x0001 => "unspecified error",
        UNSUPPORTED_FRAME_TYPE = 0x0002 => "unsupported frame type",
        NO_IP_SUPPORT = 0x0201 => "no IP support",
        NO_DHCP_SUPPORT = 0x0202 => "DHCP not supported",
        NO_FILTER_SUPPORT = 0x0401 => "no filter support",
    } else {
        _ => "unknown EoE result",
    }
}

/// The EoE header of a fragment.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FragmentHeader {
    /// The slave's port the frame goes to or came from (0: not specified).
    pub port: u8,
    /// The frame's last fragment.
    pub last_fragment: bool,
    /// A 32-bit time stamp follows the data (only in the last fragment).
    pub time_appended: bool,
    /// The sender asks for a time stamp of when the frame went out.
    pub time_request: bool,
    /// 0 for a frame's first fragment, counting up by one.
    pub fragment_number: u8,
    /// Fragment 0: the frame's size in 32-byte units, rounded up; others: where the data goes
    /// in the frame, in 32-byte units.
    pub offset_units: u8,
    /// The frame's number (4 bits), the same in all its fragments.
    pub frame_number: u8,
}

/// A Set IP Parameter request's fields; `None` for one whose flag is clear.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct IpParameters {
    /// MAC address (flag bit 0).
    pub mac: Option<[u8; 6]>,
    /// IP address (flag bit 1).
    pub ip: Option<Ipv4Addr>,
    /// Subnet mask (flag bit 2).
    pub subnet_mask: Option<Ipv4Addr>,
    /// Default gateway (flag bit 3).
    pub gateway: Option<Ipv4Addr>,
    /// DNS server (flag bit 4).
    pub dns_server: Option<Ipv4Addr>,
    /// DNS name, at most 32 bytes (flag bit 5).
    pub dns_name: Option<String>,
}

/// Flag bits of a Set IP Parameter request, in the order of its fields.
pub mod ip_flags {
    /// MAC address included.
    pub const MAC: u32 = 0x01;
    /// IP address included.
    pub const IP: u32 = 0x02;
    /// Subnet mask included.
    pub const SUBNET_MASK: u32 = 0x04;
    /// Default gateway included.
    pub const GATEWAY: u32 = 0x08;
    /// DNS server included.
    pub const DNS_SERVER: u32 = 0x10;
    /// DNS name included.
    pub const DNS_NAME: u32 = 0x20;
}

impl IpParameters {
    /// The flags word naming the fields present: bit n for the n-th field, as [`ip_flags`] lists them.
    pub fn flags(&self) -> u32 {
        let addresses = [self.ip, self.subnet_mask, self.gateway, self.dns_server];
        let present = [self.mac.is_some()].into_iter().chain(addresses.map(|a| a.is_some()));
        present.chain([self.dns_name.is_some()]).enumerate().map(|(bit, present)| u32::from(present) << bit).sum()
    }

    /// Encodes flags and the fields up to the last one present into `out` (at least
    /// [`SET_IP_LEN`] bytes), so that a request without a DNS name fits a small mailbox; returns
    /// the length. An error for a DNS name longer than its field.
    pub fn encode(&self, out: &mut [u8]) -> Result<usize, EoeError> {
        let out = &mut out[..SET_IP_LEN];
        out.fill(0);
        out[0..4].copy_from_slice(&self.flags().to_le_bytes());
        if let Some(mac) = self.mac {
            out[4..10].copy_from_slice(&mac);
        }
        for (at, address) in [(10, self.ip), (14, self.subnet_mask), (18, self.gateway), (22, self.dns_server)] {
            if let Some(address) = address {
                out[at..at + 4].copy_from_slice(&u32::from(address).to_le_bytes());
            }
        }
        if let Some(name) = &self.dns_name {
            if name.len() > DNS_NAME_LEN {
                return Err(EoeError::DnsNameTooLong { len: name.len(), max: DNS_NAME_LEN });
            }
            out[26..26 + name.len()].copy_from_slice(name.as_bytes());
        }
        // Where each field ends, in flag order.
        let ends = [10, 14, 18, 22, 26, SET_IP_LEN];
        let last = (0..ends.len()).rev().find(|bit| self.flags() & (1 << bit) != 0);
        Ok(last.map_or(4, |bit| ends[bit]))
    }

    /// Decodes a request's body after the EoE header. A field whose flag is clear may be
    /// missing at the end; one whose flag is set must be there.
    pub fn decode(body: &[u8]) -> Result<Self, EoeError> {
        let flags = u32::from_le_bytes(take(body, 0, 4, "set IP parameter flags")?.try_into().expect("4 bytes"));
        let field = |at: usize, len: usize, bit: u32, what: &'static str| -> Result<Option<&[u8]>, EoeError> {
            if flags & bit == 0 {
                return Ok(None);
            }
            take(body, at, len, what).map(Some)
        };
        let address = |at, bit, what| -> Result<Option<Ipv4Addr>, EoeError> {
            Ok(field(at, 4, bit, what)?.map(|b| Ipv4Addr::from(u32::from_le_bytes(b.try_into().expect("4 bytes")))))
        };
        let dns_name = match field(26, DNS_NAME_LEN, ip_flags::DNS_NAME, "DNS name")? {
            None => None,
            Some(raw) => {
                let end = raw.iter().position(|&b| b == 0).unwrap_or(raw.len());
                Some(std::str::from_utf8(&raw[..end]).map_err(|_| EoeError::DnsNameNotText)?.to_owned())
            }
        };
        Ok(IpParameters {
            mac: field(4, 6, ip_flags::MAC, "MAC address")?.map(|b| b.try_into().expect("6 bytes")),
            ip: address(10, ip_flags::IP, "IP address")?,
            subnet_mask: address(14, ip_flags::SUBNET_MASK, "subnet mask")?,
            gateway: address(18, ip_flags::GATEWAY, "default gateway")?,
            dns_server: address(22, ip_flags::DNS_SERVER, "DNS server")?,
            dns_name,
        })
    }
}

/// A MAC address written as six hexadecimal bytes separated by colons (`02:01:05:30:03:e9`).
pub fn parse_mac(text: &str) -> Result<[u8; 6], SettingError> {
    let error = || SettingError::Address { what: "MAC address", value: text.into(), form: "aa:bb:cc:dd:ee:ff" };
    let mut mac = [0u8; 6];
    let mut parts = text.split(':');
    for byte in &mut mac {
        let part = parts.next().filter(|p| p.len() == 2).ok_or_else(error)?;
        *byte = u8::from_str_radix(part, 16).map_err(|_| error())?;
    }
    if parts.next().is_some() {
        return Err(error());
    }
    Ok(mac)
}

/// An IPv4 address in dotted form; `what` names the field in the error.
pub fn parse_ipv4(what: &'static str, text: &str) -> Result<Ipv4Addr, SettingError> {
    text.parse().map_err(|_| SettingError::Address { what, value: text.into(), form: "a.b.c.d (IPv4)" })
}

/// `len` bytes of `body` at `at`, or the error that names what was cut short.
fn take<'a>(body: &'a [u8], at: usize, len: usize, what: &'static str) -> Result<&'a [u8], EoeError> {
    body.get(at..at + len).ok_or(EoeError::Truncated { what, len: body.len(), needed: at + len })
}

/// One decoded EoE message (the mailbox body of a message of type EoE).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum EoeMessage<'a> {
    /// A fragment of an Ethernet frame; `timestamp` when "time appended" was set.
    Fragment {
        /// Its header.
        header: FragmentHeader,
        /// The fragment's part of the frame.
        data: &'a [u8],
        /// The time stamp after the data.
        timestamp: Option<u32>,
    },
    /// Set IP Parameter request.
    SetIpRequest(IpParameters),
    /// Set IP Parameter response with its result.
    SetIpResponse(EoeResult),
    /// Another frame type, which neither side here serves; its second word kept raw.
    Other {
        /// The frame type.
        frame_type: EoeFrameType,
        /// The second EoE word.
        info: u16,
    },
}

impl<'a> EoeMessage<'a> {
    /// Decodes the mailbox body of an EoE message.
    pub fn decode(body: &'a [u8]) -> Result<Self, EoeError> {
        let header = take(body, 0, EOE_HEADER_LEN, "EoE header")?;
        let (first, second) = (u16::from_le_bytes([header[0], header[1]]), u16::from_le_bytes([header[2], header[3]]));
        let frame_type = EoeFrameType::try_from((first & 0x0F) as u8).map_err(EoeError::UnknownCode)?;
        let rest = &body[EOE_HEADER_LEN..];
        Ok(match frame_type {
            EoeFrameType::Fragment => {
                let header = FragmentHeader {
                    port: ((first >> 4) & 0x0F) as u8,
                    last_fragment: first & 0x0100 != 0,
                    time_appended: first & 0x0200 != 0,
                    time_request: first & 0x0400 != 0,
                    fragment_number: (second & 0x3F) as u8,
                    offset_units: ((second >> 6) & 0x3F) as u8,
                    frame_number: (second >> 12) as u8,
                };
                let (data, timestamp) = if header.time_appended {
                    let split = rest.len().checked_sub(TIMESTAMP_LEN).ok_or(EoeError::Truncated {
                        what: "fragment with its time stamp",
                        len: body.len(),
                        needed: EOE_HEADER_LEN + TIMESTAMP_LEN,
                    })?;
                    let stamp = u32::from_le_bytes(rest[split..].try_into().expect("4 bytes"));
                    (&rest[..split], Some(stamp))
                } else {
                    (rest, None)
                };
                EoeMessage::Fragment { header, data, timestamp }
            }
            EoeFrameType::SetIpRequest => EoeMessage::SetIpRequest(IpParameters::decode(rest)?),
            EoeFrameType::SetIpResponse => EoeMessage::SetIpResponse(EoeResult(second)),
            frame_type => EoeMessage::Other { frame_type, info: second },
        })
    }
}

/// Writes the mailbox and EoE headers for a body of `body_len` bytes already in place.
fn write_headers(out: &mut [u8], counter: u8, first: u16, second: u16, body_len: usize) -> usize {
    MailboxHeader::new(MailboxType::Eoe, (EOE_HEADER_LEN + body_len) as u16, counter).encode(out);
    out[HEADER_LEN..HEADER_LEN + 2].copy_from_slice(&first.to_le_bytes());
    out[HEADER_LEN + 2..HEADER_LEN + 4].copy_from_slice(&second.to_le_bytes());
    HEADER_LEN + EOE_HEADER_LEN + body_len
}

/// Offset of an EoE message's body in a mailbox message.
pub const BODY_OFFSET: usize = HEADER_LEN + EOE_HEADER_LEN;

/// Writes a whole fragment message (mailbox header, EoE header, `data`) into `out`; returns
/// its length. `out` must hold [`BODY_OFFSET`] + `data.len()` bytes.
pub fn write_fragment(out: &mut [u8], counter: u8, header: &FragmentHeader, data: &[u8]) -> usize {
    let first = u16::from(EoeFrameType::Fragment as u8)
        | (u16::from(header.port & 0x0F) << 4)
        | (u16::from(header.last_fragment) << 8)
        | (u16::from(header.time_appended) << 9)
        | (u16::from(header.time_request) << 10);
    let second = u16::from(header.fragment_number & 0x3F)
        | (u16::from(header.offset_units & 0x3F) << 6)
        | (u16::from(header.frame_number & 0x0F) << 12);
    out[BODY_OFFSET..BODY_OFFSET + data.len()].copy_from_slice(data);
    write_headers(out, counter, first, second, data.len())
}

/// Writes a whole Set IP Parameter request into `out` (at least [`BODY_OFFSET`] +
/// [`SET_IP_LEN`] bytes); returns its length.
pub fn write_set_ip_request(out: &mut [u8], counter: u8, parameters: &IpParameters) -> Result<usize, EoeError> {
    let len = parameters.encode(&mut out[BODY_OFFSET..])?;
    Ok(write_headers(out, counter, EoeFrameType::SetIpRequest as u16, 0, len))
}

/// Writes a whole response of `frame_type` (Set IP Parameter response, ...) with `result`
/// into `out`; returns its length.
pub fn write_response(out: &mut [u8], counter: u8, frame_type: EoeFrameType, result: EoeResult) -> usize {
    write_headers(out, counter, frame_type as u16, result.0, 0)
}

/// Cuts one Ethernet frame into the fragments that fit a mailbox of a given size.
#[derive(Clone, Debug)]
pub struct Fragmenter<'a> {
    frame: &'a [u8],
    sent: usize,
    /// Room of the last fragment, which need not be whole units.
    last_room: usize,
    /// Room of the others: the most whole 32-byte units that fit.
    room: usize,
    fragment_number: u8,
    frame_number: u8,
}

impl<'a> Fragmenter<'a> {
    /// The fragments of `frame` numbered `frame_number` (4 bits) for a mailbox of
    /// `mailbox_len` bytes. An error for a frame longer than [`MAX_FRAME_LEN`] or a mailbox too
    /// small for one 32-byte unit.
    pub fn new(frame: &'a [u8], frame_number: u8, mailbox_len: usize) -> Result<Self, EoeError> {
        if frame.len() > MAX_FRAME_LEN {
            return Err(EoeError::FrameTooLong { len: frame.len(), max: MAX_FRAME_LEN });
        }
        let last_room = mailbox_len.saturating_sub(BODY_OFFSET);
        let room = last_room / FRAGMENT_UNIT * FRAGMENT_UNIT;
        if room == 0 {
            return Err(EoeError::MailboxTooSmall { len: mailbox_len, min: BODY_OFFSET + FRAGMENT_UNIT });
        }
        Ok(Fragmenter { frame, sent: 0, last_room, room, fragment_number: 0, frame_number: frame_number & 0x0F })
    }
}

impl<'a> Iterator for Fragmenter<'a> {
    type Item = (FragmentHeader, &'a [u8]);

    fn next(&mut self) -> Option<Self::Item> {
        if self.sent >= self.frame.len() && (self.fragment_number > 0 || !self.frame.is_empty()) {
            return None;
        }
        let left = self.frame.len() - self.sent;
        // The last fragment carries what is left whatever its length; others whole units.
        let (len, last) = if left <= self.last_room { (left, true) } else { (self.room, false) };
        let offset_units = if self.fragment_number == 0 {
            self.frame.len().div_ceil(FRAGMENT_UNIT)
        } else {
            self.sent / FRAGMENT_UNIT
        };
        let header = FragmentHeader {
            last_fragment: last,
            fragment_number: self.fragment_number,
            offset_units: offset_units as u8,
            frame_number: self.frame_number,
            ..FragmentHeader::default()
        };
        let data = &self.frame[self.sent..self.sent + len];
        self.sent += len;
        self.fragment_number += 1;
        Some((header, data))
    }
}

/// Puts an Ethernet frame back together from its fragments, in a buffer allocated once.
///
/// Fragments must come in order, as the mailbox delivers them: a fragment 0 starts a frame
/// (dropping one that was not finished), any other must be the next of the frame being built,
/// with its frame number and at the offset reached. A fragment out of order drops the frame
/// being built and is an error saying which.
#[derive(Clone, Debug)]
pub struct Reassembler {
    buffer: Vec<u8>,
    len: usize,
    size_units: u8,
    next_fragment: u8,
    frame_number: u8,
    building: bool,
}

impl Default for Reassembler {
    fn default() -> Self {
        Reassembler {
            buffer: vec![0; MAX_FRAME_LEN],
            len: 0,
            size_units: 0,
            next_fragment: 0,
            frame_number: 0,
            building: false,
        }
    }
}

impl Reassembler {
    /// Whether a frame was begun and not finished.
    pub fn building(&self) -> bool {
        self.building
    }

    /// Takes one fragment; the whole frame when it was the last one.
    pub fn push(&mut self, header: &FragmentHeader, data: &[u8]) -> Result<Option<&[u8]>, EoeError> {
        if header.fragment_number == 0 {
            self.building = true;
            self.len = 0;
            self.size_units = header.offset_units;
            self.frame_number = header.frame_number;
            self.next_fragment = 0;
        } else {
            if !self.building {
                return Err(EoeError::OutOfOrder {
                    frame_number: header.frame_number,
                    expected: 0,
                    got: header.fragment_number,
                });
            }
            if header.frame_number != self.frame_number || header.fragment_number != self.next_fragment {
                self.building = false;
                return Err(EoeError::OutOfOrder {
                    frame_number: header.frame_number,
                    expected: self.next_fragment,
                    got: header.fragment_number,
                });
            }
            if usize::from(header.offset_units) * FRAGMENT_UNIT != self.len {
                self.building = false;
                return Err(EoeError::OffsetMismatch {
                    offset: usize::from(header.offset_units) * FRAGMENT_UNIT,
                    received: self.len,
                });
            }
        }
        let size = usize::from(self.size_units) * FRAGMENT_UNIT;
        if self.len + data.len() > size.min(MAX_FRAME_LEN) {
            self.building = false;
            return Err(EoeError::FrameTooLong { len: self.len + data.len(), max: size.min(MAX_FRAME_LEN) });
        }
        if !header.last_fragment && !data.len().is_multiple_of(FRAGMENT_UNIT) {
            self.building = false;
            return Err(EoeError::FragmentNotWholeUnits { len: data.len() });
        }
        self.buffer[self.len..self.len + data.len()].copy_from_slice(data);
        self.len += data.len();
        self.next_fragment = header.fragment_number.wrapping_add(1);
        if !header.last_fragment {
            return Ok(None);
        }
        self.building = false;
        if self.len.div_ceil(FRAGMENT_UNIT) != size / FRAGMENT_UNIT {
            return Err(EoeError::SizeMismatch { announced_units: self.size_units, received: self.len });
        }
        Ok(Some(&self.buffer[..self.len]))
    }
}

/// An EoE message or fragment that does not fit the standard (ETG.1000.6 §5.7), or a frame
/// that cannot be sent through EoE.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum EoeError {
    /// A message, or a field of one, cut short.
    #[error("{what} cut short: the message has {len} bytes, it needs {needed}")]
    Truncated {
        /// The structure or field.
        what: &'static str,
        /// Bytes there were.
        len: usize,
        /// Bytes it needs.
        needed: usize,
    },
    /// A frame type outside the standard's set.
    #[error("{0}")]
    UnknownCode(UnknownCode),
    /// A DNS name longer than its field.
    #[error("DNS name of {len} bytes is longer than {max}")]
    DnsNameTooLong {
        /// Its length in bytes.
        len: usize,
        /// The field's length.
        max: usize,
    },
    /// A DNS name that is not UTF-8 text.
    #[error("DNS name is not valid text")]
    DnsNameNotText,
    /// An Ethernet frame longer than EoE carries here, or than its fragment 0 announced.
    #[error("Ethernet frame of {len} bytes is longer than {max}")]
    FrameTooLong {
        /// Its length.
        len: usize,
        /// The most allowed.
        max: usize,
    },
    /// A mailbox too small for one 32-byte unit of a fragment.
    #[error("a {len}-byte mailbox cannot carry an EoE fragment (it needs {min} bytes)")]
    MailboxTooSmall {
        /// The mailbox's length.
        len: usize,
        /// The least that carries a fragment.
        min: usize,
    },
    /// A fragment other than the next one of the frame being put together.
    #[error("EoE fragment {got} of frame {frame_number} where fragment {expected} was expected")]
    OutOfOrder {
        /// Its frame number.
        frame_number: u8,
        /// The fragment number expected.
        expected: u8,
        /// The fragment number received.
        got: u8,
    },
    /// A fragment whose offset is not where the frame being put together has reached.
    #[error("EoE fragment at offset {offset} where {received} bytes were received")]
    OffsetMismatch {
        /// Its offset in bytes.
        offset: usize,
        /// Bytes received so far.
        received: usize,
    },
    /// A fragment other than the last whose length is not a multiple of 32 bytes.
    #[error("EoE fragment of {len} bytes is not the last but not a multiple of 32 bytes")]
    FragmentNotWholeUnits {
        /// Its length.
        len: usize,
    },
    /// The slave's SII does not list EoE among its mailbox protocols.
    #[error("slave {slave} does not speak EoE (SII mailbox protocols)")]
    NotSupported {
        /// Slave position.
        slave: u16,
    },
    /// The slave answered Set IP Parameter with another result than success.
    #[error("slave {slave} answered Set IP Parameter with result 0x{result:04X} ({result_name})")]
    Refused {
        /// Slave position.
        slave: u16,
        /// The result code.
        result: u16,
        /// Its name in the standard.
        result_name: &'static str,
    },
    /// A frame whose length does not round to the size its fragment 0 announced.
    #[error("EoE frame of {received} bytes where fragment 0 announced {announced_units} units of 32 bytes")]
    SizeMismatch {
        /// The size announced, in 32-byte units.
        announced_units: u8,
        /// Bytes received.
        received: usize,
    },
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The request TwinCAT sent to a real AKD (issue 15), all six fields present.
    fn twincat_request() -> IpParameters {
        IpParameters {
            mac: Some([0x02, 0x01, 0x05, 0x30, 0x03, 0xE9]),
            ip: Some(Ipv4Addr::new(192, 168, 0, 0)),
            subnet_mask: Some(Ipv4Addr::new(255, 255, 255, 0)),
            gateway: Some(Ipv4Addr::new(192, 168, 0, 139)),
            dns_server: Some(Ipv4Addr::UNSPECIFIED),
            dns_name: Some("Drive_1__AKD_".into()),
        }
    }

    #[test]
    fn set_ip_request_as_twincat_sent_it() {
        let mut out = [0u8; 128];
        let len = write_set_ip_request(&mut out, 2, &twincat_request()).unwrap();
        assert_eq!(len, BODY_OFFSET + SET_IP_LEN);
        let header = MailboxHeader::decode(&out[..len]).unwrap();
        assert_eq!((header.protocol(), header.counter), (Some(MailboxType::Eoe), 2));
        assert_eq!(&out[6..10], &[0x02, 0x00, 0x00, 0x00], "frame type 2, second word 0");
        assert_eq!(&out[10..14], &[0x3F, 0, 0, 0], "flags: all six fields");
        assert_eq!(&out[14..20], &[0x02, 0x01, 0x05, 0x30, 0x03, 0xE9]);
        assert_eq!(&out[20..24], &[0, 0, 168, 192], "IP as a little-endian word");
        assert_eq!(&out[24..28], &[0, 255, 255, 255]);
        assert_eq!(&out[28..32], &[139, 0, 168, 192]);
        assert_eq!(&out[36..49], b"Drive_1__AKD_");
        assert!(out[49..68].iter().all(|&b| b == 0), "name padded to 32 bytes");
        let EoeMessage::SetIpRequest(decoded) = EoeMessage::decode(header.body(&out)).unwrap() else { panic!() };
        assert_eq!(decoded, twincat_request());
    }

    #[test]
    fn set_ip_request_with_fewer_fields() {
        let only_ip = IpParameters { ip: Some(Ipv4Addr::new(10, 0, 0, 7)), ..IpParameters::default() };
        let mut body = [0u8; SET_IP_LEN];
        assert_eq!(only_ip.encode(&mut body).unwrap(), 14, "up to the IP address");
        assert_eq!(body[0], 0x02);
        assert_eq!(IpParameters::decode(&body).unwrap(), only_ip);
        // Cut after the IP address: the fields whose flags are clear may be missing.
        assert_eq!(IpParameters::decode(&body[..14]).unwrap(), only_ip);
        let err = IpParameters::decode(&body[..12]).unwrap_err();
        assert_eq!(err, EoeError::Truncated { what: "IP address", len: 12, needed: 14 });
        assert_eq!(IpParameters::default().encode(&mut body).unwrap(), 4, "flags alone");
        let long = IpParameters { dns_name: Some("x".repeat(33)), ..IpParameters::default() };
        assert_eq!(long.encode(&mut body).unwrap_err(), EoeError::DnsNameTooLong { len: 33, max: 32 });
    }

    #[test]
    fn addresses_are_read_in_their_forms() {
        assert_eq!(parse_mac("02:01:05:30:03:e9").unwrap(), [0x02, 0x01, 0x05, 0x30, 0x03, 0xE9]);
        for bad in ["02:01:05:30:03", "02:01:05:30:03:e9:00", "2:01:05:30:03:e9", "xx:01:05:30:03:e9"] {
            let err = parse_mac(bad).unwrap_err();
            assert_eq!(err.to_string(), format!("MAC address {bad:?} is not of the form aa:bb:cc:dd:ee:ff"));
        }
        assert_eq!(parse_ipv4("IP address", "192.168.0.10").unwrap(), Ipv4Addr::new(192, 168, 0, 10));
        let err = parse_ipv4("gateway", "192.168.0").unwrap_err();
        assert_eq!(err.to_string(), "gateway \"192.168.0\" is not of the form a.b.c.d (IPv4)");
    }

    #[test]
    fn set_ip_response_carries_its_result() {
        let mut out = [0u8; 16];
        let len = write_response(&mut out, 1, EoeFrameType::SetIpResponse, EoeResult::SUCCESS);
        assert_eq!(&out[..len], &[0x04, 0, 0, 0, 0, 0x12, 0x03, 0x00, 0x00, 0x00]);
        assert_eq!(EoeMessage::decode(&out[6..len]).unwrap(), EoeMessage::SetIpResponse(EoeResult::SUCCESS));
        write_response(&mut out, 1, EoeFrameType::SetIpResponse, EoeResult::NO_IP_SUPPORT);
        let EoeMessage::SetIpResponse(result) = EoeMessage::decode(&out[6..10]).unwrap() else { panic!() };
        assert_eq!((result, result.name()), (EoeResult(0x0201), "no IP support"));
    }

    #[test]
    fn header_bits_are_where_the_standard_puts_them() {
        let header = FragmentHeader {
            port: 0x5,
            last_fragment: true,
            time_appended: false,
            time_request: true,
            fragment_number: 0x21,
            offset_units: 0x2A,
            frame_number: 0x9,
        };
        let mut out = [0u8; 16];
        let len = write_fragment(&mut out, 3, &header, &[0xAA, 0xBB]);
        // First word: type 0, port 5, last (bit 8), time request (bit 10) -> 0x0550.
        // Second word: fragment 0x21 | offset 0x2A << 6 | frame 9 << 12 -> 0x9AA1.
        assert_eq!(&out[6..len], &[0x50, 0x05, 0xA1, 0x9A, 0xAA, 0xBB]);
        let decoded = EoeMessage::decode(&out[6..len]).unwrap();
        assert_eq!(decoded, EoeMessage::Fragment { header, data: &[0xAA, 0xBB], timestamp: None });
    }

    #[test]
    fn time_stamp_after_the_data() {
        let header = FragmentHeader { last_fragment: true, time_appended: true, offset_units: 1, ..Default::default() };
        let mut out = [0u8; 32];
        let len = write_fragment(&mut out, 1, &header, &[1, 2, 3, 0x78, 0x56, 0x34, 0x12]);
        let EoeMessage::Fragment { data, timestamp, .. } = EoeMessage::decode(&out[6..len]).unwrap() else { panic!() };
        assert_eq!((data, timestamp), (&[1u8, 2, 3][..], Some(0x1234_5678)));
        let short = [0x00, 0x03, 0x40, 0x00, 1, 2];
        assert!(matches!(EoeMessage::decode(&short), Err(EoeError::Truncated { .. })));
    }

    #[test]
    fn malformed_headers_are_errors() {
        assert!(matches!(EoeMessage::decode(&[0, 0, 0]), Err(EoeError::Truncated { what: "EoE header", .. })));
        let Err(EoeError::UnknownCode(code)) = EoeMessage::decode(&[0x0C, 0, 0, 0]) else { panic!() };
        assert_eq!(code.value, 12);
        assert!(matches!(EoeMessage::decode(&[0x02, 0, 0, 0, 0x3F]), Err(EoeError::Truncated { .. })));
        assert_eq!(
            EoeMessage::decode(&[0x06, 0, 7, 0]).unwrap(),
            EoeMessage::Other { frame_type: EoeFrameType::GetIpRequest, info: 7 }
        );
    }

    #[test]
    fn a_frame_that_fits_goes_in_one_fragment() {
        let frame = [0x11u8; 42];
        let fragments: Vec<_> = Fragmenter::new(&frame, 3, 1024).unwrap().collect();
        assert_eq!(fragments.len(), 1);
        let (header, data) = fragments[0];
        assert!(header.last_fragment);
        assert_eq!((header.fragment_number, header.offset_units, header.frame_number), (0, 2, 3));
        assert_eq!(data, &frame);
    }

    #[test]
    fn a_large_frame_is_cut_in_whole_units_and_put_back() {
        let frame: Vec<u8> = (0..1442u32).map(|i| i as u8).collect();
        let fragments: Vec<_> = Fragmenter::new(&frame, 15, 1024).unwrap().collect();
        // 1024 - 10 = 1014 bytes of room: 992 (31 whole units), then the 450 left.
        assert_eq!(fragments.iter().map(|(_, d)| d.len()).collect::<Vec<_>>(), vec![992, 450]);
        assert_eq!(fragments[0].0.offset_units, 46, "fragment 0: whole size, 1442 -> 46 units");
        assert_eq!(fragments[1].0.offset_units, 31, "fragment 1: offset 992 -> 31 units");
        let mut r = Reassembler::default();
        assert_eq!(r.push(&fragments[0].0, fragments[0].1).unwrap(), None);
        assert!(r.building());
        assert_eq!(r.push(&fragments[1].0, fragments[1].1).unwrap(), Some(&frame[..]));
        assert!(!r.building());
    }

    #[test]
    fn fragments_out_of_order_drop_the_frame() {
        let frame = [7u8; 300];
        let f: Vec<_> = Fragmenter::new(&frame, 1, 64).unwrap().collect();
        assert_eq!(f.len(), 9, "a 64-byte mailbox: 8 fragments of 32 bytes, then the 44 left");
        let mut r = Reassembler::default();
        r.push(&f[0].0, f[0].1).unwrap();
        let err = r.push(&f[2].0, f[2].1).unwrap_err();
        assert_eq!(err, EoeError::OutOfOrder { frame_number: 1, expected: 1, got: 2 });
        assert!(!r.building());
        let err = r.push(&f[1].0, f[1].1).unwrap_err();
        assert_eq!(err, EoeError::OutOfOrder { frame_number: 1, expected: 0, got: 1 });
        // A new fragment 0 starts over, and the whole frame goes through.
        let mut done = None;
        for (h, d) in &f {
            done = r.push(h, d).unwrap().map(<[u8]>::to_vec);
        }
        assert_eq!(done.as_deref(), Some(&frame[..]));
    }

    #[test]
    fn inconsistent_fragments_are_errors() {
        let mut r = Reassembler::default();
        let first = FragmentHeader { offset_units: 2, ..Default::default() };
        assert_eq!(r.push(&first, &[0; 31]).unwrap_err(), EoeError::FragmentNotWholeUnits { len: 31 });
        r.push(&first, &[0; 32]).unwrap();
        let wrong_offset = FragmentHeader { fragment_number: 1, offset_units: 2, last_fragment: true, ..first };
        assert_eq!(r.push(&wrong_offset, &[0; 4]).unwrap_err(), EoeError::OffsetMismatch { offset: 64, received: 32 });
        r.push(&first, &[0; 32]).unwrap();
        let too_long = FragmentHeader { fragment_number: 1, offset_units: 1, last_fragment: true, ..first };
        assert_eq!(r.push(&too_long, &[0; 33]).unwrap_err(), EoeError::FrameTooLong { len: 65, max: 64 });
        r.push(&first, &[0; 32]).unwrap();
        let short = FragmentHeader { fragment_number: 1, offset_units: 1, last_fragment: true, ..first };
        assert_eq!(r.push(&short, &[]).unwrap_err(), EoeError::SizeMismatch { announced_units: 2, received: 32 });
        assert_eq!(
            Fragmenter::new(&[0; 1519], 0, 1024).unwrap_err(),
            EoeError::FrameTooLong { len: 1519, max: MAX_FRAME_LEN }
        );
        assert_eq!(Fragmenter::new(&[0; 10], 0, 41).unwrap_err(), EoeError::MailboxTooSmall { len: 41, min: 42 });
    }

    proptest! {
        #[test]
        fn any_frame_round_trips(len in 1usize..=MAX_FRAME_LEN, mailbox in 42usize..1100, number in 0u8..16) {
            let frame: Vec<u8> = (0..len).map(|i| (i * 7) as u8).collect();
            let mut r = Reassembler::default();
            let mut out = vec![0u8; mailbox];
            let mut whole = None;
            let mut fragments = 0;
            for (header, data) in Fragmenter::new(&frame, number, mailbox).unwrap() {
                let n = write_fragment(&mut out, 1, &header, data);
                prop_assert!(n <= mailbox);
                let EoeMessage::Fragment { header, data, .. } = EoeMessage::decode(&out[HEADER_LEN..n]).unwrap()
                else { panic!() };
                prop_assert_eq!(header.frame_number, number);
                whole = r.push(&header, data).unwrap().map(<[u8]>::to_vec);
                fragments += 1;
            }
            prop_assert!(fragments <= 64);
            prop_assert_eq!(whole, Some(frame));
        }

        #[test]
        fn decode_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..80)) {
            let _ = EoeMessage::decode(&bytes);
        }
    }
}
