//! Fault supervision in the cycle thread: what makes a fault event and what the loop does
//! about it. A drive entering Fault waits for its 0x603F (read beside the cycle) before its
//! event goes out; a slave leaving Op, and lost frames or wrong working counters while a drive
//! is enabled, are judged here. Nothing is retried into motion: where the loop acts, it asks
//! the drive for Switch on disabled, and the sequencer holds the target at the actual
//! position from then on.

use crate::cycle::events::{Action, Event, FaultSource};
use crate::drive::akd_fault;
use crate::ethercat::al::AlState;
use crate::ethercat::master::state::AlStatus;

/// Frames in a row the AKD misses before it raises F125 (more than seven, §7): a gap that
/// long is handled as the loss of the drive, not as a gap.
pub const DRIVE_MISSED_FRAME_LIMIT: u32 = 8;

/// Whether the time between two cyclic frames, `gap_ns` at a period of `period_ns`, is a stall
/// that makes an enabled AKD raise F125 (more than seven frames missed,
/// [`akd_fault::raises_f125`]): a real drive faults on it; a virtual one judging missed frames
/// by `warn` counts it and goes on. The cycle counts these stalls while a drive is `enabled`.
pub fn stall_raises_f125(gap_ns: u64, period_ns: u64, enabled: bool) -> bool {
    enabled && akd_fault::raises_f125(gap_ns, period_ns)
}

/// A gap in the exchange: lost frames, or wrong working counters, in a row.
#[derive(Clone, Copy, Debug)]
struct Gap {
    source: FaultSource,
    length: u32,
    began: (u64, u64),
    /// Whether it reached the drive's limit and was reported then.
    reported: bool,
}

/// How the cycle went, as far as the bus is concerned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Exchange {
    /// The frame came back with the right working counter.
    Good,
    /// The frame was lost.
    Lost,
    /// The frame came back with a wrong working counter.
    WrongWkc,
}

/// A gap to report, for each enabled drive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GapReport {
    /// Lost frames or working counter.
    pub source: FaultSource,
    /// Cycles in the gap.
    pub length: u32,
    /// Cycle and time the gap began.
    pub began: (u64, u64),
    /// What is done about it: counted when it ended short, disabled at the drive's limit.
    pub action: Action,
}

/// The gap under way, if any. A gap opens only while a drive is enabled: without one, a lost
/// frame moves nothing and is only counted in the statistics.
#[derive(Clone, Copy, Debug, Default)]
pub struct Gaps {
    gap: Option<Gap>,
}

impl Gaps {
    /// Takes one cycle's outcome; returns a report when a gap ends (or turns into the other
    /// kind) short of the limit, or when it reaches the drive's limit.
    pub fn observe(&mut self, exchange: Exchange, enabled: bool, now: (u64, u64)) -> Option<GapReport> {
        let source = match exchange {
            Exchange::Good => None,
            Exchange::Lost => Some(FaultSource::LostFrames),
            Exchange::WrongWkc => Some(FaultSource::WorkingCounter),
        };
        let report = |g: &Gap, action| GapReport { source: g.source, length: g.length, began: g.began, action };
        let mut ended = None;
        if let Some(gap) = self.gap.filter(|g| Some(g.source) != source) {
            ended = (!gap.reported).then(|| report(&gap, Action::Counted));
            self.gap = None;
        }
        let Some(source) = source else { return ended };
        if self.gap.is_none() && enabled {
            self.gap = Some(Gap { source, length: 0, began: now, reported: false });
        }
        if let Some(gap) = self.gap.as_mut() {
            gap.length += 1;
            if gap.length == DRIVE_MISSED_FRAME_LIMIT {
                gap.reported = true;
                return Some(report(gap, Action::Disabled));
            }
        }
        ended
    }
}

/// One drive's watch: what it was last cycle.
#[derive(Clone, Copy, Debug, Default)]
pub struct DriveWatch {
    in_fault: bool,
    in_op: bool,
}

/// What a drive's watch saw this cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WatchEvents {
    /// The drive entered Fault (its event waits for 0x603F).
    pub fault: Option<Event>,
    /// The slave left Op.
    pub left_op: Option<Event>,
}

