//! The EtherCAT master: one [`Master`] drives one bus through a [`Link`].
//!
//! One module per concept: [`scan`] finds the slaves and gives them station addresses,
//! [`sii_read`] reads their EEPROM, [`state`] moves them through the AL state machine,
//! [`mailbox_client`] carries mailbox messages with counter and repeat, [`sdo`] and [`sdo_info`] are
//! the CoE client, [`eoe`] and [`foe`] the EoE and FoE clients, [`mapping`] sets up a slave's process data from its description, [`clocks`] sets up distributed
//! clocks and [`cyclic`] exchanges the process image and [`restore`] brings one slave back while the
//! others cycle; [`line_health`] reads every slave's links and error counters. This file holds the bus-wide state and
//! the register access all of them share.

use std::collections::VecDeque;
use std::time::Duration;

use crate::error::{Error, Result};
use crate::ethercat::coe::Emergency;
use crate::ethercat::frame::{self, Command, FrameBuilder};
use crate::ethercat::link::Link;
use crate::ethercat::pdo::ProcessData;
use crate::ethercat::sii::Sii;

pub mod clocks;
pub mod cyclic;
pub mod eoe;
pub mod foe;
pub mod line_health;
pub mod mailbox_client;
pub mod mapping;
pub mod restore;
pub mod scan;
pub mod sdo;
pub mod sdo_info;
pub mod sii_read;
pub mod slave_ref;
pub mod state;

pub use slave_ref::SlaveRef;

/// Station address given to the slave at position 0; the next ones count up from it.
pub const FIRST_STATION_ADDRESS: u16 = 0x1001;
/// How long a slave may take by default to take or answer one mailbox message.
pub const MAILBOX_TIMEOUT: Duration = Duration::from_secs(2);
/// How often an idempotent register access is repeated after a lost frame.
const REGISTER_RETRIES: u32 = 3;

/// Counters of the bus, never reset: errors are counted, not hidden.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
// Python gets a dict keyed by the field names (akd_ros._native): renaming a field renames a key.
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObject))]
pub struct Stats {
    /// Frames sent.
    pub frames: u64,
    /// Frames that did not come back in time.
    pub lost_frames: u64,
    /// Datagrams whose working counter was not the expected one.
    pub wkc_errors: u64,
    /// Cyclic exchanges done.
    pub cycles: u64,
    /// Mailbox replies fetched again with a repeat request after a lost frame.
    pub mailbox_repeats: u64,
    /// Emergency messages received.
    pub emergencies: u64,
    /// Mailbox replies dropped as stale: another counter than the request's (late answers), or
    /// the copy of the message read before that a repeat request brought back.
    pub stale_mailbox_replies: u64,
    /// Frames of their own that read every slave's AL status and mailbox status, in cycles
    /// whose broadcast reads saw a slave change (see [`set_supervision`](Master::set_supervision)).
    pub watch_frames: u64,
    /// Returns met while awaiting another frame's: frames counted lost that did come back,
    /// after their time-out (a slow line or simulator), told apart from those that never did.
    pub late_returns: u64,
}

/// One slave as the scan found it.
#[derive(Clone, Debug)]
pub struct Slave {
    /// Position on the bus, from 0.
    pub position: u16,
    /// Configured station address (register 0x0010) given by the scan.
    pub station_address: u16,
    /// Station alias (register 0x0012, from SII word 4).
    pub alias: u16,
    /// Whether it has a distributed clock with a system time: feature bit 2, and its system time
    /// (0x0910) answered the scan. The ET1200 of Beckhoff's digital terminals sets the bit but
    /// has no system time (a read there finds no register, working counter 0): it latches
    /// receive times and is not synchronised.
    pub dc: bool,
    /// AL status and code as the scan found them, before it took the slave to Init: what a
    /// commissioning engineer needs to see of a drive that was left in Op or with an error.
    pub found: state::AlStatus,
    /// The SII EEPROM content.
    pub sii: Sii,
    /// Mailbox state, when the slave has a mailbox.
    pub mailbox: Option<mailbox_client::Mailbox>,
    /// Emergency messages received and not yet taken.
    pub emergencies: VecDeque<Emergency>,
    /// Its end of EoE: Ethernet frames received, the next frame number.
    pub eoe: eoe::EoePort,
    /// The process data this slave was given, if any.
    pub process_data: Option<ProcessData>,
}

impl Slave {
    /// Whether the ESC has a distributed clock with a system time ([`Slave::dc`]).
    pub fn has_dc(&self) -> bool {
        self.dc
    }
}

