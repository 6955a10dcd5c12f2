//! Controlling the virtual AKDs of an in-process link while a master owns it: through the cycle
//! thread (a fault injected from the test's thread shows in the statusword the cycle reads) and
//! on the exchange path, which allocates nothing while no command is pending. Allocations are
//! counted by a global allocator per thread: the in-process bus runs in the master's thread, so
//! its work is counted with the master's. Waits have deadlines only so that a failure does not
//! hang; no timing is asserted.

use std::time::{Duration, Instant};

use akd_native::cycle::{Config, CycleThread};
use akd_native::drive::ds402::{statusword, State};
use akd_native::ethercat::master::Master;
use akd_native::sim::control::{Change, SimControl, QUERY_TIMEOUT};
use akd_native::sim::faults::Fault;
use akd_native::sim::in_process::InProcess;

#[path = "support/counting.rs"]
mod counting;
use counting::allocations;

#[path = "support/csp.rs"]
mod csp;
use csp::{csp_master, STEP};

/// A master in Op on one in-process virtual AKD in cyclic synchronous position with
/// 0x1724/0x1B24 (outputs: target position, controlword, torque offset; inputs: actual
/// position, statusword), and the handle that controls the drive.
fn master_in_op() -> (Master, SimControl) {
    let link = InProcess::new(1);
    let control = link.control();
    (csp_master(Box::new(link)), control)
}

fn statusword_of(inputs: &[u8]) -> u16 {
    u16::from_le_bytes([inputs[4], inputs[5]])
}

#[test]
fn a_fault_injected_while_the_cycle_thread_owns_the_link_shows_in_the_statusword() {
    let (m, control) = master_in_op();
    let cycle = CycleThread::start(m, Config::new(Duration::from_millis(1))).map_err(|e| e.0).unwrap();
    assert_eq!(control.drive_state(0, STEP).unwrap().fault, None);
    control.change(Change::inject_fault(control.products(), 0, "F439")).unwrap();
    let deadline = Instant::now() + Duration::from_secs(10);
    while statusword_of(&cycle.snapshot().inputs) & statusword::FAULT == 0 {
        assert!(Instant::now() < deadline, "no fault bit in {:?}", cycle.snapshot().inputs);
        std::thread::sleep(Duration::from_millis(1));
    }
    let state = control.drive_state(0, STEP).unwrap();
    assert_eq!((state.state, state.fault), (State::Fault, Some(Fault::FollowingError)));
    let mut m = cycle.stop().unwrap();
    // Back with its owner, idle: a query waits for a frame, and one call of the master is one.
    let asking = std::thread::spawn(move || control.drive_state(0, STEP));
    while !asking.is_finished() {
        m.exchange().unwrap();
        std::thread::sleep(Duration::from_millis(1));
    }
    assert_eq!(asking.join().unwrap().unwrap().fault, Some(Fault::FollowingError));
    let e = m.slave_mut(0).unwrap().sdo_read(0x603F, 0).unwrap();
    assert_eq!(e, 0x8611u16.to_le_bytes());
}

#[test]
fn the_exchange_allocates_nothing_while_no_command_is_pending() {
    let (mut m, control) = master_in_op();
    m.exchange().unwrap();
    // A command and a query were served once, as they are in a test that uses them.
    control.change(Change::hardware_enable(control.products(), 0, true)).unwrap();
    let asking = std::thread::spawn(move || control.drive_state(0, QUERY_TIMEOUT).map(|_| control));
    while !asking.is_finished() {
        m.exchange().unwrap();
    }
    let _control = asking.join().unwrap().unwrap();
    let probe = allocations();
    drop(std::hint::black_box(Vec::<u8>::with_capacity(8)));
    assert_eq!(allocations(), probe + 1, "the counter sees this thread's allocations");
    let before = allocations();
    for _ in 0..1000 {
        m.exchange().unwrap();
    }
    assert_eq!(allocations() - before, 0, "allocations in 1000 exchanges");
}
