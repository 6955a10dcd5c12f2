//! The drive's knowledge for Python, as the crate holds it, so that the package keeps no copy:
//! the modes of operation (`MODES_OF_OPERATION`), akd_ros's default mapping
//! (`DEFAULT_MAPPING`), the AKD's mapping rules (`check_mapping`) and entry syntax
//! (`parse_pdo_entry`), CoE data types (`data_type_name`, `data_type_kind`), an entry's access
//! bits by name (`access_names`), mapped objects' values as bytes (`encode_value`) and one
//! drive's inputs read by its mapping (`DriveInputs`, from `Cycle.drive_inputs`), the CiA
//! 402 states (`Ds402State`, every one in `DS402_STATES`), and the drive's own I/O: what a mapping carries
//! of it (`mapping_io`, `io_mappings`, `IO_MAPPING`), its layout (`IO_INPUT_COUNT`,
//! `IO_OUTPUT_COUNT`, `IO_SWITCHES`, `ANALOG_VOLTS_PER_COUNT`, `with_digital_outputs`) and one
//! drive's I/O in a cycle (`DriveIo`, from `Cycle.drives_io`).

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyTuple};

use super::IntoPyResult;
use crate::cycle::{CycleThread, Snapshot};
use crate::drive::ds402::{self, Mode, State};
use crate::drive::io::{self, Carried, DriveIo, Switch};
use crate::drive::objects::{self, DriveInputs};
use crate::drive::pdo::{self, Mapping};
use crate::ethercat::coe::{access, data_type};
use crate::ethercat::pdo::{Direction, PdoEntry};

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
            command: mode.command().map(ds402::CommandKind::name),
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
    let inputs = DriveInputs::read(tx, &cycle.inputs_of(snapshot, position).py()?);
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

/// One drive's I/O in one cycle (`Cycle.drives_io`), read by its mapping: a value is None where
/// the mapping lacks its object. Raw values in the drive's units (counts of the analog
/// objects, ±10 V over their range as `ANALOG_VOLTS_PER_COUNT` assumes), and what they say.
#[pyclass(name = "DriveIo", module = "akd_ros._native", frozen)]
#[derive(Clone, Copy)]
pub struct PyDriveIo {
    cycle: u64,
    time_ns: u64,
    fresh: bool,
    io: DriveIo,
}

#[pymethods]
impl PyDriveIo {
    /// The cycle they are from (from 1).
    #[getter]
    fn cycle(&self) -> u64 {
        self.cycle
    }

    /// That cycle's wake-up time on the monotonic clock (ns).
    #[getter]
    fn time_ns(&self) -> u64 {
        self.time_ns
    }

    /// Whether that cycle's exchange succeeded (else they are the last good ones).
    #[getter]
    fn fresh(&self) -> bool {
        self.fresh
    }

    /// Statusword 0x6041.
    #[getter]
    fn statusword(&self) -> Option<u16> {
        self.io.statusword
    }

    /// Digital inputs 0x60FD.
    #[getter]
    fn digital_inputs(&self) -> Option<u32> {
        self.io.digital_inputs
    }

    /// The switches of 0x60FD bits 0..3 by name ("negative_limit", "positive_limit",
    /// "home_switch", "interlock"): whether each is active; None without 0x60FD.
    #[getter]
    fn switches(&self) -> Option<Vec<(&'static str, bool)>> {
        self.io.digital_inputs.map(|word| Switch::ALL.iter().map(|s| (s.name(), s.active(word))).collect())
    }

    /// The levels of the AKD's digital inputs 1..7 (0x60FD bits 16..22); None without 0x60FD.
    #[getter]
    fn inputs(&self) -> Option<Vec<bool>> {
        self.io.input_levels()
    }

