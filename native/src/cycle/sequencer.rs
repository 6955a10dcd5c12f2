//! The master-side CiA 402 sequencer that runs inside the cycle thread, one per drive.
//!
//! Each cycle it decodes the drive's statusword from the inputs and, once a request (enable,
//! disable, quick stop, fault reset) was made, writes the controlword that moves the drive one
//! step toward it ([`ds402::step_toward`]); a fault reset goes out as a rising edge of bit 7
//! (low one cycle, then high), since the AKD reacts to the edge only. Requests come from other
//! threads through an atomic and the status goes back through another, so nothing here locks,
//! allocates or waits.
//!
//! Bumpless start: while the drive is not in Operation enabled the position target is the
//! actual position read in the same cycle, and after the drive gets there the target stays
//! held until a set-point is written for it, so a stale set-point (0 after power-up, or where
//! the axis was before it moved by hand) never makes it jump.
//!
//! Nothing is retried into motion: a drive that leaves Operation enabled by itself (fault,
//! hardware enable low) is brought to Switch on disabled, and enable does not reset faults.
//! A request that does not reach its state within the time-out is reported stuck, with the
//! statusword of that moment, from which [`DriveStatus::stuck_reason`] says why.

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, Ordering};

use crate::cycle::image::{i32_at, u16_at};
use crate::drive::ds402::{self, controlword as cw, statusword as sw, State};
use crate::drive::objects::POSITION_ACTUAL;
use crate::error::{Result, Unavailable};
use crate::ethercat::pdo::{find, PdoEntry};

named_variants! {
    /// What a caller asks of a drive; in Python `DriveRequest` (`DriveRequest.ENABLE`, ...),
    /// which prints as its [`name`](Request::name).
    #[cfg_attr(feature = "python", pyo3::pyclass(name = "DriveRequest", module = "akd_ros._native", frozen, eq, eq_int, rename_all = "SCREAMING_SNAKE_CASE"))]
    #[repr(u8)]
    pub enum Request {
        /// To Operation enabled (from Switch on disabled, not from Fault).
        Enable = 1 => "enable",
        /// To Switch on disabled (power stage off).
        Disable = 2 => "disable",
        /// Quick stop: brake with 0x6085 and hold in Quick stop active (from Operation enabled).
        QuickStop = 3 => "quick_stop",
        /// Fault reset by a rising edge of bit 7: Fault to Switch on disabled.
        FaultReset = 4 => "reset_fault",
    }
    /// The request's name as the Python API spells it.
    fn name;
}

impl Request {
    fn from_u8(value: u8) -> Option<Request> {
        Request::ALL.into_iter().find(|r| *r as u8 == value)
    }

    /// Whether the drive in `state` has done what was asked.
    fn reached(self, state: State) -> bool {
        match self {
            Request::Enable => state == State::OperationEnabled,
            Request::Disable | Request::FaultReset => state == State::SwitchOnDisabled,
            // From a state with the power stage off, quick stop ends in Switch on disabled.
            Request::QuickStop => matches!(state, State::QuickStopActive | State::SwitchOnDisabled),
        }
    }
}

/// Where the sequencer finds a drive's objects in its process data (byte offsets within the
/// drive's own outputs and inputs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Offsets {
    /// Controlword 0x6040 in the outputs.
    pub controlword: usize,
    /// Statusword 0x6041 in the inputs.
    pub statusword: usize,
    /// Position targets held while not enabled: 0x607A and 0x60C1:01, where mapped.
    pub targets: [Option<usize>; 2],
    /// Actual position in the inputs: the first of [`POSITION_ACTUAL`] mapped.
    pub actual: Option<usize>,
    /// Modes of operation display 0x6061 in the inputs, where mapped.
    pub mode_display: Option<usize>,
    /// Target velocity 0x60FF in the outputs, where mapped: 0 while the target is held.
    pub velocity_target: Option<usize>,
    /// Target torque 0x6071 in the outputs, where mapped: 0 while the target is held.
    pub torque_target: Option<usize>,
    /// Modes of operation 0x6060 in the outputs, where mapped.
    pub mode: Option<usize>,
    /// Velocity actual 0x606C in the inputs, where mapped (recorded, not sequenced).
    pub velocity_actual: Option<usize>,
    /// Torque actual 0x6077 in the inputs, where mapped (recorded).
    pub torque_actual: Option<usize>,
    /// Following error 0x60F4 in the inputs, where mapped (recorded).
    pub following_error: Option<usize>,
}

