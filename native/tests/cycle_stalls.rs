//! A stall of the cycle thread (the host not running it for 30 ms) while the drive is enabled:
//! the cycle counts it as a stall a real AKD would raise F125 for, and the virtual AKD raises
//! F125 when it judges missed frames as the real drive does (`late`), and goes on counting a
//! would-be F125 when told to `warn`. The stall is made inside the link's send, in the cycle
//! thread itself; the waits have deadlines only so that a failure does not hang.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use akd_native::cycle::sequencer::Request;
use akd_native::cycle::CycleThread;
use akd_native::drive::ds402::State;
use akd_native::error::Result;
use akd_native::ethercat::link::Link;
use akd_native::ethercat::link_spec::MissedFrames;
use akd_native::sim::faults::Fault;
use akd_native::sim::{Timing, VirtualBus};

#[path = "support/csp.rs"]
mod csp;
#[path = "support/shared.rs"]
mod shared;
use csp::csp_cycle;
use shared::Shared;

/// How long the host does not run the cycle thread: 30 periods of 1 ms.
const STALL: Duration = Duration::from_millis(30);

/// A link to a virtual bus the test shares, which stalls the thread that sends once when asked.
struct Stalling {
    shared: Shared,
    stall: Arc<AtomicBool>,
}

impl Link for Stalling {
    fn send(&mut self, tx: &[u8]) -> Result<()> {
        if self.stall.swap(false, Ordering::Relaxed) {
            std::thread::sleep(STALL);
        }
        self.shared.send(tx)
    }

    fn receive(&mut self, rx: &mut [u8], deadline: Instant) -> Result<Option<usize>> {
        self.shared.receive(rx, deadline)
    }

    fn describe(&self) -> String {
        "stalling sim".into()
    }
}

/// One enabled drive judging missed frames by `missed`, whose cycle thread then stalls once.
fn stalled(missed: MissedFrames) -> (CycleThread, Arc<Mutex<VirtualBus>>) {
    let bus = Arc::new(Mutex::new(VirtualBus::with_timing(1, Timing { missed_frames: missed, ..Timing::IMMEDIATE })));
    let stall = Arc::new(AtomicBool::new(false));
    let link = Stalling { shared: Shared::new(bus.clone()), stall: stall.clone() };
    let cycle = csp_cycle(Box::new(link));
    cycle.request(0, Request::Enable).unwrap();
    wait(|| cycle.drive_status(0).unwrap().state() == Some(State::OperationEnabled));
    let stalls_before = cycle.stats().f125_stalls.load(Ordering::Relaxed);
    stall.store(true, Ordering::Relaxed);
    wait(|| cycle.stats().f125_stalls.load(Ordering::Relaxed) > stalls_before);
    let later = cycle.snapshot().cycle + 20;
    wait(|| cycle.snapshot().cycle >= later);
    (cycle, bus)
}

fn wait(done: impl Fn() -> bool) {
    let deadline = Instant::now() + Duration::from_secs(10);
    while !done() {
        assert!(Instant::now() < deadline, "timed out");
        std::thread::sleep(Duration::from_millis(2));
    }
}

#[test]
fn a_stall_faults_a_drive_that_judges_missed_frames_as_the_real_one_does() {
    let (cycle, bus) = stalled(MissedFrames::Late);
    assert_eq!(bus.lock().unwrap().slave(0).drive().fault(), Some(Fault::SyncLost));
    wait(|| cycle.drive_status(0).unwrap().state() == Some(State::Fault));
    assert_eq!(bus.lock().unwrap().slave(0).would_be_f125().count, 0, "a real F125, not a would-be one");
    cycle.stop().unwrap();
}

#[test]
fn a_stall_is_counted_and_warned_of_by_a_drive_told_to_warn_and_it_goes_on() {
    let (cycle, bus) = stalled(MissedFrames::Warn);
    let would_be = bus.lock().unwrap().slave(0).would_be_f125();
    assert!(would_be.count >= 1, "{would_be:?}");
    assert!(would_be.longest_ns >= 25_000_000, "the silence the drive saw: {would_be:?}");
    assert_eq!(bus.lock().unwrap().slave(0).drive().fault(), None);
    assert_eq!(cycle.drive_status(0).unwrap().state(), Some(State::OperationEnabled));
    assert!(cycle.stats().period.summary().max_ns >= STALL.as_nanos() as u64);
    cycle.stop().unwrap();
}
