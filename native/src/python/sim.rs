//! Python face of the virtual line: `VirtualBus` for tests that build their own frames,
//! `serve_udp` / `serve_iface` for the `akd-sim` command, and `Simulator`, which controls
//! virtual slaves another thread serves (a `Master("sim")` and its Cycle, or a server), and
//! `SetpointTrace`, the file a server traces its drives' set-points to; `sim_sii_image`, the
//! SII image each virtual slave serves.

use std::net::{SocketAddr, ToSocketAddrs};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use pyo3::prelude::*;
use pyo3::types::PyBytes;

use super::IntoPyResult;
use crate::error::{Error, Result, SettingError, Unavailable, UnknownName};
use crate::ethercat::al::AlState;
use crate::ethercat::link_spec::{MissedFrames, Pace, SimLine, SimLineError, SimProduct};
use crate::sim::control::{self, Change, ControlledBus, DriveState, EscState, SimControl, QUERY_TIMEOUT};
use crate::sim::faults::Fault;
use crate::sim::line::{Burst, Delivery, LineCounts};
use crate::sim::pll::SyncState;
use crate::sim::setpoint_trace::{SetpointTrace, TraceSender, TraceSummary};
use crate::sim::terminal::{self, TerminalState};
use crate::sim::{server, sii_image, Timing, VirtualBus};

use super::line_health::EscCountsView;
use crate::ethercat::line_health::registers::PortCounts;

/// What `drive_state` gives: "state" (the CiA 402 state, a `Ds402State`), "fault" (the active fault's
/// name, or None), "fault_number" (e.g. 125, or None), the motor's "position" (counts),
/// "velocity" (counts/s) and "torque" (N·m), "dc", what its synchronisation was told
/// ([`SyncState`]), and its I/O: "digital_inputs" (0x60FD as it shows it), "digital_outputs"
/// (the levels of outputs 1 and 2 as the master drives them) and "analog_output" (V).
#[derive(IntoPyObject)]
struct DriveStateView {
    state: crate::drive::ds402::State,
    fault: Option<&'static str>,
    fault_number: Option<u16>,
    position: f64,
    velocity: f64,
    torque: f64,
    dc: SyncState,
    digital_inputs: u32,
    digital_outputs: Vec<bool>,
    analog_output: f64,
    would_be_f125: WouldBeF125View,
}

/// `drive_state()["would_be_f125"]`: "count", the F125 a real AKD would have raised where this
/// one, judging missed frames by "warn", went on; "longest_ms", the longest silence among them.
#[derive(IntoPyObject)]
struct WouldBeF125View {
    count: u64,
    longest_ms: f64,
}

impl From<DriveState> for DriveStateView {
    fn from(drive: DriveState) -> Self {
        DriveStateView {
            state: drive.state,
            fault: drive.fault.map(Fault::name),
            fault_number: drive.fault.map(Fault::number),
            position: drive.position,
            velocity: drive.velocity,
            torque: drive.torque,
            dc: drive.sync,
            digital_inputs: drive.digital_inputs,
            digital_outputs: (0..crate::drive::io::OUTPUT_COUNT).map(|o| drive.outputs.digital >> o & 1 == 1).collect(),
            analog_output: drive.outputs.analog,
            would_be_f125: WouldBeF125View {
                count: drive.would_be_f125.count,
                longest_ms: drive.would_be_f125.longest_ns as f64 / 1e6,
            },
        }
    }
}

/// `terminal_state()`: "product" (e.g. "el1004"), "al_state" (the AL state's name),
/// "al_status" (the register, error flag included), its digital "inputs" (as the master reads
/// them, after the input filter) and "outputs" (as the pins drive them), its "analog_inputs" (V),
/// each a list from channel 1, and "watchdog_expired" (the sync-manager watchdog ran out and
/// holds the outputs off).
#[derive(IntoPyObject)]
struct TerminalStateView {
    product: &'static str,
    al_state: Option<&'static str>,
    al_status: u16,
    inputs: Vec<bool>,
    outputs: Vec<bool>,
    analog_inputs: Vec<f64>,
    watchdog_expired: bool,
}

