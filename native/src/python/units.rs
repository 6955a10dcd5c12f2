//! `akd_ros._native.Units`, a joint's scale ([`JointScaling`]), made and converted from Python, and
//! `PositionUnwrap`, its position read across the 32-bit wrap ([`PositionUnwrap`]).

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyFloat, PyInt};

use crate::drive::scaling::{self, JointScaling, PositionScaling, PositionUnwrap, ScalingError};

/// `error` about `value` (given as Python gave it) in Python's words.
fn refused(error: ScalingError, value: &Bound<'_, PyAny>) -> PyErr {
    let text = error.to_string();
    let head = text.split(", got ").next().unwrap_or(&text);
    let repr = value.repr().map_or_else(|_| "?".to_owned(), |r| r.to_string());
    PyValueError::new_err(format!("{head}, got {repr}"))
}

/// `value` as a real number (NaN for anything else, which the scaling then refuses).
fn real(value: &Bound<'_, PyAny>) -> f64 {
    let number =
        !value.is_instance_of::<PyBool>() && (value.is_instance_of::<PyInt>() || value.is_instance_of::<PyFloat>());
    if number {
        value.extract().unwrap_or(f64::NAN)
    } else {
        f64::NAN
    }
}

impl From<ScalingError> for PyErr {
    fn from(error: ScalingError) -> PyErr {
        PyValueError::new_err(error.to_string())
    }
}

#[pymethods]
impl JointScaling {
    #[new]
    #[allow(clippy::too_many_arguments)] // the mechanics' seven keywords, as Python names them
    #[pyo3(signature = (counts_per_revolution = None, gear_ratio = None, direction = None, offset = None, axis = None, lead = None, peak_torque = None))]
    fn py_new(
        py: Python<'_>,
        counts_per_revolution: Option<Bound<'_, PyAny>>,
        gear_ratio: Option<Bound<'_, PyAny>>,
        direction: Option<Bound<'_, PyAny>>,
        offset: Option<Bound<'_, PyAny>>,
        axis: Option<Bound<'_, PyAny>>,
        lead: Option<Bound<'_, PyAny>>,
        peak_torque: Option<Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let default = JointScaling::default();
        let float = |x: f64| PyFloat::new(py, x).into_any();
        let cpr = counts_per_revolution.unwrap_or(default.counts_per_revolution.into_pyobject(py)?.into_any());
        let gear = gear_ratio.unwrap_or(float(default.gear_ratio));
        let direction = direction.unwrap_or(1i8.into_pyobject(py)?.into_any());
        let offset = offset.unwrap_or(float(default.offset));
        let axis = axis.unwrap_or("rotary".into_pyobject(py)?.into_any());
        let peak = peak_torque.unwrap_or(float(default.peak_torque));
        let counts = match cpr.is_instance_of::<PyBool>() {
            true => 0,
            false => cpr.extract::<u64>().unwrap_or(0),
        };
        let sense = match real(&direction) {
            d if d == 1.0 && !direction.is_instance_of::<PyBool>() => 1,
            -1.0 => -1,
            _ => 0,
        };
        let linear = match axis.extract::<String>().as_deref() {
            Ok("rotary") => false,
            Ok("linear") => true,
            _ => return Err(PyValueError::new_err(format!("axis must be 'rotary' or 'linear', got {}", axis.repr()?))),
        };
        let lead_value = lead.as_ref().map(real);
        JointScaling::new(counts, real(&gear), sense, real(&offset), (linear, lead_value), real(&peak)).map_err(|e| {
            let given = match &e {
                ScalingError::CountsPerRevolution => &cpr,
                ScalingError::Direction => &direction,
                ScalingError::NotFinite { name: "gear_ratio", .. } => &gear,
                ScalingError::NotFinite { name: "offset", .. } => &offset,
                ScalingError::NotFinite { name: "peak_torque", .. } => &peak,
                ScalingError::NoLead => return PyValueError::new_err(e.to_string()),
                _ => lead.as_ref().unwrap_or(&axis),
            };
            refused(e, given)
        })
    }

