//! The virtual AKD's file access over EtherCAT: files written by a master are kept in memory
//! (until the drive is power-cycled) and served back by name.
//!
//! What the real drive does with a file (a firmware image) is not in our sources, so the
//! virtual one only stores it. The mailbox runs in PreOp, SafeOp and Op, and so does FoE here;
//! the virtual AKD has no Bootstrap mailbox.

use std::collections::BTreeMap;

use crate::ethercat::foe::{packet_room, FoeErrorCode, FoeMessage};

/// A transfer in progress.
enum Transfer {
    /// The master writes `name`; `next` is the packet number due.
    Write { name: String, data: Vec<u8>, next: u32 },
    /// The master reads `name`; packet `packet` (ending at `end`) was sent last.
    Read { name: String, packet: u32, end: usize, last: bool },
}

/// The FoE side of one virtual AKD.
#[derive(Default)]
pub struct FoeServer {
    files: BTreeMap<String, Vec<u8>>,
    transfer: Option<Transfer>,
    /// Data packets of a write still to be answered with busy (a test's fault injection).
    busy_packets: u32,
}

impl FoeServer {
    /// A file written to the drive.
    pub fn file(&self, name: &str) -> Option<&[u8]> {
        self.files.get(name).map(Vec::as_slice)
    }

    /// Answers the next `packets` data packets of a write with busy instead of taking them, as
    /// a drive does that cannot take a packet yet; a master sends each again.
    pub fn inject_busy(&mut self, packets: u32) {
        self.busy_packets = packets;
    }

    /// Forgets a transfer in progress (the mailbox stopped); the files stay.
    pub fn stop(&mut self) {
        self.transfer = None;
    }

    /// Answers one FoE message body from the master into `out` (a mailbox message of at most
    /// `out.len()` bytes, which also sets the size of a full data packet it sends); `request_size`
    /// is the master's mailbox, whose full packets it writes. Returns the reply's length, 0 for
    /// none.
    pub fn handle(&mut self, body: &[u8], counter: u8, request_size: usize, out: &mut [u8]) -> usize {
        let error = |out: &mut [u8], code: FoeErrorCode| {
            FoeMessage::Error { code, text: code.name().as_bytes() }.write(out, counter)
        };
        let Ok(message) = FoeMessage::decode(body) else {
            self.transfer = None;
            return error(out, FoeErrorCode::ILLEGAL);
        };
        match message {
            FoeMessage::WriteRequest { name: "", .. } => error(out, FoeErrorCode::NOT_FOUND),
            FoeMessage::WriteRequest { name, .. } => {
                self.transfer = Some(Transfer::Write { name: name.to_owned(), data: Vec::new(), next: 1 });
                FoeMessage::Ack { packet: 0 }.write(out, counter)
            }
            FoeMessage::ReadRequest { name, .. } => {
                self.transfer = None;
                if !self.files.contains_key(name) {
                    return error(out, FoeErrorCode::NOT_FOUND);
                }
                self.transfer = Some(Transfer::Read { name: name.to_owned(), packet: 0, end: 0, last: false });
                self.send_next(counter, out)
            }
            FoeMessage::Data { packet, data } => {
                let Some(Transfer::Write { name, data: file, next }) = self.transfer.as_mut() else {
                    self.transfer = None;
                    return error(out, FoeErrorCode::ILLEGAL);
                };
                if packet != *next {
                    self.transfer = None;
                    return error(out, FoeErrorCode::PACKET_NUMBER_WRONG);
                }
                if self.busy_packets > 0 {
                    self.busy_packets -= 1;
                    let done = (file.len() / 1024).min(u16::MAX as usize) as u16;
                    return FoeMessage::Busy { done, entire: 0, text: b"" }.write(out, counter);
                }
                file.extend_from_slice(data);
                *next += 1;
                if data.len() < packet_room(request_size) {
                    let (name, file) = (std::mem::take(name), std::mem::take(file));
                    self.files.insert(name, file);
                    self.transfer = None;
                }
                FoeMessage::Ack { packet }.write(out, counter)
            }
            FoeMessage::Ack { packet: acked } => match self.transfer.as_ref() {
                Some(Transfer::Read { packet, last, .. }) if *packet == acked => {
                    if *last {
                        self.transfer = None;
                        return 0;
                    }
                    self.send_next(counter, out)
                }
                Some(Transfer::Read { .. }) => {
                    self.transfer = None;
                    error(out, FoeErrorCode::PACKET_NUMBER_WRONG)
                }
                _ => error(out, FoeErrorCode::ILLEGAL),
            },
            // The master ended the transfer, or asks the drive to wait, which it does not need.
            FoeMessage::Error { .. } => {
                self.transfer = None;
                0
            }
            FoeMessage::Busy { .. } => 0,
        }
    }

