//! `parse_sii` and `akd_sii_image`: the SII codec for Python, as plain dicts and bytes.

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};

use super::IntoPyResult;
use crate::sii::{MailboxLayout, Sii, SiiPdo};
use crate::sim::sii_image;

fn mailbox_dict<'py>(py: Python<'py>, m: &MailboxLayout) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("receive_offset", m.receive_offset)?;
    d.set_item("receive_size", m.receive_size)?;
    d.set_item("send_offset", m.send_offset)?;
    d.set_item("send_size", m.send_size)?;
    Ok(d)
}

/// One dict per item, filled in by `fill`.
fn dicts<'py, T>(
    py: Python<'py>,
    items: &[T],
    fill: impl Fn(&Bound<'py, PyDict>, &T) -> PyResult<()>,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    items
        .iter()
        .map(|item| {
            let d = PyDict::new(py);
            fill(&d, item)?;
            Ok(d)
        })
        .collect()
}

fn pdo_dicts<'py>(py: Python<'py>, sii: &Sii, pdos: &[SiiPdo]) -> PyResult<Vec<Bound<'py, PyDict>>> {
    dicts(py, pdos, |d, p| {
        d.set_item("index", p.index)?;
        d.set_item("name", sii.string(p.name_idx))?;
        d.set_item("sync_manager", p.sync_manager)?;
        d.set_item("dc_sync", p.dc_sync)?;
        d.set_item("flags", p.flags)?;
        let entries = dicts(py, &p.entries, |e, entry| {
            e.set_item("index", entry.index)?;
            e.set_item("subindex", entry.subindex)?;
            e.set_item("name", sii.string(entry.name_idx))?;
            e.set_item("data_type", entry.data_type)?;
            e.set_item("bit_len", entry.bit_len)
        })?;
        d.set_item("entries", entries)
    })
}

/// Puts what identifies a drive in its SII into `d`: vendor_id, product_code, revision,
/// serial_number, and the names name, model and firmware (None where absent). Shared by
/// `parse_sii` and the master's scan so both speak of a drive in the same keys.
pub(super) fn set_identity(d: &Bound<'_, PyDict>, sii: &Sii) -> PyResult<()> {
    let id = sii.identity();
    d.set_item("vendor_id", id.vendor_id)?;
    d.set_item("product_code", id.product_code)?;
    d.set_item("revision", id.revision)?;
    d.set_item("serial_number", id.serial_number)?;
    d.set_item("name", sii.name())?;
    d.set_item("model", sii.model())?;
    d.set_item("firmware", sii.firmware())
}

/// Decodes an SII EEPROM image (the whole EEPROM, or up to the end category) into a dict:
/// identity (vendor_id, product_code, revision, serial_number, alias), names (name, group,
/// order, model, firmware; None where absent), mailbox_protocols, standard_mailbox,
/// bootstrap_mailbox, eeprom_bytes, strings, general, fmmu_usage, sync_managers, tx_pdos,
/// rx_pdos (each with named entries) and dc_modes. Raises SiiError naming what is wrong.
#[pyfunction]
fn parse_sii<'py>(py: Python<'py>, data: &[u8]) -> PyResult<Bound<'py, PyDict>> {
    let sii = Sii::parse(data).py()?;
    let h = &sii.header;
    let d = PyDict::new(py);
    set_identity(&d, &sii)?;
    d.set_item("alias", sii.alias())?;
    d.set_item("group", sii.group())?;
    d.set_item("order", sii.order())?;
    d.set_item("mailbox_protocols", h.mailbox_protocols)?;
    d.set_item("standard_mailbox", mailbox_dict(py, &h.standard_mailbox)?)?;
    d.set_item("bootstrap_mailbox", mailbox_dict(py, &h.bootstrap_mailbox)?)?;
    d.set_item("eeprom_bytes", h.eeprom_bytes())?;
    d.set_item("strings", sii.strings())?;
    if let Some(g) = sii.general() {
        let gd = PyDict::new(py);
        gd.set_item("coe_details", g.coe_details)?;
        gd.set_item("foe_details", g.foe_details)?;
        gd.set_item("eoe_details", g.eoe_details)?;
        gd.set_item("flags", g.flags)?;
        gd.set_item("current_on_ebus", g.current_on_ebus)?;
        gd.set_item("physical_port", g.physical_port)?;
        d.set_item("general", gd)?;
    } else {
        d.set_item("general", py.None())?;
    }
    // A list of codes, not bytes: each is an FMMU usage code (1 outputs, 2 inputs, 3 SM status).
    d.set_item("fmmu_usage", PyList::new(py, sii.fmmu_usage())?)?;
    let sms = dicts(py, sii.sync_managers(), |s, sm| {
        s.set_item("start_address", sm.start_address)?;
        s.set_item("length", sm.length)?;
        s.set_item("control", sm.control)?;
        s.set_item("status", sm.status)?;
        s.set_item("enable", sm.enable)?;
        s.set_item("type", sm.sm_type)
    })?;
    d.set_item("sync_managers", sms)?;
    d.set_item("tx_pdos", pdo_dicts(py, &sii, sii.tx_pdos())?)?;
    d.set_item("rx_pdos", pdo_dicts(py, &sii, sii.rx_pdos())?)?;
    let modes = dicts(py, sii.dc_modes(), |s, m| {
        s.set_item("name", sii.string(m.name_idx))?;
        s.set_item("assign_activate", m.assign_activate)?;
        s.set_item("cycle_time0", m.cycle_time0)?;
        s.set_item("shift_time0", m.shift_time0)?;
        s.set_item("sync0_cycle_factor", m.sync0_cycle_factor)?;
        s.set_item("sync1_cycle_factor", m.sync1_cycle_factor)
    })?;
    d.set_item("dc_modes", modes)?;
    Ok(d)
}

/// The SII EEPROM image the virtual AKD serves: the real AKD-P00606-NBCC-E000's 2048 bytes.
#[pyfunction]
fn akd_sii_image(py: Python<'_>) -> Bound<'_, PyBytes> {
    PyBytes::new(py, &sii_image::akd_sii())
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(parse_sii, m)?)?;
    m.add_function(wrap_pyfunction!(akd_sii_image, m)?)?;
    Ok(())
}
