//! The virtual AKD moves like a drive, seen through the real master over an in-process link
//! whose clock the test steps (1 ms cycles, deterministic): every CiA 402 transition, each mode
//! tracking a moving target within a stated bound, a bumpless enable and mode change, latches
//! and touch probes firing where the simulated input toggles, F125 after the eighth missed frame, F706, the
//! following-error fault, injected faults and the fault reset on the rising edge of bit 7.

use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use akd_native::drive::akd::AkdSlave;
use akd_native::drive::ds402::{controlword as cw, statusword as sw, State};
use akd_native::drive::pdo::Mapping;
use akd_native::error::Result;
use akd_native::ethercat::al::AlState;
use akd_native::ethercat::link::{Link, Returns};
use akd_native::ethercat::master::Master;
use akd_native::ethercat::pdo::{self, PdoEntry};
use akd_native::sim::faults::Fault;
use akd_native::sim::{Timing, VirtualBus};

/// The cycle time, written to 0x60C2.
const CYCLE_NS: u64 = 1_000_000;
/// Bus time one frame takes, so that mailbox and AL traffic moves the clock too.
const FRAME_NS: u64 = 1_000;
const REV: f64 = (1u64 << 20) as f64;
const STEP: Duration = Duration::from_secs(5);

/// The bus clock the test owns, and the frames the link is to lose.
#[derive(Default)]
struct Clock {
    now: AtomicU64,
    lose: AtomicU32,
}

/// A link to a shared virtual bus at the test's bus time.
struct Stepped {
    bus: Arc<Mutex<VirtualBus>>,
    clock: Arc<Clock>,
    returns: Returns,
}

impl Link for Stepped {
    fn send(&mut self, tx: &[u8]) -> Result<()> {
        let now = self.clock.now.fetch_add(FRAME_NS, Ordering::SeqCst) + FRAME_NS;
        if self.clock.lose.load(Ordering::SeqCst) > 0 {
            self.clock.lose.fetch_sub(1, Ordering::SeqCst);
            return Ok(());
        }
        let bus = &self.bus;
        self.returns.serve(tx, |frame| {
            bus.lock().unwrap().process(frame, now)?;
            Ok(true)
        })
    }

    fn receive(&mut self, rx: &mut [u8], _deadline: Instant) -> Result<Option<usize>> {
        self.returns.take(rx)
    }

    fn describe(&self) -> String {
        "stepped sim".into()
    }
}

const fn e(index: u16, subindex: u8, bits: u8) -> PdoEntry {
    PdoEntry::new(index, subindex, bits)
}

/// Outputs (22 bytes, the AKD's most): controlword, mode, latch control, CSP target, target
/// velocity, IP set-point, torque, touch probe function.
fn rx_mapping() -> Vec<Vec<PdoEntry>> {
    vec![
        vec![e(0x6040, 0, 16), e(0x6060, 0, 8), e(0x0002, 0, 8), e(0x20A4, 0, 16)],
        vec![e(0x607A, 0, 32), e(0x60FF, 0, 32)],
        vec![e(0x60C1, 1, 32), e(0x6071, 0, 16), e(0x60B8, 0, 16)],
    ]
}

/// Inputs (32 bytes, the AKD's most): statusword, mode display, latch status, touch probe
/// status, positions, velocity, following error, latch positions, torque.
fn tx_mapping() -> Vec<Vec<PdoEntry>> {
    vec![
        vec![e(0x6041, 0, 16), e(0x6061, 0, 8), e(0x2002, 1, 8), e(0x20A5, 0, 16), e(0x60B9, 0, 16)],
        vec![e(0x6064, 0, 32), e(0x606C, 0, 32)],
        vec![e(0x60F4, 0, 32), e(0x20A0, 0, 32)],
        vec![e(0x6077, 0, 16), e(0x2002, 2, 8), e(0x2002, 3, 8), e(0x20A1, 0, 32)],
    ]
}

