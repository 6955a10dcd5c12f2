//! Mailbox client: messages to the slave through SM0, replies from it through SM1.
//!
//! A message is written as a whole buffer (the last byte makes SM0 full), with a counter
//! 1..7 that lets the slave tell a repeat from a new message. A reply is read when SM1 says
//! full; reading it empties SM1, so a reply lost on the way back is fetched again with the
//! repeat request of SM1 (activate bit 1, acknowledged in PDI control bit 1). A lost read may
//! also have found SM1 empty, or not have reached the slave: the repeat then brings back the
//! message read before it, which is dropped (and counted) rather than taken twice. Emergency
//! messages that arrive in between are queued on the slave, a reply with another counter than
//! the request's is a stale one and dropped (and counted), and a mailbox error reply becomes an
//! error naming its detail code. EoE fragments go to the slave's [`EoePort`](super::eoe::EoePort)
//! whoever reads them; EoE responses and FoE messages go to the caller.

use std::time::{Duration, Instant};

use crate::error::{Error, MailboxError, Result, SiiError};
use crate::ethercat::coe::{self, CoeService, Emergency};
use crate::ethercat::frame::Command;
use crate::ethercat::mailbox::{self as codec, MailboxHeader, MailboxType};
use crate::ethercat::master::Master;
use crate::ethercat::registers::{self, sm_reg};
use crate::ethercat::sii::Sii;

/// Pause between polls of a sync manager's status.
const POLL_INTERVAL: Duration = Duration::from_micros(100);
/// SM1's activate register, whose bit 1 asks the slave for its last reply again.
const SM1_ACTIVATE: u16 = registers::sm(1) + sm_reg::ACTIVATE as u16;
/// Smallest mailbox that holds an SDO message: mailbox header, CoE header, SDO command.
const MIN_MAILBOX_LEN: u16 = (coe::SDO_OFFSET + coe::SDO_LEN) as u16;
/// Control byte of SM0 when the SII gives none: mailbox, master writes, PDI interrupt (AKD).
const SM0_CONTROL: u8 = 0x26;
/// Control byte of SM1 when the SII gives none: mailbox, master reads, PDI interrupt (AKD).
const SM1_CONTROL: u8 = 0x22;

/// A slave's mailbox: where its two sync managers sit and the counter of the last message.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mailbox {
    /// SM0 (master to slave) start address.
    pub out_start: u16,
    /// SM0 length.
    pub out_len: u16,
    /// SM0 control byte.
    pub out_control: u8,
    /// SM1 (slave to master) start address.
    pub in_start: u16,
    /// SM1 length.
    pub in_len: u16,
    /// SM1 control byte.
    pub in_control: u8,
    /// Mailbox protocols the slave supports (SII word 0x1C).
    pub protocols: u16,
    counter: u8,
    repeat: Repeat,
    last_read: LastRead,
}

/// The last message read from SM1, for the master to know it again when a repeat request brings
/// it back: the repeat asks for the message the slave saw read last, which is the one whose read
/// was lost only if that read did reach SM1 while it was full. Two messages in a row that carry a
/// counter are never the same bytes (the counter moves on, or a reply echoes another request's),
/// so the same bytes again right after a repeat request are that copy.
#[derive(Clone, Debug, PartialEq, Eq)]
struct LastRead {
    /// Room for SM1's whole buffer, allocated with the mailbox: a cycle thread reads without
    /// allocating.
    message: Box<[u8]>,
    len: usize,
    /// A repeat request was made since: the next message read may be this one again.
    repeated: bool,
}

impl LastRead {
    fn new(in_len: u16) -> Self {
        LastRead { message: vec![0; usize::from(in_len)].into_boxed_slice(), len: 0, repeated: false }
    }

