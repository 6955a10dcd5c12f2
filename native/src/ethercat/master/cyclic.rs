//! The cyclic exchange: one frame per cycle carrying one LRW over every slave's process data
//! and, when distributed clocks run, the FRMW that hands the reference clock's time to the
//! others. With [supervision](Master::set_supervision) on, the same frame also reads every
//! slave's AL status and mailbox status, so that a slave dropping out of Op or a message
//! waiting in its mailbox (an emergency, an SDO reply) is seen in the cycle it happens. The
//! working counter is checked every cycle; lost frames and wrong counters are counted. The
//! process image and the frame buffers are allocated when the image is laid out, never per
//! cycle.
//!
//! While the slaves (two or more) were all last seen in one state, without an error or mail,
//! the frame reads the whole line with two broadcast reads (BRD of AL status and of SM1
//! status, which every slave answers with its value ORed in) instead of two reads per slave:
//! 31 bytes in all instead of 31 per slave, 2.5 µs per slave less on a 100 Mbit/s wire. A
//! slave that changes in any way sets a bit the others lack or does not answer, and then a
//! second frame reads every slave on its own in the same cycle (counted in
//! [`Stats::watch_frames`](super::Stats::watch_frames)); the cycles after it read each slave
//! in the cyclic frame until they are all alike again (an SDO reply taken, a recovered drive
//! back in Op). A line whose process data leaves no room for every slave's own reads (some 30
//! drives and more) keeps the broadcast reads in the cyclic frame and reads the slaves on their
//! own in frames of their own after it (as many as they take, 48 slaves a frame), every cycle
//! while they differ. What a cycle reports of each slave is the same either way.
//!
//! With distributed clocks the frame also reads one slave's system-time difference (0x092C),
//! a different slave each cycle in turn: every slave's is then at most as many cycles old as
//! there are slaves with DC (6 ms for six drives at 1 kHz), at the price of one 4-byte FPRD
//! (16 bytes, 1.3 µs on a 100 Mbit/s wire) per frame instead of one per slave, and the frame
//! keeps the same length every cycle, so its time on the wire does not change from one cycle to
//! the next. Reads and unanswered reads are counted in the [`Clock`](super::clocks::Clock).
//!
//! Layout of the logical address space: every slave's outputs one after the other from
//! address 0, then every slave's inputs. A slave of fewer than 8 bits a way (an EL2004's four
//! outputs) is packed at the next free bit, as SOEM packs it (two EL2004s share one logical
//! byte, bits 0-3 and 4-7); any other starts on a byte of its own and takes whole bytes.

use std::time::Instant;

use crate::error::{Error, Result, SettingError, Unavailable};
use crate::ethercat::al::AlState;
use crate::ethercat::frame::{self, Command, FrameBuilder, Slot};
use crate::ethercat::link::{copy_reply, is_reply_to, receive_reply};
use crate::ethercat::master::state::AlStatus;
use crate::ethercat::master::{Master, Slave};
use crate::ethercat::pdo::{copy_bits, Direction};
use crate::ethercat::registers::{self, sm_reg, AL_STATUS, DC_SYSTEM_TIME, DC_SYSTEM_TIME_DIFFERENCE};

/// Frame bytes the DC datagrams take: the FRMW of the system time (8 bytes) and the FPRD of
/// one slave's system-time difference (4 bytes), each with its header and working counter.
const DC_DATAGRAMS_LEN: usize = 8 + 4 + 2 * (frame::DATAGRAM_HEADER_LEN + frame::WKC_LEN);

/// Where one slave's data sits in the process image.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ImageSlot {
    /// Offset of its outputs' first byte in the output image (and logical address).
    pub out_offset: usize,
    /// Bytes of the output image its outputs touch.
    pub out_len: usize,
    /// Offset of its inputs' first byte in the input image.
    pub in_offset: usize,
    /// Bytes of the input image its inputs touch.
    pub in_len: usize,
    /// The bit of its first output in the byte at `out_offset`: 0 but for a slave packed at a
    /// bit (see the module).
    pub out_bit: u8,
    /// Bits of outputs: 8 per byte of a slave laid out in whole bytes.
    pub out_bits: usize,
    /// The bit of its first input in the byte at `in_offset`.
    pub in_bit: u8,
    /// Bits of inputs.
    pub in_bits: usize,
}

