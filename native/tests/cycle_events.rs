//! Fault and latch events of the cycle thread against a virtual AKD behind a link that the
//! test can make lose frames: a gap long enough for the drive's F125 is reported by the
//! master as lost frames (the eighth disables the drive), then as the drive's fault with its
//! 0x603F code read beside the cycle, and the drive falling out of Op as an AL state event.
//! Every test runs twice: with the cycle waiting for each frame's return, and pipelined. The
//! waits have deadlines only so that a failure does not hang; no timing is asserted.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use akd_native::cycle::events::{Action, Event, FaultSource};
use akd_native::cycle::{Config, CycleThread, RealTime};
use akd_native::drive::ds402::State;
use akd_native::error::Result;
use akd_native::ethercat::al::AlState;
use akd_native::ethercat::frame::{self, Command, FrameBuilder};
use akd_native::ethercat::link::{is_reply_to, Link};
use akd_native::ethercat::registers::AL_CONTROL;
use akd_native::sim::control::{Change, SimControl};
use akd_native::sim::in_process::InProcess;

#[path = "support/csp.rs"]
mod csp;
use csp::csp_master;

/// The in-process link, losing the next `drop` frames (the frame never reaches the drives)
/// and the next `drop_mailbox` frames beside the cyclic LRW, holding back the return of the
/// next `late_mailbox_writes` writes to the mailbox (SM0 at 0x1800; the drive takes the
/// message) until after the next frame, as a return later than the master's time-out, and
/// likewise the returns of `stall_at_mailbox_read` frames from the next read of SM1 (0x1C00)
/// on, as from a simulator stalled meanwhile, and,
/// when `to_safeop` is set, slipping the drive an AL control write to SafeOp once — a drive
/// leaving Op by itself, as far as the master can tell.
struct Lossy {
    inner: InProcess,
    drop: Arc<AtomicU32>,
    drop_mailbox: Arc<AtomicU32>,
    late_mailbox_writes: Arc<AtomicU32>,
    stall_at_mailbox_read: Arc<AtomicU32>,
    to_safeop: Arc<AtomicU32>,
    /// Frames still to come back late in the stall under way.
    stalled: u32,
    /// Returns held back, each with whether the frame after it was sent (then it comes first).
    late: VecDeque<(Vec<u8>, bool)>,
    /// Returns taken from the link before the one held back, received first.
    early: VecDeque<Vec<u8>>,
}

impl Link for Lossy {
    fn send(&mut self, tx: &[u8]) -> Result<()> {
        if self.to_safeop.swap(0, Ordering::AcqRel) > 0 {
            let mut frame = [0u8; 64];
            let mut builder = FrameBuilder::new(&mut frame);
            builder.push(Command::Apwr, 0, 0, AL_CONTROL, &(AlState::SafeOp as u16).to_le_bytes()).unwrap();
            let len = builder.finish();
            let mut reply = [0u8; 64];
            self.inner.exchange(&frame[..len], &mut reply, Duration::ZERO)?;
        }
        let cyclic = tx.get(2) == Some(&(Command::Lrw as u8));
        let lose =
            |count: &AtomicU32| count.fetch_update(Ordering::AcqRel, Ordering::Acquire, |n| n.checked_sub(1)).is_ok();
        if lose(&self.drop) || (!cyclic && lose(&self.drop_mailbox)) {
            return Ok(());
        }
        self.late.iter_mut().for_each(|(_, after)| *after = true);
        self.inner.send(tx)?;
        let first = frame::parse(tx)?.next().expect("one datagram")?.header;
        if (first.command, first.ado) == (Command::Fprd, 0x1C00) {
            self.stalled += self.stall_at_mailbox_read.swap(0, Ordering::AcqRel);
        }
        let stalled = self.stalled.checked_sub(1).inspect(|n| self.stalled = *n).is_some();
        if stalled || (first.command, first.ado) == (Command::Fpwr, 0x1800) && lose(&self.late_mailbox_writes) {
            // Served at once; a pipelined cycle's frame may be waiting to be received before it.
            loop {
                let mut back = vec![0; frame::MAX_PAYLOAD_LEN];
                let n = self.inner.receive(&mut back, Instant::now())?.expect("served at once");
                back.truncate(n);
                if is_reply_to(tx, &back) {
                    self.late.push_back((back, false));
                    break;
                }
                self.early.push_back(back);
            }
        }
        Ok(())
    }

    fn receive(&mut self, rx: &mut [u8], deadline: Instant) -> Result<Option<usize>> {
        let late = || self.late.pop_front_if(|(_, after)| *after).map(|(back, _)| back);
        if let Some(back) = self.early.pop_front().or_else(late) {
            rx[..back.len()].copy_from_slice(&back);
            return Ok(Some(back.len()));
        }
        self.inner.receive(rx, deadline)
    }