impl From<TerminalState> for TerminalStateView {
    fn from(t: TerminalState) -> Self {
        let bits = |mask: u16, count: u8| (0..count).map(|n| mask >> n & 1 == 1).collect();
        TerminalStateView {
            product: t.product.name(),
            al_state: AlState::from_bits(t.al_status & 0x0F).map(AlState::name),
            al_status: t.al_status,
            inputs: bits(t.inputs, t.input_count),
            outputs: bits(t.outputs, t.output_count),
            analog_inputs: t.analog_inputs[..usize::from(t.analog_count)].to_vec(),
            watchdog_expired: t.watchdog_expired,
        }
    }
}

/// One port of `esc_state()["ports"]`: "port", "kind" ("MII", "E-bus", ...), "link",
/// "loop_closed", "communication" (as the DL status shows them), "spoiling" (frames a faulty
/// cable is still to spoil entering it), "registers" (its counters as the master reads them)
/// and "counted" (what they counted since power-up, never cleared).
#[derive(IntoPyObject)]
struct EscPortView {
    port: usize,
    kind: &'static str,
    link: bool,
    loop_closed: bool,
    communication: bool,
    spoiling: u64,
    registers: PortCounts<u8>,
    counted: PortCounts<u64>,
}

/// `esc_state()`: "dl_status", "ports" (the ports its ESC has), "registers" and "counted" (its
/// processing unit's and PDI's counters, as for each port).
#[derive(IntoPyObject)]
struct EscStateView {
    dl_status: u16,
    ports: Vec<EscPortView>,
    registers: EscCountsView,
    counted: EscCountsView,
}

impl From<EscState> for EscStateView {
    fn from(e: EscState) -> Self {
        let ports = e
            .port_descriptor
            .ports()
            .map(|port| EscPortView {
                port,
                kind: e.port_descriptor.kind(port).name(),
                link: e.dl_status.link(port),
                loop_closed: e.dl_status.loop_closed(port),
                communication: e.dl_status.communication(port),
                spoiling: e.spoiling[port],
                registers: e.registers.ports[port],
                counted: e.counted.ports[port],
            })
            .collect();
        EscStateView { dl_status: e.dl_status.0, ports, registers: e.registers.into(), counted: e.counted.into() }
    }
}

/// The line `line` names ("ek1100,el1004,akd"), or `count` AKDs where it is None.
fn sim_line(count: usize, line: Option<&str>) -> Result<SimLine> {
    let parsed = match line {
        Some(text) => text.parse(),
        None => SimLine::akds(count),
    };
    parsed.map_err(|error| {
        SettingError::SimLine { line: line.map_or_else(|| count.to_string(), str::to_owned), error }.into()
    })
}

/// A line of virtual slaves serving EtherCAT payloads (frame header and datagrams) in place.
#[pyclass(name = "VirtualBus", module = "akd_ros._native")]
struct PyVirtualBus {
    bus: VirtualBus,
    products: Vec<SimProduct>,
}

#[pymethods]
impl PyVirtualBus {
    /// `count` AKDs at power-up, or the slaves `line` names ("ek1100,el1004,el2004,akd").
    /// `immediate=True` makes the AKDs' firmware answer AL requests and mailbox messages before
    /// the next frame instead of after the real drive's delays. `warm=True` makes them drives
    /// powered up long before, as the drive of the SOEM capture was: their Init→PreOp and
    /// first mailbox reply take the later requests' time (docs/virtual_akd.md).
    #[new]
    #[pyo3(signature = (count = 1, immediate = false, warm = false, line = None))]
    fn new(count: usize, immediate: bool, warm: bool, line: Option<&str>) -> PyResult<Self> {
        let timing = Timing::of(if immediate { Pace::Immediate } else { Pace::Real }, MissedFrames::Late);
        let mut bus = sim_line(count, line).and_then(|line| VirtualBus::of_line(&line, timing)).py()?;
        if warm {
            bus.warm_up();
        }
        Ok(PyVirtualBus { products: bus.products(), bus })
    }