impl Offsets {
    /// Finds the objects in a drive's mapping; a mapping without controlword or statusword
    /// cannot be sequenced and is refused, naming what is missing.
    pub fn find(rx: &[PdoEntry], tx: &[PdoEntry]) -> Result<Offsets, Unavailable> {
        let at = |entries: &[PdoEntry], index: u16, subindex: u8| find(entries, index, subindex).map(|(o, _)| o);
        let controlword = at(rx, 0x6040, 0);
        let statusword = at(tx, 0x6041, 0);
        let (Some(controlword), Some(statusword)) = (controlword, statusword) else {
            let missing: Vec<&'static str> = [
                controlword.is_none().then_some("controlword 0x6040 in the outputs (RxPDO)"),
                statusword.is_none().then_some("statusword 0x6041 in the inputs (TxPDO)"),
            ]
            .into_iter()
            .flatten()
            .collect();
            return Err(Unavailable::NotSequenced { slave: None, missing });
        };
        let targets = [at(rx, 0x607A, 0), at(rx, 0x60C1, 1)];
        let actual = POSITION_ACTUAL.iter().find_map(|&(index, subindex)| at(tx, index, subindex));
        Ok(Offsets {
            controlword,
            statusword,
            targets,
            actual,
            mode_display: at(tx, 0x6061, 0),
            velocity_target: at(rx, 0x60FF, 0),
            torque_target: at(rx, 0x6071, 0),
            mode: at(rx, 0x6060, 0),
            velocity_actual: at(tx, 0x606C, 0),
            torque_actual: at(tx, 0x6077, 0),
            following_error: at(tx, 0x60F4, 0),
        })
    }

    /// The same objects with their offsets moved by `out_base` and `in_base` (a slave's place
    /// in the whole images).
    pub fn shifted(self, out_base: usize, in_base: usize) -> Offsets {
        let out = |o: Option<usize>| o.map(|o| o + out_base);
        let inp = |o: Option<usize>| o.map(|o| o + in_base);
        Offsets {
            controlword: self.controlword + out_base,
            statusword: self.statusword + in_base,
            targets: self.targets.map(out),
            actual: inp(self.actual),
            mode_display: inp(self.mode_display),
            velocity_target: out(self.velocity_target),
            torque_target: out(self.torque_target),
            mode: out(self.mode),
            velocity_actual: inp(self.velocity_actual),
            torque_actual: inp(self.torque_actual),
            following_error: inp(self.following_error),
        }
    }
}

named_variants! {
    /// How far the current request is; in Python `RequestProgress` (`RequestProgress.STUCK`,
    /// ...), which prints as its [`name`](Progress::name).
    #[cfg_attr(feature = "python", pyo3::pyclass(name = "RequestProgress", module = "akd_ros._native", frozen, eq, eq_int, rename_all = "SCREAMING_SNAKE_CASE"))]
    #[derive(Default)]
    pub enum Progress {
        /// No request was made yet: the sequencer leaves the drive's outputs alone.
        #[default]
        Idle => "idle",
        /// The request is under way.
        InProgress => "in_progress",
        /// The drive reached the requested state.
        Done => "done",
        /// The time-out passed first, or the drive cannot get there (see [`DriveStatus::stuck_reason`]).
        Stuck => "stuck",
        /// The drive left the state it reached by itself (fault, hardware enable low); the
        /// sequencer brought it to Switch on disabled and does not retry.
        Lost => "lost",
    }
    /// The progress's name as the Python API spells it: "in_progress".
    fn name;
}

/// A drive's status as the cycle thread last published it; the same object in Python
/// (`Cycle.drive_status`), and what akd_ros/DriveStatus says of the drive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "python", pyo3::pyclass(module = "akd_ros._native", frozen, get_all))]
pub struct DriveStatus {
    /// The last statusword read (0 before the first cycle).
    pub statusword: u16,
    /// The last request, if any.
    pub request: Option<Request>,
    /// How far it is.
    pub progress: Progress,
    /// Mode display 0x6061 where mapped.
    pub mode_display: Option<i8>,
}