fn offset(entries: &[Vec<PdoEntry>], index: u16, subindex: u8) -> (usize, usize) {
    pdo::layout(entries.concat())
        .find(|(_, e)| (e.index, e.subindex) == (index, subindex))
        .map(|(at, e)| (at, e.bits as usize / 8))
        .unwrap_or_else(|| panic!("0x{index:04X}:{subindex} is not mapped"))
}

/// One virtual AKD in Op with the mappings above, at a 1 ms cycle.
struct Rig {
    m: Master,
    bus: Arc<Mutex<VirtualBus>>,
    clock: Arc<Clock>,
    outputs: Vec<u8>,
}

impl Rig {
    fn new() -> Rig {
        let mut rig = Rig::preop();
        rig.m
            .slave_mut(0)
            .unwrap()
            .configure_pdo(Mapping::Flexible(rx_mapping()), Mapping::Flexible(tx_mapping()))
            .unwrap();
        rig.m.slave_mut(0).unwrap().set_cycle_time(CYCLE_NS as u32).unwrap();
        rig.m.request_state(AlState::Op, STEP).unwrap();
        rig.outputs = vec![0; rig.m.slave_mut(0).unwrap().outputs().unwrap().len()];
        rig.cycles(2);
        rig
    }

    fn preop() -> Rig {
        let bus = Arc::new(Mutex::new(VirtualBus::with_timing(1, Timing::IMMEDIATE)));
        let clock = Arc::new(Clock::default());
        let link = Stepped { bus: bus.clone(), clock: clock.clone(), returns: Returns::default() };
        let mut m = Master::new(Box::new(link), Duration::from_millis(10));
        m.scan().unwrap();
        m.request_state(AlState::PreOp, STEP).unwrap();
        Rig { m, bus, clock, outputs: Vec::new() }
    }

    fn set(&mut self, index: u16, subindex: u8, value: i64) {
        let (at, len) = offset(&rx_mapping(), index, subindex);
        self.outputs[at..at + len].copy_from_slice(&value.to_le_bytes()[..len]);
    }

    fn get(&self, index: u16, subindex: u8) -> i64 {
        let (at, len) = offset(&tx_mapping(), index, subindex);
        let mut bytes = [0u8; 8];
        // The whole input image, as the cycle thread reads it, since this reader holds `&self`.
        let at = self.m.image_slot(0).unwrap().in_offset + at;
        bytes[..len].copy_from_slice(&self.m.input_image().unwrap()[at..at + len]);
        // Sign-extend the signed objects of this mapping (positions, velocity, torque).
        let value = i64::from_le_bytes(bytes);
        match (index, len) {
            (0x6041 | 0x20A5 | 0x60B9, _) => value,
            (_, 2) => value as i16 as i64,
            (_, 4) => value as i32 as i64,
            _ => value,
        }
    }

    /// Lets the bus clock run to the next cycle's start.
    fn tick(&self) {
        let now = self.clock.now.load(Ordering::SeqCst);
        self.clock.now.store((now / CYCLE_NS + 1) * CYCLE_NS, Ordering::SeqCst);
    }

    /// One cycle; the frame may be lost on purpose.
    fn cycle(&mut self) -> Result<u16> {
        self.tick();
        self.m.slave_mut(0).unwrap().set_outputs(&self.outputs.clone()).unwrap();
        self.m.exchange()
    }

    fn cycles(&mut self, n: usize) {
        for _ in 0..n {
            self.cycle().unwrap();
        }
    }

    fn statusword(&self) -> u16 {
        self.get(0x6041, 0) as u16
    }

    fn state(&self) -> State {
        State::from_statusword(self.statusword()).expect("a statusword of §4's table")
    }

    fn position(&self) -> i64 {
        self.get(0x6064, 0)
    }

    /// Sends `controlword` and returns the state the drive shows two cycles later (one to
    /// reach the drive, one to bring the statusword back).
    fn command(&mut self, controlword: u16) -> State {
        self.set(0x6040, 0, controlword as i64);
        self.cycles(2);
        self.state()
    }

