//! Distributed clocks against the virtual AKDs: with DC on, every drive runs SYNC0 at the cycle
//! time with the shift asked for, FBUS.PARAM02 = 1 and its PLL following SYNC0, and every
//! cyclic frame carries the drift FRMW and one drive's system-time difference read; with DC
//! off, SYNC0 stays off and FBUS.PARAM02 = 0, the drives follow SM2; a shift of a cycle or more
//! is refused; FBUS.PARAM02 is written only to a drive whose SDO information names the object
//! so; a drive the cycle restores after a power cycle is told its clock and its mode again. The
//! drives' own view comes from the bus behind the link, not from the master.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use akd_native::cycle::{Config, CycleThread};
use akd_native::drive::akd::AkdLine;
use akd_native::drive::ds402::Mode;
use akd_native::drive::sync;
use akd_native::error::Result;
use akd_native::ethercat::al::AlState;
use akd_native::ethercat::frame::{self, Command};
use akd_native::ethercat::link::Link;
use akd_native::ethercat::master::Master;
use akd_native::sim::in_process::InProcess;
use akd_native::sim::pll::{SyncSource, SyncState};

const STEP: Duration = Duration::from_secs(5);
const CYCLE_NS: u32 = 1_000_000;
const DRIVES: usize = 3;

/// What the link saw of the cyclic frames (those with an LRW).
#[derive(Default)]
struct Seen {
    cyclic: u64,
    with_drift: u64,
    with_difference: u64,
}

/// The in-process bus, kept at hand to ask the drives, counting what the cyclic frames carry.
struct Watched {
    bus: Arc<Mutex<InProcess>>,
    seen: Arc<Mutex<Seen>>,
}

impl Link for Watched {
    fn send(&mut self, tx: &[u8]) -> Result<()> {
        let has = |command: Command, ado: u16| {
            frame::parse(tx).unwrap().flatten().any(|d| d.header.command == command && d.header.ado == ado)
        };
        if has(Command::Lrw, 0) {
            let mut seen = self.seen.lock().unwrap();
            seen.cyclic += 1;
            seen.with_drift += has(Command::Frmw, 0x0910) as u64;
            seen.with_difference += has(Command::Fprd, 0x092C) as u64;
        }
        self.bus.lock().unwrap().send(tx)
    }

    fn receive(&mut self, rx: &mut [u8], deadline: Instant) -> Result<Option<usize>> {
        self.bus.lock().unwrap().receive(rx, deadline)
    }

    fn describe(&self) -> String {
        "watched sim".into()
    }
}

struct Rig {
    m: Master,
    bus: Arc<Mutex<InProcess>>,
    seen: Arc<Mutex<Seen>>,
}

impl Rig {
    /// `DRIVES` virtual AKDs in PreOp.
    fn new() -> Rig {
        let bus = Arc::new(Mutex::new(InProcess::new(DRIVES)));
        let seen = Arc::new(Mutex::new(Seen::default()));
        let link = Watched { bus: bus.clone(), seen: seen.clone() };
        let mut m = Master::new(Box::new(link), Duration::from_millis(100));
        assert_eq!(m.scan().unwrap(), DRIVES);
        m.request_state(AlState::PreOp, STEP).unwrap();
        Rig { m, bus, seen }
    }

    fn sync(&self, position: usize) -> SyncState {
        self.bus.lock().unwrap().bus().slave(position).sync_state()
    }
}

