//! Distributed clocks for Python: whether a link runs them by default, and the cycle's
//! `dc_status()` as a dict.

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use super::IntoPyResult;
use crate::cycle::CycleThread;
use crate::link::LinkSpec;

/// Whether `link` runs distributed clocks by default: a network interface does, as TwinCAT runs
/// the AKD; "sim", "sim:N" and "udp://HOST:PORT" do not, as their frames' timing is not a
/// wire's. Raises ConfigError for a link spec that names no bus.
#[pyfunction]
fn dc_by_default(link: &str) -> PyResult<bool> {
    Ok(link.parse::<LinkSpec>().map_err(crate::error::Error::from).py()?.runs_dc_by_default())
}

/// `Cycle.dc_status()`: "active" (False, and nothing else, without distributed clocks),
/// "cycle_ns", "shift_ns", "reference_position", "difference_reads", "difference_misses" and
/// "drives", one dict per drive with DC: "position", "fbus_param02" (None: the drive has no
/// such object) and "system_time_difference_ns" (None before the first read).
pub(super) fn dc_status<'py>(py: Python<'py>, cycle: &CycleThread) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let Some(status) = cycle.dc_status() else {
        d.set_item("active", false)?;
        return Ok(d);
    };
    d.set_item("active", true)?;
    d.set_item("cycle_ns", status.cycle_ns)?;
    d.set_item("shift_ns", status.shift_ns)?;
    d.set_item("reference_position", status.reference_position)?;
    d.set_item("difference_reads", status.difference_reads)?;
    d.set_item("difference_misses", status.difference_misses)?;
    let drives = PyList::empty(py);
    for drive in &status.drives {
        let entry = PyDict::new(py);
        entry.set_item("position", drive.position)?;
        entry.set_item("fbus_param02", drive.fbus_param02)?;
        entry.set_item("system_time_difference_ns", drive.time_difference_ns)?;
        drives.append(entry)?;
    }
    d.set_item("drives", drives)?;
    Ok(d)
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(dc_by_default, m)?)
}
