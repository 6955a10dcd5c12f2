//! EoE and FoE (`eoe_foe`): any bytes as the body of an EoE message and of a FoE message, as a
//! drive or a master might send them. What decodes encodes to a message that decodes to the
//! same value; fragments go through a reassembler that must refuse, never panic, whatever
//! order and sizes they come in; a frame cut by the fragmenter comes back whole.
#![no_main]

use akd_native::ethercat::eoe::{self, EoeMessage, Fragmenter, Reassembler, MAX_FRAME_LEN};
use akd_native::ethercat::foe::{self, FoeMessage};
use akd_native::ethercat::mailbox::{MailboxHeader, HEADER_LEN};
use libfuzzer_sys::fuzz_target;

const ROOM: usize = 4096;

fn eoe_body(body: &[u8], reassembler: &mut Reassembler) {
    let Ok(message) = EoeMessage::decode(body) else { return };
    let mut out = [0u8; ROOM];
    match &message {
        EoeMessage::Fragment { header, data, timestamp: None } => {
            let n = eoe::write_fragment(&mut out, 1, header, data);
            let h = MailboxHeader::decode(&out[..n]).unwrap();
            assert_eq!(EoeMessage::decode(h.body(&out)).unwrap(), message);
            let _ = reassembler.push(header, data);
        }
        EoeMessage::SetIpRequest(parameters) => {
            // A name cut at its first zero byte encodes again unless it held none.
            if let Ok(n) = eoe::write_set_ip_request(&mut out, 2, parameters) {
                let h = MailboxHeader::decode(&out[..n]).unwrap();
                assert_eq!(&EoeMessage::decode(h.body(&out)).unwrap(), &message);
            }
        }
        EoeMessage::SetIpResponse(result) => {
            let _ = result.name();
            let n = eoe::write_response(&mut out, 3, eoe::EoeFrameType::SetIpResponse, *result);
            assert_eq!(EoeMessage::decode(&out[HEADER_LEN..n]).unwrap(), message);
        }
        _ => {}
    }
}

fn foe_body(body: &[u8]) {
    let Ok(message) = FoeMessage::decode(body) else { return };
    let mut out = vec![0u8; message.len()];
    let n = message.write(&mut out, 4);
    assert_eq!(FoeMessage::decode(&out[HEADER_LEN..n]).unwrap(), message);
    match &message {
        FoeMessage::Error { code, text } => {
            let _ = (foe::text(text), code.name());
        }
        FoeMessage::Busy { text, .. } => {
            let _ = foe::text(text);
        }
        _ => {}
    }
}

fn fragments_round_trip(data: &[u8]) {
    let [a, b, frame @ ..] = data else { return };
    let frame = &frame[..frame.len().min(MAX_FRAME_LEN)];
    let mailbox = 42 + usize::from(u16::from_le_bytes([*a, *b]) % 1100);
    let mut r = Reassembler::default();
    let mut whole = None;
    for (header, part) in Fragmenter::new(frame, *a, mailbox).unwrap() {
        whole = r.push(&header, part).unwrap().map(<[u8]>::to_vec);
    }
    assert_eq!(whole.as_deref(), Some(frame));
}

fuzz_target!(|data: &[u8]| {
    if data.len() > ROOM / 2 {
        return;
    }
    // The bytes as a run of mailbox messages, each length-prefixed by a byte: fragments from a
    // line that lost, repeated or reordered some.
    let mut reassembler = Reassembler::default();
    let mut rest = data;
    while let [len, tail @ ..] = rest {
        let (body, next) = tail.split_at(usize::from(*len).min(tail.len()));
        eoe_body(body, &mut reassembler);
        rest = next;
    }
    eoe_body(data, &mut reassembler);
    foe_body(data);
    fragments_round_trip(data);
});