    /// Takes the message just read into `buffer` (SM1's whole buffer); `false` when it is the copy
    /// of the last one that a repeat request brought back. A counter of 0 (the slave does not
    /// count) tells nothing: such a message is always taken.
    fn take(&mut self, buffer: &[u8]) -> bool {
        let announced = buffer.get(..2).map_or(0, |b| usize::from(u16::from_le_bytes([b[0], b[1]])));
        let len = (codec::HEADER_LEN + announced).min(buffer.len()).min(self.message.len());
        let counted = buffer.get(5).is_some_and(|b| b & 0x70 != 0);
        let copy = std::mem::take(&mut self.repeated) && counted && buffer[..len] == self.message[..self.len];
        if !copy {
            self.message[..len].copy_from_slice(&buffer[..len]);
            self.len = len;
        }
        !copy
    }
}

/// Where the repeat request a lost read of SM1 calls for stands, made one frame at a time by a
/// cycle thread ([`Master::mailbox_try_repeat`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Repeat {
    #[default]
    None,
    /// SM1's activate byte is to be read, to know the toggled value.
    ReadActivate,
    /// This activate byte (repeat bit toggled) is to be written; writing it again is harmless.
    Write(u8),
}

impl Mailbox {
    /// The standard mailbox of a slave from its SII, `None` when it has no mailbox; an error
    /// when the mailbox is too small for any CoE message.
    pub fn from_sii(sii: &Sii) -> Result<Option<Self>, SiiError> {
        // "Receive" and "send" are the slave's view: it receives through SM0.
        let mb = &sii.header.standard_mailbox;
        let protocols = sii.header.mailbox_protocols;
        if protocols == 0 || mb.receive_size == 0 || mb.send_size == 0 {
            return Ok(None);
        }
        if mb.receive_size.min(mb.send_size) < MIN_MAILBOX_LEN {
            return Err(SiiError::MailboxTooSmall {
                receive: mb.receive_size,
                send: mb.send_size,
                min: MIN_MAILBOX_LEN,
            });
        }
        // The SM category, when present, holds the control bytes the slave expects.
        let control = |n: usize, default: u8| sii.sync_managers().get(n).map_or(default, |sm| sm.control);
        Ok(Some(Mailbox {
            out_start: mb.receive_offset,
            out_len: mb.receive_size,
            out_control: control(0, SM0_CONTROL),
            in_start: mb.send_offset,
            in_len: mb.send_size,
            in_control: control(1, SM1_CONTROL),
            protocols,
            counter: 0,
            repeat: Repeat::None,
            last_read: LastRead::new(mb.send_size),
        }))
    }

    /// Whether the slave speaks CoE.
    pub fn has_coe(&self) -> bool {
        self.protocols & MailboxType::Coe.sii_protocol_bit() != 0
    }
}

/// The eight bytes of a sync manager's registers.
pub(crate) fn sm_registers(start: u16, len: u16, control: u8, enable: bool) -> [u8; 8] {
    let mut r = [0u8; 8];
    r[sm_reg::START..sm_reg::START + 2].copy_from_slice(&start.to_le_bytes());
    r[sm_reg::LENGTH..sm_reg::LENGTH + 2].copy_from_slice(&len.to_le_bytes());
    r[sm_reg::CONTROL] = control;
    r[sm_reg::ACTIVATE] = enable as u8;
    r
}

fn no_mailbox(position: u16) -> Error {
    MailboxError::NoMailbox { slave: position }.into()
}

impl Master {
    fn mailbox(&self, position: u16) -> Result<Mailbox> {
        self.slave(position)?.mailbox.clone().ok_or_else(|| no_mailbox(position))
    }

    /// Writes SM0 and SM1 of the slave at `position` from its SII, as Init → PreOp needs.
    pub(crate) fn setup_mailbox(&mut self, position: u16) -> Result<()> {
        let Some(mb) = self.slave(position)?.mailbox.clone() else { return Ok(()) };
        let station = self.station(position)?;
        let mut both = [0u8; 16];
        both[..8].copy_from_slice(&sm_registers(mb.out_start, mb.out_len, mb.out_control, true));
        both[8..].copy_from_slice(&sm_registers(mb.in_start, mb.in_len, mb.in_control, true));
        self.write_registers(station, registers::sm(0), &both)
    }

