//! Control of virtual slaves whose bus another thread owns: fault injection, the hardware enable
//! input, digital input levels and toggles (an AKD's, a digital input terminal's), the analog
//! inputs, the limit and home switches, the analog input, the failures of the field (a drive power-cycled, a cable
//! pulled, a port's link taken down, a faulty cable spoiling frames into a port, frames lost or
//! corrupted, wrong working counters: see [`crate::sim::line`]), and queries of the drive
//! firmware's state, a terminal's I/O and a slave's ESC (its links and error counters).
//!
//! The bus is owned by whoever serves its frames: the in-process link inside a master (and so
//! the cycle thread while a cycle runs), or the `akd-sim` server loop. A [`SimControl`] handle
//! (Clone + Send) sends commands over a `std::sync::mpsc` channel to the [`ControlledBus`]
//! there, which takes them with `try_recv` at each frame: with no command pending that costs
//! no lock, no wait and no allocation, so the cycle thread's exchange stays as it was.
//!
//! Changes are checked before they are sent (drive position, fault name, input number,
//! finite toggle positions), so a bad one is refused at the caller with the allowed values,
//! never lost on the owner's side. They apply before the next frame is served. A query of
//! [`DriveState`] is answered after that frame, so it sees every change sent before it.
//!
//! A query waits for the owner's next frame, with a time-out. The in-process bus is not
//! answered directly while its master is idle: it lives inside the master, which Python or the
//! cycle thread holds, and sharing it behind a lock would put a lock on the exchange path.
//! Nothing happens in an idle in-process bus anyway: its drives run on bus time, which moves
//! only with frames. A query to an idle master so fails after the time-out and says why; the
//! `akd-sim` server answers within its poll interval, frames or not
//! ([`ControlledBus::serve_commands`]).

use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender, SyncSender};
use std::time::Duration;

use std::sync::Arc;

use crate::drive::ds402::State;
use crate::error::{Error, FrameError, Result, SettingError, Unavailable};
use crate::ethercat::line_health::registers::{
    DlStatus, ErrorCounts, PortDescriptor, ERROR_COUNTERS, ERROR_COUNTERS_LEN, PORTS,
};
use crate::ethercat::link_spec::SimProduct;
use crate::sim::digital_inputs::Inputs;
use crate::sim::faults::Fault;
use crate::sim::homing::{Failure as HomingFailure, Setup};
use crate::sim::line::{Burst, Delivery, LineCounts};
use crate::sim::missed_frames::WouldBeF125;
use crate::sim::pll::SyncState;
use crate::sim::terminal::{TerminalState, VirtualTerminal};
use crate::sim::terminals::{Outputs, Terminals};
use crate::sim::{VirtualAkd, VirtualBus};

/// How long a [`SimControl::drive_state`] query waits for the owner by default.
pub const QUERY_TIMEOUT: Duration = Duration::from_secs(1);

/// The drive firmware's state as a query reports it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveState {
    /// The CiA 402 state.
    pub state: State,
    /// The active fault, if any.
    pub fault: Option<Fault>,
    /// Actual position as 0x6064 reports it, counts (fractional).
    pub position: f64,
    /// Shaft velocity, counts/s.
    pub velocity: f64,
    /// Motor torque, N·m.
    pub torque: f64,
    /// What its synchronisation was told (SYNC0, FBUS.PARAM02, cycle time).
    pub sync: SyncState,
    /// Digital inputs 0x60FD as the drive shows them.
    pub digital_inputs: u32,
    /// The outputs as the master drives them.
    pub outputs: Outputs,
    /// The F125 a real AKD would have raised where this one judges missed frames by "warn".
    pub would_be_f125: WouldBeF125,
}

