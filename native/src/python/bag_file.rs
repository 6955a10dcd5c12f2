//! `akd_ros._native.BagFile`: one MCAP file of a bag for `akd_ros.recorder`, over
//! [`crate::bag_file`].

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Mutex;

use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;

use crate::bag_file::{BagFile, Compression};

/// An MCAP file being written: `BagFile(path, compression, profile, library)`, compression
/// "zstd", "lz4" or "none". Failures raise OSError naming the file.
#[pyclass(name = "BagFile", module = "akd_ros._native", frozen)]
pub struct PyBagFile {
    path: PathBuf,
    // Only the recorder's writer thread uses it; the lock makes the object shareable all the same.
    file: Mutex<BagFile>,
}

/// OSError naming `path`, with the error and every cause under it (mcap's I/O error names none).
fn os_error(path: &std::path::Path, error: &mcap::McapError) -> PyErr {
    let mut text = format!("{}: {error}", path.display());
    let mut cause = std::error::Error::source(error);
    while let Some(e) = cause {
        text += &format!(": {e}");
        cause = e.source();
    }
    PyOSError::new_err(text)
}

impl PyBagFile {
    fn with<T>(&self, action: impl FnOnce(&mut BagFile) -> Result<T, mcap::McapError>) -> PyResult<T> {
        let mut file = self.file.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        action(&mut file).map_err(|e| os_error(&self.path, &e))
    }
}

#[pymethods]
impl PyBagFile {
    #[new]
    fn new(path: PathBuf, compression: &str, profile: &str, library: &str) -> PyResult<Self> {
        let compression = match compression {
            "zstd" => Compression::Zstd,
            "lz4" => Compression::Lz4,
            "none" => Compression::None,
            other => {
                return Err(PyValueError::new_err(format!("compression {other:?} is not one of 'lz4', 'none', 'zstd'")))
            }
        };
        let file = BagFile::create(&path, compression, profile, library).map_err(|e| os_error(&path, &e))?;
        Ok(PyBagFile { path, file: Mutex::new(file) })
    }

    /// Adds a schema; its id.
    fn add_schema(&self, name: &str, encoding: &str, data: &[u8]) -> PyResult<u16> {
        self.with(|f| f.add_schema(name, encoding, data))
    }

    /// Adds a channel of `schema_id` with `metadata`; its id.
    fn add_channel(
        &self,
        schema_id: u16,
        topic: &str,
        message_encoding: &str,
        metadata: BTreeMap<String, String>,
    ) -> PyResult<u16> {
        self.with(|f| f.add_channel(schema_id, topic, message_encoding, &metadata))
    }

    /// Adds `records`, a list of (time_ns, data), to one channel; their bytes in all.
    fn add_messages(&self, channel_id: u16, records: Vec<(u64, Bound<'_, PyBytes>)>) -> PyResult<usize> {
        self.with(|f| {
            records.iter().try_fold(0, |total, (time_ns, data)| {
                f.add_message(channel_id, *time_ns, data.as_bytes()).map(|()| total + data.as_bytes().len())
            })
        })
    }

    /// Closes the open chunk and writes it (the GIL released while it compresses).
    fn flush(&self, py: Python<'_>) -> PyResult<()> {
        py.allow_threads(|| self.with(BagFile::flush))
    }

    /// The file's size so far (bytes).
    fn size(&self) -> PyResult<u64> {
        self.with(|f| Ok(f.size()?))
    }

    /// Waits until what was written is on the disk.
    fn sync(&self, py: Python<'_>) -> PyResult<()> {
        py.allow_threads(|| self.with(|f| Ok(f.sync()?)))
    }

    /// Writes the metadata record `name` of `entries`, the summary and footer, and syncs.
    fn finish(&self, py: Python<'_>, name: &str, entries: BTreeMap<String, String>) -> PyResult<()> {
        py.allow_threads(|| self.with(|f| f.finish(name, entries)))
    }
}

pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyBagFile>()
}