impl ImageSlot {
    /// Checks that `len` bytes are exactly the outputs of this slot (the slave at `position`),
    /// its bits from bit 0 of the first byte.
    pub fn check_outputs_len(&self, position: u16, len: usize) -> Result<()> {
        let expected = self.out_bits.div_ceil(8);
        if len == expected {
            return Ok(());
        }
        Err(SettingError::OutputsLength { slave: position, expected, given: len }.into())
    }

    /// The first bit of its outputs in the output image.
    pub fn out_start_bit(&self) -> usize {
        self.out_offset * 8 + usize::from(self.out_bit)
    }

    /// The first bit of its inputs in the input image.
    pub fn in_start_bit(&self) -> usize {
        self.in_offset * 8 + usize::from(self.in_bit)
    }

    /// Its outputs in `image` (the whole output image), from bit 0 of the first byte.
    pub fn outputs_in(&self, image: &[u8]) -> Vec<u8> {
        let mut data = vec![0; self.out_bits.div_ceil(8)];
        copy_bits(image, self.out_start_bit(), &mut data, 0, self.out_bits);
        data
    }

    /// Its inputs in `image` (the whole input image), from bit 0 of the first byte.
    pub fn inputs_in(&self, image: &[u8]) -> Vec<u8> {
        let mut data = vec![0; self.in_bits.div_ceil(8)];
        copy_bits(image, self.in_start_bit(), &mut data, 0, self.in_bits);
        data
    }

    /// Writes its outputs `data` (from bit 0 of the first byte, checked to be as long as
    /// [`check_outputs_len`](Self::check_outputs_len) asks) into `image`, leaving the bits of
    /// the slaves packed beside it.
    pub fn write_outputs(&self, image: &mut [u8], data: &[u8]) {
        copy_bits(data, 0, image, self.out_start_bit(), self.out_bits);
    }
}

/// Bits of process data one way of one slave, as its sync manager carries them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SlaveBits {
    /// Outputs.
    pub outputs: usize,
    /// Inputs.
    pub inputs: usize,
}

/// Places `bits` at `cursor` (bits into an image): packed at the next free bit when fewer than
/// 8, else from the next whole byte on and rounded up to whole bytes. Gives the first bit and
/// the bits taken, and moves the cursor past them.
fn place(cursor: &mut usize, bits: usize) -> (usize, usize) {
    let (start, taken) = match bits {
        0 => (*cursor, 0),
        1..=7 => (*cursor, bits),
        _ => (cursor.next_multiple_of(8), bits.next_multiple_of(8)),
    };
    *cursor = start + taken;
    (start, taken)
}

/// What the cyclic frame read of one slave besides its process data, with supervision on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SlaveWatch {
    /// AL status and AL status code as read in the last cycle whose frame came back.
    pub al_status: AlStatus,
    /// Whether SM1 held a message for the master (an emergency or a reply).
    pub mailbox_full: bool,
    /// Whether the slave answered both reads in that cycle.
    pub answered: bool,
}

/// The process image of the bus.
#[derive(Clone, Debug)]
pub struct ProcessImage {
    outputs: Vec<u8>,
    inputs: Vec<u8>,
    slots: Vec<Option<ImageSlot>>,
    expected_wkc: u16,
    /// One per slave; read only while `supervised`.
    watch: Vec<SlaveWatch>,
    supervised: bool,
    /// Whether every slave's own reads fit in the cyclic frame beside the process data.
    each_in_frame: bool,
    frame: CyclicFrame,
}

/// The cyclic frame's buffers, and the frame on its way back when one is.
#[derive(Clone, Debug)]
pub struct CyclicFrame {
    tx: Box<[u8; frame::MAX_PAYLOAD_LEN]>,
    rx: Box<[u8; frame::MAX_PAYLOAD_LEN]>,
    in_flight: Option<InFlight>,
}

/// A cyclic frame sent and not yet received: where its datagrams are and how to judge it.
#[derive(Clone, Copy, Debug)]
struct InFlight {
    /// Its bytes in `tx`.
    len: usize,
    lrw: Slot,
    /// The FRMW of the system time and the FPRD of one slave's system-time difference.
    clock: Option<(Slot, Slot)>,
    watch: Option<Watch>,
    /// Whether a wrong working counter is counted and raised (see [`Master::cycle`]).
    judge: bool,
    sent: Instant,
    /// Its return's length in `rx`, once the exchange of another frame met it on the way.
    returned: Option<usize>,
}

