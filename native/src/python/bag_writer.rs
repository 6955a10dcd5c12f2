//! `akd_ros._native.BagWriter`: a bag's MCAP files written by a thread of the crate for
//! `akd_ros.recorder`, over [`crate::ros::bag_writer`]; `Feed.record` and `Feed.record_cycles`
//! hand it what the node publishes and every cycle's records without Python.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;

use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;

use crate::ros::bag_writer::{BagWriter, Counters, Options, Report, Topic};

/// A bag being written by its thread: `BagWriter(folder, name, *, compression, ...)` (see
/// `akd_ros.recorder.Recorder`, which checks the values). Nothing it does raises for I/O: the
/// first failure is in `report()`.
#[pyclass(name = "BagWriter", module = "akd_ros._native", frozen)]
pub struct PyBagWriter {
    pub(super) writer: Arc<BagWriter>,
}

#[pymethods]
impl PyBagWriter {
    #[new]
    // One argument per keyword of the Python signature.
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (
        folder, name, *, compression, profile, library, chunk_size, flush_interval, split_size, split_duration,
        queue_size, decimation, samples_per_cycle, black_box_seconds, ring_size, sync_interval
    ))]
    fn new(
        folder: PathBuf,
        name: String,
        compression: &str,
        profile: String,
        library: String,
        chunk_size: usize,
        flush_interval: f64,
        split_size: Option<u64>,
        split_duration: Option<f64>,
        queue_size: usize,
        decimation: u64,
        samples_per_cycle: u64,
        black_box_seconds: f64,
        ring_size: usize,
        sync_interval: f64,
    ) -> PyResult<Self> {
        let compression = match compression {
            "zstd" => Some(mcap::Compression::Zstd),
            "lz4" => Some(mcap::Compression::Lz4),
            "none" => None,
            other => {
                return Err(PyValueError::new_err(format!("compression {other:?} is not one of 'lz4', 'none', 'zstd'")))
            }
        };
        let options = Options {
            folder,
            name,
            compression,
            profile,
            library,
            chunk_size,
            flush_interval: super::seconds(flush_interval, "flush interval")?,
            split_size,
            split_duration_ns: split_duration.map(|s| (s * 1e9) as i64),
            queue_size,
            decimation,
            samples_per_cycle,
            black_box_ns: (black_box_seconds > 0.0).then_some((black_box_seconds * 1e9) as i64),
            ring_size,
            sync_interval: super::seconds(sync_interval, "black box sync interval")?,
        };
        let writer = BagWriter::start(options).map_err(|e| PyOSError::new_err(format!("no bag writer thread: {e}")))?;
        Ok(PyBagWriter { writer: Arc::new(writer) })
    }

    /// Adds topic `name` of `type_name` (its definition, its channel's metadata); topics are
    /// numbered from 0 in the order added.
    fn add_topic(&self, name: String, type_name: String, definition: Vec<u8>, metadata: BTreeMap<String, String>) {
        self.writer.add_topic(Topic { name, type_name, definition, metadata });
    }

    /// Names the per-cycle and the black box topics by their numbers.
    #[pyo3(signature = (cycle, black_box))]
    fn set_cycle_topics(&self, cycle: Option<usize>, black_box: Option<usize>) {
        self.writer.set_cycle_topics(cycle, black_box);
    }

    /// Queues a serialised message of topic `topic` at `time_ns`; False when it was dropped.
    fn write(&self, topic: usize, time_ns: i64, data: &[u8]) -> bool {
        self.writer.write(topic, time_ns, data.to_vec())
    }

    /// Queues per-cycle records, a list of (time_ns, data); False when they were dropped.
    fn records(&self, records: Vec<(i64, Bound<'_, PyBytes>)>) -> bool {
        self.writer.records(records.iter().map(|(t, d)| (*t, d.as_bytes().to_vec())).collect())
    }

    /// A fault at `time_ns`: its black box is written.
    fn fault(&self, time_ns: i64) {
        self.writer.fault(time_ns);
    }

    /// Holds the thread where it is, or releases it.
    fn hold(&self, held: bool) {
        self.writer.hold(held);
    }

    /// The report once its version passes `seen`, or the current one after `timeout` seconds
    /// (the GIL released): version, bag, files (each path, span: (first, last) ns or None,
    /// messages), topic_messages, parked, failure, closing, done.
    fn report(&self, py: Python<'_>, seen: u64, timeout: f64) -> PyResult<Report> {
        let timeout = super::seconds(timeout, "timeout")?;
        let writer = &self.writer;
        Ok(py.allow_threads(|| writer.report(seen, timeout)))
    }

    /// The metadata record's text of the files parked so far.
    fn finish(&self, metadata: String) {
        self.writer.finish(metadata);
    }

    /// Asks for the end (see `finish`).
    fn close(&self) {
        self.writer.close();
    }

    /// Waits up to `timeout` seconds (the GIL released) for the thread's end; whether it ended.
    fn join(&self, py: Python<'_>, timeout: f64) -> PyResult<bool> {
        let timeout = super::seconds(timeout, "timeout")?;
        let writer = &self.writer;
        Ok(py.allow_threads(|| writer.join(timeout)))
    }

    /// written, dropped, errors, black_box_dumps (faults whose black box was written) and
    /// black_box_syncs (closes and syncs of the chunk they made).
    fn counters(&self) -> Counters {
        self.writer.counters()
    }
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyBagWriter>()
}