    /// The next data packet of the file being read.
    fn send_next(&mut self, counter: u8, out: &mut [u8]) -> usize {
        let room = packet_room(out.len());
        let Some(Transfer::Read { name, packet, end, last }) = self.transfer.as_mut() else { return 0 };
        let file = &self.files[name.as_str()];
        let from = *end;
        let to = (from + room).min(file.len());
        *packet += 1;
        *end = to;
        *last = to - from < room;
        FoeMessage::Data { packet: *packet, data: &file[from..to] }.write(out, counter)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ask(server: &mut FoeServer, message: FoeMessage<'_>, size: usize) -> Vec<u8> {
        let mut request = vec![0u8; message.len()];
        message.write(&mut request, 1);
        let mut out = vec![0u8; size];
        let len = server.handle(&request[6..], 1, size, &mut out);
        out.truncate(len);
        out
    }

    fn decode(reply: &[u8]) -> FoeMessage<'_> {
        FoeMessage::decode(&reply[6..]).unwrap()
    }

    #[test]
    fn a_file_written_reads_back() {
        let mut s = FoeServer::default();
        let file: Vec<u8> = (0..100u8).collect();
        // A 32-byte mailbox: 20 bytes a packet, so five full packets and an empty one.
        assert_eq!(
            decode(&ask(&mut s, FoeMessage::WriteRequest { password: 0, name: "a.bin" }, 32)),
            FoeMessage::Ack { packet: 0 }
        );
        for (n, chunk) in crate::ethercat::foe::packets(&file, 20) {
            let reply = ask(&mut s, FoeMessage::Data { packet: n, data: chunk }, 32);
            assert_eq!(decode(&reply), FoeMessage::Ack { packet: n });
        }
        assert_eq!(s.file("a.bin"), Some(&file[..]));
        let mut read = Vec::new();
        let mut reply = ask(&mut s, FoeMessage::ReadRequest { password: 0, name: "a.bin" }, 32);
        loop {
            let FoeMessage::Data { packet, data } = decode(&reply) else { panic!() };
            read.extend_from_slice(data);
            let short = data.len() < 20;
            reply = ask(&mut s, FoeMessage::Ack { packet }, 32);
            if short {
                assert!(reply.is_empty(), "nothing after the last acknowledge");
                break;
            }
        }
        assert_eq!(read, file);
    }

    #[test]
    fn refusals_name_the_standards_errors() {
        let mut s = FoeServer::default();
        let reply = ask(&mut s, FoeMessage::ReadRequest { password: 0, name: "missing" }, 64);
        assert_eq!(decode(&reply), FoeMessage::Error { code: FoeErrorCode::NOT_FOUND, text: b"not found" });
        let reply = ask(&mut s, FoeMessage::Data { packet: 1, data: &[1] }, 64);
        assert!(matches!(decode(&reply), FoeMessage::Error { code: FoeErrorCode::ILLEGAL, .. }));
        ask(&mut s, FoeMessage::WriteRequest { password: 0, name: "x" }, 64);
        let reply = ask(&mut s, FoeMessage::Data { packet: 2, data: &[1] }, 64);
        assert!(matches!(decode(&reply), FoeMessage::Error { code: FoeErrorCode::PACKET_NUMBER_WRONG, .. }));
        assert_eq!(s.file("x"), None, "a transfer that failed stores nothing");
    }
}
