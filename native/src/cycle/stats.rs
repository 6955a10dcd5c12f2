//! Per-cycle statistics, kept by the cycle thread and read by any other thread at any time.
//!
//! Every field is an atomic written only by the cycle thread (a plain load and store, no
//! read-modify-write needed with one writer) and read with relaxed loads, so recording takes
//! no lock and no allocation and a reader never delays the cycle. A reader may see one cycle's
//! sample counted in one field and not yet in another; the summary derives its count from the
//! buckets it read so its percentiles are consistent among themselves.

use std::sync::atomic::{AtomicU32, AtomicU64, Ordering::Relaxed};

/// Histogram buckets: 1 µs each, [`BUCKETS`] of them from the histogram's lower bound, plus
/// one below and one above.
pub const BUCKET_NS: u64 = 1_000;
/// Number of 1 µs buckets: a histogram spans about 2 ms at 1 µs resolution.
pub const BUCKETS: usize = 2048;

/// A histogram of durations with 1 µs buckets from `low_ns`, and the exact minimum, maximum
/// and sum.
pub struct Histogram {
    low_ns: u64,
    below: AtomicU32,
    buckets: Box<[AtomicU32]>,
    above: AtomicU32,
    min_ns: AtomicU64,
    max_ns: AtomicU64,
    sum_ns: AtomicU64,
}

/// Count, minimum, mean, 99th percentile and maximum of a histogram, in nanoseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
// Python gets a dict keyed by the field names (akd_ros._native): renaming a field renames a key.
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObject))]
pub struct Summary {
    /// Samples recorded.
    pub count: u64,
    /// Smallest sample.
    pub min_ns: u64,
    /// Mean of the samples.
    pub mean_ns: u64,
    /// 99th percentile, as the upper edge of its 1 µs bucket (never above the maximum).
    pub p99_ns: u64,
    /// Largest sample.
    pub max_ns: u64,
}

/// Single-writer increment: only the cycle thread records.
fn bump(counter: &AtomicU32) {
    counter.store(counter.load(Relaxed).wrapping_add(1), Relaxed);
}

impl Default for Histogram {
    /// Buckets from 0 ns.
    fn default() -> Self {
        Histogram::new(0)
    }
}

impl Histogram {
    /// An empty histogram whose 1 µs buckets start at `low_ns`.
    pub fn new(low_ns: u64) -> Self {
        Histogram {
            low_ns,
            below: AtomicU32::new(0),
            buckets: (0..BUCKETS).map(|_| AtomicU32::new(0)).collect(),
            above: AtomicU32::new(0),
            min_ns: AtomicU64::new(u64::MAX),
            max_ns: AtomicU64::new(0),
            sum_ns: AtomicU64::new(0),
        }
    }

    /// A histogram centred on `nominal_ns` (e.g. the period): about ±1 ms around it.
    pub fn around(nominal_ns: u64) -> Self {
        Self::new(nominal_ns.saturating_sub(BUCKETS as u64 / 2 * BUCKET_NS))
    }

    /// Records one sample. Only one thread may record.
    pub fn record(&self, ns: u64) {
        match ns.checked_sub(self.low_ns) {
            None => bump(&self.below),
            Some(offset) => match self.buckets.get((offset / BUCKET_NS) as usize) {
                Some(bucket) => bump(bucket),
                None => bump(&self.above),
            },
        }
        if ns < self.min_ns.load(Relaxed) {
            self.min_ns.store(ns, Relaxed);
        }
        if ns > self.max_ns.load(Relaxed) {
            self.max_ns.store(ns, Relaxed);
        }
        self.sum_ns.store(self.sum_ns.load(Relaxed).wrapping_add(ns), Relaxed);
    }

    /// The counts as a reader sees them: below, the 1 µs buckets, above.
    fn counts(&self) -> Vec<u64> {
        std::iter::once(&self.below)
            .chain(self.buckets.iter())
            .chain(std::iter::once(&self.above))
            .map(|c| u64::from(c.load(Relaxed)))
            .collect()
    }

    /// The upper edge of the bucket at `index` in [`counts`](Self::counts) order; the "above"
    /// bucket has none (`u64::MAX`, clamped to the maximum by the caller).
    fn upper_edge(&self, index: usize) -> u64 {
        if index > BUCKETS {
            u64::MAX
        } else {
            self.low_ns + index as u64 * BUCKET_NS
        }
    }

    /// The smallest value that at least `ppm` parts per million of the samples do not exceed
    /// (990_000 for the 99th percentile), as the upper edge of its bucket, never above the
    /// maximum; `None` before any sample.
    pub fn percentile(&self, ppm: u32) -> Option<u64> {
        self.percentile_of(&self.counts(), ppm)
    }

    fn percentile_of(&self, counts: &[u64], ppm: u32) -> Option<u64> {
        let total: u64 = counts.iter().sum();
        if total == 0 {
            return None;
        }
        // Integer arithmetic: 0.99 * 100 in floating point is just above 99.
        let rank = (total * u64::from(ppm.min(1_000_000))).div_ceil(1_000_000).max(1);
        let mut seen = 0;
        let index = counts.iter().position(|&c| {
            seen += c;
            seen >= rank
        })?;
        Some(self.upper_edge(index).min(self.max_ns.load(Relaxed)))
    }

    /// Count, min, mean, p99 and max.
    pub fn summary(&self) -> Summary {
        let counts = self.counts();
        let count: u64 = counts.iter().sum();
        if count == 0 {
            return Summary::default();
        }
        Summary {
            count,
            min_ns: self.min_ns.load(Relaxed),
            mean_ns: self.sum_ns.load(Relaxed) / count,
            p99_ns: self.percentile_of(&counts, 990_000).unwrap_or(0),
            max_ns: self.max_ns.load(Relaxed),
        }
    }