/// Sends `tx` on `link` and returns the length of its return in `rx`; counts the frame in
/// `stats`, and counts it lost when it does not come back. The return of the cyclic frame on its
/// way back meanwhile, if one is, is kept in `cyclic` for
/// [`receive_process_data`](Master::receive_process_data).
fn counted_exchange(
    link: &mut dyn Link,
    stats: &mut Stats,
    (tx, rx): (&[u8], &mut [u8]),
    timeout: Duration,
    mut cyclic: Option<&mut cyclic::CyclicFrame>,
) -> Result<usize> {
    stats.frames += 1;
    let mut late = 0;
    let keep = |back: &[u8]| {
        let kept = cyclic.as_deref_mut().is_some_and(|cyclic| cyclic.keep(back));
        late += u64::from(!kept);
    };
    let result = crate::ethercat::link::exchange_keeping_others(link, tx, rx, timeout, keep);
    stats.late_returns += late;
    result.inspect_err(|e| {
        if matches!(e, Error::Timeout { .. }) {
            stats.lost_frames += 1;
        }
    })
}

/// An EtherCAT master on one link.
pub struct Master {
    link: Box<dyn Link>,
    timeout: Duration,
    mailbox_timeout: Duration,
    tx: Box<[u8; frame::MAX_PAYLOAD_LEN]>,
    rx: Box<[u8; frame::MAX_PAYLOAD_LEN]>,
    index: u8,
    slaves: Vec<Slave>,
    stats: Stats,
    process: Option<cyclic::ProcessImage>,
    clock: Option<clocks::Clock>,
}

impl Master {
    /// A master on `link`; every frame waits up to `timeout` for its return.
    pub fn new(link: Box<dyn Link>, timeout: Duration) -> Self {
        Master {
            link,
            timeout,
            mailbox_timeout: MAILBOX_TIMEOUT,
            tx: Box::new([0; frame::MAX_PAYLOAD_LEN]),
            rx: Box::new([0; frame::MAX_PAYLOAD_LEN]),
            index: 0,
            slaves: Vec::new(),
            stats: Stats::default(),
            process: None,
            clock: None,
        }
    }

    /// How long a slave may take to take or answer one mailbox message (default 2 s).
    pub fn set_mailbox_timeout(&mut self, timeout: Duration) {
        self.mailbox_timeout = timeout;
    }

    /// The link's description.
    pub fn describe(&self) -> String {
        self.link.describe()
    }

    /// The slaves found by the last [`scan`](Self::scan).
    pub fn slaves(&self) -> &[Slave] {
        &self.slaves
    }

    /// The counters.
    pub fn stats(&self) -> Stats {
        self.stats
    }

    /// The slave at `position`, or an error naming how many there are.
    pub fn slave(&self, position: u16) -> Result<&Slave> {
        self.slaves.get(position as usize).ok_or(Error::NoSuchSlave { position, count: self.slaves.len() as u16 })
    }

    fn slave_entry_mut(&mut self, position: u16) -> Result<&mut Slave> {
        let count = self.slaves.len() as u16;
        self.slaves.get_mut(position as usize).ok_or(Error::NoSuchSlave { position, count })
    }

    /// Takes the emergency messages received from the slave at `position`.
    pub(super) fn take_emergencies(&mut self, position: u16) -> Result<Vec<Emergency>> {
        Ok(self.slave_entry_mut(position)?.emergencies.drain(..).collect())
    }

    /// Sends the frame of `len` bytes in `tx` and returns the length of its return in `rx`.
    /// Counts the frame, and counts it lost when it does not come back.
    fn send_frame(&mut self, len: usize) -> Result<usize> {
        let cyclic = self.process.as_mut().map(cyclic::ProcessImage::frame_mut);
        counted_exchange(&mut *self.link, &mut self.stats, (&self.tx[..len], &mut self.rx[..]), self.timeout, cyclic)
    }

    /// As [`send_frame`](Self::send_frame), with the return in `rx`: for a second frame of a
    /// cycle while the first one's return in `self.rx` is still being read.
    pub(super) fn send_frame_into(&mut self, len: usize, rx: &mut [u8]) -> Result<usize> {
        let cyclic = self.process.as_mut().map(cyclic::ProcessImage::frame_mut);
        counted_exchange(&mut *self.link, &mut self.stats, (&self.tx[..len], rx), self.timeout, cyclic)
    }

    /// Sends a frame built by another master of the same bus (one made by
    /// [`for_restore`](Self::for_restore), restoring a slave) and gives its return in `rx`; counted with this master's frames, as
    /// every frame on its link is.
    pub fn relay(&mut self, tx: &[u8], rx: &mut [u8]) -> Result<usize> {
        self.tx[..tx.len()].copy_from_slice(tx);
        let n = self.send_frame(tx.len())?;
        crate::ethercat::link::copy_reply(&self.rx[..n], rx)
    }

