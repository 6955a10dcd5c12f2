//! The virtual AKD (`sim`): whatever a master sends. The input is a sequence of frames, each
//! `[time step][length, 2 bytes LE][payload]`, served by a line of two virtual AKDs at power-up at
//! bus times 100 µs × step apart, so a sequence can walk the drives through their AL states,
//! mailboxes and process data. The line is built once and its drives power-cycled before each
//! input (the same state as a new line, without building its SII images again). Every frame is either refused untouched (malformed) or comes back
//! as a reply to itself (same frame header, and per datagram the same command, index and
//! length), never a panic.
#![no_main]

use akd_native::ethercat::frame;
use akd_native::ethercat::link::is_reply_to;
use akd_native::sim::line::Delivery;
use akd_native::sim::VirtualBus;
use libfuzzer_sys::fuzz_target;
use std::sync::Mutex;

/// Bus time per step of a record.
const STEP_NS: u64 = 100_000;
/// Longest payload a frame header can announce, with its header.
const MAX_FRAME: usize = 2 + 0x07FF;
/// Drives on the line: the first forwards to the second, the second closes the line.
const DRIVES: usize = 2;

static BUS: Mutex<Option<VirtualBus>> = Mutex::new(None);

fuzz_target!(|data: &[u8]| {
    let mut guard = BUS.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    let bus = guard.get_or_insert_with(|| VirtualBus::new(DRIVES));
    for i in 0..DRIVES {
        bus.slave_mut(i).power_cycle();
    }
    let mut now_ns = 0;
    let mut rest = data;
    while let [step, lo, hi, tail @ ..] = rest {
        let len = (usize::from(u16::from_le_bytes([*lo, *hi])) % (MAX_FRAME + 1)).min(tail.len());
        let (request, after) = tail.split_at(len);
        rest = after;
        now_ns += u64::from(*step) * STEP_NS;
        let mut reply = request.to_vec();
        match bus.process(&mut reply, now_ns) {
            Ok(Delivery::Returned) => {
                assert!(
                    is_reply_to(request, &reply),
                    "a reply that is not the frame sent:\n{request:02X?}\n{reply:02X?}"
                );
                frame::validate(&reply).expect("a returned frame is valid");
            }
            Ok(Delivery::Lost) => panic!("a frame lost on a line without faults"),
            Err(_) => assert_eq!(reply, request, "a refused frame was changed"),
        }
    }
    bus.advance(now_ns + 100 * STEP_NS);
});
