//! Mailbox traffic beside the cycle: SDO reads and writes asked by other threads, the error
//! code 0x603F read after a drive fault, and emergency messages — at most one mailbox frame per
//! cycle, sent after the cyclic exchange, so process data always goes first and a drive that
//! is slow to answer an SDO never delays a cycle. The cyclic frame's supervision reads tell
//! which slave has a message waiting in SM1.
//!
//! Ethernet frames for the drives' IP stacks ([`EoeFrames`]) go in EoE fragments in the cycles
//! no SDO transfer needs, one fragment a cycle; the drives' fragments are put back together
//! as they are read, by a reassembler per drive allocated before the cycle.
//!
//! A transfer travels in one mailbox message each way: expedited, or normal when the value
//! fits the mailbox (the AKD's objects do); a value that would need segments is refused with
//! an error saying so. Other threads hand a transfer over through [`SdoSlot`], a handshake on
//! one atomic, and wait for it without any lock the cycle thread takes.

use std::sync::atomic::{AtomicU16, AtomicU32, AtomicU8, Ordering};
use std::sync::Mutex;
use std::time::Duration;

use crate::cycle::eoe_frames::EoeFrames;
use crate::cycle::events::{Action, Event, Events, FaultSource};
use crate::error::{Error, MailboxError, Result, SettingError, Unavailable};
use crate::ethercat::coe::{self, CoeService, Emergency, SdoRequest, SdoResponse, SDO_LEN, SDO_OFFSET};
use crate::ethercat::eoe::{self, EoeMessage, Fragmenter, Reassembler, MAX_FRAME_LEN};
use crate::ethercat::mailbox::{MailboxHeader, MailboxType};
use crate::ethercat::master::cyclic::SlaveWatch;
use crate::ethercat::master::mailbox_client::Mailbox;
use crate::ethercat::master::Master;

/// Largest value a transfer beside the cycle carries.
pub const MAX_DATA: usize = 1024;
/// How long a transfer beside the cycle may take.
pub const TRANSFER_TIMEOUT: Duration = Duration::from_secs(1);

const FREE: u8 = 0;
const ASKED: u8 = 1;
const TAKEN: u8 = 2;
const DONE: u8 = 3;

/// How a transfer ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
enum Outcome {
    Done = 0,
    Aborted = 1,
    TimedOut = 2,
    TooLarge = 3,
    Unexpected = 4,
    MailboxError = 5,
    NoMailbox = 6,
    /// The slave was lost while its transfer was under way; its mailbox is the recovery's.
    Lost = 7,
}

/// The hand-over of one SDO transfer between another thread and the cycle thread.
pub struct SdoSlot {
    state: AtomicU8,
    slave: AtomicU16,
    index: AtomicU16,
    subindex: AtomicU8,
    /// Bytes to write; 0 for a read. After the transfer: bytes read.
    len: AtomicU16,
    data: Box<[AtomicU8]>,
    outcome: AtomicU8,
    /// The abort code, or the mailbox error's detail code.
    code: AtomicU32,
    /// Callers take turns; the cycle thread never takes this.
    callers: Mutex<()>,
}

impl Default for SdoSlot {
    fn default() -> Self {
        SdoSlot {
            state: AtomicU8::new(FREE),
            slave: AtomicU16::new(0),
            index: AtomicU16::new(0),
            subindex: AtomicU8::new(0),
            len: AtomicU16::new(0),
            data: (0..MAX_DATA).map(|_| AtomicU8::new(0)).collect(),
            outcome: AtomicU8::new(0),
            code: AtomicU32::new(0),
            callers: Mutex::new(()),
        }
    }
}