    /// The slaves' products in order, e.g. ["ek1100", "el1004", "akd"].
    #[getter]
    fn products(&self) -> Vec<&'static str> {
        self.products.iter().map(|p| p.name()).collect()
    }

    /// Serves `payload` at bus time `time_ns` and returns the frame as it comes back, or None
    /// when it is lost on the line; raises FrameError for a malformed frame.
    fn process<'py>(&mut self, py: Python<'py>, payload: &[u8], time_ns: u64) -> PyResult<Option<Bound<'py, PyBytes>>> {
        let mut frame = payload.to_vec();
        let delivery = self.bus.process(&mut frame, time_ns).py()?;
        Ok((delivery == Delivery::Returned).then(|| PyBytes::new(py, &frame)))
    }

    /// AL state bits with the error flag, and the AL status code, of slave `position`.
    fn al_status(&self, position: usize) -> PyResult<(u16, u16)> {
        self.check(position)?;
        let registers = self.bus.at(position).registers();
        let word = |at: u16| u16::from_le_bytes([registers[usize::from(at)], registers[usize::from(at) + 1]]);
        Ok((word(crate::ethercat::registers::AL_STATUS), word(crate::ethercat::registers::AL_STATUS_CODE)))
    }

    /// Lets bus time `time_ns` pass with no frame: the drives' firmware and motors run up to it.
    fn advance(&mut self, time_ns: u64) {
        self.bus.advance(time_ns);
    }

    /// Raises fault `name` in drive `position` at its next run, as `Simulator.inject_fault` does.
    fn inject_fault(&mut self, position: usize, name: &str) -> PyResult<()> {
        self.apply(Change::inject_fault(&self.products, position, name))
    }

    /// Sets the hardware enable input of drive `position` (high at power-up).
    fn set_hardware_enable(&mut self, position: usize, high: bool) -> PyResult<()> {
        self.apply(Change::hardware_enable(&self.products, position, high))
    }

    /// Digital input `input` of drive `position` toggles as `Simulator.set_input_toggles` says.
    fn set_input_toggles(&mut self, position: usize, input: usize, positions: Vec<f64>) -> PyResult<()> {
        self.apply(Change::input_toggles(&self.products, position, input, positions))
    }

    /// Digital input `input` (from 1) of slave `position` `high` or low, as `Simulator.set_input` says.
    fn set_input(&mut self, position: usize, input: usize, high: bool) -> PyResult<()> {
        self.apply(Change::input_level(&self.products, position, input, high))
    }

    /// Switch `name` of 0x60FD of drive `position` active or not, as `Simulator.set_switch` says.
    fn set_switch(&mut self, position: usize, name: &str, active: bool) -> PyResult<()> {
        self.apply(Change::switch(&self.products, position, name, active))
    }

    /// Analog input `input` (from 1) of slave `position` at `volts`, as `Simulator.set_analog_input` says.
    #[pyo3(signature = (position, volts, input = 1))]
    fn set_analog_input(&mut self, position: usize, volts: f64, input: usize) -> PyResult<()> {
        self.apply(Change::analog_input(&self.products, position, input, volts))
    }

    /// Makes drive `position`'s homing runs fail as `name` says (see `Simulator.set_homing_failure`).
    fn set_homing_failure(&mut self, position: usize, name: &str) -> PyResult<()> {
        self.apply(Change::homing_failure(&self.products, position, name))
    }

    /// The drive firmware of drive `position` as a dict: "state" (its `Ds402State`),
    /// "fault" (the active fault's name, or None), "fault_number" (e.g. 125, or None), and the
    /// motor's "position" (counts), "velocity" (counts/s) and "torque" (N·m), and "dc", what its
    /// synchronisation was told (SYNC0, FBUS.PARAM02, 0x60C2, whether its PLL would lock).
    fn drive_state(&self, position: usize) -> PyResult<DriveStateView> {
        control::check_akd(&self.products, position, "a drive state").py()?;
        Ok(DriveState::of(self.bus.slave(position)).into())
    }

    /// The I/O of the terminal at `position` as a dict (see `Simulator.terminal_state`).
    fn terminal_state(&self, position: usize) -> PyResult<TerminalStateView> {
        control::check_terminal(&self.products, position, "a terminal state").py()?;
        Ok(self.bus.at(position).terminal().map(|t| t.state().into()).expect("checked: a terminal"))
    }

    /// Takes the link at `port` of slave `position` down (`up` False) or up again, as
    /// `Simulator.set_link` does.
    fn set_link(&mut self, position: usize, port: usize, up: bool) -> PyResult<()> {
        self.apply(Change::link(&self.products, position, port, up))
    }

    /// The cable into `port` of slave `position` spoils the next `frames` frames entering
    /// there, one in every `every`, as `Simulator.crc_errors` says.
    #[pyo3(signature = (position, port, frames, every = 1))]
    fn crc_errors(&mut self, position: usize, port: usize, frames: i64, every: i64) -> PyResult<()> {
        self.apply(Change::spoil_port(&self.products, position, port, frames, every))
    }

    /// The ESC of slave `position` as a dict (see `Simulator.esc_state`).
    fn esc_state(&self, position: usize) -> PyResult<EscStateView> {
        self.check(position)?;
        Ok(EscState::of(&self.bus, position).into())
    }

    fn __len__(&self) -> usize {
        self.bus.len()
    }
}

