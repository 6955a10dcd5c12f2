//! The drive's knowledge for Python, as the crate holds it, so that the package keeps no copy:
//! the modes of operation (`MODES_OF_OPERATION`), akd_ros's default mapping
//! (`DEFAULT_MAPPING`), the AKD's mapping rules (`check_mapping`) and entry syntax
//! (`parse_pdo_entry`), CoE data types (`data_type_name`, `data_type_kind`), an entry's access
//! bits by name (`access_names`), mapped objects' values as bytes (`encode_value`) and one
//! drive's inputs read by its mapping (`DriveInputs`, from `Cycle.drive_inputs`), and the CiA
//! 402 states (`DS402_STATES`, `ds402_state`).

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyTuple};

use super::IntoPyResult;
use crate::coe::{access, data_type};
use crate::cycle::{CycleThread, Snapshot};
use crate::ds402::{self, Mode, State};
use crate::objects::{self, DriveInputs};
use crate::pdo::{self, Direction, PdoEntry};

/// One mode of operation of the AKD (0x6060), as `MODES_OF_OPERATION` lists them.
#[pyclass(name = "ModeOfOperation", module = "akd_ros._native", frozen, get_all)]
pub struct PyModeOfOperation {
    /// The mode's name as one word, e.g. "profile_position".
    name: String,
    /// Its value in 0x6060 and 0x6061.
    code: i8,
    /// What its command sets: "position", "velocity", "torque", or None (homing).
    command: Option<&'static str>,
    /// The objects (index, subindex) its command is written to, in the order tried: the first
    /// the output mapping carries; a mode with a handshake writes the first by SDO where none
    /// is mapped, the others need one mapped.
    command_objects: Vec<(u16, u8)>,
    /// The controlword bits whose rising edge starts a command (profile position, homing), for
    /// `Cycle.start_setpoint`; None for a mode that follows its command every cycle.
    handshake_controlword: Option<u16>,
}

impl PyModeOfOperation {
    fn of(mode: Mode) -> Self {
        PyModeOfOperation {
            name: mode.snake_name(),
            code: mode as i8,
            command: mode.command().map(ds402::Command::name),
            command_objects: mode.command_objects().to_vec(),
            handshake_controlword: mode.handshake_controlword(),
        }
    }
}

#[pymethods]
impl PyModeOfOperation {
    fn __repr__(&self) -> String {
        format!("ModeOfOperation({:?}, code={})", self.name, self.code)
    }
}

/// One drive's inputs in one cycle, read by its mapping with each object's data type; a value
/// is None where the mapping lacks its object.
#[pyclass(name = "DriveInputs", module = "akd_ros._native", frozen, get_all)]
pub struct PyDriveInputs {
    /// The cycle they are from (from 1).
    cycle: u64,
    /// That cycle's wake-up time on the monotonic clock (ns).
    time_ns: u64,
    /// Whether that cycle's exchange succeeded (else they are the last good ones).
    fresh: bool,
    /// Statusword 0x6041.
    statusword: Option<u16>,
    /// Modes of operation display 0x6061.
    mode_display: Option<i8>,
    /// Position actual value 0x6064, else the internal value 0x6063, in counts.
    position_actual: Option<i32>,
    /// Velocity actual value 0x606C, counts/s.
    velocity_actual: Option<i32>,
    /// Torque actual value 0x6077, 0.1 % of peak torque.
    torque_actual: Option<i16>,
    /// Following error actual value 0x60F4, counts.
    following_error: Option<i32>,
    /// Digital inputs 0x60FD.
    digital_inputs: Option<u32>,
}

#[pymethods]
impl PyDriveInputs {
    fn __repr__(&self) -> String {
        format!(
            "DriveInputs(cycle={}, statusword={:?}, position_actual={:?})",
            self.cycle, self.statusword, self.position_actual
        )
    }
}

/// Drive `position`'s inputs in `cycle`'s last snapshot (for `Cycle.drive_inputs`).
pub(super) fn drive_inputs(cycle: &CycleThread, position: u16) -> PyResult<PyDriveInputs> {
    inputs_in(cycle, &cycle.snapshot(), position)
}

/// The inputs of each drive of `positions`, all from the same snapshot: one cycle's values of
/// the whole bus (for `Cycle.drives_inputs`).
pub(super) fn drives_inputs(cycle: &CycleThread, positions: &[u16]) -> PyResult<Vec<PyDriveInputs>> {
    let snapshot = cycle.snapshot();
    positions.iter().map(|&position| inputs_in(cycle, &snapshot, position)).collect()
}

