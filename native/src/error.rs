//! The umbrella error of the master, the links, the cycle thread and the virtual AKD, and the
//! errors of those layers: each codec's own error lives beside the codec that raises it
//! (`frame::FrameError`, `mailbox::MailboxError`, ...) and is lifted into [`Error`] by `?`.
//!
//! Each error names what went wrong in the drive's or the standard's own words (the AL status
//! code's name, the SDO abort code's name) so that the Python exception it becomes can be read
//! without a manual.

use std::borrow::Cow;
use std::fmt;

pub use crate::drive::pdo::PdoError;
pub use crate::drive::trajectory::TrajectoryError;
use crate::ethercat::coe::SdoAbortCode;
pub use crate::ethercat::eoe::EoeError;
pub use crate::ethercat::foe::FoeError;
pub use crate::ethercat::frame::FrameError;
pub use crate::ethercat::link_spec::LinkSpecError;
pub use crate::ethercat::mailbox::MailboxError;
pub use crate::ethercat::sii::SiiError;
pub use crate::setting::SettingError;
pub use crate::wire_code::UnknownCode;

/// A name that is none of the allowed ones; the text lists them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum UnknownName {
    /// An AL state name.
    AlState {
        /// The name given.
        name: String,
    },
    /// A fault the virtual AKD does not raise.
    Fault {
        /// The name given.
        name: String,
        /// The faults' names and numbers, e.g. "sync_lost (F125)".
        allowed: Vec<String>,
    },
    /// A latch edge name.
    LatchEdge {
        /// The name given.
        name: String,
    },
    /// A command time-out policy name.
    CommandTimeoutPolicy {
        /// The name given.
        name: String,
    },
    /// How virtual AKDs judge missed frames.
    MissedFrames {
        /// The name given.
        name: String,
    },
    /// How a virtual AKD's homing fails.
    HomingFailure {
        /// The name given.
        name: String,
    },
    /// How fast virtual AKDs answer.
    Pace {
        /// The name given.
        name: String,
    },
}

impl fmt::Display for UnknownName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            UnknownName::AlState { name } => {
                write!(f, "unknown AL state {name:?} (allowed: init, preop, safeop, op, bootstrap)")
            }
            UnknownName::Fault { name, allowed } => {
                write!(f, "no fault named {name:?}: the virtual AKD raises {}", allowed.join(", "))
            }
            UnknownName::LatchEdge { name } => write!(f, "latch edge {name:?}: allowed \"rising\" or \"falling\""),
            UnknownName::CommandTimeoutPolicy { name } => {
                write!(f, "command timeout policy {name:?}: allowed \"hold\" or \"quick_stop\"")
            }
            UnknownName::MissedFrames { name } => write!(
                f,
                "missed frames judged {name:?}: allowed \"late\" (as the real drive), \"lost\" (only frames lost on \
                 the line) or \"warn\" (as the real drive, a would-be F125 counted and warned of, not raised)"
            ),
            UnknownName::Pace { name } => write!(
                f,
                "virtual AKD pace {name:?}: allowed \"real\" (as the real drive) or \"immediate\" (requests handled \
                 at once)"
            ),
            UnknownName::HomingFailure { name } => {
                write!(f, "homing failure {name:?}: allowed ok, error, no_reference")
            }
        }
    }
}

