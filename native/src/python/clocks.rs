//! Distributed clocks for Python: whether a link runs them by default, and the cycle's
//! `dc_status()`.

use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::IntoPyResult;
use crate::cycle::dc_status::DcStatus;
use crate::ethercat::link_spec::LinkSpec;

/// Whether `link` runs distributed clocks by default: a network interface does, as TwinCAT runs
/// the AKD; "sim", "sim:N" and "udp://HOST:PORT" do not, as their frames' timing is not a
/// wire's. Raises ConfigError for a link spec that names no bus.
#[pyfunction]
fn dc_by_default(link: &str) -> PyResult<bool> {
    Ok(link.parse::<LinkSpec>().py()?.runs_dc_by_default())
}

/// `Cycle.dc_status()`: {"active": False} without distributed clocks; with them "active" and
/// the fields of [`DcStatus`], each drive's those of [`crate::cycle::dc_status::DcDrive`].
pub(super) fn dc_status(py: Python<'_>, status: Option<DcStatus>) -> PyResult<Bound<'_, PyDict>> {
    let dict = PyDict::new(py);
    dict.set_item("active", status.is_some())?;
    if let Some(status) = status {
        dict.update(status.into_pyobject(py)?.as_mapping())?;
    }
    Ok(dict)
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(dc_by_default, m)?)
}