impl CyclicFrame {
    /// Keeps `back` in `rx` when it is the return of the frame on its way and none was kept;
    /// whether it was.
    pub(super) fn keep(&mut self, back: &[u8]) -> bool {
        let Some(flight) = self.in_flight.as_mut().filter(|f| f.returned.is_none()) else { return false };
        if is_reply_to(&self.tx[..flight.len], back) {
            flight.returned = copy_reply(back, &mut self.rx[..]).ok();
        }
        flight.returned.is_some()
    }
}

impl ProcessImage {
    /// Lays out the slaves' process data (`None` for a slave without process data), as the
    /// module says.
    fn layout(bits: &[Option<SlaveBits>]) -> Result<Self> {
        let (mut out_cursor, mut in_cursor, mut expected_wkc) = (0, 0, 0);
        let slots: Vec<Option<ImageSlot>> = bits
            .iter()
            .map(|b| {
                b.map(|b| {
                    let (out_start, out_bits) = place(&mut out_cursor, b.outputs);
                    let (in_start, in_bits) = place(&mut in_cursor, b.inputs);
                    let touched = |start: usize, bits: usize| (start % 8 + bits).div_ceil(8);
                    // A slave's ESC counts the LRW once for its inputs and twice for its
                    // outputs, whoever shares their bytes.
                    expected_wkc += frame::expected_wkc(Command::Lrw, (in_bits > 0) as u16, (out_bits > 0) as u16);
                    ImageSlot {
                        out_offset: out_start / 8,
                        out_len: touched(out_start, out_bits),
                        in_offset: in_start / 8,
                        in_len: touched(in_start, in_bits),
                        out_bit: (out_start % 8) as u8,
                        out_bits,
                        in_bit: (in_start % 8) as u8,
                        in_bits,
                    }
                })
            })
            .collect();
        let (out_total, in_total) = (out_cursor.div_ceil(8), in_cursor.div_ceil(8));
        let limit = frame::MAX_DATAGRAM_DATA - DC_DATAGRAMS_LEN;
        if out_total + in_total > limit {
            return Err(SettingError::ImageTooLarge { bytes: out_total + in_total, limit }.into());
        }
        let unseen = SlaveWatch { al_status: AlStatus { status: 0, code: 0 }, mailbox_full: false, answered: false };
        Ok(ProcessImage {
            outputs: vec![0; out_total],
            inputs: vec![0; in_total],
            slots,
            expected_wkc,
            watch: vec![unseen; bits.len()],
            supervised: false,
            each_in_frame: false,
            frame: CyclicFrame {
                tx: Box::new([0; frame::MAX_PAYLOAD_LEN]),
                rx: Box::new([0; frame::MAX_PAYLOAD_LEN]),
                in_flight: None,
            },
        })
    }

    /// The cyclic frame, for the exchanges of other frames to keep its return.
    pub(super) fn frame_mut(&mut self) -> &mut CyclicFrame {
        &mut self.frame
    }

    fn slot(&self, position: u16) -> Result<ImageSlot> {
        self.slots
            .get(position as usize)
            .copied()
            .flatten()
            .ok_or(Unavailable::NoProcessData { slave: position, with_data: None }.into())
    }
}

fn no_image() -> Error {
    Unavailable::NoProcessImage.into()
}

impl Master {
    /// Before SafeOp: gives every slave at `positions` without process data what its SII
    /// assigns (over CoE where it has CoE and its SII says the assignment may be written, see
    /// [`Sii::process_data`](crate::ethercat::sii::Sii::process_data)), lays out the process
    /// image over every slave with process data, and sets up the sync managers and FMMUs of
    /// the slaves at `positions`.
    pub(crate) fn setup_process_data(&mut self, positions: &[u16]) -> Result<()> {
        for &p in positions {
            let slave = self.slave(p)?;
            if slave.process_data.is_none() {
                let coe = slave.mailbox.as_ref().is_some_and(|m| m.has_coe());
                let described = slave.sii.process_data(coe);
                self.configure_process_data(p, described)?;
            }
        }
        let bits: Vec<Option<SlaveBits>> = self
            .slaves
            .iter()
            .map(|s| {
                let d = s.process_data.as_ref()?;
                let bits = SlaveBits { outputs: d.bits(Direction::Rx), inputs: d.bits(Direction::Tx) };
                (bits != SlaveBits::default()).then_some(bits)
            })
            .collect();
        let image = ProcessImage::layout(&bits)?;
        let out_total = image.outputs.len() as u32;
        for &p in positions {
            if let Ok(slot) = image.slot(p) {
                self.setup_process_syncmanagers(p, &slot, out_total)?;
            }
        }
        self.process = Some(image);
        Ok(())
    }