impl DriveState {
    /// The state of `akd` now.
    pub fn of(akd: &VirtualAkd) -> Self {
        let drive = akd.drive();
        let shaft = drive.shaft();
        DriveState {
            state: drive.state(),
            fault: drive.fault(),
            position: drive.position(),
            velocity: shaft.velocity,
            torque: shaft.torque,
            sync: akd.sync_state(),
            digital_inputs: akd.od().get(0x60FD, 0).map_or(0, |b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            outputs: Terminals::outputs(akd.od()),
            would_be_f125: akd.would_be_f125(),
        }
    }
}

/// A slave's ESC as a query reports it: its ports and their links, its error counters as the
/// master reads them, and what it counted since power-up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EscState {
    /// Its port descriptor: the ports it has.
    pub port_descriptor: PortDescriptor,
    /// Its DL status: each port's link, loop and communication.
    pub dl_status: DlStatus,
    /// Its error counters' registers (stopped at 0xFF, cleared by the master's writes).
    pub registers: ErrorCounts<u8>,
    /// What they counted since power-up, never cleared.
    pub counted: ErrorCounts<u64>,
    /// Frames a faulty cable is still to spoil entering each port.
    pub spoiling: [u64; PORTS],
}

impl EscState {
    /// Slave `position`'s ESC on `bus` now.
    pub fn of(bus: &VirtualBus, position: usize) -> Self {
        let esc = bus.at(position).esc();
        let at = usize::from(ERROR_COUNTERS);
        let block = esc.memory()[at..at + ERROR_COUNTERS_LEN].try_into().expect("the block's length");
        EscState {
            port_descriptor: PortDescriptor(esc.hardware().port_descriptor),
            dl_status: DlStatus(esc.u16_at(crate::ethercat::registers::DL_STATUS)),
            registers: ErrorCounts::decode(block),
            counted: esc.counted(),
            spoiling: std::array::from_fn(|port| bus.line().spoiling(position, port)),
        }
    }
}

/// The cable into `port` of slave `position` of a line of `products`: the index of that cable
/// as [`VirtualBus::set_cable`] counts them (the one in front of a slave). Refused for a port the
/// slave's ESC lacks, and for one no cable of the virtual line reaches (the line is a daisy
/// chain: port 0 in, port 1 on to the next slave).
pub fn cable_at(products: &[SimProduct], position: usize, port: usize) -> Result<usize> {
    check_position(products.len(), position)?;
    let product = products[position];
    let descriptor = PortDescriptor(crate::sim::slave::hardware_of(product).port_descriptor);
    if port >= PORTS || !descriptor.has(port) {
        let ports: Vec<String> = descriptor.ports().map(|p| p.to_string()).collect();
        return Err(
            SettingError::NoSuchPort { position, product: product.name(), port, ports: ports.join(", ") }.into()
        );
    }
    let why = match port {
        0 => return Ok(position),
        1 if position + 1 < products.len() => return Ok(position + 1),
        1 => "it is the last slave of the line, nothing follows it on port 1",
        _ => "the virtual line is a daisy chain, each slave taking frames in at port 0 and passing them on at port 1",
    };
    Err(SettingError::NoCable { position, product: product.name(), port, why }.into())
}

/// Checks that slave `position` is on a line of `count` slaves.
pub fn check_position(count: usize, position: usize) -> Result<()> {
    if position < count {
        return Ok(());
    }
    Err(match (u16::try_from(position), u16::try_from(count)) {
        (Ok(position), Ok(count)) => Error::NoSuchSlave { position, count },
        _ => SettingError::DrivePosition { position, count }.into(),
    })
}

/// Checks that slave `position` of a line of `products` is an AKD, for `what`.
pub fn check_akd(products: &[SimProduct], position: usize, what: &'static str) -> Result<()> {
    check_kind(products, position, what, true)
}

/// Checks that slave `position` of a line of `products` is a terminal, for `what`.
pub fn check_terminal(products: &[SimProduct], position: usize, what: &'static str) -> Result<()> {
    check_kind(products, position, what, false)
}

