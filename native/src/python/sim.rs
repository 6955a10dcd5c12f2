//! Python face of the virtual AKD: `VirtualBus` for tests that build their own frames, and
//! `serve_udp` / `serve_iface` for the `akd-sim` command.

use std::net::{SocketAddr, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use super::IntoPyResult;
use crate::error::{Error, Result};
use crate::sim::faults::Fault;
use crate::sim::{server, Timing, VirtualBus};

/// A line of virtual AKDs serving EtherCAT payloads (frame header and datagrams) in place.
#[pyclass(name = "VirtualBus", module = "akd_ros._native")]
struct PyVirtualBus {
    bus: VirtualBus,
}

#[pymethods]
impl PyVirtualBus {
    /// `count` drives at power-up. `immediate=True` makes the firmware answer AL requests and
    /// mailbox messages before the next frame instead of after the real drive's delays.
    #[new]
    #[pyo3(signature = (count = 1, immediate = false))]
    fn new(count: usize, immediate: bool) -> Self {
        PyVirtualBus {
            bus: VirtualBus::with_timing(count, if immediate { Timing::IMMEDIATE } else { Timing::REAL_DRIVE }),
        }
    }

    /// Serves `payload` at bus time `time_ns` and returns the frame as it comes back; raises
    /// FrameError for a malformed frame.
    fn process<'py>(&mut self, py: Python<'py>, payload: &[u8], time_ns: u64) -> PyResult<Bound<'py, PyBytes>> {
        let mut frame = payload.to_vec();
        self.bus.process(&mut frame, time_ns).map_err(Error::from).py()?;
        Ok(PyBytes::new(py, &frame))
    }

    /// AL state bits with the error flag, and the AL status code, of drive `position`.
    fn al_status(&self, position: usize) -> PyResult<(u16, u16)> {
        self.check(position)?;
        let (state, error, code) = self.bus.slave(position).al_status();
        Ok((state as u16 | if error { crate::al::AL_ERROR_FLAG } else { 0 }, code))
    }

    /// Lets bus time `time_ns` pass with no frame: the drives' firmware and motors run up to it.
    fn advance(&mut self, time_ns: u64) {
        self.bus.advance(time_ns);
    }

    /// Raises fault `name` in drive `position` at its next run, as its firmware would:
    /// "following_error" (F439), "over_temperature" (F235), "sync_lost" (F125) or
    /// "setpoints_missing" (F706), by name or as "F125".
    fn inject_fault(&mut self, position: usize, name: &str) -> PyResult<()> {
        self.check(position)?;
        let fault = Fault::from_name(name).map_err(Error::Config).py()?;
        self.bus.slave_mut(position).drive_mut().inject(fault);
        Ok(())
    }

    /// Sets the hardware enable input of drive `position` (high at power-up).
    fn set_hardware_enable(&mut self, position: usize, high: bool) -> PyResult<()> {
        self.check(position)?;
        self.bus.slave_mut(position).drive_mut().set_hardware_enable(high);
        Ok(())
    }

    /// Digital input `input` (1..7) of drive `position` toggles wherever the actual position
    /// (counts, 2^20 per revolution) crosses one of `positions`; it is low below all of them.
    fn set_input_toggles(&mut self, position: usize, input: usize, positions: Vec<f64>) -> PyResult<()> {
        self.check(position)?;
        self.bus.slave_mut(position).drive_mut().inputs_mut().set_toggles(input, &positions).map_err(Error::Config).py()
    }

    /// The drive firmware of drive `position` as a dict: "state" (the CiA 402 state's name),
    /// "fault" (the active fault's name, or None), "fault_number" (e.g. 125, or None), and the
    /// motor's "position" (counts), "velocity" (counts/s) and "torque" (N·m).
    fn drive_state<'py>(&self, py: Python<'py>, position: usize) -> PyResult<Bound<'py, PyDict>> {
        self.check(position)?;
        let drive = self.bus.slave(position).drive();
        let shaft = drive.shaft();
        let state = PyDict::new(py);
        state.set_item("state", drive.state().name())?;
        state.set_item("fault", drive.fault().map(Fault::name))?;
        state.set_item("fault_number", drive.fault().map(Fault::number))?;
        state.set_item("position", drive.position())?;
        state.set_item("velocity", shaft.velocity)?;
        state.set_item("torque", shaft.torque)?;
        Ok(state)
    }

    fn __len__(&self) -> usize {
        self.bus.len()
    }
}

impl PyVirtualBus {
    fn check(&self, position: usize) -> PyResult<()> {
        if position < self.bus.len() {
            return Ok(());
        }
        Err(Error::NoSuchSlave { position: position as u16, count: self.bus.len() as u16 }).py()
    }
}

/// Runs `serve` on a thread until it ends or a Python signal handler raises (SIGINT gives
/// KeyboardInterrupt): the GIL is released while waiting, signals are checked every 100 ms.
fn run_until_signal(
    py: Python<'_>,
    serve: impl FnOnce(&AtomicBool) -> Result<server::ServerStats> + Send + 'static,
) -> PyResult<()> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let worker = std::thread::spawn(move || serve(&flag));
    loop {
        py.allow_threads(|| std::thread::sleep(server::POLL_INTERVAL));
        if worker.is_finished() {
            break;
        }
        if let Err(interrupt) = py.check_signals() {
            stop.store(true, Ordering::Relaxed);
            // The worker sees the flag within one poll interval.
            let _ = py.allow_threads(|| worker.join());
            return Err(interrupt);
        }
    }
    match py.allow_threads(|| worker.join()) {
        Ok(result) => result.map(|_| ()).py(),
        Err(_) => Err(Error::Config("the simulator thread panicked".into())).py(),
    }
}

/// Serves `count` virtual AKDs on UDP `host:port` until SIGINT/SIGTERM.
#[pyfunction]
#[pyo3(signature = (host, port, count = 1))]
fn serve_udp(py: Python<'_>, host: &str, port: u16, count: usize) -> PyResult<()> {
    let address: SocketAddr = (host, port)
        .to_socket_addrs()
        .ok()
        .and_then(|mut a| a.next())
        .ok_or_else(|| Error::Config(format!("cannot resolve {host:?} as a host to bind")))
        .py()?;
    run_until_signal(py, move |stop| server::serve_udp(address, VirtualBus::new(count), stop))
}

/// Serves `count` virtual AKDs on network interface `iface` until SIGINT/SIGTERM.
#[pyfunction]
#[pyo3(signature = (iface, count = 1))]
fn serve_iface(py: Python<'_>, iface: &str, count: usize) -> PyResult<()> {
    let iface = iface.to_owned();
    run_until_signal(py, move |stop| server::serve_iface(&iface, VirtualBus::new(count), stop))
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyVirtualBus>()?;
    m.add_function(wrap_pyfunction!(serve_udp, m)?)?;
    m.add_function(wrap_pyfunction!(serve_iface, m)?)?;
    Ok(())
}
