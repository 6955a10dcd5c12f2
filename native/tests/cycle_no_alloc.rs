//! The cycle thread's loop allocates nothing, waiting for each frame or pipelined: a global allocator counts the allocations of
//! the thread named `akd-cycle` (found by its kernel thread id in /proc), while the virtual
//! AKDs are served over UDP by another thread whose allocations are not counted. Drive 2 is
//! mapped for the profile modes, so that the set-point handshake and the command time-out (its
//! halt, its release and its quick stop) run in the watched cycles too; drive 1 (its
//! interpolation set-point 0x60C1:01 mapped) follows a trajectory that another replaces early on (both allocated in
//! this thread, handed over and returned by the loop). Drive 0 is pinged through EoE meanwhile,
//! small pings and large ones in fragments. The line's links and error counters are read beside
//! the cycle every 20 ms meanwhile. Then a virtual cell (an EK1100, an EL1004, an EL2004
//! and an AKD): the devices' outputs set by name, their input edges reported, one of them
//! power-cycled, lost, brought back and its outputs switched off, all in the watched cycles.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicI32, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use akd_native::cycle::events::{CommandTimeoutAction, Event, TrajectoryState};
use akd_native::cycle::sequencer::{Progress, Request};
use akd_native::cycle::trajectory_player::TrajectoryStatus;
use akd_native::cycle::{handshake, Config, CycleThread, RealTime, Snapshot};
use akd_native::drive::akd::{AkdLine, AkdSlave};
use akd_native::drive::ds402::{Mode, State};
use akd_native::drive::trajectory::Knot;
use akd_native::ethercat::al::AlState;
use akd_native::ethercat::device::ChannelValue;
use akd_native::ethercat::link::udp::Udp;
use akd_native::ethercat::link_spec::{MissedFrames, SimLine};
use akd_native::ethercat::master::Master;
use akd_native::sim::control::{Change, ControlledBus};
use akd_native::sim::{server, Timing, VirtualBus};

#[path = "support/ethernet.rs"]
mod ethernet;
#[path = "support/profile.rs"]
mod profile;

struct Counting;

/// The kernel thread id whose allocations are counted (0: none yet).
static WATCHED: AtomicI32 = AtomicI32::new(0);
static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