fn check_kind(products: &[SimProduct], position: usize, what: &'static str, akd: bool) -> Result<()> {
    check_position(products.len(), position)?;
    let product = products[position];
    if (product == SimProduct::Akd) == akd {
        return Ok(());
    }
    let needs = if akd { "an AKD" } else { "a terminal" };
    Err(SettingError::WrongSlave { position, product: product.name(), what, needs }.into())
}

/// A change to one slave of a line, checked against that line's slaves when made.
#[derive(Clone, Debug, PartialEq)]
pub enum Change {
    /// Raise `fault` at the drive's next model step.
    InjectFault {
        /// Drive position.
        position: usize,
        /// The fault.
        fault: Fault,
    },
    /// Set the hardware enable input (X8).
    HardwareEnable {
        /// Drive position.
        position: usize,
        /// Input level.
        high: bool,
    },
    /// Make a digital input toggle where the actual position crosses `positions`.
    InputToggles {
        /// Drive position.
        position: usize,
        /// Digital input, 1..=7.
        input: usize,
        /// Toggle positions, counts, each finite.
        positions: Vec<f64>,
    },
    /// Set a digital input high or low (an AKD's wherever the shaft is).
    InputLevel {
        /// Slave position.
        position: usize,
        /// Digital input, from 1: an AKD's 1..=7, a digital input terminal's.
        input: usize,
        /// Its level.
        high: bool,
    },
    /// Set a switch of 0x60FD (a limit or home switch, the interlock) active or not.
    Switch {
        /// Drive position.
        position: usize,
        /// The switch's name, one [`crate::drive::io::Switch::from_name`] knows.
        name: String,
        /// Whether it is active.
        active: bool,
    },
    /// Set an analog input.
    AnalogInput {
        /// Slave position.
        position: usize,
        /// The input, from 1: an AKD's 1, an analog input terminal's.
        input: usize,
        /// Volts, within the range the slave measures.
        volts: f64,
    },
    /// Make the drive's homing runs fail, or work again.
    HomingFailure {
        /// Drive position.
        position: usize,
        /// How they fail; `None`: they work.
        failure: Option<HomingFailure>,
    },
    /// Power-cycle the drive ([`VirtualAkd::power_cycle`]).
    PowerCycle {
        /// Drive position.
        position: usize,
    },
    /// Pull the cable in front of the drive out, or plug it back in.
    Cable {
        /// Drive position.
        position: usize,
        /// Whether it is in.
        plugged: bool,
    },
    /// Make the cable into a port spoil frames ([`crate::sim::line::Line::spoil_port`]).
    SpoilPort {
        /// Slave position.
        position: usize,
        /// Its port.
        port: usize,
        /// Frames to spoil.
        frames: u64,
        /// One in every so many frames entering there.
        every: u64,
    },
    /// Lose, corrupt or give a wrong working counter to the next frames.
    Burst(Burst),
}

impl Change {
    /// Fault `name` (as [`Fault::from_name`] takes it, e.g. "F439" or "following_error") for
    /// the AKD at `position` of a line of `products`.
    pub fn inject_fault(products: &[SimProduct], position: usize, name: &str) -> Result<Self> {
        check_akd(products, position, "a fault")?;
        Ok(Change::InjectFault { position, fault: Fault::from_name(name)? })
    }

    /// Hardware enable `high` or low for the AKD at `position` of a line of `products`.
    pub fn hardware_enable(products: &[SimProduct], position: usize, high: bool) -> Result<Self> {
        check_akd(products, position, "the hardware enable")?;
        Ok(Change::HardwareEnable { position, high })
    }

    /// Toggle positions of digital input `input` of the AKD at `position` of a line of
    /// `products`; refused for an input outside 1..=7 or a position that is not finite.
    pub fn input_toggles(products: &[SimProduct], position: usize, input: usize, positions: Vec<f64>) -> Result<Self> {
        check_akd(products, position, "input toggles")?;
        // The drive's own inputs decide what they take; a scratch set asks them now, so the
        // owner never gets a change it would refuse.
        Inputs::default().set_toggles(input, &positions)?;
        Ok(Change::InputToggles { position, input, positions })
    }

