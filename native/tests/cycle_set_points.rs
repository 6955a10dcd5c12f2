//! The set-point handshake and the command time-out in the cycle thread, against a virtual AKD
//! mapped for the profile modes. The waits have deadlines only so that a failure does not hang;
//! no timing is asserted beyond "not before the time-out".

use std::time::{Duration, Instant};

use akd_native::cycle::events::{CommandTimeoutAction, CommandedTarget, Event};
use akd_native::cycle::handshake::{Progress, Stuck};
use akd_native::cycle::sequencer::Request;
use akd_native::cycle::CycleThread;
use akd_native::drive::ds402::{controlword as cw, Mode, State};
use akd_native::drive::pdo::Mapping;

#[path = "support/one_drive.rs"]
mod one_drive;
#[path = "support/profile.rs"]
mod profile;
use one_drive::{one_drive, wait_until};
use profile::{inputs, outputs, profile_mapping};

/// One virtual AKD in `mode`, mapped for the profile modes (or with `mapping`), cycled at 1 kHz.
fn rig_with(mode: Mode, mapping: Option<(Mapping, Mapping)>) -> CycleThread {
    one_drive(mode, mapping.unwrap_or_else(profile_mapping)).0
}

fn rig(mode: Mode) -> CycleThread {
    rig_with(mode, None)
}

fn enabled(cycle: &CycleThread) {
    cycle.request(0, Request::Enable).unwrap();
    wait_until("Operation enabled", || {
        (cycle.drive_status(0).unwrap().state() == Some(State::OperationEnabled)).then_some(())
    });
}

/// The mode display once it shows `mode`.
fn shows_mode(cycle: &CycleThread, mode: Mode) {
    wait_until("the mode display", || (cycle.drive_status(0).unwrap().mode_display == Some(mode as i8)).then_some(()));
}

fn input_i32(cycle: &CycleThread, at: usize) -> i32 {
    let s = cycle.snapshot();
    i32::from_le_bytes(cycle.inputs_of(&s, 0).unwrap()[at..at + 4].try_into().unwrap())
}

/// The controlword the last cycle sent.
fn sent_controlword(cycle: &CycleThread) -> u16 {
    let s = cycle.snapshot();
    let out = cycle.outputs_of(&s, 0).unwrap();
    u16::from_le_bytes([out[outputs::CONTROLWORD], out[outputs::CONTROLWORD + 1]])
}

fn cycles(cycle: &CycleThread, count: u64) {
    let later = cycle.snapshot().cycle + count;
    wait_until("cycles", || (cycle.snapshot().cycle >= later).then_some(()));
}

#[test]
fn a_profile_position_set_point_is_acknowledged_and_the_axis_goes_there() {
    let cycle = rig(Mode::ProfilePosition);
    enabled(&cycle);
    let target = input_i32(&cycle, inputs::POSITION) + 200_000;
    cycle.set_object(0, 0x607A, 0, &target.to_le_bytes()).unwrap();
    let first = cycle.start_setpoint(0, 0x0030, None).unwrap();
    let status = cycle.wait_setpoint(0, Some(Duration::from_secs(5))).unwrap();
    assert_eq!((status.request, status.bits, status.progress), (first, 0x0030, Progress::Done));
    assert_ne!(status.statusword & 0x1000, 0, "bit 12 set: acknowledged");
    // Lowered after the acknowledgement, so the next set-point makes a new edge.
    cycles(&cycle, 3);
    assert_eq!(sent_controlword(&cycle) & 0x0030, 0);
    wait_until("the target", || ((input_i32(&cycle, inputs::POSITION) - target).abs() <= 10).then_some(()));
    // A second set-point at once, and back.
    let back = target - 200_000;
    cycle.set_object(0, 0x607A, 0, &back.to_le_bytes()).unwrap();
    assert_eq!(cycle.start_setpoint(0, 0x0030, None).unwrap(), first + 1);
    cycle.wait_setpoint(0, Some(Duration::from_secs(5))).unwrap();
    wait_until("the way back", || ((input_i32(&cycle, inputs::POSITION) - back).abs() <= 10).then_some(()));
}

#[test]
fn a_handshake_is_stuck_when_the_drive_is_not_enabled() {
    let cycle = rig(Mode::ProfilePosition);
    cycle.start_setpoint(0, 0x0030, None).unwrap();
    let e = cycle.wait_setpoint(0, None).unwrap_err().to_string();
    assert!(
        e.starts_with("timed out waiting for drive 0: set-point handshake (controlword bits 0x0030) stuck in"),
        "{e}"
    );
    assert!(e.contains("stuck in Switch on disabled"), "{e}");
    assert!(e.contains("the drive is not in Operation enabled"), "{e}");
    assert_eq!(cycle.setpoint_status(0).unwrap().progress, Progress::Stuck(Stuck::NotEnabled));
    assert_eq!(sent_controlword(&cycle) & cw::NEW_SETPOINT, 0);
}