/// An operation that the master, the cycle thread or the simulator cannot do in the state it
/// is in; the text says what would make it possible.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Unavailable {
    /// Homing needs modes of operation and its display in the process data.
    HomingUnmapped {
        /// The slave's position.
        slave: u16,
    },
    /// Homing starts only in Operation enabled.
    HomingNotEnabled {
        /// The slave's position.
        slave: u16,
        /// The state it is in.
        state: &'static str,
    },
    /// No process image: the slaves were not taken to SafeOp.
    NoProcessImage,
    /// A slave without process data in the image.
    NoProcessData {
        /// Slave position.
        slave: u16,
        /// The slaves that have process data, when the cycle thread knows them.
        with_data: Option<Vec<u16>>,
    },
    /// Supervision asked of a bus without slaves.
    NoSlaves,
    /// Distributed clocks asked of a bus where no slave has one.
    NoDistributedClock,
    /// The cycle thread is stopped.
    CycleStopped {
        /// What no longer happens, e.g. "set-points no longer go out".
        consequence: Cow<'static, str>,
    },
    /// The cycle thread was stopped before.
    CycleAlreadyStopped,
    /// The slave is lost and being brought back: its mailbox is the recovery's meanwhile.
    Recovering {
        /// The slave's position.
        slave: u16,
    },
    /// The cycle thread panicked and took the master with it.
    CyclePanicked,
    /// A drive whose mapping lacks what the CiA 402 sequencer needs.
    NotSequenced {
        /// Slave position, once known.
        slave: Option<u16>,
        /// What the mapping lacks.
        missing: Vec<&'static str>,
    },
    /// A slave without a mapping, asked of the cycle thread.
    NoMapping {
        /// Slave position.
        slave: u16,
    },
    /// Process data for a slave whose SII describes no sync manager to carry them.
    NoSyncManager {
        /// Slave position.
        slave: u16,
        /// The sync manager (2 for outputs, 3 for inputs).
        n: u8,
    },
    /// A latch asked of a slave whose mapping carries none.
    NoLatch {
        /// Slave position.
        slave: u16,
    },
    /// Latch edges whose latched positions the mapping does not carry.
    LatchEdgesUnreadable {
        /// Slave position.
        slave: u16,
        /// Edge bits asked for and not readable.
        missing: u8,
        /// Edge bits readable.
        readable: u8,
    },
    /// A trajectory id that was never given, or whose status is no longer kept.
    NoSuchTrajectory {
        /// The id asked for.
        id: u32,
        /// The first and last ids whose statuses are kept, if any.
        kept: Option<(u32, u32)>,
    },
    /// A set-point handshake waited for where none was asked.
    NoHandshake {
        /// Drive position.
        position: u16,
    },
    /// A command time-out asked of a drive whose mapping does not carry what it watches.
    CommandTimeoutUnwatched {
        /// Slave position.
        slave: u16,
        /// What the mapping lacks.
        missing: &'static str,
    },
    /// An object that is not in the slave's output mapping.
    NotInOutputs {
        /// Slave position.
        slave: u16,
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
    },
    /// A cyclic frame sent while the last one's return was not taken yet.
    CyclicFrameInFlight,
    /// A cyclic frame's return asked for where none was sent.
    NoCyclicFrameInFlight,
    /// The master was closed, or is held by a cycle thread.
    MasterClosed,
    /// The master is in use by another thread.
    MasterBusy,
    /// A simulator asked of a link that is not in-process.
    NoSimulator,
    /// The simulator's server thread panicked.
    SimulatorPanicked,
    /// A set-point trace that cannot take a server.
    SetpointTrace {
        /// The trace file.
        path: String,
        /// Why not: closed, or taken by another server.
        why: &'static str,
    },
    /// A channel name a slave does not have among its outputs.
    NoSuchOutput {
        /// Slave position.
        slave: u16,
        /// The name given.
        name: String,
        /// Its output channels' names.
        outputs: Vec<String>,
        /// Whether the name is one of its inputs.
        is_input: bool,
    },
    /// Channels asked of a drive the cycle sequences.
    DriveChannels {
        /// Slave position.
        slave: u16,
    },
    /// A channel's value it cannot take.
    ChannelValue {
        /// Slave position.
        slave: u16,
        /// What is wrong with it.
        error: crate::ethercat::device::ChannelValueError,
    },
    /// The virtual AKDs are gone with their master or server.
    SimulatorGone,
    /// A drive that a trajectory or a homing drives, asked for what would fight it (a
    /// set-point, a mode change, a homing, a trajectory).
    Driven {
        /// Slave position.
        slave: u16,
        /// What was asked, e.g. "a set-point".
        what: &'static str,
        /// The trajectory that drives it, or `None` for its homing.
        trajectory: Option<u32>,
    },
    /// A set-point whose step from the target last sent, taken within one cycle, would go past
    /// the joint's limits.
    StepPastLimit {
        /// Slave position.
        slave: u16,
        /// The step, the limit and what to do, in the joint's words.
        detail: String,
    },
    /// A virtual AKD whose bus served no frame in time to answer a query.
    SimulatorSilent {
        /// Drive position, or `None` for a query of the line's counts.
        position: Option<usize>,
        /// How long the query waited.
        timeout: std::time::Duration,
    },
}