    /// Digital input `input` of slave `position` of a line of `products` `high` or low; refused
    /// for an input the slave does not have (an AKD has 1..=7, an EL1004 1..=4, ...).
    pub fn input_level(products: &[SimProduct], position: usize, input: usize, high: bool) -> Result<Self> {
        check_position(products.len(), position)?;
        match products[position] {
            SimProduct::Akd => Inputs::default().set_level(input, high)?,
            product => VirtualTerminal::check_input(product, position, input, false)?,
        }
        Ok(Change::InputLevel { position, input, high })
    }

    /// Switch `name` of the AKD at `position` of a line of `products` `active` or not; refused
    /// for a name that is none of 0x60FD's switches.
    pub fn switch(products: &[SimProduct], position: usize, name: &str, active: bool) -> Result<Self> {
        check_akd(products, position, "a switch")?;
        Terminals::default().set_switch(name, active)?;
        Ok(Change::Switch { position, name: name.to_owned(), active })
    }

    /// Analog input `input` of slave `position` of a line of `products` at `volts`; refused for
    /// an input the slave does not have, and when not finite or beyond what it measures (what
    /// an AKD's 0x3470:04 holds, an EL3102's ±10 V).
    pub fn analog_input(products: &[SimProduct], position: usize, input: usize, volts: f64) -> Result<Self> {
        check_position(products.len(), position)?;
        match products[position] {
            SimProduct::Akd if input == 1 => Terminals::default().set_analog_input(volts)?,
            SimProduct::Akd => {
                let kind = "analog";
                return Err(SettingError::TerminalInput { position, product: "akd", input, count: 1, kind }.into());
            }
            product => {
                VirtualTerminal::check_input(product, position, input, true)?;
                VirtualTerminal::check_volts(volts)?;
            }
        }
        Ok(Change::AnalogInput { position, input, volts })
    }

    /// Homing failure `name` ("ok", "error", "no_reference", see [`HomingFailure`]) for the AKD
    /// at `position` of a line of `products`.
    pub fn homing_failure(products: &[SimProduct], position: usize, name: &str) -> Result<Self> {
        check_akd(products, position, "homing")?;
        Ok(Change::HomingFailure { position, failure: HomingFailure::from_name(name)? })
    }

    /// Power-cycle slave `position` of a line of `products`.
    pub fn power_cycle(products: &[SimProduct], position: usize) -> Result<Self> {
        check_position(products.len(), position)?;
        Ok(Change::PowerCycle { position })
    }

    /// Pull the cable in front of slave `position` of a line of `products` out, or plug it in.
    pub fn cable(products: &[SimProduct], position: usize, plugged: bool) -> Result<Self> {
        check_position(products.len(), position)?;
        Ok(Change::Cable { position, plugged })
    }

    /// Takes the link at `port` of slave `position` of a line of `products` down (`up` false) or
    /// up again: the cable there pulled out or plugged back in.
    pub fn link(products: &[SimProduct], position: usize, port: usize, up: bool) -> Result<Self> {
        Ok(Change::Cable { position: cable_at(products, position, port)?, plugged: up })
    }

    /// The cable into `port` of slave `position` of a line of `products` spoils the next
    /// `frames` frames entering there, one in every `every`; refused for a negative count, an
    /// `every` below 1, and a port no cable reaches.
    pub fn spoil_port(products: &[SimProduct], position: usize, port: usize, frames: i64, every: i64) -> Result<Self> {
        cable_at(products, position, port)?;
        let frames = Burst::frames(frames)?;
        let every = u64::try_from(every).ok().filter(|&e| e >= 1).ok_or(SettingError::FrameSpacing { every })?;
        Ok(Change::SpoilPort { position, port, frames, every })
    }