    /// Sends one mailbox message (header included) to the slave at `position`, waiting up to
    /// `timeout` for SM0 to be free. Gives the message the next counter value.
    pub(super) fn mailbox_send(&mut self, position: u16, message: &mut [u8], timeout: Duration) -> Result<()> {
        let mb = self.mailbox(position)?;
        if message.len() > mb.out_len as usize {
            return Err(MailboxError::TooLong { slave: position, len: message.len(), room: mb.out_len }.into());
        }
        let counter = self.mailbox_take_counter(position)?;
        message[5] = (message[5] & 0x0F) | (counter << 4);
        let mut buffer = vec![0u8; mb.out_len as usize];
        buffer[..message.len()].copy_from_slice(message);
        let deadline = Instant::now() + timeout;
        loop {
            if self.mailbox_try_send(position, &mut buffer)? {
                return Ok(());
            }
            if Instant::now() >= deadline {
                return Err(Error::Timeout {
                    what: format!("slave {position}'s mailbox (SM0) to accept a message").into(),
                });
            }
            std::thread::sleep(POLL_INTERVAL);
        }
    }

    /// Waits up to `timeout` for the next mailbox message from the slave at `position` that is
    /// not an emergency; emergencies are queued on the slave. Returns the whole message.
    pub(super) fn mailbox_receive(&mut self, position: u16, timeout: Duration) -> Result<Vec<u8>> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(message) = self.mailbox_poll(position)? {
                return Ok(message);
            }
            if Instant::now() >= deadline {
                return Err(Error::Timeout { what: format!("a mailbox reply from slave {position}").into() });
            }
            std::thread::sleep(POLL_INTERVAL);
        }
    }

    /// The counter of the last message sent to the slave at `position` (0 before any), so
    /// that a restoring master ([`Master::for_restore`]) talking to the same slave goes on from it.
    pub fn mailbox_counter(&self, position: u16) -> Option<u8> {
        Some(self.slave(position).ok()?.mailbox.as_ref()?.counter)
    }

    /// Goes on from `counter` (see [`mailbox_counter`](Self::mailbox_counter)).
    pub fn set_mailbox_counter(&mut self, position: u16, counter: u8) {
        if let Some(mailbox) = self.slave_entry_mut(position).ok().and_then(|s| s.mailbox.as_mut()) {
            mailbox.counter = counter;
        }
    }

    /// Takes the counter for the next message to the slave at `position` (1..=7), as
    /// [`mailbox_send`](Self::mailbox_send) does, for a caller that writes SM0 itself.
    pub(super) fn mailbox_take_counter(&mut self, position: u16) -> Result<u8> {
        let mailbox = self.mailbox_entry_mut(position)?;
        mailbox.counter = codec::next_counter(mailbox.counter);
        Ok(mailbox.counter)
    }

    /// One attempt to write `buffer` (exactly SM0's length, counter in place) into the slave's
    /// SM0, for a cycle thread that must not wait: `true` when the slave took it, `false` when
    /// SM0 still held an earlier message or the frame was lost (try again with the same bytes).
    pub(super) fn mailbox_try_send(&mut self, position: u16, buffer: &mut [u8]) -> Result<bool> {
        let (station, out_start) = self.mailbox_address(position, |mb| mb.out_start)?;
        // Writing the whole buffer fills SM0; WKC 0 means it is still full with an earlier
        // message. A frame lost on the way is written again with the same counter, which the
        // slave takes as a repeat if the first one did arrive.
        match self.datagram(Command::Fpwr, station, out_start, buffer) {
            Ok(wkc) => Ok(wkc == 1),
            Err(Error::Timeout { .. }) => Ok(false),
            Err(e) => Err(e),
        }
    }

    /// One read of the slave's SM1 into `buffer` (exactly SM1's length), for a cycle thread
    /// that saw SM1 full and must not wait: `true` when a message was read, not the copy of the
    /// last one that a repeat request brought back (dropped, and counted stale). A read whose
    /// return does not come may have emptied SM1 all the same (it came late): the reply is
    /// then asked for again with SM1's repeat request, made by
    /// [`mailbox_try_repeat`](Self::mailbox_try_repeat) in the calls after; SM1 shows full
    /// again once the slave has put it back.
    pub(super) fn mailbox_try_read(&mut self, position: u16, buffer: &mut [u8]) -> Result<bool> {
        let (station, in_start) = self.mailbox_address(position, |mb| mb.in_start)?;
        match self.datagram(Command::Fprd, station, in_start, buffer) {
            Ok(1) => self.take_read(position, buffer),
            Ok(_) => Ok(false),
            Err(Error::Timeout { .. }) => {
                self.mailbox_entry_mut(position)?.repeat = Repeat::ReadActivate;
                Ok(false)
            }
            Err(e) => Err(e),
        }
    }

    /// Keeps the message just read from the slave's SM1 as its last; `false` (and counted stale)
    /// when it is the copy of the last one that a repeat request brought back.
    fn take_read(&mut self, position: u16, buffer: &[u8]) -> Result<bool> {
        let new = self.mailbox_entry_mut(position)?.last_read.take(buffer);
        self.stats.stale_mailbox_replies += u64::from(!new);
        Ok(new)
    }

    /// One frame towards the repeat request a lost read of SM1 left to make, for a cycle
    /// thread that must not wait: `true` when a frame was spent on it (call again in the next
    /// cycle), `false` when none is left to make. Frames lost meanwhile (the line, or a
    /// simulator, stalled) only put it off: given up, the reply would never come back.
    pub(super) fn mailbox_try_repeat(&mut self, position: u16) -> Result<bool> {
        let station = self.station(position)?;
        let mut activate = [0u8; 1];
        let next = match self.mailbox_entry_mut(position)?.repeat {
            Repeat::None => return Ok(false),
            Repeat::ReadActivate => match self.datagram(Command::Fprd, station, SM1_ACTIVATE, &mut activate) {
                Ok(1) => Repeat::Write(activate[0] ^ sm_reg::ACTIVATE_REPEAT),
                Ok(_) | Err(Error::Timeout { .. }) => Repeat::ReadActivate,
                Err(e) => return Err(e),
            },
            Repeat::Write(byte) => match self.datagram(Command::Fpwr, station, SM1_ACTIVATE, &mut [byte]) {
                Ok(1) => {
                    self.stats.mailbox_repeats += 1;
                    self.mailbox_entry_mut(position)?.last_read.repeated = true;
                    Repeat::None
                }
                Ok(_) | Err(Error::Timeout { .. }) => Repeat::Write(byte),
                Err(e) => return Err(e),
            },
        };
        self.mailbox_entry_mut(position)?.repeat = next;
        Ok(true)
    }

    fn mailbox_entry_mut(&mut self, position: u16) -> Result<&mut Mailbox> {
        self.slave_entry_mut(position)?.mailbox.as_mut().ok_or_else(|| no_mailbox(position))
    }

    /// Toggles SM1's repeat request (activate bit 1) and counts it; gives the activate byte
    /// written, whose bit 1 the slave's acknowledge (PDI control bit 1) will match.
    fn toggle_repeat_request(&mut self, station: u16) -> Result<u8> {
        self.stats.mailbox_repeats += 1;
        let mut activate = [0u8; 1];
        self.read_registers(station, SM1_ACTIVATE, &mut activate)?;
        let request = activate[0] ^ sm_reg::ACTIVATE_REPEAT;
        self.write_registers(station, SM1_ACTIVATE, &[request])?;
        Ok(request)
    }

    /// The station address and one address of the slave's mailbox, without copying it.
    fn mailbox_address(&self, position: u16, which: impl Fn(&Mailbox) -> u16) -> Result<(u16, u16)> {
        let slave = self.slave(position)?;
        let mailbox = slave.mailbox.as_ref().ok_or_else(|| no_mailbox(position))?;
        Ok((slave.station_address, which(mailbox)))
    }

    /// Drops whatever waits in the slave's SM1 (a reply to an abandoned request), keeping
    /// emergencies.
    pub(crate) fn mailbox_flush(&mut self, position: u16) -> Result<()> {
        while self.mailbox_poll(position)?.is_some() {}
        Ok(())
    }

    /// Reads SM1 once if it is full; `None` when it was empty or held only an emergency.
    fn mailbox_poll(&mut self, position: u16) -> Result<Option<Vec<u8>>> {
        let mb = self.mailbox(position)?;
        let station = self.station(position)?;
        let mut status = [0u8; 1];
        self.read_registers(station, registers::sm(1) + sm_reg::STATUS as u16, &mut status)?;
        if status[0] & sm_reg::STATUS_MAILBOX_FULL == 0 {
            return Ok(None);
        }
        let mut buffer = vec![0u8; mb.in_len as usize];
        match self.datagram(Command::Fprd, station, mb.in_start, &mut buffer) {
            Ok(1) if self.take_read(position, &buffer)? => {}
            Ok(_) => return Ok(None),
            Err(Error::Timeout { .. }) => {
                self.repeat_request(position, station)?;
                return Ok(None);
            }
            Err(e) => return Err(e),
        }
        let header = MailboxHeader::decode(&buffer)?;
        match header.protocol() {
            Some(MailboxType::Error) => {
                let detail = codec::parse_error_reply(header.body(&buffer))?;
                Err(MailboxError::ErrorReply { slave: position, detail, detail_name: codec::error_detail_name(detail) }
                    .into())
            }
            Some(MailboxType::Coe) => {
                let (_, coe_header, body) = coe::split_message(&buffer)?;
                if coe_header.service == CoeService::Emergency {
                    let emergency = Emergency::decode(body)?;
                    self.stats.emergencies += 1;
                    self.slave_entry_mut(position)?.emergencies.push_back(emergency);
                    return Ok(None);
                }
                // The AKD answers with the counter of the request. Another counter is the late
                // answer to an earlier request this master gave up waiting for.
                if header.counter != 0 && header.counter != mb.counter {
                    self.stats.stale_mailbox_replies += 1;
                    return Ok(None);
                }
                buffer.truncate(codec::HEADER_LEN + header.length as usize);
                Ok(Some(buffer))
            }
            Some(MailboxType::Eoe) => {
                buffer.truncate(codec::HEADER_LEN + header.length as usize);
                // Fragments go to the slave's EoE port, whoever reads them; responses on.
                if self.slave_entry_mut(position)?.eoe.take(header.body(&buffer)) {
                    return Ok(None);
                }
                Ok(Some(buffer))
            }
            Some(MailboxType::Foe) => {
                buffer.truncate(codec::HEADER_LEN + header.length as usize);
                Ok(Some(buffer))
            }
            _ => Err(MailboxError::UnsupportedType { slave: position, mailbox_type: header.mailbox_type }.into()),
        }
    }

    /// Asks the slave to put its last reply into SM1 again after the frame reading it was lost:
    /// toggle SM1's repeat request and wait for the slave's acknowledge.
    fn repeat_request(&mut self, position: u16, station: u16) -> Result<()> {
        let request = self.toggle_repeat_request(station)?;
        self.mailbox_entry_mut(position)?.last_read.repeated = true;
        let deadline = Instant::now() + self.timeout.max(Duration::from_millis(100));
        loop {
            let mut pdi = [0u8; 1];
            self.read_registers(station, registers::sm(1) + sm_reg::PDI_CONTROL as u16, &mut pdi)?;
            if pdi[0] & sm_reg::PDI_REPEAT_ACK == request & sm_reg::ACTIVATE_REPEAT {
                return Ok(());
            }
            if Instant::now() >= deadline {
                return Err(Error::Timeout {
                    what: format!("slave {position} to acknowledge the mailbox repeat request").into(),
                });
            }
            std::thread::sleep(POLL_INTERVAL);
        }
    }
}
