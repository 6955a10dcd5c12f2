//! `parse_link` and `LINK_FORMS`: the link spec for Python, parsed by the crate's
//! [`LinkSpec`] so that the node's parameter check accepts and refuses what `Master(link)` does.

use pyo3::prelude::*;

use crate::ethercat::link_spec::{self as spec, LinkSpec};

/// A parsed link spec: "kind" ("sim", "udp" or "interface") and the fields of that kind, the
/// others None.
#[pyclass(name = "LinkSpec", module = "akd_ros._native", frozen)]
#[derive(Default)]
pub struct PyLinkSpec {
    /// "sim", "udp" or "interface".
    #[pyo3(get)]
    kind: &'static str,
    /// How many virtual slaves (sim), else None.
    #[pyo3(get)]
    count: Option<usize>,
    /// The virtual slaves' products in order, e.g. ["ek1100", "el1004", "akd"] (sim), else None.
    #[pyo3(get)]
    line: Option<Vec<&'static str>>,
    /// How the virtual AKDs judge missed frames, "late", "lost" or "warn" (sim), else None.
    #[pyo3(get)]
    missed: Option<&'static str>,
    /// How fast the virtual AKDs answer, "real" or "immediate" (sim), else None.
    #[pyo3(get)]
    pace: Option<&'static str>,
    /// `HOST:PORT` (udp), else None.
    #[pyo3(get)]
    address: Option<String>,
    /// The network interface's name (interface), else None.
    #[pyo3(get)]
    name: Option<String>,
    /// How many µs the master busy-polls for the returning frame (interface), else None.
    #[pyo3(get)]
    busy_poll_us: Option<u32>,
    /// The spec in the form it was parsed from ("sim:1" for "sim").
    text: String,
}

#[pymethods]
impl PyLinkSpec {
    fn __str__(&self) -> &str {
        &self.text
    }

    fn __repr__(&self) -> String {
        format!("LinkSpec({:?})", self.text)
    }
}

/// Parses a link spec as `Master(link)` does, without opening it: raises ConfigError naming
/// the allowed forms (`LINK_FORMS`) for one that is none of them, with the text `Master(link)`
/// gives after its "configuration: ".
#[pyfunction]
fn parse_link(spec: &str) -> PyResult<PyLinkSpec> {
    // The link error's own text: the caller asked about a link spec, so it needs no category.
    let spec = spec.parse::<LinkSpec>().map_err(|e| super::ConfigError::new_err(e.to_string()))?;
    let text = spec.to_string();
    Ok(match spec {
        LinkSpec::Sim { line, missed, pace } => PyLinkSpec {
            kind: "sim",
            count: Some(line.len()),
            line: Some(line.products().iter().map(|p| p.name()).collect()),
            missed: Some(missed.name()),
            pace: Some(pace.name()),
            text,
            ..Default::default()
        },
        LinkSpec::Udp { address } => PyLinkSpec { kind: "udp", address: Some(address), text, ..Default::default() },
        LinkSpec::Interface { name, busy_poll_us } => PyLinkSpec {
            kind: "interface",
            name: Some(name),
            busy_poll_us: Some(busy_poll_us),
            text,
            ..Default::default()
        },
    })
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyLinkSpec>()?;
    m.add_function(wrap_pyfunction!(parse_link, m)?)?;
    m.add("LINK_FORMS", spec::allowed_forms())?;
    Ok(())
}