#[test]
fn dc_on_every_drive_runs_sync0_at_the_cycle_with_the_shift_and_every_frame_keeps_the_clocks() {
    let mut rig = Rig::new();
    let param02 = rig.m.configure_dc(CYCLE_NS, -250_000).unwrap();
    for position in 0..DRIVES {
        let s = rig.sync(position);
        assert!(s.sync0_active, "drive {position}: {s:?}");
        assert_eq!((s.sync0_cycle_ns, s.fbus_param02, s.cycle_ns), (CYCLE_NS, 1, Some(CYCLE_NS as u64)));
        assert_eq!(s.sync0_start_ns % CYCLE_NS as u64, 750_000, "drive {position}: SYNC0 moved 250 µs early");
        assert_eq!((s.source, s.pll_locked), (SyncSource::Sync0, true), "drive {position}");
    }
    let clock = rig.m.clock().unwrap().clone();
    assert_eq!((clock.cycle_ns, clock.shift_ns, clock.reference_position), (CYCLE_NS, -250_000, 0));
    assert_eq!(param02, [Some(1); DRIVES]);
    rig.m.request_state(AlState::Op, STEP).unwrap();
    let before = std::mem::take(&mut *rig.seen.lock().unwrap());
    let reads_before = rig.m.clock().unwrap().difference_reads;
    let cycles = 30;
    for _ in 0..cycles {
        rig.m.exchange().unwrap();
    }
    let seen = rig.seen.lock().unwrap();
    assert!(before.cyclic > 0 && before.with_drift == before.cyclic, "while going to Op too");
    assert_eq!((seen.cyclic, seen.with_drift, seen.with_difference), (cycles, cycles, cycles));
    let clock = rig.m.clock().unwrap();
    assert_eq!((clock.difference_reads - reads_before, clock.difference_misses), (cycles, 0));
    for slave in &clock.slaves {
        let d = slave.time_difference_ns.expect("read in turn");
        assert!(d.abs() < 10_000, "drive {} is {d} ns off the reference", slave.position);
    }
    assert_eq!(rig.m.stats().wkc_errors, 0);
}

#[test]
fn dc_off_leaves_sync0_off_and_the_drives_on_sm2() {
    let mut rig = Rig::new();
    // Switched on first, so that off is seen to switch it off again.
    rig.m.configure_dc(CYCLE_NS, 0).unwrap();
    rig.m.configure_sm2_sync(500_000).unwrap();
    for position in 0..DRIVES {
        let s = rig.sync(position);
        assert!(!s.sync0_active, "drive {position}: {s:?}");
        assert_eq!((s.fbus_param02, s.cycle_ns, s.source, s.pll_locked), (0, Some(500_000), SyncSource::Sm2, false));
    }
    assert!(rig.m.clock().is_none());
    rig.m.request_state(AlState::Op, STEP).unwrap();
    rig.m.exchange().unwrap();
    let seen = rig.seen.lock().unwrap();
    assert_eq!((seen.with_drift, seen.with_difference), (0, 0), "no DC datagram without DC");
}

#[test]
fn a_shift_of_a_cycle_or_more_is_refused_and_nothing_is_started() {
    let mut rig = Rig::new();
    for shift in [CYCLE_NS as i64, -(CYCLE_NS as i64), 5_000_000_000] {
        let e = rig.m.configure_dc(CYCLE_NS, shift).unwrap_err().to_string();
        assert!(
            e.contains(&format!("SYNC0 shift {shift} ns")) && e.contains("allowed are -999999 to 999999 ns"),
            "{e}"
        );
    }
    assert!(rig.m.clock().is_none());
    assert!((0..DRIVES).all(|p| !rig.sync(p).sync0_active && rig.sync(p).fbus_param02 == 0));
}

#[test]
fn the_cycle_thread_publishes_every_drives_system_time_difference() {
    let mut rig = Rig::new();
    let fbus_param02 = rig.m.configure_dc(CYCLE_NS, 100_000).unwrap();
    rig.m.request_state(AlState::Op, STEP).unwrap();
    let config = Config { fbus_param02, ..Config::new(Duration::from_millis(1)) };
    let cycle = CycleThread::start(rig.m, config).map_err(|e| e.0).unwrap();
    let deadline = std::time::Instant::now() + STEP;
    let status = loop {
        let status = cycle.dc_status().unwrap();
        if status.difference_reads >= 2 * DRIVES as u64 || std::time::Instant::now() > deadline {
            break status;
        }
        std::thread::sleep(Duration::from_millis(2));
    };
    assert_eq!((status.cycle_ns, status.shift_ns, status.reference_position), (CYCLE_NS, 100_000, 0));
    assert_eq!(status.drives.iter().map(|d| d.position).collect::<Vec<_>>(), [0, 1, 2]);
    for drive in &status.drives {
        assert_eq!(drive.fbus_param02, Some(1));
        let d = drive.time_difference_ns.expect("read within two rounds");
        assert!(d.abs() < 10_000, "drive {} is {d} ns off", drive.position);
    }
    cycle.stop().unwrap();
}