    fn describe(&self) -> String {
        "lossy sim".into()
    }
}

struct Rig {
    cycle: CycleThread,
    drop: Arc<AtomicU32>,
    drop_mailbox: Arc<AtomicU32>,
    late_mailbox_writes: Arc<AtomicU32>,
    stall_at_mailbox_read: Arc<AtomicU32>,
    to_safeop: Arc<AtomicU32>,
    control: SimControl,
}

fn rig(pipelined: bool) -> Rig {
    let (drop, drop_mailbox, late_mailbox_writes, stall_at_mailbox_read, to_safeop) = Default::default();
    let inner = InProcess::new(1);
    let control = inner.control();
    let link = Lossy {
        inner,
        drop: Arc::clone(&drop),
        drop_mailbox: Arc::clone(&drop_mailbox),
        late_mailbox_writes: Arc::clone(&late_mailbox_writes),
        stall_at_mailbox_read: Arc::clone(&stall_at_mailbox_read),
        to_safeop: Arc::clone(&to_safeop),
        stalled: 0,
        late: VecDeque::new(),
        early: VecDeque::new(),
    };
    let config =
        Config { realtime: RealTime { pipelined, ..RealTime::default() }, ..Config::new(Duration::from_millis(1)) };
    let cycle = CycleThread::start(csp_master(Box::new(link)), config).map_err(|e| e.0).unwrap();
    Rig { cycle, drop, drop_mailbox, late_mailbox_writes, stall_at_mailbox_read, to_safeop, control }
}

