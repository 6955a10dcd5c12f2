//! Reading a drive's position scaling: the DS402 scaling objects 0x608F, 0x6091 and 0x6092,
//! and FBUS.PARAM05 where the drive's SDO information confirms the object
//! ([`scaling::FBUS_PARAM05`] explains why). What the values mean is [`scaling`]'s.

use crate::drive::scaling::{self, PositionScaling, SCALING_ENTRIES};
use crate::error::{Error, Result};
use crate::ethercat::coe::SdoAbortCode;
use crate::ethercat::master::sdo_info::parameter_confirmed;
use crate::ethercat::master::Master;

impl Master {
    /// The position scaling of the drive at `position` (in PreOp or above); `None` for a drive
    /// without the DS402 scaling objects (an abort "no such object"), as firmware before them.
    pub(super) fn position_scaling(&mut self, position: u16) -> Result<Option<PositionScaling>> {
        let mut entries = [0u32; SCALING_ENTRIES.len()];
        for (value, (index, subindex)) in entries.iter_mut().zip(SCALING_ENTRIES) {
            match self.sdo_read(position, index, subindex) {
                Ok(bytes) => *value = u32_of(&bytes),
                Err(Error::SdoAbort { code, .. }) if code == SdoAbortCode::NO_SUCH_OBJECT.0 => return Ok(None),
                Err(e) => return Err(e),
            }
        }
        let description = self.sdo_object_description(position, scaling::FBUS_PARAM05);
        let param05 = match parameter_confirmed(description, scaling::FBUS_PARAM05_NAME)? {
            true => Some(u32_of(&self.sdo_read(position, scaling::FBUS_PARAM05, 0)?)),
            false => None,
        };
        Ok(Some(PositionScaling::from_entries(entries, param05)))
    }
}

/// An UNSIGNED32 as the drive sent it (shorter values padded, as an expedited upload may be).
fn u32_of(bytes: &[u8]) -> u32 {
    let mut le = [0u8; 4];
    let n = bytes.len().min(4);
    le[..n].copy_from_slice(&bytes[..n]);
    u32::from_le_bytes(le)
}
