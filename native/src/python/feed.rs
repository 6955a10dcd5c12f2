//! `akd_ros._native.Feed`: the node's periodic publications made by a thread of the crate from a
//! running `Cycle` (see [`crate::node::feed`]), and `diagnostic_array`, the /diagnostics message
//! made of what the node says.

use std::sync::atomic::{AtomicI64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;

use super::bag_writer::PyBagWriter;
use super::cycle::PyCycle;
use super::record::joint_scale;
use crate::node::cycle_records::CycleRecords;
use crate::node::feed::{Feed, Kind};
use crate::node::Joint;
use crate::ros_msgs::{self, DiagnosticArray, DiagnosticStatus, Header, KeyValue};

/// What `take` gives: each message made (its stream's id, its bytes), and whether events wait.
type Taken<'py> = (Vec<(usize, Bound<'py, PyBytes>)>, bool);

/// `Feed(cycle, joints)`: the publications of `joints`, each (drive position, name, its
/// `akd_ros.units.Units`, whether the drive homes it: DriveStatus.homed is always true for a
/// joint it does not), of `cycle`. Streams are added (`add_joint_states`,
/// `add_drive_status`, each giving its id) before `start()`; while active, each stream's
/// message is made at its rate and handed out by `take()` as (id, bytes). Stamps are the
/// monotonic clock plus `set_offset`'s ROS minus monotonic time.
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
    fn new(cycle: Py<PyCycle>, joints: Vec<(u16, String, Bound<'_, PyAny>, bool)>) -> PyResult<Self> {
        let joints = joints
            .iter()
            .map(|(slave, name, units, homes)| {
                Ok(Joint { slave: *slave, name: name.clone(), scale: joint_scale(units)?, homes: *homes })
            })
            .collect::<PyResult<Vec<_>>>()?;
        let offset_ns = Arc::new(AtomicI64::new(0));
        let thread = cycle.get().thread();
        Ok(PyFeed { feed: Feed::new(thread, joints, offset_ns.clone()), offset_ns, cycle })
    }

    /// A stream of sensor_msgs/JointState of every joint every `period` seconds; its id.
    fn add_joint_states(&self, period: f64) -> PyResult<usize> {
        self.stream(Kind::JointStates, period)
    }

    /// A stream of akd_ros/DriveStatus of joint number `joint` every `period` seconds; its id.
    fn add_drive_status(&self, joint: usize, period: f64) -> PyResult<usize> {
        if joint >= self.feed.joints().len() {
            return Err(PyValueError::new_err(format!("no joint {joint}: the feed has {}", self.feed.joints().len())));
        }
        self.stream(Kind::DriveStatus(joint), period)
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
    PyBytes::new(py, &ros_msgs::to_cdr(&message, 4096))
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyFeed>()?;
    m.add_function(wrap_pyfunction!(diagnostic_array, m)?)
}
