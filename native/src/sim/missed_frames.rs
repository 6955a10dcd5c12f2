//! The firmware's count of missed frames, which raises F125 once it exceeds seven while the
//! drive is enabled, under the judgement the virtual AKD was given
//! ([`MissedFrames`]): by time as the real drive, by frames lost on the line, or by time with
//! the would-be F125 counted instead of raised.

use crate::drive::akd_fault::{self, MISSED_FRAMES_TOLERATED};
use crate::ethercat::link_spec::MissedFrames;

/// The would-be F125 a virtual AKD judging [`MissedFrames::Warn`] counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WouldBeF125 {
    /// How many silences a real AKD would have raised F125 for.
    pub count: u64,
    /// The process data each silence began after, so that one silence counts once.
    counted_after: Option<u64>,
    /// The longest of them, ns.
    pub longest_ns: u64,
    /// The latest of them, as long as it has lasted, ns.
    pub latest_ns: u64,
}

impl WouldBeF125 {
    /// The frames that count as missed at time `t` under `judgement`: `last` is when the last
    /// process data arrived, `frames_lost` how many frames in a row the line lost since.
    pub fn missed(
        &mut self,
        judgement: MissedFrames,
        t: u64,
        last: Option<u64>,
        cycle_ns: u64,
        frames_lost: u64,
    ) -> u64 {
        let late = last.map_or(0, |last| akd_fault::frames_missed(t.saturating_sub(last), cycle_ns));
        match judgement {
            MissedFrames::Late => late,
            MissedFrames::Lost => frames_lost,
            MissedFrames::Warn => {
                if late > MISSED_FRAMES_TOLERATED {
                    if self.counted_after != last {
                        self.count += 1;
                        self.counted_after = last;
                    }
                    self.latest_ns = t.saturating_sub(last.unwrap_or(t));
                    self.longest_ns = self.longest_ns.max(self.latest_ns);
                }
                frames_lost
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;

    #[test]
    fn warn_counts_each_long_silence_once_and_faults_only_on_lost_frames() {
        let mut w = WouldBeF125::default();
        // 8.4 cycles of silence is no F125; 8.5 is, by time.
        assert_eq!(w.missed(MissedFrames::Late, 18_400_000, Some(10 * MS), MS, 0), 7);
        assert_eq!(w.missed(MissedFrames::Late, 18_500_000, Some(10 * MS), MS, 0), 8);
        for t in [18_500_000, 19 * MS, 30 * MS] {
            assert_eq!(w.missed(MissedFrames::Warn, t, Some(10 * MS), MS, 0), 0);
        }
        assert_eq!((w.count, w.longest_ns, w.latest_ns), (1, 20 * MS, 20 * MS));
        assert_eq!(w.missed(MissedFrames::Warn, 60 * MS, Some(40 * MS), MS, 9), 9, "the line's losses count");
        assert_eq!(w.count, 2);
        assert_eq!(w.missed(MissedFrames::Lost, 99 * MS, Some(40 * MS), MS, 3), 3);
    }
}
