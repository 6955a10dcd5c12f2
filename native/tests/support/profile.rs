//! A flexible mapping for the profile modes and the modes' targets, as the Python Axis maps
//! them: out controlword, modes of operation, pad, target position | target velocity, target
//! torque; in statusword, mode display, pad, position actual | velocity actual, torque actual.

use akd_native::drive::pdo::Mapping;
use akd_native::ethercat::pdo::PdoEntry;

/// Byte offsets within the drive's outputs.
#[allow(dead_code)] // not every test that includes this module reads each
pub mod outputs {
    /// Controlword 0x6040.
    pub const CONTROLWORD: usize = 0;
    /// Target position 0x607A.
    pub const TARGET_POSITION: usize = 4;
    /// Target velocity 0x60FF.
    pub const TARGET_VELOCITY: usize = 8;
    /// Target torque 0x6071.
    pub const TARGET_TORQUE: usize = 12;
}

/// Byte offsets within the drive's inputs.
#[allow(dead_code)]
pub mod inputs {
    /// Statusword 0x6041.
    pub const STATUSWORD: usize = 0;
    /// Mode display 0x6061.
    pub const MODE_DISPLAY: usize = 2;
    /// Position actual 0x6064.
    pub const POSITION: usize = 4;
    /// Velocity actual 0x606C.
    pub const VELOCITY: usize = 8;
}

/// The outputs (RxPDO) and inputs (TxPDO) mappings.
pub fn profile_mapping() -> (Mapping, Mapping) {
    let pdos = |pdos: &[&[u32]]| {
        Mapping::Flexible(pdos.iter().map(|p| p.iter().map(|&e| PdoEntry::from_u32(e)).collect()).collect())
    };
    (
        pdos(&[&[0x6040_0010, 0x6060_0008, 0x0002_0008, 0x607A_0020], &[0x60FF_0020, 0x6071_0010]]),
        pdos(&[&[0x6041_0010, 0x6061_0008, 0x2002_0108, 0x6064_0020], &[0x606C_0020, 0x6077_0010]]),
    )
}