    /// The non-empty buckets as (upper edge in ns, count); the bucket above the range has the
    /// maximum as its edge.
    pub fn buckets(&self) -> Vec<(u64, u64)> {
        let max = self.max_ns.load(Relaxed);
        self.counts()
            .into_iter()
            .enumerate()
            .filter(|&(_, c)| c > 0)
            .map(|(i, c)| (self.upper_edge(i).min(max.max(self.low_ns)), c))
            .collect()
    }
}

/// The cycle thread's counters and histograms.
#[derive(Default)]
pub struct CycleStats {
    /// Time from one cycle's wake-up to the next's: the period as it really was.
    pub period: Histogram,
    /// How late the thread woke after its deadline (what `cyclictest` calls latency).
    pub wake_latency: Histogram,
    /// Time the exchange of the process image took (frame out and back).
    pub exchange: Histogram,
    /// Cycles run.
    pub cycles: AtomicU64,
    /// Deadlines missed because a cycle ended after the next one.
    pub overruns: AtomicU64,
    /// Stalls: cyclic frames that went out 8.5 periods or more after the one before while a
    /// drive was enabled, long enough for a real AKD to raise F125 (more than seven frames
    /// missed). A real drive faults on each; a virtual one judging missed frames by `warn`
    /// goes on.
    pub f125_stalls: AtomicU64,
    /// Cyclic frames (the process data) that did not come back (the master's count, since the
    /// thread started).
    pub lost_frames: AtomicU64,
    /// Cyclic frames that came back with a wrong working counter (the master's count, since
    /// the thread started): the process data's, and a second frame's of a cycle that read
    /// each slave apart (see `watch_frames`) in which a slave did not answer.
    pub wkc_errors: AtomicU64,
    /// Cycles that sent a second frame to read each slave, their broadcast supervision reads
    /// having seen a change (the master's count, since the thread started).
    pub watch_frames: AtomicU64,
    /// Frames the thread sent beside the process data (mailbox: SDO, EoE, emergencies; a
    /// recovery's relayed frames) that did not come back: counted apart, a mailbox frame lost is
    /// sent again and costs no process data.
    pub acyclic_lost_frames: AtomicU64,
    /// Wrong working counters of the register accesses beside the process data.
    pub acyclic_wkc_errors: AtomicU64,
    /// Frames counted lost above, cyclic or beside, that came back after all, after their
    /// time-out: a slow line or slave (or simulator), told apart from frames that never did.
    pub late_returns: AtomicU64,
    /// Cycles whose exchange failed otherwise (a malformed reply, a link error).
    pub other_errors: AtomicU64,
    /// Cycles that went out with the previous cycle's set-points because a writer was
    /// writing new ones at that moment.
    pub setpoints_busy: AtomicU64,
}

impl CycleStats {
    /// Empty statistics for a cycle of `period_ns`.
    pub fn new(period_ns: u64) -> Self {
        CycleStats { period: Histogram::around(period_ns), ..CycleStats::default() }
    }

    /// Adds `n` to a counter (cycle thread only).
    pub fn add(counter: &AtomicU64, n: u64) {
        counter.store(counter.load(Relaxed) + n, Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summary_of_known_samples() {
        let h = Histogram::new(0);
        // 0.5, 1.5, .. 99.5 µs, each once: the 99th sample is 98.5 µs, in the 98..99 µs bucket.
        for us in 1..=100u64 {
            h.record(us * 1000 - 500);
        }
        let s = h.summary();
        assert_eq!(s, Summary { count: 100, min_ns: 500, mean_ns: 50_000, p99_ns: 99_000, max_ns: 99_500 });
        assert_eq!(h.percentile(500_000), Some(50_000));
        assert_eq!(h.percentile(0), Some(1000));
        assert_eq!(h.percentile(1_000_000), Some(99_500), "the last bucket's edge is clamped to the maximum");
    }

    #[test]
    fn percentile_is_the_upper_edge_of_its_bucket_but_never_above_the_max() {
        let h = Histogram::new(0);
        h.record(1_200);
        h.record(1_300);
        // Both in the 1..2 µs bucket: its edge is 2 µs, but nothing was above 1.3 µs.
        assert_eq!(h.percentile(990_000), Some(1_300));
        h.record(5_500);
        assert_eq!(h.percentile(500_000), Some(2_000));
    }

    #[test]
    fn outliers_land_below_and_above_and_keep_exact_extremes() {
        let h = Histogram::around(5_000_000);
        for _ in 0..98 {
            h.record(5_000_400);
        }
        h.record(10); // far below the range
        h.record(50_000_000); // far above it
        let s = h.summary();
        assert_eq!((s.count, s.min_ns, s.max_ns), (100, 10, 50_000_000));
        assert_eq!(s.p99_ns, 5_001_000);
        assert_eq!(h.percentile(1_000_000), Some(50_000_000));
        assert_eq!(h.percentile(10_000), Some(h.low_ns), "the bucket below has the range's start as edge");
        let buckets = h.buckets();
        assert_eq!(buckets, vec![(h.low_ns, 1), (5_001_000, 98), (50_000_000, 1)]);
    }

    #[test]
    fn empty_histogram_has_no_percentile() {
        let h = Histogram::new(0);
        assert_eq!(h.percentile(990_000), None);
        assert_eq!(h.summary(), Summary::default());
        assert!(h.buckets().is_empty());
    }
}
