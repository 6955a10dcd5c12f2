//! The drive's own I/O through the cycle thread, against a virtual AKD with akd_ros's `io`
//! mapping in cyclic synchronous position: outputs written in the next cycle's process image
//! without releasing a held target, each change of the digital inputs an event of the cycle
//! whose inputs show it, and a limit switch that holds a move toward it. The waits have
//! deadlines only so that a failure does not hang.

use akd_native::cycle::events::Event;
use akd_native::cycle::sequencer::Request;
use akd_native::cycle::CycleThread;
use akd_native::drive::ds402::{statusword, Mode, State};
use akd_native::drive::io;
use akd_native::drive::pdo;
use akd_native::drive::pdo::Mapping;
use akd_native::ethercat::pdo::{find, PdoEntry};
use akd_native::sim::control::{Change, SimControl, QUERY_TIMEOUT};

#[path = "support/one_drive.rs"]
mod one_drive;
use one_drive::{one_drive, wait_until};

fn rig() -> (CycleThread, SimControl) {
    let pdos = |p: &[&[PdoEntry]]| Mapping::Flexible(p.iter().map(|e| e.to_vec()).collect());
    one_drive(Mode::CyclicSynchronousPosition, (pdos(&pdo::IO_RX), pdos(&pdo::IO_TX)))
}

fn request(cycle: &CycleThread, request: Request, state: State) {
    cycle.request(0, request).unwrap();
    wait_until(state.name(), || (cycle.drive_status(0).unwrap().state() == Some(state)).then_some(()));
}

/// Object `index:subindex` (32 bits) in the last snapshot: an input, or with `sent` an output.
fn word(cycle: &CycleThread, (index, subindex): (u16, u8), sent: bool) -> i32 {
    let (rx, tx) = cycle.mapping(0).unwrap();
    let s = cycle.snapshot();
    let (entries, image) =
        if sent { (rx, cycle.outputs_of(&s, 0).unwrap()) } else { (tx, cycle.inputs_of(&s, 0).unwrap()) };
    let (at, _) = find(entries, index, subindex).unwrap();
    i32::from_le_bytes(image[at..at + 4].try_into().unwrap())
}

fn position(cycle: &CycleThread) -> i32 {
    word(cycle, (0x6064, 0), false)
}

fn cycles(cycle: &CycleThread, count: u64) {
    let later = cycle.snapshot().cycle + count;
    wait_until("cycles", || (cycle.snapshot().cycle >= later).then_some(()));
}

/// Streams targets from the axis's position by `step` counts a cycle, `count` of them.
fn ramp(cycle: &CycleThread, step: i32, count: usize) -> i32 {
    let mut target = position(cycle);
    for _ in 0..count {
        target += step;
        cycle.set_object(0, 0x607A, 0, &target.to_le_bytes()).unwrap();
        cycles(cycle, 1);
    }
    target
}

#[test]
fn outputs_go_out_in_the_next_cycles_image_and_leave_a_held_target_held() {
    let (cycle, control) = rig();
    request(&cycle, Request::Enable, State::OperationEnabled);
    let there = ramp(&cycle, 400, 250);
    wait_until("the axis there", || ((position(&cycle) - there).abs() <= 20).then_some(()));
    // A target written while disabled is no command after the next enable, which holds the
    // axis where it is; an output written then must not release that hold.
    request(&cycle, Request::Disable, State::SwitchOnDisabled);
    cycle.set_object(0, 0x607A, 0, &0i32.to_le_bytes()).unwrap();
    request(&cycle, Request::Enable, State::OperationEnabled);
    let held = word(&cycle, (0x607A, 0), true);
    assert!((held - there).abs() <= 20, "held at {held}, the axis at {there}");
    cycle.set_object(0, io::DIGITAL_OUTPUTS.0, io::DIGITAL_OUTPUTS.1, &io::bit(2).to_le_bytes()).unwrap();
    cycle.set_object(0, io::ANALOG_OUTPUT.0, io::ANALOG_OUTPUT.1, &(-16384i16).to_le_bytes()).unwrap();
    cycles(&cycle, 20);
    let drive = control.drive_state(0, QUERY_TIMEOUT).unwrap();
    assert_eq!(drive.outputs.digital, 0b10, "output 2 driven");
    assert!((drive.outputs.analog + 5.0).abs() < 1e-3, "{:?}", drive.outputs);
    assert_eq!(word(&cycle, (0x607A, 0), true), held, "the target still held");
    assert!((position(&cycle) - there).abs() <= 20, "the axis did not move: {}", position(&cycle));
}

#[test]
fn a_change_of_the_digital_inputs_is_an_event_of_the_cycle_whose_inputs_show_it() {
    let (cycle, control) = rig();
    request(&cycle, Request::Enable, State::OperationEnabled);
    cycle.events();
    cycle.samples();
    // Input 3 rises half a count past a whole count, where the rounded 0x6064 shows the crossing.
    let edge = position(&cycle) as f64 + 5000.5;
    control.change(Change::input_toggles(control.products(), 0, 3, vec![edge])).unwrap();
    ramp(&cycle, 200, 60);
    let events = wait_until("the event", || {
        let events: Vec<_> = cycle.events();
        (!events.is_empty()).then_some(events)
    });
    let samples = cycle.samples();
    let Event::Inputs { cycle: seen, digital_inputs, statusword, .. } = events[0] else { panic!("{events:?}") };
    assert_eq!(io::inputs(digital_inputs), 0b100, "{events:?}");
    assert_eq!(io::hardware_enable(statusword), io::HardwareEnable::High);
    let first = samples.iter().find(|s| s.position as f64 >= edge).expect("the axis crossed the edge");
    assert_eq!(seen, first.cycle, "the event is of the cycle whose 0x6064 first shows the crossing");

    control.change(Change::hardware_enable(control.products(), 0, false)).unwrap();
    let low = wait_until("the hardware enable's event", || {
        cycle.events().into_iter().find_map(|e| match e {
            Event::Inputs { statusword, .. } => Some(io::hardware_enable(statusword)),
            _ => None,
        })
    });
    assert_eq!(low, io::HardwareEnable::Low);
}

#[test]
fn a_limit_switch_holds_a_move_toward_it_and_lets_one_away_from_it_go() {
    let (cycle, control) = rig();
    request(&cycle, Request::Enable, State::OperationEnabled);
    let start = position(&cycle);
    control.change(Change::switch(control.products(), 0, "positive_limit", true)).unwrap();
    cycles(&cycle, 5);
    assert_eq!(word(&cycle, io::DIGITAL_INPUTS, false) & 0b11, 0b10, "0x60FD bit 1");
    let target = ramp(&cycle, 200, 100);
    cycles(&cycle, 50);
    let stopped = position(&cycle);
    assert!(stopped - start < 1000, "held near {start}: at {stopped}, commanded {target}");
    let status = cycle.drive_status(0).unwrap();
    assert_eq!(status.state(), Some(State::OperationEnabled));
    assert_ne!(status.statusword & statusword::INTERNAL_LIMIT, 0, "internal limit active");
    let back = ramp(&cycle, -200, 100);
    wait_until("the move away", || ((position(&cycle) - back).abs() <= 50).then_some(()));
    assert!(back < start - 15_000, "{back}");
}
