//! The Python face of the crate, the extension module `akd_ros._native`.
//!
//! Thin by design: it converts arguments, releases the GIL around anything that waits on the
//! bus, and turns [`Error`] into exceptions that carry the drive's own codes and names.

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::IntoPyObjectExt;

use crate::error::Error;

mod bag_writer;
mod clocks;
mod cycle;
mod device;
mod drive;
mod eeprom;
mod feed;
mod homing;
mod line_health;
mod link_spec;
mod master;
mod record;
mod sim;
mod trajectory;
mod units;

/// The exceptions, each named once: created, and added to the module by `add_exceptions`.
macro_rules! exceptions {
    ($($name:ident($base:ty, $doc:literal)),* $(,)?) => {
        $(create_exception!(_native, $name, $base, $doc);)*

        /// Adds every exception to the module by its name.
        fn add_exceptions(m: &Bound<'_, PyModule>) -> PyResult<()> {
            $(m.add(stringify!($name), m.py().get_type::<$name>())?;)*
            Ok(())
        }
    };
}

exceptions!(
    EtherCatError(PyException, "Base of every error raised by akd_ros._native."),
    FrameError(EtherCatError, "A malformed or unexpected EtherCAT frame."),
    LinkError(EtherCatError, "The operating system refused a link operation (socket, interface, permission)."),
    TimeoutError(EtherCatError, "No reply in time."),
    WorkingCounterError(
        EtherCatError,
        "A datagram's working counter was not the expected one; attributes expected, got."
    ),
    AlStateError(
        EtherCatError,
        "A slave refused a state change; attributes slave, requested, actual, code, code_name."
    ),
    SdoAbortError(EtherCatError, "An SDO transfer was aborted; attributes index, subindex, code, code_name."),
    MailboxError(EtherCatError, "A mailbox reply that does not fit the request or the protocol."),
    FoeError(
        MailboxError,
        "A file transfer over EtherCAT refused or failed; attributes name, code, code_name where the slave refused."
    ),
    SiiError(EtherCatError, "The SII EEPROM content or interface is not as expected."),
    PdoError(EtherCatError, "A process-data mapping the AKD would refuse, or an unknown one."),
    ConfigError(EtherCatError, "A configuration value out of its allowed range."),
);

/// Converts a crate error into the matching Python exception, with the codes as attributes.
pub(crate) fn to_py_err(error: Error) -> PyErr {
    let message = error.to_string();
    Python::with_gil(|py| {
        let err = match &error {
            Error::Frame(_) => FrameError::new_err(message),
            Error::Io { .. } => LinkError::new_err(message),
            Error::Timeout { .. } => TimeoutError::new_err(message),
            Error::WorkingCounter { .. } => WorkingCounterError::new_err(message),
            Error::AlState { .. } => AlStateError::new_err(message),
            Error::SdoAbort { .. } => SdoAbortError::new_err(message),
            Error::Mailbox(_) | Error::Eoe(_) => MailboxError::new_err(message),
            Error::Foe(_) => FoeError::new_err(message),
            Error::Sii(_) | Error::Replaced { .. } => SiiError::new_err(message),
            Error::Pdo(_) => PdoError::new_err(message),
            Error::LinkSpec(_)
            | Error::Setting(_)
            | Error::UnknownName(_)
            | Error::Unavailable(_)
            | Error::AliasNotUnique { .. }
            | Error::NoSuchSlave { .. }
            | Error::Trajectory(_)
            | Error::Command(_) => ConfigError::new_err(message),
        };
        let value = err.value(py);
        let set = |name: &str, v: PyResult<PyObject>| {
            // Setting an attribute on a fresh exception instance cannot fail.
            if let Ok(v) = v {
                let _ = value.setattr(name, v);
            }
        };
        match error {
            Error::WorkingCounter { expected, got, .. } => {
                set("expected", expected.into_py_any(py));
                set("got", got.into_py_any(py));
            }
            Error::AlState { slave, requested, actual, code, code_name } => {
                set("slave", slave.into_py_any(py));
                set("requested", requested.into_py_any(py));
                set("actual", actual.into_py_any(py));
                set("code", code.into_py_any(py));
                set("code_name", code_name.into_py_any(py));
            }
            Error::SdoAbort { index, subindex, code, code_name } => {
                set("index", index.into_py_any(py));
                set("subindex", subindex.into_py_any(py));
                set("code", code.into_py_any(py));
                set("code_name", code_name.into_py_any(py));
            }
            Error::Foe(crate::error::FoeError::Refused { name, code, code_name, .. }) => {
                set("name", name.into_py_any(py));
                set("code", code.into_py_any(py));
                set("code_name", code_name.into_py_any(py));
            }
            _ => {}
        }
        err
    })
}