    fn next_index(&mut self) -> u8 {
        self.index = self.index.wrapping_add(1);
        self.index
    }

    /// One frame with one datagram. For reads the reply's data lands in `data`. Returns the
    /// working counter. Not repeated on loss: the caller knows whether a repeat is harmless.
    pub fn datagram(&mut self, command: Command, adp: u16, ado: u16, data: &mut [u8]) -> Result<u16> {
        let index = self.next_index();
        let mut builder = FrameBuilder::new(&mut self.tx[..]);
        let slot = builder.push(command, index, adp, ado, data)?;
        let len = builder.finish();
        let n = self.send_frame(len)?;
        let reply = &self.rx[..n];
        let wkc = slot.wkc(reply)?;
        if command.reads() {
            data.copy_from_slice(slot.data(reply)?);
        }
        Ok(wkc)
    }

    /// [`datagram`](Self::datagram) repeated up to three times after a lost frame, for
    /// register accesses that may safely happen twice.
    fn datagram_retry(&mut self, command: Command, adp: u16, ado: u16, data: &mut [u8]) -> Result<u16> {
        let mut attempt = 0;
        loop {
            match self.datagram(command, adp, ado, data) {
                Err(Error::Timeout { .. }) if attempt < REGISTER_RETRIES => attempt += 1,
                other => return other,
            }
        }
    }

    /// Checks a working counter, counting a wrong one.
    fn expect_wkc(&mut self, what: impl FnOnce() -> String, expected: u16, got: u16) -> Result<()> {
        if got == expected {
            Ok(())
        } else {
            self.stats.wkc_errors += 1;
            Err(Error::WorkingCounter { what: what().into(), expected, got })
        }
    }

    /// Reads registers of the slave at `station` (FPRD) into `data`.
    pub fn read_registers(&mut self, station: u16, register: u16, data: &mut [u8]) -> Result<()> {
        let wkc = self.datagram_retry(Command::Fprd, station, register, data)?;
        self.expect_wkc(|| format!("FPRD of 0x{register:04X} from station 0x{station:04X}"), 1, wkc)
    }

    /// Writes registers of the slave at `station` (FPWR).
    pub fn write_registers(&mut self, station: u16, register: u16, data: &[u8]) -> Result<()> {
        let mut copy = [0u8; frame::MAX_DATAGRAM_DATA];
        let buf = copy
            .get_mut(..data.len())
            .ok_or(crate::error::FrameError::TooLarge { len: data.len(), room: frame::MAX_DATAGRAM_DATA })?;
        buf.copy_from_slice(data);
        let wkc = self.datagram_retry(Command::Fpwr, station, register, buf)?;
        self.expect_wkc(|| format!("FPWR of 0x{register:04X} to station 0x{station:04X}"), 1, wkc)
    }

    /// Reads a 16-bit register.
    pub fn read_u16(&mut self, station: u16, register: u16) -> Result<u16> {
        let mut b = [0u8; 2];
        self.read_registers(station, register, &mut b)?;
        Ok(u16::from_le_bytes(b))
    }

    /// Broadcast write (BWR) to every slave; returns how many slaves took it.
    pub fn broadcast_write(&mut self, register: u16, data: &[u8]) -> Result<u16> {
        let mut copy = data.to_vec();
        self.datagram_retry(Command::Bwr, 0, register, &mut copy)
    }

    /// The station address of the slave at `position`.
    pub fn station(&self, position: u16) -> Result<u16> {
        Ok(self.slave(position)?.station_address)
    }

    /// Reads registers of the slave at `position` (for tools and tests).
    pub(super) fn read_register_at(&mut self, position: u16, register: u16, len: usize) -> Result<Vec<u8>> {
        let station = self.station(position)?;
        let mut data = vec![0; len];
        self.read_registers(station, register, &mut data)?;
        Ok(data)
    }

    /// Writes registers of the slave at `position` (for tools and tests).
    pub(super) fn write_register_at(&mut self, position: u16, register: u16, data: &[u8]) -> Result<()> {
        let station = self.station(position)?;
        self.write_registers(station, register, data)
    }

    /// Positions `position` or, when `None`, every slave.
    fn positions(&self, position: Option<u16>) -> Result<Vec<u16>> {
        match position {
            Some(p) => self.slave(p).map(|_| vec![p]),
            None => Ok((0..self.slaves.len() as u16).collect()),
        }
    }
}