impl DriveStatus {
    /// The state the statusword shows, if it shows a valid one.
    pub fn state(&self) -> Option<State> {
        State::from_statusword(self.statusword)
    }

    /// Why a request is stuck or lost, from the statusword: fault, warning (on the AKD the
    /// hardware enable input is low), quick stop active, voltage not enabled. `None` when it
    /// is neither stuck nor lost.
    pub fn stuck_reason(&self) -> Option<String> {
        if !matches!(self.progress, Progress::Stuck | Progress::Lost) {
            return None;
        }
        let state = self.state().map_or("no valid state", State::name);
        let s = self.statusword;
        let mut why: Vec<&str> = Vec::new();
        if s & sw::FAULT != 0 {
            why.push("fault (bit 3): reset_fault() first; 0x603F gives the error code");
        }
        if s & sw::WARNING != 0 {
            why.push("warning (bit 7): on the AKD the hardware enable input is low");
        }
        if self.state() == Some(State::QuickStopActive) {
            why.push("quick stop active");
        }
        if s & sw::VOLTAGE_ENABLED == 0 && self.request == Some(Request::Enable) {
            why.push("voltage not enabled (bit 4)");
        }
        let what = if self.progress == Progress::Lost { "left the requested state" } else { "stuck" };
        let request = self.request.map_or("", Request::name);
        if why.is_empty() {
            return Some(format!("{request} {what} in {state} (statusword 0x{s:04X})"));
        }
        Some(format!("{request} {what} in {state} (statusword 0x{s:04X}): {}", why.join("; ")))
    }

    fn pack(self) -> u64 {
        let progress = self.progress as u64;
        let mode = self.mode_display.map_or(0, |m| 0x100 | m as u8 as u64);
        self.statusword as u64 | (self.request.map_or(0, |r| r as u64) << 16) | (progress << 24) | (mode << 32)
    }

    fn unpack(v: u64) -> DriveStatus {
        DriveStatus {
            statusword: v as u16,
            request: Request::from_u8((v >> 16) as u8),
            progress: Progress::ALL.get((v >> 24) as u8 as usize).copied().unwrap_or(Progress::Idle),
            mode_display: (v >> 32 & 0x100 != 0).then_some((v >> 32) as u8 as i8),
        }
    }
}

/// What a drive's sequencer shares with other threads: all atomics, all zero at first (an idle
/// status packs as 0).
#[derive(Default)]
pub struct SequencerShared {
    request: AtomicU8,
    status: AtomicU64,
    setpoint_writes: AtomicU64,
    /// Asks for the target to be held at the actual position again (after a mode change):
    /// 1 + the set-point writes counted when asked, so that only later writes release it; 0
    /// when not asked.
    rehold: AtomicU64,
    /// Controlword bit 8: the drive stops and stays enabled.
    halt: AtomicBool,
}

impl SequencerShared {
    /// Asks for `request`; the cycle thread takes it in its next cycle, replacing any other.
    pub fn request(&self, request: Request) {
        self.request.store(request as u8, Ordering::Release);
    }

    /// The status the cycle thread last published; a request not yet taken shows as in
    /// progress.
    pub fn status(&self) -> DriveStatus {
        let mut status = DriveStatus::unpack(self.status.load(Ordering::Acquire));
        if let Some(pending) = Request::from_u8(self.request.load(Ordering::Acquire)) {
            status.request = Some(pending);
            status.progress = Progress::InProgress;
        }
        status
    }

    /// Notes that a set-point was written for this drive: a held target is released.
    pub fn setpoint_written(&self) {
        self.setpoint_writes.fetch_add(1, Ordering::Release);
    }

    /// Holds the target at the actual position again from the next cycle until a set-point is
    /// written after it (after a mode change, so the new mode starts where the axis is).
    pub fn hold(&self) {
        self.rehold.store(self.setpoint_writes.load(Ordering::Acquire) + 1, Ordering::Release);
    }

    /// Sets or clears halt (controlword bit 8) while the drive is enabled.
    pub fn set_halt(&self, halt: bool) {
        self.halt.store(halt, Ordering::Release);
    }

    /// Whether halt is set.
    pub fn halted(&self) -> bool {
        self.halt.load(Ordering::Acquire)
    }
}