fn inputs_in(cycle: &CycleThread, snapshot: &Snapshot, position: u16) -> PyResult<PyDriveInputs> {
    let (_, tx) = cycle.mapping(position).py()?;
    let inputs = DriveInputs::read(tx, cycle.inputs_of(snapshot, position).py()?);
    Ok(PyDriveInputs {
        cycle: snapshot.cycle,
        time_ns: snapshot.time_ns,
        fresh: snapshot.fresh,
        statusword: inputs.statusword,
        mode_display: inputs.mode_display,
        position_actual: inputs.position_actual,
        velocity_actual: inputs.velocity_actual,
        torque_actual: inputs.torque_actual,
        following_error: inputs.following_error,
        digital_inputs: inputs.digital_inputs,
    })
}

/// Checks `rx` and `tx` (each as `Master.configure_pdo` takes it) against the AKD's mapping
/// rules without a drive; raises PdoError saying what is wrong and what is allowed, as
/// configuring a drive with them would.
#[pyfunction]
fn check_mapping(rx: &Bound<'_, PyAny>, tx: &Bound<'_, PyAny>) -> PyResult<()> {
    let (rx, tx) = (super::master::parse_mapping(rx)?, super::master::parse_mapping(tx)?);
    rx.entries(Direction::Rx).py()?;
    tx.entries(Direction::Tx).py()?;
    Ok(())
}

/// The mapping entry 0xIIIISSBB written as `INDEX:SUB/BITS` (hex index and subindex, decimal
/// bits, e.g. "0x6040:00/16"); raises ValueError naming the syntax.
#[pyfunction]
fn parse_pdo_entry(text: &str) -> PyResult<u32> {
    PdoEntry::parse(text).map(PdoEntry::to_u32).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// The name of CoE data type `code`, e.g. "UNSIGNED16" ("unknown data type" for another code).
#[pyfunction]
fn data_type_name(code: u16) -> &'static str {
    data_type::name(code)
}

/// How values of CoE data type `code` read: "signed_integer", "unsigned_integer", "real",
/// "visible_string" or "other".
#[pyfunction]
fn data_type_kind(code: u16) -> &'static str {
    data_type::kind(code).name()
}

/// The names of the access bits `bits` of an entry description holds
/// (`Master.sdo_entry_description`'s "access"), in bit order: "read_preop", "read_safeop",
/// "read_op", "write_preop", "write_safeop", "write_op", "rx_pdo", "tx_pdo".
#[pyfunction]
fn access_names(bits: u16) -> Vec<&'static str> {
    access::names(bits).collect()
}

/// `value` as the bytes of mappable object `index:subindex` (e.g. a set-point for
/// `Cycle.set_object`): little-endian in its data type's length; raises ValueError for a value
/// outside the type's range or an object the AKD does not map.
#[pyfunction]
fn encode_value<'py>(py: Python<'py>, index: u16, subindex: u8, value: i64) -> PyResult<Bound<'py, PyBytes>> {
    let bytes = objects::encode(index, subindex, value).map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(PyBytes::new(py, &bytes))
}

/// The name of the CiA 402 state `statusword` shows (one of `DS402_STATES`), None for none.
#[pyfunction]
fn ds402_state(statusword: u16) -> Option<&'static str> {
    State::from_statusword(statusword).map(State::name)
}

/// The flexible PDOs of a mapping as `Master.configure_pdo` takes them: lists of 0xIIIISSBB.
fn as_words(pdos: &[&[PdoEntry]]) -> Vec<Vec<u32>> {
    pdos.iter().map(|p| p.iter().map(|e| e.to_u32()).collect()).collect()
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyModeOfOperation>()?;
    m.add_class::<PyDriveInputs>()?;
    let modes: Vec<PyModeOfOperation> = Mode::ALL.into_iter().map(PyModeOfOperation::of).collect();
    m.add("MODES_OF_OPERATION", PyTuple::new(m.py(), modes)?)?;
    let not_offered: std::collections::HashMap<&str, &str> =
        ds402::NOT_OFFERED.iter().map(|&(_, name, why)| (name, why)).collect();
    m.add("MODES_NOT_OFFERED", not_offered)?;
    m.add("DEFAULT_MAPPING", (as_words(&pdo::DEFAULT_RX), as_words(&pdo::DEFAULT_TX)))?;
    m.add_function(wrap_pyfunction!(check_mapping, m)?)?;
    m.add_function(wrap_pyfunction!(parse_pdo_entry, m)?)?;
    m.add_function(wrap_pyfunction!(data_type_name, m)?)?;
    m.add_function(wrap_pyfunction!(data_type_kind, m)?)?;
    m.add_function(wrap_pyfunction!(access_names, m)?)?;
    m.add_function(wrap_pyfunction!(encode_value, m)?)?;
    m.add_function(wrap_pyfunction!(ds402_state, m)?)?;
    m.add("DS402_STATES", PyTuple::new(m.py(), State::ALL.map(State::name))?)?;
    Ok(())
}
