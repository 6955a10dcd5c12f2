//! `akd_ros._native.cycle_sample_records`: per-cycle records, as `Cycle.samples` gives them,
//! turned into serialised `akd_ros/msg/CycleSample` messages for the recorder in one call.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use crate::cycle::samples::Sample;
use crate::drive::scaling::JointScaling;
use crate::ros::cycle_sample;

/// A column of `columns` by name, every row converted to T.
fn column<'py, T: FromPyObject<'py>>(columns: &Bound<'py, PyDict>, name: &str) -> PyResult<Vec<T>> {
    match columns.get_item(name)? {
        Some(values) => values.extract(),
        None => Err(PyValueError::new_err(format!("per-cycle records without their {name:?} column"))),
    }
}

/// `values`, a column of `rows` values; refused where it has another length.
fn of_length<T>(values: Vec<T>, rows: usize) -> PyResult<Vec<T>> {
    match values.len() == rows {
        true => Ok(values),
        false => Err(PyValueError::new_err("per-cycle records whose columns differ in length")),
    }
}

/// Each of `fields` of `samples` from its column of `columns`.
macro_rules! read_columns {
    ($columns:ident, $samples:ident: $($field:ident),*) => {
        $(
            let values = of_length(column($columns, stringify!($field))?, $samples.len())?;
            $samples.iter_mut().zip(values).for_each(|(sample, value)| sample.$field = value);
        )*
    };
}

/// The rows of `columns` (`Cycle.samples`' columns of one drive; none at all for no rows) as
/// Samples: what a CycleSample carries of each (not its slave, freshness or loss).
fn samples_of(columns: &Bound<'_, PyDict>) -> PyResult<Vec<Sample>> {
    if columns.is_empty() {
        return Ok(Vec::new());
    }
    let mut samples = vec![Sample::default(); column::<u64>(columns, "cycle")?.len()];
    read_columns!(columns, samples: cycle, time_ns, period_ns, exchange_ns, wkc, statusword, mode, position,
        velocity, torque, following_error, target_position, target_velocity, target_torque);
    Ok(samples)
}

/// The records of `joints`, a list of (joint name, its `Units`, its columns as
/// `Cycle.samples` gives them), as a list of (ROS time ns, serialised `akd_ros/msg/CycleSample`),
/// cycle by cycle and within a cycle in the order of `joints`; `offset_ns` (ROS minus monotonic
/// time) stamps each with its cycle's wake-up on the ROS clock.
#[pyfunction]
fn cycle_sample_records(
    py: Python<'_>,
    joints: Vec<(String, JointScaling, Bound<'_, PyDict>)>,
    offset_ns: i64,
) -> PyResult<Vec<(i64, Py<PyBytes>)>> {
    let mut rows = Vec::new();
    let mut named = Vec::with_capacity(joints.len());
    for (k, (joint, units, columns)) in joints.iter().enumerate() {
        named.push((joint.as_str(), *units));
        rows.extend(samples_of(columns)?.into_iter().map(|s| (k, s)));
    }
    Ok(cycle_sample::encode_rows(rows, &named, offset_ns)
        .into_iter()
        .map(|(stamp_ns, data)| (stamp_ns, PyBytes::new(py, &data).unbind()))
        .collect())
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(cycle_sample_records, m)?)
}
