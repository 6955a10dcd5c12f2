//! The virtual AKD's mailbox server: CoE SDO transfers (expedited, normal, segmented), SDO
//! information with fragmentation, emergencies, EoE ([`eoe_server`](crate::sim::eoe_server)) and
//! FoE ([`foe_server`](crate::sim::foe_server)), and mailbox error replies for anything else.
//!
//! Replies echo the request's mailbox counter, as the real drive does (request counter 1 →
//! reply counter 1 in the SOEM capture). A message with the same non-zero counter as the last
//! one accepted is the master writing it again after a lost frame (ETG.1000.6 mailbox "Cnt"):
//! it is not served a second time. Replies wait in a queue until the mailbox-in buffer is free;
//! the one the master read last is kept for a repeat request.

use std::collections::VecDeque;

use crate::error::EoeError;
use crate::ethercat::al::AlState;
use crate::ethercat::coe::{
    access, write_info_message, write_message, write_sdo_response, CoeHeader, CoeService, Emergency, EntryDescription,
    ObjectDescription, OdListType, SdoAbortCode, SdoInfoHeader, SdoInfoOpcode, SdoRequest, SdoResponse, COE_HEADER_LEN,
    SDO_INFO_HEADER_LEN, SDO_LEN,
};
use crate::ethercat::mailbox::{
    next_counter, write_error_reply, MailboxErrorDetail, MailboxHeader, MailboxType, HEADER_LEN,
};
use crate::sim::eoe_server::EoeServer;
use crate::sim::foe_server::FoeServer;
use crate::sim::od::ObjectDictionary;

/// Messages the drive queues for the master before its IP stack waits (a master that does not
/// read its mailbox must not make the drive's memory grow).
const MAX_QUEUED: usize = 32;

/// A segmented upload in progress.
struct Upload {
    index: u16,
    subindex: u8,
    data: Vec<u8>,
    sent: usize,
    toggle: bool,
}

/// A segmented download in progress.
struct Download {
    index: u16,
    subindex: u8,
    size: usize,
    data: Vec<u8>,
    toggle: bool,
}

/// The mailbox server of one virtual AKD.
#[derive(Default)]
pub struct MailboxServer {
    upload: Option<Upload>,
    download: Option<Download>,
    replies: VecDeque<Vec<u8>>,
    /// The reply last put in the mailbox-in buffer, and the one before it, which the master read
    /// (the buffer takes a reply only once the last one was read).
    last: Option<Vec<u8>>,
    read_before: Option<Vec<u8>>,
    counter: u8,
    /// Counter of the last message from the master that was served (0: none, or not counted).
    accepted_counter: u8,
    eoe: EoeServer,
    foe: FoeServer,
    /// The firmware's delays before the Set IP Parameter response and after it, before the
    /// announcement (see [`Timing`](crate::sim::Timing)).
    eoe_delays: (u64, u64),
    /// The protocols the slave's SII declares (its bits of
    /// [`MailboxType::sii_protocol_bit`]), where it serves fewer than the AKD; the others are
    /// answered with a mailbox error.
    protocols: Option<u16>,
}

/// The write-access bit of the state the drive is in.
fn state_write_access(state: AlState) -> u16 {
    match state {
        AlState::SafeOp => access::WRITE_SAFEOP,
        AlState::Op => access::WRITE_OP,
        _ => access::WRITE_PREOP,
    }
}

impl MailboxServer {
    /// A server whose EoE answers Set IP Parameter after `set_ip_ns` and announces the drive's
    /// address `announce_ns` after that.
    pub fn with_eoe_delays(set_ip_ns: u64, announce_ns: u64) -> Self {
        MailboxServer { eoe_delays: (set_ip_ns, announce_ns), ..MailboxServer::default() }
    }

    /// A server of `protocols` only (bits of [`MailboxType::sii_protocol_bit`], as an SII
    /// declares them).
    pub fn of_protocols(protocols: u16) -> Self {
        MailboxServer { protocols: Some(protocols), ..MailboxServer::default() }
    }