    /// Applies the change to `bus` (the bus it was checked against).
    pub fn apply(self, bus: &mut VirtualBus) {
        match self {
            Change::InjectFault { position, fault } => bus.slave_mut(position).drive_mut().inject(fault),
            Change::HardwareEnable { position, high } => bus.slave_mut(position).drive_mut().set_hardware_enable(high),
            Change::InputToggles { position, input, positions } => {
                let checked = bus.slave_mut(position).drive_mut().inputs_mut().set_toggles(input, &positions);
                debug_assert!(checked.is_ok(), "checked when the change was made: {checked:?}");
            }
            Change::InputLevel { position, input, high } => match bus.at_mut(position).terminal_mut() {
                Some(terminal) => terminal.set_input(input, high),
                None => {
                    let checked = bus.slave_mut(position).drive_mut().inputs_mut().set_level(input, high);
                    debug_assert!(checked.is_ok(), "checked when the change was made: {checked:?}");
                }
            },
            Change::Switch { position, name, active } => {
                let checked = bus.slave_mut(position).drive_mut().terminals_mut().set_switch(&name, active);
                debug_assert!(checked.is_ok(), "checked when the change was made: {checked:?}");
            }
            Change::AnalogInput { position, input, volts } => match bus.at_mut(position).terminal_mut() {
                Some(terminal) => terminal.set_analog_input(input, volts),
                None => {
                    let checked = bus.slave_mut(position).drive_mut().terminals_mut().set_analog_input(volts);
                    debug_assert!(checked.is_ok(), "checked when the change was made: {checked:?}");
                }
            },
            Change::HomingFailure { position, failure } => {
                let drive = bus.slave_mut(position).drive_mut();
                drive.set_homing(Setup { failure, ..drive.homing_setup() });
            }
            // A test's rare event: the fresh drive's allocation on the owner's side is the
            // power-up's, not the exchange path's.
            Change::PowerCycle { position } => bus.power_cycle(position),
            Change::Cable { position, plugged } => bus.set_cable(position, plugged),
            Change::SpoilPort { position, port, frames, every } => bus.spoil_port(position, port, frames, every),
            Change::Burst(burst) => bus.start_burst(burst),
        }
    }
}

/// What a [`SimControl`] sends to the owner of the bus.
enum Message {
    Change(Change),
    DriveState { position: usize, reply: SyncSender<DriveState> },
    TerminalState { position: usize, reply: SyncSender<TerminalState> },
    EscState { position: usize, reply: SyncSender<EscState> },
    LineCounts { reply: SyncSender<LineCounts> },
}

/// A handle that controls virtual slaves whose bus another thread serves.
#[derive(Clone, Debug)]
pub struct SimControl {
    sender: Sender<Message>,
    products: Arc<[SimProduct]>,
}

impl SimControl {
    /// Number of slaves on the line.
    pub fn len(&self) -> usize {
        self.products.len()
    }

    /// Whether the line has no slave.
    pub fn is_empty(&self) -> bool {
        self.products.is_empty()
    }

    /// The line's slaves, in order.
    pub fn products(&self) -> &[SimProduct] {
        &self.products
    }

    fn send(&self, message: Message) -> Result<()> {
        self.sender.send(message).map_err(|_| gone())
    }

    /// Sends `change`, which one of [`Change`]'s constructors checked against
    /// [`products`](Self::products), to the owner, who makes it before the next frame; a change
    /// refused there is returned as it is, and nothing is sent.
    pub fn change(&self, change: Result<Change>) -> Result<()> {
        self.send(Message::Change(change?))
    }

    /// The drive firmware's state of drive `position` after the owner's next frame; waits up
    /// to `timeout` for it.
    pub fn drive_state(&self, position: usize, timeout: Duration) -> Result<DriveState> {
        check_akd(&self.products, position, "a drive state")?;
        let (reply, answer) = mpsc::sync_channel(1);
        self.send(Message::DriveState { position, reply })?;
        wait(&answer, Some(position), timeout)
    }

