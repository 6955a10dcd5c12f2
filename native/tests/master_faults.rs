//! Corrupt replies never make the master panic: whatever byte of whatever frame a broken link
//! flips, every operation ends, within its time-outs, in a result or an error.

use std::sync::OnceLock;
use std::time::{Duration, Instant};

use akd_native::error::Result;
use akd_native::ethercat::al::AlState;
use akd_native::ethercat::link::Link;
use akd_native::ethercat::master::Master;
use akd_native::sim::in_process::InProcess;
use akd_native::sim::{Timing, VirtualBus};
use proptest::prelude::*;

/// A link that flips bits of chosen replies after the drives served them.
struct Corrupting {
    inner: InProcess,
    frame: usize,
    /// (frame number, byte offset, XOR mask), by frame number.
    faults: Vec<(usize, usize, u8)>,
}

impl Link for Corrupting {
    fn send(&mut self, tx: &[u8]) -> Result<()> {
        self.inner.send(tx)
    }

    fn receive(&mut self, rx: &mut [u8], deadline: Instant) -> Result<Option<usize>> {
        let Some(n) = self.inner.receive(rx, deadline)? else { return Ok(None) };
        for &(_, at, mask) in self.faults.iter().filter(|f| f.0 == self.frame) {
            rx[at % n] ^= mask;
        }
        self.frame += 1;
        Ok(Some(n))
    }

    fn describe(&self) -> String {
        "corrupting sim".into()
    }
}

fn session(m: &mut Master) -> Result<()> {
    m.scan()?;
    m.request_state(AlState::PreOp, Duration::from_millis(50))?;
    m.slave_mut(0).unwrap().sdo_read(0x100A, 0)?;
    m.slave_mut(0).unwrap().sdo_object_description(0x1018)?;
    m.request_state(AlState::Op, Duration::from_millis(50))?;
    for _ in 0..3 {
        m.exchange()?;
    }
    Ok(())
}

fn master(faults: Vec<(usize, usize, u8)>) -> Master {
    let inner = InProcess::with_bus(VirtualBus::with_timing(1, Timing::IMMEDIATE));
    let mut m = Master::new(Box::new(Corrupting { inner, frame: 0, faults }), Duration::from_millis(20));
    m.set_mailbox_timeout(Duration::from_millis(50));
    m
}

/// Frames of the scan and of the whole session without faults, measured once, so that the
/// faults land where the session has frames whatever the master's frame count is.
fn frames() -> (usize, usize) {
    static FRAMES: OnceLock<(usize, usize)> = OnceLock::new();
    *FRAMES.get_or_init(|| {
        let mut m = master(Vec::new());
        m.scan().unwrap();
        let scan = m.stats().frames as usize;
        session(&mut m).unwrap();
        (scan, m.stats().frames as usize - scan)
    })
}

/// Runs the session with each fault at a share (in 1/65536) of the frames from `from`.
fn run_with(from: usize, faults: Vec<(u16, usize, u8)>) -> std::result::Result<(), TestCaseError> {
    let (_, session_frames) = frames();
    let span = session_frames - from;
    let faults = faults.into_iter().map(|(share, at, mask)| (from + span * share as usize / 65536, at, mask)).collect();
    let mut m = master(faults);
    // Any outcome but a panic or a hang is right; errors must still say something.
    if let Err(e) = session(&mut m) {
        prop_assert!(!e.to_string().is_empty());
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    #[test]
    fn corrupt_replies_anywhere_give_errors_not_panics(
        faults in proptest::collection::vec((any::<u16>(), any::<usize>(), 1u8..=255), 1..6)
    ) {
        run_with(0, faults)?;
    }

    #[test]
    fn corrupt_replies_after_the_scan_give_errors_not_panics(
        faults in proptest::collection::vec((any::<u16>(), any::<usize>(), 1u8..=255), 1..4)
    ) {
        run_with(frames().0, faults)?;
    }
}

#[test]
fn the_session_without_faults_succeeds_after_a_scan() {
    let (scan, session) = frames();
    assert!(scan > 0 && session > scan, "scan {scan} frames, session {session}");
}
