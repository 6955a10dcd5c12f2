//! The line's health read beside the cycle, on six in-process virtual AKDs: a clean line counts
//! nothing, a faulty cable's errors are counted where the virtual ESCs counted them and named
//! as the cable they entered by, a link taken down and up is named the same way, and a read at
//! rest gives what the ESCs counted since power-up. Waits have deadlines only so that a failure
//! does not hang; no timing is asserted.

use std::time::{Duration, Instant};

use akd_native::cycle::{Config, CycleThread};
use akd_native::drive::akd::AkdSlave;
use akd_native::drive::pdo::Mapping;
use akd_native::ethercat::al::AlState;
use akd_native::ethercat::line_health::place::Finding;
use akd_native::ethercat::line_health::registers::ErrorCounts;
use akd_native::ethercat::line_health::topology::End;
use akd_native::ethercat::line_health::LineReading;
use akd_native::ethercat::master::Master;
use akd_native::sim::control::{Change, SimControl, QUERY_TIMEOUT};
use akd_native::sim::in_process::InProcess;

const STEP: Duration = Duration::from_secs(5);
/// Read often, so that the test waits little.
const INTERVAL: Duration = Duration::from_millis(20);

/// Six drives in cyclic synchronous position, in Op, and the handle that controls them.
fn line_in_op() -> (Master, SimControl) {
    let link = InProcess::new(6);
    let control = link.control();
    let mut m = Master::new(Box::new(link), Duration::from_millis(100));
    m.scan().unwrap();
    m.request_state(AlState::PreOp, STEP).unwrap();
    for position in 0..6 {
        let mut slave = m.slave_mut(position).unwrap();
        slave.configure_pdo(Mapping::Fixed(0x1724), Mapping::Fixed(0x1B24)).unwrap();
        slave.sdo_write(0x6060, 0, &[8]).unwrap();
    }
    m.request_state(AlState::Op, STEP).unwrap();
    (m, control)
}

fn cycle(m: Master) -> CycleThread {
    let config = Config { line_health: Some(INTERVAL), ..Config::new(Duration::from_millis(1)) };
    CycleThread::start(m, config).map_err(|e| e.0).unwrap()
}

