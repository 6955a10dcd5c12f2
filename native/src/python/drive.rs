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
use crate::drive::ds402::{self, Mode, State};
use crate::drive::io::{self, Carried, DriveIo, Switch};
use crate::drive::objects::{self, DriveInputs};
use crate::drive::pdo::{self, Mapping};
use crate::ethercat::coe::{access, data_type};
use crate::ethercat::pdo::{Direction, PdoEntry};

#[pymethods]
impl Mode {
    /// The mode's name as one word, e.g. "profile_position".
    #[getter(name)]
    fn py_name(&self) -> String {
        self.snake_name()
    }

    /// Its value in 0x6060 and 0x6061.
    #[getter]
    fn code(&self) -> i8 {
        *self as i8
    }

    /// What its command sets: "position", "velocity", "torque", or None (homing).
    #[getter(command)]
    fn py_command(&self) -> Option<&'static str> {
        self.command().map(ds402::CommandKind::name)
    }

    /// The objects (index, subindex) its command is written to, in the order tried: the first
    /// the output mapping carries; a mode with a handshake writes the first by SDO where none
    /// is mapped, the others need one mapped.
    #[getter(command_objects)]
    fn py_command_objects(&self) -> &'static [(u16, u8)] {
        self.command_objects()
    }

    /// The controlword bits whose rising edge starts a command (profile position, homing), for
    /// `Cycle.start_setpoint`; None for a mode that follows its command every cycle.
    #[getter(handshake_controlword)]
    fn py_handshake_controlword(&self) -> Option<u16> {
        self.handshake_controlword()
    }

    fn __repr__(&self) -> String {
        format!("ModeOfOperation({:?}, code={})", self.snake_name(), *self as i8)
    }
}

#[pymethods]
impl DriveInputs {
    fn __repr__(&self) -> String {
        format!(
            "DriveInputs(cycle={}, statusword={:?}, position_actual={:?})",
            self.cycle, self.statusword, self.position_actual
        )
    }
}

#[pymethods]
impl DriveIo {
    /// The switches of 0x60FD bits 0..3 by name ("negative_limit", "positive_limit",
    /// "home_switch", "interlock"): whether each is active; None without 0x60FD.
    #[getter]
    fn switches(&self) -> Option<Vec<(&'static str, bool)>> {
        self.digital_inputs.map(|word| Switch::ALL.iter().map(|s| (s.name(), s.active(word))).collect())
    }

    /// The levels of the AKD's digital inputs 1..7 (0x60FD bits 16..22); None without 0x60FD.
    #[getter]
    fn inputs(&self) -> Option<Vec<bool>> {
        self.input_levels()
    }

    /// The hardware enable as the statusword shows it: "high", "low" or "unknown".
    #[getter(hardware_enable)]
    fn py_hardware_enable(&self) -> &'static str {
        self.hardware_enable().name()
    }

    /// The levels of the AKD's digital outputs 1..2 as sent; None without 0x60FE:01.
    #[getter]
    fn outputs(&self) -> Option<Vec<bool>> {
        self.output_levels()
    }

    /// These I/O with the digital inputs and statusword of another cycle (an "inputs" event of
    /// `Cycle.events`), where this drive's mapping carries them.
    #[pyo3(name = "with_inputs")]
    fn py_with_inputs(&self, cycle: u64, time_ns: u64, digital_inputs: u32, statusword: u16) -> DriveIo {
        self.with_inputs(cycle, time_ns, digital_inputs, statusword)
    }

    fn __repr__(&self) -> String {
        format!("{self:?}")
    }
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

/// Whether `index` is a PDO mapping object (CiA 301: RxPDO 0x1600-0x17FF, TxPDO 0x1A00-0x1BFF).
#[pyfunction]
fn is_pdo_mapping(index: u16) -> bool {
    crate::ethercat::pdo::is_mapping_object(index)
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Mode>()?;
    m.add_class::<DriveInputs>()?;
    m.add("MODES_OF_OPERATION", PyTuple::new(m.py(), Mode::ALL)?)?;
    let not_offered: std::collections::HashMap<&str, &str> =
        ds402::NOT_OFFERED.iter().map(|&(_, name, why)| (name, why)).collect();
    m.add("MODES_NOT_OFFERED", not_offered)?;
    m.add("DEFAULT_MAPPING", (as_words(&pdo::DEFAULT_RX), as_words(&pdo::DEFAULT_TX)))?;
    m.add("IO_MAPPING", (as_words(&pdo::IO_RX), as_words(&pdo::IO_TX)))?;
    m.add_class::<DriveIo>()?;
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
    m.add_function(wrap_pyfunction!(is_pdo_mapping, m)?)?;
    m.add("PDO_ASSIGNMENTS", (Direction::Rx.assignment_index(), Direction::Tx.assignment_index()))?;
    m.add("OBJECTS_WRITTEN_WHOLE", PyTuple::new(m.py(), crate::drive::sync::WRITTEN_WHOLE)?)?;
    m.add_class::<State>()?;
    m.add("DS402_STATES", PyTuple::new(m.py(), State::ALL)?)?;
    Ok(())
}
