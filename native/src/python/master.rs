//! `akd_ros._native.Master`: the EtherCAT master for Python.
//!
//! Every call that waits on the bus releases the GIL. The master is taken with `try_lock` for
//! the call, so a second thread using the same master at once gets an error instead of waiting
//! on a lock it cannot see.

use std::sync::{Mutex, MutexGuard, TryLockError};

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};

use super::IntoPyResult;
use crate::al::AlState;
use crate::error::{Error, SettingError, Unavailable, UnknownName};
use crate::link::{self, Link, LinkSpec};
use crate::master::{self, Mapping};
use crate::pdo::PdoEntry;
use crate::sim::control::SimControl;
use crate::sim::in_process::InProcess;

/// Opens the link named by `spec` (a [`LinkSpec`]), with the handle that controls its virtual
/// AKDs for the in-process links.
fn open_link(spec: &str) -> crate::error::Result<(Box<dyn Link>, Option<SimControl>)> {
    Ok(match spec.parse::<LinkSpec>()? {
        LinkSpec::Sim { count } => {
            let link = InProcess::new(count);
            let control = link.control();
            (Box::new(link), Some(control))
        }
        LinkSpec::Udp { address } => (Box::new(link::udp::Udp::connect(&address)?), None),
        LinkSpec::Interface { name } => (Box::new(link::raw::RawLink::open(&name)?), None),
    })
}

fn parse_state(name: &str) -> crate::error::Result<AlState> {
    AlState::parse(name).ok_or_else(|| UnknownName::AlState { name: name.to_owned() }.into())
}

/// A mapping given from Python: a fixed mapping's index, or a list of PDOs, each a list of
/// entries 0xIIIISSBB.
pub(super) fn parse_mapping(value: &Bound<'_, PyAny>) -> PyResult<Mapping> {
    if let Ok(index) = value.extract::<u16>() {
        return Ok(Mapping::Fixed(index));
    }
    let pdos: Vec<Vec<u32>> =
        value.extract().map_err(|_| Error::from(SettingError::MappingForm)).map_err(super::to_py_err)?;
    Ok(Mapping::Flexible(pdos.into_iter().map(|p| p.into_iter().map(PdoEntry::from_u32).collect()).collect()))
}

/// An EtherCAT master on one link.
#[pyclass(name = "Master", module = "akd_ros._native")]
pub struct PyMaster {
    master: Mutex<Option<master::Master>>,
    /// The in-process link's virtual AKDs, apart from the master so that a Cycle holding it
    /// does not hold them.
    simulator: Option<SimControl>,
}

/// The master while one call uses it.
struct InUse<'a>(MutexGuard<'a, Option<master::Master>>);

impl InUse<'_> {
    fn get(&mut self) -> PyResult<&mut master::Master> {
        self.0.as_mut().ok_or_else(|| super::to_py_err(Unavailable::MasterClosed.into()))
    }
}

impl PyMaster {
    fn lock(&self) -> PyResult<InUse<'_>> {
        match self.master.try_lock() {
            Ok(guard) => Ok(InUse(guard)),
            // A call that panicked left the master as it was; the panic was already raised.
            Err(TryLockError::Poisoned(poisoned)) => Ok(InUse(poisoned.into_inner())),
            Err(TryLockError::WouldBlock) => Err(super::to_py_err(Unavailable::MasterBusy.into())),
        }
    }
}

#[pymethods]
impl PyMaster {
    /// Opens `link`: "sim" (one in-process virtual AKD), "sim:N", "udp://HOST:PORT", or a
    /// network interface name. `pcap` records every frame to a pcapng file; `timeout` is how
    /// long each frame may take to come back, in seconds.
    #[new]
    #[pyo3(signature = (link, *, pcap = None, timeout = 0.1))]
    fn new(py: Python<'_>, link: &str, pcap: Option<&str>, timeout: f64) -> PyResult<Self> {
        let timeout = super::seconds(timeout, "timeout")?;
        let (master, simulator) = py
            .allow_threads(|| -> crate::error::Result<(master::Master, Option<SimControl>)> {
                let (inner, simulator) = open_link(link)?;
                let inner: Box<dyn Link> = match pcap {
                    Some(path) => Box::new(link::pcap::Recorder::new(inner, path)?),
                    None => inner,
                };
                Ok((master::Master::new(inner, timeout), simulator))
            })
            .py()?;
        Ok(PyMaster { master: Mutex::new(Some(master)), simulator })
    }

