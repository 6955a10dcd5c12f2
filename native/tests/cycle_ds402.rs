//! The DS402 sequencer in the cycle thread against a virtual AKD the test can reach while the
//! thread cycles (hardware enable, injected faults), which a Master("sim") from Python cannot.
//! The waits have deadlines only so that a failure does not hang; no timing is asserted.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use akd_native::cycle::sequencer::{DriveStatus, Progress, Request};
use akd_native::cycle::CycleThread;
use akd_native::drive::akd::AkdSlave;
use akd_native::drive::ds402::State;
use akd_native::sim::faults::Fault;
use akd_native::sim::{Timing, VirtualBus};

#[path = "support/csp.rs"]
mod csp;
#[path = "support/shared.rs"]
mod shared;
use csp::csp_cycle;
use shared::Shared;

/// One virtual AKD in cyclic synchronous position with 0x1724/0x1B24, cycling at 1 kHz.
fn rig() -> (CycleThread, Arc<Mutex<VirtualBus>>) {
    let bus = Arc::new(Mutex::new(VirtualBus::with_timing(1, Timing::IMMEDIATE)));
    let cycle = csp_cycle(Box::new(Shared::new(bus.clone())));
    cycle.set_request_timeout(Duration::from_millis(200));
    (cycle, bus)
}

/// Waits until the drive's status satisfies `done`.
fn wait(cycle: &CycleThread, done: impl Fn(&DriveStatus) -> bool) -> DriveStatus {
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let status = cycle.drive_status(0).unwrap();
        if done(&status) {
            return status;
        }
        assert!(Instant::now() < deadline, "{status:?}");
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// Lets `count` cycles pass.
fn cycles(cycle: &CycleThread, count: u64) {
    let later = cycle.snapshot().cycle + count;
    while cycle.snapshot().cycle < later {
        std::thread::sleep(Duration::from_millis(1));
    }
}

fn wait_state(cycle: &CycleThread, state: State) -> DriveStatus {
    wait(cycle, |s| s.state() == Some(state))
}

#[test]
fn hardware_enable_low_makes_enable_stuck_with_the_reason() {
    let (cycle, bus) = rig();
    bus.lock().unwrap().slave_mut(0).drive_mut().set_hardware_enable(false);
    cycle.request(0, Request::Enable).unwrap();
    let status = wait(&cycle, |s| s.progress == Progress::Stuck);
    let why = status.stuck_reason().unwrap();
    assert!(why.starts_with("enable stuck in "), "{why}");
    assert!(why.contains("warning (bit 7): on the AKD the hardware enable input is low"), "{why}");
    // A stuck enable leaves the drive powerless (the statusword comes back a cycle after the
    // controlword went out, so a few cycles on).
    cycles(&cycle, 5);
    assert_eq!(cycle.drive_status(0).unwrap().state(), Some(State::SwitchOnDisabled));
    assert_eq!(bus.lock().unwrap().slave(0).drive().state(), State::SwitchOnDisabled);
    bus.lock().unwrap().slave_mut(0).drive_mut().set_hardware_enable(true);
    cycle.request(0, Request::Enable).unwrap();
    let status = wait_state(&cycle, State::OperationEnabled);
    assert_eq!((status.request, status.stuck_reason()), (Some(Request::Enable), None));
}

#[test]
fn a_fault_while_enabled_is_not_retried_and_the_reset_clears_it() {
    let (cycle, bus) = rig();
    cycle.request(0, Request::Enable).unwrap();
    wait_state(&cycle, State::OperationEnabled);
    bus.lock().unwrap().slave_mut(0).drive_mut().inject(Fault::OverTemperature);
    let status = wait_state(&cycle, State::Fault);
    let status =
        if status.progress == Progress::Lost { status } else { wait(&cycle, |s| s.progress == Progress::Lost) };
    let why = status.stuck_reason().unwrap();
    assert!(why.contains("enable left the requested state in Fault"), "{why}");
    assert!(why.contains("fault (bit 3)"), "{why}");
    // Many cycles later the drive is still in Fault: nothing reset it behind the caller's back.
    cycles(&cycle, 50);
    assert_eq!(bus.lock().unwrap().slave(0).drive().fault(), Some(Fault::OverTemperature));
    cycle.request(0, Request::FaultReset).unwrap();
    let status = wait_state(&cycle, State::SwitchOnDisabled);
    let status =
        if status.progress == Progress::Done { status } else { wait(&cycle, |s| s.progress == Progress::Done) };
    assert_eq!(status.request, Some(Request::FaultReset));
    assert_eq!(bus.lock().unwrap().slave(0).drive().fault(), None);
    // Out of Fault, bit 7 is low again (ready for the next edge) and the power stage stays off.
    // The status is published while the cycle builds its frame, the snapshot once that frame is
    // back: two cycles on, the snapshot is certainly of a frame built after the status.
    cycles(&cycle, 2);
    let snapshot = cycle.snapshot();
    assert_eq!(cycle.outputs_of(&snapshot, 0).unwrap()[4..6], [0, 0]);
    cycle.request(0, Request::Enable).unwrap();
    wait_state(&cycle, State::OperationEnabled);
}

/// Three virtual AKDs in cyclic synchronous position, enabled, with a fault on the middle one:
/// the states the other two end in.
fn others_after_a_fault(quick_stop_on_fault: bool) -> [Option<State>; 2] {
    use akd_native::cycle::Config;
    use akd_native::drive::pdo::Mapping;
    use akd_native::ethercat::al::AlState;
    use akd_native::ethercat::master::Master;

    let bus = Arc::new(Mutex::new(VirtualBus::with_timing(3, Timing::IMMEDIATE)));
    let mut m = Master::new(Box::new(Shared::new(bus.clone())), Duration::from_millis(100));
    m.scan().unwrap();
    m.request_state(AlState::PreOp, csp::STEP).unwrap();
    for position in 0..3 {
        m.slave_mut(position).unwrap().configure_pdo(Mapping::Fixed(0x1724), Mapping::Fixed(0x1B24)).unwrap();
        m.slave_mut(position).unwrap().sdo_write(0x6060, 0, &[8]).unwrap();
    }
    m.request_state(AlState::Op, csp::STEP).unwrap();
    let cycle = CycleThread::start(m, Config::new(Duration::from_millis(1))).map_err(|e| e.0).unwrap();
    cycle.set_quick_stop_on_fault(quick_stop_on_fault);
    let state = |p| cycle.drive_status(p).unwrap().state();
    for position in 0..3 {
        cycle.request(position, Request::Enable).unwrap();
    }
    let deadline = Instant::now() + Duration::from_secs(10);
    while (0..3).any(|p| state(p) != Some(State::OperationEnabled)) {
        assert!(Instant::now() < deadline, "not all enabled");
        std::thread::sleep(Duration::from_millis(2));
    }
    bus.lock().unwrap().slave_mut(1).drive_mut().inject(Fault::OverTemperature);
    while state(1) != Some(State::Fault) {
        assert!(Instant::now() < deadline, "no fault");
        std::thread::sleep(Duration::from_millis(2));
    }
    // The quick stop is asked for in the cycle that saw the fault; a few cycles bring it about.
    cycles(&cycle, 20);
    [state(0), state(2)]
}

#[test]
fn a_fault_on_one_drive_quick_stops_the_others_when_asked_to() {
    assert_eq!(others_after_a_fault(true), [Some(State::QuickStopActive); 2]);
    assert_eq!(others_after_a_fault(false), [Some(State::OperationEnabled); 2]);
}
