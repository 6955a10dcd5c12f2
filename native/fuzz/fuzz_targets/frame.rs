//! The frame and datagram codec (`frame`): any bytes as an EtherCAT payload. Walking, validating
//! and serving in place never panic; a valid frame rebuilt datagram by datagram with
//! `FrameBuilder` decodes to the same datagrams, and serving it in place without change leaves
//! every byte as it was.
#![no_main]

use akd_native::ethercat::frame::{self, Command, FrameBuilder, DATAGRAM_HEADER_LEN, FRAME_HEADER_LEN, MAX_PAYLOAD_LEN};
use libfuzzer_sys::fuzz_target;

/// Bits 11–13 of a datagram's length word, which the standard reserves and the codec drops.
const RESERVED_LEN_BITS: u8 = 0x38;

fuzz_target!(|data: &[u8]| {
    for &code in data.iter().take(4) {
        if let Ok(command) = Command::from_u8(code) {
            assert_eq!(command as u8, code);
            let _ = (command.name(), command.addressing(), frame::expected_wkc(command, 3, 2));
        }
    }
    let walked: Vec<_> = match frame::parse(data) {
        Ok(datagrams) => datagrams.collect(),
        Err(_) => Vec::new(),
    };
    let Ok(count) = frame::validate(data) else { return };
    assert_eq!(walked.len(), count);
    let datagrams: Vec<_> = walked.into_iter().map(|d| d.expect("a valid frame's datagrams decode")).collect();

    let len = FRAME_HEADER_LEN + frame::frame_header(data).unwrap();
    let mut buf = vec![0u8; MAX_PAYLOAD_LEN];
    let mut builder = FrameBuilder::new(&mut buf);
    for d in &datagrams {
        let h = d.header;
        if let Err(e) = builder.push(h.command, h.index, h.adp, h.ado, d.data) {
            // Only a frame longer than Ethernet carries does not fit the builder.
            assert!(len > MAX_PAYLOAD_LEN, "{e} for a frame of {len} bytes");
            return;
        }
    }
    let built_len = builder.finish();
    assert_eq!(built_len, len);
    let rebuilt: Vec<_> = frame::parse(&buf[..built_len]).unwrap().map(Result::unwrap).collect();
    assert_eq!(rebuilt.len(), datagrams.len());
    for (a, b) in datagrams.iter().zip(&rebuilt) {
        assert_eq!(
            (a.header.command, a.header.index, a.header.adp, a.header.ado),
            (b.header.command, b.header.index, b.header.adp, b.header.ado)
        );
        assert_eq!(
            (a.header.len, a.header.more, a.data, a.data_offset),
            (b.header.len, b.header.more, b.data, b.data_offset)
        );
    }

    let mut served = data.to_vec();
    assert_eq!(frame::for_each_datagram_mut(&mut served, |_| {}).unwrap(), count);
    let mut expected = data.to_vec();
    for d in &datagrams {
        expected[d.data_offset - DATAGRAM_HEADER_LEN + 7] &= !RESERVED_LEN_BITS;
    }
    assert_eq!(served, expected, "serving in place without change altered the frame");
});