impl DriveWatch {
    /// Judges one cycle of a drive: its statusword (when it came), and its AL status (when
    /// read). `sequenced` says whether a request is in force, i.e. whether the sequencer
    /// reacts to a fault by disabling.
    pub fn observe(
        &mut self,
        slave: u16,
        statusword: Option<u16>,
        al_status: Option<AlStatus>,
        sequenced: bool,
        (cycle, time_ns): (u64, u64),
    ) -> WatchEvents {
        let mut seen = WatchEvents::default();
        let event = |source, code, statusword, action| {
            Event::fault((cycle, time_ns), slave, statusword, al_status, (source, code, action))
        };
        if let Some(s) = statusword {
            let in_fault = s & crate::drive::ds402::statusword::FAULT != 0;
            if in_fault && !self.in_fault {
                let action = if sequenced { Action::Disabled } else { Action::Reported };
                seen.fault = Some(event(FaultSource::DriveFault, 0, s, action));
            }
            self.in_fault = in_fault;
        }
        if let Some(a) = al_status {
            let in_op = a.state() == Some(AlState::Op) && !a.error();
            if self.in_op && !in_op {
                seen.left_op = Some(event(FaultSource::AlState, 0, statusword.unwrap_or(0), Action::Disabled));
            }
            self.in_op = in_op;
        }
        seen
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_short_gap_is_counted_once_and_a_long_one_disables_at_the_limit() {
        let mut gaps = Gaps::default();
        assert_eq!(gaps.observe(Exchange::Good, true, (1, 10)), None);
        for n in 0..3 {
            assert_eq!(gaps.observe(Exchange::Lost, true, (2 + n, 20)), None);
        }
        let ended = gaps.observe(Exchange::Good, true, (5, 50)).unwrap();
        assert_eq!((ended.source, ended.length, ended.action), (FaultSource::LostFrames, 3, Action::Counted));
        assert_eq!(ended.began, (2, 20));
        let mut reports = Vec::new();
        for n in 0..12 {
            reports.extend(gaps.observe(Exchange::WrongWkc, true, (10 + n, 0)));
        }
        reports.extend(gaps.observe(Exchange::Good, true, (30, 0)));
        assert_eq!(reports.len(), 1, "{reports:?}");
        assert_eq!(
            (reports[0].source, reports[0].length, reports[0].action),
            (FaultSource::WorkingCounter, 8, Action::Disabled)
        );
        // With no drive enabled, a gap is not a fault.
        assert_eq!(gaps.observe(Exchange::Lost, false, (40, 0)), None);
        assert_eq!(gaps.observe(Exchange::Good, false, (41, 0)), None);
    }

    #[test]
    fn a_stall_of_eight_and_a_half_periods_with_a_drive_enabled_would_raise_f125() {
        let ms = 1_000_000;
        assert!(!stall_raises_f125(8_499_999, ms, true));
        assert!(stall_raises_f125(8_500_000, ms, true));
        assert!(!stall_raises_f125(100 * ms, ms, false), "nothing enabled, nothing to fault");
        assert!(stall_raises_f125(2_125_000, 250_000, true));
    }

    #[test]
    fn a_fault_and_a_drop_out_of_op_are_seen_once() {
        let mut watch = DriveWatch::default();
        let op = AlStatus { status: 0x08, code: 0 };
        assert_eq!(watch.observe(0, Some(0x0237), Some(op), true, (1, 1)), WatchEvents::default());
        let seen = watch.observe(0, Some(0x0218), Some(op), true, (2, 2));
        assert!(matches!(
            seen.fault,
            Some(Event::Fault { source: FaultSource::DriveFault, action: Action::Disabled, .. })
        ));
        assert_eq!(watch.observe(0, Some(0x0218), Some(op), true, (3, 3)), WatchEvents::default());
        let safeop = AlStatus { status: 0x14, code: 0x001B };
        let seen = watch.observe(0, Some(0x0218), Some(safeop), true, (4, 4));
        assert!(matches!(seen.left_op, Some(Event::Fault { al_status: 0x14, al_status_code: 0x001B, .. })));
        assert_eq!(watch.observe(0, Some(0x0218), Some(safeop), true, (5, 5)), WatchEvents::default());
    }
}
