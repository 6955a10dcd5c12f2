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

/// The rows of `columns` (`Cycle.samples`' columns of one drive; none at all for no rows) as Samples.
fn samples_of(columns: &Bound<'_, PyDict>) -> PyResult<Vec<Sample>> {
    if columns.is_empty() {
        return Ok(Vec::new());
    }
    let cycle: Vec<u64> = column(columns, "cycle")?;
    let time_ns: Vec<u64> = column(columns, "time_ns")?;
    let period_ns: Vec<u32> = column(columns, "period_ns")?;
    let exchange_ns: Vec<u32> = column(columns, "exchange_ns")?;
    let wkc: Vec<u16> = column(columns, "wkc")?;
    let statusword: Vec<u16> = column(columns, "statusword")?;
    let mode: Vec<i8> = column(columns, "mode")?;
    let position: Vec<i32> = column(columns, "position")?;
    let velocity: Vec<i32> = column(columns, "velocity")?;
    let torque: Vec<i16> = column(columns, "torque")?;
    let following_error: Vec<i32> = column(columns, "following_error")?;
    let target_position: Vec<i32> = column(columns, "target_position")?;
    let target_velocity: Vec<i32> = column(columns, "target_velocity")?;
    let target_torque: Vec<i16> = column(columns, "target_torque")?;
    let rows = cycle.len();
    let lengths = [
        time_ns.len(),
        period_ns.len(),
        exchange_ns.len(),
        wkc.len(),
        statusword.len(),
        mode.len(),
        position.len(),
        velocity.len(),
        torque.len(),
        following_error.len(),
        target_position.len(),
        target_velocity.len(),
        target_torque.len(),
    ];
    if lengths.iter().any(|&n| n != rows) {
        return Err(PyValueError::new_err("per-cycle records whose columns differ in length"));
    }
    Ok((0..rows)
        .map(|i| Sample {
            cycle: cycle[i],
            time_ns: time_ns[i],
            period_ns: period_ns[i],
            exchange_ns: exchange_ns[i],
            wkc: wkc[i],
            statusword: statusword[i],
            mode: mode[i],
            position: position[i],
            velocity: velocity[i],
            torque: torque[i],
            following_error: following_error[i],
            target_position: target_position[i],
            target_velocity: target_velocity[i],
            target_torque: target_torque[i],
            ..Sample::default()
        })
        .collect())
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