impl SdoSlot {
    /// Runs one transfer through the cycle thread and waits for it (polling every 100 µs,
    /// for at most the transfer time-out and a margin); `write` is `None` for a read. Returns
    /// the value read (empty for a write). `running` says whether the thread still cycles.
    pub fn transfer(
        &self,
        slave: u16,
        index: u16,
        subindex: u8,
        write: Option<&[u8]>,
        running: impl Fn() -> bool,
    ) -> Result<Vec<u8>> {
        let what = || format!("0x{index:04X}:{subindex:02X} of slave {slave}");
        if let Some(data) = write {
            if data.is_empty() || data.len() > MAX_DATA {
                return Err(
                    SettingError::SdoWriteLength { slave, index, subindex, len: data.len(), max: MAX_DATA }.into()
                );
            }
        }
        let _turn = self.callers.lock().unwrap_or_else(|p| p.into_inner());
        self.slave.store(slave, Ordering::Relaxed);
        self.index.store(index, Ordering::Relaxed);
        self.subindex.store(subindex, Ordering::Relaxed);
        let data = write.unwrap_or(&[]);
        for (cell, b) in self.data.iter().zip(data) {
            cell.store(*b, Ordering::Relaxed);
        }
        self.len.store(data.len() as u16, Ordering::Relaxed);
        self.state.store(ASKED, Ordering::Release);
        let deadline = std::time::Instant::now() + TRANSFER_TIMEOUT + Duration::from_millis(500);
        while self.state.load(Ordering::Acquire) != DONE {
            if !running() || std::time::Instant::now() > deadline {
                // Taken back only if the thread has not started it; else it finishes on its own.
                let _ = self.state.compare_exchange(ASKED, FREE, Ordering::AcqRel, Ordering::Acquire);
                return Err(Error::Timeout { what: format!("the cycle thread to transfer {}", what()).into() });
            }
            std::thread::sleep(Duration::from_micros(100));
        }
        let len = self.len.load(Ordering::Relaxed) as usize;
        let value: Vec<u8> = self.data[..len].iter().map(|c| c.load(Ordering::Relaxed)).collect();
        let code = self.code.load(Ordering::Relaxed);
        let outcome = self.outcome.load(Ordering::Relaxed);
        self.state.store(FREE, Ordering::Release);
        let verb = if write.is_some() { "write" } else { "read" };
        match outcome {
            o if o == Outcome::Done as u8 => Ok(value),
            o if o == Outcome::Aborted as u8 => Err(Error::sdo_abort(index, subindex, coe::SdoAbortCode(code))),
            o if o == Outcome::TimedOut as u8 => Err(Error::Timeout {
                what: format!("slave {slave} to answer the SDO {verb} of 0x{index:04X}:{subindex:02X}").into(),
            }),
            o if o == Outcome::TooLarge as u8 => {
                Err(MailboxError::NeedsSegments { verb, slave, index, subindex }.into())
            }
            o if o == Outcome::MailboxError as u8 => Err(MailboxError::TransferErrorReply {
                verb,
                slave,
                index,
                subindex,
                detail: code as u16,
                detail_name: crate::ethercat::mailbox::error_detail_name(code as u16),
            }
            .into()),
            o if o == Outcome::NoMailbox as u8 => {
                Err(MailboxError::NoCoeForTransfer { verb, slave, index, subindex }.into())
            }
            o if o == Outcome::Lost as u8 => Err(Unavailable::Recovering { slave }.into()),
            _ => Err(MailboxError::TransferUnexpected { verb, slave, index, subindex }.into()),
        }
    }
}

/// Where a transfer came from.
#[derive(Clone, Copy, Debug)]
enum Origin {
    Caller,
    /// A drive fault's event, reported once its code is in.
    ErrorCode(Event),
}

#[derive(Clone, Copy, Debug)]
enum Phase {
    Idle,
    /// The request is built in the send buffer; SM0 has not taken it yet.
    Sending {
        slave: u16,
        origin: Origin,
        deadline_ns: u64,
    },
    /// SM0 took it; the answer is awaited in SM1.
    Awaiting {
        slave: u16,
        counter: u8,
        origin: Origin,
        deadline_ns: u64,
    },
}

/// The cycle thread's side: buffers and the transfer under way.
pub struct MailboxService {
    send: Vec<u8>,
    receive: Vec<u8>,
    phase: Phase,
    /// Drive fault events waiting for their code from 0x603F, one per slave.
    pending: Vec<Option<Event>>,
    /// Where the search for a full SM1 starts next, so every slave gets its turn.
    next_slave: usize,
    /// The slave whose read of SM1 failed: its repeat request may be left to make.
    repeat: Option<u16>,
    index: u16,
    subindex: u8,
    eoe: EoeService,
}

