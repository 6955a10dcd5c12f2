//! `akd_ros._native.Cycle`: the real-time cycle thread for Python.
//!
//! The Cycle takes the Master for as long as it runs and gives it back on `stop()`. The thread
//! never needs the GIL; set-points and snapshots go through lock-free buffers, so a Python
//! thread busy with anything never delays a cycle. Waiting on the thread releases the GIL.
//! Drives are enabled, disabled, quick-stopped and reset by the DS402 sequencer inside the
//! thread (`enable`, `disable`, `quick_stop`, `reset_fault`, `drive_status`, `wait_state`), and
//! so are the set-point handshake (`start_setpoint`, `wait_setpoint`, `setpoint_status`) and the
//! command time-out (`set_command_timeout`, `command_timeout_status`).

use std::collections::HashMap;
use std::sync::Arc;
use std::time::Duration;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use super::master::PyMaster;
use super::{IntoPyResult, Merged};
use crate::cycle::events::{CommandTimeoutAction, Edge, Event, FaultSource};
use crate::cycle::line_health::DEFAULT_INTERVAL as LINE_HEALTH_INTERVAL;
use crate::cycle::rt::{self, RealTime};
use crate::cycle::samples::Sample;
use crate::cycle::sequencer::{DriveStatus, Progress, Request};
use crate::cycle::stats::Summary;
use crate::cycle::{handshake, latch};
use crate::cycle::{Config, CycleThread};
use crate::drive::akd_fault;
use crate::drive::ds402::{CommandKind, State};
use crate::drive::io::DriveIo;
use crate::drive::objects::DriveInputs;
use crate::drive::trajectory::Scale;
use crate::error::{CommandRefused, Error, SettingError, UnknownName};

/// Exchanges a Master's process image every period on a thread of its own.
// Frozen: stop() may come while another thread waits inside a method (an SDO, a state).
#[pyclass(name = "Cycle", module = "akd_ros._native", frozen)]
pub struct PyCycle {
    master: Py<PyMaster>,
    // Shared with the threads that publish and record from it (`Feed`, `BagWriter`).
    cycle: Arc<CycleThread>,
}

// The columns `Cycle.samples` gives, one list per field of Sample, and their names in that
// order; filled by hand: pyo3's derive converts one record, and a struct of columns would list
// every field a second time.
macro_rules! sample_columns {
    ($($field:ident),*) => {
        /// The names of `Cycle.samples`' columns.
        const SAMPLE_COLUMNS: &[&str] = &[$(stringify!($field)),*];

        /// `samples` as columns.
        fn columns<'py>(py: Python<'py>, samples: &[Sample]) -> PyResult<Bound<'py, PyDict>> {
            let d = PyDict::new(py);
            $( d.set_item(stringify!($field), samples.iter().map(|s| s.$field).collect::<Vec<_>>())?; )*
            Ok(d)
        }
    };
}

sample_columns!(
    cycle,
    time_ns,
    slave,
    period_ns,
    exchange_ns,
    wkc,
    fresh,
    lost,
    statusword,
    mode,
    position,
    velocity,
    torque,
    following_error,
    target_position,
    target_velocity,
    target_torque
);

/// What `snapshot` gives; a slave without process data has None.
#[derive(IntoPyObject)]
struct SnapshotView<'a> {
    cycle: u64,
    time_ns: u64,
    wkc: u16,
    fresh: bool,
    inputs: Vec<Option<std::borrow::Cow<'a, [u8]>>>,
    outputs: Vec<Option<std::borrow::Cow<'a, [u8]>>>,
}

/// What `stats` gives.
#[derive(IntoPyObject)]
struct StatsView {
    cycles: u64,
    overruns: u64,
    f125_stalls: u64,
    lost_frames: u64,
    wkc_errors: u64,
    watch_frames: u64,
    acyclic_lost_frames: u64,
    acyclic_wkc_errors: u64,
    late_returns: u64,
    other_errors: u64,
    setpoints_busy: u64,
    relayed_frames: u64,
    relayed_lost: u64,
    period: Summary,
    wake_latency: Summary,
    exchange: Summary,
}

/// What `histograms` gives: (upper edge in ns, count) of each non-empty bucket.
#[derive(IntoPyObject)]
struct Histograms {
    period: Vec<(u64, u64)>,
    wake_latency: Vec<(u64, u64)>,
    exchange: Vec<(u64, u64)>,
}

/// What `wait_setpoint` and `setpoint_status` give.
#[derive(IntoPyObject)]
struct SetpointView {
    request: u32,
    bits: u16,
    progress: &'static str,
    reason: Option<String>,
    statusword: u16,
}

impl From<handshake::HandshakeStatus> for SetpointView {
    fn from(s: handshake::HandshakeStatus) -> Self {
        let progress = match s.progress {
            handshake::Progress::Idle => "idle",
            handshake::Progress::InProgress => "in_progress",
            handshake::Progress::Done => "done",
            handshake::Progress::Stuck(_) => "stuck",
        };
        SetpointView { request: s.request, bits: s.bits, progress, reason: s.stuck_reason(), statusword: s.statusword }
    }
}

/// What `command_timeout_status` gives.
#[derive(IntoPyObject)]
struct CommandTimeoutView {
    timeout: f64,
    policy: Option<&'static str>,
    armed: bool,
    halted: bool,
    timeouts: u64,
}

/// What `mapping` gives: (index, subindex, bit length, byte offset) in wire order.
#[derive(IntoPyObject)]
struct MappingView {
    outputs: Vec<(u16, u8, u8, usize)>,
    inputs: Vec<(u16, u8, u8, usize)>,
}

/// One event as `events` gives it, "kind" first.
#[derive(IntoPyObject)]
enum EventView {
    Latch {
        kind: &'static str,
        cycle: u64,
        time_ns: u64,
        slave: u16,
        channel: u8,
        edge: &'static str,
        position: i32,
    },
    /// A fault: its kind and slave, to file it by, and the `FaultEvent`.
    Fault {
        kind: &'static str,
        slave: u16,
        fault: FaultEvent,
    },
    CommandTimeout {
        kind: &'static str,
        cycle: u64,
        time_ns: u64,
        slave: u16,
        command: &'static str,
        value: i32,
        timeout: f64,
        statusword: u16,
        ds402_state: Option<State>,
        action: &'static str,
        text: &'static str,
    },
    /// A trajectory's start or end: its kind, cycle, time and id, then its state's keys.
    Trajectory(Merged<TrajectoryEventView, super::trajectory::StateView>),
    Inputs {
        kind: &'static str,
        cycle: u64,
        time_ns: u64,
        slave: u16,
        digital_inputs: u32,
        statusword: u16,
    },
    DeviceInputs {
        kind: &'static str,
        cycle: u64,
        time_ns: u64,
        slave: u16,
        levels: u64,
    },
}