impl fmt::Display for Unavailable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Unavailable::NoProcessImage => write!(f, "no process image yet: take the slaves to SafeOp first"),
            Unavailable::HomingUnmapped { slave } => write!(
                f,
                "slave {slave} cannot home from the cycle: its mapping lacks modes of operation 0x6060 (outputs) or \
                 its display 0x6061 (inputs); map both (akd_ros's default mapping has them)"
            ),
            Unavailable::HomingNotEnabled { slave, state } => {
                write!(f, "slave {slave} cannot home: it is in {state}, not Operation enabled; enable it first")
            }
            Unavailable::NoProcessData { slave, with_data: None } => {
                write!(f, "slave {slave} has no process data (map it, then go to SafeOp)")
            }
            Unavailable::NoProcessData { slave, with_data: Some(with) } => {
                write!(f, "slave {slave} has no process data (slaves with process data: {with:?})")
            }
            Unavailable::NoSlaves => write!(f, "supervision needs at least one slave"),
            Unavailable::NoDistributedClock => {
                write!(f, "no slave on the bus has a distributed clock (ESC feature bit 2)")
            }
            Unavailable::CycleStopped { consequence } => write!(f, "the cycle is stopped: {consequence}"),
            Unavailable::CycleAlreadyStopped => write!(f, "the cycle thread was already stopped"),
            Unavailable::Recovering { slave } => write!(
                f,
                "slave {slave} is unreachable and being brought back; its objects can be read and written again once \
                 it is back in Op (see recovery_status)"
            ),
            Unavailable::CyclePanicked => write!(f, "the cycle thread panicked; the master is lost"),
            Unavailable::NotSequenced { slave, missing } => {
                if let Some(slave) = slave {
                    write!(f, "slave {slave}: ")?;
                }
                write!(f, "the drive cannot be sequenced: its mapping lacks {}", missing.join(" and "))
            }
            Unavailable::NoMapping { slave } => write!(f, "slave {slave} has no process-data mapping"),
            Unavailable::NoSyncManager { slave, n } => {
                write!(f, "slave {slave}'s SII describes no sync manager {n} to carry its process data")
            }
            Unavailable::NoLatch { slave } => write!(
                f,
                "slave {slave}'s mapping carries no latch: map latch control 0x20A4 and latch status 0x20A5 with a \
                 latched position (0x20A0..0x20A3, 0x20A6, 0x20A7), or the touch probe 0x60B8/0x60B9 with \
                 0x60BA..0x60BD"
            ),
            Unavailable::LatchEdgesUnreadable { slave, missing, readable } => write!(
                f,
                "slave {slave}'s mapping carries no latched position for edge bits 0x{missing:X} (readable: \
                 0x{readable:X}; bit 0 latch 1 rising, 1 latch 1 falling, 2 latch 2 rising, 3 latch 2 falling)"
            ),
            Unavailable::NoSuchTrajectory { id, kept: Some((first, last)) } => {
                write!(f, "no trajectory {id}: the statuses of trajectories {first} ..= {last} are kept")
            }
            Unavailable::NoSuchTrajectory { id, kept: None } => write!(f, "no trajectory {id}: none was played"),
            Unavailable::NoHandshake { position } => {
                write!(f, "drive {position}: no set-point handshake was asked for")
            }
            Unavailable::CommandTimeoutUnwatched { slave, missing } => {
                write!(f, "slave {slave}: the command time-out watches mapped targets, and the mapping lacks {missing}")
            }
            Unavailable::NotInOutputs { slave, index, subindex } => {
                write!(f, "0x{index:04X}:{subindex:02X} is not in slave {slave}'s output mapping")
            }
            Unavailable::CyclicFrameInFlight => write!(
                f,
                "a cyclic frame is already on its way: take its return with receive_process_data before sending \
                 the next"
            ),
            Unavailable::NoCyclicFrameInFlight => {
                write!(f, "no cyclic frame is on its way: send one with send_process_data first")
            }
            Unavailable::MasterClosed => {
                write!(f, "the master is closed, or handed to a Cycle (stop the Cycle to get it back)")
            }
            Unavailable::MasterBusy => {
                write!(f, "the master is in use by another thread; use one master from one thread at a time")
            }
            Unavailable::NoSimulator => write!(
                f,
                "Master.simulator is there for the in-process links \"sim\" and \"sim:N\" only; an akd-sim server \
                 takes its commands on stdin"
            ),
            Unavailable::SimulatorPanicked => write!(f, "the simulator thread panicked"),
            Unavailable::SetpointTrace { path, why } => write!(f, "the set-point trace {path} {why}"),
            Unavailable::Driven { slave, what, trajectory: Some(id) } => write!(
                f,
                "slave {slave}: {what} refused, nothing changed: trajectory {id} drives it until it ends; stop it \
                 (cancel its goal) or wait for its end"
            ),
            Unavailable::Driven { slave, what, trajectory: None } => write!(
                f,
                "slave {slave}: {what} refused, nothing changed: it is being homed; cancel the homing or wait for \
                 its end"
            ),
            Unavailable::StepPastLimit { slave, detail } => {
                write!(f, "slave {slave}: {detail}")
            }
            Unavailable::NoSuchOutput { slave, name, outputs, is_input } => {
                let outputs = if outputs.is_empty() { "none".to_owned() } else { outputs.join(", ") };
                match is_input {
                    true => write!(f, "slave {slave}'s channel {name:?} is an input; its outputs: {outputs}"),
                    false => write!(f, "slave {slave} has no output channel {name:?}; its outputs: {outputs}"),
                }
            }
            Unavailable::ChannelValue { slave, error } => write!(f, "slave {slave}: {error}"),
            Unavailable::DriveChannels { slave } => write!(
                f,
                "slave {slave} is a drive the cycle sequences: its outputs are its objects, set with set_object (or \
                 set_outputs), not by channel"
            ),
            Unavailable::SimulatorGone => {
                write!(f, "the virtual AKDs are gone: their master was closed or their server stopped")
            }
            Unavailable::SimulatorSilent { position, timeout } => write!(
                f,
                "{} not answered within {timeout:?}: the drives answer when their bus serves a frame and none passed \
                 (an idle in-process master exchanges no frames: start a Cycle, or query while a master call runs)",
                match position {
                    Some(position) => format!("the state of virtual AKD {position} was"),
                    None => "the line's counts were".to_owned(),
                }
            ),
        }
    }
}