/// The EoE part: the frame being sent and the fragment of it built, a reassembler and the
/// next frame number per drive.
struct EoeService {
    frame: Vec<u8>,
    /// The frame in `frame`: its slave, length, fragment to send next.
    sending: Option<(u16, usize, usize)>,
    /// The fragment built in `message` and not yet taken by SM0: its length.
    built: Option<usize>,
    message: Vec<u8>,
    reassemblers: Vec<Reassembler>,
    frame_numbers: Vec<u8>,
}

impl MailboxService {
    /// Buffers for the largest mailbox of `master`'s slaves, allocated before the cycle.
    pub fn new(master: &Master) -> Self {
        let largest = |f: fn(&Mailbox) -> u16| {
            master.slaves().iter().filter_map(|s| s.mailbox.as_ref().map(f)).max().unwrap_or(0) as usize
        };
        MailboxService {
            send: vec![0; largest(|m| m.out_len)],
            receive: vec![0; largest(|m| m.in_len)],
            phase: Phase::Idle,
            pending: vec![None; master.slaves().len()],
            next_slave: 0,
            repeat: None,
            index: 0,
            subindex: 0,
            eoe: EoeService {
                frame: vec![0; MAX_FRAME_LEN],
                sending: None,
                built: None,
                message: vec![0; largest(|m| m.out_len)],
                reassemblers: vec![Reassembler::default(); master.slaves().len()],
                frame_numbers: vec![0; master.slaves().len()],
            },
        }
    }

    /// Queues the read of 0x603F for a drive fault's `event`; the event goes out when the code
    /// is in (or at once, code 0, for a slave without CoE).
    pub fn read_error_code(&mut self, master: &Master, slave: u16, event: Event, events: &Events) {
        let has_coe = mailbox_of(master, slave).is_some_and(|m| m.has_coe());
        match self.pending.get_mut(slave as usize) {
            Some(slot) if has_coe => *slot = Some(event),
            _ => events.push(event),
        }
    }

    /// One cycle's mailbox work, after the exchange: reads one waiting message, else starts
    /// or continues one transfer, else sends one EoE fragment. `statusword(slave)` gives a
    /// drive's statusword for events; the mailbox of a slave `recovering` is the recovery's,
    /// and left alone.
    pub fn run(
        &mut self,
        master: &mut Master,
        (slot, frames): (&SdoSlot, &EoeFrames),
        events: &Events,
        context: (u64, u64),
        recovering: impl Fn(u16) -> bool,
        statusword: impl Fn(u16) -> u16,
    ) {
        let now_ns = context.1;
        if self.read_one(master, slot, frames, events, context, (&recovering, &statusword)) {
            return;
        }
        if let Phase::Sending { slave, deadline_ns, origin } | Phase::Awaiting { slave, deadline_ns, origin, .. } =
            self.phase
        {
            if recovering(slave) {
                // No answer is coming before the slave is back, if ever: the caller hears so now.
                self.finish(slot, events, origin, Outcome::Lost, 0, &[]);
            } else if now_ns > deadline_ns {
                self.finish(slot, events, origin, Outcome::TimedOut, 0, &[]);
            }
        }
        if let Phase::Idle = self.phase {
            self.start(master, (slot, events), &recovering, now_ns + TRANSFER_TIMEOUT.as_nanos() as u64);
        }
        if let Phase::Sending { slave, origin, deadline_ns } = self.phase {
            let len = mailbox_of(master, slave).map_or(0, |m| m.out_len as usize);
            match master.slave_mut(slave).and_then(|mut s| s.mailbox_try_send(&mut self.send[..len])) {
                Ok(true) => {
                    let counter = self.send[5] >> 4;
                    self.phase = Phase::Awaiting { slave, counter, origin, deadline_ns };
                }
                Ok(false) => {}
                Err(_) => self.finish(slot, events, origin, Outcome::Unexpected, 0, &[]),
            }
            return;
        }
        self.send_fragment(master, frames, &recovering);
    }

