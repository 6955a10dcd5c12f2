//! `parse_sii` and `akd_sii_image`: the SII codec for Python, as plain dicts and bytes.

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use super::IntoPyResult;
use crate::drive::identity;
use crate::ethercat::sii::{General, MailboxLayout, Sii, SiiPdo, SyncManager};
use crate::sim::sii_image;

/// What identifies a slave in its SII: the identity words, the names (None where absent) and
/// whether it is an AKD.
/// Shared by `parse_sii` and the master's scan, so both speak of a drive in the same keys.
#[derive(IntoPyObject)]
pub(super) struct IdentityView {
    vendor_id: u32,
    product_code: u32,
    revision: u32,
    serial_number: u32,
    name: Option<String>,
    order: Option<String>,
    akd: bool,
    model: Option<String>,
    firmware: Option<String>,
}

impl IdentityView {
    /// The identity `sii` holds.
    pub(super) fn of(sii: &Sii) -> Self {
        let id = sii.identity();
        IdentityView {
            vendor_id: id.vendor_id,
            product_code: id.product_code,
            revision: id.revision,
            serial_number: id.serial_number,
            name: sii.name().map(str::to_owned),
            order: sii.order().map(str::to_owned),
            akd: identity::is_akd(&id),
            model: identity::model(sii),
            firmware: identity::firmware(sii),
        }
    }
}

/// One entry of a PDO in the SII, its name resolved.
#[derive(IntoPyObject)]
struct PdoEntryView<'a> {
    index: u16,
    subindex: u8,
    name: Option<&'a str>,
    data_type: u8,
    bit_len: u8,
}

/// One PDO in the SII, its names resolved.
#[derive(IntoPyObject)]
struct PdoView<'a> {
    index: u16,
    name: Option<&'a str>,
    sync_manager: u8,
    dc_sync: u8,
    flags: u16,
    entries: Vec<PdoEntryView<'a>>,
}

fn pdo_views<'a>(sii: &'a Sii, pdos: &'a [SiiPdo]) -> Vec<PdoView<'a>> {
    pdos.iter()
        .map(|p| PdoView {
            index: p.index,
            name: sii.string(p.name_idx),
            sync_manager: p.sync_manager,
            dc_sync: p.dc_sync,
            flags: p.flags,
            entries: p
                .entries
                .iter()
                .map(|e| PdoEntryView {
                    index: e.index,
                    subindex: e.subindex,
                    name: sii.string(e.name_idx),
                    data_type: e.data_type,
                    bit_len: e.bit_len,
                })
                .collect(),
        })
        .collect()
}

/// One DC operation mode, its name resolved.
#[derive(IntoPyObject)]
struct DcModeView<'a> {
    name: Option<&'a str>,
    assign_activate: u16,
    cycle_time0: u32,
    shift_time0: u32,
    sync0_cycle_factor: i16,
    sync1_cycle_factor: i16,
}

/// What `parse_sii` gives besides the identity.
#[derive(IntoPyObject)]
struct SiiView<'a> {
    alias: u16,
    group: Option<&'a str>,
    mailbox_protocols: u16,
    standard_mailbox: MailboxLayout,
    bootstrap_mailbox: MailboxLayout,
    eeprom_bytes: usize,
    strings: &'a [String],
    general: Option<&'a General>,
    /// FMMU usage codes (1 outputs, 2 inputs, 3 SM status), widened: pyo3 makes bytes of a
    /// `u8` sequence, and Python reads a list of codes.
    fmmu_usage: Vec<u16>,
    sync_managers: &'a [SyncManager],
    tx_pdos: Vec<PdoView<'a>>,
    rx_pdos: Vec<PdoView<'a>>,
    dc_modes: Vec<DcModeView<'a>>,
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
    let rest = SiiView {
        alias: sii.alias(),
        group: sii.group(),
        mailbox_protocols: h.mailbox_protocols,
        standard_mailbox: h.standard_mailbox,
        bootstrap_mailbox: h.bootstrap_mailbox,
        eeprom_bytes: h.eeprom_bytes(),
        strings: sii.strings(),
        general: sii.general(),
        fmmu_usage: sii.fmmu_usage().iter().map(|&u| u.into()).collect(),
        sync_managers: sii.sync_managers(),
        tx_pdos: pdo_views(&sii, sii.tx_pdos()),
        rx_pdos: pdo_views(&sii, sii.rx_pdos()),
        dc_modes: sii
            .dc_modes()
            .iter()
            .map(|m| DcModeView {
                name: sii.string(m.name_idx),
                assign_activate: m.assign_activate,
                cycle_time0: m.cycle_time0,
                shift_time0: m.shift_time0,
                sync0_cycle_factor: m.sync0_cycle_factor,
                sync1_cycle_factor: m.sync1_cycle_factor,
            })
            .collect(),
    };
    super::Merged(rest, IdentityView::of(&sii)).into_pyobject(py)
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