    /// "rotary" (rad, rad/s, N·m) or "linear" (m, m/s, N).
    #[getter]
    fn axis(&self) -> &'static str {
        if self.lead.is_some() {
            "linear"
        } else {
            "rotary"
        }
    }

    /// The SI unit of positions: "rad" or "m".
    #[getter(position_unit)]
    fn py_position_unit(&self) -> &'static str {
        self.position_unit().name()
    }

    /// Load travel (rad or m, signed by `direction`) per motor count.
    #[getter(si_per_count)]
    fn py_si_per_count(&self) -> f64 {
        self.si_per_count()
    }

    /// Load torque (N·m) or force (N), signed by `direction`, per drive torque unit (0.1 % of peak).
    #[getter(si_per_torque_unit)]
    fn py_si_per_torque_unit(&self) -> f64 {
        self.si_per_torque_unit()
    }

    /// The load position (rad or m) at motor position `counts` (raw int32 or an unwrapped count).
    #[pyo3(name = "position_to_si")]
    fn py_position_to_si(&self, counts: f64) -> f64 {
        self.position_to_si(counts)
    }

    /// The int32 target position (0x607A) for the load position `position` (rad or m).
    #[pyo3(name = "position_to_counts")]
    fn py_position_to_counts(&self, position: f64) -> PyResult<i32> {
        Ok(self.position_to_counts(position)?)
    }

    /// The load velocity (rad/s or m/s) at motor velocity `counts_per_second` (0x606C).
    #[pyo3(name = "velocity_to_si")]
    fn py_velocity_to_si(&self, counts_per_second: f64) -> f64 {
        self.velocity_to_si(counts_per_second)
    }

    /// The int32 target velocity (0x60FF, counts per second) for the load velocity `velocity`.
    #[pyo3(name = "velocity_to_counts")]
    fn py_velocity_to_counts(&self, velocity: f64) -> PyResult<i32> {
        Ok(self.velocity_to_counts(velocity)?)
    }

    /// Motor counts/s² for the load acceleration `acceleration` (rad/s² or m/s²).
    #[pyo3(name = "acceleration_to_counts")]
    fn py_acceleration_to_counts(&self, acceleration: f64) -> PyResult<f64> {
        Ok(self.acceleration_to_counts(acceleration)?)
    }

    /// The load torque (N·m) or force (N) for the drive torque `value` (0x6077, 0.1 % of peak).
    #[pyo3(name = "torque_to_si")]
    fn py_torque_to_si(&self, value: f64) -> f64 {
        self.torque_to_si(value)
    }

    /// The int16 target torque (0x6071, 0.1 % of peak) for the load torque (N·m) or force (N).
    #[pyo3(name = "torque_to_drive")]
    fn py_torque_to_drive(&self, torque: f64) -> PyResult<i16> {
        Ok(self.torque_to_drive(torque)?)
    }

    /// Where the drive counts the position objects its mapping carries (`mapped`, (index,
    /// subindex) pairs) in another scale than `counts_per_revolution`, one sentence saying which,
    /// by how much, from which of its objects, and what to change; None where they agree or the
    /// drive does not tell (`scaling` is `Master.position_scaling`'s, None for a drive without
    /// the DS402 scaling objects).
    #[pyo3(signature = (scaling, mapped))]
    fn scale_mismatch(&self, scaling: Option<PositionScaling>, mapped: Vec<(u16, u8)>) -> Option<String> {
        scaling?.mismatch(self.counts_per_revolution, |index, sub| mapped.contains(&(index, sub)))
    }

    fn __hash__(&self) -> u64 {
        let bits = [self.gear_ratio, self.offset, self.lead.unwrap_or(-1.0), self.peak_torque].map(f64::to_bits);
        bits.iter().fold(self.counts_per_revolution ^ self.direction as u64, |h, b| h.rotate_left(13) ^ b)
    }

    fn __repr__(&self) -> String {
        let lead = self.lead.map_or("None".to_owned(), scaling::py_repr);
        format!(
            "Units(counts_per_revolution={}, gear_ratio={}, direction={}, offset={}, axis='{}', lead={lead}, \
             peak_torque={})",
            self.counts_per_revolution,
            scaling::py_repr(self.gear_ratio),
            self.direction,
            scaling::py_repr(self.offset),
            self.axis(),
            scaling::py_repr(self.peak_torque)
        )
    }
}

/// One reader's view of a joint's position across the drive's 32-bit wrap: `next(raw)` gives
/// the continuous count of each reading (`unwrap_position` from the last), the first as it is.
/// The node's feed keeps one per joint for /joint_states, an `Axis` one for its states.
#[pyclass(name = "PositionUnwrap", module = "akd_ros._native")]
#[derive(Default)]
pub struct PyPositionUnwrap {
    unwrap: PositionUnwrap,
}

/// `raw` as an int32, or ValueError naming the range.
fn int32(raw: &Bound<'_, PyAny>) -> PyResult<i32> {
    match raw.is_instance_of::<PyInt>() && !raw.is_instance_of::<PyBool>() {
        true => raw.extract::<i32>().ok(),
        false => None,
    }
    .ok_or_else(|| {
        let repr = raw.repr().map_or_else(|_| "?".to_owned(), |r| r.to_string());
        PyValueError::new_err(format!("raw position must be an int32, in [{}, {}], got {repr}", i32::MIN, i32::MAX))
    })
}

#[pymethods]
impl PyPositionUnwrap {
    #[new]
    fn new() -> Self {
        Self::default()
    }

    /// The continuous count of the int32 reading `raw`.
    fn next(&mut self, raw: &Bound<'_, PyAny>) -> PyResult<i64> {
        Ok(self.unwrap.next(int32(raw)?))
    }
}

/// The continuous count nearest `previous` that reads as the int32 `raw` on the drive: fed each
/// raw reading with the last result, the count stays continuous while the axis moves less than
/// 2**31 counts between readings. Start with `previous = raw`.
#[pyfunction]
fn unwrap_position(previous: i64, raw: &Bound<'_, PyAny>) -> PyResult<i64> {
    Ok(scaling::unwrap_position(previous, int32(raw)?))
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<JointScaling>()?;
    m.add_class::<PyPositionUnwrap>()?;
    m.add_function(wrap_pyfunction!(unwrap_position, m)?)
}