    /// Builds the next EoE fragment of the frame under way (taking the next frame when none
    /// is) and offers it to the drive's SM0 once.
    fn send_fragment(&mut self, master: &mut Master, frames: &EoeFrames, recovering: &impl Fn(u16) -> bool) {
        let e = &mut self.eoe;
        if e.sending.is_none() {
            let Some((slave, len)) = frames.next_to_drive(&mut e.frame) else { return };
            if mailbox_of(master, slave).is_none_or(|m| m.protocols & MailboxType::Eoe.sii_protocol_bit() == 0) {
                return;
            }
            let number = &mut e.frame_numbers[slave as usize];
            *number = (*number + 1) & 0x0F;
            e.sending = Some((slave, len, 0));
        }
        let Some((slave, len, fragment)) = e.sending else { return };
        if recovering(slave) {
            return;
        }
        let out_len = mailbox_of(master, slave).map_or(0, |m| m.out_len as usize);
        if e.built.is_none() {
            let number = e.frame_numbers[slave as usize];
            let next = Fragmenter::new(&e.frame[..len], number, out_len).ok().and_then(|mut f| f.nth(fragment));
            let (Some((header, data)), Ok(counter)) =
                (next, master.slave_mut(slave).and_then(|mut s| s.mailbox_take_counter()))
            else {
                e.sending = None;
                return;
            };
            e.message[..out_len].fill(0);
            eoe::write_fragment(&mut e.message[..out_len], counter, &header, data);
            e.built = Some(usize::from(header.last_fragment));
        }
        match master.slave_mut(slave).and_then(|mut s| s.mailbox_try_send(&mut e.message[..out_len])) {
            Ok(true) => {
                let last = e.built.take() == Some(1);
                e.sending = if last { None } else { Some((slave, len, fragment + 1)) };
            }
            Ok(false) => {}
            Err(_) => (e.sending, e.built) = (None, None),
        }
    }

    /// Builds the next request: a fault's 0x603F first, then a caller's transfer. One for a
    /// slave `recovering` ends at once: its mailbox is the recovery's, which goes on from the
    /// counter the slave had when lost; a counter taken here would be handed out again after.
    fn start(
        &mut self,
        master: &mut Master,
        (slot, events): (&SdoSlot, &Events),
        recovering: &impl Fn(u16) -> bool,
        deadline_ns: u64,
    ) {
        let (slave, origin, write_len) = if let Some(slave) = self.pending.iter().position(Option::is_some) {
            let fault = self.pending[slave].take().expect("found above");
            (self.index, self.subindex) = crate::drive::ds402::ERROR_CODE;
            (slave as u16, Origin::ErrorCode(fault), 0)
        } else if slot.state.compare_exchange(ASKED, TAKEN, Ordering::AcqRel, Ordering::Acquire).is_ok() {
            self.index = slot.index.load(Ordering::Relaxed);
            self.subindex = slot.subindex.load(Ordering::Relaxed);
            (slot.slave.load(Ordering::Relaxed), Origin::Caller, slot.len.load(Ordering::Relaxed) as usize)
        } else {
            return;
        };
        if recovering(slave) {
            return self.finish(slot, events, origin, Outcome::Lost, 0, &[]);
        }
        let Some(out_len) = mailbox_of(master, slave).map(|m| m.out_len as usize) else {
            return self.finish(slot, events, origin, Outcome::NoMailbox, 0, &[]);
        };
        if write_len > out_len - SDO_OFFSET - SDO_LEN {
            return self.finish(slot, events, origin, Outcome::TooLarge, 0, &[]);
        }
        let Ok(counter) = master.slave_mut(slave).and_then(|mut s| s.mailbox_take_counter()) else {
            return self.finish(slot, events, origin, Outcome::NoMailbox, 0, &[]);
        };
        let mut value = [0u8; MAX_DATA];
        for (v, cell) in value.iter_mut().zip(slot.data.iter()).take(write_len) {
            *v = cell.load(Ordering::Relaxed);
        }
        let (index, subindex, data) = (self.index, self.subindex, &value[..write_len]);
        let request = match write_len {
            0 => SdoRequest::Upload { index, subindex, complete_access: false },
            1..=4 => SdoRequest::DownloadExpedited { index, subindex, complete_access: false, data },
            _ => SdoRequest::DownloadNormal {
                index,
                subindex,
                complete_access: false,
                complete_size: write_len as u32,
                data,
            },
        };
        self.send.fill(0);
        coe::write_sdo_request(&mut self.send[..out_len], counter, &request);
        self.phase = Phase::Sending { slave, origin, deadline_ns };
    }

