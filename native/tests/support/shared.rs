//! A link to a virtual bus the test shares with the cycle thread (to reach its drives while the
//! thread cycles), on the monotonic clock.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use akd_native::error::Result;
use akd_native::ethercat::link::{Link, Returns};
use akd_native::sim::VirtualBus;

/// The link: every frame served by the shared bus at the time since the link was made.
pub struct Shared {
    bus: Arc<Mutex<VirtualBus>>,
    start: Instant,
    returns: Returns,
}

impl Shared {
    /// A link to `bus`.
    pub fn new(bus: Arc<Mutex<VirtualBus>>) -> Self {
        Shared { bus, start: Instant::now(), returns: Returns::default() }
    }
}

impl Link for Shared {
    fn send(&mut self, tx: &[u8]) -> Result<()> {
        let (bus, now_ns) = (&self.bus, self.start.elapsed().as_nanos() as u64);
        self.returns.serve(tx, |frame| {
            bus.lock().unwrap().process(frame, now_ns)?;
            Ok(true)
        })
    }

    fn receive(&mut self, rx: &mut [u8], _deadline: Instant) -> Result<Option<usize>> {
        self.returns.take(rx)
    }

    fn describe(&self) -> String {
        "shared sim".into()
    }
}