    /// The I/O of the terminal at `position` after the owner's next frame; waits up to
    /// `timeout` for it.
    pub fn terminal_state(&self, position: usize, timeout: Duration) -> Result<TerminalState> {
        check_terminal(&self.products, position, "a terminal state")?;
        let (reply, answer) = mpsc::sync_channel(1);
        self.send(Message::TerminalState { position, reply })?;
        wait(&answer, Some(position), timeout)
    }

    /// The ESC of slave `position` ([`EscState`]) after the owner's next frame; waits up to
    /// `timeout` for it.
    pub fn esc_state(&self, position: usize, timeout: Duration) -> Result<EscState> {
        check_position(self.products.len(), position)?;
        let (reply, answer) = mpsc::sync_channel(1);
        self.send(Message::EscState { position, reply })?;
        wait(&answer, Some(position), timeout)
    }

    /// What the line did to the frames it carried ([`LineCounts`]), after the owner's next
    /// frame (counted in); waits up to `timeout` for it.
    pub fn line_counts(&self, timeout: Duration) -> Result<LineCounts> {
        let (reply, answer) = mpsc::sync_channel(1);
        self.send(Message::LineCounts { reply })?;
        wait(&answer, None, timeout)
    }
}

/// The owner's answer to a query about slave `position` (`None`: the line), waited for up to
/// `timeout`.
fn wait<T>(answer: &Receiver<T>, position: Option<usize>, timeout: Duration) -> Result<T> {
    answer.recv_timeout(timeout).map_err(|e| match e {
        RecvTimeoutError::Disconnected => gone(),
        RecvTimeoutError::Timeout => Unavailable::SimulatorSilent { position, timeout }.into(),
    })
}

fn gone() -> Error {
    Unavailable::SimulatorGone.into()
}

/// A [`VirtualBus`] that takes commands from [`SimControl`] handles while it serves frames.
pub struct ControlledBus {
    bus: VirtualBus,
    receiver: Receiver<Message>,
    control: SimControl,
    /// Queries taken before a frame, answered after it. Its capacity stays once a query came,
    /// so later queries do not allocate on the owner's side either.
    queries: Vec<(usize, SyncSender<DriveState>)>,
    /// Queries of terminals, likewise.
    terminal_queries: Vec<(usize, SyncSender<TerminalState>)>,
    /// Queries of ESCs, likewise.
    esc_queries: Vec<(usize, SyncSender<EscState>)>,
    /// Queries of the line's counts, likewise.
    line_queries: Vec<SyncSender<LineCounts>>,
}

impl From<VirtualBus> for ControlledBus {
    fn from(bus: VirtualBus) -> Self {
        let (sender, receiver) = mpsc::channel();
        let control = SimControl { sender, products: bus.products().into() };
        let (queries, terminal_queries, esc_queries, line_queries) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        ControlledBus { bus, receiver, control, queries, terminal_queries, esc_queries, line_queries }
    }
}

impl ControlledBus {
    /// A handle that controls this bus from any thread.
    pub fn control(&self) -> SimControl {
        self.control.clone()
    }

    /// The bus.
    pub fn bus(&self) -> &VirtualBus {
        &self.bus
    }

    /// The bus, to change it directly (the owner's own tests).
    pub fn bus_mut(&mut self) -> &mut VirtualBus {
        &mut self.bus
    }

    /// Serves an EtherCAT payload in place at bus time `now_ns` as [`VirtualBus::process`]
    /// does, with the changes sent before it applied first and the queries answered after it.
    pub fn process(&mut self, payload: &mut [u8], now_ns: u64) -> std::result::Result<Delivery, FrameError> {
        let served = self.answer(payload, now_ns);
        self.bus.run_ip_stacks(now_ns);
        served
    }

    /// [`process`](Self::process) without the drives' IP stacks ([`VirtualBus::answer`]), for a
    /// server that sends the frame back before it runs them ([`run_ip_stacks`](Self::run_ip_stacks)).
    pub fn answer(&mut self, payload: &mut [u8], now_ns: u64) -> std::result::Result<Delivery, FrameError> {
        self.take_commands();
        let served = self.bus.answer(payload, now_ns);
        self.answer_queries();
        served
    }