    fn image(&self) -> Result<&ProcessImage> {
        self.process.as_ref().ok_or_else(no_image)
    }

    fn image_mut(&mut self) -> Result<&mut ProcessImage> {
        self.process.as_mut().ok_or_else(no_image)
    }

    /// The outputs of the slave at `position` as they go out in the next cycle, from bit 0 of
    /// the first byte.
    pub(super) fn outputs(&self, position: u16) -> Result<Vec<u8>> {
        let image = self.image()?;
        Ok(image.slot(position)?.outputs_in(&image.outputs))
    }

    /// Sets the outputs of the slave at `position`; `data` must have their exact length (its
    /// bits from bit 0 of the first byte), the slaves packed beside it keep theirs.
    pub(super) fn set_outputs(&mut self, position: u16, data: &[u8]) -> Result<()> {
        let image = self.image_mut()?;
        let s = image.slot(position)?;
        s.check_outputs_len(position, data.len())?;
        s.write_outputs(&mut image.outputs, data);
        Ok(())
    }

    /// The inputs of the slave at `position` from the last good cycle, from bit 0 of the first
    /// byte.
    pub(super) fn inputs(&self, position: u16) -> Result<Vec<u8>> {
        let image = self.image()?;
        Ok(image.slot(position)?.inputs_in(&image.inputs))
    }

    /// The LRW's expected working counter.
    pub fn expected_wkc(&self) -> Result<u16> {
        Ok(self.image()?.expected_wkc)
    }

    /// One cycle: sends the outputs, takes the inputs, and keeps the clocks together. Returns
    /// the LRW's working counter; a wrong one is counted and raised as
    /// [`Error::WorkingCounter`], and the inputs of that cycle are not taken.
    pub fn exchange(&mut self) -> Result<u16> {
        self.cycle(true)
    }

    /// The first half of [`exchange`](Self::exchange): sends the cyclic frame with the outputs
    /// and returns without waiting for it. [`receive_process_data`](Self::receive_process_data)
    /// takes its return later, up to the frame time-out after it was sent: a cycle that sends
    /// at one wake-up and receives at the next never waits for the round trip. Other frames
    /// may go and come meanwhile (mailbox, registers); their exchanges keep the cyclic frame's
    /// return for it. One cyclic frame is on its way at a time.
    pub fn send_process_data(&mut self) -> Result<()> {
        self.send_cycle(true)
    }

    /// The second half of [`exchange`](Self::exchange): takes the return of the frame
    /// [`send_process_data`](Self::send_process_data) sent, waiting for it until the frame
    /// time-out after it was sent, and returns the LRW's working counter as `exchange` does.
    pub fn receive_process_data(&mut self) -> Result<u16> {
        self.receive_cycle()
    }

    /// Whether a cyclic frame is on its way, sent and its return not yet taken.
    pub fn cyclic_frame_in_flight(&self) -> bool {
        self.process.as_ref().is_some_and(|image| image.frame.in_flight.is_some())
    }

    /// One cycle; with `judge` a wrong working counter is counted and raised, without it (while
    /// the slaves change state) it is only returned. Inputs are taken only from a good cycle.
    pub(crate) fn cycle(&mut self, judge: bool) -> Result<u16> {
        self.send_cycle(judge)?;
        self.receive_cycle()
    }