/// Any failure of the master or of a link.
#[derive(Debug)]
pub enum Error {
    /// A malformed frame.
    Frame(FrameError),
    /// The operating system refused an operation on a link (socket, interface).
    Io {
        /// What was being done.
        context: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// No reply in time.
    Timeout {
        /// What was awaited; a fixed text where the cycle thread may meet it, which must not
        /// allocate even when a frame is lost.
        what: Cow<'static, str>,
    },
    /// A datagram's working counter was not the expected one.
    WorkingCounter {
        /// What the datagram did (a fixed text in the cycle, as for a time-out).
        what: Cow<'static, str>,
        /// The expected WKC.
        expected: u16,
        /// The WKC received.
        got: u16,
    },
    /// A slave refused or failed an AL state change.
    AlState {
        /// Slave position on the bus.
        slave: u16,
        /// The state requested.
        requested: &'static str,
        /// The state the slave is in.
        actual: &'static str,
        /// AL status code (register 0x0134).
        code: u16,
        /// The code's name.
        code_name: &'static str,
    },
    /// An SDO transfer was aborted by the slave or by the master.
    SdoAbort {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// Abort code.
        code: u32,
        /// The abort code's name.
        code_name: &'static str,
    },
    /// A mailbox reply that does not fit the request or the protocol.
    Mailbox(MailboxError),
    /// The SII EEPROM content or its interface is not as expected.
    Sii(SiiError),
    /// A process-data mapping that the AKD would refuse, or an unknown one.
    Pdo(PdoError),
    /// A link spec that names no link.
    LinkSpec(LinkSpecError),
    /// A value given for a setting outside what it allows.
    Setting(SettingError),
    /// A name that is none of the allowed ones.
    UnknownName(UnknownName),
    /// An operation not possible in the present state of the master, cycle or simulator.
    Unavailable(Unavailable),
    /// A station alias that is on no slave or on several, so it names no one drive.
    AliasNotUnique {
        /// The alias asked for.
        alias: u16,
        /// Slaves that have it.
        count: usize,
    },
    /// Another device answers at a slave's position than the scan found there (a drive swapped
    /// while the bus ran): it is not configured as if it were the old one.
    Replaced {
        /// The position.
        slave: u16,
        /// What the scan found there.
        expected: crate::ethercat::sii::Identity,
        /// What answers now.
        found: crate::ethercat::sii::Identity,
    },
    /// A slave position that is not on the bus.
    NoSuchSlave {
        /// The position asked for.
        position: u16,
        /// Slaves found.
        count: u16,
    },
    /// A trajectory refused before anything moved.
    Trajectory(TrajectoryError),
    /// A joint's command refused before anything was sent.
    Command(CommandRefused),
    /// An Ethernet-over-EtherCAT message or frame that does not fit the standard.
    Eoe(EoeError),
    /// A file transfer over EtherCAT that failed or a message that does not fit the standard.
    Foe(FoeError),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Frame(e) => write!(f, "{e}"),
            Error::Io { context, source } => write!(f, "{context}: {source}"),
            Error::Timeout { what } => write!(f, "timed out waiting for {what}"),
            Error::WorkingCounter { what, expected, got } => {
                write!(f, "working counter error on {what}: expected {expected}, got {got}")
            }
            Error::AlState { slave, requested, actual, code, code_name } => write!(
                f,
                "slave {slave} did not reach {requested}: it is in {actual}, AL status code 0x{code:04X} ({code_name})"
            ),
            Error::SdoAbort { index, subindex, code, code_name } => {
                write!(f, "SDO 0x{index:04X}:{subindex:02X} aborted with 0x{code:08X} ({code_name})")
            }
            Error::Mailbox(m) => write!(f, "mailbox: {m}"),
            Error::Sii(m) => write!(f, "SII: {m}"),
            Error::Pdo(m) => write!(f, "PDO mapping: {m}"),
            Error::LinkSpec(e) => write!(f, "configuration: {e}"),
            Error::Setting(e) => write!(f, "configuration: {e}"),
            Error::UnknownName(e) => write!(f, "configuration: {e}"),
            Error::Unavailable(e) => write!(f, "configuration: {e}"),
            Error::AliasNotUnique { alias, count } => {
                write!(f, "station alias {alias} is on {count} slave(s), not one")
            }
            Error::Replaced { slave, expected: e, found: n } => write!(
                f,
                "another device is at position {slave}: vendor 0x{:X}, product 0x{:X}, serial {} where the scan found \
                 vendor 0x{:X}, product 0x{:X}, serial {}; it is not configured as the old one (restart the bus to \
                 take it)",
                n.vendor_id, n.product_code, n.serial_number, e.vendor_id, e.product_code, e.serial_number
            ),
            Error::NoSuchSlave { position, count } => {
                write!(f, "no slave at position {position}: the bus has {count} slave(s)")
            }
            Error::Trajectory(e) => write!(f, "{e}"),
            Error::Command(e) => write!(f, "{e}"),
            Error::Eoe(e) => write!(f, "EoE: {e}"),
            Error::Foe(e) => write!(f, "FoE: {e}"),
        }
    }
}