#[test]
fn fbus_param02_is_left_alone_on_a_drive_without_the_object_or_naming_it_otherwise() {
    let mut rig = Rig::new();
    {
        let mut bus = rig.bus.lock().unwrap();
        // Drive 1 has another parameter at the modelled index; drive 2 has no object there.
        let od = bus.bus_mut().slave_mut(1).od_mut();
        let mut other = od.object(sync::FBUS_PARAM02).unwrap().clone();
        (other.name, other.entries[0].name) = ("DRV.OTHER", "DRV.OTHER");
        od.insert(other);
        bus.bus_mut().slave_mut(2).od_mut().remove(sync::FBUS_PARAM02).unwrap();
    }
    let param02 = rig.m.configure_dc(CYCLE_NS, 0).unwrap();
    assert_eq!(param02, [Some(1), None, None], "unknown where not confirmed");
    let drive_1 = rig.bus.lock().unwrap().bus().slave(1).od().get(sync::FBUS_PARAM02, 0).unwrap().to_vec();
    assert_eq!(drive_1, [0; 4], "the object named otherwise was not written");
    // SYNC0 and the cycle time are still set on every drive; only drive 0's PLL follows SYNC0.
    let sources: Vec<_> = (0..DRIVES).map(|p| rig.sync(p)).map(|s| (s.sync0_active, s.source)).collect();
    assert_eq!(sources, [(true, SyncSource::Sync0), (true, SyncSource::Sm2), (true, SyncSource::Sm2)]);
    assert!((0..DRIVES).all(|p| rig.sync(p).cycle_ns == Some(CYCLE_NS as u64)));
    rig.m.configure_sm2_sync(CYCLE_NS).unwrap();
    let drive_1 = rig.bus.lock().unwrap().bus().slave(1).od().get(sync::FBUS_PARAM02, 0).unwrap().to_vec();
    assert_eq!(drive_1, [0; 4], "nor written with DC off");
}

#[test]
fn a_drive_restored_by_the_cycle_is_told_its_clock_and_its_mode_again() {
    for dc in [true, false] {
        let Rig { mut m, bus, .. } = Rig::new();
        let fbus_param02 = if dc { m.configure_dc(CYCLE_NS, 0) } else { m.configure_sm2_sync(CYCLE_NS) }.unwrap();
        // Neither the drive's power-up mode (none) nor its power-up cycle time (2 ms): a power
        // cycle forgets both, and only the restore gives them back.
        let mode = Mode::CyclicSynchronousPosition as u8;
        m.slave_mut(1).unwrap().sdo_write(0x6060, 0, &[mode]).unwrap();
        m.request_state(AlState::Op, STEP).unwrap();
        let config = Config { fbus_param02, ..Config::new(Duration::from_nanos(CYCLE_NS.into())) };
        let cycle = CycleThread::start(m, config).map_err(|e| e.0).unwrap();
        bus.lock().unwrap().bus_mut().slave_mut(1).power_cycle();
        let deadline = Instant::now() + 4 * STEP;
        while cycle.recovery_status(1).unwrap().recoveries == 0 {
            assert!(Instant::now() < deadline, "dc {dc}: never restored: {:?}", cycle.recovery_status(1));
            std::thread::sleep(Duration::from_millis(2));
        }
        let (sync, modes) = {
            let bus = bus.lock().unwrap();
            (bus.bus().slave(1).sync_state(), bus.bus().slave(1).od().get(0x6060, 0).unwrap().to_vec())
        };
        let clock = (sync.sync0_active, sync.fbus_param02, sync.cycle_ns, sync.source, sync.pll_locked);
        let expected = match dc {
            true => (true, 1, Some(CYCLE_NS as u64), SyncSource::Sync0, true),
            false => (false, 0, Some(CYCLE_NS as u64), SyncSource::Sm2, false),
        };
        assert_eq!(clock, expected, "dc {dc}");
        assert_eq!(modes, [mode], "dc {dc}");
        cycle.stop().unwrap();
    }
}