    fn send_cycle(&mut self, judge: bool) -> Result<()> {
        // The field itself, not image(): the frame index is updated while the image is read.
        let Some(image) = self.process.as_mut() else {
            return Err(no_image());
        };
        if image.frame.in_flight.is_some() {
            return Err(Unavailable::CyclicFrameInFlight.into());
        }
        let index = self.index.wrapping_add(1);
        self.index = index;
        let out_len = image.outputs.len();
        let mut builder = FrameBuilder::new(&mut image.frame.tx[..]);
        let lrw = builder.push_zeroed(Command::Lrw, index, 0, 0, out_len + image.inputs.len())?;
        builder.bytes_mut()[lrw.data_offset..lrw.data_offset + out_len].copy_from_slice(&image.outputs);
        let clock: Option<(Slot, Slot)> = match &self.clock {
            Some(c) => {
                let frmw = builder.push_zeroed(Command::Frmw, index, c.reference_station, DC_SYSTEM_TIME, 8)?;
                let station = c.slaves[c.next_difference].station;
                Some((frmw, builder.push_zeroed(Command::Fprd, index, station, DC_SYSTEM_TIME_DIFFERENCE, 4)?))
            }
            None => None,
        };
        let watch = match (image.supervised, common_status(&image.watch)) {
            (false, _) => None,
            (true, None) if image.each_in_frame => Some(Watch::Each(push_watch(&self.slaves, &mut builder, index)?)),
            // Alike (or, without room for each slave's reads, not: then read on their own after it).
            (true, common) => Some(Watch::Whole {
                al: builder.push_zeroed(Command::Brd, index, 0, AL_STATUS, AL_STATUS_LEN)?,
                sm1: builder.push_zeroed(Command::Brd, index, 0, sm1_status(), 1)?,
                common,
            }),
        };
        let len = builder.finish();
        self.stats.cycles += 1;
        self.stats.frames += 1;
        self.link.send(&image.frame.tx[..len])?;
        image.frame.in_flight = Some(InFlight { len, lrw, clock, watch, judge, sent: Instant::now(), returned: None });
        Ok(())
    }

    fn receive_cycle(&mut self) -> Result<u16> {
        let Some(image) = self.process.as_mut() else {
            return Err(no_image());
        };
        let frame = &mut image.frame;
        let flight = frame.in_flight.take().ok_or(Unavailable::NoCyclicFrameInFlight)?;
        let n = match flight.returned {
            Some(n) => n,
            None => {
                let (tx, deadline) = (&frame.tx[..flight.len], flight.sent + self.timeout);
                let late = &mut self.stats.late_returns;
                match receive_reply(&mut *self.link, tx, &mut frame.rx[..], deadline, |_| *late += 1)? {
                    Some(n) => n,
                    None => {
                        self.stats.lost_frames += 1;
                        return Err(Error::Timeout { what: self.link.awaited().into() });
                    }
                }
            }
        };
        let changed = match flight.watch {
            Some(Watch::Each(first)) => {
                read_watch(&mut image.watch, first, &frame.rx[..n])?;
                false
            }
            Some(Watch::Whole { al, sm1, common }) => !unchanged(al, sm1, common, self.slaves.len(), &frame.rx[..n])?,
            None => false,
        };
        if changed {
            self.watch_each(flight.judge)?;
        }
        let image = self.process.as_mut().ok_or_else(no_image)?;
        let reply = &image.frame.rx[..n];
        let (lrw, out_len, expected) = (flight.lrw, image.outputs.len(), image.expected_wkc);
        let wkc = lrw.wkc(reply)?;
        let mut clock_time = None;
        if let (Some((slot, difference)), Some(c)) = (flight.clock, self.clock.as_mut()) {
            let data = slot.data(reply)?;
            clock_time = Some((u64::from_le_bytes(data.try_into().expect("8 bytes")), slot.wkc(reply)?));
            read_difference(c, difference, reply)?;
        }
        let data = &reply[lrw.data_offset + out_len..lrw.data_offset + lrw.len];
        if wkc != expected {
            if !flight.judge {
                return Ok(wkc);
            }
            self.stats.wkc_errors += 1;
            // A slave that answered its supervision reads in SafeOp or Op took the LRW in the
            // same frame: its inputs are good though another slave's are not (one that is
            // gone or being restored), so the slaves still there go on with fresh inputs.
            if image.supervised {
                for (slot, watch) in image.slots.iter().zip(&image.watch) {
                    let exchanged = matches!(watch.al_status.state(), Some(AlState::SafeOp | AlState::Op));
                    if let (Some(slot), true) = (slot, watch.answered && exchanged) {
                        copy_bits(data, slot.in_start_bit(), &mut image.inputs, slot.in_start_bit(), slot.in_bits);
                    }
                }
            }
            return Err(Error::WorkingCounter { what: "the cyclic LRW".into(), expected, got: wkc });
        }
        image.inputs.copy_from_slice(data);
        if let (Some((time, clock_wkc)), Some(c)) = (clock_time, self.clock.as_mut()) {
            c.system_time = time;
            if flight.judge && clock_wkc != c.expected_wkc {
                self.stats.wkc_errors += 1;
                let expected = c.expected_wkc;
                return Err(Error::WorkingCounter {
                    what: "the cyclic FRMW of the DC system time".into(),
                    expected,
                    got: clock_wkc,
                });
            }
        }
        Ok(wkc)
    }
}

