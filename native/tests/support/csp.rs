//! The rig several cycle tests share: one AKD behind `link`, mapped 0x1724/0x1B24 in cyclic
//! synchronous position, in Op, cycled at 1 kHz by a [`CycleThread`].

use std::time::Duration;

use akd_native::cycle::{Config, CycleThread};
use akd_native::drive::akd::AkdSlave;
use akd_native::drive::pdo::Mapping;
use akd_native::ethercat::al::AlState;
use akd_native::ethercat::link::Link;
use akd_native::ethercat::master::Master;

/// How long each AL step of the set-up may take.
pub const STEP: Duration = Duration::from_secs(5);

/// The master of one drive in cyclic synchronous position behind `link`, in Op.
pub fn csp_master(link: Box<dyn Link>) -> Master {
    let mut m = Master::new(link, Duration::from_millis(100));
    m.scan().unwrap();
    m.request_state(AlState::PreOp, STEP).unwrap();
    m.slave_mut(0).unwrap().configure_pdo(Mapping::Fixed(0x1724), Mapping::Fixed(0x1B24)).unwrap();
    m.slave_mut(0).unwrap().sdo_write(0x6060, 0, &[8]).unwrap();
    m.request_state(AlState::Op, STEP).unwrap();
    m
}

/// [`csp_master`], cycled at 1 kHz.
#[allow(dead_code)] // not every test that includes this module cycles
pub fn csp_cycle(link: Box<dyn Link>) -> CycleThread {
    CycleThread::start(csp_master(link), Config::new(Duration::from_millis(1))).map_err(|e| e.0).unwrap()
}