impl std::error::Error for Error {}

/// `From` of each sub-error into the [`Error`] variant that carries it, so `?` lifts it.
macro_rules! error_from {
    ($($sub:ident => $variant:ident),+ $(,)?) => {
        $(impl From<$sub> for Error {
            fn from(e: $sub) -> Self {
                Error::$variant(e)
            }
        })+
    };
}

error_from! {
    MailboxError => Mailbox,
    SiiError => Sii,
    PdoError => Pdo,
    SettingError => Setting,
    UnknownName => UnknownName,
    Unavailable => Unavailable,
    LinkSpecError => LinkSpec,
    FrameError => Frame,
    TrajectoryError => Trajectory,
    CommandRefused => Command,
    EoeError => Eoe,
    FoeError => Foe,
}

impl From<UnknownCode> for Error {
    fn from(e: UnknownCode) -> Self {
        Error::Mailbox(MailboxError::UnknownCode(e))
    }
}

/// Why a joint's command was refused, nothing sent.
#[derive(Clone, Debug, PartialEq)]
pub enum CommandRefused {
    /// The drive's mode commands another kind, or none (or is not known).
    Mode {
        /// What was commanded.
        kind: crate::drive::ds402::CommandKind,
        /// The drive's mode.
        mode: String,
        /// The modes that take it, in words.
        needs: String,
    },
    /// The mode changed between making the command and sending it.
    ModeChanged {
        /// What was commanded.
        kind: crate::drive::ds402::CommandKind,
        /// The mode it was made for.
        made: String,
        /// The mode now.
        now: String,
    },
    /// The value has no drive value (NaN, past the drive object's range).
    Value {
        /// What was commanded.
        kind: crate::drive::ds402::CommandKind,
        /// Why.
        reason: crate::drive::scaling::ScalingError,
    },
    /// A drive's output its mapping does not carry.
    OutputUnmapped {
        /// The joint's name.
        joint: String,
        /// Which: "digital outputs (0x60FE:01)" or "analog output (0x3470:03)".
        what: &'static str,
        /// The drive's mode.
        mode: String,
        /// The mappings that carry it with that mode, in words.
        mappings: String,
    },
    /// A digital output the AKD does not have.
    NoSuchOutput {
        /// Its number, as given (an integer of any size).
        number: String,
    },
    /// An analog output voltage that is not finite or beyond the output's range.
    Voltage {
        /// The voltage asked for.
        volts: f64,
        /// The highest magnitude allowed.
        highest: f64,
    },
    /// The value could not be encoded, or the cycle refused the set-point.
    NotSent {
        /// What was refused: "position command", "outputs".
        what: String,
        /// Why.
        why: NotSent,
    },
}