/// Takes the system-time difference the frame read of the slave whose turn it was, and moves
/// the turn on.
fn read_difference(clock: &mut super::clocks::Clock, slot: Slot, reply: &[u8]) -> Result<()> {
    let n = clock.next_difference;
    clock.difference_reads += 1;
    if slot.wkc(reply)? == 1 {
        let raw = u32::from_le_bytes(slot.data(reply)?.try_into().expect("4 bytes"));
        clock.slaves[n].time_difference_ns = Some(crate::ethercat::dc::time_difference(raw));
    } else {
        clock.difference_misses += 1;
    }
    clock.next_difference = (n + 1) % clock.slaves.len();
    Ok(())
}

/// Bytes of AL status (0x0130) through AL status code (0x0134..0x0135).
const AL_STATUS_LEN: usize = 6;
/// Frame bytes each datagram takes besides its data.
const DATAGRAM_OVERHEAD: usize = frame::DATAGRAM_HEADER_LEN + frame::WKC_LEN;
/// Frame bytes of one slave's AL status and SM1 status reads (and of the two broadcast ones).
const WATCH_LEN: usize = AL_STATUS_LEN + 1 + 2 * DATAGRAM_OVERHEAD;
/// Slaves whose own reads one frame carries.
const WATCHED_PER_FRAME: usize = (frame::MAX_PAYLOAD_LEN - frame::FRAME_HEADER_LEN) / WATCH_LEN;

/// How the cyclic frame reads what it supervises.
#[derive(Clone, Copy, Debug)]
enum Watch {
    /// Every slave's AL status and SM1 status, its own two reads from the first slot on.
    Each(Slot),
    /// While every slave was last seen in the `common` state without an error or mail: one
    /// broadcast read of each register, which every slave answers with its value ORed in. With
    /// `common` `None` they were not, and their own reads did not fit: each is read after it.
    Whole { al: Slot, sm1: Slot, common: Option<AlStatus> },
}

/// The SM1 (mailbox in) status register.
fn sm1_status() -> u16 {
    registers::sm(1) + sm_reg::STATUS as u16
}

/// The AL status every slave was last seen in, when they were all seen in the same one: a
/// single state, no error flag, no AL status code, no mail waiting. From there a slave that
/// changes, in any way, sets a bit of AL status, AL status code or SM1 status the others do
/// not have (the states are 1, 2, 3, 4, 8 and an error sets 0x10), or does not answer. `None`
/// for a single slave too: its own reads take no more room than the broadcast ones.
fn common_status(watch: &[SlaveWatch]) -> Option<AlStatus> {
    if watch.len() < 2 {
        return None;
    }
    let common = watch[0].al_status;
    let one_state = matches!(common.status, 0x01 | 0x02 | 0x04 | 0x08) && common.code == 0;
    (one_state && watch.iter().all(|w| w.answered && !w.mailbox_full && w.al_status == common)).then_some(common)
}

/// Whether the broadcast reads say every one of `slaves` answered and is as it was (`common`;
/// never when they were not alike).
fn unchanged(al: Slot, sm1: Slot, common: Option<AlStatus>, slaves: usize, reply: &[u8]) -> Result<bool> {
    let Some(common) = common else { return Ok(false) };
    if al.wkc(reply)? as usize != slaves || sm1.wkc(reply)? as usize != slaves {
        return Ok(false);
    }
    let bytes: &[u8; AL_STATUS_LEN] = al.data(reply)?.try_into().expect("six bytes");
    Ok(AlStatus::from_registers(bytes) == common && sm1.data(reply)?[0] & sm_reg::STATUS_MAILBOX_FULL == 0)
}

