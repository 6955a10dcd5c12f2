//! The master against virtual AKDs whose SII declares a 64-byte mailbox instead of the real
//! drive's 1 KiB, so that what never happens with the real drive does: SDO values in segments
//! with alternating toggle bits, and SDO information replies in fragments. A spy on the link
//! decodes every mailbox message that went through, to show the transfers were split.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use akd_native::drive::pdo::{AKD_MAILBOX_IN, AKD_MAILBOX_OUT};
use akd_native::error::{Error, Result};
use akd_native::ethercat::al::AlState;
use akd_native::ethercat::coe::{
    self, access, data_type, CoeService, ObjectCode, OdListType, SdoAbortCode, SdoInfoHeader, SdoInfoOpcode,
    SdoRequest, SdoResponse,
};
use akd_native::ethercat::frame::{self, Command};
use akd_native::ethercat::link::Link;
use akd_native::ethercat::master::Master;
use akd_native::sim::in_process::InProcess;
use akd_native::sim::od::{Entry, Object};
use akd_native::sim::{Timing, VirtualBus};

const MAILBOX: u16 = 64;
const STEP: Duration = Duration::from_secs(5);

/// Index of the string object the tests add: the AKD has no writable object longer than 4
/// bytes, so this one stands in for one (it is not an AKD object).
const TEXT: u16 = 0x2FF0;
/// Its name, long enough that its object description does not fit one 64-byte message.
const TEXT_NAME: &str = "Writable text longer than a 64-byte mailbox, added by the test";

/// Every mailbox message the master wrote (`true`) or read (`false`) through the link.
type Messages = Arc<Mutex<Vec<(bool, Vec<u8>)>>>;

/// The in-process link, keeping a copy of every mailbox message that went through.
struct Spy {
    inner: InProcess,
    messages: Messages,
}

impl Link for Spy {
    fn send(&mut self, tx: &[u8]) -> Result<()> {
        self.inner.send(tx)
    }

    fn receive(&mut self, rx: &mut [u8], deadline: Instant) -> Result<Option<usize>> {
        let Some(n) = self.inner.receive(rx, deadline)? else { return Ok(None) };
        for dg in frame::parse(&rx[..n])? {
            let dg = dg?;
            let written = match (dg.header.command, dg.header.ado) {
                (Command::Fpwr, AKD_MAILBOX_OUT) => true,
                (Command::Fprd, AKD_MAILBOX_IN) => false,
                _ => continue,
            };
            if dg.wkc == 1 {
                self.messages.lock().unwrap().push((written, dg.data.to_vec()));
            }
        }
        Ok(Some(n))
    }

    fn describe(&self) -> String {
        "spy on sim".into()
    }
}

/// A master in PreOp with one small-mailbox AKD that has the [`TEXT`] object holding `text`.
fn master(text: &str) -> (Master, Messages) {
    let mut bus = VirtualBus::with_mailbox_size(1, Timing::IMMEDIATE, MAILBOX).unwrap();
    let value = text.as_bytes().to_vec();
    let entry = Entry {
        subindex: 0,
        name: TEXT_NAME,
        data_type: data_type::VISIBLE_STRING,
        bits: (value.len() * 8) as u16,
        access: access::READ | access::WRITE,
        value,
        check: None,
    };
    bus.slave_mut(0).od_mut().insert(Object {
        index: TEXT,
        name: TEXT_NAME,
        object_code: ObjectCode::Var,
        data_type: data_type::VISIBLE_STRING,
        entries: vec![entry],
        check: None,
    });
    let messages = Messages::default();
    let spy = Spy { inner: InProcess::with_bus(bus), messages: messages.clone() };
    let mut m = Master::new(Box::new(spy), Duration::from_millis(100));
    m.scan().unwrap();
    let mb = m.slave(0).unwrap().mailbox.clone().unwrap();
    assert_eq!((mb.out_len, mb.in_len), (MAILBOX, MAILBOX), "the master takes the size from the SII");
    m.request_state(AlState::PreOp, STEP).unwrap();
    messages.lock().unwrap().clear();
    (m, messages)
}

/// The CoE body of every message, master's first; takes them out of the log.
fn bodies(messages: &Messages) -> (Vec<Vec<u8>>, Vec<Vec<u8>>) {
    let (mut written, mut read) = (Vec::new(), Vec::new());
    for (to_slave, message) in messages.lock().unwrap().drain(..) {
        assert!(message.len() <= MAILBOX as usize);
        let (_, coe, body) = coe::split_message(&message).unwrap();
        assert_ne!(coe.service, CoeService::Emergency);
        if to_slave { &mut written } else { &mut read }.push(body.to_vec());
    }
    (written, read)
}

/// What `pick` finds in each message body; a body where it finds nothing fails the test.
fn decode_each<T>(bodies: &[Vec<u8>], pick: impl Fn(&[u8]) -> Option<T>) -> Vec<T> {
    bodies.iter().map(|b| pick(b).unwrap_or_else(|| panic!("unexpected message body {b:02X?}"))).collect()
}