    /// Operation enabled in `mode`, the position target at the actual position.
    fn enable(&mut self, mode: i8) {
        self.set(0x6060, 0, mode as i64);
        self.follow_actual();
        for controlword in [cw::SHUTDOWN, cw::SWITCH_ON_COMMAND, cw::ENABLE_OPERATION_COMMAND] {
            self.follow_actual();
            self.command(controlword);
        }
        assert_eq!(self.state(), State::OperationEnabled);
    }

    fn follow_actual(&mut self) {
        let actual = self.position();
        self.set(0x607A, 0, actual);
        self.set(0x60C1, 1, actual);
    }

    fn inject(&self, fault: Fault) {
        self.bus.lock().unwrap().slave_mut(0).drive_mut().inject(fault);
    }
}

#[test]
fn every_ds402_transition_of_the_manual() {
    let mut rig = Rig::new();
    assert_eq!(rig.state(), State::SwitchOnDisabled, "transition 1 happens by itself");
    rig.set(0x6060, 0, 8);
    let steps: [(u16, State); 21] = [
        (cw::SHUTDOWN, State::ReadyToSwitchOn),                  // 2
        (cw::SWITCH_ON_COMMAND, State::SwitchedOn),              // 3
        (cw::ENABLE_OPERATION_COMMAND, State::OperationEnabled), // 4
        (cw::SWITCH_ON_COMMAND, State::SwitchedOn),              // 5
        (cw::SHUTDOWN, State::ReadyToSwitchOn),                  // 6
        (cw::DISABLE_VOLTAGE, State::SwitchOnDisabled),          // 7
        (cw::SHUTDOWN, State::ReadyToSwitchOn),                  // 2
        (cw::QUICK_STOP_COMMAND, State::SwitchOnDisabled),       // 7 by quick stop
        (cw::SHUTDOWN, State::ReadyToSwitchOn),                  // 2
        (cw::SWITCH_ON_COMMAND, State::SwitchedOn),              // 3
        (cw::DISABLE_VOLTAGE, State::SwitchOnDisabled),          // 10
        (cw::ENABLE_OPERATION_COMMAND, State::SwitchOnDisabled), // nothing from here
        (cw::SHUTDOWN, State::ReadyToSwitchOn),                  // 2
        (cw::ENABLE_OPERATION_COMMAND, State::OperationEnabled), // 3 then 4
        (cw::SHUTDOWN, State::ReadyToSwitchOn),                  // 8
        (cw::ENABLE_OPERATION_COMMAND, State::OperationEnabled), // 3, 4
        (cw::DISABLE_VOLTAGE, State::SwitchOnDisabled),          // 9
        (cw::ENABLE_OPERATION_COMMAND, State::SwitchOnDisabled), // no shortcut
        (cw::SHUTDOWN, State::ReadyToSwitchOn),                  // 2
        (cw::ENABLE_OPERATION_COMMAND, State::OperationEnabled), // 3, 4
        (cw::QUICK_STOP_COMMAND, State::QuickStopActive),        // 11
    ];
    for (i, (controlword, expected)) in steps.into_iter().enumerate() {
        rig.follow_actual();
        assert_eq!(rig.command(controlword), expected, "step {i}: controlword 0x{controlword:04X}");
        let word = rig.statusword();
        assert_ne!(word & sw::REMOTE, 0, "remote is always 1");
        let voltage = matches!(expected, State::SwitchedOn | State::OperationEnabled | State::QuickStopActive);
        assert_eq!(word & sw::VOLTAGE_ENABLED != 0, voltage, "voltage enabled in {}", expected.name());
    }
    assert_eq!(rig.command(cw::ENABLE_OPERATION_COMMAND), State::OperationEnabled, "16");
    assert_eq!(rig.command(cw::QUICK_STOP_COMMAND), State::QuickStopActive, "11");
    assert_eq!(rig.command(cw::DISABLE_VOLTAGE), State::SwitchOnDisabled, "12");

    // A fault (13, 14), then a reset: only the rising edge of bit 7 resets (15).
    rig.enable(8);
    rig.set(0x6040, 0, (cw::ENABLE_OPERATION_COMMAND | cw::FAULT_RESET) as i64);
    rig.cycles(2);
    rig.inject(Fault::OverTemperature);
    rig.cycles(3);
    assert_eq!(rig.state(), State::Fault, "a drive at rest leaves Fault reaction active at once");
    assert_eq!(rig.m.slave_mut(0).unwrap().sdo_read(0x603F, 0).unwrap(), 0x4310u16.to_le_bytes());
    let emergencies = rig.m.slave_mut(0).unwrap().take_emergencies().unwrap();
    assert_eq!(emergencies.iter().map(|e| e.error_code).collect::<Vec<_>>(), [0x4310]);
    assert_eq!(&emergencies[0].data[..4], b"F235");
    assert_eq!(rig.command(cw::FAULT_RESET), State::Fault, "bit 7 was already high: no edge");
    assert_eq!(rig.command(cw::ENABLE_OPERATION_COMMAND), State::Fault, "no reset without bit 7");
    assert_eq!(rig.command(cw::FAULT_RESET), State::SwitchOnDisabled, "15 on the rising edge");
}