/// The reading once `done` says it is what the test waits for.
fn wait_for(cycle: &CycleThread, what: &str, done: impl Fn(&LineReading) -> bool) -> LineReading {
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let reading = cycle.line_health();
        if done(&reading) {
            return reading;
        }
        assert!(Instant::now() < deadline, "no {what}: {:?}", reading.findings());
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// A read of the whole line after `reads` were done.
fn read_after(cycle: &CycleThread, reads: u64) -> LineReading {
    wait_for(cycle, "read", |r| r.health.reads > reads && r.health.slaves.iter().all(|s| s.answered))
}

fn label(slave: usize) -> String {
    format!("slave {slave} (joint_{})", slave + 1)
}

#[test]
fn a_clean_line_counts_nothing_and_shows_a_line() {
    let (m, _control) = line_in_op();
    let cycle = cycle(m);
    let reading = read_after(&cycle, 3);
    assert!(reading.findings().is_empty(), "{:?}", reading.findings());
    for slave in &reading.health.slaves {
        assert_eq!((slave.totals, slave.window), (ErrorCounts::default(), ErrorCounts::default()));
    }
    let topology = reading.topology();
    assert_eq!(topology.peer(0, 0), Some(End::Master));
    for s in 0..5 {
        assert_eq!(topology.peer(s, 1), Some(End::Port { slave: s + 1, port: 0 }));
    }
    assert_eq!(reading.ports.len(), 6);
    assert!(reading.frames >= 3 && reading.frames_lost == 0, "{reading:?}");
    cycle.stop().unwrap();
}

#[test]
fn errors_into_a_port_1_are_named_as_the_return_path_and_counted_as_the_escs_counted_them() {
    let (m, control) = line_in_op();
    let cycle = cycle(m);
    read_after(&cycle, 1);
    // A flaky connector between slaves 3 and 4 on the return pair: one frame in 50 entering
    // slave 3's port 1, 40 of them.
    control.change(Change::spoil_port(control.products(), 3, 1, 40, 50)).unwrap();
    let named = wait_for(&cycle, "finding", |r| !r.findings().is_empty());
    let worst = &named.findings()[0];
    assert_eq!(worst.port(), Some((3, 1)), "{worst:?}");
    let words = worst.words(label, &named.period());
    assert!(
        words.starts_with("errors on the cable into slave 3 (joint_4) port 1, from slave 4 (joint_5) port 0: "),
        "{words}"
    );
    wait_for(&cycle, "the fault's end", |_| control.esc_state(3, QUERY_TIMEOUT).unwrap().spoiling[1] == 0);
    let reads = cycle.line_health().health.reads;
    let reading = read_after(&cycle, reads);
    for slave in 0..6 {
        let counted = control.esc_state(slave, QUERY_TIMEOUT).unwrap().counted;
        assert_eq!(reading.health.slaves[slave].totals, counted, "slave {slave}");
    }
    assert_eq!(reading.health.slaves[3].totals.ports[1].invalid_frames, 40);
    assert_eq!(reading.health.slaves[0].totals.ports[1].forwarded_errors, 40);
    assert_eq!(reading.health.slaves[4].totals, ErrorCounts::default());
    cycle.stop().unwrap();
}

#[test]
fn a_link_taken_down_and_up_is_named_as_the_cable_it_is() {
    let (m, control) = line_in_op();
    let cycle = cycle(m);
    read_after(&cycle, 1);
    control.change(Change::link(control.products(), 3, 1, false)).unwrap();
    let down = wait_for(&cycle, "link down", |r| r.findings().first().is_some_and(Finding::is_down));
    let words = down.findings()[0].words(label, &down.period());
    assert_eq!(
        words,
        "no link on the cable into slave 4 (joint_5) port 0, from slave 3 (joint_4) port 1: unreachable slave 4 \
         (joint_5), slave 5 (joint_6)"
    );
    control.change(Change::link(control.products(), 3, 1, true)).unwrap();
    let up = wait_for(&cycle, "the link back", |r| {
        r.health.slaves.iter().all(|s| s.answered) && r.findings().first().is_some_and(|f| !f.is_down())
    });
    let words = up.findings()[0].words(label, &up.period());
    assert!(
        words.starts_with("link lost on the cable into slave 4 (joint_5) port 0, from slave 3 (joint_4) port 1: 1 "),
        "{words}"
    );
    assert_eq!(up.health.slaves[3].totals.ports[1].lost_links, 1);
    assert_eq!(up.health.slaves[4].totals.ports[0].lost_links, 1);
    cycle.stop().unwrap();
}

#[test]
fn a_read_at_rest_gives_what_the_escs_counted_since_power_up() {
    let link = InProcess::new(3);
    let control = link.control();
    let mut m = Master::new(Box::new(link), Duration::from_millis(100));
    m.scan().unwrap();
    control.change(Change::cable(control.products(), 2, false)).unwrap();
    control.change(Change::cable(control.products(), 2, true)).unwrap();
    let reading = m.line_health().unwrap();
    assert_eq!(reading.health.slaves[1].totals.ports[1].lost_links, 1);
    assert_eq!(reading.health.slaves[2].totals.ports[0].lost_links, 1);
    // At rest, what the ESCs counted since power-up is what the findings place.
    let words: Vec<String> = reading.findings().iter().map(|f| f.words(label, &reading.period())).collect();
    assert_eq!(
        words,
        ["link lost on the cable into slave 2 (joint_3) port 0, from slave 1 (joint_2) port 1: 1 since power-up or \
         the last clear"]
    );
    assert_eq!(reading.ports.iter().map(|p| p.0).collect::<Vec<_>>(), [0x0F; 3]);
}

#[test]
fn a_line_of_terminals_is_read_port_by_port_as_each_esc_has_them() {
    // The master takes lines of AKDs only so far (issue 35 part B teaches it terminals): the ESCs
    // are read here as a master's read of the line would read them, through the simulator's query.
    use akd_native::ethercat::line_health::registers::{PortDescriptor, PortKind};
    use akd_native::ethercat::line_health::tally::{LineTally, SlaveRead};
    use akd_native::sim::control::ControlledBus;
    use akd_native::sim::{Timing, VirtualBus};
    let line = "ek1100,el1004,el2004,akd".parse().unwrap();
    let mut bus = ControlledBus::from(VirtualBus::of_line(&line, Timing::IMMEDIATE).unwrap());
    // The EL2004's input from the EL1004, on the E-bus: every other frame, 5 of them.
    let control = bus.control();
    control.change(Change::spoil_port(control.products(), 2, 0, 5, 2)).unwrap();
    let mut frame = [0u8; 64];
    let mut builder = akd_native::ethercat::frame::FrameBuilder::new(&mut frame);
    builder.push(akd_native::ethercat::frame::Command::Brd, 0, 0, 0x0130, &[0, 0]).unwrap();
    let len = builder.finish();
    for _ in 0..10 {
        bus.process(&mut frame[..len], 0).unwrap();
    }
    let states: Vec<_> = (0..4).map(|s| akd_native::sim::control::EscState::of(bus.bus(), s)).collect();
    let mut tally = LineTally::at_rest(4);
    for (s, state) in states.iter().enumerate() {
        tally.take(s, &SlaveRead { answered: true, dl_status: state.dl_status, counters: state.registers });
    }
    tally.close_read(0);
    let ports: Vec<PortDescriptor> = states.iter().map(|s| s.port_descriptor).collect();
    let reading = LineReading { ports, health: tally.health(), interval: None, frames: 1, frames_lost: 0 };
    let kinds = |s: usize| reading.ports[s].ports().map(|p| reading.ports[s].kind(p)).collect::<Vec<_>>();
    assert_eq!(kinds(0), [PortKind::Mii, PortKind::Ebus, PortKind::Mii], "the EK1100's ET1100");
    assert_eq!(kinds(1), [PortKind::Ebus, PortKind::Ebus, PortKind::NotConfigured], "the EL1004's ET1200");
    assert_eq!(kinds(3), [PortKind::Mii, PortKind::Mii], "the AKD's");
    let topology = reading.topology();
    assert_eq!(topology.peer(0, 1), Some(End::Port { slave: 1, port: 0 }));
    assert_eq!(topology.peer(0, 2), None, "the EK1100's X2 OUT has no cable on the virtual line");
    assert_eq!(reading.health.slaves[2].totals.ports[0].invalid_frames, 5);
    assert_eq!(reading.health.slaves[0].totals.ports[1].forwarded_errors, 5, "the EK1100's E-bus port");
    let names = ["EK1100", "EL1004", "EL2004", "AKD"];
    let words = reading.findings()[0].words(|s| format!("slave {s} ({})", names[s]), &reading.period());
    assert_eq!(
        words,
        "errors on the cable into slave 2 (EL2004) port 0, from slave 1 (EL1004) port 1: 5 since power-up or the \
         last clear"
    );
}
