//! Distributed clocks for Python: whether a link runs them by default, and the cycle's
//! `dc_status()`.

use pyo3::prelude::*;

use super::{IntoPyResult, Merged};
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
#[derive(IntoPyObject)]
pub(super) enum DcStatusView {
    Off(Active),
    On(Merged<Active, DcStatus>),
}

/// Whether the bus runs distributed clocks.
#[derive(IntoPyObject)]
pub(super) struct Active {
    active: bool,
}

impl From<Option<DcStatus>> for DcStatusView {
    fn from(status: Option<DcStatus>) -> Self {
        match status {
            Some(status) => DcStatusView::On(Merged(Active { active: true }, status)),
            None => DcStatusView::Off(Active { active: false }),
        }
    }
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(dc_by_default, m)?)
}