/// One fault and what the cycle thread did about it (`akd_ros.FaultEvent`, from `Axis.fault_events`).
#[pyclass(module = "akd_ros._native", frozen, get_all)]
pub struct FaultEvent {
    /// The cycle that saw it (from 1).
    cycle: u64,
    /// That cycle's wake-up time on the monotonic clock (ns).
    time_ns: u64,
    /// The slave's position on the line.
    slave: u16,
    /// What it is about: "drive_fault", "emergency", "lost_frames", "working_counter",
    /// "al_state", "unreachable" (the drive stopped answering: power, cable or line; it is
    /// being brought back) or "recovered" (back in Op, its power stage off).
    source: FaultSource,
    /// CiA error code (0x603F or the emergency's); cycles in a row for lost frames, working
    /// counter errors and an unreachable drive; how long it was gone (ms) for a recovered one.
    code: u16,
    /// The AKD's text for the code where known, e.g. "F439 Following error".
    text: Option<String>,
    /// The statusword of that cycle.
    statusword: u16,
    /// The CiA 402 state it shows (a `Ds402State`), None for none.
    ds402_state: Option<State>,
    /// AL status 0x0130 of that cycle (0 when not read).
    al_status: u16,
    /// The AL state it shows ("Op", "SafeOp", ...), None when not read.
    al_state: Option<&'static str>,
    /// AL status code 0x0134 of that cycle.
    al_status_code: u16,
    /// Its name.
    al_status_code_name: &'static str,
    /// What the cycle thread did about it.
    action: &'static str,
}

#[pymethods]
impl FaultEvent {
    /// One line for a log.
    fn describe(&self) -> String {
        let code = self.code;
        let what = match self.source {
            FaultSource::LostFrames | FaultSource::WorkingCounter => format!("{code} cycles in a row"),
            FaultSource::Unreachable => {
                format!("no answer for {code} cycles (power, cable or line); being brought back")
            }
            FaultSource::Recovered => format!("back after {code} ms"),
            FaultSource::AlState => format!(
                "slave now in {}, AL status code 0x{:04X} ({})",
                self.al_state.unwrap_or("None"),
                self.al_status_code,
                self.al_status_code_name
            ),
            _ => self.text.clone().unwrap_or_else(|| format!("code 0x{code:04X}")),
        };
        format!("{}: {what}; {}", self.source.name(), self.action)
    }

    fn __repr__(&self) -> String {
        format!("FaultEvent(cycle={}, slave={}, {})", self.cycle, self.slave, self.describe())
    }
}

/// The head of a trajectory event, before its state's keys.
#[derive(IntoPyObject)]
struct TrajectoryEventView {
    kind: &'static str,
    cycle: u64,
    time_ns: u64,
    id: u32,
}

impl EventView {
    /// `event` as Python sees it, a trajectory's refusal worded by `cycle`.
    fn of(event: Event, cycle: &CycleThread) -> Self {
        match event {
            Event::Latch { cycle, time_ns, slave, channel, edge, position } => {
                EventView::Latch { kind: "latch", cycle, time_ns, slave, channel, edge: edge.name(), position }
            }
            Event::Fault { cycle, time_ns, slave, source, code, statusword, al_status, al_status_code, action } => {
                let text = matches!(source, FaultSource::DriveFault | FaultSource::Emergency)
                    .then(|| akd_fault::by_code(code).map(|f| format!("F{} {}", f.number, f.text)))
                    .flatten();
                let fault = FaultEvent {
                    cycle,
                    time_ns,
                    slave,
                    source,
                    code,
                    text,
                    statusword,
                    ds402_state: State::from_statusword(statusword),
                    al_status,
                    al_state: (al_status != 0).then(|| crate::ethercat::al::state_name(al_status)),
                    al_status_code,
                    al_status_code_name: crate::ethercat::al::AlStatusCode(al_status_code).name(),
                    action: action.describe(),
                };
                EventView::Fault { kind: "fault", slave, fault }
            }
            Event::CommandTimeout { cycle, time_ns, slave, target, value, timeout_us, statusword, action } => {
                EventView::CommandTimeout {
                    kind: "command_timeout",
                    cycle,
                    time_ns,
                    slave,
                    command: target.name(),
                    value,
                    timeout: timeout_us as f64 * 1e-6,
                    statusword,
                    ds402_state: State::from_statusword(statusword),
                    action: action.name(),
                    text: action.describe(),
                }
            }
            Event::Trajectory { cycle: number, time_ns, id, state } => EventView::Trajectory(Merged(
                TrajectoryEventView { kind: "trajectory", cycle: number, time_ns, id },
                super::trajectory::state_view(state, cycle),
            )),
            Event::Inputs { cycle, time_ns, slave, digital_inputs, statusword } => {
                EventView::Inputs { kind: "inputs", cycle, time_ns, slave, digital_inputs, statusword }
            }
            Event::DeviceInputs { cycle, time_ns, slave, levels } => {
                EventView::DeviceInputs { kind: "device_inputs", cycle, time_ns, slave, levels }
            }
        }
    }
}

/// A /diagnostics status of the line: level, what, message, hardware_id, values.
type LineStatus = crate::ros::line_diagnostics::Status;

/// How often `wait_state` looks at the drive's status.
const WAIT_POLL: Duration = Duration::from_millis(1);

impl PyCycle {
    /// The cycle thread, for the threads that publish and record from it.
    pub(super) fn thread(&self) -> Arc<CycleThread> {
        self.cycle.clone()
    }

    fn request(&self, position: u16, request: Request) -> PyResult<()> {
        self.cycle.request(position, request).py()
    }

    fn halt(&self, py: Python<'_>) -> PyResult<()> {
        if self.cycle.stopped() {
            return Ok(());
        }
        let cycle = &self.cycle;
        let master = py.allow_threads(|| cycle.stop()).py()?;
        self.master.borrow(py).put_back(master);
        Ok(())
    }
}