#[test]
fn a_handshake_starts_from_bit_12_clear() {
    // Cyclic synchronous position shows bit 12 set all along: the bits are never raised.
    let cycle = rig(Mode::CyclicSynchronousPosition);
    enabled(&cycle);
    cycle.set_request_timeout(Duration::from_millis(100));
    cycle.start_setpoint(0, 0x0030, None).unwrap();
    let e = cycle.wait_setpoint(0, None).unwrap_err().to_string();
    assert!(e.contains("bit 12 stayed set"), "{e}");
    assert_eq!(sent_controlword(&cycle) & cw::NEW_SETPOINT, 0);
    // Homing attained stays set after a homing; a later handshake waits for it to clear (here
    // by a mode change to profile position) and then goes through.
    cycle.set_request_timeout(Duration::from_secs(10));
    cycle.set_mode(0, Mode::Homing as i8).unwrap();
    shows_mode(&cycle, Mode::Homing);
    cycle.start_setpoint(0, 0x0010, Some(Duration::from_secs(5))).unwrap();
    cycle.wait_setpoint(0, None).unwrap();
    cycle.start_setpoint(0, 0x0030, Some(Duration::from_secs(30))).unwrap();
    cycles(&cycle, 20);
    let waiting = cycle.setpoint_status(0).unwrap();
    assert_eq!(waiting.progress, Progress::InProgress);
    assert_ne!(waiting.statusword & 0x1000, 0);
    assert_eq!(sent_controlword(&cycle) & cw::NEW_SETPOINT, 0, "not raised while bit 12 is set");
    let e = cycle.wait_setpoint(0, Some(Duration::from_millis(10))).unwrap_err().to_string();
    assert!(e.contains("still in progress"), "{e}");
    cycle.set_mode(0, Mode::ProfilePosition as i8).unwrap();
    assert_eq!(cycle.wait_setpoint(0, None).unwrap().progress, Progress::Done);
}

#[test]
fn bad_handshake_bits_and_waits_are_refused_naming_what_is_allowed() {
    let cycle = rig(Mode::ProfilePosition);
    let e = cycle.wait_setpoint(0, None).unwrap_err().to_string();
    assert!(e.contains("no set-point handshake was asked for"), "{e}");
    for bits in [0x0020, 0x0110, 0] {
        let e = cycle.start_setpoint(0, bits, None).unwrap_err().to_string();
        assert!(e.contains("allowed are bit 4 (0x0010"), "{e}");
    }
    assert!(cycle.start_setpoint(3, 0x0010, None).is_err());
}

fn write_velocity(cycle: &CycleThread, v: i32) {
    cycle.set_object(0, 0x60FF, 0, &v.to_le_bytes()).unwrap();
}

