//! The line's health read beside the cycle: every slave's DL status and error counters, a few
//! times a second, in a frame of their own after the cycle's ([`SLAVES_PER_FRAME`] slaves a
//! frame: a longer line takes one frame a cycle until all are read), tallied as the EtherCAT
//! layer says ([`crate::ethercat::line_health`]) and published for other threads.
//!
//! It never gets in the cycle's way: its frame goes after the process data, in a cycle in which
//! neither the mailbox nor a recovery sent one, or, when those keep every cycle busy, one read
//! interval late in any cycle; nothing allocates (the tally, the reads and the published bytes
//! are made before the cycle starts), and nothing waits for another thread: the published
//! bytes are a seqlock whose only writer is the cycle thread. A read that does not come back is
//! counted, as every frame is, and its slaves are read again at the next interval, their
//! counters having kept counting meanwhile.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use super::seqlock::SeqBytes;
use crate::ethercat::line_health::registers::PortDescriptor;
use crate::ethercat::line_health::tally::{LineHealth, LineTally, SlaveHealth, SlaveRead, SLAVE_HEALTH_LEN};
use crate::ethercat::line_health::LineReading;
use crate::ethercat::master::line_health::SLAVES_PER_FRAME;
use crate::ethercat::master::Master;

/// How often the line is read by default: four times a second.
pub const DEFAULT_INTERVAL: Duration = Duration::from_millis(250);
/// How long the window of [`LineHealth::window_ns`] spans: the reads of the last 10 s.
pub const WINDOW: Duration = Duration::from_secs(10);
/// Bytes of the published header: time, reads, window (u64 each).
const HEADER_LEN: usize = 24;

/// What the cycle thread publishes of the line's health, and what was found before it started.
pub struct LineHealthShared {
    bytes: SeqBytes,
    /// Each slave's port descriptor, read before the cycle started.
    ports: Vec<PortDescriptor>,
    /// How often the line is read (ns); 0: not at all.
    interval_ns: u64,
    /// Frames the reads took, and those that did not come back.
    frames: AtomicU64,
    lost: AtomicU64,
}

impl LineHealthShared {
    /// For a line whose slaves have `ports`, read every `interval` (`None`: never).
    pub(super) fn new(ports: Vec<PortDescriptor>, interval: Option<Duration>) -> Self {
        LineHealthShared {
            bytes: SeqBytes::new(HEADER_LEN + ports.len() * SLAVE_HEALTH_LEN, &[]),
            ports,
            interval_ns: interval.map_or(0, |i| i.as_nanos() as u64),
            frames: AtomicU64::new(0),
            lost: AtomicU64::new(0),
        }
    }

    /// What the reads found so far (allocates: for threads other than the cycle's).
    pub(super) fn reading(&self) -> LineReading {
        LineReading {
            ports: self.ports.clone(),
            health: self.health(),
            interval: (self.interval_ns > 0).then(|| Duration::from_nanos(self.interval_ns)),
            frames: self.frames.load(Ordering::Relaxed),
            frames_lost: self.lost.load(Ordering::Relaxed),
        }
    }

    /// The health as last published.
    fn health(&self) -> LineHealth {
        let mut bytes = vec![0u8; self.bytes.len()];
        self.bytes.read(&mut bytes);
        let word = |i: usize| u64::from_le_bytes(bytes[8 * i..8 * i + 8].try_into().expect("8 bytes"));
        let slaves = bytes[HEADER_LEN..].chunks_exact(SLAVE_HEALTH_LEN).map(SlaveHealth::decode).collect();
        LineHealth { time_ns: word(0), reads: word(1), window_ns: word(2), slaves }
    }
}

/// The cycle thread's side: the tally and where the read under way stands.
pub(super) struct LineHealthReader {
    tally: LineTally,
    reads: Vec<SlaveRead>,
    /// The first slave the next frame reads; 0 between reads of the line.
    next: usize,
    /// When the next read of the line is due (the cycle's clock, ns); 0: at the first chance.
    due_ns: u64,
}

impl LineHealthReader {
    /// For a line of `slaves` slaves read as `shared` says.
    pub(super) fn new(slaves: usize, shared: &LineHealthShared) -> Self {
        let window_reads = match shared.interval_ns {
            0 => 1,
            interval => (WINDOW.as_nanos() as u64).div_ceil(interval) as usize,
        };
        LineHealthReader {
            tally: LineTally::new(slaves, window_reads),
            reads: vec![SlaveRead::default(); SLAVES_PER_FRAME.min(slaves)],
            next: 0,
            due_ns: 0,
        }
    }

    /// One cycle's turn at `now_ns`, after the cycle's own frames: sends the next frame of the
    /// read when one is due and the cycle sent no other frame beside its own (`frame_free`),
    /// or the read is an interval late.
    pub(super) fn run(&mut self, master: &mut Master, shared: &LineHealthShared, now_ns: u64, frame_free: bool) {
        let interval = shared.interval_ns;
        let count = self.tally.len();
        if interval == 0 || count == 0 || now_ns < self.due_ns || (!frame_free && now_ns < self.due_ns + interval) {
            return;
        }
        let first = self.next;
        let frame = (count - first).min(self.reads.len());
        let reads = &mut self.reads[..frame];
        let tally = &self.tally;
        shared.frames.fetch_add(1, Ordering::Relaxed);
        if master.read_line_health(first, reads, |n| tally.clears_next(n)).is_err() {
            shared.lost.fetch_add(1, Ordering::Relaxed);
        }
        for (n, read) in self.reads[..frame].iter().enumerate() {
            self.tally.take(first + n, read);
        }
        self.next = first + frame;
        if self.next < count {
            return;
        }
        self.next = 0;
        self.tally.close_read(now_ns);
        // An interval after this one's due time: a steady pace, unless it ran an interval late.
        let late = self.due_ns == 0 || now_ns >= self.due_ns + interval;
        self.due_ns = if late { now_ns + interval } else { self.due_ns + interval };
        self.publish(shared);
    }

    fn publish(&self, shared: &LineHealthShared) {
        let (time_ns, reads, window_ns) = self.tally.line();
        let mut w = shared.bytes.write();
        for (i, word) in [time_ns, reads, window_ns].into_iter().enumerate() {
            w.write(8 * i, &word.to_le_bytes());
        }
        let mut slave = [0u8; SLAVE_HEALTH_LEN];
        for n in 0..self.tally.len() {
            if let Some(health) = self.tally.slave(n) {
                health.encode(&mut slave);
                w.write(HEADER_LEN + n * SLAVE_HEALTH_LEN, &slave);
            }
        }
    }
}