/// One cycle's inputs to the sequencing step.
#[derive(Clone, Copy, Debug)]
pub struct Observed {
    /// The statusword read this cycle.
    pub statusword: u16,
    /// The actual position read this cycle, where mapped.
    pub actual: Option<i32>,
    /// The cycle's wake-up time (ns, monotonic).
    pub now_ns: u64,
    /// How many set-points were written for the drive so far.
    pub setpoint_writes: u64,
    /// Whether the target is to be held at the actual position again from this cycle, with
    /// the set-point writes counted when that was asked.
    pub rehold: Option<u64>,
}

/// What the sequencing step writes into the drive's outputs; `None` leaves them as the user
/// set them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SequencerOutputs {
    /// The controlword.
    pub controlword: Option<u16>,
    /// The position target(s) to hold; while held, velocity and torque targets are 0.
    pub target: Option<i32>,
}

/// The sequencing state of one drive, kept by the cycle thread.
#[derive(Clone, Debug, Default)]
pub struct Sequencer {
    request: Option<Request>,
    progress: Progress,
    started_ns: u64,
    /// Whether the fault reset's bit 7 went out low for a cycle already.
    reset_low_sent: bool,
    /// The target held while not released by a set-point written after enable.
    held: Option<i32>,
    /// Set-point writes counted when the target was last held.
    writes_at_hold: u64,
}

impl Sequencer {
    /// The request in force and how far it is.
    pub fn progress(&self) -> (Option<Request>, Progress) {
        (self.request, self.progress)
    }

    /// One cycle: takes `new` (a request made since the last cycle), judges progress against
    /// `timeout_ns`, and gives the controlword and held target to write.
    pub fn step(&mut self, new: Option<Request>, seen: Observed, timeout_ns: u64) -> SequencerOutputs {
        let state = State::from_statusword(seen.statusword);
        if let Some(request) = new {
            self.request = Some(request);
            self.progress = Progress::InProgress;
            self.started_ns = seen.now_ns;
            self.reset_low_sent = false;
        }
        let Some(request) = self.request else {
            return SequencerOutputs { controlword: None, target: None };
        };
        let controlword = self.controlword(request, state, seen, timeout_ns);
        SequencerOutputs { controlword: Some(controlword), target: self.target(state, seen) }
    }

    fn controlword(&mut self, request: Request, state: Option<State>, seen: Observed, timeout_ns: u64) -> u16 {
        let reached = state.is_some_and(|s| request.reached(s));
        match self.progress {
            Progress::InProgress if reached => self.progress = Progress::Done,
            Progress::InProgress if seen.now_ns.saturating_sub(self.started_ns) >= timeout_ns => {
                self.progress = Progress::Stuck
            }
            Progress::Done if !reached => self.progress = Progress::Lost,
            _ => {}
        }
        let Some(state) = state else { return cw::DISABLE_VOLTAGE };
        match (request, self.progress) {
            // A drive that gave up a reached state, or a stuck request, is left powerless.
            (_, Progress::Lost) | (Request::Enable, Progress::Stuck) => cw::DISABLE_VOLTAGE,
            // The drive takes the rising edge in Fault only (transition 15): while it still brakes in Fault
            // reaction active, bit 7 stays low, so that the edge comes once it is in Fault.
            (Request::FaultReset, _) if state == State::FaultReactionActive => {
                self.reset_low_sent = true;
                cw::DISABLE_VOLTAGE
            }
            (Request::FaultReset, _) if state == State::Fault => {
                if std::mem::replace(&mut self.reset_low_sent, true) {
                    cw::FAULT_RESET
                } else {
                    cw::DISABLE_VOLTAGE
                }
            }
            (Request::FaultReset | Request::Disable, _) => cw::DISABLE_VOLTAGE,
            // Enable never resets a fault: nothing is retried into motion.
            (Request::Enable, _) if matches!(state, State::Fault | State::FaultReactionActive) => cw::DISABLE_VOLTAGE,
            (Request::Enable, _) => ds402::step_toward(state, State::OperationEnabled),
            (Request::QuickStop, _) if state.is_power_stage_on() => cw::QUICK_STOP_COMMAND,
            (Request::QuickStop, _) => cw::DISABLE_VOLTAGE,
        }
    }