/// Calls `write` every 5 ms for `how_long`; when it wrote last.
fn stream(how_long: Duration, mut write: impl FnMut()) -> Instant {
    let end = Instant::now() + how_long;
    loop {
        write();
        let last = Instant::now();
        if last >= end {
            return last;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn command_timeouts(cycle: &CycleThread) -> Vec<Event> {
    cycle.events().into_iter().filter(|e| matches!(e, Event::CommandTimeout { .. })).collect()
}

#[test]
fn a_stopped_velocity_stream_halts_until_the_next_write_and_leaves_a_user_halt_alone() {
    let cycle = rig(Mode::ProfileVelocity);
    enabled(&cycle);
    let timeout = Duration::from_millis(300);
    cycle.set_command_timeout(0, Some(timeout), CommandTimeoutAction::Halt).unwrap();
    // A stream longer than the time-out does not time out while it flows.
    let last = stream(Duration::from_millis(600), || write_velocity(&cycle, 100_000));
    assert!(command_timeouts(&cycle).is_empty());
    assert!(cycle.command_timeout_status(0).unwrap().armed);
    assert_eq!(sent_controlword(&cycle) & cw::HALT, 0);
    let event = wait_until("the time-out", || command_timeouts(&cycle).pop());
    assert!(last.elapsed() >= timeout, "not before the time-out");
    let Event::CommandTimeout { slave, target, value, timeout_us, statusword, action, .. } = event else {
        unreachable!()
    };
    assert_eq!((slave, target, value, timeout_us), (0, CommandedTarget::Velocity, 100_000, 300_000));
    assert_eq!(
        (State::from_statusword(statusword), action),
        (Some(State::OperationEnabled), CommandTimeoutAction::Halt)
    );
    let status = cycle.command_timeout_status(0).unwrap();
    assert_eq!((status.armed, status.halted, status.timeouts), (false, true, 1));
    // The event is pushed while the cycle builds its frame; the snapshot shows that frame once
    // it is back, so two snapshots later the halt is certainly in what was sent.
    cycles(&cycle, 2);
    assert_ne!(sent_controlword(&cycle) & cw::HALT, 0);
    wait_until("standstill", || (input_i32(&cycle, inputs::VELOCITY).abs() < 1000).then_some(()));
    assert_eq!(cycle.drive_status(0).unwrap().state(), Some(State::OperationEnabled));
    // It holds until the next write, which releases it.
    cycles(&cycle, 50);
    assert_ne!(sent_controlword(&cycle) & cw::HALT, 0);
    write_velocity(&cycle, 100_000);
    wait_until("the velocity again", || (input_i32(&cycle, inputs::VELOCITY) > 90_000).then_some(()));
    assert_eq!(sent_controlword(&cycle) & cw::HALT, 0);
    // A halt the user set is not the watchdog's to release.
    cycle.set_halt(0, true).unwrap();
    wait_until("the second time-out", || command_timeouts(&cycle).pop());
    write_velocity(&cycle, 100_000);
    wait_until("the watchdog's halt released", || (!cycle.command_timeout_status(0).unwrap().halted).then_some(()));
    cycles(&cycle, 5);
    assert_ne!(sent_controlword(&cycle) & cw::HALT, 0, "the user's halt stays");
    cycle.set_halt(0, false).unwrap();
    cycle.set_command_timeout(0, None, CommandTimeoutAction::Halt).unwrap();
    assert_eq!(cycle.command_timeout_status(0).unwrap().config, None);
}

#[test]
fn a_stopped_torque_stream_quick_stops_until_enabled_again() {
    let cycle = rig(Mode::ProfileTorque);
    enabled(&cycle);
    cycle.set_command_timeout(0, Some(Duration::from_millis(100)), CommandTimeoutAction::QuickStop).unwrap();
    cycle.set_object(0, 0x6071, 0, &50i16.to_le_bytes()).unwrap();
    let event = wait_until("the time-out", || command_timeouts(&cycle).pop());
    let Event::CommandTimeout { target, value, action, .. } = event else { unreachable!() };
    assert_eq!((target, value, action), (CommandedTarget::Torque, 50, CommandTimeoutAction::QuickStop));
    wait_until("Quick stop active", || {
        (cycle.drive_status(0).unwrap().state() == Some(State::QuickStopActive)).then_some(())
    });
    // The next command does not enable it again; enable does.
    cycle.set_object(0, 0x6071, 0, &50i16.to_le_bytes()).unwrap();
    cycles(&cycle, 20);
    assert_eq!(cycle.drive_status(0).unwrap().state(), Some(State::QuickStopActive));
    assert_eq!(cycle.command_timeout_status(0).unwrap().timeouts, 1);
    enabled(&cycle);
}

#[test]
fn zero_commands_and_position_commands_never_time_out() {
    let cycle = rig(Mode::ProfileVelocity);
    enabled(&cycle);
    cycle.set_command_timeout(0, Some(Duration::from_millis(50)), CommandTimeoutAction::Halt).unwrap();
    write_velocity(&cycle, 100_000);
    write_velocity(&cycle, 0);
    cycles(&cycle, 200);
    // A position mode: a velocity written there is not the mode's command, a position never
    // times out.
    cycle.set_mode(0, Mode::CyclicSynchronousPosition as i8).unwrap();
    shows_mode(&cycle, Mode::CyclicSynchronousPosition);
    write_velocity(&cycle, 100_000);
    let here = input_i32(&cycle, inputs::POSITION);
    cycle.set_object(0, 0x607A, 0, &(here + 1000).to_le_bytes()).unwrap();
    cycles(&cycle, 200);
    assert!(command_timeouts(&cycle).is_empty());
    let status = cycle.command_timeout_status(0).unwrap();
    assert_eq!((status.armed, status.halted, status.timeouts), (false, false, 0));
    assert_eq!(sent_controlword(&cycle) & cw::HALT, 0);
}

#[test]
fn a_mapping_without_the_targets_cannot_be_watched() {
    let cycle = rig_with(Mode::CyclicSynchronousPosition, Some((Mapping::Fixed(0x1724), Mapping::Fixed(0x1B24))));
    let e = cycle.set_command_timeout(0, Some(Duration::from_secs(1)), CommandTimeoutAction::Halt).unwrap_err();
    assert!(e.to_string().contains("lacks target velocity 0x60FF or target torque 0x6071"), "{e}");
}
