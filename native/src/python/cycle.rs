//! `akd_ros._native.Cycle`: the real-time cycle thread for Python.
//!
//! The Cycle takes the Master for as long as it runs and gives it back on `stop()`. The thread
//! never needs the GIL; set-points and snapshots go through lock-free buffers, so a Python
//! thread busy with anything never delays a cycle. Waiting on the thread releases the GIL.

use std::time::Duration;

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};

use super::master::PyMaster;
use super::IntoPyResult;
use crate::cycle::stats::Summary;
use crate::cycle::{Config, CycleThread};
use crate::error::Error;

/// Exchanges a Master's process image every period on a thread of its own.
#[pyclass(name = "Cycle", module = "akd_ros._native")]
pub struct PyCycle {
    master: Py<PyMaster>,
    cycle: CycleThread,
}

fn summary<'py>(py: Python<'py>, s: Summary) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("count", s.count)?;
    d.set_item("min_ns", s.min_ns)?;
    d.set_item("mean_ns", s.mean_ns)?;
    d.set_item("p99_ns", s.p99_ns)?;
    d.set_item("max_ns", s.max_ns)?;
    Ok(d)
}

impl PyCycle {
    fn halt(&mut self, py: Python<'_>) -> PyResult<()> {
        if self.cycle.stopped() {
            return Ok(());
        }
        let cycle = &mut self.cycle;
        let master = py.allow_threads(|| cycle.stop()).py()?;
        self.master.borrow(py).put_back(master);
        Ok(())
    }
}

#[pymethods]
impl PyCycle {
    /// Starts cycling `master` (its slaves in Op) every `period` seconds (0.00025 to 0.01).
    /// `priority` asks for SCHED_FIFO (1..=99), `cpu` binds the thread to one CPU, and
    /// `lock_memory` locks the process's memory; what the system does not permit is listed in
    /// `warnings` and the cycle runs without it. The master is unusable until `stop()`.
    #[new]
    #[pyo3(signature = (master, period, *, priority = None, cpu = None, lock_memory = false))]
    fn new(
        py: Python<'_>,
        master: Py<PyMaster>,
        period: f64,
        priority: Option<i32>,
        cpu: Option<usize>,
        lock_memory: bool,
    ) -> PyResult<Self> {
        let period = Duration::try_from_secs_f64(period).map_err(|_| {
            super::to_py_err(Error::Config(format!(
                "cycle period {period} s is outside the allowed range 0.00025 ..= 0.01 s"
            )))
        })?;
        let config = Config { period, priority, cpu, lock_memory };
        let taken = master.borrow(py).take()?;
        match py.allow_threads(|| CycleThread::start(taken, config)) {
            Ok(cycle) => Ok(PyCycle { master, cycle }),
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

    /// The outputs of the slave at `position` as they go out.
    fn outputs<'py>(&self, py: Python<'py>, position: u16) -> PyResult<Bound<'py, PyBytes>> {
        Ok(PyBytes::new(py, &self.cycle.outputs(position).py()?))
    }

    /// The last cycle's snapshot: cycle (count, from 1), time_ns (monotonic wake-up time),
    /// wkc, fresh (whether this cycle's exchange succeeded) and inputs (one bytes per slave,
    /// None for a slave without process data), all from the same cycle.
    fn snapshot<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let cycle = &self.cycle;
        let s = cycle.snapshot();
        let d = PyDict::new(py);
        d.set_item("cycle", s.cycle)?;
        d.set_item("time_ns", s.time_ns)?;
        d.set_item("wkc", s.wkc)?;
        d.set_item("fresh", s.fresh)?;
        let inputs = PyList::empty(py);
        for position in 0..cycle.slave_count() {
            match cycle.inputs_of(&s, position) {
                Ok(data) => inputs.append(PyBytes::new(py, data))?,
                Err(_) => inputs.append(py.None())?,
            }
        }
        d.set_item("inputs", inputs)?;
        Ok(d)
    }

    /// The statistics: cycles, overruns, lost_frames, wkc_errors, other_errors,
    /// setpoints_busy, and period, wake_latency (how late after its deadline the thread woke)
    /// and exchange, each {count, min_ns, mean_ns, p99_ns, max_ns}.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        use std::sync::atomic::Ordering::Relaxed;
        let s = self.cycle.stats();
        let d = PyDict::new(py);
        d.set_item("cycles", s.cycles.load(Relaxed))?;
        d.set_item("overruns", s.overruns.load(Relaxed))?;
        d.set_item("lost_frames", s.lost_frames.load(Relaxed))?;
        d.set_item("wkc_errors", s.wkc_errors.load(Relaxed))?;
        d.set_item("other_errors", s.other_errors.load(Relaxed))?;
        d.set_item("setpoints_busy", s.setpoints_busy.load(Relaxed))?;
        d.set_item("period", summary(py, s.period.summary())?)?;
        d.set_item("wake_latency", summary(py, s.wake_latency.summary())?)?;
        d.set_item("exchange", summary(py, s.exchange.summary())?)?;
        Ok(d)
    }

    /// The histograms "period", "wake_latency" and "exchange", each a list of (upper edge in ns, count) of its
    /// non-empty 1 µs buckets.
    fn histograms<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.cycle.stats();
        let d = PyDict::new(py);
        d.set_item("period", s.period.buckets())?;
        d.set_item("wake_latency", s.wake_latency.buckets())?;
        d.set_item("exchange", s.exchange.buckets())?;
        Ok(d)
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
    fn stop(&mut self, py: Python<'_>) -> PyResult<()> {
        self.halt(py)
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    fn __exit__(&mut self, py: Python<'_>, _exc_type: PyObject, _exc: PyObject, _tb: PyObject) -> PyResult<()> {
        self.halt(py)
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

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyCycle>()
}
