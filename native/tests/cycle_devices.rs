//! The devices beside the drives in the cycle thread, on a virtual cell of an EK1100, an EL1004,
//! an EL2004 and an AKD: outputs set by channel name reach the EL2004's pins, each edge of the
//! EL1004's inputs is an event of the cycle whose inputs show it, a power-cycled terminal is
//! reported, brought back with its outputs off, and costs the enabled drive nothing, and the
//! line's fault reaction switches the terminals' outputs off. The waits have deadlines only so
//! that a failure does not hang.

use std::time::Duration;

use akd_native::cycle::events::{Action, Event, FaultSource};
use akd_native::cycle::sequencer::Request;
use akd_native::cycle::{Config, CycleThread};
use akd_native::drive::akd::AkdSlave;
use akd_native::drive::ds402::State;
use akd_native::drive::pdo::Mapping;
use akd_native::ethercat::al::AlState;
use akd_native::ethercat::device::ChannelValue;
use akd_native::ethercat::link_spec::{MissedFrames, Pace, SimLine};
use akd_native::ethercat::master::Master;
use akd_native::sim::control::{Change, SimControl, QUERY_TIMEOUT};
use akd_native::sim::in_process::InProcess;
use akd_native::sim::{Timing, VirtualBus};

#[allow(dead_code)]
#[path = "support/one_drive.rs"]
mod one_drive;
use one_drive::wait_until;

const STEP: Duration = Duration::from_secs(5);
const EL1004: u16 = 1;
const EL2004: u16 = 2;
const AKD: u16 = 3;

fn cell() -> (CycleThread, SimControl) {
    let line: SimLine = "ek1100,el1004,el2004,akd".parse().unwrap();
    let bus = VirtualBus::of_line(&line, Timing::of(Pace::Immediate, MissedFrames::Lost)).unwrap();
    let link = InProcess::with_bus(bus);
    let control = link.control();
    let mut m = Master::new(Box::new(link), Duration::from_millis(100));
    m.scan().unwrap();
    m.request_state(AlState::PreOp, STEP).unwrap();
    m.slave_mut(AKD).unwrap().configure_pdo(Mapping::Fixed(0x1701), Mapping::Fixed(0x1B01)).unwrap();
    m.slave_mut(AKD).unwrap().sdo_write(0x6060, 0, &[7]).unwrap();
    m.request_state(AlState::Op, STEP).unwrap();
    let cycle = CycleThread::start(m, Config::new(Duration::from_millis(1))).map_err(|e| e.0).unwrap();
    (cycle, control)
}

fn pins(control: &SimControl) -> u16 {
    control.terminal_state(EL2004 as usize, QUERY_TIMEOUT).unwrap().outputs
}

fn enable(cycle: &CycleThread) {
    cycle.request(AKD, Request::Enable).unwrap();
    wait_until("the drive enabled", || {
        (cycle.drive_status(AKD).unwrap().state() == Some(State::OperationEnabled)).then_some(())
    });
}

#[test]
fn outputs_by_name_reach_the_pins_and_input_edges_are_events_of_their_cycle() {
    let (cycle, control) = cell();
    let names: Vec<&str> = cycle.channels(EL1004).unwrap().iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["channel_1_input", "channel_2_input", "channel_3_input", "channel_4_input"]);
    cycle.set_channels(EL2004, &[("channel_2_output", ChannelValue::Bit(true))]).unwrap();
    wait_until("output 2 on", || (pins(&control) == 0b0010).then_some(()));
    cycle.set_channels(EL2004, &[("channel_4_output", ChannelValue::Integer(1))]).unwrap();
    wait_until("output 4 on beside 2", || (pins(&control) == 0b1010).then_some(()));
    assert_eq!(cycle.outputs(EL2004).unwrap(), [0b1010]);

    // Refused whole, nothing set.
    let refused = cycle
        .set_channels(
            EL2004,
            &[("channel_1_output", ChannelValue::Bit(true)), ("channel_9_output", ChannelValue::Bit(true))],
        )
        .unwrap_err()
        .to_string();
    assert!(
        refused.contains("slave 2 has no output channel \"channel_9_output\"; its outputs: channel_1_output"),
        "{refused}"
    );
    let refused = cycle.set_channels(EL1004, &[("channel_1_input", ChannelValue::Bit(true))]).unwrap_err().to_string();
    assert_eq!(refused, "configuration: slave 1's channel \"channel_1_input\" is an input; its outputs: none");
    let refused = cycle.set_channels(AKD, &[("controlword", ChannelValue::Integer(6))]).unwrap_err().to_string();
    assert!(refused.contains("slave 3 is a drive the cycle sequences"), "{refused}");
    assert_eq!(cycle.outputs(EL2004).unwrap(), [0b1010]);

    cycle.events();
    control.change(Change::input_level(control.products(), EL1004 as usize, 3, true)).unwrap();
    let (seen, levels) = wait_until("the EL1004's edge", || {
        cycle.events().into_iter().find_map(|e| match e {
            Event::DeviceInputs { cycle, slave: EL1004, levels, .. } => Some((cycle, levels)),
            _ => None,
        })
    });
    assert_eq!(levels, 0b0100);
    // The event's cycle is the first whose inputs show it: the one before did not.
    let snapshot = cycle.snapshot();
    assert!(snapshot.cycle >= seen);
    let values = cycle.channel_values(&snapshot, EL1004).unwrap();
    assert_eq!(values[2], ChannelValue::Bit(true));
    cycle.switch_outputs_off(EL2004).unwrap();
    wait_until("the outputs off", || (pins(&control) == 0).then_some(()));
    cycle.stop().unwrap();
}