/// Runs `cycles` cycles with `target(cycle)` as set-point at `index:subindex`, returning the
/// largest |0x60F4| and the largest |actual − the set-point sent a cycle before| (the drive
/// interpolates to a set-point during the cycle after it was sent, and the actual value of
/// that cycle's end comes back with the next frame).
fn track(rig: &mut Rig, cycles: usize, mut target: impl FnMut(usize) -> i64, index: u16, subindex: u8) -> (i64, i64) {
    let (mut following, mut lag) = (0, 0);
    let mut sent = Vec::new();
    for k in 0..cycles {
        let value = target(k);
        rig.set(index, subindex, value);
        sent.push(value);
        rig.cycle().unwrap();
        following = following.max(rig.get(0x60F4, 0).abs());
        if k >= 1 {
            lag = lag.max((rig.position() - sent[k - 1]).abs());
        }
        assert_eq!(rig.state(), State::OperationEnabled, "cycle {k}");
    }
    (following, lag)
}

#[test]
fn cyclic_position_modes_track_a_moving_target_and_enable_without_a_jump() {
    for (mode, index, subindex) in [(8i8, 0x607A, 0), (7, 0x60C1, 1)] {
        let mut rig = Rig::new();
        let start = rig.position();
        rig.enable(mode);
        rig.follow_actual();
        rig.cycles(50);
        assert!((rig.position() - start).abs() <= 1, "mode {mode}: enable moved the axis");
        assert_eq!(rig.get(0x6061, 0), mode as i64);
        // A 1 Hz cosine of 2 revolutions' amplitude from rest (peak 12.6 rev/s, 79 rev/s²) for
        // two seconds.
        let here = rig.position();
        let wave = |k: usize| here + (2.0 * REV * (1.0 - (std::f64::consts::TAU * k as f64 * 1e-3).cos())) as i64;
        let (following, lag) = track(&mut rig, 2000, wave, index, subindex);
        // Bounds: following error and distance to the set-point under 0.002 rev (0.72°).
        assert!(following < (REV * 0.002) as i64, "mode {mode}: following error {following} counts");
        assert!(lag < (REV * 0.002) as i64, "mode {mode}: actual {lag} counts from the set-point");
        // A mode change with the target at the actual position moves nothing.
        rig.cycles(200);
        let here = rig.position();
        let other = if mode == 8 { 7 } else { 8 };
        rig.follow_actual();
        rig.set(0x6060, 0, other as i64);
        rig.cycles(50);
        assert_eq!(rig.get(0x6061, 0), other as i64);
        assert!((rig.position() - here).abs() <= 1, "mode {mode} to {other} moved the axis");
    }
}

