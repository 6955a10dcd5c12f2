//! The mailbox header (`mailbox`): any bytes as a mailbox message. A header that decodes
//! encodes back to the same six bytes (but for the reserved bit 7 of byte 5), its body lies
//! within the message, and an error reply's detail reads back as written.
#![no_main]

use akd_native::ethercat::mailbox::{self, MailboxErrorDetail, MailboxHeader, HEADER_LEN};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(header) = MailboxHeader::decode(data) else { return };
    let mut out = [0u8; HEADER_LEN];
    header.encode(&mut out);
    let mut expected = [0u8; HEADER_LEN];
    expected.copy_from_slice(&data[..HEADER_LEN]);
    expected[5] &= 0x7F;
    assert_eq!(out, expected);
    assert_eq!(MailboxHeader::decode(&data[..HEADER_LEN + header.length as usize]).ok(), Some(header));

    let body = header.body(data);
    assert_eq!(body.len(), header.length as usize);
    if let Some(protocol) = header.protocol() {
        assert_eq!(protocol as u8, header.mailbox_type);
        let _ = protocol.sii_protocol_bit();
    }
    let next = mailbox::next_counter(header.counter);
    assert!((1..=7).contains(&next));
    if let Ok(detail) = mailbox::parse_error_reply(body) {
        let _ = mailbox::error_detail_name(detail);
        if let Ok(known) = MailboxErrorDetail::try_from(detail) {
            let mut reply = [0u8; HEADER_LEN + mailbox::ERROR_BODY_LEN];
            let n = mailbox::write_error_reply(&mut reply, next, known);
            let back = MailboxHeader::decode(&reply[..n]).unwrap();
            assert_eq!((back.counter, back.length as usize), (next, mailbox::ERROR_BODY_LEN));
            assert_eq!(mailbox::parse_error_reply(back.body(&reply)).unwrap(), detail);
        }
    }
});