    /// Forgets transfers, queued replies and the IP settings (the mailbox stops when the drive
    /// goes to Init); files written by FoE stay.
    pub fn reset(&mut self) {
        let (mut foe, eoe_delays, protocols) = (std::mem::take(&mut self.foe), self.eoe_delays, self.protocols);
        foe.stop();
        *self = MailboxServer { foe, eoe_delays, protocols, ..MailboxServer::default() };
    }

    /// The EoE side (its IP parameters, fragments dropped).
    pub fn eoe(&self) -> &EoeServer {
        &self.eoe
    }

    /// The FoE side, to inject a busy drive.
    pub fn foe_mut(&mut self) -> &mut FoeServer {
        &mut self.foe
    }

    /// The firmware's work at bus time `now_ns` beside the master's requests: EoE replies that
    /// are due and the frames the drive's IP stack sends, in messages of `mailbox_size` bytes.
    pub fn poll(&mut self, now_ns: u64, mailbox_size: usize) {
        if self.replies.len() >= MAX_QUEUED {
            return;
        }
        let (counter, replies) = (&mut self.counter, &mut self.replies);
        self.eoe.poll(
            now_ns,
            mailbox_size,
            || {
                *counter = next_counter(*counter);
                *counter
            },
            |message| replies.push_back(message),
        );
    }

    /// The next reply for the mailbox-in buffer; it is kept for a repeat request.
    pub fn next_reply(&mut self) -> Option<&[u8]> {
        let reply = self.replies.pop_front()?;
        self.read_before = self.last.replace(reply);
        self.last.as_deref()
    }

    /// The reply a repeat request asks for, to put into the mailbox-in buffer again: the one the
    /// master read last, whose read it lost. When the buffer is `full`, the master has not read
    /// the reply in it, which was put in after that read: it goes back to the front of the queue,
    /// to follow the repeated one rather than take its place.
    pub fn repeat(&mut self, full: bool) -> Option<&[u8]> {
        if full {
            let read = self.read_before.take()?;
            if let Some(unread) = self.last.replace(read) {
                self.replies.push_front(unread);
            }
        }
        self.last.as_deref()
    }

    /// Queues an emergency message (CoE service 1) with the drive's own counter.
    pub fn emergency(&mut self, emergency: &Emergency, mailbox_size: usize) {
        self.counter = next_counter(self.counter);
        let mut out = vec![0u8; mailbox_size.max(HEADER_LEN + COE_HEADER_LEN + 8)];
        let len = write_message(&mut out, self.counter, CoeService::Emergency, |b| emergency.encode(b));
        self.queue(out, len);
    }

    /// Queues the reply in the first `len` bytes of `out`; none when `len` is 0.
    fn queue(&mut self, mut out: Vec<u8>, len: usize) {
        if len > 0 {
            out.truncate(len);
            self.replies.push_back(out);
        }
    }

