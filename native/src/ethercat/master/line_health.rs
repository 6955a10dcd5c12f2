//! Reading the line's health: each slave's DL status and error counters, in as few frames as
//! they fit, a read-write (that clears as it reads) where a slave's counters are to be cleared;
//! and each slave's port descriptor. Nothing allocates in
//! [`read_line_health`](Master::read_line_health), so a cycle thread reads beside its cycle
//! (see [`crate::ethercat::line_health`] for what the registers say).

use crate::error::{Error, Result};
use crate::ethercat::frame::{self, Command, FrameBuilder, Slot};
use crate::ethercat::line_health::registers::{
    DlStatus, ErrorCounts, PortDescriptor, ERROR_COUNTERS, ERROR_COUNTERS_LEN,
};
use crate::ethercat::line_health::tally::{LineTally, SlaveRead};
use crate::ethercat::line_health::LineReading;
use crate::ethercat::master::{Master, Slave};
use crate::ethercat::registers::{DL_STATUS, PORT_DESCRIPTOR};

/// Frame bytes one slave's reads take: its DL status (2 bytes) and its error counters (20), each
/// with its datagram header and working counter.
pub const READ_LEN: usize = 2 + ERROR_COUNTERS_LEN + 2 * (frame::DATAGRAM_HEADER_LEN + frame::WKC_LEN);
/// Slaves one frame reads.
pub const SLAVES_PER_FRAME: usize = (frame::MAX_PAYLOAD_LEN - frame::FRAME_HEADER_LEN) / READ_LEN;

impl Master {
    /// Reads the DL status and error counters of the slaves from position `first` on, one per
    /// entry of `reads` (at most [`SLAVES_PER_FRAME`]), in one frame; where `clears(position)`
    /// says so, with a read-write of the counters that clears them as it reads them (what is
    /// read is what was there before the write). Each read says whether its slave answered;
    /// a frame in which one did not is one working-counter error, counted as the cycle's are.
    /// A frame that does not come back leaves every read unanswered and is returned as the
    /// error, counted as the master counts lost frames. No allocation.
    pub fn read_line_health(
        &mut self,
        first: usize,
        reads: &mut [SlaveRead],
        clears: impl Fn(usize) -> bool,
    ) -> Result<()> {
        reads.iter_mut().for_each(|r| r.answered = false);
        let count = reads.len().min(SLAVES_PER_FRAME);
        let slaves = self
            .slaves
            .get(first..first + count)
            .ok_or(Error::NoSuchSlave { position: (first + count) as u16, count: self.slaves.len() as u16 })?;
        let index = self.index.wrapping_add(1);
        self.index = index;
        let mut builder = FrameBuilder::new(&mut self.tx[..]);
        let mut first_slot = None;
        for (n, slave) in slaves.iter().enumerate() {
            let station = slave.station_address;
            let status = builder.push_zeroed(Command::Fprd, index, station, DL_STATUS, 2)?;
            let command = if clears(first + n) { Command::Fprw } else { Command::Fprd };
            builder.push_zeroed(command, index, station, ERROR_COUNTERS, ERROR_COUNTERS_LEN)?;
            first_slot.get_or_insert(status);
        }
        let Some(first_slot) = first_slot else { return Ok(()) };
        let len = builder.finish();
        let n = self.send_frame(len)?;
        let reply = &self.rx[..n];
        let mut all_answered = true;
        for (i, read) in reads.iter_mut().take(count).enumerate() {
            let status = Slot { data_offset: first_slot.data_offset + i * READ_LEN, len: 2, index: first_slot.index };
            let counters = Slot {
                data_offset: status.data_offset + 2 + frame::DATAGRAM_HEADER_LEN + frame::WKC_LEN,
                len: ERROR_COUNTERS_LEN,
                index: first_slot.index,
            };
            // A read-write counts 3 where the slave read and wrote.
            let answered = status.wkc(reply)? == 1 && counters.wkc(reply)? >= 1;
            read.answered = answered;
            all_answered &= answered;
            if answered {
                read.dl_status = DlStatus(u16::from_le_bytes(status.data(reply)?.try_into().expect("2 bytes")));
                read.counters = ErrorCounts::decode(counters.data(reply)?.try_into().expect("the block's length"));
            }
        }
        if !all_answered {
            self.stats.wkc_errors += 1;
        }
        Ok(())
    }

    /// Every slave's port descriptor (0x0007): the ports its ESC has.
    pub fn port_descriptors(&mut self) -> Result<Vec<PortDescriptor>> {
        let stations: Vec<u16> = self.slaves.iter().map(|s| s.station_address).collect();
        stations
            .into_iter()
            .map(|station| {
                let mut b = [0u8];
                self.read_registers(station, PORT_DESCRIPTOR, &mut b)?;
                Ok(PortDescriptor(b[0]))
            })
            .collect()
    }

    /// The line's health as one read finds it, at rest (for tools): each slave's links and what
    /// its ESC counted since its power-up or the last clear (the window's counts too, so that the
    /// findings place them), nothing cleared; and its port descriptor.
    pub fn line_health(&mut self) -> Result<LineReading> {
        let ports = self.port_descriptors()?;
        let frames_before = self.stats.frames;
        let mut tally = LineTally::at_rest(self.slaves.len());
        let mut reads = vec![SlaveRead::default(); SLAVES_PER_FRAME];
        for first in (0..self.slaves.len()).step_by(SLAVES_PER_FRAME) {
            let count = SLAVES_PER_FRAME.min(self.slaves.len() - first);
            self.read_line_health(first, &mut reads[..count], |_| false)?;
            for (n, read) in reads[..count].iter().enumerate() {
                tally.take(first + n, read);
            }
        }
        tally.close_read(0);
        let frames = self.stats.frames - frames_before;
        Ok(LineReading { ports, health: tally.health(), interval: None, frames, frames_lost: 0 })
    }
}

impl Slave {
    /// What the slave is, as its SII names it: its order number ("EL1004"), else its name.
    pub fn product(&self) -> &str {
        self.sii.order().or(self.sii.name()).unwrap_or("unnamed")
    }
}