    /// The hardware enable as the statusword shows it: "high", "low" or "unknown".
    #[getter]
    fn hardware_enable(&self) -> &'static str {
        self.io.hardware_enable().name()
    }

    /// The analog input 0x3470:04, counts.
    #[getter]
    fn analog_input(&self) -> Option<i16> {
        self.io.analog_input
    }

    /// Digital outputs 0x60FE:01 as sent.
    #[getter]
    fn digital_outputs(&self) -> Option<u32> {
        self.io.digital_outputs
    }

    /// The levels of the AKD's digital outputs 1..2 as sent; None without 0x60FE:01.
    #[getter]
    fn outputs(&self) -> Option<Vec<bool>> {
        self.io.output_levels()
    }

    /// The analog output set-point 0x3470:03 as sent, counts.
    #[getter]
    fn analog_output(&self) -> Option<i16> {
        self.io.analog_output
    }

    /// These I/O with the digital inputs and statusword of another cycle (an "inputs" event of
    /// `Cycle.events`), where this drive's mapping carries them.
    fn with_inputs(&self, cycle: u64, time_ns: u64, digital_inputs: u32, statusword: u16) -> PyDriveIo {
        PyDriveIo { cycle, time_ns, fresh: true, io: self.io.with_inputs(digital_inputs, statusword) }
    }

    fn __repr__(&self) -> String {
        format!("DriveIo(cycle={}, {:?})", self.cycle, self.io)
    }
}

/// The I/O of each drive of `positions`, all from the same snapshot (for `Cycle.drives_io`).
pub(super) fn drives_io(cycle: &CycleThread, positions: &[u16]) -> PyResult<Vec<PyDriveIo>> {
    let snapshot = cycle.snapshot();
    positions
        .iter()
        .map(|&position| {
            let (rx, tx) = cycle.mapping(position).py()?;
            let outputs = cycle.outputs_of(&snapshot, position).py()?;
            let io = DriveIo::read(rx, tx, &outputs, &cycle.inputs_of(&snapshot, position).py()?);
            Ok(PyDriveIo { cycle: snapshot.cycle, time_ns: snapshot.time_ns, fresh: snapshot.fresh, io })
        })
        .collect()
}

/// What the mapping `rx`, `tx` (each as `Master.configure_pdo` takes it) carries of the drive's
/// I/O, as a dict of "digital_inputs", "analog_input", "digital_outputs", "analog_output";
/// raises PdoError as `check_mapping` does for a mapping the AKD refuses.
#[pyfunction]
fn mapping_io(rx: &Bound<'_, PyAny>, tx: &Bound<'_, PyAny>) -> PyResult<Carried> {
    let (rx, tx) = (super::master::parse_mapping(rx)?, super::master::parse_mapping(tx)?);
    Ok(Carried::of(&rx.entries(Direction::Rx).py()?, &tx.entries(Direction::Tx).py()?))
}

/// The mappings, as the node's `mapping` parameter names them ("io", "0x1725/0x1B20"), that
/// carry the command of mode `mode` (its name, e.g. "cyclic_synchronous_position") and each
/// of the I/O in `needs` (names as `mapping_io` gives them), those carrying all the I/O first:
/// a list of (name, what it carries as `mapping_io` gives it). ValueError for an unknown mode
/// or I/O name.
#[pyfunction]
fn io_mappings(mode: &str, needs: Vec<String>) -> PyResult<Vec<(String, Carried)>> {
    let mode = Mode::from_snake_name(mode).ok_or_else(|| PyValueError::new_err(format!("no mode {mode:?}")))?;
    let names = ["digital_inputs", "analog_input", "digital_outputs", "analog_output"];
    if let Some(bad) = needs.iter().find(|n| !names.contains(&n.as_str())) {
        return Err(PyValueError::new_err(format!("{bad:?} is none of {}", names.join(", "))));
    }
    let wanted = |c: Carried| {
        let has = [c.digital_inputs, c.analog_input, c.digital_outputs, c.analog_output];
        needs.iter().all(|n| has[names.iter().position(|m| m == n).unwrap_or_default()])
    };
    Ok(io::mappings_for(mode, wanted).into_iter().map(|m| (m.name, m.carried)).collect())
}

