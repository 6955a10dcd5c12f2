//! A device's channels for Python: each channel as a dict, its values as `bool` (a bit), `int`
//! or `float`, and the I/O of several devices from one snapshot (see
//! [`crate::ethercat::device`]).

use std::collections::BTreeMap;

use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyFloat, PyInt};

use super::IntoPyResult;
use crate::cycle::CycleThread;
use crate::ethercat::coe::data_type;
use crate::ethercat::device::{Channel, ChannelValue};
use crate::ethercat::pdo::Direction;

/// One channel as `Cycle.channels` gives it.
#[derive(IntoPyObject)]
pub(super) struct ChannelView {
    name: String,
    direction: &'static str,
    index: u16,
    subindex: u8,
    bits: u8,
    data_type: &'static str,
    pdo: u16,
}

impl From<&Channel> for ChannelView {
    fn from(c: &Channel) -> Self {
        ChannelView {
            name: c.name.clone(),
            direction: match c.direction {
                Direction::Rx => "output",
                Direction::Tx => "input",
            },
            index: c.entry.index,
            subindex: c.entry.subindex,
            bits: c.entry.bits,
            data_type: data_type::name(c.data_type),
            pdo: c.pdo,
        }
    }
}

/// A channel's value as Python holds it.
pub(super) struct PyChannelValue(pub(super) ChannelValue);

impl<'py> IntoPyObject<'py> for PyChannelValue {
    type Target = PyAny;
    type Output = Bound<'py, PyAny>;
    type Error = std::convert::Infallible;

    /// A bit is a bool, an integer an int, a real a float.
    fn into_pyobject(self, py: Python<'py>) -> Result<Bound<'py, PyAny>, Self::Error> {
        Ok(match self.0 {
            ChannelValue::Bit(b) => PyBool::new(py, b).to_owned().into_any(),
            ChannelValue::Integer(v) => v.into_pyobject(py)?.into_any(),
            ChannelValue::Real(v) => PyFloat::new(py, v).into_any(),
        })
    }
}

impl<'py> FromPyObject<'py> for PyChannelValue {
    /// A bool is a bit, an int an integer, a float a real; anything else is refused.
    fn extract_bound(value: &Bound<'py, PyAny>) -> PyResult<Self> {
        if let Ok(b) = value.downcast::<PyBool>() {
            return Ok(PyChannelValue(ChannelValue::Bit(b.is_true())));
        }
        if value.downcast::<PyInt>().is_ok() {
            let v: i64 =
                value.extract().map_err(|_| PyTypeError::new_err(format!("{value} is past a 64-bit integer")))?;
            return Ok(PyChannelValue(ChannelValue::Integer(v)));
        }
        if let Ok(f) = value.downcast::<PyFloat>() {
            return Ok(PyChannelValue(ChannelValue::Real(f.value())));
        }
        Err(PyTypeError::new_err(format!("a channel takes a bool, an int or a float, not {}", value.get_type())))
    }
}

/// The I/O of one device in one snapshot, as `Cycle.devices_io` gives it.
#[derive(IntoPyObject)]
pub(super) struct DeviceIoView {
    cycle: u64,
    time_ns: u64,
    fresh: bool,
    inputs: BTreeMap<String, PyChannelValue>,
    outputs: BTreeMap<String, PyChannelValue>,
}

/// The channels of the slave at `position`.
pub(super) fn channels(cycle: &CycleThread, position: u16) -> PyResult<Vec<ChannelView>> {
    Ok(cycle.channels(position).py()?.iter().map(ChannelView::from).collect())
}

/// The I/O of each slave at `positions`, all from the last snapshot: inputs as read, outputs as
/// sent, by channel name.
pub(super) fn devices_io(cycle: &CycleThread, positions: &[u16]) -> PyResult<Vec<DeviceIoView>> {
    let snapshot = cycle.snapshot();
    positions
        .iter()
        .map(|&p| {
            let channels = cycle.channels(p).py()?;
            let values = cycle.channel_values(&snapshot, p).py()?;
            let (mut inputs, mut outputs) = (BTreeMap::new(), BTreeMap::new());
            for (c, v) in channels.iter().zip(values) {
                let side = if c.direction == Direction::Tx { &mut inputs } else { &mut outputs };
                side.insert(c.name.clone(), PyChannelValue(v));
            }
            Ok(DeviceIoView {
                cycle: snapshot.cycle,
                time_ns: snapshot.time_ns,
                fresh: snapshot.fresh,
                inputs,
                outputs,
            })
        })
        .collect()
}
