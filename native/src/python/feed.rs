//! `akd_ros._native.Feed`: the node's periodic publications made by a thread of the crate from a
//! running `Cycle` (see [`crate::ros::feed`]), and `diagnostic_array`, the /diagnostics message
//! made of what the node says.

use std::sync::atomic::{AtomicI64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;

use super::bag_writer::PyBagWriter;
use super::cycle::PyCycle;
use crate::drive::scaling::JointScaling;
use crate::ros::cycle_records::CycleRecords;
use crate::ros::feed::{Feed, Kind};
use crate::ros::msgs::{self, DiagnosticArray, DiagnosticStatus, Header, KeyValue};
use crate::ros::{Device, Joint, JointIo};

/// What `take` gives: each message made (its stream's id, its bytes), and whether events wait.
type Taken<'py> = (Vec<(usize, Bound<'py, PyBytes>)>, bool);

/// `Feed(cycle, joints, devices=[])`: the publications of `joints` (each a dict, see
/// `FeedJoint`) and `devices` (each a dict of "slave", "name", "product") of `cycle`. Streams are added (`add_joint_states`,
/// `add_drive_status`, `add_drive_io`, `add_device_io`, each giving its id) before `start()`; while active, each stream's message is made at its rate and
/// handed out by `take()` as (id, bytes). Stamps are the monotonic clock plus `set_offset`'s ROS
/// minus monotonic time.
#[pyclass(name = "Feed", module = "akd_ros._native", frozen)]
pub struct PyFeed {
    feed: Feed,
    offset_ns: Arc<AtomicI64>,
    cycle: Py<PyCycle>,
}

fn period(seconds: f64) -> PyResult<Duration> {
    match Duration::try_from_secs_f64(seconds) {
        Ok(period) if !period.is_zero() => Ok(period),
        _ => Err(PyValueError::new_err(format!(
            "a stream's period must be a finite number of seconds > 0, not {seconds}"
        ))),
    }
}

/// A joint of a feed, a dict with every key: "slave" (its drive's position), "name", "units"
/// (its `Units`), "homes" (whether its drive homes it: DriveStatus.homed is always
/// true for a joint it does not), "inputs" and "outputs" (the names it gives the drive's digital
/// inputs and outputs, each (name, AKD number)) and "volts_per_count" (its analog scale).
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct FeedJoint {
    slave: u16,
    name: String,
    units: JointScaling,
    homes: bool,
    inputs: Vec<(String, u8)>,
    outputs: Vec<(String, u8)>,
    volts_per_count: f64,
}

/// `index` where it is below `count`, the feed's number of `what`s; else ValueError saying so.
fn one_of(what: &str, index: usize, count: usize) -> PyResult<usize> {
    match index < count {
        true => Ok(index),
        false => Err(PyValueError::new_err(format!("no {what} {index}: the feed has {count}"))),
    }
}

impl PyFeed {
    fn stream(&self, kind: Kind, seconds: f64) -> PyResult<usize> {
        self.feed
            .add(kind, period(seconds)?)
            .ok_or_else(|| PyValueError::new_err("the feed has started: add its streams before start()"))
    }
}

#[pymethods]
impl PyFeed {
    #[new]
    #[pyo3(signature = (cycle, joints, devices = Vec::new()))]
    fn new(cycle: Py<PyCycle>, joints: Vec<FeedJoint>, devices: Vec<Device>) -> PyResult<Self> {
        let joints = joints
            .into_iter()
            .map(|j| {
                let io = JointIo::new(j.inputs, j.outputs, j.volts_per_count)
                    .map_err(|e| PyValueError::new_err(format!("joint {}: {e}", j.name)))?;
                Ok(Joint { slave: j.slave, scale: j.units, name: j.name, homes: j.homes, io })
            })
            .collect::<PyResult<Vec<_>>>()?;
        let offset_ns = Arc::new(AtomicI64::new(0));
        let thread = cycle.get().thread();
        Ok(PyFeed { feed: Feed::new(thread, joints, devices, offset_ns.clone()), offset_ns, cycle })
    }

    /// A stream of sensor_msgs/JointState of every joint every `period` seconds; its id.
    fn add_joint_states(&self, period: f64) -> PyResult<usize> {
        self.stream(Kind::JointStates, period)
    }

    /// A stream of akd_ros/DriveStatus of joint number `joint` every `period` seconds; its id.
    fn add_drive_status(&self, joint: usize, period: f64) -> PyResult<usize> {
        self.stream(Kind::DriveStatus(one_of("joint", joint, self.feed.joints().len())?), period)
    }

    /// A stream of akd_ros/DriveIO of joint number `joint` every `period` seconds; its id.
    fn add_drive_io(&self, joint: usize, period: f64) -> PyResult<usize> {
        self.stream(Kind::DriveIo(one_of("joint", joint, self.feed.joints().len())?), period)
    }