/// The mappings `io_mappings` finds for mode `mode` and the one I/O `needs`, in words for a
/// refusal: their names, or a flexible mapping where none has it.
#[pyfunction]
fn io_mappings_in_words(mode: &str, needs: &str) -> PyResult<String> {
    let mode = Mode::from_snake_name(mode).ok_or_else(|| PyValueError::new_err(format!("no mode {mode:?}")))?;
    let names = ["digital_inputs", "analog_input", "digital_outputs", "analog_output"];
    let Some(k) = names.iter().position(|n| *n == needs) else {
        return Err(PyValueError::new_err(format!("{needs:?} is none of {}", names.join(", "))));
    };
    Ok(io::mappings_in_words(mode, |c| [c.digital_inputs, c.analog_input, c.digital_outputs, c.analog_output][k]))
}

/// Checks `rx` and `tx` (each as `Master.configure_pdo` takes it) against the AKD's mapping
/// rules without a drive; raises PdoError saying what is wrong and what is allowed, as
/// configuring a drive with them would.
#[pyfunction]
fn check_mapping(rx: &Bound<'_, PyAny>, tx: &Bound<'_, PyAny>) -> PyResult<()> {
    let (rx, tx) = (super::master::parse_mapping(rx)?, super::master::parse_mapping(tx)?);
    Mapping::process_data(&rx, &tx).py().map(drop)
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
#[pymethods]
impl State {
    /// The state `statusword` shows, None for one that shows none.
    #[staticmethod]
    #[pyo3(name = "from_statusword")]
    fn py_from_statusword(statusword: u16) -> Option<State> {
        State::from_statusword(statusword)
    }

    /// What a message says of `state`: its `snake_name`, "unknown" for None.
    #[staticmethod]
    #[pyo3(name = "message_name", signature = (state))]
    fn py_message_name(state: Option<State>) -> String {
        State::message_name(state)
    }

    /// The state's name as one word, as the messages spell it: "operation_enabled".
    #[getter(snake_name)]
    fn py_snake_name(&self) -> String {
        self.snake_name()
    }

    /// Whether the drive shows a fault (Fault, Fault reaction active).
    #[getter(is_fault)]
    fn py_is_fault(&self) -> bool {
        self.is_fault()
    }

    /// The state's name as CiA 402 writes it: "Operation enabled".
    fn __str__(&self) -> &'static str {
        self.name()
    }
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
    m.add("IO_MAPPING", (as_words(&pdo::IO_RX), as_words(&pdo::IO_TX)))?;
    m.add_class::<PyDriveIo>()?;
    m.add_function(wrap_pyfunction!(mapping_io, m)?)?;
    m.add_function(wrap_pyfunction!(io_mappings, m)?)?;
    m.add_function(wrap_pyfunction!(io_mappings_in_words, m)?)?;
    m.add("IO_INPUT_COUNT", io::INPUT_COUNT)?;
    m.add("IO_OUTPUT_COUNT", io::OUTPUT_COUNT)?;
    m.add("IO_SWITCHES", PyTuple::new(m.py(), Switch::ALL.iter().map(|s| s.name()))?)?;
    m.add("ANALOG_VOLTS_PER_COUNT", io::ANALOG_VOLTS_PER_COUNT)?;
    m.add_function(wrap_pyfunction!(check_mapping, m)?)?;
    m.add_function(wrap_pyfunction!(parse_pdo_entry, m)?)?;
    m.add_function(wrap_pyfunction!(data_type_name, m)?)?;
    m.add_function(wrap_pyfunction!(data_type_kind, m)?)?;
    m.add_function(wrap_pyfunction!(access_names, m)?)?;
    m.add_function(wrap_pyfunction!(encode_value, m)?)?;
    m.add_class::<State>()?;
    m.add("DS402_STATES", PyTuple::new(m.py(), State::ALL)?)?;
    Ok(())
}
