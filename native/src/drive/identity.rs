//! What tells an AKD from any other slave, and what its SII says of it beyond what EtherCAT says
//! of every slave: its vendor and product code ([`is_akd`]), and its manufacturer's categories,
//! the model string (0x0800, e.g. `AKD-P00606-NBCC-E000`) and the firmware version (0x0801,
//! `01-20-00-003`; AKD manual §5.15), which the EtherCAT layer keeps raw.

use crate::ethercat::sii::{Category, Identity, Sii};

/// Kollmorgen's vendor id.
pub const VENDOR_ID: u32 = 0x0000_006A;
/// The AKD's product code, "AKD" in ASCII.
pub const PRODUCT_CODE: u32 = 0x0041_4B44;
/// The SII category of the AKD's model string.
pub const MODEL_CATEGORY: u16 = 0x0800;
/// The SII category of the AKD's firmware version string.
pub const FIRMWARE_CATEGORY: u16 = 0x0801;

/// Whether `identity` is an AKD's: the drive profile writes its objects to those slaves only.
pub fn is_akd(identity: &Identity) -> bool {
    (identity.vendor_id, identity.product_code) == (VENDOR_ID, PRODUCT_CODE)
}

/// The AKD's model string in its SII, `None` where the category is absent.
pub fn model(sii: &Sii) -> Option<String> {
    sii.other_category(MODEL_CATEGORY).map(padded_string)
}

/// The AKD's firmware version string in its SII, `None` where the category is absent.
pub fn firmware(sii: &Sii) -> Option<String> {
    sii.other_category(FIRMWARE_CATEGORY).map(padded_string)
}

/// A category of type `kind` holding `text` (ISO 8859-1; a character beyond it is written '?'),
/// padded with a NUL to whole words, as the AKD writes its model and firmware.
pub fn string_category(kind: u16, text: &str) -> Category {
    let mut data: Vec<u8> = text.chars().map(|c| u8::try_from(u32::from(c)).unwrap_or(b'?')).collect();
    data.resize(data.len().next_multiple_of(2), 0);
    Category::Other { kind, data }
}

/// A string category's content: ISO 8859-1 up to the first NUL (the padding).
fn padded_string(data: &[u8]) -> String {
    data.iter().take_while(|&&b| b != 0).map(|&b| char::from(b)).collect()
}