/// Why a command was not sent.
#[derive(Clone, Debug, PartialEq)]
pub enum NotSent {
    /// Its value has no encoding in its object.
    Encode(crate::drive::objects::EncodeError),
    /// The cycle refused the set-point (a step past the joint's limits).
    Setting(SettingError),
    /// The cycle cannot take it now (a trajectory or a homing drives the drive).
    Unavailable(Unavailable),
}

impl fmt::Display for NotSent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NotSent::Encode(e) => write!(f, "{e}"),
            NotSent::Setting(e) => write!(f, "{e}"),
            NotSent::Unavailable(e) => write!(f, "{e}"),
        }
    }
}

impl fmt::Display for CommandRefused {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CommandRefused::Mode { kind, mode, needs } => {
                let kind = kind.name();
                write!(f, "{kind} command refused: the axis is in mode {mode}; {kind} commands need mode {needs}")
            }
            CommandRefused::ModeChanged { kind, made, now } => {
                write!(f, "{} command refused: it was made in mode {made}, the axis is in {now}", kind.name())
            }
            CommandRefused::Value { kind, reason } => write!(f, "{} command refused: {reason}", kind.name()),
            CommandRefused::OutputUnmapped { joint, what, mode, mappings } => {
                let refused = if what.starts_with("analog") { "analog output" } else { "outputs" };
                write!(
                    f,
                    "{refused} refused: the mapping of {joint} carries no {what}; mappings that do with mode {mode}: \
                     {mappings}"
                )
            }
            CommandRefused::NoSuchOutput { number } => write!(
                f,
                "outputs refused: output {number}: the AKD has digital outputs 1 to {}",
                crate::drive::io::OUTPUT_COUNT
            ),
            CommandRefused::Voltage { volts, highest } => write!(
                f,
                "analog output refused: {} V; allowed a finite voltage within ±{} V",
                crate::drive::scaling::py_repr(*volts),
                crate::drive::trajectory::trimmed(*highest)
            ),
            CommandRefused::NotSent { what, why } => write!(f, "{what} refused, nothing sent: {why}"),
        }
    }
}

/// Result of master and link operations.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An SDO transfer of `index`:`subindex` aborted with `code`.
    pub fn sdo_abort(index: u16, subindex: u8, code: SdoAbortCode) -> Self {
        Error::SdoAbort { index, subindex, code: code.0, code_name: code.name() }
    }

    /// An I/O error with what was being done.
    pub fn io(context: impl Into<String>, source: std::io::Error) -> Self {
        Error::Io { context: context.into(), source }
    }

    /// The last OS error with what was being done.
    pub fn last_os(context: impl Into<String>) -> Self {
        Error::io(context, std::io::Error::last_os_error())
    }
}

impl std::error::Error for UnknownName {}
impl std::error::Error for Unavailable {}
