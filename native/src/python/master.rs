//! `akd_ros._native.Master`: the EtherCAT master for Python.
//!
//! Every call that waits on the bus releases the GIL. The master is taken with `try_lock` for
//! the call, so a second thread using the same master at once gets an error instead of waiting
//! on a lock it cannot see.

use std::sync::{Mutex, MutexGuard, TryLockError};
use std::time::Duration;

use pyo3::prelude::*;
use pyo3::types::PyInt;

use super::eeprom::IdentityView;
use super::IntoPyResult;
use super::Merged;
use crate::drive::akd::{AkdLine, AkdSlave};
use crate::drive::pdo::Mapping;
use crate::drive::scaling::{self, PositionScaling};
use crate::error::{Error, SettingError, Unavailable, UnknownName};
use crate::ethercat::al::AlState;
use crate::ethercat::coe::{Emergency, ObjectCode, OdListType};
use crate::ethercat::device;
use crate::ethercat::link::{self, Link};
use crate::ethercat::link_spec::LinkSpec;
use crate::ethercat::master::sdo_info::{EntryInfo, ObjectInfo};
use crate::ethercat::master::{self, SlaveRef};
use crate::ethercat::pdo::PdoEntry;
use crate::sim::control::SimControl;
use crate::sim::in_process::InProcess;
use crate::sim::{Timing, VirtualBus};

/// An opened link with the handle that controls its virtual AKDs (the in-process links) and
/// what opening it could not do as asked.
struct Opened {
    link: Box<dyn Link>,
    simulator: Option<SimControl>,
    warnings: Vec<String>,
}