impl PyVirtualBus {
    fn check(&self, position: usize) -> PyResult<()> {
        control::check_position(self.bus.len(), position).py()
    }

    /// Makes `change` to the line at once, or raises why it was refused.
    fn apply(&mut self, change: Result<Change>) -> PyResult<()> {
        change.py()?.apply(&mut self.bus);
        Ok(())
    }
}

/// Controls virtual AKDs that another thread serves: those of a `Master("sim")` or
/// `Master("sim:N")` (`Master.simulator`), also while a `Cycle` holds the master, or those of
/// an `akd-sim` server (`serve_udp`'s and `serve_iface`'s `on_start`).
///
/// Changes are checked at once (a bad one raises ConfigError naming the allowed values) and
/// reach the drives before their next frame. `drive_state` waits for the drives' answer after
/// that frame: an idle in-process master exchanges no frame, so it raises ConfigError after
/// `timeout`; start a Cycle first.
#[pyclass(name = "Simulator", module = "akd_ros._native", frozen)]
pub struct PySimulator {
    control: SimControl,
}

impl PySimulator {
    /// The Python face of `control`.
    pub(super) fn new(control: SimControl) -> Self {
        PySimulator { control }
    }

    /// Sends the change `change` builds against the line, or raises why it was refused.
    fn change(&self, change: impl FnOnce(&[SimProduct]) -> Result<Change>) -> PyResult<()> {
        self.control.change(change(self.control.products())).py()
    }
}

#[pymethods]
impl PySimulator {
    /// Raises fault `name` in drive `position` at its next model step after the next frame:
    /// "following_error" (F439), "over_temperature" (F235), "sync_lost" (F125) or
    /// "setpoints_missing" (F706), by name or as "F125".
    fn inject_fault(&self, position: usize, name: &str) -> PyResult<()> {
        self.change(|line| Change::inject_fault(line, position, name))
    }

    /// Sets the hardware enable input of drive `position` (high at power-up).
    fn set_hardware_enable(&self, position: usize, high: bool) -> PyResult<()> {
        self.change(|line| Change::hardware_enable(line, position, high))
    }

    /// Digital input `input` (1..7) of drive `position` toggles wherever the actual position
    /// (counts, 2^20 per revolution) crosses one of `positions`; it is low below all of them.
    fn set_input_toggles(&self, position: usize, input: usize, positions: Vec<f64>) -> PyResult<()> {
        self.change(|line| Change::input_toggles(line, position, input, positions))
    }

    /// Digital input `input` (from 1) of slave `position` `high` or low from the next frame on:
    /// an AKD's 1..7 wherever the shaft is, a digital input terminal's at its connector (the
    /// master sees it after the terminal's input filter, 3 ms).
    fn set_input(&self, position: usize, input: usize, high: bool) -> PyResult<()> {
        self.change(|line| Change::input_level(line, position, input, high))
    }

    /// Switch `name` of 0x60FD ("negative_limit", "positive_limit", "home_switch",
    /// "interlock") of drive `position` active or not from the next frame on; a limit switch
    /// holds motion toward it (braking with 0x6085) and lets motion away from it go.
    fn set_switch(&self, position: usize, name: &str, active: bool) -> PyResult<()> {
        self.change(|line| Change::switch(line, position, name, active))
    }

