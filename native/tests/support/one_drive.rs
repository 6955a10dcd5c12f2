//! One virtual AKD in Op with a given mapping and mode of operation, cycled at 1 kHz, and the
//! handle that controls it; and a wait with a deadline. Its missed frames are judged by frames lost: a cycle this shared
//! host runs late must not fault the drive (F125) under a test of something else.

use std::time::{Duration, Instant};

use akd_native::cycle::{Config, CycleThread};
use akd_native::drive::akd::AkdSlave;
use akd_native::drive::ds402::Mode;
use akd_native::drive::pdo::Mapping;
use akd_native::ethercat::al::AlState;
use akd_native::ethercat::link_spec::MissedFrames;
use akd_native::ethercat::master::Master;
use akd_native::sim::control::SimControl;
use akd_native::sim::in_process::InProcess;
use akd_native::sim::{Timing, VirtualBus};

const STEP: Duration = Duration::from_secs(5);
/// How long a wait may last before the test fails: a bound, not a timing expectation.
const DEADLINE: Duration = Duration::from_secs(10);

/// The first `Some` of `done()`, polled every millisecond; fails naming `what` after DEADLINE.
pub fn wait_until<T>(what: &str, mut done: impl FnMut() -> Option<T>) -> T {
    let deadline = Instant::now() + DEADLINE;
    loop {
        if let Some(value) = done() {
            return value;
        }
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// The drive mapped with outputs `rx` and inputs `tx`, in `mode`, its cycle running.
pub fn one_drive(mode: Mode, (rx, tx): (Mapping, Mapping)) -> (CycleThread, SimControl) {
    let timing = Timing { missed_frames: MissedFrames::Lost, ..Timing::IMMEDIATE };
    let link = InProcess::with_bus(VirtualBus::with_timing(1, timing));
    let control = link.control();
    let mut m = Master::new(Box::new(link), Duration::from_millis(100));
    m.scan().unwrap();
    m.request_state(AlState::PreOp, STEP).unwrap();
    m.slave_mut(0).unwrap().configure_pdo(rx, tx).unwrap();
    m.slave_mut(0).unwrap().sdo_write(0x6060, 0, &[mode as u8]).unwrap();
    m.request_state(AlState::Op, STEP).unwrap();
    let cycle = CycleThread::start(m, Config::new(Duration::from_millis(1))).map_err(|e| e.0).unwrap();
    (cycle, control)
}