/// Opens the link named by `spec` (a [`LinkSpec`]).
fn open_link(spec: &str) -> crate::error::Result<Opened> {
    Ok(match spec.parse::<LinkSpec>()? {
        LinkSpec::Sim { line, missed, pace } => {
            let link = InProcess::with_bus(VirtualBus::of_line(&line, Timing::of(pace, missed))?);
            let simulator = Some(link.control());
            Opened { link: Box::new(link), simulator, warnings: Vec::new() }
        }
        LinkSpec::Udp { address } => {
            Opened { link: Box::new(link::udp::Udp::connect(&address)?), simulator: None, warnings: Vec::new() }
        }
        LinkSpec::Interface { name, busy_poll_us } => {
            let link = link::raw::RawLink::open(&name, Duration::from_micros(busy_poll_us.into()))?;
            let warnings = link.kept_capabilities().map(str::to_owned).into_iter().collect();
            Opened { link: Box::new(link), simulator: None, warnings }
        }
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

impl<'py> IntoPyObject<'py> for scaling::Ratio {
    type Target = pyo3::types::PyTuple;
    type Output = Bound<'py, pyo3::types::PyTuple>;
    type Error = PyErr;

    /// Python reads a ratio as (numerator, denominator).
    fn into_pyobject(self, py: Python<'py>) -> PyResult<Self::Output> {
        (self.numerator, self.denominator).into_pyobject(py)
    }
}

#[pymethods]
impl PositionScaling {
    /// For each position object (index, subindex) the counts per motor revolution it takes, None
    /// where the objects do not tell (0x6064, 0x607A with DS402 scaling off follow the drive's
    /// UNIT parameters, which no DS402 object gives).
    #[getter(counts_per_revolution)]
    fn py_counts_per_revolution(&self) -> std::collections::BTreeMap<(u16, u8), Option<f64>> {
        let objects = scaling::POSITION_OBJECTS.iter();
        objects.map(|&((index, sub), _)| ((index, sub), self.counts_per_revolution(index, sub, None))).collect()
    }
}

/// An EtherCAT master on one link.
#[pyclass(name = "Master", module = "akd_ros._native")]
pub struct PyMaster {
    master: Mutex<Option<master::Master>>,
    /// The in-process link's virtual AKDs, apart from the master so that a Cycle holding it
    /// does not hold them.
    simulator: Option<SimControl>,
    warnings: Vec<String>,
    /// FBUS.PARAM02 as the last clock set-up left it in each slave, by position, for the Cycle
    /// that shows it.
    pub(super) fbus_param02: Mutex<Vec<Option<u32>>>,
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

    /// Runs `f` on the master, the GIL released: the master is taken for the call (ConfigError
    /// when another thread uses it, when it is closed or while a Cycle holds it).
    fn with_master<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut master::Master) -> crate::error::Result<T> + Send,
    ) -> PyResult<T> {
        let mut in_use = self.lock()?;
        let master = in_use.get()?;
        py.allow_threads(|| f(master)).py()
    }

    /// Runs `f` on the slave at `position`, as [`with_master`](Self::with_master) does.
    fn with_slave<T: Send>(
        &self,
        py: Python<'_>,
        position: u16,
        f: impl FnOnce(&mut SlaveRef<'_>) -> crate::error::Result<T> + Send,
    ) -> PyResult<T> {
        self.with_master(py, |m| f(&mut m.slave_mut(position)?))
    }
}

/// Calls a Python progress callback from a thread without the GIL; what it raises is its own
/// and does not stop the transfer.
fn report(progress: &Option<PyObject>, args: &[usize]) {
    if let Some(callback) = progress {
        Python::with_gil(|py| {
            if let Ok(args) = pyo3::types::PyTuple::new(py, args) {
                let _ = callback.call1(py, args);
            }
        });
    }
}

/// One slave as `scan` reports it, besides its identity.
#[derive(IntoPyObject)]
struct ScannedSlave {
    position: u16,
    station_address: u16,
    alias: u16,
    al_state: &'static str,
    al_status_code: u16,
    al_status_code_name: &'static str,
    found_al_state: &'static str,
    found_al_status_code: u16,
    found_al_status_code_name: &'static str,
    mailbox_protocols: u16,
    dc: bool,
    /// The channels its SII's process data carries, named as a device's
    /// ([`crate::ethercat::device`]): what it has if no profile gives it other PDOs.
    channels: Vec<super::device::ChannelView>,
}

/// One slave as `watch` reports it.
#[derive(IntoPyObject)]
struct WatchedSlave {
    answered: bool,
    al_state: &'static str,
    al_status_code: u16,
    al_status_code_name: &'static str,
    mailbox_full: bool,
}

impl From<&master::cyclic::SlaveWatch> for WatchedSlave {
    fn from(w: &master::cyclic::SlaveWatch) -> Self {
        WatchedSlave {
            answered: w.answered,
            al_state: w.al_status.state_name(),
            al_status_code: w.al_status.code,
            al_status_code_name: w.al_status.code_name(),
            mailbox_full: w.mailbox_full,
        }
    }
}

impl<'py> IntoPyObject<'py> for ObjectCode {
    type Target = PyInt;
    type Output = Bound<'py, PyInt>;
    type Error = std::convert::Infallible;

    /// Python reads an object code as its number (7 VAR, 8 ARRAY, 9 RECORD, ...).
    fn into_pyobject(self, py: Python<'py>) -> Result<Bound<'py, PyInt>, Self::Error> {
        u8::from(self).into_pyobject(py)
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
        py.allow_threads(|| -> crate::error::Result<PyMaster> {
            let Opened { link: inner, simulator, warnings } = open_link(link)?;
            let inner: Box<dyn Link> = match pcap {
                Some(path) => Box::new(link::pcap::CapturingLink::new(inner, path)?),
                None => inner,
            };
            let master = Mutex::new(Some(master::Master::new(inner, timeout)));
            Ok(PyMaster { master, simulator, warnings, fbus_param02: Mutex::default() })
        })
        .py()
    }

    /// What opening the link could not do as asked, one sentence each: on a raw interface, the
    /// threads of this process that kept their capabilities after the socket was open (those
    /// that block every signal; see docs/howto/without_root.md).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    /// The `Simulator` of link "sim" or "sim:N": injects faults, sets inputs and queries the
    /// virtual AKDs while this master, or a Cycle holding it, serves their frames. Other links
    /// raise ConfigError.
    #[getter]
    fn simulator(&self) -> PyResult<super::sim::PySimulator> {
        let control = self.simulator.clone().ok_or_else(|| super::to_py_err(Unavailable::NoSimulator.into()))?;
        Ok(super::sim::PySimulator::new(control))
    }

    /// Finds the slaves, takes them to Init and returns one dict per slave: its identity and
    /// names (vendor_id, product_code, revision, serial_number, name, order, akd, model,
    /// firmware), `al_state` and `al_status_code` the state now (Init), `found_al_state` and
    /// `found_al_status_code` what the scan found before it reset the bus, and `channels`, those
    /// its SII's process data carries (each a dict as `Cycle.channels` gives it).
    fn scan(&self, py: Python<'_>) -> PyResult<Vec<Merged<ScannedSlave, IdentityView>>> {
        lock(&self.fbus_param02).clear();
        self.with_master(py, |m| {
            m.scan()?;
            (0..m.slaves().len() as u16)
                .map(|position| {
                    let status = m.slave_mut(position)?.al_status()?;
                    let slave = m.slave(position)?;
                    let rest = ScannedSlave {
                        position: slave.position,
                        station_address: slave.station_address,
                        alias: slave.alias,
                        al_state: status.state_name(),
                        al_status_code: status.code,
                        al_status_code_name: status.code_name(),
                        found_al_state: slave.found.state_name(),
                        found_al_status_code: slave.found.code,
                        found_al_status_code_name: slave.found.code_name(),
                        mailbox_protocols: slave.sii.header.mailbox_protocols,
                        dc: slave.has_dc(),
                        channels: {
                            let coe = slave.mailbox.as_ref().is_some_and(|m| m.has_coe());
                            let described = slave.sii.process_data(coe);
                            device::channels(&slave.sii, &described).iter().map(Into::into).collect()
                        },
                    };
                    Ok(Merged(rest, IdentityView::of(&slave.sii)))
                })
                .collect()
        })
    }

    /// The position of the one slave of the last scan whose station alias is `alias`; raises
    /// ConfigError saying on how many slaves it is when that is not one.
    fn position_of_alias(&self, py: Python<'_>, alias: u16) -> PyResult<u16> {
        self.with_master(py, |m| Ok(m.slave_by_alias(alias)?.position()))
    }

    /// Number of slaves found by the last scan.
    #[getter]
    fn slave_count(&self, py: Python<'_>) -> PyResult<usize> {
        self.with_master(py, |m| Ok(m.slaves().len()))
    }

    /// The link's description.
    #[getter]
    fn link(&self, py: Python<'_>) -> PyResult<String> {
        self.with_master(py, |m| Ok(m.describe()))
    }

    /// Takes the slave at `position` (every slave when None) to `state`.
    #[pyo3(signature = (state, position = None, timeout = 5.0))]
    fn request_state(&self, py: Python<'_>, state: &str, position: Option<u16>, timeout: f64) -> PyResult<()> {
        let target = parse_state(state).py()?;
        let timeout = super::seconds(timeout, "timeout")?;
        match position {
            Some(p) => self.with_slave(py, p, |s| s.request_state(target, timeout)),
            None => self.with_master(py, |m| m.request_state(target, timeout)),
        }
    }

    /// (state, AL status code, its name) of the slave at `position`.
    fn al_status(&self, py: Python<'_>, position: u16) -> PyResult<(&'static str, u16, &'static str)> {
        let s = self.with_slave(py, position, |s| s.al_status())?;
        Ok((s.state_name(), s.code, s.code_name()))
    }

    /// Reads `length` bytes of ESC registers from `address` of the slave at `position`.
    fn read_register(&self, py: Python<'_>, position: u16, address: u16, length: usize) -> PyResult<Vec<u8>> {
        self.with_slave(py, position, |s| s.read_register(address, length))
    }

    /// Writes ESC registers from `address` of the slave at `position`.
    fn write_register(&self, py: Python<'_>, position: u16, address: u16, data: Vec<u8>) -> PyResult<()> {
        self.with_slave(py, position, |s| s.write_register(address, &data))
    }

    /// Reads an SDO.
    fn sdo_read(&self, py: Python<'_>, position: u16, index: u16, subindex: u8) -> PyResult<Vec<u8>> {
        self.with_slave(py, position, |s| s.sdo_read(index, subindex))
    }

    /// Writes an SDO.
    fn sdo_write(&self, py: Python<'_>, position: u16, index: u16, subindex: u8, data: Vec<u8>) -> PyResult<()> {
        self.with_slave(py, position, |s| s.sdo_write(index, subindex, &data))
    }

    /// Gives slave `position` its IP parameters through EoE (Set IP Parameter) and waits for
    /// its response. Addresses are dotted IPv4 text, `mac` six colon-separated hex bytes; the
    /// MAC defaults to 02:01:05:30 and the station address, as TwinCAT chose a real AKD's. A
    /// field left `None` is not sent (the drive keeps what it had).
    #[pyo3(signature = (position, ip, subnet_mask=None, gateway=None, dns_server=None, dns_name=None, mac=None))]
    #[allow(clippy::too_many_arguments)]
    fn eoe_set_ip(
        &self,
        py: Python<'_>,
        position: u16,
        ip: &str,
        subnet_mask: Option<&str>,
        gateway: Option<&str>,
        dns_server: Option<&str>,
        dns_name: Option<String>,
        mac: Option<&str>,
    ) -> PyResult<String> {
        use crate::ethercat::eoe::{parse_ipv4, parse_mac, IpParameters};
        let address = |what, text: Option<&str>| text.map(|t| parse_ipv4(what, t)).transpose();
        let parameters = IpParameters {
            mac: mac.map(parse_mac).transpose().py()?,
            ip: Some(parse_ipv4("IP address", ip).py()?),
            subnet_mask: address("subnet mask", subnet_mask).py()?,
            gateway: address("default gateway", gateway).py()?,
            dns_server: address("DNS server", dns_server).py()?,
            dns_name,
        };
        self.with_slave(py, position, |s| {
            let mac = parameters.mac.unwrap_or_else(|| master::eoe::default_mac(s.info().station_address));
            s.eoe_set_ip(&crate::ethercat::eoe::IpParameters { mac: Some(mac), ..parameters })?;
            Ok(mac.iter().map(|b| format!("{b:02x}")).collect::<Vec<_>>().join(":"))
        })
    }

    /// Sends one Ethernet frame to slave `position`'s IP stack through EoE (the bus stopped).
    fn eoe_send(&self, py: Python<'_>, position: u16, frame: Vec<u8>) -> PyResult<()> {
        self.with_slave(py, position, |s| s.eoe_send(&frame))
    }

    /// The next Ethernet frame slave `position`'s IP stack sent, waiting up to `timeout` s;
    /// `None` when none came.
    fn eoe_receive<'py>(
        &self,
        py: Python<'py>,
        position: u16,
        timeout: f64,
    ) -> PyResult<Option<Bound<'py, pyo3::types::PyBytes>>> {
        let timeout = super::seconds(timeout, "timeout")?;
        let frame = self.with_slave(py, position, |s| s.eoe_receive(timeout))?;
        Ok(frame.map(|f| pyo3::types::PyBytes::new(py, &f)))
    }

    /// Writes `data` as the file `name` to slave `position` through FoE; `progress(sent, total)`
    /// after each packet the drive acknowledged. Raises FoeError with the drive's code by name.
    #[pyo3(signature = (position, name, data, password=0, progress=None))]
    fn foe_write(
        &self,
        py: Python<'_>,
        position: u16,
        name: &str,
        data: Vec<u8>,
        password: u32,
        progress: Option<PyObject>,
    ) -> PyResult<()> {
        self.with_slave(py, position, |s| {
            s.foe_write(name, password, &data, &mut |sent, total| report(&progress, &[sent, total]))
        })
    }

    /// Reads the file `name` from slave `position` through FoE; `progress(received)` after each
    /// packet. Raises FoeError with the drive's code by name (0x8001 "not found").
    #[pyo3(signature = (position, name, password=0, progress=None))]
    fn foe_read<'py>(
        &self,
        py: Python<'py>,
        position: u16,
        name: &str,
        password: u32,
        progress: Option<PyObject>,
    ) -> PyResult<Bound<'py, pyo3::types::PyBytes>> {
        let file = self.with_slave(py, position, |s| s.foe_read(name, password, &mut |n| report(&progress, &[n])))?;
        Ok(pyo3::types::PyBytes::new(py, &file))
    }

    /// Every object index of the slave's object dictionary (SDO information).
    fn sdo_object_list(&self, py: Python<'_>, position: u16) -> PyResult<Vec<u16>> {
        self.with_slave(py, position, |s| s.sdo_object_list(OdListType::All))
    }

    /// The description of object `index`: index, data_type, max_subindex, object_code, name.
    fn sdo_object_description(&self, py: Python<'_>, position: u16, index: u16) -> PyResult<ObjectInfo> {
        self.with_slave(py, position, |s| s.sdo_object_description(index))
    }

    /// The position scaling of the drive at `position` (in PreOp or above), or None for a drive
    /// without the DS402 scaling objects: a PositionScaling, its "encoder_resolution" (0x608F),
    /// "gear_ratio" (0x6091) and "feed_constant" (0x6092) each (numerator, denominator);
    /// "ds402_scaling", FBUS.PARAM05 bit 4, None where the drive's SDO information does not
    /// confirm the object; and "counts_per_revolution" by position object.
    fn position_scaling(&self, py: Python<'_>, position: u16) -> PyResult<Option<PositionScaling>> {
        self.with_slave(py, position, |s| s.position_scaling())
    }

    /// Sets the mode of operation (0x6060) of the drive at `position` by SDO, `mode` its code
    /// (`ModeOfOperation.code`): the mode it starts the cycle in.
    fn set_mode(&self, py: Python<'_>, position: u16, mode: i8) -> PyResult<()> {
        self.with_slave(py, position, |s| s.set_mode(mode))
    }

    /// The description of entry `index:subindex`: subindex, data_type, bit_length, access, name.
    fn sdo_entry_description(&self, py: Python<'_>, position: u16, index: u16, subindex: u8) -> PyResult<EntryInfo> {
        self.with_slave(py, position, |s| s.sdo_entry_description(index, subindex))
    }

    /// Takes the emergency messages received from the slave at `position`, each a dict of
    /// error_code, error_register and data.
    fn emergencies(&self, py: Python<'_>, position: u16) -> PyResult<Vec<Emergency>> {
        self.with_slave(py, position, |s| s.take_emergencies())
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
        self.with_slave(py, position, |s| s.configure_pdo(rx, tx))
    }

    /// Sets the drive's cycle time (interpolation time period 0x60C2) without distributed
    /// clocks, e.g. for a drive synchronised on the SM2 event (in PreOp).
    fn set_cycle_time(&self, py: Python<'_>, position: u16, cycle_time_ns: u32) -> PyResult<()> {
        self.with_slave(py, position, |s| s.set_cycle_time(cycle_time_ns))
    }

    /// Sets up distributed clocks and SYNC0 at `cycle_time_ns`, moved by `shift_ns` (less than
    /// a cycle either way), with FBUS.PARAM02 = 1 on every AKD (in PreOp).
    #[pyo3(signature = (cycle_time_ns, shift_ns = 0))]
    fn configure_dc(&self, py: Python<'_>, cycle_time_ns: u32, shift_ns: i64) -> PyResult<()> {
        let fbus_param02 = self.with_master(py, |m| m.configure_dc(cycle_time_ns, shift_ns))?;
        *lock(&self.fbus_param02) = fbus_param02;
        Ok(())
    }

    /// Runs the drives without distributed clocks at `cycle_time_ns`: SYNC0 off,
    /// FBUS.PARAM02 = 0 and the cycle time 0x60C2 on every AKD, which then follows the SM2
    /// event (in PreOp).
    fn configure_sm2_sync(&self, py: Python<'_>, cycle_time_ns: u32) -> PyResult<()> {
        let fbus_param02 = self.with_master(py, |m| m.configure_sm2_sync(cycle_time_ns))?;
        *lock(&self.fbus_param02) = fbus_param02;
        Ok(())
    }

    /// One cyclic exchange; returns the working counter.
    fn exchange(&self, py: Python<'_>) -> PyResult<u16> {
        self.with_master(py, |m| m.exchange())
    }

    /// The first half of `exchange`: sends the cyclic frame and returns without waiting for it;
    /// `receive_process_data` takes its return later (other calls may go between). Raises
    /// ConfigError while the last one's return was not taken.
    fn send_process_data(&self, py: Python<'_>) -> PyResult<()> {
        self.with_master(py, |m| m.send_process_data())
    }

    /// The second half of `exchange`: takes the return of the frame `send_process_data` sent,
    /// waiting for it up to the frame time-out after it was sent; returns the working counter
    /// as `exchange` does. Raises ConfigError when no frame was sent.
    fn receive_process_data(&self, py: Python<'_>) -> PyResult<u16> {
        self.with_master(py, |m| m.receive_process_data())
    }

    /// Adds (True) or removes (False) the reads of every slave's AL status and mailbox status
    /// that a Cycle's frame carries to each `exchange`, to supervise the bus from a loop of
    /// one's own (`watch`); raises ConfigError when they would not fit in the frame.
    fn set_supervision(&self, py: Python<'_>, on: bool) -> PyResult<()> {
        self.with_master(py, |m| m.set_supervision(on))
    }

    /// What the last `exchange` read of every slave with supervision on, one dict per slave:
    /// answered, al_state, al_status_code, al_status_code_name, mailbox_full (all unanswered
    /// while supervision is off).
    fn watch(&self, py: Python<'_>) -> PyResult<Vec<WatchedSlave>> {
        self.with_master(py, |m| Ok(m.watch()?.iter().map(WatchedSlave::from).collect()))
    }

    /// Every slave's links and error counters as one read finds them, the line at rest (no
    /// Cycle): as `Cycle.line_health()` gives them, each count what the slave's ESC counted
    /// since its power-up or the last clear (nothing is cleared here, and nothing counts in the
    /// window of one read). `names` as there.
    #[pyo3(signature = (names = None))]
    fn line_health(
        &self,
        py: Python<'_>,
        names: Option<std::collections::HashMap<usize, String>>,
    ) -> PyResult<super::line_health::LineHealthView> {
        let (reading, products) = self.with_master(py, |m| {
            let products: Vec<String> = m.slaves().iter().map(|s| s.product().to_owned()).collect();
            Ok((m.line_health()?, products))
        })?;
        Ok(super::line_health::LineHealthView::new(&reading, &super::line_health::labels(&products, names)))
    }

    /// The working counter a good cycle comes back with.
    #[getter]
    fn expected_wkc(&self, py: Python<'_>) -> PyResult<u16> {
        self.with_master(py, |m| m.expected_wkc())
    }

    /// The outputs of the slave at `position`.
    fn outputs(&self, py: Python<'_>, position: u16) -> PyResult<Vec<u8>> {
        self.with_slave(py, position, |s| s.outputs())
    }

    /// Sets the outputs of the slave at `position` for the next cycles.
    fn set_outputs(&self, py: Python<'_>, position: u16, data: Vec<u8>) -> PyResult<()> {
        self.with_slave(py, position, |s| s.set_outputs(&data))
    }

    /// The inputs of the slave at `position` from the last good cycle.
    fn inputs(&self, py: Python<'_>, position: u16) -> PyResult<Vec<u8>> {
        self.with_slave(py, position, |s| s.inputs())
    }

    /// The bus counters: frames, lost_frames, wkc_errors, cycles, mailbox_repeats,
    /// emergencies, stale_mailbox_replies, watch_frames (frames that read each slave in a
    /// cycle whose broadcast supervision reads saw a change).
    fn stats(&self, py: Python<'_>) -> PyResult<master::Stats> {
        self.with_master(py, |m| Ok(m.stats()))
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
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyMaster>()?;
    m.add_class::<PositionScaling>()
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
        *lock(&self.master) = Some(master);
    }
}

/// A lock that a panicking holder left holds what it held.
pub(super) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}