    /// Analog input `input` (from 1) of slave `position` at `volts` from the next frame on: an
    /// AKD's one (0x3470:04, ±10 V over its range), an EL3102's two (±10 V).
    #[pyo3(signature = (position, volts, input = 1))]
    fn set_analog_input(&self, position: usize, volts: f64, input: usize) -> PyResult<()> {
        self.change(|line| Change::analog_input(line, position, input, volts))
    }

    /// Makes drive `position`'s homing runs fail from the next frame on as `name` says: "error"
    /// (a homing error halfway to the reference), "no_reference" (it searches and never finds
    /// it), or "ok".
    fn set_homing_failure(&self, position: usize, name: &str) -> PyResult<()> {
        self.change(|line| Change::homing_failure(line, position, name))
    }

    /// Power-cycles drive `position` before the next frame: it comes back as at power-up (AL
    /// Init, station address 0, mailbox and mappings reset, Not ready to switch on).
    fn power_cycle(&self, position: usize) -> PyResult<()> {
        self.change(|line| Change::power_cycle(line, position))
    }

    /// Pulls the cable in front of drive `position` out: frames stop reaching it and every
    /// drive behind it, and come back with the working counters of the drives before it only
    /// (with position 0, not at all), until `replug_cable`.
    fn pull_cable(&self, position: usize) -> PyResult<()> {
        self.change(|line| Change::cable(line, position, false))
    }

    /// Plugs the cable in front of drive `position` back in.
    fn replug_cable(&self, position: usize) -> PyResult<()> {
        self.change(|line| Change::cable(line, position, true))
    }

    /// Takes the link at `port` of slave `position` down (`up` False) before the next frame, or
    /// up again: the cable there pulled or plugged (port 0: the one in front of it; port 1: the
    /// one to the next slave), each end counting a lost link. Raises ConfigError for a port its
    /// ESC lacks or no cable of the line reaches.
    fn set_link(&self, position: usize, port: usize, up: bool) -> PyResult<()> {
        self.change(|line| Change::link(line, position, port, up))
    }

    /// The cable into `port` of slave `position` spoils (a CRC error) the next `frames` frames
    /// entering there, one in every `every`, from the next frame on: the slave's ESC counts an
    /// invalid frame at that port, every ESC after it on the frame's way a forwarded error, and
    /// the master never gets the frame. Port 0 takes frames on their way out, from the slave in
    /// front (or the master); port 1 on their way back, from the slave behind. 0 ends a fault
    /// still pending.
    #[pyo3(signature = (position, port, frames, every = 1))]
    fn crc_errors(&self, position: usize, port: usize, frames: i64, every: i64) -> PyResult<()> {
        self.change(|line| Change::spoil_port(line, position, port, frames, every))
    }

    /// The ESC of slave `position` after the next frame, as a dict: "dl_status", "ports" (each
    /// port its ESC has: "port", "kind", "link", "loop_closed", "communication", "spoiling",
    /// "registers" and "counted", its counters as the master reads them and as counted since
    /// power-up), "registers" and "counted" (its processing unit's and PDI's); waits up to
    /// `timeout` seconds for that frame.
    #[pyo3(signature = (position, timeout = QUERY_TIMEOUT.as_secs_f64()))]
    fn esc_state(&self, py: Python<'_>, position: usize, timeout: f64) -> PyResult<EscStateView> {
        let timeout = super::seconds(timeout, "timeout")?;
        let control = &self.control;
        Ok(py.allow_threads(|| control.esc_state(position, timeout)).py()?.into())
    }

    /// The next `frames` frames get no reply at all; 0 ends a burst still pending.
    fn drop_frames(&self, frames: i64) -> PyResult<()> {
        self.change(|_| Burst::frames(frames).map(|n| Change::Burst(Burst::Lost(n))))
    }

    /// The next `frames` replies come back corrupted (the frame header's length one short),
    /// so the master's codec refuses them; 0 ends a burst still pending.
    fn corrupt_frames(&self, frames: i64) -> PyResult<()> {
        self.change(|_| Burst::frames(frames).map(|n| Change::Burst(Burst::Corrupted(n))))
    }

    /// The next `frames` replies carry a wrong working counter in every datagram; 0 ends a
    /// burst still pending.
    fn wrong_wkc(&self, frames: i64) -> PyResult<()> {
        self.change(|_| Burst::frames(frames).map(|n| Change::Burst(Burst::WrongWkc(n))))
    }