    /// The target to hold: the actual position while not in Operation enabled, and the last
    /// one held after it until a set-point is written.
    fn target(&mut self, state: Option<State>, seen: Observed) -> Option<i32> {
        if let Some(writes) = seen.rehold {
            self.held = seen.actual;
            self.writes_at_hold = writes;
        }
        if state != Some(State::OperationEnabled) {
            self.held = seen.actual;
            self.writes_at_hold = seen.setpoint_writes;
        } else if seen.setpoint_writes != self.writes_at_hold {
            self.held = None;
        }
        self.held
    }

    /// The status to publish.
    pub fn status(&self, statusword: u16, mode_display: Option<i8>) -> u64 {
        DriveStatus { statusword, request: self.request, progress: self.progress, mode_display }.pack()
    }
}

/// A drive the cycle thread sequences: where its objects are and its sequencing state.
#[derive(Default)]
pub struct SequencedDrive {
    /// The drive's objects in the images (offsets within the whole images).
    pub offsets: Offsets,
    /// Its sequencing state.
    pub sequencer: Sequencer,
    /// What to write in this cycle.
    pub command: SequencerOutputs,
    /// Whether halt (bit 8) goes out.
    halt: bool,
    /// The set-point writes counted before this cycle's copy of the set-points began.
    writes_before_copy: u64,
    /// The set-point writes whose values are in the outputs: those counted before the last
    /// copy that succeeded. A write that lands during a copy is counted in the next cycle, so
    /// a held target is never released while the outputs still carry the old set-point.
    writes_in_outputs: u64,
}

impl SequencedDrive {
    /// A drive with its objects at `offsets`, not sequenced until a request comes.
    pub fn new(offsets: Offsets) -> Self {
        SequencedDrive { offsets, ..SequencedDrive::default() }
    }

    /// Counts the set-point writes before the cycle copies the set-points into the outputs.
    pub fn before_copy(&mut self, shared: &SequencerShared) {
        self.writes_before_copy = shared.setpoint_writes.load(Ordering::Acquire);
    }

    /// The copy succeeded: the writes counted before it are in the outputs.
    pub fn copied(&mut self) {
        self.writes_in_outputs = self.writes_before_copy;
    }

    /// Counts a set-point the cycle thread itself wrote into this cycle's outputs (a
    /// trajectory's) as a set-point write already in them, so a held target is released in
    /// this cycle.
    pub fn written_in_loop(&mut self, shared: &SequencerShared) {
        shared.setpoint_written();
        self.writes_in_outputs += 1;
    }

    /// The first half of a cycle: reads the statusword and actual position from `inputs`,
    /// takes a request from `shared`, decides what to write and publishes the status.
    pub fn observe(&mut self, shared: &SequencerShared, inputs: &[u8], now_ns: u64, timeout_ns: u64) {
        let o = self.offsets;
        let statusword = u16_at(inputs, o.statusword);
        let seen = Observed {
            statusword,
            actual: o.actual.map(|at| i32_at(inputs, at)),
            now_ns,
            setpoint_writes: self.writes_in_outputs,
            rehold: shared.rehold.swap(0, Ordering::AcqRel).checked_sub(1),
        };
        self.halt = shared.halted();
        let new = Request::from_u8(shared.request.swap(0, Ordering::AcqRel));
        self.command = self.sequencer.step(new, seen, timeout_ns);
        let mode_display = o.mode_display.map(|at| inputs[at] as i8);
        shared.status.store(self.sequencer.status(statusword, mode_display), Ordering::Release);
    }

    /// The second half: writes the controlword and held target into `outputs`, over what the
    /// user set.
    ///
    /// The sequencer owns the state bits (0–3, 7); the mode-specific bits the user set (4–6,
    /// 9, e.g. new set-point in profile position) go through once the target is released, and
    /// halt (bit 8) is added while asked for.
    pub fn apply(&self, outputs: &mut [u8]) {
        let o = self.offsets;
        if let Some(controlword) = self.command.controlword {
            let user = u16::from_le_bytes([outputs[o.controlword], outputs[o.controlword + 1]]);
            let mode_bits = if self.command.target.is_none() { user & !cw::COMMAND_MASK & !cw::HALT } else { 0 };
            let halt = if self.halt { cw::HALT } else { 0 };
            outputs[o.controlword..o.controlword + 2].copy_from_slice(&(controlword | mode_bits | halt).to_le_bytes());
        }
        if let Some(target) = self.command.target {
            for at in o.targets.into_iter().flatten() {
                outputs[at..at + 4].copy_from_slice(&target.to_le_bytes());
            }
            for at in o.velocity_target.into_iter() {
                outputs[at..at + 4].fill(0);
            }
            for at in o.torque_target.into_iter() {
                outputs[at..at + 2].fill(0);
            }
        }
    }

