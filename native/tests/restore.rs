//! The master's restore of one lost slave with nothing written between its two halves, as a
//! slave without a profile gets it (a drive's profile writes its mode and clock there; the
//! cycle's recovery of drives is tests/test_recovery.py's): a power-cycled virtual AKD comes
//! back to Op with its station address, its process data in the same place of the image and
//! SYNC0 on the line's common boundary, while the master that cycles goes on exchanging with
//! the other drive; a slave found in Op by itself needs nothing.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use akd_native::ethercat::al::AlState;
use akd_native::ethercat::master::restore::Restoring;
use akd_native::ethercat::master::Master;
use akd_native::sim::VirtualBus;

#[path = "support/shared.rs"]
mod shared;
use shared::Shared;

const STEP: Duration = Duration::from_secs(5);
const CYCLE_NS: u32 = 1_000_000;
const SHIFT_NS: i32 = 250_000;

#[test]
fn a_power_cycled_slave_comes_back_to_op_from_the_two_halves_alone() {
    let bus = Arc::new(Mutex::new(VirtualBus::new(2)));
    let mut m = Master::new(Box::new(Shared::new(bus.clone())), Duration::from_millis(100));
    m.scan().unwrap();
    m.request_state(AlState::PreOp, STEP).unwrap();
    m.set_up_dc(CYCLE_NS, SHIFT_NS.into()).unwrap();
    m.request_state(AlState::Op, STEP).unwrap();
    let good = m.exchange().unwrap();

    let mut restoring = m.for_restore(Box::new(Shared::new(bus.clone())));
    assert_eq!(restoring.restore_to_preop(1).unwrap(), Restoring::InOp, "nothing lost yet");
    bus.lock().unwrap().slave_mut(1).power_cycle();
    // The restore waits for Op, which the drive enters once outputs reach it: the cycling
    // master's frames carry them meanwhile.
    let restore = std::thread::spawn(move || -> akd_native::error::Result<Restoring> {
        let found = restoring.restore_to_preop(1)?;
        restoring.restore_to_op(1)?;
        Ok(found)
    });
    let deadline = Instant::now() + 4 * STEP;
    while !restore.is_finished() {
        assert!(Instant::now() < deadline, "the restore never ended");
        let _ = m.exchange();
        std::thread::sleep(Duration::from_millis(1));
    }
    assert_eq!(restore.join().unwrap().unwrap(), Restoring::InPreOp);

    assert_eq!(bus.lock().unwrap().slave(1).al_status(), (AlState::Op, false, 0));
    assert_eq!(m.exchange().unwrap(), good, "both slaves exchange in the same image again");
    let after = bus.lock().unwrap().slave(1).sync_state();
    assert!(after.sync0_active);
    assert_eq!(after.sync0_cycle_ns, CYCLE_NS);
    assert_eq!(after.sync0_start_ns % CYCLE_NS as u64, SHIFT_NS as u64, "on the line's boundary, shifted");
}
