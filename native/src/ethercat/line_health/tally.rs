//! The error counters of a line's slaves, read now and then and tallied: totals since the first
//! read and counts over a window of the last reads, made of the registers' differences from one
//! read to the next. Nothing allocates once a [`LineTally`] is made, so the cycle thread keeps
//! it.
//!
//! A counter stops at 0xFF, so the tally asks for a slave's counters to be cleared once one of
//! them reached [`CLEAR_AT`]: the read that clears reads the counts it clears in the same
//! datagram (a read-write, whose read gives what was there before the write), and they are
//! counted. Nothing is hidden: a read that found a counter stopped at 0xFF is counted in
//! [`SlaveHealth::saturated`] (what it would have counted beyond is missing), and one that found
//! a counter lower than the read before, without a clearing read of ours answered, in
//! [`SlaveHealth::found_lower`] (the slave was reset or power-cycled, a clearing read's frame
//! was lost after it cleared, or another master cleared them: what was counted since the read
//! before is missing).

use super::registers::{DlStatus, ErrorCounts, COUNTERS};

/// A counter at or above this is cleared by the slave's next read.
pub const CLEAR_AT: u8 = 0x80;

/// What one read of one slave gave.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SlaveRead {
    /// Whether the slave answered.
    pub answered: bool,
    /// Its DL status.
    pub dl_status: DlStatus,
    /// Its error counters, as they were when the read passed (before a clearing read's write).
    pub counters: ErrorCounts<u8>,
}

/// One slave's counts as the tally has them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SlaveHealth {
    /// Whether it answered the last read.
    pub answered: bool,
    /// Its DL status as last answered; `None` before it answered once.
    pub dl_status: Option<DlStatus>,
    /// Its DL status as first answered: the line as found.
    pub found: Option<DlStatus>,
    /// Counted since the first read, that read's counts included (what the slave had counted
    /// since its power-up or the last clear).
    pub totals: ErrorCounts<u64>,
    /// Counted over the window: from the read that ended [`LineHealth::window_ns`] before the
    /// last one, the first read's counts left out.
    pub window: ErrorCounts<u64>,
    /// Reads asked of it.
    pub reads: u64,
    /// Of those, the ones it did not answer (unreachable, or their frame lost).
    pub unanswered: u64,
    /// Reads that found a counter stopped at 0xFF.
    pub saturated: u64,
    /// Reads that found a counter lower than the read before, without a clearing read answered.
    pub found_lower: u64,
    /// Clearing reads it answered: its counters were cleared and their counts taken.
    pub cleared: u64,
}

/// The line's counts as the tally has them.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LineHealth {
    /// When the last read ended (the reader's clock, ns); 0 before any.
    pub time_ns: u64,
    /// Reads of the whole line done.
    pub reads: u64,
    /// How long the window spans: from the read before its oldest to the last (ns).
    pub window_ns: u64,
    /// Each slave's, by position.
    pub slaves: Vec<SlaveHealth>,
}

/// One slave's tally.
#[derive(Clone, Debug)]
struct SlaveTally {
    health: SlaveHealth,
    /// The registers as the last answered read left them (zero after a clearing one).
    last: ErrorCounts<u8>,
    /// Whether its next read clears.
    clear_next: bool,
    /// Whether its next read's counts are the window's: from its first answered read on (or at
    /// once, at rest).
    started: bool,
    /// Counted in the line read under way.
    current: ErrorCounts<u8>,
    /// Counted in each of the window's reads, a ring.
    ring: Vec<ErrorCounts<u8>>,
}

/// The tally of a line's error counters.
#[derive(Clone, Debug)]
pub struct LineTally {
    slaves: Vec<SlaveTally>,
    /// When each of the window's reads ended, a ring beside the slaves'.
    times: Vec<u64>,
    reads: u64,
    time_ns: u64,
    window_start_ns: u64,
}

impl LineTally {
    /// A tally of `slaves` slaves whose window spans the last `window_reads` reads (at least 1).
    pub fn new(slaves: usize, window_reads: usize) -> Self {
        Self::with_first_read(slaves, window_reads, false)
    }

    /// A tally of one read of a line at rest: its window is that read's counts, all each slave
    /// counted since its power-up or the last clear.
    pub fn at_rest(slaves: usize) -> Self {
        Self::with_first_read(slaves, 1, true)
    }

    fn with_first_read(slaves: usize, window_reads: usize, first_in_window: bool) -> Self {
        let window_reads = window_reads.max(1);
        let slave = SlaveTally {
            health: SlaveHealth::default(),
            last: ErrorCounts::default(),
            clear_next: false,
            started: first_in_window,
            current: ErrorCounts::default(),
            ring: vec![ErrorCounts::default(); window_reads],
        };
        LineTally {
            slaves: vec![slave; slaves],
            times: vec![0; window_reads],
            reads: 0,
            time_ns: 0,
            window_start_ns: 0,
        }
    }