    /// The drives' IP stacks at bus time `now_ns`, after a frame [`answer`](Self::answer) served.
    pub fn run_ip_stacks(&mut self, now_ns: u64) {
        self.bus.run_ip_stacks(now_ns);
    }

    /// No frame came until bus time `now_ns`: the drives' firmware runs up to it (supervision
    /// counts the frames missed), and the commands waiting are served.
    pub fn idle(&mut self, now_ns: u64) {
        self.bus.advance(now_ns);
        self.serve_commands();
    }

    /// Applies the changes and answers the queries pending, with no frame: for an owner that
    /// waits for frames and wakes up now and then (the `akd-sim` server).
    pub fn serve_commands(&mut self) {
        self.take_commands();
        self.answer_queries();
    }

    fn take_commands(&mut self) {
        while let Ok(message) = self.receiver.try_recv() {
            match message {
                Message::Change(change) => change.apply(&mut self.bus),
                Message::DriveState { position, reply } => self.queries.push((position, reply)),
                Message::TerminalState { position, reply } => self.terminal_queries.push((position, reply)),
                Message::EscState { position, reply } => self.esc_queries.push((position, reply)),
                Message::LineCounts { reply } => self.line_queries.push(reply),
            }
        }
    }

    fn answer_queries(&mut self) {
        for (position, reply) in self.queries.drain(..) {
            // A query that timed out has dropped its receiver; there is nobody left to tell.
            let _ = reply.try_send(DriveState::of(self.bus.slave(position)));
        }
        for (position, reply) in self.terminal_queries.drain(..) {
            if let Some(terminal) = self.bus.at(position).terminal() {
                let _ = reply.try_send(terminal.state());
            }
        }
        for (position, reply) in self.esc_queries.drain(..) {
            let _ = reply.try_send(EscState::of(&self.bus, position));
        }
        for reply in self.line_queries.drain(..) {
            let _ = reply.try_send(self.bus.line().counts());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::frame::{Command, FrameBuilder};
    use crate::sim::Timing;

    /// One BRD of the AL status through `bus` at `now_ns`.
    fn frame(bus: &mut ControlledBus, now_ns: u64) {
        let mut buf = [0u8; 64];
        let mut b = FrameBuilder::new(&mut buf);
        b.push(Command::Brd, 0, 0, 0x0130, &[0, 0]).unwrap();
        let len = b.finish();
        bus.process(&mut buf[..len], now_ns).unwrap();
    }

    #[test]
    fn changes_are_checked_before_they_are_sent() {
        let bus = ControlledBus::from(VirtualBus::with_timing(2, Timing::IMMEDIATE));
        let control = bus.control();
        let line = control.products();
        let max = format!("no slave at position {}: the bus has 2", usize::MAX);
        let refused: [(Result<Change>, &[&str]); 11] = [
            (Change::inject_fault(line, 2, "F439"), &["no slave at position 2: the bus has 2 slave(s)"]),
            (Change::inject_fault(line, 0, "F1"), &["no fault named \"F1\"", "following_error (F439)"]),
            (Change::input_toggles(line, 1, 8, vec![1.0]), &["digital input 8: the AKD has inputs 1 to 7"]),
            (
                Change::input_toggles(line, 1, 1, vec![1.0, f64::INFINITY]),
                &["toggle position inf of digital input 1 is not a finite"],
            ),
            (Change::power_cycle(line, 2), &["no slave at position 2: the bus has 2 slave(s)"]),
            (Change::cable(line, 3, false), &["no slave at position 3: the bus has 2 slave(s)"]),
            (Change::link(line, 1, 1, false), &["no cable at port 1 of the akd at position 1: it is the last slave"]),
            (Change::spoil_port(line, 0, 2, 10, 1), &["port 2: the akd at position 0 has ports 0, 1"]),
            (Change::spoil_port(line, 0, 1, 10, 0), &["one frame in every 0: allowed are 1 (each frame) or more"]),
            (Change::spoil_port(line, 0, 1, -1, 1), &["-1 frames"]),
            (Change::hardware_enable(line, usize::MAX, false), &[&max]),
        ];
        for (change, expected) in refused {
            let e = control.change(change).unwrap_err().to_string();
            assert!(expected.iter().all(|x| e.contains(x)), "{e}");
        }
        // Nothing refused reached the owner.
        assert!(bus.receiver.try_recv().is_err());
    }

    #[test]
    fn a_query_is_answered_after_the_next_frame_with_the_changes_before_it() {
        let mut bus = ControlledBus::from(VirtualBus::with_timing(2, Timing::IMMEDIATE));
        let control = bus.control();
        frame(&mut bus, 0);
        control.change(Change::inject_fault(control.products(), 1, "sync_lost")).unwrap();
        control.change(Change::hardware_enable(control.products(), 0, false)).unwrap();
        control.change(Change::input_toggles(control.products(), 0, 1, vec![-10.0])).unwrap();
        let asking = std::thread::spawn(move || control.drive_state(1, Duration::from_secs(30)));
        // The query reaches the owner's queue before the frame that answers it.
        while !asking.is_finished() {
            frame(&mut bus, 1_000_000);
            std::thread::sleep(Duration::from_millis(1));
        }
        let state = asking.join().unwrap().unwrap();
        assert_eq!((state.state, state.fault), (State::Fault, Some(Fault::SyncLost)));
        let counting = std::thread::spawn({
            let control = bus.control();
            move || control.line_counts(Duration::from_secs(30))
        });
        let mut frames = bus.bus().line().counts().frames;
        while !counting.is_finished() {
            frame(&mut bus, 2_000_000);
            frames += 1;
            std::thread::sleep(Duration::from_millis(1));
        }
        // Answered after the frame it reached the owner before, that frame counted in.
        let counts = counting.join().unwrap().unwrap();
        assert!(counts.frames <= frames && counts.frames > 1, "{counts:?}, {frames} served");
        assert_eq!(bus.bus().slave(0).drive().fault(), None);
        // Input 1 is high above -10 counts: the toggles arrived.
        assert_eq!(bus.bus().slave(0).od().get(0x20A5, 0).unwrap()[1] & 0x80, 0x80);
    }

    #[test]
    fn an_idle_owner_is_named_and_a_gone_one_too() {
        let bus = ControlledBus::from(VirtualBus::new(1));
        let control = bus.control();
        let e = control.drive_state(0, Duration::from_millis(10)).unwrap_err().to_string();
        assert!(e.contains("not answered within 10ms") && e.contains("idle in-process master"), "{e}");
        let e = control.line_counts(Duration::from_millis(10)).unwrap_err().to_string();
        assert!(e.contains("the line's counts were not answered within 10ms"), "{e}");
        drop(bus);
        let e = control.change(Change::hardware_enable(control.products(), 0, true)).unwrap_err().to_string();
        assert!(e.contains("the virtual AKDs are gone"), "{e}");
        assert!(control.drive_state(0, QUERY_TIMEOUT).unwrap_err().to_string().contains("gone"));
        assert!(control.line_counts(QUERY_TIMEOUT).unwrap_err().to_string().contains("gone"));
    }

    #[test]
    fn a_server_answers_between_frames() {
        let mut bus = ControlledBus::from(VirtualBus::new(1));
        let control = bus.control();
        control.change(Change::hardware_enable(control.products(), 0, false)).unwrap();
        let asking = std::thread::spawn(move || control.drive_state(0, Duration::from_secs(30)));
        while !asking.is_finished() {
            bus.serve_commands();
            std::thread::sleep(Duration::from_millis(1));
        }
        let state = asking.join().unwrap().unwrap();
        assert_eq!((state.state, state.fault, state.position), (State::NotReadyToSwitchOn, None, 0.0));
    }
}