    /// Reads SM1 of the next slave that has a message; `true` when a frame was spent on it.
    fn read_one(
        &mut self,
        master: &mut Master,
        slot: &SdoSlot,
        frames: &EoeFrames,
        events: &Events,
        (cycle, time_ns): (u64, u64),
        (recovering, statusword): (&impl Fn(u16) -> bool, &impl Fn(u16) -> u16),
    ) -> bool {
        if let Some(slave) = self.repeat.filter(|s| !recovering(*s)) {
            if matches!(master.slave_mut(slave).and_then(|mut s| s.mailbox_try_repeat()), Ok(true)) {
                return true;
            }
        }
        self.repeat = None;
        let Ok(watch) = master.watch() else { return false };
        let count = watch.len();
        let waiting = |s: &usize| watch[*s].mailbox_full && !recovering(*s as u16);
        let Some(slave) = (0..count).map(|n| (self.next_slave + n) % count).find(waiting) else {
            return false;
        };
        let SlaveWatch { al_status, .. } = watch[slave];
        self.next_slave = (slave + 1) % count;
        let slave = slave as u16;
        let len = mailbox_of(master, slave).map_or(0, |m| m.in_len as usize);
        if !matches!(master.slave_mut(slave).and_then(|mut s| s.mailbox_try_read(&mut self.receive[..len])), Ok(true)) {
            // A lost read may have emptied SM1: its repeat request goes first from the next cycle.
            self.repeat = Some(slave);
            return true;
        }
        let Ok(header) = MailboxHeader::decode(&self.receive[..len]) else { return true };
        // A request whose write came back after the frame's time-out may have reached the
        // slave all the same: an answer with its counter proves it did, and must be taken, for
        // the slave ignores the same request written again (same counter: a repeat).
        let awaited = match self.phase {
            Phase::Awaiting { slave: s, counter, origin, .. } if s == slave => Some((counter, origin)),
            Phase::Sending { slave: s, origin, .. } if s == slave && header.counter == self.send[5] >> 4 => {
                Some((header.counter, origin))
            }
            _ => None,
        };
        match header.protocol() {
            Some(MailboxType::Error) => {
                if let Some((_, origin)) = awaited {
                    let detail =
                        crate::ethercat::mailbox::parse_error_reply(header.body(&self.receive[..len])).unwrap_or(0);
                    self.finish(slot, events, origin, Outcome::MailboxError, detail as u32, &[]);
                }
            }
            Some(MailboxType::Coe) => {
                let Ok((_, coe_header, body)) = coe::split_message(&self.receive[..len]) else { return true };
                if coe_header.service == CoeService::Emergency {
                    if let Ok(emergency) = Emergency::decode(body) {
                        let fault = (FaultSource::Emergency, emergency.error_code, Action::Reported);
                        events.push(Event::fault((cycle, time_ns), slave, statusword(slave), Some(al_status), fault));
                    }
                    return true;
                }
                let Some((counter, origin)) = awaited else { return true };
                if header.counter != 0 && header.counter != counter {
                    return true;
                }
                let (index, subindex) = (self.index, self.subindex);
                // The response borrows the receive buffer; copy what is kept first.
                let mut value = [0u8; MAX_DATA];
                let (outcome, code, len) = match SdoResponse::decode(body) {
                    Ok(SdoResponse::UploadExpedited { index: i, subindex: s, data }) if (i, s) == (index, subindex) => {
                        value[..data.len()].copy_from_slice(data);
                        (Outcome::Done, 0, data.len())
                    }
                    Ok(SdoResponse::UploadNormal { index: i, subindex: s, complete_size, data })
                        if (i, s) == (index, subindex) =>
                    {
                        if complete_size as usize > data.len() || data.len() > MAX_DATA {
                            (Outcome::TooLarge, 0, 0)
                        } else {
                            let n = complete_size as usize;
                            value[..n].copy_from_slice(&data[..n]);
                            (Outcome::Done, 0, n)
                        }
                    }
                    Ok(SdoResponse::Download { index: i, subindex: s }) if (i, s) == (index, subindex) => {
                        (Outcome::Done, 0, 0)
                    }
                    Ok(SdoResponse::Abort { code, .. }) => (Outcome::Aborted, code.0, 0),
                    _ => (Outcome::Unexpected, 0, 0),
                };
                self.finish(slot, events, origin, outcome, code, &value[..len]);
            }
            // Only fragments: the decoding of any other EoE message may allocate.
            Some(MailboxType::Eoe) if header.body(&self.receive[..len]).first().is_some_and(|b| b & 0x0F == 0) => {
                let body = header.body(&self.receive[..len]);
                if let Ok(EoeMessage::Fragment { header, data, .. }) = EoeMessage::decode(body) {
                    if let Ok(Some(frame)) = self.eoe.reassemblers[slave as usize].push(&header, data) {
                        frames.drive_sent(slave, frame);
                    }
                }
            }
            _ => {}
        }
        true
    }

