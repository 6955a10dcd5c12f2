//! Emergency messages (CoE service 1, CiA 301 §7.2.7): the error code a drive reports,
//! also readable in its 0x603F.

use crate::ethercat::mailbox::MailboxError;

/// An emergency message (CoE service 1): CiA error code, error register, 5 bytes of
/// manufacturer data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
// Python gets a dict keyed by the field names (akd_ros._native): renaming a field renames a key.
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObject))]
pub struct Emergency {
    /// CiA 301 / 402 error code, also readable in 0x603F on the AKD.
    pub error_code: u16,
    /// Error register (0x1001).
    pub error_register: u8,
    /// Manufacturer-specific data.
    pub data: [u8; 5],
}

/// Length of an emergency message body after the CoE header.
pub const EMERGENCY_LEN: usize = 8;

impl Emergency {
    /// Decodes the body after the CoE header.
    pub fn decode(body: &[u8]) -> Result<Self, MailboxError> {
        if body.len() < EMERGENCY_LEN {
            return Err(MailboxError::Truncated { what: "emergency message", len: body.len(), needed: EMERGENCY_LEN });
        }
        let mut data = [0; 5];
        data.copy_from_slice(&body[3..8]);
        Ok(Emergency { error_code: u16::from_le_bytes([body[0], body[1]]), error_register: body[2], data })
    }

    /// Encodes the body after the CoE header; returns its length.
    pub fn encode(&self, out: &mut [u8]) -> usize {
        out[0..2].copy_from_slice(&self.error_code.to_le_bytes());
        out[2] = self.error_register;
        out[3..8].copy_from_slice(&self.data);
        EMERGENCY_LEN
    }
}