impl Master {
    /// Reads every slave's AL status and SM1 status in a frame of their own, after the
    /// broadcast reads of the cyclic frame saw a change: the watch is then this cycle's, as it
    /// would have been with the reads in the cyclic frame. When it does not come back, the
    /// cycle is lost as when its first frame does not: a watch this cycle did not read would
    /// let the inputs of a slave just gone be taken. With `judge`, a frame in which a slave
    /// did not answer is counted as one with a wrong working counter, as the cyclic frame is.
    fn watch_each(&mut self, judge: bool) -> Result<()> {
        let mut rx = [0u8; frame::MAX_PAYLOAD_LEN];
        for start in (0..self.slaves.len()).step_by(WATCHED_PER_FRAME) {
            let end = (start + WATCHED_PER_FRAME).min(self.slaves.len());
            let index = self.next_index();
            let mut builder = FrameBuilder::new(&mut self.tx[..]);
            let first = push_watch(&self.slaves[start..end], &mut builder, index)?;
            let len = builder.finish();
            self.stats.watch_frames += 1;
            let n = self.send_frame_into(len, &mut rx)?;
            read_watch(&mut self.image_mut()?.watch[start..end], first, &rx[..n])?;
        }
        let unanswered = self.image()?.watch.iter().any(|w| !w.answered);
        self.stats.wkc_errors += u64::from(judge && unanswered);
        Ok(())
    }
}

/// Pushes the AL status and SM1 status reads of every slave; returns the first slot. The
/// slots follow each other in the frame, so the reply is walked with the same arithmetic
/// (every slot's size is fixed).
fn push_watch(slaves: &[Slave], builder: &mut FrameBuilder<'_>, index: u8) -> Result<Slot> {
    let mut first = None;
    for slave in slaves {
        let station = slave.station_address;
        let al = builder.push_zeroed(Command::Fprd, index, station, AL_STATUS, AL_STATUS_LEN)?;
        builder.push_zeroed(Command::Fprd, index, station, sm1_status(), 1)?;
        first.get_or_insert(al);
    }
    first.ok_or(Unavailable::NoSlaves.into())
}

impl Master {
    /// Turns the AL status and mailbox status reads of the cyclic frame on or off: on, they
    /// need room for the two broadcast reads beside the process data.
    pub fn set_supervision(&mut self, on: bool) -> Result<()> {
        let slaves = self.slaves.len();
        let image = self.image_mut()?;
        let room = frame::MAX_DATAGRAM_DATA - DC_DATAGRAMS_LEN - (image.outputs.len() + image.inputs.len());
        if on && WATCH_LEN > room {
            return Err(SettingError::SupervisionTooLarge {
                image: image.outputs.len() + image.inputs.len(),
                slaves,
                watch: WATCH_LEN,
            }
            .into());
        }
        image.supervised = on;
        image.each_in_frame = slaves * WATCH_LEN <= room;
        Ok(())
    }

    /// What the last cycle read of every slave besides process data (all unanswered while
    /// supervision is off).
    pub fn watch(&self) -> Result<&[SlaveWatch]> {
        Ok(&self.image()?.watch)
    }
}

/// Takes every slave's AL status and SM1 status from `reply`, from the slot of the first read on.
fn read_watch(watch: &mut [SlaveWatch], first: Slot, reply: &[u8]) -> Result<()> {
    let stride = WATCH_LEN;
    for (n, w) in watch.iter_mut().enumerate() {
        let al = Slot { data_offset: first.data_offset + n * stride, len: AL_STATUS_LEN, index: first.index };
        let sm1 = Slot { data_offset: al.data_offset + AL_STATUS_LEN + DATAGRAM_OVERHEAD, len: 1, index: first.index };
        w.answered = al.wkc(reply)? == 1 && sm1.wkc(reply)? == 1;
        if w.answered {
            let bytes: &[u8; AL_STATUS_LEN] = al.data(reply)?.try_into().expect("six bytes");
            w.al_status = AlStatus::from_registers(bytes);
            w.mailbox_full = sm1.data(reply)?[0] & sm_reg::STATUS_MAILBOX_FULL != 0;
        }
    }
    Ok(())
}

