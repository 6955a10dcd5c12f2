//! SII EEPROM images (`sii`): any bytes as an image read from a drive. Parsing never panics,
//! every accessor answers, and an image that parses and encodes parses back to the same.
#![no_main]

use akd_native::ethercat::sii::Sii;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(sii) = Sii::parse(data) else { return };
    let _ = (sii.identity(), sii.alias(), sii.general(), sii.name(), sii.group(), sii.order());
    let _ = (sii.fmmu_usage(), sii.sync_managers(), sii.dc_modes(), sii.model(), sii.firmware());
    for pdo in sii.tx_pdos().iter().chain(sii.rx_pdos()) {
        for entry in &pdo.entries {
            let _ = entry.pdo_entry();
        }
    }
    for i in 0..=sii.strings().len().min(255) {
        let _ = sii.string(i as u8);
    }
    let _ = sii.header.eeprom_bytes();
    if let Ok(image) = sii.encode() {
        assert_eq!(Sii::parse(&image).expect("an encoded image parses"), sii);
    }
});
