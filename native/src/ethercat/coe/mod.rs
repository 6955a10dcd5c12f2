//! CANopen over EtherCAT codec (ETG.1000.6 §5.6, CiA 301, AKD manual §5.13).
//!
//! A CoE message is a mailbox message of type 3 whose body starts with a 2-byte CoE header
//! (number and service). This module encodes and decodes the SDO transfers (expedited, normal,
//! segmented, abort), emergency messages and the SDO information service, on both the client
//! (master) and server (virtual AKD) side. Values are borrowed from the caller's buffers.
//!
//! One file per service, as the standard splits them: [`sdo`] (SDO transfers: expedited,
//! normal, segmented, abort, and the abort codes), [`sdo_info`] (the SDO information service:
//! OD lists, object and entry descriptions), [`emergency`] (emergency messages), and
//! [`data_type`] (CiA 301 data types, which the descriptions and the mappings name). This file
//! holds what they share: the CoE header and the message around it.

use crate::ethercat::mailbox::MailboxError;
use crate::ethercat::mailbox::{MailboxHeader, MailboxType, HEADER_LEN};

pub mod data_type;
pub mod emergency;
pub mod sdo;
pub mod sdo_info;

pub use emergency::*;
pub use sdo::*;
pub use sdo_info::*;

/// Length of the CoE header.
pub const COE_HEADER_LEN: usize = 2;

/// Offset of the SDO body from the start of the mailbox message.
pub const SDO_OFFSET: usize = HEADER_LEN + COE_HEADER_LEN;

wire_codes! {
    /// CoE services (CoE header bits 12–15, ETG.1000.6 Table 29).
    pub enum CoeService: u8, "CoE service" {
        Emergency = 1 => "Emergency",
        /// SDO request (master to slave).
        SdoRequest = 2 => "SDO Request",
        /// SDO response (slave to master).
        SdoResponse = 3 => "SDO Response",
        TxPdo = 4 => "TxPDO",
        RxPdo = 5 => "RxPDO",
        TxPdoRemoteRequest = 6 => "TxPDO remote request",
        RxPdoRemoteRequest = 7 => "RxPDO remote request",
        SdoInformation = 8 => "SDO Information",
    }
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

/// Writes a whole CoE mailbox message: mailbox header, CoE header for `service`, and a body
/// written by `body` into the space after them. Returns the message length.
pub fn write_message(out: &mut [u8], counter: u8, service: CoeService, body: impl FnOnce(&mut [u8]) -> usize) -> usize {
    let len = body(&mut out[SDO_OFFSET..]);
    MailboxHeader::new(MailboxType::Coe, (COE_HEADER_LEN + len) as u16, counter).encode(out);
    CoeHeader::new(service).encode(&mut out[HEADER_LEN..]);
    SDO_OFFSET + len
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wire_codes_round_trip_and_name_the_unknown() {
        for service in CoeService::ALL {
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