#[pymethods]
impl PyCycle {
    /// Starts cycling `master` (its slaves in Op) every `period` seconds (0.00025 to 0.01).
    /// `priority` asks for SCHED_FIFO (1..=99), `cpu` binds the thread to one CPU, and
    /// `lock_memory` locks the process's memory, and `cpu_latency_us` (0..=1000000) holds every
    /// CPU's wake-up latency from idle while the cycle runs (PM QoS, /dev/cpu_dma_latency, as
    /// cyclictest does); what the system does not permit is listed in `warnings` and the cycle
    /// runs without it. `pipelined` sends each cycle's frame without waiting for it and takes
    /// its return at the next wake-up: no wait for the round trip (less CPU, a lost frame costs
    /// no time), what a cycle read published a period later. The master is unusable until
    /// `stop()`.
    /// `line_health`: how often (s) every slave's links and error counters are read beside the
    /// cycle (`line_health()`), 0 or None for never.
    #[new]
    #[pyo3(signature = (master, period, *, realtime = None, line_health = LINE_HEALTH_INTERVAL.as_secs_f64()))]
    fn new(
        py: Python<'_>,
        master: Py<PyMaster>,
        period: f64,
        realtime: Option<RealTime>,
        line_health: Option<f64>,
    ) -> PyResult<Self> {
        let period = Duration::try_from_secs_f64(period)
            .map_err(|_| super::to_py_err(SettingError::CyclePeriodSeconds { seconds: period }.into()))?;
        let fbus_param02 = super::master::lock(&master.borrow(py).fbus_param02).clone();
        let line_health = line_health.map(|s| {
            super::seconds_allowing(s, "line health interval", "a finite number of seconds >= 0, 0 for never")
        });
        let config = Config {
            period,
            realtime: realtime.unwrap_or_default(),
            fbus_param02,
            line_health: line_health.transpose()?,
        };
        let taken = master.borrow(py).take()?;
        match py.allow_threads(|| CycleThread::start(taken, config)) {
            Ok(cycle) => Ok(PyCycle { master, cycle: Arc::new(cycle) }),
            Err(refused) => {
                let (error, taken) = *refused;
                master.borrow(py).put_back(taken);
                Err(super::to_py_err(error))
            }
        }
    }

    /// Sets the outputs of the slave at `position` (their exact length) from the next cycle on.
    fn set_outputs(&self, position: u16, data: Vec<u8>) -> PyResult<()> {
        self.cycle.set_outputs(position, &data).py()
    }