#[test]
fn a_power_cycled_terminal_comes_back_with_its_outputs_off_and_costs_the_drive_nothing() {
    let (cycle, control) = cell();
    enable(&cycle);
    cycle.set_channels(EL2004, &[("channel_1_output", ChannelValue::Bit(true))]).unwrap();
    wait_until("output 1 on", || (pins(&control) == 0b0001).then_some(()));
    cycle.events();
    control.change(Change::power_cycle(control.products(), EL2004 as usize)).unwrap();
    let mut seen = Vec::new();
    wait_until("the terminal lost and back", || {
        seen.extend(cycle.events());
        seen.iter()
            .any(|e| matches!(e, Event::Fault { slave: EL2004, source: FaultSource::Recovered, .. }))
            .then_some(())
    });
    let lost = seen.iter().find_map(|e| match *e {
        Event::Fault { slave: EL2004, source, action, .. } if source != FaultSource::Recovered => {
            Some((source, action))
        }
        _ => None,
    });
    assert_eq!(lost, Some((FaultSource::Unreachable, Action::OutputsOff)), "{seen:?}");
    assert!(
        seen.iter().any(|e| matches!(e, Event::Fault { slave: EL2004, action: Action::RestoredOutputsOff, .. })),
        "{seen:?}"
    );
    assert!(!seen.iter().any(|e| matches!(e, Event::Fault { slave: AKD, .. })), "the drive was spared: {seen:?}");
    assert_eq!(cycle.drive_status(AKD).unwrap().state(), Some(State::OperationEnabled));
    assert_eq!(cycle.recovery_status(EL2004).unwrap().recoveries, 1);
    // Off until set again, in the terminal and in what the cycle holds.
    assert_eq!(cycle.outputs(EL2004).unwrap(), [0]);
    wait_until("the terminal in Op", || {
        let state = control.terminal_state(EL2004 as usize, QUERY_TIMEOUT).unwrap();
        (state.al_status == AlState::Op as u16).then_some(())
    });
    assert_eq!(pins(&control), 0);
    cycle.set_channels(EL2004, &[("channel_3_output", ChannelValue::Bit(true))]).unwrap();
    wait_until("output 3 on", || (pins(&control) == 0b0100).then_some(()));
    cycle.stop().unwrap();
}

#[test]
fn the_lines_fault_reaction_switches_the_terminals_outputs_off() {
    let (cycle, control) = cell();
    cycle.set_quick_stop_on_fault(true);
    enable(&cycle);
    cycle.set_channels(EL2004, &[("channel_1_output", ChannelValue::Bit(true))]).unwrap();
    wait_until("output 1 on", || (pins(&control) == 0b0001).then_some(()));
    control.change(Change::inject_fault(control.products(), AKD as usize, "following_error")).unwrap();
    wait_until("the outputs off", || (pins(&control) == 0).then_some(()));
    assert_eq!(cycle.outputs(EL2004).unwrap(), [0]);
    cycle.stop().unwrap();
}