/// A duration given from Python in seconds; a negative or non-finite one is a ConfigError
/// naming `what`.
pub(crate) fn seconds(value: f64, what: &'static str) -> PyResult<std::time::Duration> {
    seconds_allowing(value, what, "a finite number of seconds >= 0")
}

/// [`seconds`], the ConfigError saying that `allowed` is (where 0 means off).
pub(crate) fn seconds_allowing(
    seconds: f64,
    what: &'static str,
    allowed: &'static str,
) -> PyResult<std::time::Duration> {
    std::time::Duration::try_from_secs_f64(seconds)
        .map_err(|_| to_py_err(crate::error::SettingError::Duration { what, seconds, allowed }.into()))
}

/// Two derived dicts as one, the second's keys added to the first's. pyo3's derive has no
/// flattening, and some keys are one list for several results (a drive's identity in `scan` and
/// `parse_sii`, a trajectory's state in its status and its events).
pub(crate) struct Merged<A, B>(pub(crate) A, pub(crate) B);

impl<'py, A, B> IntoPyObject<'py> for Merged<A, B>
where
    A: IntoPyObject<'py, Target = pyo3::types::PyDict, Output = Bound<'py, pyo3::types::PyDict>>,
    B: IntoPyObject<'py, Target = pyo3::types::PyDict, Output = Bound<'py, pyo3::types::PyDict>>,
    PyErr: From<A::Error> + From<B::Error>,
{
    type Target = pyo3::types::PyDict;
    type Output = Bound<'py, pyo3::types::PyDict>;
    type Error = PyErr;

    fn into_pyobject(self, py: Python<'py>) -> PyResult<Self::Output> {
        let dict = self.0.into_pyobject(py)?;
        dict.update(self.1.into_pyobject(py)?.as_mapping())?;
        Ok(dict)
    }
}

/// Enums that reach Python as their `name()`, a str ("sync0").
macro_rules! named {
    ($($t:ty),*) => {$(
        impl<'py> IntoPyObject<'py> for $t {
            type Target = pyo3::types::PyString;
            type Output = Bound<'py, pyo3::types::PyString>;
            type Error = std::convert::Infallible;

            fn into_pyobject(self, py: Python<'py>) -> Result<Self::Output, Self::Error> {
                Ok(pyo3::types::PyString::new(py, self.name()))
            }
        }
    )*};
}

named!(crate::sim::pll::SyncSource, crate::cycle::events::FaultSource);

/// Extension trait: `.py()?` converts a crate result, or a codec's, into a Python one.
pub(crate) trait IntoPyResult<T> {
    fn py(self) -> PyResult<T>;
}

impl<T, E: Into<Error>> IntoPyResult<T> for std::result::Result<T, E> {
    fn py(self) -> PyResult<T> {
        self.map_err(|e| to_py_err(e.into()))
    }
}

/// `name` spelled as one word, as every name akd_ros gives from a device, a standard or a state
/// machine is ("Operation enabled" -> "operation_enabled", "SafeOp" -> "safe_op", a PDO entry's
/// "TxPDO-Map Channel 1" -> "tx_pdo_map_channel_1"): the crate's one rule,
/// [`crate::spelling::snake_case`].
#[pyfunction]
fn snake_case(name: &str) -> String {
    crate::spelling::snake_case(name)
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> pyo3::PyResult<()> {
    add_exceptions(m)?;
    master::register(m)?;
    sim::register(m)?;
    eeprom::register(m)?;
    cycle::register(m)?;
    drive::register(m)?;
    link_spec::register(m)?;
    clocks::register(m)?;
    record::register(m)?;
    bag_writer::register(m)?;
    feed::register(m)?;
    units::register(m)?;
    m.add_function(wrap_pyfunction!(snake_case, m)?)?;
    Ok(())
}