    /// Handles one message the master wrote to the mailbox-out buffer at bus time `now_ns`;
    /// `mailbox_size` is the length of the mailbox-in buffer the replies must fit,
    /// `request_size` that of the mailbox-out buffer (whose full FoE packets a master writes).
    pub fn handle(
        &mut self,
        message: &[u8],
        od: &mut ObjectDictionary,
        state: AlState,
        mailbox_size: usize,
        request_size: usize,
        now_ns: u64,
    ) {
        let counter = message.get(5).map_or(0, |b| (b >> 4) & 0x07);
        // Counter 0 is the master's "not counting"; any other repeated value is a repetition.
        if counter != 0 && counter == self.accepted_counter {
            return;
        }
        self.accepted_counter = counter;
        let mut out = vec![0u8; mailbox_size];
        let header = match MailboxHeader::decode(message) {
            Ok(h) if h.length == 0 => return self.error(counter, MailboxErrorDetail::SizeTooShort, mailbox_size),
            Ok(h) => h,
            Err(_) => return self.error(counter, MailboxErrorDetail::InvalidSize, mailbox_size),
        };
        let body = header.body(message);
        let declared = |p: MailboxType| self.protocols.is_none_or(|bits| bits & p.sii_protocol_bit() != 0);
        match header.protocol() {
            Some(p) if !declared(p) => {
                return self.error(counter, MailboxErrorDetail::UnsupportedProtocol, mailbox_size)
            }
            Some(MailboxType::Coe) => {}
            Some(MailboxType::Eoe) => return self.serve_eoe(body, counter, now_ns, mailbox_size),
            Some(MailboxType::Foe) => {
                let len = self.foe.handle(body, counter, request_size, &mut out);
                return self.queue(out, len);
            }
            _ => return self.error(counter, MailboxErrorDetail::UnsupportedProtocol, mailbox_size),
        }
        if body.len() < COE_HEADER_LEN {
            return self.error(counter, MailboxErrorDetail::SizeTooShort, mailbox_size);
        }
        // Long enough, so only a service outside the standard's set fails to decode.
        let Ok(coe) = CoeHeader::decode(body) else {
            return self.error(counter, MailboxErrorDetail::ServiceNotSupported, mailbox_size);
        };
        let body = &body[COE_HEADER_LEN..];
        match coe.service {
            CoeService::SdoRequest => {
                let len = match SdoRequest::decode(body) {
                    Ok(request) => self.sdo(&request, od, state, &mut out, header.counter),
                    Err(_) => {
                        let (index, subindex) = match body {
                            [_, lo, hi, sub, ..] => (u16::from_le_bytes([*lo, *hi]), *sub),
                            _ => (0, 0),
                        };
                        let response = SdoResponse::Abort { index, subindex, code: SdoAbortCode::BAD_COMMAND };
                        write_sdo_response(&mut out, header.counter, &response)
                    }
                };
                // An abort from the master is not answered (a reply of 0 bytes).
                self.queue(out, len);
            }
            CoeService::SdoInformation => self.information(body, od, header.counter, mailbox_size),
            _ => self.error(counter, MailboxErrorDetail::ServiceNotSupported, mailbox_size),
        }
    }

    /// One EoE message: an EoE reply when the request has one, a mailbox error for a header
    /// that is none (cut short: "data too short"; a frame type outside the standard's: "service
    /// not supported"; a field that cannot be read: "invalid protocol header").
    fn serve_eoe(&mut self, body: &[u8], counter: u8, now_ns: u64, mailbox_size: usize) {
        let mut out = vec![0u8; mailbox_size];
        match self.eoe.handle(body, counter, now_ns, self.eoe_delays, &mut out) {
            Ok(len) => self.queue(out, len),
            Err(EoeError::Truncated { .. }) => self.error(counter, MailboxErrorDetail::SizeTooShort, mailbox_size),
            Err(EoeError::UnknownCode(_)) => self.error(counter, MailboxErrorDetail::ServiceNotSupported, mailbox_size),
            Err(_) => self.error(counter, MailboxErrorDetail::InvalidHeader, mailbox_size),
        }
    }

    fn error(&mut self, counter: u8, detail: MailboxErrorDetail, mailbox_size: usize) {
        let mut out = vec![0u8; mailbox_size.max(HEADER_LEN + 4)];
        let len = write_error_reply(&mut out, counter, detail);
        self.queue(out, len);
    }