    /// The drive firmware of drive `position` after the next frame, as `VirtualBus.drive_state`
    /// gives it; waits up to `timeout` seconds for that frame.
    #[pyo3(signature = (position, timeout = QUERY_TIMEOUT.as_secs_f64()))]
    fn drive_state(&self, py: Python<'_>, position: usize, timeout: f64) -> PyResult<DriveStateView> {
        let timeout = super::seconds(timeout, "timeout")?;
        let control = &self.control;
        Ok(py.allow_threads(|| control.drive_state(position, timeout)).py()?.into())
    }

    /// The I/O of the terminal at `position` after the next frame, as a dict: "product",
    /// "al_state", "al_status", "inputs" and "outputs" (lists of levels from channel 1),
    /// "analog_inputs" (V) and "watchdog_expired"; waits up to `timeout` seconds for that frame.
    #[pyo3(signature = (position, timeout = QUERY_TIMEOUT.as_secs_f64()))]
    fn terminal_state(&self, py: Python<'_>, position: usize, timeout: f64) -> PyResult<TerminalStateView> {
        let timeout = super::seconds(timeout, "timeout")?;
        let control = &self.control;
        Ok(py.allow_threads(|| control.terminal_state(position, timeout)).py()?.into())
    }

    /// The slaves' products in order, e.g. ["ek1100", "el1004", "akd"].
    #[getter]
    fn products(&self) -> Vec<&'static str> {
        self.control.products().iter().map(|p| p.name()).collect()
    }

    /// What the line did to the frames it carried since the drives were laid out, counted by
    /// the virtual AKDs themselves, after the next frame (counted in): "frames" (that reached
    /// the line), "lost" (before the first drive: dropped, or the first cable out),
    /// "corrupted" and "wrong_wkc" (replies spoiled so), "spoiled" (frames a faulty cable
    /// spoiled, `crc_errors`). Waits up to `timeout` seconds.
    #[pyo3(signature = (timeout = QUERY_TIMEOUT.as_secs_f64()))]
    fn line_counts(&self, py: Python<'_>, timeout: f64) -> PyResult<LineCounts> {
        let timeout = super::seconds(timeout, "timeout")?;
        let control = &self.control;
        py.allow_threads(|| control.line_counts(timeout)).py()
    }

    fn __len__(&self) -> usize {
        self.control.len()
    }
}

/// A file the set-points a server's virtual AKDs receive are traced to (JSON lines, see
/// `akd-sim --help`): created (or truncated) here, a bad path raising LinkError naming it; given
/// to one `serve_udp` or `serve_iface` (`setpoint_trace=`), and closed by `close()` once that
/// server stopped.
#[pyclass(name = "SetpointTrace", module = "akd_ros._native", frozen)]
pub struct PySetpointTrace {
    trace: Mutex<SetpointTrace>,
}

impl PySetpointTrace {
    fn sender(&self, drives: usize) -> PyResult<TraceSender> {
        self.trace.lock().unwrap_or_else(|poisoned| poisoned.into_inner()).sender(drives).py()
    }
}

#[pymethods]
impl PySetpointTrace {
    #[new]
    fn new(path: PathBuf) -> PyResult<Self> {
        Ok(PySetpointTrace { trace: Mutex::new(SetpointTrace::create(path).py()?) })
    }

    /// Waits for the server that recorded to have stopped, writes the rest and the end line, and
    /// closes the file: {"changes": written, "dropped": because the writer fell behind}.
    fn close(&self, py: Python<'_>) -> PyResult<TraceSummary> {
        let trace = &self.trace;
        py.allow_threads(|| trace.lock().unwrap_or_else(|poisoned| poisoned.into_inner()).finish()).py()
    }
}

/// A bus of `count` virtual AKDs, or of the slaves `line` names, for a server; `on_start`, if
/// given, is called with its Simulator before serving starts.
fn controlled_bus(
    (count, line): (usize, Option<&str>),
    (missed, pace): (&str, &str),
    on_start: Option<&Bound<'_, PyAny>>,
) -> PyResult<ControlledBus> {
    let missed_frames = MissedFrames::parse(missed)
        .ok_or_else(|| Error::from(UnknownName::MissedFrames { name: missed.to_owned() }))
        .py()?;
    let pace = Pace::parse(pace).ok_or_else(|| Error::from(UnknownName::Pace { name: pace.to_owned() })).py()?;
    let timing = Timing::of(pace, missed_frames);
    let bus = ControlledBus::from(sim_line(count, line).and_then(|line| VirtualBus::of_line(&line, timing)).py()?);
    if let Some(on_start) = on_start {
        on_start.call1((PySimulator::new(bus.control()),))?;
    }
    Ok(bus)
}