    /// The outputs of the slave at `position` as last set; what went out is in `snapshot()`.
    fn outputs<'py>(&self, py: Python<'py>, position: u16) -> PyResult<Bound<'py, PyBytes>> {
        Ok(PyBytes::new(py, &self.cycle.outputs(position).py()?))
    }

    /// The last cycle's snapshot: cycle (count, from 1), time_ns (monotonic wake-up time),
    /// wkc, fresh (whether this cycle's exchange succeeded), inputs and outputs (as sent: the
    /// set-points with the sequencer's controlword and held target), each one bytes per slave
    /// (None for a slave without process data), all from the same cycle.
    fn snapshot<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let cycle = &self.cycle;
        let s = cycle.snapshot();
        let positions = 0..cycle.slave_count();
        SnapshotView {
            cycle: s.cycle,
            time_ns: s.time_ns,
            wkc: s.wkc,
            fresh: s.fresh,
            inputs: positions.clone().map(|p| cycle.inputs_of(&s, p).ok()).collect(),
            outputs: positions.map(|p| cycle.outputs_of(&s, p).ok()).collect(),
        }
        .into_pyobject(py)
    }

    /// The statistics: cycles, overruns, f125_stalls (frames that went out so late after the one
    /// before, a drive enabled, that a real AKD would raise F125), lost_frames and wkc_errors (the cyclic frame's),
    /// watch_frames (cycles that read each slave in a second frame, a change having been seen),
    /// acyclic_lost_frames and acyclic_wkc_errors (the frames beside it: mailbox, and a
    /// recovery's), late_returns (frames of either counted lost that came back after their
    /// time-out: a slow line or slave, not a broken one), other_errors, setpoints_busy, relayed_frames and relayed_lost (frames a
    /// slave's recovery sent beside the cycle, and those lost, which acyclic_lost_frames counts too),
    /// and period, wake_latency (how late after its deadline the thread woke)
    /// and exchange, each {count, min_ns, mean_ns, p99_ns, max_ns}.
    fn stats(&self) -> StatsView {
        use std::sync::atomic::Ordering::Relaxed;
        let s = self.cycle.stats();
        let (relayed_frames, relayed_lost) = self.cycle.relayed_frames();
        StatsView {
            relayed_frames,
            relayed_lost,
            cycles: s.cycles.load(Relaxed),
            overruns: s.overruns.load(Relaxed),
            f125_stalls: s.f125_stalls.load(Relaxed),
            lost_frames: s.lost_frames.load(Relaxed),
            wkc_errors: s.wkc_errors.load(Relaxed),
            watch_frames: s.watch_frames.load(Relaxed),
            acyclic_lost_frames: s.acyclic_lost_frames.load(Relaxed),
            acyclic_wkc_errors: s.acyclic_wkc_errors.load(Relaxed),
            late_returns: s.late_returns.load(Relaxed),
            other_errors: s.other_errors.load(Relaxed),
            setpoints_busy: s.setpoints_busy.load(Relaxed),
            period: s.period.summary(),
            wake_latency: s.wake_latency.summary(),
            exchange: s.exchange.summary(),
        }
    }

    /// The histograms "period", "wake_latency" and "exchange", each a list of (upper edge in ns, count) of its
    /// non-empty 1 µs buckets.
    fn histograms(&self) -> Histograms {
        let s = self.cycle.stats();
        Histograms {
            period: s.period.buckets(),
            wake_latency: s.wake_latency.buckets(),
            exchange: s.exchange.buckets(),
        }
    }

    /// Asks drive `position` for Operation enabled, stepping it through the CiA 402 states in
    /// the cycle thread. While it is not enabled the position target is its actual position,
    /// and after that it stays there until a set-point is written: nothing moves until
    /// commanded. A drive in Fault is not reset by it (`reset_fault()` first). Returns at once;
    /// `wait_state` waits.
    fn enable(&self, position: u16) -> PyResult<()> {
        self.request(position, Request::Enable)
    }

    /// Asks drive `position` for Switch on disabled (power stage off).
    fn disable(&self, position: u16) -> PyResult<()> {
        self.request(position, Request::Disable)
    }

    /// Asks drive `position` for a quick stop: it brakes and holds in Quick stop active.
    fn quick_stop(&self, position: u16) -> PyResult<()> {
        self.request(position, Request::QuickStop)
    }

    /// Asks drive `position` for a fault reset where it shows a fault (Fault, Fault reaction
    /// active): bit 7 of the controlword low for a cycle, then high (the drive reacts to the
    /// rising edge), to Switch on disabled. Returns whether it asked: a drive without a fault is
    /// left as it is, its power stage untouched.
    fn reset_fault(&self, position: u16) -> PyResult<bool> {
        self.cycle.reset_fault(position).py()
    }

    /// How long a request may take before it is reported stuck, in seconds (1 by default).
    #[getter]
    fn get_request_timeout(&self) -> f64 {
        self.cycle.request_timeout().as_secs_f64()
    }

    #[setter]
    fn set_request_timeout(&self, seconds: f64) -> PyResult<()> {
        let timeout = super::seconds(seconds, "request timeout")?;
        self.cycle.set_request_timeout(timeout);
        Ok(())
    }

    /// Drive `position` as the cycle thread last saw it (a `DriveStatus`).
    fn drive_status(&self, position: u16) -> PyResult<DriveStatus> {
        self.cycle.drive_status(position).py()
    }

    /// Waits, without holding the GIL, until drive `position` shows `wanted` (a `Ds402State`);
    /// raises TimeoutError after `timeout` seconds, and at once when the request under way is
    /// stuck, saying in which state it is and why.
    #[pyo3(signature = (position, wanted, timeout = 5.0))]
    fn wait_state(&self, py: Python<'_>, position: u16, wanted: State, timeout: f64) -> PyResult<()> {
        let timeout = super::seconds(timeout, "timeout")?;
        let cycle = &self.cycle;
        let outcome = py.allow_threads(|| -> crate::error::Result<Option<String>> {
            let deadline = std::time::Instant::now() + timeout;
            loop {
                let status = cycle.drive_status(position)?;
                if status.state() == Some(wanted) {
                    return Ok(None);
                }
                let stuck = status.progress == Progress::Stuck;
                if stuck || std::time::Instant::now() >= deadline || !cycle.running() {
                    let seen = status.state().map_or("no valid state", |s| s.name());
                    let why = match status.stuck_reason() {
                        _ if !cycle.running() => ": cut short, the cycle stopped".to_owned(),
                        Some(r) => format!(": {r}"),
                        None => String::new(),
                    };
                    return Ok(Some(format!(
                        "drive {position} to reach {} (it is in {seen}, statusword 0x{:04X}){why}",
                        wanted.name(),
                        status.statusword
                    )));
                }
                std::thread::sleep(WAIT_POLL);
            }
        });
        match outcome.py()? {
            None => Ok(()),
            Some(what) => Err(super::to_py_err(Error::Timeout { what: what.into() })),
        }
    }

    /// Latch, fault, command time-out and trajectory events since the last call, oldest first,
    /// each a dict. Every event has "kind" ("latch", "fault", "command_timeout", "inputs" or
    /// "trajectory"), and all but trajectory events "slave". A fault's only other key is
    /// "fault", its `FaultEvent`; the others have "cycle" and "time_ns" (the cycle's monotonic
    /// wake-up time). A latch adds "channel" (1, 2), "edge" ("rising", "falling") and "position"
    /// (counts). A command
    /// time-out adds "command" ("velocity", "torque"), "value" (its last value in drive units:
    /// counts/s, 0.1 % of peak torque), "timeout" (s), "statusword", "ds402_state", "action"
    /// ("hold" or "quick_stop") and "text" (what was done, for the log). A trajectory event
    /// (one when it starts, one when it ends) has "id" and what `trajectory_status` gives of
    /// its state: "state" ("running", "done", "replaced", "aborted"), "replaced_by", "slave",
    /// "statusword", "ds402_state". An inputs event (a change of the drive's digital inputs
    /// 0x60FD, or of its hardware enable as the statusword shows it, in that cycle's inputs) adds
    /// "digital_inputs" and "statusword" (`DriveIo.with_inputs` reads them).
    fn events(&self) -> Vec<EventView> {
        self.cycle.events().into_iter().map(|event| EventView::of(event, &self.cycle)).collect()
    }

    /// One record per cycle and sequenced drive since the last call, oldest first, as columns:
    /// a dict of equal-length lists "cycle", "time_ns", "slave", "period_ns", "exchange_ns",
    /// "wkc", "fresh", "lost" (stale because a frame did not come back or its return could not be
    /// read, not for a wrong working counter), "statusword", "mode", "position", "velocity", "torque",
    /// "following_error", "target_position", "target_velocity", "target_torque" (drive units:
    /// counts, counts/s, 0.1 % of peak torque; 0 for objects the mapping lacks). The ring holds
    /// 8192 records; take them at least that often (`samples_dropped` counts the rest).
    /// With `by_slave`, a dict of such columns for each slave that has records, by its position.
    #[pyo3(signature = (by_slave = false))]
    fn samples<'py>(&self, py: Python<'py>, by_slave: bool) -> PyResult<Bound<'py, PyDict>> {
        let samples = self.cycle.samples();
        if !by_slave {
            return columns(py, &samples);
        }
        let mut slaves: Vec<u16> = samples.iter().map(|s| s.slave).collect();
        slaves.sort_unstable();
        slaves.dedup();
        let d = PyDict::new(py);
        for slave in slaves {
            let of_slave: Vec<Sample> = samples.iter().filter(|s| s.slave == slave).copied().collect();
            d.set_item(slave, columns(py, &of_slave)?)?;
        }
        Ok(d)
    }

    /// Per-cycle records lost because they were not taken in time.
    #[getter]
    fn samples_dropped(&self) -> u64 {
        self.cycle.samples_dropped()
    }

    /// Whether events wait to be taken (`events()`).
    #[getter]
    fn events_pending(&self) -> bool {
        self.cycle.events_pending()
    }

    /// Events lost because they were not taken before 256 piled up.
    #[getter]
    fn events_dropped(&self) -> u64 {
        self.cycle.events_dropped()
    }

    /// Arms (or with `arm=False` disarms) latch `channel` (1 or 2) on `edge` ("rising" or
    /// "falling") of drive `position`; every capture then becomes one event.
    #[pyo3(signature = (position, channel, edge, arm = true))]
    fn arm_latch(&self, position: u16, channel: u8, edge: &str, arm: bool) -> PyResult<()> {
        if !(1..=2).contains(&channel) {
            return Err(super::to_py_err(SettingError::LatchChannel { channel }.into()));
        }
        let edge = match edge {
            "rising" => Edge::Rising,
            "falling" => Edge::Falling,
            other => return Err(super::to_py_err(UnknownName::LatchEdge { name: other.to_owned() }.into())),
        };
        self.cycle.arm_latch(position, latch::edge_bit(channel, edge), arm).py()
    }

    /// Reads `index:subindex` of slave `position` beside the running cycle (the GIL released
    /// while it waits); raises SdoAbortError, TimeoutError or MailboxError.
    fn sdo_read<'py>(&self, py: Python<'py>, position: u16, index: u16, subindex: u8) -> PyResult<Bound<'py, PyBytes>> {
        let cycle = &self.cycle;
        let value = py.allow_threads(|| cycle.sdo_read(position, index, subindex)).py()?;
        Ok(PyBytes::new(py, &value))
    }

    /// The drive's error code (0x603F) of slave `position`, the CiA 402 code of its last fault,
    /// read beside the running cycle; raises as `sdo_read` does.
    fn drive_error_code(&self, py: Python<'_>, position: u16) -> PyResult<u16> {
        let cycle = &self.cycle;
        py.allow_threads(|| cycle.drive_error_code(position)).py()
    }

    /// Writes `data` to `index:subindex` of slave `position` beside the running cycle.
    fn sdo_write(&self, py: Python<'_>, position: u16, index: u16, subindex: u8, data: Vec<u8>) -> PyResult<()> {
        let cycle = &self.cycle;
        py.allow_threads(|| cycle.sdo_write(position, index, subindex, &data)).py()
    }

    /// Queues one Ethernet frame for drive `position`'s IP stack, carried through EoE beside
    /// the process data; `False` when the queue was full and the frame was dropped.
    fn eoe_send(&self, position: u16, frame: Vec<u8>) -> PyResult<bool> {
        self.cycle.eoe_send(position, &frame).py()
    }

    /// The next Ethernet frame a drive's IP stack sent, waiting up to `timeout` s (the GIL
    /// released): `(position, frame)`, or `None`.
    fn eoe_receive<'py>(&self, py: Python<'py>, timeout: f64) -> PyResult<Option<(u16, Bound<'py, PyBytes>)>> {
        let timeout = super::seconds(timeout, "timeout")?;
        let cycle = &self.cycle;
        let frame = py.allow_threads(|| cycle.eoe_receive(timeout));
        Ok(frame.map(|(position, f)| (position, PyBytes::new(py, &f))))
    }

    /// Ethernet frames dropped because a queue was full: `(to the drives, from the drives)`.
    fn eoe_dropped(&self) -> (u64, u64) {
        self.cycle.eoe_dropped()
    }

    /// Sets the mode of operation (0x6060) of drive `position` and holds its target at the
    /// actual position until the next set-point.
    fn set_mode(&self, py: Python<'_>, position: u16, mode: i8) -> PyResult<()> {
        let cycle = &self.cycle;
        py.allow_threads(|| cycle.set_mode(position, mode)).py()
    }

    /// Sets or clears halt (controlword bit 8) of drive `position`.
    fn set_halt(&self, position: u16, halt: bool) -> PyResult<()> {
        self.cycle.set_halt(position, halt).py()
    }

    /// Starts the set-point handshake of drive `position` in the cycle thread: from statusword
    /// bit 12 clear, controlword `bits` (0x0030: a profile-position set-point changed at once;
    /// 0x0010: start homing; bit 6 0x0040 relative) go out with the sequencer's own until bit 12
    /// is set (set-point acknowledged, homing attained), then low again. Stuck when the drive is
    /// not in Operation enabled, when bit 12 does not clear within `request_timeout`, when it is
    /// not set within `timeout` seconds of the raise (`request_timeout` when None; homing may
    /// take long), or on a homing error (bit 13). Replaces one under way; returns its number at
    /// once (`wait_setpoint` waits).
    #[pyo3(signature = (position, bits, timeout = None))]
    fn start_setpoint(&self, position: u16, bits: u16, timeout: Option<f64>) -> PyResult<u32> {
        let timeout = timeout.map(|t| super::seconds(t, "set-point handshake timeout")).transpose()?;
        self.cycle.start_setpoint(position, bits, timeout).py()
    }

    /// Waits, without holding the GIL, until the set-point handshake last started on drive
    /// `position` is done. Raises TimeoutError saying why at once when it is stuck, and when
    /// `timeout` seconds pass first (None: until the handshake's own time-out ends it).
    #[pyo3(signature = (position, timeout = None))]
    fn wait_setpoint(&self, py: Python<'_>, position: u16, timeout: Option<f64>) -> PyResult<SetpointView> {
        let timeout = timeout.map(|t| super::seconds(t, "timeout")).transpose()?;
        let cycle = &self.cycle;
        Ok(py.allow_threads(|| cycle.wait_setpoint(position, timeout)).py()?.into())
    }

    /// The set-point handshake last started on drive `position`: "request" (its number, 0
    /// before any), "bits", "progress" ("idle", "in_progress", "done", "stuck"), "reason" (why
    /// stuck, else None) and "statusword" (the last seen while under way, at its end after).
    fn setpoint_status(&self, position: u16) -> PyResult<SetpointView> {
        Ok(self.cycle.setpoint_status(position).py()?.into())
    }

    /// Starts homing drive `position` in the cycle thread with the method and speeds set in the
    /// drive: into homing mode (6), start (bit 4), homing attained (bit 12) with the motion
    /// stopped, then back to the mode the set-points carry with the target at the actual
    /// position; halted and ended "timed_out" when not attained within `timeout` s. The drive
    /// must be in Operation enabled with 0x6060 and 0x6061 mapped. Returns its number at once.
    fn start_homing(&self, position: u16, timeout: f64) -> PyResult<u32> {
        let timeout = super::seconds(timeout, "homing timeout")?;
        self.cycle.start_homing(position, timeout).py()
    }

    /// Cancels the homing under way on drive `position`: halted, then back to its mode.
    fn cancel_homing(&self, position: u16) -> PyResult<()> {
        self.cycle.cancel_homing(position).py()
    }

    /// The homing of drive `position`: "request" (its number, 0 before any), "phase" ("idle",
    /// "homing", "ending", "done"), "outcome" ("attained", "homing_error", "timed_out",
    /// "canceled", "not_enabled"; None while under way), "reason" (why it failed, else None),
    /// "statusword" and "homing_state" (from bits 13, 12, 10 in homing mode: "in_progress",
    /// "interrupted", "attained", "error"), and "homed" (attained since the drive was last lost).
    fn homing_status(&self, position: u16) -> PyResult<super::homing::HomingView> {
        Ok(self.cycle.homing_status(position).py()?.into())
    }

    /// Sets the command time-out of drive `position`: when a non-zero velocity (profile
    /// velocity) or torque (profile torque) written by `set_object` or `set_outputs` is not
    /// written again for `timeout` seconds while the drive is in Operation enabled, the cycle
    /// thread acts by `policy` — "hold": halt (controlword bit 8, its own; a halt set by
    /// `set_halt` stays) until the next velocity or torque write; "quick_stop": quick stop,
    /// until enabled again — and reports a "command_timeout" event. 0 turns it off. Position
    /// commands and zero never time out. A request (enable, ...) or mode change forgets the
    /// stream and lifts the hold.
    #[pyo3(signature = (position, timeout, policy = "hold"))]
    fn set_command_timeout(&self, position: u16, timeout: f64, policy: &str) -> PyResult<()> {
        let action =
            CommandTimeoutAction::ALL.iter().copied().find(|a| a.name() == policy).ok_or_else(|| {
                super::to_py_err(UnknownName::CommandTimeoutPolicy { name: policy.to_owned() }.into())
            })?;
        let timeout =
            super::seconds_allowing(timeout, "command timeout", "a finite number of seconds >= 0, 0 turning it off")?;
        self.cycle.set_command_timeout(position, Some(timeout), action).py()
    }

    /// The command time-out of drive `position`: "timeout" (s, 0 when off), "policy" ("hold",
    /// "quick_stop", None when off), "armed" (a non-zero stream is watched), "halted" (its
    /// hold is on) and "timeouts" (how many so far).
    fn command_timeout_status(&self, position: u16) -> PyResult<CommandTimeoutView> {
        let s = self.cycle.command_timeout_status(position).py()?;
        Ok(CommandTimeoutView {
            timeout: s.config.map_or(0.0, |(t, _)| t.as_secs_f64()),
            policy: s.config.map(|(_, a)| a.name()),
            armed: s.armed,
            halted: s.halted,
            timeouts: s.timeouts,
        })
    }

    /// Commands joints in SI units in one call, each of `commands` a (drive position, kind
    /// "position", "velocity" or "torque", value, the joint's `Units`): for each the crate picks
    /// the target object of the drive's mode that its mapping carries, converts and encodes
    /// the value, and writes it into the next cycle's outputs (by SDO where a profile-position
    /// target is unmapped); all are checked before any is sent. A mode started by a handshake
    /// starts it in the cycle thread without waiting: each command's handshake number, None
    /// for a mode without one (`setpoint_status` and `wait_setpoint` follow it). ConfigError
    /// says why a command was refused, nothing of it sent; its `command` is the refused one's
    /// index in `commands`.
    fn command(
        &self,
        py: Python<'_>,
        commands: Vec<(u16, String, f64, crate::drive::scaling::JointScaling)>,
    ) -> PyResult<Vec<Option<u32>>> {
        let commands = commands
            .into_iter()
            .map(|(position, kind, value, units)| {
                let kinds = [CommandKind::Position, CommandKind::Velocity, CommandKind::Torque];
                let kind = kinds.into_iter().find(|k| k.name() == kind).ok_or_else(|| {
                    PyValueError::new_err(format!("kind must be 'position', 'velocity' or 'torque', got {kind:?}"))
                })?;
                Ok((position, kind, value, units))
            })
            .collect::<PyResult<Vec<_>>>()?;
        let cycle = &self.cycle;
        py.allow_threads(|| cycle.command(&commands)).map_err(|(index, e)| {
            let err = super::to_py_err(e);
            // Setting an attribute on a fresh exception instance cannot fail.
            let _ = err.value(py).setattr("command", index);
            err
        })
    }

    /// Sets the digital outputs of the drive at `position` at `levels` (AKD output number 1..2:
    /// level) and its analog output set-point at `analog_output` (V, at `volts_per_count`) from
    /// the next cycle on, the others as they are; all checked first, a refusal (ConfigError
    /// naming `joint` and the mappings that carry what its mapping lacks, an output the AKD
    /// does not have, a voltage out of range) changing nothing.
    #[pyo3(signature = (position, joint, levels, analog_output, volts_per_count))]
    fn set_drive_outputs(
        &self,
        position: u16,
        joint: &str,
        levels: Vec<(Bound<'_, pyo3::types::PyInt>, bool)>,
        analog_output: Option<f64>,
        volts_per_count: f64,
    ) -> PyResult<()> {
        let levels = levels
            .iter()
            .map(|(number, high)| match number.extract::<i64>() {
                Ok(n) => Ok((n, *high)),
                // Past 64 bits: no output the AKD has.
                Err(_) => Err(Error::from(CommandRefused::NoSuchOutput { number: number.to_string() })),
            })
            .collect::<crate::error::Result<Vec<_>>>()
            .py()?;
        self.cycle.set_drive_outputs(position, joint, &levels, analog_output, volts_per_count).py()
    }

    /// Sets one mapped output object of slave `position` from the next cycle on (its exact
    /// size in bytes); a mode's command object (a motion set-point) releases a held target,
    /// any other output (digital outputs, the analog output, a latch control) leaves it held.
    fn set_object(&self, position: u16, index: u16, subindex: u8, data: Vec<u8>) -> PyResult<()> {
        self.cycle.set_object(position, index, subindex, &data).py()
    }

    /// The mapping of slave `position`: {"outputs": [...], "inputs": [...]}, each a list of
    /// (index, subindex, bit length, byte offset within the slave's data) in wire order.
    fn mapping(&self, position: u16) -> PyResult<MappingView> {
        let (rx, tx) = self.cycle.mapping(position).py()?;
        let layout = |entries: &[crate::ethercat::pdo::PdoEntry]| {
            crate::ethercat::pdo::layout(entries.iter().copied())
                .map(|(offset, e)| (e.index, e.subindex, e.bits, offset))
                .collect()
        };
        Ok(MappingView { outputs: layout(rx), inputs: layout(tx) })
    }

    /// The real-time settings asked for and not permitted, one sentence each.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.cycle.warnings().to_vec()
    }

    /// The period in seconds.
    #[getter]
    fn period(&self) -> f64 {
        self.cycle.period().as_secs_f64()
    }

    /// Whether the thread runs.
    #[getter(running)]
    fn is_running(&self) -> bool {
        self.cycle.running()
    }

    /// Stops the thread after its current cycle and hands the master back to its Master object;
    /// snapshot, stats and histograms stay readable (the final ones). A second stop does nothing.
    fn stop(&self, py: Python<'_>) -> PyResult<()> {
        self.halt(py)
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    fn __exit__(&self, py: Python<'_>, _exc_type: PyObject, _exc: PyObject, _tb: PyObject) -> PyResult<()> {
        self.halt(py)
    }

    /// Drive `position`'s inputs in the last snapshot, read by its mapping with each object's
    /// data type: a DriveInputs (statusword, mode_display, position_actual, velocity_actual,
    /// torque_actual, following_error, digital_inputs; None where not mapped) with the
    /// snapshot's cycle, time_ns and fresh.
    fn drive_inputs(&self, position: u16) -> PyResult<DriveInputs> {
        self.cycle.drive_inputs(&self.cycle.snapshot(), position).py()
    }

    /// The inputs of each drive of `positions` (DriveInputs, as `drive_inputs` gives them),
    /// all from the same snapshot: every joint's values of one cycle.
    fn drives_inputs(&self, positions: Vec<u16>) -> PyResult<Vec<DriveInputs>> {
        let snapshot = self.cycle.snapshot();
        positions.into_iter().map(|p| self.cycle.drive_inputs(&snapshot, p).py()).collect()
    }

    /// The I/O of each drive of `positions` (DriveIo: digital and analog inputs, outputs as
    /// sent, hardware enable), all from the last snapshot.
    fn drives_io(&self, positions: Vec<u16>) -> PyResult<Vec<DriveIo>> {
        let snapshot = self.cycle.snapshot();
        positions.into_iter().map(|p| self.cycle.drive_io(&snapshot, p).py()).collect()
    }

    /// The channels of the slave at `position`, named after its PDO entries as its SII names
    /// them in snake case (an EL1004's "channel_1_input"): outputs, then inputs, each a dict of
    /// name, direction ("output" or "input"), index, subindex, bits and data_type (its CoE name);
    /// none for a slave without process data.
    fn channels(&self, position: u16) -> PyResult<Vec<super::device::ChannelView>> {
        super::device::channels(&self.cycle, position)
    }

    /// The I/O of each slave of `positions` by channel name, all from the last snapshot: a dict
    /// of cycle, time_ns, fresh, inputs ({name: value} as read) and outputs ({name: value} as
    /// sent); a bit is a bool, an integer an int.
    fn devices_io(&self, positions: Vec<u16>) -> PyResult<Vec<super::device::DeviceIoView>> {
        super::device::devices_io(&self.cycle, &positions)
    }

    /// Sets output channels of the device at `position` (a slave the cycle does not sequence)
    /// by name from the next cycle on, all or none: `values` maps each name to a bool (a bit),
    /// an int or a float; the other outputs keep theirs. ConfigError names an unknown output
    /// (and the device's outputs) or a value it does not take.
    fn set_channels(
        &self,
        position: u16,
        values: std::collections::BTreeMap<String, super::device::PyChannelValue>,
    ) -> PyResult<()> {
        let values: Vec<(&str, crate::ethercat::device::ChannelValue)> =
            values.iter().map(|(name, v)| (name.as_str(), v.0)).collect();
        self.cycle.set_channels(position, &values).py()
    }

    /// Switches every output of the device at `position` off from the next cycle on.
    fn switch_outputs_off(&self, position: u16) -> PyResult<()> {
        self.cycle.switch_outputs_off(position).py()
    }

    /// With `on`, a drive entering Fault or leaving Op quick-stops, in the same cycle, every
    /// other drive being enabled or enabled (and not in Fault): a bus of joints stops together.
    /// Off (the default), each drive reacts alone. The faulting drive's event is the only one.
    fn set_quick_stop_on_fault(&self, on: bool) {
        self.cycle.set_quick_stop_on_fault(on)
    }

    /// Where the recovery of slave `position` stands: "recovering" (lost, being brought back),
    /// "attempts" since it was lost, "recoveries" since the cycle started, "last_error" (why the
    /// last attempt failed, or None).
    fn recovery_status(&self, position: u16) -> PyResult<crate::cycle::recovery::RecoveryStatus> {
        self.cycle.recovery_status(position).py()
    }

    /// The distributed clocks while the cycle runs: SYNC0's cycle and shift, the reference
    /// clock's position and each drive's FBUS.PARAM02 and last system-time difference (read
    /// in the cyclic frame, one drive per cycle in turn); {"active": False} without them.
    fn dc_status<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        super::clocks::dc_status(py, self.cycle.dc_status())
    }

    /// Every slave's links and error counters as the reads beside the cycle found them: each
    /// port's link, what is at its other end, its counters since the first read ("total") and
    /// over the last 10 s ("window"), and the findings, the worst first ("errors on the cable
    /// into slave 4 (joint_5) port 0, from slave 3 (joint_4) port 1: 37 in the last 10 s").
    /// `names` (position to name) names slaves in the words; the others by their product.
    #[pyo3(signature = (names = None))]
    fn line_health(&self, names: Option<HashMap<usize, String>>) -> super::line_health::LineHealthView {
        let labels = super::line_health::labels(self.cycle.products(), names);
        super::line_health::LineHealthView::new(&self.cycle.line_health(), &labels)
    }

    /// What /diagnostics says of the line: a status of the line (its worst finding) and one per
    /// slave, each a tuple (level, what, message, hardware_id, [(key, value)]) as
    /// `diagnostic_array` takes it once the node's name is put in front of `what` ("line",
    /// "line slave N"); `link` names the line in hardware_id, `names` as for `line_health`.
    #[pyo3(signature = (link, names = None))]
    fn line_diagnostics(&self, link: &str, names: Option<HashMap<usize, String>>) -> Vec<LineStatus> {
        let labels = super::line_health::labels(self.cycle.products(), names);
        crate::ros::line_diagnostics::statuses(&self.cycle.line_health(), &labels, link)
    }

    /// Plays a joint trajectory in the cycle thread: joint j on drive `positions[j]`, point k
    /// at `times_ns[k]` from the start (strictly increasing, the first > 0), `points[k]` one
    /// entry per joint, a position (counts) or (position, velocity counts/s or None,
    /// acceleration counts/s² or None) — quintic where both ends of a segment give
    /// accelerations, cubic where they give velocities, linear otherwise — within each joint's
    /// limits (`set_joint_limits`; a 32-bit target's range at any speed where none were set):
    /// every point and the path interpolated between them, from `start_ns`
    /// (time.monotonic_ns(); None: now). Every drive must be in Operation enabled in
    /// interpolated position or cyclic synchronous position, and not being homed. Takes over
    /// from the trajectory in force without a step; a bad one raises ConfigError saying why
    /// before anything moves. Judged again when it takes over, from the set-points then in
    /// force: it may end "refused" there, nothing moved, the trajectory in force going on.
    /// With `tolerances` (FollowJointTrajectory's), a list of (path position, path velocity,
    /// goal position, goal velocity, stop deceleration) per joint in counts, counts/s and
    /// counts/s² (inf: not judged; for the deceleration: stop at once), with `goal_time_ns`:
    /// it ends "path_tolerance_violated" (after braking to a standstill) or
    /// "goal_tolerance_violated" where a drive strays, and `stop_trajectory` brakes it.
    /// `names`, one per joint, name them in a refusal (else the names their limits were set
    /// with, else their numbers in the lists). Returns its id.
    #[pyo3(signature = (positions, times_ns, points, start_ns = None, tolerances = None, goal_time_ns = 0, names = None))]
    #[allow(clippy::too_many_arguments)]
    fn play_trajectory(
        &self,
        py: Python<'_>,
        positions: Vec<u16>,
        times_ns: Vec<u64>,
        points: Vec<Vec<super::trajectory::PyKnot>>,
        start_ns: Option<u64>,
        tolerances: Option<Vec<super::trajectory::PyTolerance>>,
        goal_time_ns: u64,
        names: Option<Vec<String>>,
    ) -> PyResult<u32> {
        let tolerances = tolerances.map(|t| super::trajectory::tolerances(t, goal_time_ns));
        let played = super::trajectory::Played { positions, times_ns, points, start_ns, tolerances };
        super::trajectory::play(py, &self.cycle, played, names.as_deref())
    }

    /// Hands down the limits of joint `name` on drive `position`, by which every motion of it
    /// is judged from then on: `position` (min, max) in counts, `max_velocity` counts/s and
    /// `max_acceleration` counts/s² (None: open), and its `units` to word refusals in (None:
    /// counts). Trajectories are refused where a point or the path between them goes past them;
    /// in a cyclic position mode, so is a set-point whose step from the target last sent, taken
    /// within one cycle, does.
    #[pyo3(signature = (position, name, limits, max_velocity = None, max_acceleration = None, units = None))]
    fn set_joint_limits(
        &self,
        position: u16,
        name: String,
        limits: (Option<f64>, Option<f64>),
        max_velocity: Option<f64>,
        max_acceleration: Option<f64>,
        units: Option<crate::drive::scaling::JointScaling>,
    ) -> PyResult<()> {
        let scale = units.map_or(Scale::COUNTS, |u| u.scale());
        let joint = super::trajectory::joint_limits(name, limits, max_velocity, max_acceleration, scale);
        self.cycle.set_joint_limits(position, joint).py()
    }

    /// Brings trajectory `id` to a standstill in the cycle thread at its joints' stop
    /// decelerations (it ends "stopped"); nothing for one that is not in force.
    fn stop_trajectory(&self, id: u32) {
        self.cycle.stop_trajectory(id);
    }

    /// Drive `position`'s (desired position, desired velocity, actual position, actual
    /// velocity), counts and counts/s, as the trajectory in force judges them; None while none
    /// drives it.
    fn trajectory_followed(&self, position: u16) -> Option<(f64, f64, f64, f64)> {
        self.cycle.trajectory_followed(position).map(|[a, b, c, d]| (a, b, c, d))
    }

    /// Trajectory `id` as the cycle thread last published it: "id", "state" ("pending",
    /// "running", "done", "replaced", "aborted", "stopped", "path_tolerance_violated",
    /// "goal_tolerance_violated"), "replaced_by" (the newer id), "slave",
    /// "statusword" and "ds402_state" (of the drive that aborted it), "point" (the point
    /// approached; "points" once past the last), "started_ns" (None while pending),
    /// "elapsed_ns", "duration_ns". The last 64 are kept.
    fn trajectory_status(&self, id: u32) -> PyResult<super::trajectory::StatusView> {
        Ok(super::trajectory::status_view(self.cycle.trajectory_status(id).py()?, &self.cycle))
    }
}