    /// Answers one SDO request into `out`; returns the reply's length.
    fn sdo(
        &mut self,
        request: &SdoRequest<'_>,
        od: &mut ObjectDictionary,
        state: AlState,
        out: &mut [u8],
        counter: u8,
    ) -> usize {
        let room = out.len() - HEADER_LEN - COE_HEADER_LEN;
        let response = match *request {
            SdoRequest::Upload { index, subindex, complete_access } => {
                self.upload = None;
                match od.read(index, subindex) {
                    _ if complete_access => {
                        SdoResponse::Abort { index, subindex, code: SdoAbortCode::UNSUPPORTED_ACCESS }
                    }
                    Err(code) => SdoResponse::Abort { index, subindex, code },
                    Ok(data) if data.len() <= 4 => {
                        return write_sdo_response(
                            out,
                            counter,
                            &SdoResponse::UploadExpedited { index, subindex, data },
                        );
                    }
                    Ok(data) => {
                        let first = data.len().min(room - SDO_LEN);
                        let data = data.to_vec();
                        if first < data.len() {
                            self.upload =
                                Some(Upload { index, subindex, data: data.clone(), sent: first, toggle: false });
                        }
                        let response = SdoResponse::UploadNormal {
                            index,
                            subindex,
                            complete_size: data.len() as u32,
                            data: &data[..first],
                        };
                        return write_sdo_response(out, counter, &response);
                    }
                }
            }
            SdoRequest::UploadSegment { toggle } => match self.upload.as_mut() {
                None => SdoResponse::Abort { index: 0, subindex: 0, code: SdoAbortCode::BAD_COMMAND },
                Some(u) if u.toggle != toggle => {
                    let (index, subindex) = (u.index, u.subindex);
                    self.upload = None;
                    SdoResponse::Abort { index, subindex, code: SdoAbortCode::TOGGLE_BIT }
                }
                Some(u) => {
                    let n = (u.data.len() - u.sent).min(room - 1);
                    let (from, last) = (u.sent, u.sent + n == u.data.len());
                    u.sent += n;
                    u.toggle = !u.toggle;
                    let data = u.data[from..from + n].to_vec();
                    if last {
                        self.upload = None;
                    }
                    return write_sdo_response(out, counter, &SdoResponse::UploadSegment { toggle, last, data: &data });
                }
            },
            SdoRequest::DownloadExpedited { index, subindex, complete_access, data }
            | SdoRequest::DownloadNormal { index, subindex, complete_access, data, .. }
                if complete_access =>
            {
                let _ = data;
                SdoResponse::Abort { index, subindex, code: SdoAbortCode::UNSUPPORTED_ACCESS }
            }
            SdoRequest::DownloadExpedited { index, subindex, data, .. } => {
                self.download = None;
                match od.write(index, subindex, data, state_write_access(state)) {
                    Ok(()) => SdoResponse::Download { index, subindex },
                    Err(code) => SdoResponse::Abort { index, subindex, code },
                }
            }
            SdoRequest::DownloadNormal { index, subindex, complete_size, data, .. } => {
                let size = complete_size as usize;
                self.download = None;
                if data.len() >= size {
                    match od.write(index, subindex, &data[..size], state_write_access(state)) {
                        Ok(()) => SdoResponse::Download { index, subindex },
                        Err(code) => SdoResponse::Abort { index, subindex, code },
                    }
                } else {
                    self.download = Some(Download { index, subindex, size, data: data.to_vec(), toggle: false });
                    SdoResponse::Download { index, subindex }
                }
            }
            SdoRequest::DownloadSegment { toggle, last, data } => match self.download.as_mut() {
                None => SdoResponse::Abort { index: 0, subindex: 0, code: SdoAbortCode::BAD_COMMAND },
                Some(d) if d.toggle != toggle => {
                    let (index, subindex) = (d.index, d.subindex);
                    self.download = None;
                    SdoResponse::Abort { index, subindex, code: SdoAbortCode::TOGGLE_BIT }
                }
                Some(d) => {
                    d.data.extend_from_slice(data);
                    d.toggle = !d.toggle;
                    if !last {
                        return write_sdo_response(out, counter, &SdoResponse::DownloadSegment { toggle });
                    }
                    let d = self.download.take().expect("matched above");
                    let result = if d.data.len() == d.size {
                        od.write(d.index, d.subindex, &d.data, state_write_access(state))
                    } else {
                        Err(SdoAbortCode::LENGTH_MISMATCH)
                    };
                    match result {
                        Ok(()) => SdoResponse::DownloadSegment { toggle },
                        Err(code) => SdoResponse::Abort { index: d.index, subindex: d.subindex, code },
                    }
                }
            },
            SdoRequest::Abort { .. } => {
                // The master gave up a transfer: forget it, nothing is answered.
                self.upload = None;
                self.download = None;
                return 0;
            }
        };
        write_sdo_response(out, counter, &response)
    }