/// What a server did, for `on_stop`: "served", "malformed", "lost" (on the simulated line),
/// "unsent" (the line went down under the reply), "late", how late replies went back
/// because the server was not run ([`LateView`]; None over UDP), "serving", how long its own
/// serving of each frame took (the same view), and "would_be_f125", the F125
/// its drives did not raise judging missed frames by "warn".
#[derive(IntoPyObject)]
struct ServerStatsView {
    served: u64,
    malformed: u64,
    lost: u64,
    unsent: u64,
    late: Option<LateView>,
    serving: LateView,
    would_be_f125: u64,
}

/// [`server::LateReplies`]: "over", the count of replies later than each bound (µs → count),
/// and "longest_us".
#[derive(IntoPyObject)]
struct LateView {
    over: std::collections::BTreeMap<u64, u64>,
    longest_us: u64,
}

impl From<server::LateReplies> for LateView {
    fn from(late: server::LateReplies) -> Self {
        LateView { over: server::LATE_AFTER_US.into_iter().zip(late.over).collect(), longest_us: late.longest_us }
    }
}

impl From<server::ServerStats> for ServerStatsView {
    fn from(stats: server::ServerStats) -> Self {
        ServerStatsView {
            served: stats.served,
            malformed: stats.malformed,
            lost: stats.lost,
            unsent: stats.unsent,
            would_be_f125: stats.would_be_f125,
            late: stats.late.map(LateView::from),
            serving: stats.serving.into(),
        }
    }
}

/// Runs `serve` on a thread until it ends or a Python signal handler raises (SIGINT gives
/// KeyboardInterrupt): the GIL is released while waiting, signals are checked every 100 ms.
/// `on_stop(stats)`, if given, is called with what the server did once it has stopped.
fn run_until_signal(
    py: Python<'_>,
    on_stop: Option<&Bound<'_, PyAny>>,
    serve: impl FnOnce(&AtomicBool) -> Result<server::ServerStats> + Send + 'static,
) -> PyResult<()> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let worker = std::thread::spawn(move || serve(&flag));
    let mut interrupt = None;
    loop {
        py.allow_threads(|| std::thread::sleep(server::POLL_INTERVAL));
        if worker.is_finished() {
            break;
        }
        if let Err(signalled) = py.check_signals() {
            // The worker sees the flag within one poll interval.
            stop.store(true, Ordering::Relaxed);
            interrupt = Some(signalled);
            break;
        }
    }
    let stats = match py.allow_threads(|| worker.join()) {
        Ok(result) => result.py()?,
        Err(_) => return Err(Unavailable::SimulatorPanicked).py(),
    };
    if let Some(on_stop) = on_stop {
        on_stop.call1((ServerStatsView::from(stats),))?;
    }
    interrupt.map_or(Ok(()), Err)
}