    /// Slaves tallied.
    pub fn len(&self) -> usize {
        self.slaves.len()
    }

    /// Whether it tallies no slave.
    pub fn is_empty(&self) -> bool {
        self.slaves.is_empty()
    }

    /// Whether slave `n`'s next read is to clear its counters.
    pub fn clears_next(&self, n: usize) -> bool {
        self.slaves.get(n).is_some_and(|s| s.clear_next)
    }

    /// Takes slave `n`'s read of the line read under way; a clearing read if
    /// [`clears_next`](Self::clears_next) said so when it was made.
    pub fn take(&mut self, n: usize, read: &SlaveRead) {
        let Some(s) = self.slaves.get_mut(n) else { return };
        let h = &mut s.health;
        h.reads += 1;
        h.answered = read.answered;
        if !read.answered {
            h.unanswered += 1;
            return;
        }
        h.dl_status = Some(read.dl_status);
        h.found.get_or_insert(read.dl_status);
        let (now, before) = (read.counters.values(), s.last.values());
        let mut lower = false;
        let mut delta = [0u8; COUNTERS];
        for ((d, &n), &b) in delta.iter_mut().zip(&now).zip(&before) {
            lower |= n < b;
            *d = if n >= b { n - b } else { n };
        }
        h.found_lower += u64::from(lower);
        h.saturated += u64::from(read.counters.saturated());
        let mut totals = h.totals.values();
        for (t, &d) in totals.iter_mut().zip(&delta) {
            *t += u64::from(d);
        }
        h.totals = ErrorCounts::from_values(totals);
        if s.started {
            let mut current = s.current.values();
            for (c, &d) in current.iter_mut().zip(&delta) {
                *c = c.saturating_add(d);
            }
            s.current = ErrorCounts::from_values(current);
        }
        s.started = true;
        if s.clear_next {
            h.cleared += 1;
            s.last = ErrorCounts::default();
            s.clear_next = false;
        } else {
            s.last = read.counters;
            s.clear_next = read.counters.highest() >= CLEAR_AT;
        }
    }

    /// Ends the line read under way at `time_ns`: the window moves on by one read.
    pub fn close_read(&mut self, time_ns: u64) {
        let at = (self.reads % self.times.len() as u64) as usize;
        self.window_start_ns = if self.reads < self.times.len() as u64 { self.times[0] } else { self.times[at] };
        if self.reads == 0 {
            self.window_start_ns = time_ns;
        }
        self.times[at] = time_ns;
        for s in &mut self.slaves {
            let mut window = s.health.window.values();
            for ((w, &old), &new) in window.iter_mut().zip(&s.ring[at].values()).zip(&s.current.values()) {
                *w = *w - u64::from(old) + u64::from(new);
            }
            s.health.window = ErrorCounts::from_values(window);
            s.ring[at] = std::mem::take(&mut s.current);
        }
        self.reads += 1;
        self.time_ns = time_ns;
    }

    /// Slave `n`'s counts.
    pub fn slave(&self, n: usize) -> Option<&SlaveHealth> {
        self.slaves.get(n).map(|s| &s.health)
    }

    /// When the last read ended, reads done, and how long the window spans (ns).
    pub fn line(&self) -> (u64, u64, u64) {
        (self.time_ns, self.reads, self.time_ns - self.window_start_ns)
    }

    /// The whole line's counts (allocates: for readers off the cycle thread).
    pub fn health(&self) -> LineHealth {
        let (time_ns, reads, window_ns) = self.line();
        LineHealth { time_ns, reads, window_ns, slaves: self.slaves.iter().map(|s| s.health).collect() }
    }
}

/// Bytes a [`SlaveHealth`] takes encoded ([`SlaveHealth::encode`]).
pub const SLAVE_HEALTH_LEN: usize = 8 * (2 * COUNTERS + 7);

impl SlaveHealth {
    /// Writes it into `out` ([`SLAVE_HEALTH_LEN`] bytes), for a thread to hand it to another
    /// through bytes without allocating.
    pub fn encode(&self, out: &mut [u8]) {
        let status = |s: Option<DlStatus>| s.map_or(0, |s| 0x1_0000 | u64::from(s.0));
        let head = [
            u64::from(self.answered) | status(self.dl_status) << 1,
            status(self.found),
            self.reads,
            self.unanswered,
            self.saturated,
            self.found_lower,
            self.cleared,
        ];
        let words = head.into_iter().chain(self.totals.values()).chain(self.window.values());
        for (chunk, word) in out.chunks_exact_mut(8).zip(words) {
            chunk.copy_from_slice(&word.to_le_bytes());
        }
    }

