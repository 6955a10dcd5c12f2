//! `parse_link` and `LINK_FORMS`: the link spec for Python, parsed by the crate's
//! [`LinkSpec`] so that the node's parameter check accepts and refuses what `Master(link)` does.

use pyo3::prelude::*;

use crate::ethercat::link_spec::{self as spec, LinkSpec};

/// A parsed link spec: "kind" ("sim", "udp" or "interface") and the one field of that kind,
/// the others None.
#[pyclass(name = "LinkSpec", module = "akd_ros._native", frozen)]
pub struct PyLinkSpec {
    spec: LinkSpec,
}

#[pymethods]
impl PyLinkSpec {
    /// "sim", "udp" or "interface".
    #[getter]
    fn kind(&self) -> &'static str {
        match &self.spec {
            LinkSpec::Sim { .. } => "sim",
            LinkSpec::Udp { .. } => "udp",
            LinkSpec::Interface { .. } => "interface",
        }
    }

    /// How many virtual slaves (sim), else None.
    #[getter]
    fn count(&self) -> Option<usize> {
        match &self.spec {
            LinkSpec::Sim { line, .. } => Some(line.len()),
            _ => None,
        }
    }

    /// The virtual slaves' products in order, e.g. ["ek1100", "el1004", "akd"] (sim), else None.
    #[getter]
    fn line(&self) -> Option<Vec<&'static str>> {
        match &self.spec {
            LinkSpec::Sim { line, .. } => Some(line.products().iter().map(|p| p.name()).collect()),
            _ => None,
        }
    }

    /// How the virtual AKDs judge missed frames, "late", "lost" or "warn" (sim), else None.
    #[getter]
    fn missed(&self) -> Option<&'static str> {
        match &self.spec {
            LinkSpec::Sim { missed, .. } => Some(missed.name()),
            _ => None,
        }
    }

    /// How fast the virtual AKDs answer, "real" or "immediate" (sim), else None.
    #[getter]
    fn pace(&self) -> Option<&'static str> {
        match &self.spec {
            LinkSpec::Sim { pace, .. } => Some(pace.name()),
            _ => None,
        }
    }

    /// `HOST:PORT` (udp), else None.
    #[getter]
    fn address(&self) -> Option<&str> {
        match &self.spec {
            LinkSpec::Udp { address } => Some(address),
            _ => None,
        }
    }

    /// The network interface's name (interface), else None.
    #[getter]
    fn name(&self) -> Option<&str> {
        match &self.spec {
            LinkSpec::Interface { name, .. } => Some(name),
            _ => None,
        }
    }

    /// How many µs the master busy-polls for the returning frame (interface), else None.
    #[getter]
    fn busy_poll_us(&self) -> Option<u32> {
        match &self.spec {
            LinkSpec::Interface { busy_poll_us, .. } => Some(*busy_poll_us),
            _ => None,
        }
    }

    /// The spec in the form it was parsed from ("sim:1" for "sim").
    fn __str__(&self) -> String {
        self.spec.to_string()
    }

    fn __repr__(&self) -> String {
        format!("LinkSpec({:?})", self.spec.to_string())
    }
}

/// Parses a link spec as `Master(link)` does, without opening it: raises ConfigError naming
/// the allowed forms (`LINK_FORMS`) for one that is none of them, with the text `Master(link)`
/// gives after its "configuration: ".
#[pyfunction]
fn parse_link(spec: &str) -> PyResult<PyLinkSpec> {
    // The link error's own text: the caller asked about a link spec, so it needs no category.
    let spec = spec.parse::<LinkSpec>().map_err(|e| super::ConfigError::new_err(e.to_string()))?;
    Ok(PyLinkSpec { spec })
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyLinkSpec>()?;
    m.add_function(wrap_pyfunction!(parse_link, m)?)?;
    m.add("LINK_FORMS", spec::allowed_forms())?;
    Ok(())
}