/// Serves `count` virtual AKDs, or the slaves `line` names ("ek1100,el1004,el2004,akd"), on UDP
/// `host:port` until SIGINT/SIGTERM. `on_start(simulator)` is called once the socket is bound,
/// before serving starts, with the `Simulator` that controls them while they serve. `missed`: how
/// they judge missed frames, "late" (as the real drive), "lost" (only frames lost on the line)
/// or "warn" (as the real drive, a would-be F125 warned of and not raised). `pace`: how fast
/// their firmware answers, "real" (as the real drive) or "immediate".
/// `setpoint_trace`: a `SetpointTrace` the drives' set-points are traced to. `on_stop(stats)`
/// is called once serving has stopped, with what the server did ([`ServerStatsView`]).
#[pyfunction]
#[pyo3(signature = (host, port, count = 1, on_start = None, missed = "late", setpoint_trace = None, on_stop = None, pace = "real", line = None))]
#[allow(clippy::too_many_arguments)]
fn serve_udp(
    py: Python<'_>,
    host: &str,
    port: u16,
    count: usize,
    on_start: Option<&Bound<'_, PyAny>>,
    missed: &str,
    setpoint_trace: Option<&PySetpointTrace>,
    on_stop: Option<&Bound<'_, PyAny>>,
    pace: &str,
    line: Option<&str>,
) -> PyResult<()> {
    let address: SocketAddr = (host, port)
        .to_socket_addrs()
        .ok()
        .and_then(|mut a| a.next())
        .ok_or_else(|| Error::from(SettingError::UnresolvedHost { host: host.to_owned(), role: "bind" }))
        .py()?;
    // Bound before on_start: a client waiting for what on_start says finds the socket there.
    let socket = server::bind_udp(address).py()?;
    let bus = controlled_bus((count, line), (missed, pace), on_start)?;
    let trace = setpoint_trace.map(|t| t.sender(bus.bus().len())).transpose()?;
    run_until_signal(py, on_stop, move |stop| server::serve_udp_on(socket, bus, stop, trace))
}

/// Serves `count` virtual AKDs, or the slaves `line` names, on network interface `iface` until
/// SIGINT/SIGTERM. `on_start(simulator)` is called once the socket is open, with the
/// `Simulator` that controls them; `missed`, `pace`, `setpoint_trace` and `on_stop` as for `serve_udp`. `busy_poll`: never sleep between frames,
/// answering each as it arrives as the drive's ESC does, on a CPU of its own (raises ConfigError
/// under SCHED_FIFO or SCHED_RR).
#[pyfunction]
#[pyo3(signature = (iface, count = 1, on_start = None, missed = "late", setpoint_trace = None, busy_poll = false, on_stop = None, pace = "real", line = None))]
#[allow(clippy::too_many_arguments)]
fn serve_iface(
    py: Python<'_>,
    iface: &str,
    count: usize,
    on_start: Option<&Bound<'_, PyAny>>,
    missed: &str,
    setpoint_trace: Option<&PySetpointTrace>,
    busy_poll: bool,
    on_stop: Option<&Bound<'_, PyAny>>,
    pace: &str,
    line: Option<&str>,
) -> PyResult<()> {
    let socket = server::open_iface(iface, busy_poll).py()?;
    let bus = controlled_bus((count, line), (missed, pace), on_start)?;
    let trace = setpoint_trace.map(|t| t.sender(bus.bus().len())).transpose()?;
    run_until_signal(py, on_stop, move |stop| server::serve_iface_on(socket, bus, stop, trace, busy_poll))
}

/// The SII EEPROM image the virtual slave `product` serves ("akd", "ek1100", "el1004", ...):
/// the AKD's is the real drive's, the EK1100's and EL2004's their real dumps, the others made as
/// the simulator's documentation says.
#[pyfunction]
fn sim_sii_image<'py>(py: Python<'py>, product: &str) -> PyResult<Bound<'py, PyBytes>> {
    let unknown = || SimLineError::UnknownProduct { position: 0, name: product.to_owned() };
    let known = SimProduct::parse(product).ok_or_else(unknown);
    let parsed = known.map_err(|error| Error::from(SettingError::SimLine { line: product.to_owned(), error })).py()?;
    let image = match terminal::description(parsed) {
        None => Ok(sii_image::akd_sii()),
        Some(description) => description.image(),
    };
    let image =
        image.map_err(|error| Error::from(SettingError::TerminalImage { product: parsed.name(), error })).py()?;
    Ok(PyBytes::new(py, &image))
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyVirtualBus>()?;
    m.add_class::<PySimulator>()?;
    m.add_class::<PySetpointTrace>()?;
    m.add_function(wrap_pyfunction!(serve_udp, m)?)?;
    m.add_function(wrap_pyfunction!(serve_iface, m)?)?;
    m.add("MISSED_FRAMES", MissedFrames::ALL.map(MissedFrames::name))?;
    m.add("PACES", Pace::ALL.map(Pace::name))?;
    m.add_function(wrap_pyfunction!(sim_sii_image, m)?)?;
    m.add("SIM_PRODUCTS", SimProduct::ALL.map(SimProduct::name))?;
    Ok(())
}
