//! FoE client: reads and writes a file on a slave by name, packet by packet, each answered
//! before the next goes; a busy slave gets the same packet again after a pause.

use std::time::{Duration, Instant};

use crate::error::{Error, FoeError, Result};
use crate::ethercat::foe::{self, FoeMessage};
use crate::ethercat::mailbox::{MailboxHeader, MailboxType};
use crate::ethercat::master::Master;

/// The longest file read into memory.
pub const MAX_FILE_LEN: usize = 64 << 20;
/// Pause before a packet the slave was busy for goes again.
const BUSY_PAUSE: Duration = Duration::from_millis(10);

/// What a transfer step awaits from the slave.
enum Awaited {
    /// The acknowledge of this packet (0: of the write request).
    Ack(u32),
    /// Data packet of this number.
    Data(u32),
}

impl Master {
    fn check_foe(&self, position: u16) -> Result<(usize, usize)> {
        match &self.slave(position)?.mailbox {
            Some(mb) if mb.protocols & MailboxType::Foe.sii_protocol_bit() != 0 => {
                Ok((mb.out_len as usize, mb.in_len as usize))
            }
            _ => Err(FoeError::NotSupported { slave: position }.into()),
        }
    }

    /// Sends `message` and waits for what `awaited` names; a busy slave gets it again. Returns
    /// the slave's reply message (the data packet, or the acknowledge).
    fn foe_step(&mut self, position: u16, name: &str, message: &FoeMessage<'_>, awaited: Awaited) -> Result<Vec<u8>> {
        let mut out = vec![0u8; message.len()];
        message.write(&mut out, 0);
        let deadline = Instant::now() + self.mailbox_timeout;
        'send: loop {
            self.mailbox_send(position, &mut out, self.mailbox_timeout)?;
            loop {
                let left = deadline.saturating_duration_since(Instant::now());
                let reply = self.mailbox_receive(position, left)?;
                let header = MailboxHeader::decode(&reply)?;
                if header.protocol() != Some(MailboxType::Foe) {
                    continue;
                }
                let unexpected = |got: &FoeMessage<'_>, expected| {
                    Error::from(FoeError::Unexpected {
                        slave: position,
                        name: name.into(),
                        expected,
                        got: got.opcode().name(),
                    })
                };
                match (FoeMessage::decode(header.body(&reply))?, &awaited) {
                    (FoeMessage::Error { code, text }, _) => {
                        return Err(FoeError::Refused {
                            slave: position,
                            name: name.into(),
                            code: code.0,
                            code_name: code.name(),
                            text: foe::text(text).into_owned(),
                        }
                        .into());
                    }
                    (FoeMessage::Busy { .. }, _) => {
                        if Instant::now() >= deadline {
                            return Err(Error::Timeout {
                                what: format!("slave {position} to stop being busy with {name:?}").into(),
                            });
                        }
                        std::thread::sleep(BUSY_PAUSE);
                        continue 'send;
                    }
                    (FoeMessage::Ack { packet }, Awaited::Ack(expected))
                    | (FoeMessage::Data { packet, .. }, Awaited::Data(expected)) => {
                        if packet != *expected {
                            return Err(
                                FoeError::PacketNumber { slave: position, expected: *expected, got: packet }.into()
                            );
                        }
                        return Ok(reply);
                    }
                    (got, Awaited::Ack(_)) => return Err(unexpected(&got, "an acknowledge")),
                    (got, Awaited::Data(_)) => return Err(unexpected(&got, "data")),
                }
            }
        }
    }

    /// Writes `data` as the file `name` to the slave at `position`; `progress(sent, total)`
    /// after each packet the slave acknowledged.
    pub(super) fn foe_write(
        &mut self,
        position: u16,
        name: &str,
        password: u32,
        data: &[u8],
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<()> {
        let (out_len, _) = self.check_foe(position)?;
        self.mailbox_flush(position)?;
        self.foe_step(position, name, &FoeMessage::WriteRequest { password, name }, Awaited::Ack(0))?;
        let mut sent = 0;
        for (packet, chunk) in foe::packets(data, foe::packet_room(out_len)) {
            self.foe_step(position, name, &FoeMessage::Data { packet, data: chunk }, Awaited::Ack(packet))?;
            sent += chunk.len();
            progress(sent, data.len());
        }
        Ok(())
    }

    /// Reads the file `name` from the slave at `position`; `progress(received)` after each
    /// packet.
    pub(super) fn foe_read(
        &mut self,
        position: u16,
        name: &str,
        password: u32,
        progress: &mut dyn FnMut(usize),
    ) -> Result<Vec<u8>> {
        let (_, in_len) = self.check_foe(position)?;
        let room = foe::packet_room(in_len);
        self.mailbox_flush(position)?;
        let mut file = Vec::new();
        let mut request = FoeMessage::ReadRequest { password, name };
        let mut packet = 1;
        loop {
            let reply = self.foe_step(position, name, &request, Awaited::Data(packet))?;
            let FoeMessage::Data { data, .. } = FoeMessage::decode(&reply[crate::ethercat::mailbox::HEADER_LEN..])?
            else {
                let got = "another message";
                return Err(FoeError::Unexpected { slave: position, name: name.into(), expected: "data", got }.into());
            };
            if file.len() + data.len() > MAX_FILE_LEN {
                return Err(FoeError::TooLong { name: name.into(), max: MAX_FILE_LEN }.into());
            }
            file.extend_from_slice(data);
            progress(file.len());
            let last = data.len() < room;
            request = FoeMessage::Ack { packet };
            if last {
                // The last acknowledge has no answer.
                let mut out = vec![0u8; request.len()];
                request.write(&mut out, 0);
                self.mailbox_send(position, &mut out, self.mailbox_timeout)?;
                return Ok(file);
            }
            packet += 1;
        }
    }
}