    /// Ends the transfer under way: a caller's goes back through the slot, a fault's becomes
    /// its event (code 0 when 0x603F could not be read).
    fn finish(&mut self, slot: &SdoSlot, events: &Events, origin: Origin, outcome: Outcome, code: u32, value: &[u8]) {
        self.phase = Phase::Idle;
        match origin {
            Origin::ErrorCode(mut event) => {
                if let (Event::Fault { code, .. }, Outcome::Done, Ok(read)) =
                    (&mut event, outcome, crate::drive::ds402::error_code(value))
                {
                    *code = read;
                }
                events.push(event)
            }
            Origin::Caller => {
                for (cell, b) in slot.data.iter().zip(value) {
                    cell.store(*b, Ordering::Relaxed);
                }
                slot.len.store(value.len() as u16, Ordering::Relaxed);
                slot.outcome.store(outcome as u8, Ordering::Relaxed);
                slot.code.store(code, Ordering::Relaxed);
                slot.state.store(DONE, Ordering::Release);
            }
        }
    }
}

/// The mailbox of the slave at `slave`, if it has one.
fn mailbox_of(master: &Master, slave: u16) -> Option<&Mailbox> {
    master.slave(slave).ok()?.mailbox.as_ref()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::al::AlState;
    use crate::sim::in_process::InProcess;

    #[test]
    fn a_transfer_asked_of_a_slave_being_recovered_takes_no_mailbox_counter() {
        let mut master = Master::new(Box::new(InProcess::new(1)), Duration::from_millis(100));
        master.scan().unwrap();
        master.request_state(AlState::PreOp, Duration::from_secs(5)).unwrap();
        let before = master.mailbox_counter(0);
        let (mut service, slot) = (MailboxService::new(&master), SdoSlot::default());
        let (frames, events) = (EoeFrames::default(), Events::default());
        // Asked before the slave was seen lost, taken up after, in the cycle that saw it lost.
        std::thread::scope(|s| {
            let caller = s.spawn(|| slot.transfer(0, 0x1018, 1, None, || true));
            while !caller.is_finished() {
                service.run(&mut master, (&slot, &frames), &events, (1, 0), |_| true, |_| 0);
                std::thread::sleep(Duration::from_millis(1));
            }
            let e = caller.join().unwrap().unwrap_err();
            assert!(matches!(e, Error::Unavailable(Unavailable::Recovering { slave: 0 })), "{e:?}");
        });
        // The recovery goes on from the counter the slave was lost with, and so does the cycle
        // after it: a counter taken here would be the next request's again, which the drive
        // ignores as a repeat.
        assert_eq!(master.mailbox_counter(0), before);
    }
}