/// Whole-image access for a cycle thread, which moves every slave's data at once.
impl Master {
    /// Where the slave at `position` has its data in the images.
    pub fn image_slot(&self, position: u16) -> Result<ImageSlot> {
        self.image()?.slot(position)
    }

    /// The whole output image, every slave's outputs at their [`ImageSlot`] offsets.
    pub fn output_image(&self) -> Result<&[u8]> {
        Ok(&self.image()?.outputs)
    }

    /// The whole output image, to set for the next cycle.
    pub fn output_image_mut(&mut self) -> Result<&mut [u8]> {
        Ok(&mut self.image_mut()?.outputs)
    }

    /// The whole input image from the last good cycle.
    pub fn input_image(&self) -> Result<&[u8]> {
        Ok(&self.image()?.inputs)
    }

    /// Sets how long every frame may take to come back and returns the previous time-out; a
    /// cycle thread shortens it to its period so that a lost frame costs one cycle, not more.
    pub fn replace_timeout(&mut self, timeout: std::time::Duration) -> std::time::Duration {
        std::mem::replace(&mut self.timeout, timeout)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bytes(outputs: usize, inputs: usize) -> Option<SlaveBits> {
        Some(SlaveBits { outputs: outputs * 8, inputs: inputs * 8 })
    }

    fn whole(out_offset: usize, out_len: usize, in_offset: usize, in_len: usize) -> ImageSlot {
        ImageSlot {
            out_offset,
            out_len,
            in_offset,
            in_len,
            out_bits: out_len * 8,
            in_bits: in_len * 8,
            ..ImageSlot::default()
        }
    }

    #[test]
    fn layout_puts_outputs_then_inputs_and_counts_wkc() {
        let image = ProcessImage::layout(&[bytes(6, 6), None, bytes(10, 28)]).unwrap();
        assert_eq!(image.slot(0).unwrap(), whole(0, 6, 0, 6));
        assert_eq!(image.slot(2).unwrap(), whole(6, 10, 6, 28));
        assert!(image.slot(1).is_err());
        assert_eq!(image.expected_wkc, 6);
        assert_eq!((image.outputs.len(), image.inputs.len()), (16, 34));
    }

    #[test]
    fn slaves_of_a_few_bits_share_bytes_as_soem_packs_them() {
        // EL1004, EL2004, EL2004, EL3102 (6 bytes in), AKD: as SOEM maps two EL2004s to bits
        // 0-3 and 4-7 of one byte, and the next slave of whole bytes on a byte of its own.
        let four_in = Some(SlaveBits { outputs: 0, inputs: 4 });
        let four_out = Some(SlaveBits { outputs: 4, inputs: 0 });
        let image = ProcessImage::layout(&[None, four_in, four_out, four_out, bytes(0, 6), bytes(6, 6)]).unwrap();
        let el2004 = |p| image.slot(p).map(|s| (s.out_offset, s.out_bit, s.out_bits, s.out_len)).unwrap();
        assert_eq!((el2004(2), el2004(3)), ((0, 0, 4, 1), (0, 4, 4, 1)));
        assert_eq!(image.slot(5).unwrap().out_offset, 1, "the AKD's outputs on a byte of their own");
        assert_eq!((image.slot(1).unwrap().in_bit, image.slot(4).unwrap().in_offset), (0, 1));
        assert_eq!(image.slot(5).unwrap().in_offset, 7);
        // 1 (EL1004) + 2 + 2 (EL2004s) + 1 (EL3102) + 3 (AKD).
        assert_eq!(image.expected_wkc, 9);
        assert_eq!((image.outputs.len(), image.inputs.len()), (7, 13));
        let mut outputs = image.outputs.clone();
        image.slot(3).unwrap().write_outputs(&mut outputs, &[0b1010]);
        image.slot(2).unwrap().write_outputs(&mut outputs, &[0b0001]);
        assert_eq!(outputs[0], 0b1010_0001);
        assert_eq!(image.slot(3).unwrap().outputs_in(&outputs), [0b1010]);
        assert!(image.slot(2).unwrap().check_outputs_len(2, 1).is_ok());
    }

    #[test]
    fn layout_refuses_an_image_beyond_one_frame() {
        assert!(ProcessImage::layout(&[bytes(1000, 1000)]).is_err());
    }
}
