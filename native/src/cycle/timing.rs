//! Cycle timing: the period's allowed range, the monotonic clock in nanoseconds, sleeping to
//! an absolute deadline, and the schedule of deadlines.
//!
//! Deadlines are absolute (`clock_nanosleep` with `TIMER_ABSTIME` on `CLOCK_MONOTONIC`) so that
//! the time spent in a cycle and the sleep's own latency never add up into drift: deadline `n`
//! is always `start + n * period`. A cycle that ends after its next deadline is an overrun; the
//! schedule then skips the deadlines already past instead of running a burst of late cycles.

use std::time::Duration;

use crate::error::{Result, SettingError};

/// The shortest period: the AKD's minimum cycle time.
pub const MIN_PERIOD: Duration = Duration::from_micros(250);
/// The longest period.
pub const MAX_PERIOD: Duration = Duration::from_millis(10);

/// Checks a cycle period against [`MIN_PERIOD`]..=[`MAX_PERIOD`] and returns it in nanoseconds.
pub fn period_ns(period: Duration) -> Result<u64> {
    if (MIN_PERIOD..=MAX_PERIOD).contains(&period) {
        Ok(period.as_nanos() as u64)
    } else {
        Err(SettingError::CyclePeriod { period_us: period.as_nanos() as f64 / 1000.0 }.into())
    }
}

/// Now on the monotonic clock, in nanoseconds.
pub fn now_ns() -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // CLOCK_MONOTONIC always exists on Linux and `ts` is valid: this cannot fail.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// A monotonic time in nanoseconds as a `timespec`.
fn timespec(ns: u64) -> libc::timespec {
    libc::timespec { tv_sec: (ns / 1_000_000_000) as libc::time_t, tv_nsec: (ns % 1_000_000_000) as libc::c_long }
}

/// Sleeps until the monotonic clock reaches `deadline_ns` (at once when it already has).
pub fn sleep_until(deadline_ns: u64) {
    let ts = timespec(deadline_ns);
    // A signal interrupts the sleep with EINTR; the deadline is absolute, so sleep again.
    while unsafe { libc::clock_nanosleep(libc::CLOCK_MONOTONIC, libc::TIMER_ABSTIME, &ts, std::ptr::null_mut()) }
        == libc::EINTR
    {}
}

/// The deadlines of a cycle: `first + n * period`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Schedule {
    next_ns: u64,
    period_ns: u64,
}

impl Schedule {
    /// Deadlines from `first_ns` every `period_ns`.
    pub fn new(first_ns: u64, period_ns: u64) -> Self {
        Schedule { next_ns: first_ns, period_ns }
    }

    /// The next deadline.
    pub fn next_ns(&self) -> u64 {
        self.next_ns
    }

    /// Moves to the deadline after the current one, at `now_ns` when the cycle ends. Returns
    /// how many deadlines were missed: 0 when the next one is still ahead; otherwise the
    /// deadlines already past are skipped (each one a missed cycle) so the schedule stays on
    /// its grid and the next cycle starts at the first deadline not yet past.
    pub fn advance(&mut self, now_ns: u64) -> u64 {
        self.next_ns += self.period_ns;
        if now_ns < self.next_ns {
            return 0;
        }
        let missed = (now_ns - self.next_ns) / self.period_ns + 1;
        self.next_ns += missed * self.period_ns;
        missed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn period_range_is_250_us_to_10_ms() {
        assert_eq!(period_ns(Duration::from_micros(250)).unwrap(), 250_000);
        assert_eq!(period_ns(Duration::from_millis(10)).unwrap(), 10_000_000);
        for bad in [Duration::from_micros(249), Duration::from_micros(10_001), Duration::ZERO] {
            let message = period_ns(bad).unwrap_err().to_string();
            assert!(message.contains("250 µs ..= 10000 µs"), "{message}");
        }
    }

    #[test]
    fn timespec_splits_seconds_and_nanoseconds() {
        let ts = timespec(3_000_000_007);
        assert_eq!((ts.tv_sec, ts.tv_nsec), (3, 7));
    }

    #[test]
    fn schedule_stays_on_its_grid() {
        let mut s = Schedule::new(1_000, 100);
        // On time: the next deadline is one period on, whatever the cycle's length.
        assert_eq!(s.advance(1_050), 0);
        assert_eq!(s.next_ns(), 1_100);
        assert_eq!(s.advance(1_199), 0);
        assert_eq!(s.next_ns(), 1_200);
        // Ending exactly on the next deadline has missed it.
        assert_eq!(s.advance(1_300), 1);
        assert_eq!(s.next_ns(), 1_400);
        // Ending 2.5 periods late skips the deadlines past; the grid is kept.
        assert_eq!(s.advance(1_750), 3);
        assert_eq!(s.next_ns(), 1_800);
    }

    #[test]
    fn sleep_until_a_past_deadline_returns_and_a_future_one_is_reached() {
        sleep_until(0);
        let deadline = now_ns() + 200_000;
        sleep_until(deadline);
        assert!(now_ns() >= deadline);
    }
}