#[test]
fn profile_velocity_torque_and_profile_position_track() {
    let mut rig = Rig::new();
    rig.enable(3);
    rig.set(0x60FF, 0, (5.0 * REV) as i64);
    rig.cycles(500);
    // 5 rev/s reached in 50 ms at 100 rev/s²; after 0.5 s within 0.01 rev/s.
    assert!((rig.get(0x606C, 0) - (5.0 * REV) as i64).abs() < (REV * 0.01) as i64, "{}", rig.get(0x606C, 0));
    assert_ne!(rig.statusword() & sw::TARGET_REACHED, 0);
    // Halt ramps to zero and holds.
    rig.set(0x6040, 0, (cw::ENABLE_OPERATION_COMMAND | cw::HALT) as i64);
    rig.cycles(200);
    assert!(rig.get(0x606C, 0).abs() < (REV * 0.01) as i64, "halted: {}", rig.get(0x606C, 0));
    rig.set(0x6040, 0, cw::ENABLE_OPERATION_COMMAND as i64);

    // Torque: 10 % of the peak torque is given and accelerates the motor.
    rig.set(0x6071, 0, 100);
    rig.set(0x6060, 0, 4);
    rig.cycles(20);
    let v0 = rig.get(0x606C, 0);
    rig.cycles(20);
    assert!((rig.get(0x6077, 0) - 100).abs() <= 1, "torque actual {}", rig.get(0x6077, 0));
    assert!(rig.get(0x606C, 0) > v0, "10 % torque accelerates");

    // Profile position: 3 revolutions further, started by the rising edge of bit 4.
    rig.set(0x6071, 0, 0);
    rig.set(0x60FF, 0, 0);
    rig.set(0x6060, 0, 3);
    rig.cycles(500);
    rig.set(0x6060, 0, 1);
    rig.cycles(2);
    let target = rig.position() + (3.0 * REV) as i64;
    rig.set(0x607A, 0, target);
    rig.set(0x6040, 0, (cw::ENABLE_OPERATION_COMMAND | cw::NEW_SETPOINT) as i64);
    rig.cycles(2);
    assert_ne!(rig.statusword() & sw::MODE_SPECIFIC_12, 0, "set-point acknowledged");
    assert_eq!(rig.statusword() & sw::TARGET_REACHED, 0);
    rig.set(0x6040, 0, cw::ENABLE_OPERATION_COMMAND as i64);
    rig.cycles(1000);
    assert!((rig.position() - target).abs() <= 100, "{} from {target}", rig.position());
    assert_ne!(rig.statusword() & sw::TARGET_REACHED, 0);
}

#[test]
fn latches_capture_within_one_count_of_where_the_input_toggled() {
    let mut rig = Rig::new();
    let (rise, fall) = (1_234_567.0, 2_345_678.25);
    rig.bus.lock().unwrap().slave_mut(0).drive_mut().inputs_mut().set_toggles(1, &[rise, fall]).unwrap();
    rig.enable(3);
    rig.set(0x20A4, 0, 0x0003); // latch 1, both edges
    rig.set(0x60B8, 0, 0x0011); // touch probe 1, rising edge
    rig.set(0x60FF, 0, (3.0 * REV) as i64);
    rig.cycles(1500);
    assert!(rig.position() > fall as i64);
    let status = rig.get(0x20A5, 0);
    assert_eq!(status & 0x0F, 0x03, "latch 1 rising and falling valid: 0x{status:04X}");
    assert!((rig.get(0x20A0, 0) as f64 - rise).abs() <= 1.0, "rising {}", rig.get(0x20A0, 0));
    assert!((rig.get(0x20A1, 0) as f64 - fall).abs() <= 1.0, "falling {}", rig.get(0x20A1, 0));
    assert_eq!(status & 0x8000, 0, "input 1 is low again past its second toggle");
    assert_eq!(rig.get(0x60B9, 0), 0x0003, "touch probe 1 enabled, rising edge stored");
    let probe = i32::from_le_bytes(rig.m.slave_mut(0).unwrap().sdo_read(0x60BA, 0).unwrap().try_into().unwrap());
    assert_eq!(probe as i64, rig.get(0x20A0, 0), "the same capture as latch 1 rising");
}