    /// SDO information: OD lists, object and entry descriptions, split into fragments when a
    /// reply does not fit the mailbox.
    fn information(&mut self, body: &[u8], od: &ObjectDictionary, counter: u8, mailbox_size: usize) {
        if body.len() < SDO_INFO_HEADER_LEN {
            return self.error(counter, MailboxErrorDetail::SizeTooShort, mailbox_size);
        }
        // Long enough, so only an opcode outside the standard's set fails to decode.
        let Ok(header) = SdoInfoHeader::decode(body) else {
            return self.error(counter, MailboxErrorDetail::ServiceNotSupported, mailbox_size);
        };
        let request = &body[SDO_INFO_HEADER_LEN..];
        let word = |at: usize| request.get(at..at + 2).map(|b| u16::from_le_bytes([b[0], b[1]]));
        let mut data = Vec::new();
        let opcode = match header.opcode {
            SdoInfoOpcode::GetOdListRequest => {
                let Some(raw) = word(0) else {
                    return self.info_error(counter, SdoAbortCode::GENERAL, mailbox_size);
                };
                let Ok(list) = OdListType::try_from(raw) else {
                    return self.info_error(counter, SdoAbortCode::VALUE_RANGE, mailbox_size);
                };
                data.extend_from_slice(&raw.to_le_bytes());
                if list == OdListType::Lengths {
                    for &l in OdListType::ALL.iter().filter(|&&l| l != OdListType::Lengths) {
                        data.extend_from_slice(&(object_list(od, l).count() as u16).to_le_bytes());
                    }
                } else {
                    for index in object_list(od, list) {
                        data.extend_from_slice(&index.to_le_bytes());
                    }
                }
                SdoInfoOpcode::GetOdListResponse
            }
            SdoInfoOpcode::GetObjectDescriptionRequest => {
                let Some(index) = word(0) else {
                    return self.info_error(counter, SdoAbortCode::GENERAL, mailbox_size);
                };
                let Some(o) = od.object(index) else {
                    return self.info_error(counter, SdoAbortCode::NO_SUCH_OBJECT, mailbox_size);
                };
                let d = ObjectDescription {
                    index,
                    data_type: o.data_type,
                    max_subindex: o.max_subindex(),
                    object_code: o.object_code,
                    name: o.name,
                };
                data.resize(6 + o.name.len(), 0);
                d.encode(&mut data);
                SdoInfoOpcode::GetObjectDescriptionResponse
            }
            SdoInfoOpcode::GetEntryDescriptionRequest => {
                let (Some(index), Some(&subindex), Some(_value_info)) = (word(0), request.get(2), request.get(3))
                else {
                    return self.info_error(counter, SdoAbortCode::GENERAL, mailbox_size);
                };
                let Some(o) = od.object(index) else {
                    return self.info_error(counter, SdoAbortCode::NO_SUCH_OBJECT, mailbox_size);
                };
                let Some(e) = o.entry(subindex) else {
                    return self.info_error(counter, SdoAbortCode::NO_SUCH_SUBINDEX, mailbox_size);
                };
                // The AKD sends no unit, default, minimum or maximum, so no value information.
                let d = EntryDescription {
                    index,
                    subindex,
                    value_info: 0,
                    data_type: e.data_type,
                    bit_length: e.bits,
                    access: e.access,
                    name: e.name,
                };
                data.resize(10 + e.name.len(), 0);
                d.encode(&mut data);
                SdoInfoOpcode::GetEntryDescriptionResponse
            }
            _ => return self.error(counter, MailboxErrorDetail::ServiceNotSupported, mailbox_size),
        };
        let room = mailbox_size - HEADER_LEN - COE_HEADER_LEN - SDO_INFO_HEADER_LEN;
        let fragments = data.len().div_ceil(room).max(1);
        for (i, chunk) in data.chunks(room).chain(data.is_empty().then_some(&[][..])).enumerate() {
            let left = (fragments - 1 - i) as u16;
            let h = SdoInfoHeader { opcode, incomplete: left > 0, fragments_left: left };
            let mut out = vec![0u8; mailbox_size];
            let len = write_info_message(&mut out, counter, h, chunk);
            self.queue(out, len);
        }
    }

    fn info_error(&mut self, counter: u8, code: SdoAbortCode, mailbox_size: usize) {
        let mut out = vec![0u8; mailbox_size];
        let h = SdoInfoHeader { opcode: SdoInfoOpcode::SdoInfoErrorRequest, incomplete: false, fragments_left: 0 };
        let len = write_info_message(&mut out, counter, h, &code.0.to_le_bytes());
        self.queue(out, len);
    }
}

