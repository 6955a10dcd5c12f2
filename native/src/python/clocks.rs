//! Distributed clocks for Python: whether a link runs them by default, and the cycle's
//! `dc_status()`.

use pyo3::prelude::*;

use super::IntoPyResult;
use crate::cycle::dc_status::DcStatus;
use crate::ethercat::link_spec::LinkSpec;
use crate::ethercat::master::clocks::DcSlave;

/// Whether `link` runs distributed clocks by default: a network interface does, as TwinCAT runs
/// the AKD; "sim", "sim:N" and "udp://HOST:PORT" do not, as their frames' timing is not a
/// wire's. Raises ConfigError for a link spec that names no bus.
#[pyfunction]
fn dc_by_default(link: &str) -> PyResult<bool> {
    Ok(link.parse::<LinkSpec>().py()?.runs_dc_by_default())
}

/// `Cycle.dc_status()`: {"active": False} without distributed clocks; with them "active",
/// "cycle_ns", "shift_ns", "reference_position", "difference_reads", "difference_misses" and
/// "drives", one [`DcDriveView`] per drive with DC.
#[derive(IntoPyObject)]
pub(super) enum DcStatusView {
    Off {
        active: bool,
    },
    On {
        active: bool,
        cycle_ns: u32,
        shift_ns: i32,
        reference_position: u16,
        difference_reads: u64,
        difference_misses: u64,
        drives: Vec<DcDriveView>,
    },
}

/// One drive of `dc_status()["drives"]`: "position", "fbus_param02" (None: unknown, nothing
/// was written; see [`crate::ethercat::master::clocks::DcSlave::fbus_param02`]) and
/// "system_time_difference_ns" (None before the first read).
#[derive(IntoPyObject)]
pub(super) struct DcDriveView {
    position: u16,
    fbus_param02: Option<u32>,
    system_time_difference_ns: Option<i64>,
}

impl From<DcSlave> for DcDriveView {
    fn from(slave: DcSlave) -> Self {
        DcDriveView {
            position: slave.position,
            fbus_param02: slave.fbus_param02,
            system_time_difference_ns: slave.time_difference_ns,
        }
    }
}

impl From<Option<DcStatus>> for DcStatusView {
    fn from(status: Option<DcStatus>) -> Self {
        let Some(s) = status else { return DcStatusView::Off { active: false } };
        DcStatusView::On {
            active: true,
            cycle_ns: s.cycle_ns,
            shift_ns: s.shift_ns,
            reference_position: s.reference_position,
            difference_reads: s.difference_reads,
            difference_misses: s.difference_misses,
            drives: s.drives.into_iter().map(DcDriveView::from).collect(),
        }
    }
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(dc_by_default, m)?)
}