#[test]
fn f125_after_the_eighth_missed_frame() {
    let mut rig = Rig::new();
    rig.enable(8);
    for lost in [1, 7] {
        rig.clock.lose.store(lost, Ordering::SeqCst);
        for _ in 0..lost {
            assert!(rig.cycle().is_err());
        }
        rig.follow_actual();
        rig.cycles(2);
        assert_eq!(rig.state(), State::OperationEnabled, "{lost} missed frames are tolerated");
    }
    rig.clock.lose.store(8, Ordering::SeqCst);
    for _ in 0..8 {
        assert!(rig.cycle().is_err());
    }
    rig.cycles(3);
    assert_eq!(rig.state(), State::Fault, "the eighth missed frame raises F125");
    assert_eq!(rig.m.slave_mut(0).unwrap().sdo_read(0x603F, 0).unwrap(), 0x8700u16.to_le_bytes());
    let codes: Vec<u16> =
        rig.m.slave_mut(0).unwrap().take_emergencies().unwrap().iter().map(|e| e.error_code).collect();
    assert_eq!(codes, [0x8700]);
    assert_eq!(rig.m.stats().lost_frames, 16);
}

#[test]
fn f706_when_enabled_by_sdo_before_any_set_point() {
    let mut rig = Rig::preop();
    rig.m.slave_mut(0).unwrap().sdo_write(0x6060, 0, &[8]).unwrap();
    for controlword in [cw::SHUTDOWN, cw::SWITCH_ON_COMMAND, cw::ENABLE_OPERATION_COMMAND] {
        rig.m.slave_mut(0).unwrap().sdo_write(0x6040, 0, &controlword.to_le_bytes()).unwrap();
    }
    let statusword = |rig: &mut Rig| {
        u16::from_le_bytes(rig.m.slave_mut(0).unwrap().sdo_read(0x6041, 0).unwrap().try_into().unwrap())
    };
    assert_eq!(State::from_statusword(statusword(&mut rig)), Some(State::OperationEnabled));
    rig.clock.now.fetch_add(50_000_000, Ordering::SeqCst);
    assert_eq!(State::from_statusword(statusword(&mut rig)), Some(State::OperationEnabled), "within 100 ms");
    rig.clock.now.fetch_add(60_000_000, Ordering::SeqCst);
    assert_eq!(State::from_statusword(statusword(&mut rig)), Some(State::Fault));
    assert_eq!(rig.m.slave_mut(0).unwrap().sdo_read(0x603F, 0).unwrap(), 0x8250u16.to_le_bytes());
    assert_eq!(rig.m.slave_mut(0).unwrap().take_emergencies().unwrap()[0].data[..4], *b"F706");
}

#[test]
fn a_target_far_from_the_actual_position_raises_the_following_error_fault() {
    let mut rig = Rig::new();
    rig.enable(8);
    // The classic start-up mistake: a target left at some other place.
    rig.set(0x607A, 0, rig.position() + (50.0 * REV) as i64);
    rig.cycles(100);
    assert_eq!(rig.state(), State::Fault);
    assert_eq!(rig.m.slave_mut(0).unwrap().sdo_read(0x603F, 0).unwrap(), 0x8611u16.to_le_bytes());
    assert_eq!(rig.m.slave_mut(0).unwrap().take_emergencies().unwrap()[0].error_code, 0x8611);
}

#[test]
fn hardware_enable_low_drops_to_switch_on_disabled_with_a_warning() {
    let mut rig = Rig::new();
    rig.enable(8);
    rig.bus.lock().unwrap().slave_mut(0).drive_mut().set_hardware_enable(false);
    rig.cycles(2);
    assert_eq!(rig.state(), State::SwitchOnDisabled);
    assert_ne!(rig.statusword() & sw::WARNING, 0);
    assert_eq!(rig.command(cw::SHUTDOWN), State::ReadyToSwitchOn);
    assert_eq!(rig.command(cw::ENABLE_OPERATION_COMMAND), State::SwitchOnDisabled, "cannot switch on");
    rig.bus.lock().unwrap().slave_mut(0).drive_mut().set_hardware_enable(true);
    rig.enable(8);
    assert_eq!(rig.statusword() & sw::WARNING, 0);
    assert!(rig.m.slave_mut(0).unwrap().take_emergencies().unwrap().is_empty(), "hardware enable is not a fault");
}
