//! What akd_ros does to an AKD through the master ([`AkdSlave`], on the master's
//! [`SlaveRef`]): give it a mapping checked against the AKD's rules, and read its position
//! scaling — the DS402 scaling objects 0x608F, 0x6091 and 0x6092, and FBUS.PARAM05 where the
//! drive's SDO information confirms the object ([`scaling::FBUS_PARAM05`] explains why). What
//! the values mean is [`scaling`]'s and [`crate::drive::pdo`]'s; this module only carries them.

use crate::drive::pdo::Mapping;
use crate::drive::scaling::{self, PositionScaling, SCALING_ENTRIES};
use crate::error::{Error, Result};
use crate::ethercat::coe::SdoAbortCode;
use crate::ethercat::master::sdo_info::parameter_confirmed;
use crate::ethercat::master::SlaveRef;

/// A slave of the master that is an AKD.
pub trait AkdSlave {
    /// Gives the drive (in PreOp) its outputs mapping `rx` and inputs mapping `tx`; both are
    /// checked against the AKD's rules first ([`crate::drive::pdo::check_flexible`]), so a refused mapping
    /// writes nothing.
    fn configure_pdo(&mut self, rx: Mapping, tx: Mapping) -> Result<()>;

    /// The drive's position scaling (in PreOp or above); `None` for a drive without the DS402
    /// scaling objects (an abort "no such object"), as firmware before them.
    fn position_scaling(&mut self) -> Result<Option<PositionScaling>>;
}

impl AkdSlave for SlaveRef<'_> {
    fn configure_pdo(&mut self, rx: Mapping, tx: Mapping) -> Result<()> {
        self.configure_process_data(Mapping::process_data(&rx, &tx)?)
    }

    fn position_scaling(&mut self) -> Result<Option<PositionScaling>> {
        let mut entries = [0u32; SCALING_ENTRIES.len()];
        for (value, (index, subindex)) in entries.iter_mut().zip(SCALING_ENTRIES) {
            match self.sdo_read(index, subindex) {
                Ok(bytes) => *value = u32_of(&bytes),
                Err(Error::SdoAbort { code, .. }) if code == SdoAbortCode::NO_SUCH_OBJECT.0 => return Ok(None),
                Err(e) => return Err(e),
            }
        }
        let description = self.sdo_object_description(scaling::FBUS_PARAM05);
        let param05 = match parameter_confirmed(description, scaling::FBUS_PARAM05_NAME)? {
            true => Some(u32_of(&self.sdo_read(scaling::FBUS_PARAM05, 0)?)),
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