    /// What [`encode`](Self::encode) wrote into `bytes`.
    pub fn decode(bytes: &[u8]) -> Self {
        let word = |i: usize| u64::from_le_bytes(bytes[8 * i..8 * i + 8].try_into().expect("8 bytes"));
        let counts = |from: usize| ErrorCounts::from_values(std::array::from_fn(|i| word(from + i)));
        let status = |w: u64| (w & 0x1_0000 != 0).then_some(DlStatus(w as u16));
        SlaveHealth {
            answered: word(0) & 1 == 1,
            dl_status: status(word(0) >> 1),
            found: status(word(1)),
            reads: word(2),
            unanswered: word(3),
            saturated: word(4),
            found_lower: word(5),
            cleared: word(6),
            totals: counts(7),
            window: counts(7 + COUNTERS),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::line_health::registers::Counter;

    fn read(counts: &[(Counter, u8)]) -> SlaveRead {
        let mut counters = ErrorCounts::default();
        for &(counter, n) in counts {
            *counters.get_mut(counter) = n;
        }
        SlaveRead { answered: true, dl_status: DlStatus(0x5A33), counters }
    }

    #[test]
    fn totals_and_window_from_the_registers_differences() {
        let mut tally = LineTally::new(1, 2);
        let invalid = Counter::InvalidFrames(0);
        // What the slave counted before the first read is a total, not the window's.
        for (t, n) in [(0, 5), (1, 9), (2, 12), (3, 12)] {
            tally.take(0, &read(&[(invalid, n)]));
            tally.close_read(t * 250);
        }
        let h = tally.slave(0).unwrap();
        assert_eq!(h.totals.ports[0].invalid_frames, 12);
        // The window: the last two reads, 12 - 9 + 12 - 12.
        assert_eq!(h.window.ports[0].invalid_frames, 3);
        assert_eq!(tally.line(), (750, 4, 500));
        assert_eq!(h.dl_status, Some(DlStatus(0x5A33)));
    }

    #[test]
    fn a_counter_past_half_is_cleared_by_the_next_read_and_its_counts_kept() {
        let mut tally = LineTally::new(1, 4);
        let lost = Counter::LostLinks(1);
        tally.take(0, &read(&[(lost, 0)]));
        tally.close_read(0);
        tally.take(0, &read(&[(lost, 0x90)]));
        tally.close_read(1);
        assert!(tally.clears_next(0));
        // The clearing read reads what it clears, 0x95; the next starts from 0.
        tally.take(0, &read(&[(lost, 0x95)]));
        tally.close_read(2);
        assert!(!tally.clears_next(0));
        tally.take(0, &read(&[(lost, 3)]));
        tally.close_read(3);
        let h = tally.slave(0).unwrap();
        assert_eq!(
            (h.totals.ports[1].lost_links, h.window.ports[1].lost_links, h.cleared, h.found_lower),
            (0x98, 0x98, 1, 0)
        );
    }

    #[test]
    fn what_was_lost_is_counted_not_hidden() {
        let mut tally = LineTally::new(1, 4);
        let invalid = Counter::InvalidFrames(1);
        tally.take(0, &read(&[(invalid, 0x85)]));
        tally.close_read(0);
        // The clearing read's frame lost: the slave may or may not have cleared.
        tally.take(0, &SlaveRead::default());
        tally.close_read(1);
        assert!(tally.clears_next(0), "the next read clears again");
        // It had: 2 counted since, lower than 0x85; what came between the last read and the
        // clear is missing, and said so.
        tally.take(0, &read(&[(invalid, 2)]));
        tally.close_read(2);
        tally.take(0, &read(&[(invalid, 0xFF)]));
        tally.close_read(3);
        let h = tally.slave(0).unwrap();
        assert_eq!((h.reads, h.unanswered, h.found_lower, h.cleared, h.saturated), (4, 1, 1, 1, 1));
        assert_eq!(h.totals.ports[1].invalid_frames, 0x85 + 2 + 0xFF);
        // Cleared by the next read; then a power cycle, no clear of ours: found lower again.
        for (t, n) in [(4, 0xFF), (5, 5), (6, 1)] {
            tally.take(0, &read(&[(invalid, n)]));
            tally.close_read(t);
        }
        let h = tally.slave(0).unwrap();
        assert_eq!((h.cleared, h.found_lower, h.totals.ports[1].invalid_frames), (2, 2, 0x85 + 2 + 0xFF + 5 + 1));
    }

    #[test]
    fn health_goes_through_bytes_unchanged() {
        let mut tally = LineTally::new(2, 3);
        tally.take(0, &read(&[(Counter::ForwardedErrors(0), 7), (Counter::Pdi, 1)]));
        tally.take(1, &SlaveRead::default());
        tally.close_read(10);
        for n in 0..2 {
            let h = *tally.slave(n).unwrap();
            let mut bytes = [0u8; SLAVE_HEALTH_LEN];
            h.encode(&mut bytes);
            assert_eq!(SlaveHealth::decode(&bytes), h);
        }
        assert_eq!(tally.slave(1).unwrap().dl_status, None);
    }
}