fn count() {
    // gettid allocates nothing, so the allocator may call it.
    if WATCHED.load(Ordering::Relaxed) == unsafe { libc::gettid() } {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        System.alloc(layout)
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static COUNTING: Counting = Counting;

/// The kernel thread id of this process's thread named `name`.
fn thread_named(name: &str) -> i32 {
    std::fs::read_dir("/proc/self/task")
        .unwrap()
        .filter_map(|e| e.ok())
        .find(|e| std::fs::read_to_string(e.path().join("comm")).is_ok_and(|c| c.trim_end() == name))
        .and_then(|e| e.file_name().to_str()?.parse().ok())
        .unwrap_or_else(|| panic!("no thread named {name}"))
}

fn wait_for_cycle(cycle: &CycleThread, after: u64) -> Snapshot {
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let s = cycle.snapshot();
        if s.cycle > after {
            return s;
        }
        assert!(Instant::now() < deadline, "the cycle stopped at {}", s.cycle);
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// The virtual AKDs judge missed frames by frames lost, not by time: a cycle this shared host runs
/// late is no lost frame, which is what the test tolerates F125 for.
const LATE_IS_NOT_MISSED: Timing = Timing { missed_frames: MissedFrames::Lost, ..Timing::IMMEDIATE };

#[test]
fn cycle_loop_allocates_nothing() {
    // One mode after the other: the counter watches one thread at a time.
    for pipelined in [false, true] {
        loop_allocates_nothing(pipelined);
    }
    devices_allocate_nothing();
}

/// The cell's run (see the module): the allocations of the watched cycles, none.
fn devices_allocate_nothing() {
    let socket = server::bind_udp("127.0.0.1:0".parse().unwrap()).unwrap();
    let address = socket.local_addr().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let line: SimLine = "ek1100,el1004,el2004,akd".parse().unwrap();
    let bus = ControlledBus::from(VirtualBus::of_line(&line, LATE_IS_NOT_MISSED).unwrap());
    let control = bus.control();
    let serving = {
        let stop = stop.clone();
        std::thread::spawn(move || server::serve_udp_on(socket, bus, &stop, None))
    };
    let mut m = Master::new(Box::new(Udp::connect(&address.to_string()).unwrap()), Duration::from_millis(500));
    let deadline = Instant::now() + Duration::from_secs(5);
    while m.scan().is_err() {
        assert!(Instant::now() < deadline, "no simulator on {address}");
    }
    m.request_state(AlState::Op, Duration::from_secs(5)).unwrap();
    let cycle = CycleThread::start(m, Config::new(Duration::from_millis(1))).map_err(|e| e.0).unwrap();
    let started = wait_for_cycle(&cycle, 5);
    WATCHED.store(thread_named("akd-cycle"), Ordering::SeqCst);
    let armed = wait_for_cycle(&cycle, started.cycle);
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    let mut edges = 0;
    for n in 0..20 {
        cycle.set_channels(2, &[("channel_1_output", ChannelValue::Bit(n % 2 == 0))]).unwrap();
        control.change(Change::input_level(control.products(), 1, 1 + n % 4, n % 3 == 0)).unwrap();
        let later = wait_for_cycle(&cycle, cycle.snapshot().cycle + 5);
        edges += cycle.events().iter().filter(|e| matches!(e, Event::DeviceInputs { .. })).count();
        wait_for_cycle(&cycle, later.cycle);
    }
    control.change(Change::power_cycle(control.products(), 2)).unwrap();
    wait_until("the EL2004 lost and back", || cycle.recovery_status(2).unwrap().recoveries == 1);
    let recovered = cycle.events().iter().any(|e| matches!(e, Event::Fault { slave: 2, .. }));
    cycle.switch_outputs_off(2).unwrap();
    let last = wait_for_cycle(&cycle, cycle.snapshot().cycle + 20);
    let during = ALLOCATIONS.load(Ordering::SeqCst) - before;
    WATCHED.store(0, Ordering::SeqCst);
    cycle.stop().unwrap();
    stop.store(true, Ordering::SeqCst);
    serving.join().unwrap().unwrap();
    eprintln!("cell: {} cycles watched, {edges} input edges reported", last.cycle - armed.cycle);
    assert!(edges > 0 && recovered, "{edges} edges, recovered {recovered}");
    assert_eq!(during, 0, "allocations in {} cycles of the cell", last.cycle - armed.cycle);
}

/// The run for one way of taking each frame's return: waited for, or `pipelined`.
fn loop_allocates_nothing(pipelined: bool) {
    let socket = server::bind_udp("127.0.0.1:0".parse().unwrap()).unwrap();
    let address = socket.local_addr().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let serving = {
        let stop = stop.clone();
        std::thread::spawn(move || {
            server::serve_udp_on(socket, VirtualBus::with_timing(3, LATE_IS_NOT_MISSED), &stop, None)
        })
    };
    let mut m = Master::new(Box::new(Udp::connect(&address.to_string()).unwrap()), Duration::from_millis(500));
    let deadline = Instant::now() + Duration::from_secs(5);
    while m.scan().is_err() {
        assert!(Instant::now() < deadline, "no simulator on {address}");
    }
    m.request_state(AlState::PreOp, Duration::from_secs(5)).unwrap();
    let mac = [0x02, 0x01, 0x05, 0x30, 0x10, 0x01];
    let ip = std::net::Ipv4Addr::new(192, 168, 0, 10);
    let parameters = akd_native::ethercat::eoe::IpParameters {
        mac: Some(mac),
        ip: Some(ip),
        subnet_mask: Some(std::net::Ipv4Addr::new(255, 255, 255, 0)),
        ..Default::default()
    };
    m.slave_mut(0).unwrap().eoe_set_ip(&parameters).unwrap();
    // The host's ARP request, from which the drive learns where to send its replies.
    m.slave_mut(0).unwrap().eoe_send(&ethernet::who_has(ip)).unwrap();
    m.configure_dc(1_000_000, 0).unwrap();
    let (rx, tx) = profile::profile_mapping();
    m.slave_mut(2).unwrap().configure_pdo(rx, tx).unwrap();
    m.slave_mut(2).unwrap().sdo_write(0x6060, 0, &[Mode::ProfilePosition as u8]).unwrap();
    m.request_state(AlState::Op, Duration::from_secs(5)).unwrap();
    let config = Config {
        realtime: RealTime { pipelined, ..RealTime::default() },
        line_health: Some(Duration::from_millis(20)),
        ..Config::new(Duration::from_millis(1))
    };
    let cycle = CycleThread::start(m, config).map_err(|e| e.0).unwrap();
    let started = wait_for_cycle(&cycle, 5);
    WATCHED.store(thread_named("akd-cycle"), Ordering::SeqCst);
    // The counter sees the watched thread only: this thread's allocation is not counted.
    drop(std::hint::black_box(Vec::<u8>::with_capacity(8)));
    let armed = wait_for_cycle(&cycle, started.cycle);
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    let line_reads = cycle.line_health().health.reads;
    // Set-points written, drives sequenced and snapshots read meanwhile, as a user would.
    cycle.request(1, Request::Enable).unwrap();
    let (trajectories, pings) = std::thread::scope(|scope| {
        let trajectories = scope.spawn(|| trajectories(&cycle));
        let pings = scope.spawn(|| pings(&cycle, mac, ip));
        set_points_and_requests(&cycle);
        (trajectories.join().unwrap(), pings.join().unwrap())
    });
    let handshake = set_point_and_command_timeouts(&cycle);
    let last = wait_for_cycle(&cycle, armed.cycle + 300);
    let during = ALLOCATIONS.load(Ordering::SeqCst) - before;
    WATCHED.store(0, Ordering::SeqCst);
    let line_reads = cycle.line_health().health.reads - line_reads;
    let stats = cycle.stats();
    let (lost, wkc) = (stats.lost_frames.load(Ordering::Relaxed), stats.wkc_errors.load(Ordering::Relaxed));
    // The sequencer did run in those cycles.
    let sequenced = cycle.drive_status(1).unwrap();
    let command_timeouts = cycle.command_timeout_status(2).unwrap().timeouts;
    let master = cycle.stop().unwrap();
    stop.store(true, Ordering::SeqCst);
    serving.join().unwrap().unwrap();
    // A machine loaded beyond its cores can delay the simulator past the 1 ms frame time-out:
    // a lost frame is counted, costs no allocation either, and may fault the drive (F125) once
    // it was enabled. What must hold is that the sequencer got the drive there and nothing
    // allocated.
    eprintln!(
        "pipelined {pipelined}: {} cycles watched, {lost} lost frames, {wkc} WKC errors",
        last.cycle - armed.cycle
    );
    assert!(
        sequenced.progress == Progress::Done || (sequenced.progress == Progress::Lost && lost > 0),
        "{sequenced:?}"
    );
    // Drive 2 went through the handshake and both time-outs, and drive 1 through both
    // trajectories, unless lost frames faulted them.
    if lost == 0 {
        let states = trajectories.map(|t| t.map(|s| s.map(|s| s.state)));
        assert_eq!(states, Some([Some(TrajectoryState::Replaced { by: 2 }), Some(TrajectoryState::Done)]));
        assert_eq!(handshake.map(|s| s.progress), Some(handshake::Progress::Done), "{handshake:?}");
        assert_eq!(command_timeouts, 2);
        assert_eq!(pings, 20, "echo replies");
    }
    assert!(line_reads > 0, "the line's health was not read in the cycles watched");
    assert_eq!(during, 0, "allocations in {} cycles (pipelined {pipelined})", last.cycle - armed.cycle);
    drop(master);
}

/// Drive 0 pinged 20 times through EoE, every other ping of 1400 bytes (two fragments each
/// way), 10 ms apart; the pings answered. Each reply is judged by its own sequence number, so
/// one that comes after the next ping went out is still its own ping's: each ping waits up to
/// a second for its reply, and those still missing at the end up to ten seconds more. (Back to
/// back, a debug build's cycle carrying a fragment in most cycles over UDP overran its 1 ms in
/// about half of them.)
fn pings(cycle: &CycleThread, mac: [u8; 6], ip: std::net::Ipv4Addr) -> usize {
    const PINGS: u16 = 20;
    let data = |seq_no: u16| vec![seq_no as u8; if seq_no.is_multiple_of(2) { 56 } else { 1400 }];
    // The drive's announcement and its answer to the ARP request, sent before the cycle.
    while cycle.eoe_receive(Duration::from_millis(100)).is_some_and(|(_, f)| f[12..14] == [0x08, 0x06]) {}
    // Takes the next reply within `timeout`, if one comes, checked against its own ping.
    let take = |answered: &mut [bool], timeout| {
        let Some((_, frame)) = cycle.eoe_receive(timeout) else { return };
        let (seq_no, _) = ethernet::echo_reply(&frame, ip).expect("an echo reply");
        ethernet::check_echo_reply(&frame, ip, &data(seq_no), seq_no);
        let seen = answered.get_mut(seq_no as usize).expect("the reply of a ping sent");
        assert!(!std::mem::replace(seen, true), "ping {seq_no} answered twice");
    };
    let mut answered = [false; PINGS as usize];
    for seq_no in 0..PINGS {
        std::thread::sleep(Duration::from_millis(10));
        cycle.eoe_send(0, &ethernet::ping(ip, mac, &data(seq_no), seq_no)).unwrap();
        let deadline = Instant::now() + Duration::from_secs(1);
        while !answered[seq_no as usize] && Instant::now() < deadline {
            take(&mut answered, Duration::from_millis(100));
        }
    }
    let deadline = Instant::now() + Duration::from_secs(10);
    while answered.contains(&false) && Instant::now() < deadline {
        take(&mut answered, Duration::from_millis(100));
    }
    answered.iter().filter(|&&a| a).count()
}

/// Drive 0's set-points written and its requests made, as a user would.
fn set_points_and_requests(cycle: &CycleThread) {
    for n in 0..200u32 {
        cycle.set_outputs(0, &[n as u8, 0, 0, 0, 0x06, 0]).unwrap();
        if n % 50 == 0 {
            let request = [Request::Enable, Request::QuickStop, Request::Disable, Request::FaultReset][n as usize / 50];
            cycle.request(0, request).unwrap();
        }
        std::hint::black_box((cycle.snapshot(), cycle.drive_status(1).unwrap()));
    }
}

/// Drive 1 enabled follows a trajectory of 10 s that another of 100 ms replaces 50 ms into it
/// (long enough to be still running then when a loaded host stalls this thread, as a first of
/// 100 ms was not); their final statuses, `None` when the drive could not be enabled.
fn trajectories(cycle: &CycleThread) -> Option<[Option<TrajectoryStatus>; 2]> {
    let enabled = || cycle.drive_status(1).unwrap().state() == Some(State::OperationEnabled);
    wait_until("drive 1 enabled", || enabled() || cycle.drive_status(1).unwrap().progress != Progress::InProgress);
    if !enabled() {
        return None;
    }
    let at = |ms: u64, position: f64| (ms * 1_000_000, vec![Knot { velocity: Some(0.0), ..Knot::position(position) }]);
    let ((t0, p0), (t1, p1)) = (at(5000, 5000.0), at(10_000, -5000.0));
    let first = cycle.follow_trajectory(&[1], &[t0, t1], &[p0, p1], None, None).unwrap();
    std::thread::sleep(Duration::from_millis(50));
    let (t, p) = at(100, 0.0);
    let second = cycle.follow_trajectory(&[1], &[t], &[p], None, None).unwrap();
    let ended = |id| cycle.trajectory_status(id).ok().filter(|s| s.state.ended());
    wait_until("the second trajectory's end", || ended(second).is_some() || !enabled());
    Some([ended(first), ended(second)])
}

fn wait_until(what: &str, done: impl Fn() -> bool) {
    let deadline = Instant::now() + Duration::from_secs(10);
    while !done() {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Drive 2: a profile-position set-point, then a velocity stream that times out twice, halted
/// and released by the next write, then quick-stopped. The handshake's end, `None` when the
/// drive could not be enabled (a lost frame on a loaded machine can fault it).
fn set_point_and_command_timeouts(cycle: &CycleThread) -> Option<handshake::HandshakeStatus> {
    cycle.request(2, Request::Enable).unwrap();
    let enabled = || cycle.drive_status(2).unwrap().state() == Some(State::OperationEnabled);
    wait_until("drive 2 enabled", || enabled() || cycle.drive_status(2).unwrap().progress != Progress::InProgress);
    if !enabled() {
        return None;
    }
    cycle.set_object(2, 0x607A, 0, &1000i32.to_le_bytes()).unwrap();
    cycle.start_setpoint(2, 0x0030, None).unwrap();
    let handshake = cycle.wait_setpoint(2, None).ok();
    cycle.set_mode(2, Mode::ProfileVelocity as i8).unwrap();
    let timeouts = || cycle.command_timeout_status(2).unwrap().timeouts;
    for (n, action) in [CommandTimeoutAction::Halt, CommandTimeoutAction::QuickStop].into_iter().enumerate() {
        cycle.set_command_timeout(2, Some(Duration::from_millis(20)), action).unwrap();
        cycle.set_object(2, 0x60FF, 0, &10_000i32.to_le_bytes()).unwrap();
        wait_until("a command time-out", || timeouts() > n as u64 || !enabled());
        // Released by the next write.
        cycle.set_object(2, 0x60FF, 0, &0i32.to_le_bytes()).unwrap();
    }
    handshake
}