    /// The `Simulator` of link "sim" or "sim:N": injects faults, sets inputs and queries the
    /// virtual AKDs while this master, or a Cycle holding it, serves their frames. Other links
    /// raise ConfigError.
    #[getter]
    fn simulator(&self) -> PyResult<super::sim::PySimulator> {
        let control = self.simulator.clone().ok_or_else(|| super::to_py_err(Unavailable::NoSimulator.into()))?;
        Ok(super::sim::PySimulator::new(control))
    }

    /// Finds the slaves, takes them to Init and returns one dict per slave: `al_state` and
    /// `al_status_code` are the state now (Init), `found_al_state` and `found_al_status_code`
    /// what the scan found before it reset the bus.
    fn scan<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let mut in_use = self.lock()?;
        let m = in_use.get()?;
        py.allow_threads(|| m.scan()).py()?;
        let list = PyList::empty(py);
        for position in 0..m.slaves().len() as u16 {
            let status = py.allow_threads(|| m.slave_mut(position)?.al_status()).py()?;
            let slave = m.slave(position).py()?;
            let d = PyDict::new(py);
            d.set_item("position", slave.position)?;
            d.set_item("station_address", slave.station_address)?;
            d.set_item("alias", slave.alias)?;
            super::eeprom::set_identity(&d, &slave.sii)?;
            d.set_item("al_state", status.state_name())?;
            d.set_item("al_status_code", status.code)?;
            d.set_item("al_status_code_name", status.code_name())?;
            d.set_item("found_al_state", slave.found.state_name())?;
            d.set_item("found_al_status_code", slave.found.code)?;
            d.set_item("found_al_status_code_name", slave.found.code_name())?;
            d.set_item("mailbox_protocols", slave.sii.header.mailbox_protocols)?;
            d.set_item("dc", slave.has_dc())?;
            list.append(d)?;
        }
        Ok(list)
    }

    /// Number of slaves found by the last scan.
    #[getter]
    fn slave_count(&self) -> PyResult<usize> {
        Ok(self.lock()?.get()?.slaves().len())
    }

    /// The link's description.
    #[getter]
    fn link(&self) -> PyResult<String> {
        Ok(self.lock()?.get()?.describe())
    }

    /// Takes the slave at `position` (every slave when None) to `state`.
    #[pyo3(signature = (state, position = None, timeout = 5.0))]
    fn request_state(&self, py: Python<'_>, state: &str, position: Option<u16>, timeout: f64) -> PyResult<()> {
        let target = parse_state(state).py()?;
        let timeout = super::seconds(timeout, "timeout")?;
        let mut in_use = self.lock()?;
        let m = in_use.get()?;
        py.allow_threads(|| match position {
            Some(p) => m.slave_mut(p)?.request_state(target, timeout),
            None => m.request_state(target, timeout),
        })
        .py()
    }

    /// (state, AL status code, its name) of the slave at `position`.
    fn al_status(&self, py: Python<'_>, position: u16) -> PyResult<(String, u16, String)> {
        let mut in_use = self.lock()?;
        let m = in_use.get()?;
        let s = py.allow_threads(|| m.slave_mut(position)?.al_status()).py()?;
        Ok((s.state_name().to_owned(), s.code, s.code_name().to_owned()))
    }

    /// Reads `length` bytes of ESC registers from `address` of the slave at `position`.
    fn read_register<'py>(
        &self,
        py: Python<'py>,
        position: u16,
        address: u16,
        length: usize,
    ) -> PyResult<Bound<'py, PyBytes>> {
        let mut in_use = self.lock()?;
        let m = in_use.get()?;
        let data = py.allow_threads(|| m.slave_mut(position)?.read_register(address, length)).py()?;
        Ok(PyBytes::new(py, &data))
    }

    /// Writes ESC registers from `address` of the slave at `position`.
    fn write_register(&self, py: Python<'_>, position: u16, address: u16, data: Vec<u8>) -> PyResult<()> {
        let mut in_use = self.lock()?;
        let m = in_use.get()?;
        py.allow_threads(|| m.slave_mut(position)?.write_register(address, &data)).py()
    }

    /// Reads an SDO.
    fn sdo_read<'py>(&self, py: Python<'py>, position: u16, index: u16, subindex: u8) -> PyResult<Bound<'py, PyBytes>> {
        let mut in_use = self.lock()?;
        let m = in_use.get()?;
        let data = py.allow_threads(|| m.slave_mut(position)?.sdo_read(index, subindex)).py()?;
        Ok(PyBytes::new(py, &data))
    }

    /// Writes an SDO.
    fn sdo_write(&self, py: Python<'_>, position: u16, index: u16, subindex: u8, data: Vec<u8>) -> PyResult<()> {
        let mut in_use = self.lock()?;
        let m = in_use.get()?;
        py.allow_threads(|| m.slave_mut(position)?.sdo_write(index, subindex, &data)).py()
    }

    /// Every object index of the slave's object dictionary (SDO information).
    fn sdo_object_list(&self, py: Python<'_>, position: u16) -> PyResult<Vec<u16>> {
        let mut in_use = self.lock()?;
        let m = in_use.get()?;
        py.allow_threads(|| m.slave_mut(position)?.sdo_object_list(crate::coe::OdListType::All)).py()
    }

    /// The description of object `index`.
    fn sdo_object_description<'py>(&self, py: Python<'py>, position: u16, index: u16) -> PyResult<Bound<'py, PyDict>> {
        let mut in_use = self.lock()?;
        let m = in_use.get()?;
        let o = py.allow_threads(|| m.slave_mut(position)?.sdo_object_description(index)).py()?;
        let d = PyDict::new(py);
        d.set_item("index", o.index)?;
        d.set_item("data_type", o.data_type)?;
        d.set_item("max_subindex", o.max_subindex)?;
        d.set_item("object_code", u8::from(o.object_code))?;
        d.set_item("name", o.name)?;
        Ok(d)
    }

    /// The description of entry `index:subindex`.
    fn sdo_entry_description<'py>(
        &self,
        py: Python<'py>,
        position: u16,
        index: u16,
        subindex: u8,
    ) -> PyResult<Bound<'py, PyDict>> {
        let mut in_use = self.lock()?;
        let m = in_use.get()?;
        let e = py.allow_threads(|| m.slave_mut(position)?.sdo_entry_description(index, subindex)).py()?;
        let d = PyDict::new(py);
        d.set_item("subindex", e.subindex)?;
        d.set_item("data_type", e.data_type)?;
        d.set_item("bit_length", e.bit_length)?;
        d.set_item("access", e.access)?;
        d.set_item("name", e.name)?;
        Ok(d)
    }

    /// Takes the emergency messages received from the slave at `position`.
    fn emergencies<'py>(&self, py: Python<'py>, position: u16) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty(py);
        for e in self.lock()?.get()?.slave_mut(position).py()?.take_emergencies().py()? {
            let d = PyDict::new(py);
            d.set_item("error_code", e.error_code)?;
            d.set_item("error_register", e.error_register)?;
            d.set_item("data", PyBytes::new(py, &e.data))?;
            list.append(d)?;
        }
        Ok(list)
    }

    /// Gives the slave at `position` (in PreOp) its outputs mapping `rx` and inputs mapping
    /// `tx`: each a fixed mapping index (0x1701, 0x1B01, ...) or a list of PDOs, each a list of
    /// entries 0xIIIISSBB.
    fn configure_pdo(
        &self,
        py: Python<'_>,
        position: u16,
        rx: &Bound<'_, PyAny>,
        tx: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let (rx, tx) = (parse_mapping(rx)?, parse_mapping(tx)?);
        let mut in_use = self.lock()?;
        let m = in_use.get()?;
        py.allow_threads(|| m.slave_mut(position)?.configure_pdo(rx, tx)).py()
    }

    /// Sets the drive's cycle time (interpolation time period 0x60C2) without distributed
    /// clocks, e.g. for a drive synchronised on the SM2 event (in PreOp).
    fn set_cycle_time(&self, py: Python<'_>, position: u16, cycle_time_ns: u32) -> PyResult<()> {
        let mut in_use = self.lock()?;
        let m = in_use.get()?;
        py.allow_threads(|| m.slave_mut(position)?.set_cycle_time(cycle_time_ns)).py()
    }

    /// Sets up distributed clocks and SYNC0 at `cycle_time_ns`, moved by `shift_ns` (less than
    /// a cycle either way), with FBUS.PARAM02 = 1 on every AKD (in PreOp).
    #[pyo3(signature = (cycle_time_ns, shift_ns = 0))]
    fn configure_dc(&self, py: Python<'_>, cycle_time_ns: u32, shift_ns: i64) -> PyResult<()> {
        let mut in_use = self.lock()?;
        let m = in_use.get()?;
        py.allow_threads(|| m.configure_dc(cycle_time_ns, shift_ns)).py()
    }

    /// One cyclic exchange; returns the working counter.
    fn exchange(&self, py: Python<'_>) -> PyResult<u16> {
        let mut in_use = self.lock()?;
        let m = in_use.get()?;
        py.allow_threads(|| m.exchange()).py()
    }

    /// The working counter a good cycle comes back with.
    #[getter]
    fn expected_wkc(&self) -> PyResult<u16> {
        self.lock()?.get()?.expected_wkc().py()
    }

    /// The outputs of the slave at `position`.
    fn outputs<'py>(&self, py: Python<'py>, position: u16) -> PyResult<Bound<'py, PyBytes>> {
        Ok(PyBytes::new(py, self.lock()?.get()?.slave_mut(position).py()?.outputs().py()?))
    }

    /// Sets the outputs of the slave at `position` for the next cycles.
    fn set_outputs(&self, position: u16, data: Vec<u8>) -> PyResult<()> {
        self.lock()?.get()?.slave_mut(position).py()?.set_outputs(&data).py()
    }

    /// The inputs of the slave at `position` from the last good cycle.
    fn inputs<'py>(&self, py: Python<'py>, position: u16) -> PyResult<Bound<'py, PyBytes>> {
        Ok(PyBytes::new(py, self.lock()?.get()?.slave_mut(position).py()?.inputs().py()?))
    }

    /// The bus counters: frames, lost_frames, wkc_errors, cycles, mailbox_repeats,
    /// emergencies, stale_mailbox_replies.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.lock()?.get()?.stats();
        let d = PyDict::new(py);
        d.set_item("frames", s.frames)?;
        d.set_item("lost_frames", s.lost_frames)?;
        d.set_item("wkc_errors", s.wkc_errors)?;
        d.set_item("cycles", s.cycles)?;
        d.set_item("mailbox_repeats", s.mailbox_repeats)?;
        d.set_item("emergencies", s.emergencies)?;
        d.set_item("stale_mailbox_replies", s.stale_mailbox_replies)?;
        Ok(d)
    }

    /// Closes the link; later calls raise ConfigError.
    fn close(&self) -> PyResult<()> {
        *self.lock()?.0 = None;
        Ok(())
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    fn __exit__(&self, _exc_type: PyObject, _exc: PyObject, _tb: PyObject) -> PyResult<()> {
        self.close()
    }

    /// Runs the drives without distributed clocks at `cycle_time_ns`: SYNC0 off,
    /// FBUS.PARAM02 = 0 and the cycle time 0x60C2 on every AKD, which then follows the SM2
    /// event (in PreOp).
    fn configure_sm2_sync(&self, py: Python<'_>, cycle_time_ns: u32) -> PyResult<()> {
        let mut in_use = self.lock()?;
        let m = in_use.get()?;
        py.allow_threads(|| m.configure_sm2_sync(cycle_time_ns)).py()
    }
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyMaster>()
}

/// Handing the master to a cycle thread and back (`akd_ros._native.Cycle`).
impl PyMaster {
    /// Takes the master out; calls meanwhile raise ConfigError until it is [`put_back`](Self::put_back).
    pub(super) fn take(&self) -> PyResult<master::Master> {
        let mut in_use = self.lock()?;
        in_use.get()?;
        Ok(in_use.0.take().expect("checked just above"))
    }

    /// Gives the master back after its cycle thread stopped. Waits for the lock: while the
    /// master is out, a call holds it only to fail at once, with the GIL that the caller holds.
    pub(super) fn put_back(&self, master: master::Master) {
        *self.master.lock().unwrap_or_else(|poisoned| poisoned.into_inner()) = Some(master);
    }
}
