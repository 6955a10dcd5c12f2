//! Little-endian values at byte offsets of the process images, for the cycle thread's readers
//! of mapped objects (sequencer, latch, per-cycle records).

/// The UINT16 at `at`.
pub fn u16_at(image: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([image[at], image[at + 1]])
}

/// The INT16 at `at`.
pub fn i16_at(image: &[u8], at: usize) -> i16 {
    i16::from_le_bytes([image[at], image[at + 1]])
}

/// The INT32 at `at`.
pub fn i32_at(image: &[u8], at: usize) -> i32 {
    i32::from_le_bytes([image[at], image[at + 1], image[at + 2], image[at + 3]])
}