    /// A stream of akd_ros/DeviceIO of device number `device` every `period` seconds; its id.
    fn add_device_io(&self, device: usize, period: f64) -> PyResult<usize> {
        self.stream(Kind::DeviceIo(one_of("device", device, self.feed.devices().len())?), period)
    }

    /// Hands out at once on `stream`, a DeviceIO stream, the DeviceIO of a change of its
    /// device's inputs that the cycle reported (a "device_inputs" event of `Cycle.events`: its
    /// cycle, time_ns and levels), stamped with that cycle, recorded as the stream is; its
    /// other channels are the last snapshot's. False when `stream` makes no DeviceIO or the feed
    /// is inactive.
    fn device_input_change(&self, stream: usize, cycle: u64, time_ns: u64, levels: u64) -> bool {
        self.feed.device_input_change(stream, cycle, time_ns, levels)
    }

    /// Starts the thread (inactive until `set_active(True)`).
    fn start(&self) -> PyResult<()> {
        self.feed.start().map_err(|e| PyOSError::new_err(format!("no feed thread: {e}")))
    }

    /// Makes messages, or none.
    fn set_active(&self, active: bool) {
        self.feed.set_active(active);
    }

    /// ROS minus monotonic time (ns), which stamps the messages and the recorded cycles.
    fn set_offset(&self, offset_ns: i64) {
        self.offset_ns.store(offset_ns, Ordering::Relaxed);
    }

    /// Hands out at once on `stream`, a DriveIO stream, the DriveIO of a change of its drive's
    /// inputs that the cycle reported (an "inputs" event of `Cycle.events`: its cycle, time_ns,
    /// digital_inputs and statusword), stamped with that cycle, recorded as the stream is; the
    /// analog input and the outputs are the last snapshot's. False when `stream` makes no
    /// DriveIO or the feed is inactive.
    fn input_change(&self, stream: usize, cycle: u64, time_ns: u64, digital_inputs: u32, statusword: u16) -> bool {
        self.feed.input_change(stream, cycle, time_ns, digital_inputs, statusword)
    }

    /// Every message of stream `stream` is also queued in `writer` as its topic number `topic`.
    fn record(&self, stream: usize, writer: &PyBagWriter, topic: usize) {
        self.feed.record(stream, writer.writer.clone(), topic);
    }

    /// `writer` takes every cycle's records of the joints for itself from now on, as
    /// akd_ros/CycleSample, stamped as the messages are (the cycle's own `samples()` are then
    /// the writer's).
    fn record_cycles(&self, py: Python<'_>, writer: &PyBagWriter) {
        let cycle = self.cycle.bind(py).get().thread();
        let source = CycleRecords::new(cycle, self.feed.joints().to_vec(), self.offset_ns.clone());
        writer.writer.attach(Box::new(source));
    }

    /// Waits up to `timeout` seconds (the GIL released) for messages or events: ([(stream id,
    /// bytes)], whether the cycle has events waiting).
    fn take<'py>(&self, py: Python<'py>, timeout: f64) -> PyResult<Taken<'py>> {
        let timeout = super::seconds(timeout, "timeout")?;
        let feed = &self.feed;
        let (messages, events) = py.allow_threads(|| feed.take(timeout));
        Ok((messages.into_iter().map(|(stream, data)| (stream, PyBytes::new(py, &data))).collect(), events))
    }

    /// Messages dropped because nobody took them in time.
    #[getter]
    fn dropped(&self) -> u64 {
        self.feed.dropped()
    }

    /// Stops the thread (the GIL released while it ends); `take` returns at once from then on.
    fn stop(&self, py: Python<'_>) {
        let feed = &self.feed;
        py.allow_threads(|| feed.stop());
    }
}

/// One DiagnosticStatus as `diagnostic_array` takes it: level, name, message, hardware_id and
/// the (key, value) pairs.
type Status = (u8, String, String, String, Vec<(String, String)>);

/// diagnostic_msgs/DiagnosticArray of `statuses`, stamped `stamp_ns` (ROS time), serialised.
#[pyfunction]
fn diagnostic_array<'py>(py: Python<'py>, stamp_ns: i64, statuses: Vec<Status>) -> Bound<'py, PyBytes> {
    let message = DiagnosticArray {
        header: Header::at(stamp_ns),
        status: statuses
            .iter()
            .map(|(level, name, message, hardware_id, values)| DiagnosticStatus {
                level: *level,
                name,
                message,
                hardware_id,
                values: values.iter().map(|(key, value)| KeyValue { key, value }).collect(),
            })
            .collect(),
    };
    PyBytes::new(py, &msgs::to_cdr(&message, 4096))
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyFeed>()?;
    m.add_function(wrap_pyfunction!(diagnostic_array, m)?)
}