    /// Whether the drive is in Operation enabled by the sequencer's request (what a gap in the
    /// exchange would interrupt).
    pub fn enabled(&self) -> bool {
        self.sequencer.progress() == (Some(Request::Enable), Progress::Done)
    }

    /// Whether a request is in force, so that the sequencer reacts to a fault by disabling.
    pub fn sequenced(&self) -> bool {
        self.sequencer.progress().0.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TIMEOUT: u64 = 1_000_000_000;

    fn seen(state: State, now_ns: u64) -> Observed {
        Observed { statusword: state.statusword_bits(), actual: Some(1234), now_ns, setpoint_writes: 0, rehold: None }
    }

    #[test]
    fn finds_the_objects_or_names_what_is_missing() {
        let rx = crate::drive::pdo::fixed(0x1724).unwrap().entries;
        let tx = crate::drive::pdo::fixed(0x1B24).unwrap().entries;
        let o = Offsets::find(rx, tx).unwrap();
        assert_eq!((o.controlword, o.statusword, o.targets, o.actual), (4, 4, [Some(0), None], Some(0)));
        let tx = [PdoEntry::new(0x6064, 0, 32)];
        let e = Offsets::find(&rx[1..2], &tx).unwrap_err().to_string();
        assert!(e.contains("lacks statusword 0x6041"), "{e}");
        let e = Offsets::find(&rx[..1], &tx).unwrap_err().to_string();
        assert!(e.contains("controlword 0x6040 in the outputs (RxPDO) and statusword"), "{e}");
    }

    #[test]
    fn leaves_the_outputs_alone_until_asked() {
        let mut s = Sequencer::default();
        assert_eq!(
            s.step(None, seen(State::SwitchOnDisabled, 0), TIMEOUT),
            SequencerOutputs { controlword: None, target: None }
        );
    }

    #[test]
    fn enables_step_by_step_holding_the_actual_position() {
        let mut s = Sequencer::default();
        let c = s.step(Some(Request::Enable), seen(State::SwitchOnDisabled, 0), TIMEOUT);
        assert_eq!(c, SequencerOutputs { controlword: Some(cw::SHUTDOWN), target: Some(1234) });
        let c = s.step(None, seen(State::ReadyToSwitchOn, 1), TIMEOUT);
        assert_eq!(c.controlword, Some(cw::SWITCH_ON_COMMAND));
        let c = s.step(None, seen(State::SwitchedOn, 2), TIMEOUT);
        assert_eq!(c.controlword, Some(cw::ENABLE_OPERATION_COMMAND));
        // Enabled: the target stays where the axis was until a set-point is written, even if
        // the actual position changes meanwhile.
        let enabled = Observed { actual: Some(1300), ..seen(State::OperationEnabled, 3) };
        let c = s.step(None, enabled, TIMEOUT);
        assert_eq!(c, SequencerOutputs { controlword: Some(cw::ENABLE_OPERATION_COMMAND), target: Some(1234) });
        assert_eq!(s.progress(), (Some(Request::Enable), Progress::Done));
        let c = s.step(None, Observed { setpoint_writes: 1, ..enabled }, TIMEOUT);
        assert_eq!(c.target, None);
    }

    #[test]
    fn a_set_point_written_before_enable_is_not_taken() {
        let mut s = Sequencer::default();
        let written = Observed { setpoint_writes: 5, ..seen(State::SwitchedOn, 0) };
        s.step(Some(Request::Enable), written, TIMEOUT);
        let c = s.step(None, Observed { setpoint_writes: 5, ..seen(State::OperationEnabled, 1) }, TIMEOUT);
        assert_eq!(c.target, Some(1234));
    }

    #[test]
    fn fault_reset_is_a_rising_edge_of_bit_7() {
        let mut s = Sequencer::default();
        let c = s.step(Some(Request::FaultReset), seen(State::Fault, 0), TIMEOUT);
        assert_eq!(c.controlword, Some(cw::DISABLE_VOLTAGE));
        assert_eq!(s.step(None, seen(State::Fault, 1), TIMEOUT).controlword, Some(cw::FAULT_RESET));
        // Bit 7 stays high while the drive is still in Fault: one edge, not a train.
        assert_eq!(s.step(None, seen(State::Fault, 2), TIMEOUT).controlword, Some(cw::FAULT_RESET));
        assert_eq!(s.step(None, seen(State::SwitchOnDisabled, 3), TIMEOUT).controlword, Some(cw::DISABLE_VOLTAGE));
        assert_eq!(s.progress(), (Some(Request::FaultReset), Progress::Done));
        // A second reset request starts low again.
        let c = s.step(Some(Request::FaultReset), seen(State::Fault, 4), TIMEOUT);
        assert_eq!(c.controlword, Some(cw::DISABLE_VOLTAGE));
    }

    #[test]
    fn fault_reset_asked_while_the_drive_still_brakes_gives_its_edge_once_in_fault() {
        let mut s = Sequencer::default();
        for now in 0..3 {
            let request = (now == 0).then_some(Request::FaultReset);
            let c = s.step(request, seen(State::FaultReactionActive, now), TIMEOUT);
            assert_eq!(c.controlword, Some(cw::DISABLE_VOLTAGE), "no edge the drive would not take, at {now}");
        }
        assert_eq!(s.step(None, seen(State::Fault, 3), TIMEOUT).controlword, Some(cw::FAULT_RESET));
        s.step(None, seen(State::SwitchOnDisabled, 4), TIMEOUT);
        assert_eq!(s.progress(), (Some(Request::FaultReset), Progress::Done));
    }

    #[test]
    fn enable_does_not_reset_a_fault_and_gets_stuck_with_the_reason() {
        let mut s = Sequencer::default();
        let c = s.step(Some(Request::Enable), seen(State::Fault, 0), TIMEOUT);
        assert_eq!(c.controlword, Some(cw::DISABLE_VOLTAGE));
        s.step(None, seen(State::Fault, TIMEOUT), TIMEOUT);
        assert_eq!(s.progress(), (Some(Request::Enable), Progress::Stuck));
        let status = DriveStatus::unpack(s.status(State::Fault.statusword_bits(), None));
        let why = status.stuck_reason().unwrap();
        assert!(why.starts_with("enable stuck in Fault (statusword 0x0008): fault (bit 3)"), "{why}");
    }

    #[test]
    fn a_drive_that_drops_out_of_operation_enabled_is_not_re_enabled() {
        let mut s = Sequencer::default();
        s.step(Some(Request::Enable), seen(State::OperationEnabled, 0), TIMEOUT);
        let dropped = State::SwitchOnDisabled.statusword_bits() | sw::WARNING;
        let c = s.step(None, Observed { statusword: dropped, ..seen(State::SwitchOnDisabled, 1) }, TIMEOUT);
        assert_eq!(c.controlword, Some(cw::DISABLE_VOLTAGE));
        let why = DriveStatus::unpack(s.status(dropped, None)).stuck_reason().unwrap();
        assert!(why.contains("enable left the requested state in Switch on disabled"), "{why}");
        assert!(why.contains("hardware enable input is low"), "{why}");
    }

    #[test]
    fn quick_stop_brakes_and_holds() {
        let mut s = Sequencer::default();
        let c = s.step(Some(Request::QuickStop), seen(State::OperationEnabled, 0), TIMEOUT);
        assert_eq!(c.controlword, Some(cw::QUICK_STOP_COMMAND));
        let c = s.step(None, seen(State::QuickStopActive, 1), TIMEOUT);
        assert_eq!((c.controlword, s.progress().1), (Some(cw::QUICK_STOP_COMMAND), Progress::Done));
    }

    #[test]
    fn status_packs_and_unpacks() {
        let idle = DriveStatus { statusword: 0, request: None, progress: Progress::Idle, mode_display: None };
        assert_eq!(SequencerShared::default().status(), idle, "a drive's shared state starts all zero: idle");
        for progress in [Progress::Idle, Progress::InProgress, Progress::Done, Progress::Stuck, Progress::Lost] {
            for mode_display in [None, Some(-3), Some(8)] {
                let s = DriveStatus { statusword: 0xBEEF, request: Some(Request::QuickStop), progress, mode_display };
                assert_eq!(DriveStatus::unpack(s.pack()), s);
            }
        }
    }
}