/// The indices of one OD list: all, Rx- or Tx-mappable; the AKD marks none for backup or
/// start-up.
fn object_list(od: &ObjectDictionary, list: OdListType) -> impl Iterator<Item = u16> + '_ {
    let wanted = match list {
        OdListType::All => 0,
        OdListType::RxPdoMappable => access::RX_PDO,
        OdListType::TxPdoMappable => access::TX_PDO,
        OdListType::Lengths | OdListType::Backup | OdListType::Startup => u16::MAX,
    };
    od.objects()
        .iter()
        .filter(move |o| wanted == 0 || (wanted != u16::MAX && o.entries.iter().any(|e| e.access & wanted != 0)))
        .map(|o| o.index)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::coe::{split_message, write_sdo_request};

    fn ask(server: &mut MailboxServer, od: &mut ObjectDictionary, request: &SdoRequest<'_>) -> Vec<u8> {
        let mut buf = [0u8; 64];
        // Each request a new one, as a master counts them.
        let len = write_sdo_request(&mut buf, next_counter(server.accepted_counter), request);
        server.handle(&buf[..len], od, AlState::PreOp, 128, 128, 0);
        server.next_reply().expect("a reply").to_vec()
    }

    #[test]
    fn answers_as_the_real_drive() {
        let (mut server, mut od) = (MailboxServer::default(), ObjectDictionary::akd());
        // From the capture: upload 0x1C12:01 with counter 1 -> 4B 12 1C 01 00 16 00 00.
        let request = [0x0A, 0, 0, 0, 0, 0x13, 0x00, 0x20, 0x40, 0x12, 0x1C, 0x01, 0, 0, 0, 0];
        server.handle(&request, &mut od, AlState::PreOp, 1024, 1024, 0);
        let reply = server.next_reply().unwrap();
        assert_eq!(reply, &[0x0A, 0, 0, 0, 0, 0x13, 0x00, 0x30, 0x4B, 0x12, 0x1C, 0x01, 0x00, 0x16, 0x00, 0x00]);
    }

    #[test]
    fn segmented_upload_and_download() {
        let (mut server, mut od) = (MailboxServer::default(), ObjectDictionary::akd());
        // 0x100A is 12 bytes; a 24-byte mailbox carries 8 in the initiate reply, then segments.
        let mut buf = [0u8; 32];
        let len =
            write_sdo_request(&mut buf, 1, &SdoRequest::Upload { index: 0x100A, subindex: 0, complete_access: false });
        server.handle(&buf[..len], &mut od, AlState::PreOp, 24, 24, 0);
        let reply = server.next_reply().unwrap().to_vec();
        let (_, _, body) = split_message(&reply).unwrap();
        let SdoResponse::UploadNormal { complete_size: 12, data, .. } = SdoResponse::decode(body).unwrap() else {
            panic!()
        };
        let mut value = data.to_vec();
        let mut toggle = false;
        loop {
            let counter = next_counter(server.accepted_counter);
            let len = write_sdo_request(&mut buf, counter, &SdoRequest::UploadSegment { toggle });
            server.handle(&buf[..len], &mut od, AlState::PreOp, 24, 24, 0);
            let reply = server.next_reply().unwrap().to_vec();
            let (_, _, body) = split_message(&reply).unwrap();
            let SdoResponse::UploadSegment { last, data, .. } = SdoResponse::decode(body).unwrap() else { panic!() };
            value.extend_from_slice(data);
            toggle = !toggle;
            if last {
                break;
            }
        }
        assert_eq!(value, b"01-20-00-003");
        // A 4-byte value downloaded in a normal transfer with one segment.
        let reply = ask(
            &mut server,
            &mut od,
            &SdoRequest::DownloadNormal {
                index: 0x607A,
                subindex: 0,
                complete_access: false,
                complete_size: 4,
                data: &[1],
            },
        );
        assert_eq!(SdoResponse::decode(&reply[8..]).unwrap(), SdoResponse::Download { index: 0x607A, subindex: 0 });
        let reply =
            ask(&mut server, &mut od, &SdoRequest::DownloadSegment { toggle: false, last: true, data: &[2, 3, 4] });
        assert_eq!(SdoResponse::decode(&reply[8..]).unwrap(), SdoResponse::DownloadSegment { toggle: false });
        assert_eq!(od.get(0x607A, 0).unwrap(), &[1, 2, 3, 4]);
    }

    #[test]
    fn aborts_by_the_rules() {
        let (mut server, mut od) = (MailboxServer::default(), ObjectDictionary::akd());
        let cases: [(SdoRequest<'_>, SdoAbortCode); 4] = [
            (SdoRequest::Upload { index: 0x1234, subindex: 0, complete_access: false }, SdoAbortCode::NO_SUCH_OBJECT),
            (
                SdoRequest::Upload { index: 0x1C12, subindex: 0, complete_access: true },
                SdoAbortCode::UNSUPPORTED_ACCESS,
            ),
            (
                SdoRequest::DownloadExpedited { index: 0x6041, subindex: 0, complete_access: false, data: &[0, 0] },
                SdoAbortCode::READ_ONLY,
            ),
            (SdoRequest::UploadSegment { toggle: false }, SdoAbortCode::BAD_COMMAND),
        ];
        for (request, code) in cases {
            let reply = ask(&mut server, &mut od, &request);
            let SdoResponse::Abort { code: got, .. } = SdoResponse::decode(&reply[8..]).unwrap() else { panic!() };
            assert_eq!(got, code, "{request:?}");
        }
    }

    #[test]
    fn other_protocols_get_a_mailbox_error() {
        let (mut server, mut od) = (MailboxServer::default(), ObjectDictionary::akd());
        // SoE (5): the AKD's SII lists CoE, EoE and FoE only.
        server.handle(&[0x04, 0, 0, 0, 0, 0x25, 1, 2, 3, 4], &mut od, AlState::PreOp, 64, 64, 0);
        let reply = server.next_reply().unwrap();
        assert_eq!(reply, &[0x04, 0, 0, 0, 0, 0x20, 0x01, 0x00, 0x02, 0x00]);
    }

    #[test]
    fn od_list_is_fragmented_to_fit_the_mailbox() {
        let (mut server, mut od) = (MailboxServer::default(), ObjectDictionary::akd());
        let request = [0x08, 0, 0, 0, 0, 0x13, 0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00];
        server.handle(&request, &mut od, AlState::PreOp, 32, 32, 0);
        let mut indices = Vec::new();
        while let Some(reply) = server.next_reply() {
            let (_, coe, body) = split_message(reply).unwrap();
            assert_eq!(coe.service, CoeService::SdoInformation);
            let h = SdoInfoHeader::decode(body).unwrap();
            indices.extend_from_slice(&body[SDO_INFO_HEADER_LEN..]);
            if !h.incomplete {
                break;
            }
        }
        let listed: Vec<u16> = indices[2..].chunks(2).map(|c| u16::from_le_bytes([c[0], c[1]])).collect();
        assert_eq!(listed, od.objects().iter().map(|o| o.index).collect::<Vec<_>>());
    }

    #[test]
    fn a_message_written_again_with_its_counter_is_served_once() {
        let (mut server, mut od) = (MailboxServer::default(), ObjectDictionary::akd());
        let mut buf = [0u8; 32];
        let write = SdoRequest::DownloadExpedited { index: 0x607A, subindex: 0, complete_access: false, data: &[5; 4] };
        let len = write_sdo_request(&mut buf, 4, &write);
        server.handle(&buf[..len], &mut od, AlState::PreOp, 128, 128, 0);
        // The master did not see its frame come back and writes the same message again.
        server.handle(&buf[..len], &mut od, AlState::PreOp, 128, 128, 0);
        assert!(server.next_reply().is_some());
        assert_eq!(server.next_reply(), None, "the repetition was answered");
        // The next counter is a new request; counter 0 (a master that does not count) always is.
        let len = write_sdo_request(&mut buf, 5, &write);
        server.handle(&buf[..len], &mut od, AlState::PreOp, 128, 128, 0);
        assert!(server.next_reply().is_some());
        let read = SdoRequest::Upload { index: 0x607A, subindex: 0, complete_access: false };
        let len = write_sdo_request(&mut buf, 0, &read);
        server.handle(&buf[..len], &mut od, AlState::PreOp, 128, 128, 0);
        server.handle(&buf[..len], &mut od, AlState::PreOp, 128, 128, 0);
        assert!(server.next_reply().is_some() && server.next_reply().is_some());
        assert_eq!(server.next_reply(), None);
    }
}