impl Drop for PyCycle {
    /// A Cycle forgotten without `stop()` still stops and hands its master back.
    fn drop(&mut self) {
        if !self.cycle.stopped() {
            Python::with_gil(|py| {
                let _ = self.halt(py);
            });
        }
    }
}

#[pymethods]
impl DriveStatus {
    /// The CiA 402 state the statusword shows (a `Ds402State`), None for a statusword that
    /// shows none.
    #[getter(state)]
    fn py_state(&self) -> Option<State> {
        self.state()
    }

    /// Why the request is stuck or lost, from the statusword; None when it is neither.
    #[getter(reason)]
    fn py_reason(&self) -> Option<String> {
        self.stuck_reason()
    }
}

#[pymethods]
impl Request {
    fn __str__(&self) -> &'static str {
        self.name()
    }
}

#[pymethods]
impl Progress {
    fn __str__(&self) -> &'static str {
        self.name()
    }
}

#[pymethods]
impl RealTime {
    /// Real-time options of a cycle thread, each checked here: a priority outside the
    /// SCHED_FIFO range, a CPU that does not exist or a wake-up latency outside
    /// 0..=1000000 µs is a ConfigError naming the allowed values.
    #[new]
    #[pyo3(signature = (*, priority = None, cpu = None, lock_memory = false, cpu_latency_us = None, pipelined = false))]
    fn py_new(
        priority: Option<i32>,
        cpu: Option<usize>,
        lock_memory: bool,
        cpu_latency_us: Option<i64>,
        pipelined: bool,
    ) -> PyResult<Self> {
        rt::check(priority, cpu).py()?;
        let cpu_latency_us = cpu_latency_us.map(rt::cpu_latency).transpose().py()?;
        Ok(RealTime { priority, cpu, lock_memory, cpu_latency_us, pipelined })
    }

    fn __repr__(&self) -> String {
        let option = |v: Option<String>| v.unwrap_or_else(|| "None".into());
        format!(
            "RealTime(priority={}, cpu={}, lock_memory={}, cpu_latency_us={}, pipelined={})",
            option(self.priority.map(|p| p.to_string())),
            option(self.cpu.map(|c| c.to_string())),
            if self.lock_memory { "True" } else { "False" },
            option(self.cpu_latency_us.map(|us| us.to_string())),
            if self.pipelined { "True" } else { "False" },
        )
    }
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyCycle>()?;
    m.add_class::<RealTime>()?;
    m.add_class::<DriveStatus>()?;
    m.add_class::<FaultEvent>()?;
    m.add_class::<Request>()?;
    m.add_class::<Progress>()?;
    m.add("DRIVE_REQUESTS", pyo3::types::PyTuple::new(m.py(), Request::ALL)?)?;
    // Per-cycle records the cycle keeps for each drive until `samples()` takes them.
    m.add("SAMPLES_PER_DRIVE", crate::cycle::samples::CAPACITY)?;
    m.add("SAMPLE_COLUMNS", pyo3::types::PyTuple::new(m.py(), SAMPLE_COLUMNS)?)
}