fn enable(cycle: &CycleThread) {
    cycle.request(0, akd_native::cycle::sequencer::Request::Enable).unwrap();
    let deadline = Instant::now() + Duration::from_secs(10);
    while cycle.drive_status(0).unwrap().state() != Some(State::OperationEnabled) {
        assert!(Instant::now() < deadline, "not enabled: {:?}", cycle.drive_status(0).unwrap());
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Collects events until `done` holds for the ones so far.
fn events_until(cycle: &CycleThread, done: impl Fn(&[Event]) -> bool) -> Vec<Event> {
    let deadline = Instant::now() + Duration::from_secs(10);
    let mut events = Vec::new();
    while !done(&events) {
        assert!(Instant::now() < deadline, "events so far: {events:?}");
        events.extend(cycle.events());
        std::thread::sleep(Duration::from_millis(1));
    }
    events
}

fn source(e: &Event) -> Option<FaultSource> {
    match e {
        Event::Fault { source, .. } => Some(*source),
        Event::Latch { .. }
        | Event::CommandTimeout { .. }
        | Event::Trajectory { .. }
        | Event::Inputs { .. }
        | Event::DeviceInputs { .. } => None,
    }
}

fn a_short_gap_is_counted_and_the_drive_stays_enabled(pipelined: bool) {
    let Rig { cycle, drop, .. } = rig(pipelined);
    enable(&cycle);
    drop.store(3, Ordering::Release);
    let events = events_until(&cycle, |e| !e.is_empty());
    match events[0] {
        Event::Fault { source: FaultSource::LostFrames, code: 3, action: Action::Counted, .. } => {}
        other => panic!("{other:?}"),
    }
    std::thread::sleep(Duration::from_millis(50));
    assert_eq!(cycle.drive_status(0).unwrap().state(), Some(State::OperationEnabled));
    assert!(cycle.events().is_empty());
}

fn f125_after_the_eighth_lost_frame_is_reported_with_its_code_and_the_drive_disabled(pipelined: bool) {
    let Rig { cycle, drop, .. } = rig(pipelined);
    enable(&cycle);
    // The AKD keeps its AL state through a gap (its SII asks for no process-data watchdog)
    // and raises F125 instead.
    drop.store(100, Ordering::Release);
    let events = events_until(&cycle, |e| {
        e.iter().any(|e| source(e) == Some(FaultSource::DriveFault))
            && e.iter().any(|e| source(e) == Some(FaultSource::Emergency))
    });
    let lost = events.iter().find(|e| source(e) == Some(FaultSource::LostFrames)).unwrap();
    assert!(matches!(lost, Event::Fault { code: 8, action: Action::Disabled, .. }), "{lost:?}");
    let fault = events.iter().find(|e| source(e) == Some(FaultSource::DriveFault)).unwrap();
    assert!(matches!(fault, Event::Fault { code: 0x8700, .. }), "F125's code from 0x603F: {fault:?}");
    let emergency = events.iter().find(|e| source(e) == Some(FaultSource::Emergency)).unwrap();
    assert!(matches!(emergency, Event::Fault { code: 0x8700, action: Action::Reported, .. }), "{emergency:?}");
    // The eighth frame's event comes once: the rest of the gap adds none.
    assert_eq!(events.iter().filter(|e| source(e) == Some(FaultSource::LostFrames)).count(), 1, "{events:?}");
    // Nothing is retried into motion: the drive stays out of Operation enabled.
    std::thread::sleep(Duration::from_millis(50));
    assert_ne!(cycle.drive_status(0).unwrap().state(), Some(State::OperationEnabled));
}

fn a_drive_leaving_op_is_reported_with_its_al_status_and_disabled(pipelined: bool) {
    let Rig { cycle, to_safeop, .. } = rig(pipelined);
    enable(&cycle);
    to_safeop.store(1, Ordering::Release);
    let events = events_until(&cycle, |e| e.iter().any(|e| source(e) == Some(FaultSource::AlState)));
    let al = events.iter().find(|e| source(e) == Some(FaultSource::AlState)).unwrap();
    match al {
        Event::Fault { al_status, action: Action::Disabled, .. } => {
            assert_eq!(al_status & 0x0F, AlState::SafeOp as u16, "{al:?}")
        }
        other => panic!("{other:?}"),
    }
    let deadline = Instant::now() + Duration::from_secs(10);
    while cycle.drive_status(0).unwrap().request != Some(akd_native::cycle::sequencer::Request::Disable) {
        assert!(Instant::now() < deadline, "{:?}", cycle.drive_status(0).unwrap());
        std::thread::sleep(Duration::from_millis(1));
    }
}

fn sdo_beside_the_cycle_reads_writes_and_names_aborts(pipelined: bool) {
    let Rig { cycle, .. } = rig(pipelined);
    assert_eq!(cycle.sdo_read(0, 0x1018, 1).unwrap(), 0x6Au32.to_le_bytes());
    cycle.sdo_write(0, 0x6083, 0, &5000u32.to_le_bytes()).unwrap();
    assert_eq!(cycle.sdo_read(0, 0x6083, 0).unwrap(), 5000u32.to_le_bytes());
    let e = cycle.sdo_read(0, 0x7777, 0).unwrap_err().to_string();
    assert!(e.contains("0x06020000"), "{e}");
    let e = cycle.sdo_write(0, 0x1018, 1, &[1, 0, 0, 0]).unwrap_err().to_string();
    assert!(e.contains("0x06010002"), "{e}");
    assert!(cycle.sdo_read(3, 0x1018, 1).is_err());
    let stats = cycle.stats();
    assert_eq!(stats.lost_frames.load(Ordering::Relaxed), 0);
}

fn a_lost_mailbox_frame_is_counted_apart_from_a_lost_cyclic_frame(pipelined: bool) {
    let Rig { cycle, drop, drop_mailbox, .. } = rig(pipelined);
    drop_mailbox.store(1, Ordering::Release);
    // The transfer goes on after its lost frame: sent again, or its reply fetched again.
    assert_eq!(cycle.sdo_read(0, 0x1018, 1).unwrap(), 0x6Au32.to_le_bytes());
    let stats = cycle.stats();
    assert_eq!(drop_mailbox.load(Ordering::Acquire), 0);
    assert_eq!(stats.lost_frames.load(Ordering::Relaxed), 0, "no process-data frame was lost");
    assert_eq!(stats.acyclic_lost_frames.load(Ordering::Relaxed), 1);
    drop.store(1, Ordering::Release);
    let deadline = Instant::now() + Duration::from_secs(10);
    while stats.lost_frames.load(Ordering::Relaxed) == 0 {
        assert!(Instant::now() < deadline, "the cyclic frame's loss not counted");
        std::thread::sleep(Duration::from_millis(1));
    }
    assert_eq!(stats.lost_frames.load(Ordering::Relaxed), 1);
    assert_eq!(stats.acyclic_lost_frames.load(Ordering::Relaxed), 1);
}

fn a_transfer_whose_request_came_back_late_is_answered(pipelined: bool) {
    let Rig { cycle, late_mailbox_writes, .. } = rig(pipelined);
    late_mailbox_writes.store(3, Ordering::Release);
    // The drive took the request though its frame came back after the master stopped waiting
    // (a long line, a busy simulator), and so did the request written again in the next
    // cycles, until its answer shows in SM1: the answer, with the request's counter, ends the
    // transfer; the writes after the first are repeats (same counter) the drive rightly ignores.
    cycle.sdo_write(0, 0x6060, 0, &[8]).unwrap();
    assert_eq!(cycle.sdo_read(0, 0x6060, 0).unwrap(), [8]);
    // Each late return counted as a lost frame beside the cycle (the read may have met some).
    let stats = cycle.stats();
    let late = 3 - u64::from(late_mailbox_writes.load(Ordering::Acquire));
    assert!(late >= 2, "only {late} late");
    assert_eq!(stats.acyclic_lost_frames.load(Ordering::Relaxed), late);
    assert_eq!(stats.lost_frames.load(Ordering::Relaxed), 0);
    // Each came back after all, later: told apart from a frame that never does.
    // The cycle's count follows the master's at the end of each cycle.
    let deadline = Instant::now() + Duration::from_secs(5);
    while stats.late_returns.load(Ordering::Relaxed) != late {
        assert!(Instant::now() < deadline, "the cycle's late_returns never reached {late}");
        std::thread::sleep(Duration::from_millis(1));
    }
    assert_eq!(cycle.stop().unwrap().stats().late_returns, late);
}

fn an_answer_whose_read_came_back_late_is_fetched_again(pipelined: bool) {
    let Rig { cycle, stall_at_mailbox_read, .. } = rig(pipelined);
    // The read of the answer empties SM1 though its return comes late, and so do the frames
    // after it for a while (a stalled simulator): the repeat request that puts the answer back
    // is made once frames come back, not given up with the first frames it took.
    stall_at_mailbox_read.store(6, Ordering::Release);
    assert_eq!(cycle.sdo_read(0, 0x1018, 1).unwrap(), 0x6Au32.to_le_bytes());
    assert_eq!(stall_at_mailbox_read.load(Ordering::Acquire), 0);
    assert_eq!(cycle.sdo_read(0, 0x1018, 2).unwrap(), 0x0041_4B44u32.to_le_bytes());
}

fn a_stale_cycle_records_whether_its_frame_was_lost_or_came_back_with_a_wrong_working_counter(pipelined: bool) {
    let Rig { cycle, drop, control, .. } = rig(pipelined);
    let stats = cycle.stats();
    let wait_for = |what: &str, counter: &std::sync::atomic::AtomicU64| {
        let deadline = Instant::now() + Duration::from_secs(10);
        while counter.load(Ordering::Relaxed) == 0 {
            assert!(Instant::now() < deadline, "{what} not counted");
            std::thread::sleep(Duration::from_millis(1));
        }
    };
    drop.store(1, Ordering::Release);
    wait_for("the lost frame", &stats.lost_frames);
    // The only drive power-cycled has lost its FMMUs: the frame comes back, no slave took its
    // LRW, working counter 0, as a lost frame's record has it.
    control.change(Change::power_cycle(control.products(), 0)).unwrap();
    wait_for("the wrong working counter", &stats.wkc_errors);
    cycle.stop().unwrap();
    let samples = cycle.samples();
    assert_eq!(cycle.samples_dropped(), 0);
    let lost = samples.iter().filter(|s| s.lost).count() as u64;
    let wrong_wkc = samples.iter().filter(|s| !s.fresh && !s.lost).count() as u64;
    assert!(samples.iter().all(|s| !(s.fresh && s.lost)));
    assert!(samples.iter().any(|s| !s.fresh && !s.lost && s.wkc == 0), "no wrong working counter of 0 recorded");
    let counted = |c: &std::sync::atomic::AtomicU64| c.load(Ordering::Relaxed);
    // One slave: its AL and mailbox status are read in the cyclic frame, never in a second one.
    assert_eq!(counted(&stats.watch_frames), 0);
    assert_eq!(
        (lost, wrong_wkc),
        (counted(&stats.lost_frames) + counted(&stats.other_errors), counted(&stats.wkc_errors))
    );
}

/// Every test twice: with the cycle waiting for each frame's return, and pipelined (the return
/// taken at the next wake-up).
macro_rules! both_ways {
    ($($name:ident),* $(,)?) => {
        mod waiting {
            $(#[test]
            fn $name() {
                super::$name(false)
            })*
        }
        mod pipelined {
            $(#[test]
            fn $name() {
                super::$name(true)
            })*
        }
    };
}

both_ways!(
    a_short_gap_is_counted_and_the_drive_stays_enabled,
    f125_after_the_eighth_lost_frame_is_reported_with_its_code_and_the_drive_disabled,
    a_drive_leaving_op_is_reported_with_its_al_status_and_disabled,
    sdo_beside_the_cycle_reads_writes_and_names_aborts,
    a_lost_mailbox_frame_is_counted_apart_from_a_lost_cyclic_frame,
    a_transfer_whose_request_came_back_late_is_answered,
    an_answer_whose_read_came_back_late_is_fetched_again,
    a_stale_cycle_records_whether_its_frame_was_lost_or_came_back_with_a_wrong_working_counter
);