/// 200 characters: 48 go in the initiate message, the rest in segments of up to 55.
fn long_text(seed: u8) -> String {
    (0..200u8).map(|i| char::from(b'A' + (i.wrapping_mul(7).wrapping_add(seed)) % 26)).collect()
}

#[test]
fn segmented_upload_alternates_the_toggle_bit() {
    let text = long_text(0);
    let (mut m, messages) = master(&text);
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(TEXT, 0).unwrap(), text.as_bytes());
    let (requests, responses) = bodies(&messages);
    let toggles = decode_each(&requests[1..], |b| match SdoRequest::decode(b) {
        Ok(SdoRequest::UploadSegment { toggle }) => Some(toggle),
        _ => None,
    });
    assert_eq!(toggles, [false, true, false]);
    let mut carried = Vec::new();
    for (i, body) in responses.iter().enumerate() {
        match SdoResponse::decode(body).unwrap() {
            SdoResponse::UploadNormal { complete_size: 200, data, .. } if i == 0 => carried.push(data.len()),
            SdoResponse::UploadSegment { toggle, last, data } => {
                assert_eq!((toggle, last), (toggles[i - 1], i == toggles.len()));
                carried.push(data.len());
            }
            other => panic!("{other:?}"),
        }
    }
    assert_eq!(carried, [48, 55, 55, 42]);
}

#[test]
fn segmented_download_alternates_the_toggle_bit_and_round_trips() {
    let (mut m, messages) = master(&long_text(0));
    let text = long_text(5);
    m.slave_mut(0).unwrap().sdo_write(TEXT, 0, text.as_bytes()).unwrap();
    let (requests, responses) = bodies(&messages);
    let mut toggles = Vec::new();
    let mut carried = Vec::new();
    for (i, body) in requests.iter().enumerate() {
        match SdoRequest::decode(body).unwrap() {
            SdoRequest::DownloadNormal { complete_size: 200, data, .. } if i == 0 => carried.push(data.len()),
            SdoRequest::DownloadSegment { toggle, last, data } => {
                assert_eq!(last, i == requests.len() - 1);
                toggles.push(toggle);
                carried.push(data.len());
            }
            other => panic!("{other:?}"),
        }
    }
    assert_eq!(toggles, [false, true, false]);
    assert_eq!(carried, [48, 55, 55, 42]);
    let answered = decode_each(&responses[1..], |b| match SdoResponse::decode(b) {
        Ok(SdoResponse::DownloadSegment { toggle }) => Some(toggle),
        _ => None,
    });
    assert_eq!(answered, toggles);
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(TEXT, 0).unwrap(), text.as_bytes());
    // A value of the wrong length is refused after its last segment, by name.
    match m.slave_mut(0).unwrap().sdo_write(TEXT, 0, &text.as_bytes()[..150]).unwrap_err() {
        Error::SdoAbort { code, .. } => assert_eq!(code, SdoAbortCode::LENGTH_TOO_LOW.0),
        other => panic!("{other}"),
    }
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(TEXT, 0).unwrap(), text.as_bytes());
}

/// The fragments of every SDO information reply in the log: (opcode, fragments left, incomplete).
fn fragments(messages: &Messages) -> Vec<(SdoInfoOpcode, u16, bool)> {
    let (_, responses) = bodies(messages);
    responses
        .iter()
        .map(|b| SdoInfoHeader::decode(b).unwrap())
        .map(|h| (h.opcode, h.fragments_left, h.incomplete))
        .collect()
}

#[test]
fn sdo_information_replies_come_in_fragments() {
    let (mut m, messages) = master("short");
    let list = m.slave_mut(0).unwrap().sdo_object_list(OdListType::All).unwrap();
    let mut expected: Vec<u16> = VirtualBus::new(1).slave(0).od().objects().iter().map(|o| o.index).collect();
    expected.push(TEXT);
    expected.sort();
    assert_eq!(list, expected);
    // Two bytes of list type and two per index, 52 bytes of data per fragment.
    let count = (2 + 2 * list.len()).div_ceil(52) as u16;
    assert!(count >= 4, "{} objects fit {count} fragments", list.len());
    let expected: Vec<_> = (0..count).rev().map(|left| (SdoInfoOpcode::GetOdListResponse, left, left > 0)).collect();
    assert_eq!(fragments(&messages), expected);

    let text = m.slave_mut(0).unwrap().sdo_object_description(TEXT).unwrap();
    assert_eq!(
        (text.name.as_str(), text.data_type, text.object_code),
        (TEXT_NAME, data_type::VISIBLE_STRING, ObjectCode::Var)
    );
    let opcode = SdoInfoOpcode::GetObjectDescriptionResponse;
    assert_eq!(fragments(&messages), [(opcode, 1, true), (opcode, 0, false)]);
    let entry = m.slave_mut(0).unwrap().sdo_entry_description(TEXT, 0).unwrap();
    assert_eq!((entry.name.as_str(), entry.bit_length), (TEXT_NAME, 40));
    let opcode = SdoInfoOpcode::GetEntryDescriptionResponse;
    assert_eq!(fragments(&messages), [(opcode, 1, true), (opcode, 0, false)]);
}
